"""Ski routes: the list, the upload of a ski's camber measurements, and one ski
(:mod:`app.api.items`). The flex sheet of a ski is :mod:`app.api.flex`.

Uploads are checked at once (line-numbered errors); the ski's beam is identified and its
network trained by a background job (docs/uploads.md).
"""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Depends, File, Form, Request, UploadFile
from fastapi.responses import JSONResponse
from skisnow.app.api import catalogue as C
from skisnow.app.api import problems
from skisnow.app.api.access import visible_catalogue
from skisnow.app.api.items import item_routes
from skisnow.app.api.responses import SkiAccepted, SkiList
from skisnow.app.jobs import uploads
from skisnow.app.service.profiles import profile_model

router = APIRouter(tags=["catalogue"])

#: what an upload can be answered with besides 202
UPLOAD_ERRORS = problems.responses(401, 403, 409, 415, 422, 429)


@router.get("/v1/skis", response_model=SkiList, responses=problems.responses(401))
def list_skis(request: Request) -> dict:
    """Skis with their outline, model and file provenance; ``failed``: uploads whose job
    failed, with the reason (their name can be uploaded again)."""
    cat = visible_catalogue(request, fresh=True)
    out = []
    for s in cat.skis.values():
        lo, hi = s.position_range_m
        o = s.record.outline
        net = s.record.network
        out.append(
            {
                "name": s.name,
                "length_mm": o.length_m * 1e3,
                "width_mm": [float(w) * 1e3 for w in o.width_m],
                "load_position_range_mm": [lo * 1e3, hi * 1e3],
                "profile_model": profile_model(s.record).source,
                "profile_model_reason": profile_model(s.record).reason,
                "network_metrics": (net or {}).get("attrs", {}).get("metrics_json"),
                "description": s.record.metadata.get("description"),
                "file": s.path.name,
                "sha256": s.sha256,
            }
        )
    return {"skis": out, "failed": C.failed_views(request, "ski")}


@router.post(
    "/v1/skis",
    status_code=202,
    dependencies=[Depends(C.multipart)],
    response_model=SkiAccepted,
    responses=UPLOAD_ERRORS,
)
def post_ski(
    request: Request,
    team: C.Team,
    file: Annotated[UploadFile, File(description="neutral camber CSV")],
    name: Annotated[str, Form(min_length=1, max_length=64)],
    length_mm: Annotated[float, Form(gt=0, description="ski length [mm]")],
    width_mm: Annotated[str, Form(description="running-surface width [mm]: one or a list")],
    width_positions_mm: Annotated[str | None, Form()] = None,
    style: Annotated[Literal["classic", "skate"], Form()] = "classic",
    brand_model: Annotated[str, Form(max_length=128)] = "",
    owner_team: Annotated[str, Form(max_length=64)] = "",
    notes: Annotated[str, Form(max_length=2000)] = "",
    unmeasured: Annotated[
        Literal["drop", "refuse"],
        Form(
            description="samples without a gap (empty, NaN; a row a case leaves out of the "
            "grid the other cases list): drop their positions from every case, or their "
            "cases, whichever sets aside fewer samples (recorded), or refuse the file"
        ),
    ] = "drop",
) -> JSONResponse:
    """Upload a ski's camber measurements: validated at once (line-numbered errors; data
    too sparse for the accuracy check are refused); its network is trained by a job."""
    state = C.catalogue_state(request)
    settings = request.app.state.settings
    # a taken name first (409; a failed item of the same team is replaced), then the job
    # quota (429), both before the file is read
    uploads.check_name_free(state.db, "ski", name, team)
    uploads.check_job_quota(state.db, team, C.limits(request))
    meta = {
        "brand_model": C.text(brand_model, "brand_model"),
        "style": style,
        "owner_team": C.text(owner_team, "owner_team") or (team or ""),
        "notes": C.text(notes, "notes"),
    }
    with C.incoming(state, file, settings.max_upload_bytes) as path:
        item, job_id, figures = uploads.accept_ski(
            state.db,
            state.layout,
            data=path.read_bytes(),
            filename=file.filename or "upload",
            name=name,
            metadata=meta,
            length_mm=length_mm,
            width_mm=width_mm,
            width_positions_mm=width_positions_mm,
            unmeasured=unmeasured,
            team=team,
            limits=C.limits(request),
            max_cases=settings.max_camber_cases,
            max_rows=settings.max_camber_rows,
            max_check_s=settings.max_check_s,
        )
    state.runner.wake()
    return C.accepted(item, job_id, data=figures)


item_routes(router, "ski", "skis")
