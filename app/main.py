"""The service: the REST API (:mod:`app.api`) and the web pages (:mod:`app.web`) in one app.

``skisnow.app.main:app`` is the ASGI entry point of the uvicorn workers (``skisnow serve``,
settings from the SKISNOW_* environment). It is built on first access, not on import, so that
importing :func:`create_app` (tests, scripts) builds nothing.
"""

from __future__ import annotations

from skisnow.app.api.factory import create_api
from skisnow.app.service import Catalogue
from skisnow.app.settings import Settings
from skisnow.app.web import routes as web_routes

__all__ = ["create_app"]  # and ``app``, made on first access (below)


def create_app(settings: Settings | None = None, catalogue: Catalogue | None = None):
    """The API of :func:`app.api.factory.create_api` with the web pages mounted."""
    app = create_api(settings, catalogue)
    web_routes.mount(app)
    return app


def __getattr__(name: str):
    # PEP 562: ``app`` is made once, when uvicorn (or anyone) first asks for it
    if name == "app":
        globals()["app"] = instance = create_app()
        return instance
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
