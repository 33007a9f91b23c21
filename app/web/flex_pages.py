"""The flex tab of the web form (issue #14; docs/flex.md): flex sheet → pair → ranking.

Three pages over :mod:`app.service.flex`, each a GET form that shows its answer below it:

- ``/flex?ski=..&body_weight_kg=..[&snow_modulus_mpa=..]``: the sheet, its plot
  (:func:`app.plots.flex_profile_svg`) and a CSV link (the API's ``format=csv``);
- ``/flex/pair?left=..&right=..&body_weight_kg=..``: the differences, flagged rows marked;
- ``/flex/ranking?ski=..&ski=..&grind=..&body_weight_kg=..&snow_modulus_mpa=..&porosity=..``.

Bad input is shown next to its field (status 422), as in the contact form; the bounds the pages
check themselves are in :func:`check_bounds`.
"""

from __future__ import annotations

import math
from urllib.parse import quote, urlencode

from fastapi import Request
from fastapi.responses import HTMLResponse
from skisnow.app.api.access import visible_catalogue
from skisnow.app.plots import flex_pair_svg, flex_profile_svg
from skisnow.app.service import UnknownItemError, flex
from skisnow.app.snow import SNOW_PRESETS, resolve_snow, snow_choices
from skisnow.app.web.form import chosen_snow
from skisnow.app.web.templating import page, svg
from skisnow.solvers.errors import SkisnowError

#: the pages' defaults: the snow is the same preset as the contact form's (app/snow.py); its
#: modulus and porosity fields stay empty (the preset's numbers) unless a user types one
DEFAULTS = {"body_weight_kg": "75", "snow_modulus_mpa": "", "porosity": ""}


def _float(q: dict, name: str, errors: dict, required: bool = True) -> float | None:
    text = q.get(name, "").strip()
    if not text:
        if required:
            errors[name] = "required"
        return None
    try:
        v = float(text)
    except ValueError:
        errors[name] = f"not a number: {text!r}"
        return None
    if not math.isfinite(v):
        errors[name] = "must be finite"
        return None
    return v


def check_bounds(
    body_weight_kg: float | None,
    snow_modulus_mpa: float | None,
    porosity: float | None,
    errors: dict,
) -> None:
    """The bounds of the flex pages' inputs; a value out of them gets its message in
    ``errors`` (a missing value is not checked here)."""
    if body_weight_kg is not None and not 0 < body_weight_kg <= 300:
        errors["body_weight_kg"] = "must be in (0, 300] kg"
    if snow_modulus_mpa is not None and not 1 <= snow_modulus_mpa <= 2000:
        errors["snow_modulus_mpa"] = "must be in [1, 2000] MPa"
    if porosity is not None and not 0 <= porosity < 1:
        errors["porosity"] = "must be in [0, 1)"


def _fail(exc: Exception, errors: dict, default: str) -> None:
    field = getattr(exc, "field", None)
    if isinstance(exc, UnknownItemError) and field is None:
        field = exc.kind
    errors[field or default] = str(exc)


def _snow(request: Request, q: dict, errors: dict) -> str | None:
    """The snow preset of the page (the contact form's rule, :func:`chosen_snow`); None for
    custom numbers. Sets ``q["snow"]`` for the page's select."""
    name = chosen_snow(request.query_params)
    if name and name not in SNOW_PRESETS:
        errors["snow"] = f"unknown snow {name!r}; choose {', '.join(SNOW_PRESETS)}"
        name = ""
    q["snow"] = name
    return name or None


def _request(
    request: Request, q: dict, errors: dict, ski: str, snow_required: bool
) -> flex.FlexRequest | None:
    w = _float(q, "body_weight_kg", errors)
    snow = _snow(request, q, errors)
    e = _float(q, "snow_modulus_mpa", errors, required=False)
    n = _float(q, "porosity", errors, required=False)
    e, n = resolve_snow(snow, e, n)
    if snow_required:
        for name, v in (("snow_modulus_mpa", e), ("porosity", n)):
            if v is None and name not in errors:
                errors[name] = "required (or choose a snow type)"
    check_bounds(w, e, n, errors)
    if errors:
        return None
    return flex.FlexRequest(ski, w, e, n, snow=snow)


