"""Operations routes: liveness and readiness."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse
from skisnow.app.api import problems
from skisnow.app.api.access import visible_catalogue
from skisnow.app.api.responses import Health, Ready

router = APIRouter(tags=["ops"])


@router.get("/healthz", response_model=Health, responses=problems.responses())
def healthz() -> dict:
    """Liveness: the process answers."""
    return {"status": "ok"}


@router.get("/readyz", response_model=Ready, responses=problems.responses(401, 503))
def readyz(request: Request) -> JSONResponse:
    """Readiness: tables and ski files loaded and verified against their manifests."""
    if request.app.state.catalogue is None:
        return problems.problem(503, "Not ready", "catalogue not loaded")
    cat = visible_catalogue(request)
    return JSONResponse({"status": "ready", "skis": sorted(cat.skis), "grinds": sorted(cat.grinds)})
