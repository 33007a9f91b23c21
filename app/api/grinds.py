"""Grind routes: the list, the upload of a grind's topography, and one grind
(:mod:`app.api.items`).

Uploads are detrended and checked at once (ISO 25178 parameters in the answer); the grind's
table is built by a background job (docs/uploads.md).
"""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter, Depends, File, Form, Request, UploadFile
from fastapi.responses import JSONResponse
from skisnow.app.api import catalogue as C
from skisnow.app.api import problems
from skisnow.app.api.access import visible_catalogue
from skisnow.app.api.items import item_routes
from skisnow.app.api.responses import GrindAccepted, GrindList
from skisnow.app.jobs import uploads

router = APIRouter(tags=["catalogue"])

#: what an upload can be answered with besides 202
UPLOAD_ERRORS = problems.responses(401, 403, 409, 415, 422, 429)


@router.get("/v1/grinds", response_model=GrindList, responses=problems.responses(401))
def list_grinds(request: Request) -> dict:
    """Grinds with their ISO 25178 parameters and table provenance; ``failed``: uploads whose
    job failed, with the reason (their name can be uploaded again)."""
    cat = visible_catalogue(request, fresh=True)
    out = []
    for g in cat.grinds.values():
        t = g.table
        out.append(
            {
                "name": g.name,
                "iso25178": t.iso_parameters,
                "texture_pixel_size_um": t.pixel_size_m * 1e6,
                "grid": list(t.grid_shape),
                "pressure_ratio_range": [
                    float(t.pressure_ratio[0]),
                    float(t.pressure_ratio[-1]),
                ],
                "gap_floor_nm": t.gap_floor_m * 1e9,
                # what was removed from the heights (plane, mean, none); None: not recorded
                "detrend": t.attrs.get("texture_detrend"),
                "provenance": C.grind_provenance(t),
                "file": g.path.name,
                "sha256": g.sha256,
                "code_version": t.attrs.get("code_version"),
                "git_commit": t.attrs.get("git_commit"),
            }
        )
    return {"grinds": out, "failed": C.failed_views(request, "grind")}


@router.post(
    "/v1/grinds",
    status_code=202,
    dependencies=[Depends(C.multipart)],
    response_model=GrindAccepted,
    responses=UPLOAD_ERRORS,
)
def post_grind(
    request: Request,
    team: C.Team,
    file: Annotated[UploadFile, File(description="topography: x3p, instrument files, .npy, .csv")],
    name: Annotated[str, Form(min_length=1, max_length=64)],
    shop_code: Annotated[str, Form(max_length=64)] = "",
    machine: Annotated[str, Form(max_length=128)] = "",
    pattern_family: Annotated[str, Form(max_length=128)] = "",
    coarseness_grade: Annotated[str, Form(max_length=64)] = "",
    temperature_window: Annotated[str, Form(max_length=64)] = "",
    notes: Annotated[str, Form(max_length=2000)] = "",
    pixel_size_um: Annotated[float | None, Form(gt=0, le=1000)] = None,
    height_unit: Annotated[str | None, Form(max_length=8)] = None,
    along_ski: Annotated[Literal["x", "y"], Form()] = "x",
    periodic: Annotated[Literal["mirror", "window", "none"], Form()] = "mirror",
    detrend: Annotated[
        Literal["plane", "mean", "none"] | None,
        Form(
            description=(
                "removed from the measured heights before the solve: plane (the default, "
                "whatever periodic is), mean or none; recorded in the item's metadata"
            )
        ),
    ] = None,
    reduce: Annotated[
        Literal["block", "crop", "none"],
        Form(
            description=(
                "how a map too large for the solver is reduced: block (default: block "
                "average to a larger pixel), crop (a centred window, pixel kept) or none "
                "(refused); recorded in the answer and the item's metadata"
            )
        ),
    ] = uploads.DEFAULT_REDUCTION,
) -> JSONResponse:
    """Upload a grind's topography: detrended and checked at once (ISO 25178 parameters of the
    measured points in the answer, with what was cut, filled and reduced); its table is built
    by a background job (``job`` → ``GET /v1/jobs/{id}``)."""
    state = C.catalogue_state(request)
    settings = request.app.state.settings
    # a taken name first (409; a failed item of the same team is replaced), then the job
    # quota (429), both before the file is read
    uploads.check_name_free(state.db, "grind", name, team)
    uploads.check_job_quota(state.db, team, C.limits(request))
    meta = {
        "shop_code": C.text(shop_code, "shop_code"),
        "machine": C.text(machine, "machine"),
        "pattern_family": C.text(pattern_family, "pattern_family"),
        "coarseness_grade": C.text(coarseness_grade, "coarseness_grade"),
        "temperature_window": C.text(temperature_window, "temperature_window"),
        "notes": C.text(notes, "notes"),
    }
    with C.incoming(state, file, settings.max_upload_bytes) as path:
        item, job_id, iso, preparation = uploads.accept_grind(
            state.db,
            state.layout,
            settings,
            upload_path=path,
            filename=file.filename or "upload",
            name=name,
            metadata=meta,
            pixel_size_um=pixel_size_um,
            height_unit=height_unit,
            along_ski=along_ski,
            periodic=periodic,
            detrend=detrend,
            reduce=reduce,
            team=team,
            limits=C.limits(request),
        )
    state.runner.wake()
    return C.accepted(item, job_id, iso25178=iso, preparation=preparation)


item_routes(router, "grind", "grinds")
