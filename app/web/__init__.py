"""The technician's HTML pages: contact form and results, ski page, upload page, flex pages.

What lives here
---------------
- :mod:`.routes`: the page routes (``GET``, not in the OpenAPI schema); thin, one render call
  each;
- one module per page family: :mod:`.form` (the contact form and its validation),
  :mod:`.results` (results page, CSV download, result cache), :mod:`.ski_page`,
  :mod:`.upload_page`, :mod:`.flex_pages`;
- :mod:`.templating`: the Jinja2 environment (autoescape on) over ``templates/`` and the
  inline CSS/JS of ``static/``;
- :mod:`.plots` (SVG figures drawn with matplotlib) and :mod:`.ski_figures` (the ski page's
  figures, cached per ski file).

What it may import
------------------
The top-level modules of :mod:`skisnow.app` (settings, units, presets, errors, schemas), the
service layer (catalogue, contact, flex, profiles, access), storage and solvers; never
:mod:`skisnow.app.api` routes nor a command module. This ``__init__`` imports nothing, so
that importing :mod:`.plots` (the report, the ski job) does not load the pages.
"""
