"""The routes of the HTML pages (all ``GET``, none in the OpenAPI schema)."""

from __future__ import annotations

from fastapi import FastAPI
from skisnow.app.web import contact, flex_pages


def mount(app: FastAPI) -> None:
    """Add every page route to ``app``."""
    contact.mount(app)
    flex_pages.mount(app)
