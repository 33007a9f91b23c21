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
- the figures come from :mod:`app.plots` (SVG drawn with matplotlib from numbers, shared with
  the reports) and :mod:`app.service.ski_figures` (the ski page's figures, cached per ski file,
  also drawn by the ski job).

What it may import
------------------
The top-level modules of :mod:`skisnow.app` (settings, units, presets, bounds, errors, plots),
the service and jobs layers, storage and solvers, and of the API only its error module
(:mod:`app.api.problems`) and its access checks (:mod:`app.api.access`); never an API route
nor a command module. This ``__init__`` imports nothing.
"""
