"""ASGI entry point for uvicorn workers: ``app.main:app`` (settings from SKISNOW_* env)."""

from skisnow.app.api import create_app

app = create_app()
