"""Routes of the technician's flex sheet (issue #14; docs/flex.md): thin wrappers over
:mod:`app.service.flex`.

- ``GET /v1/skis/{name}/flex``: one ski's flex sheet for a body weight (and a snow);
- ``GET /v1/flex/pair``: two skis side by side, flagged differences;
- ``POST /v1/flex/ranking``: ski × grind combinations ranked for a skier.

Each takes ``format=json`` (default) or ``format=csv``. Bad input is a 4xx problem body whose
``errors`` name the field (query validation by FastAPI, range checks of the service through the
``field`` of its errors, :mod:`app.api.handlers`). The bounds are those of :mod:`app.bounds`.
"""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Query, Request
from fastapi.responses import JSONResponse, Response
from pydantic import BaseModel, ConfigDict, Field, model_validator
from skisnow.app import bounds
from skisnow.app.api import problems
from skisnow.app.api.access import visible_catalogue
from skisnow.app.api.responses import FlexPair, FlexRanking, FlexSheet
from skisnow.app.bounds import SNOW_DOC, PresetName, SkiModelName, fill_snow
from skisnow.app.service import flex
from skisnow.app.snow import SnowName, resolve_snow
from skisnow.solvers.errors import InputError

Format = Literal["json", "csv"]
Criterion = Literal["real_area", "reciprocal_separation"]

_W_DOC = "skier's body weight [kg]; half of it is the two-ski stance of the wax pocket"
_E_DOC = "Young's modulus of the snow [MPa] (kick-zone share on snow, contact metrics)"
_N_DOC = "snow porosity n = 1 − ρ/917 [-]"
#: the ``snow`` query parameter (a snow preset; its numbers fill the ones not given)
_SNOW_QUERY = Query(None, description=SNOW_DOC)


class RankingBody(BaseModel):
    """Body of ``POST /v1/flex/ranking``."""

    model_config = ConfigDict(extra="forbid")

    skis: list[str] = Field(..., min_length=1, max_length=16, examples=[["ski-a", "ski-b"]])
    grinds: list[str] = Field(..., min_length=1, max_length=16, examples=[["grind-1"]])
    body_weight_kg: float = Field(
        ..., **bounds.BODY_WEIGHT_KG.field(), description=_W_DOC, examples=[75]
    )
    snow: SnowName | None = Field(None, description=SNOW_DOC, examples=["fine-grained"])
    snow_modulus_mpa: float = Field(
        ..., **bounds.SNOW_MODULUS_MPA.field(), description=_E_DOC, examples=[200]
    )
    porosity: float = Field(..., **bounds.POROSITY.field(), description=_N_DOC, examples=[0.5])
    base_modulus_mpa: float = Field(700.0, **bounds.BASE_MODULUS_MPA.field())
    poisson_ratio: float = Field(0.3, **bounds.POISSON_RATIO.field())
    preset: PresetName = "default"
    ski_model: SkiModelName = "auto"
    criterion: Criterion = Field(
        "real_area",
        description="; ".join(f"{k}: {v[2]}" for k, v in flex.CRITERIA.items()),
    )

    @model_validator(mode="before")
    @classmethod
    def _snow_preset(cls, data):
        return fill_snow(data)


def _csv(text: str, name: str) -> Response:
    return Response(
        text,
        media_type="text/csv; charset=utf-8",
        headers={"Content-Disposition": f'attachment; filename="{name}.csv"'},
    )


router = APIRouter(tags=["flex"])

#: a csv answer besides the JSON one
_CSV = {"content": {"text/csv": {"schema": {"type": "string"}}}}
#: what a flex route can be answered with besides 200
_ERRORS = problems.responses(401, 404, 422)


