"""Contact routes: one ski × grind case, and every combination of skis and grinds.

The answers are plain JSON types already (float lists: ``service.rounding.finite_list``), so
they go out as a ``JSONResponse``: FastAPI's jsonable_encoder would walk their ~10^4 values
again (8-10 ms of a ~60 ms request on the benchmark machine) to give the same bytes. The
response models document them (:mod:`app.api.responses`). orjson encodes them
(:class:`AnswerResponse`): the standard library's encoder took 2.3 ms of a ~20 ms answer,
orjson 0.4 ms, with the same values (issue #29).
"""

from __future__ import annotations

import orjson
from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse
from skisnow.app import service
from skisnow.app.api import problems
from skisnow.app.api.access import visible_catalogue
from skisnow.app.api.models import CompareBody, ContactBody
from skisnow.app.api.responses import CompareAnswer, ContactAnswer

router = APIRouter(tags=["contact"])

#: what a contact or compare request can be answered with besides 200
ERRORS = problems.responses(401, 404, 422)


class AnswerResponse(JSONResponse):
    """A JSON answer encoded by orjson. The answers hold plain finite floats: non-finite
    values are ``None`` already (:func:`app.service.rounding.finite_list`, the answers'
    convention), and orjson writes any other non-finite float as ``null`` too, where
    ``JSONResponse`` would fail the request with a 500 (a walk over the ~10^4 values to
    refuse them would cost 1.4 ms, more than the encoding)."""

    def render(self, content) -> bytes:
        return orjson.dumps(content)


@router.post("/v1/contact", response_model=ContactAnswer, responses=ERRORS)
def post_contact(request: Request, body: ContactBody) -> JSONResponse:
    """One ski × grind case: metrics, apparent contact, distributions, provenance."""
    return AnswerResponse(
        service.contact(
            visible_catalogue(request, skis=[body.ski], grinds=[body.grind]),
            service.ContactInputs(**body.model_dump()),
        )
    )


@router.post("/v1/compare", response_model=CompareAnswer, responses=ERRORS)
def post_compare(request: Request, body: CompareBody) -> JSONResponse:
    """Every ski × grind combination for one load and snow."""
    max_cells = request.app.state.settings.max_compare_cells
    cells = len(body.skis) * len(body.grinds)
    if cells > max_cells:
        return problems.problem(
            422,
            "Invalid input",
            f"skis × grinds = {cells} cases exceeds the limit of {max_cells}",
            errors=[{"field": "skis", "reason": "too many combinations"}],
        )
    cat = visible_catalogue(request, skis=body.skis, grinds=body.grinds)
    for s in body.skis:
        cat.ski(s)
    for g in body.grinds:
        cat.grind(g)
    common = body.model_dump(exclude={"skis", "grinds"})
    results = []
    for s in body.skis:
        for g in body.grinds:
            results.append(service.contact(cat, service.ContactInputs(ski=s, grind=g, **common)))
    return AnswerResponse({"results": results})
