"""The REST API as a FastAPI application: settings, lifespan, middleware, handlers, routes.

:func:`create_api` builds it; :func:`app.main.create_app` adds the web pages. Every error a
user can cause is a problem body (:mod:`app.api.problems`, mapped in :mod:`app.api.handlers`);
bodies over the limit are 413 (:mod:`app.api.limits`). Who may change and see what (tokens,
the same-origin check of changes, team filtering) is :mod:`app.api.access`.
"""

from __future__ import annotations

import logging
import time
from contextlib import asynccontextmanager

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from skisnow.app import service
from skisnow.app.api import catalogue as catalogue_state
from skisnow.app.api import contact, flex, grinds, handlers, jobs, ops, problems, skis
from skisnow.app.api.access import HostGuardMiddleware, WriteGuardMiddleware, allowed_hosts
from skisnow.app.api.idle import ActivityMiddleware, IdleTrimmer
from skisnow.app.api.limits import BodyLimitMiddleware
from skisnow.app.settings import Settings

__all__ = ["create_api"]

#: uvicorn's own logger: what it logs appears under ``skisnow serve`` beside uvicorn's lines
start_log = logging.getLogger("uvicorn.error")

DESCRIPTION = (
    "Multi-scale contact between cross-country skis and snow (Kalliorinne et al. "
    "2022–2023): real contact area, average real contact pressure, minimum average "
    "separation and total reciprocal separation for a ski, a grind, a load and a snow."
)


def create_api(settings: Settings | None = None, catalogue: service.Catalogue | None = None):
    """Build the API; the catalogue is loaded (and verified) once at start-up."""
    settings = settings or Settings()
    from skisnow.app.storage import memory

    memory.BUDGET.set_max_bytes(int(settings.ski_cache_mb * 2**20))
    trimmer = IdleTrimmer(settings.idle_trim_s)

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        t0 = time.perf_counter()
        if app.state.catalogue is None:
            start_log.info("loading the catalogue from %s", settings.tables_dir)
            app.state.catalogue = service.load_catalogue(settings.tables_dir)
        if settings.warm_up:
            start_log.info(
                "warming up: solving one case so that the first request is fast "
                "(compiling the kernels; up to ~30 s at the first start)"
            )
            took_s = service.warm_up(app.state.catalogue)
            start_log.info("warm-up done in %.1f s", took_s)
        catalogue_state.start(app)
        trimmer.start()
        start_log.info("skisnow ready after %.1f s", time.perf_counter() - t0)
        try:
            yield
        finally:
            trimmer.stop()
            catalogue_state.stop(app)

    app = FastAPI(
        title="skisnow",
        version=service.code_version(),
        description=DESCRIPTION,
        lifespan=lifespan,
    )
    app.state.catalogue = catalogue
    app.state.settings = settings
    app.state.idle_trimmer = trimmer
    app.add_middleware(ActivityMiddleware, tracker=trimmer)
    app.add_middleware(
        BodyLimitMiddleware,
        limit=settings.max_body_bytes,
        upload_limit=settings.max_upload_bytes,
        upload_paths=catalogue_state.UPLOAD_PATHS,
    )
    # added last, so it runs first: a refused change never has its body read
    app.add_middleware(
        WriteGuardMiddleware,
        tokens=settings.team_tokens,
        trusted_origins=settings.trusted_origins,
    )
    # added after the write guard, so it runs before it: a request naming a host that is not
    # this service's (DNS rebinding) is refused before anything else looks at it
    app.add_middleware(HostGuardMiddleware, allowed=allowed_hosts(settings))
    handlers.install(app)
    for module in (ops, contact, flex, skis, grinds, jobs):
        app.include_router(module.router)

    def openapi() -> dict:
        if app.openapi_schema is None:
            schema = get_openapi(
                title=app.title,
                version=app.version,
                description=app.description,
                routes=app.routes,
            )
            app.openapi_schema = problems.add_to_openapi(schema)
        return app.openapi_schema

    app.openapi = openapi
    return app
