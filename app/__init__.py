"""skisnow edges: command line, storage, offline jobs and (later) the web service."""
