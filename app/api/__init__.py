"""The REST API (FastAPI): routes per resource, their request and response models, problem+json.

- :mod:`.factory`: :func:`~.factory.create_api` (settings, lifespan, middleware, routers);
- routes: :mod:`.ops` (health), :mod:`.contact` (contact, compare), :mod:`.skis`,
  :mod:`.grinds`, :mod:`.items` (one item of either), :mod:`.jobs`, :mod:`.flex`;
- :mod:`.models` (request bodies, bounds from :mod:`app.bounds`), :mod:`.responses` (answers);
- :mod:`.problems` (problem bodies and their OpenAPI schema: the one error module, which the web
  pages and :mod:`app.api.access` may use too), :mod:`.handlers` (exceptions → problems),
  :mod:`.limits` (body size), :mod:`.catalogue` (the uploads' state and request checks).

May import the service and jobs layers (:mod:`app.service`, :mod:`app.jobs.uploads`, ...),
storage, solvers and the top-level modules; never the web pages or a command. Importing this
package imports none of its modules (``app.api.problems`` stays light for the web pages).
"""