@router.get(
    "/v1/skis/{name}/flex",
    response_model=FlexSheet,
    responses={200: _CSV, **_ERRORS},
)
def get_flex(
    request: Request,
    name: str,
    body_weight_kg: float = Query(..., **bounds.BODY_WEIGHT_KG.field(), description=_W_DOC),
    snow_modulus_mpa: float | None = Query(
        None, **bounds.SNOW_MODULUS_MPA.field(), description=_E_DOC
    ),
    porosity: float | None = Query(None, **bounds.POROSITY.field(), description=_N_DOC),
    snow: SnowName | None = _SNOW_QUERY,
    base_modulus_mpa: float = Query(700.0, **bounds.BASE_MODULUS_MPA.field()),
    poisson_ratio: float = Query(0.3, **bounds.POISSON_RATIO.field()),
    preset: PresetName = "default",
    format: Format = "json",
):
    """The flex sheet: wax pocket at 0.10/0.15/0.20/0.30 mm under half and full weight,
    closing load, kick-zone load share (flat and snow), wheelbase, glide check; each with
    its 90 % band from the camber model."""
    snow_modulus_mpa, porosity = resolve_snow(snow, snow_modulus_mpa, porosity)
    req = flex.FlexRequest(
        name,
        body_weight_kg,
        snow_modulus_mpa,
        porosity,
        base_modulus_mpa,
        poisson_ratio,
        preset,
        snow,
    )
    answer = flex.flex_sheet_answer(visible_catalogue(request, skis=[name]), req)
    if format == "csv":
        return _csv(flex.sheet_csv(answer), f"flex-{name}")
    return JSONResponse(answer)


@router.get("/v1/flex/pair", response_model=FlexPair, responses={200: _CSV, **_ERRORS})
def get_pair(
    request: Request,
    left: str = Query(..., min_length=1, max_length=64),
    right: str = Query(..., min_length=1, max_length=64),
    body_weight_kg: float = Query(..., **bounds.BODY_WEIGHT_KG.field(), description=_W_DOC),
    grind: str | None = Query(None, min_length=1, max_length=64),
    snow_modulus_mpa: float | None = Query(
        None, **bounds.SNOW_MODULUS_MPA.field(), description=_E_DOC
    ),
    porosity: float | None = Query(None, **bounds.POROSITY.field(), description=_N_DOC),
    snow: SnowName | None = _SNOW_QUERY,
    base_modulus_mpa: float = Query(700.0, **bounds.BASE_MODULUS_MPA.field()),
    poisson_ratio: float = Query(0.3, **bounds.POISSON_RATIO.field()),
    preset: PresetName = "default",
    ski_model: SkiModelName = "auto",
    format: Format = "json",
):
    """Two skis of a pair side by side: every flex-sheet number and (with a grind and a
    snow) the four contact metrics, flagged where a difference exceeds the camber band."""
    snow_modulus_mpa, porosity = resolve_snow(snow, snow_modulus_mpa, porosity)
    req = flex.FlexRequest(
        left,
        body_weight_kg,
        snow_modulus_mpa,
        porosity,
        base_modulus_mpa,
        poisson_ratio,
        preset,
        snow,
    )
    answer = flex.flex_pair(
        visible_catalogue(request, skis=[left, right], grinds=[grind] if grind else []),
        left,
        right,
        req,
        grind=grind,
        ski_model=ski_model,
    )
    if format == "csv":
        return _csv(flex.pair_csv(answer), f"pair-{left}-{right}")
    return JSONResponse(answer)


@router.post("/v1/flex/ranking", response_model=FlexRanking, responses={200: _CSV, **_ERRORS})
def post_ranking(request: Request, body: RankingBody, format: Format = "json"):
    """Ski × grind combinations ranked for a skier by a switchable criterion."""
    max_cells = request.app.state.settings.max_compare_cells
    cells = len(body.skis) * len(body.grinds)
    if cells > max_cells:
        raise flex.field_error(
            InputError, "skis", f"skis × grinds = {cells} cases exceeds the limit of {max_cells}"
        )
    req = flex.FlexRequest(
        body.skis[0],
        body.body_weight_kg,
        body.snow_modulus_mpa,
        body.porosity,
        body.base_modulus_mpa,
        body.poisson_ratio,
        body.preset,
        body.snow,
    )
    answer = flex.flex_ranking(
        visible_catalogue(request, skis=body.skis, grinds=body.grinds),
        body.skis,
        body.grinds,
        req,
        criterion=body.criterion,
        ski_model=body.ski_model,
    )
    if format == "csv":
        return _csv(flex.ranking_csv(answer), "ranking")
    return JSONResponse(answer)