def _catalogue(request: Request):
    """The caller's catalogue, with the skis and grinds the query names loaded if another
    process finished them (:func:`skisnow.app.api.access.visible_catalogue`)."""
    qp = request.query_params
    named = qp.getlist("ski") + [v for k in ("left", "right") if (v := qp.get(k))]
    return visible_catalogue(request, skis=named, grinds=qp.getlist("grind"))


def render_sheet(request: Request) -> HTMLResponse:
    cat = _catalogue(request)
    q = {**DEFAULTS, **dict(request.query_params), "snow": chosen_snow(request.query_params)}
    errors: dict[str, str] = {}
    context: dict = {"ans": None}
    status = 200
    if "ski" in request.query_params:
        req = _request(request, q, errors, q["ski"], snow_required=False)
        if req is not None:
            try:
                ans = flex.flex_sheet_answer(cat, req)
                csv_q = {
                    "body_weight_kg": req.body_weight_kg,
                    **({"snow": req.snow} if req.snow else {}),
                    **({"snow_modulus_mpa": req.snow_modulus_mpa} if req.snow_modulus_mpa else {}),
                    "format": "csv",
                }
                context = {
                    "ans": ans,
                    "figure": svg(flex_profile_svg(ans)),
                    "csv_url": f"/v1/skis/{quote(req.ski, safe='')}/flex?{urlencode(csv_q)}",
                    "json_url": f"/v1/skis/{quote(req.ski, safe='')}/flex?"
                    + urlencode({**csv_q, "format": "json"}),
                }
            except SkisnowError as exc:
                _fail(exc, errors, "body_weight_kg")
            except UnknownItemError as exc:
                _fail(exc, errors, "ski")
        status = 422 if errors else 200
    return page(
        request,
        "flex_sheet.html",
        "skisnow — flex sheet",
        status,
        q=q,
        skis=sorted(cat.skis),
        errors=errors,
        snow_choices=snow_choices(),
        **context,
    )


def render_pair(request: Request) -> HTMLResponse:
    cat = _catalogue(request)
    q = {**DEFAULTS, **dict(request.query_params), "snow": chosen_snow(request.query_params)}
    errors: dict[str, str] = {}
    out, status = None, 200
    if "left" in request.query_params:
        grind = q.get("grind") or None
        req = _request(request, q, errors, q.get("left", ""), snow_required=grind is not None)
        if req is not None:
            try:
                out = flex.flex_pair(cat, q["left"], q.get("right", ""), req, grind=grind)
            except (SkisnowError, UnknownItemError) as exc:
                _fail(exc, errors, "left")
        status = 422 if errors else 200
    return page(
        request,
        "flex_pair.html",
        "skisnow — pair",
        status,
        q=q,
        skis=sorted(cat.skis),
        grinds=["", *sorted(cat.grinds)],
        errors=errors,
        out=out,
        figure=svg(flex_pair_svg(out["left"], out["right"])) if out else None,
        snow_choices=snow_choices(),
    )


def render_ranking(request: Request) -> HTMLResponse:
    cat = _catalogue(request)
    q = {**DEFAULTS, **dict(request.query_params), "snow": chosen_snow(request.query_params)}
    chosen_skis = request.query_params.getlist("ski")
    chosen_grinds = request.query_params.getlist("grind")
    criterion = q.get("criterion", "real_area")
    errors: dict[str, str] = {}
    out, status = None, 200
    if "body_weight_kg" in request.query_params:
        if not chosen_skis:
            errors["skis"] = "choose at least one ski"
        if not chosen_grinds:
            errors["grinds"] = "choose at least one grind"
        req = _request(
            request, q, errors, chosen_skis[0] if chosen_skis else "", snow_required=True
        )
        if req is not None and not errors:
            try:
                out = flex.flex_ranking(cat, chosen_skis, chosen_grinds, req, criterion=criterion)
            except (SkisnowError, UnknownItemError) as exc:
                _fail(exc, errors, "skis")
        status = 422 if errors else 200
    return page(
        request,
        "flex_ranking.html",
        "skisnow — ranking",
        status,
        q=q,
        skis=sorted(cat.skis),
        grinds=sorted(cat.grinds),
        chosen_skis=chosen_skis,
        chosen_grinds=chosen_grinds,
        criterion=criterion,
        criteria=list(flex.CRITERIA),
        errors=errors,
        out=out,
        snow_choices=snow_choices(),
    )
