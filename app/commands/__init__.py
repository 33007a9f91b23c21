"""Small subcommands of the ``skisnow`` command line."""
