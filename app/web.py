"""Technician web form at ``/`` (server-rendered HTML with SVG plots)."""

from __future__ import annotations

from fastapi import FastAPI


def mount(app: FastAPI) -> None:
    """Add the web-form routes to ``app`` (filled in by the web-form work)."""
