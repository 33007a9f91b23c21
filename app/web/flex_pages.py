"""The flex tab of the web form (issue #14; docs/flex.md): flex sheet → pair → ranking.

Three pages over :mod:`app.flex`, each a GET form that shows its answer below it:

- ``/flex?ski=..&body_weight_kg=..[&snow_modulus_mpa=..]``: the sheet, its plot
  (:func:`app.plots.flex_profile_svg`) and a CSV link (the API's ``format=csv``);
- ``/flex/pair?left=..&right=..&body_weight_kg=..``: the differences, flagged rows marked;
- ``/flex/ranking?ski=..&ski=..&grind=..&body_weight_kg=..&snow_modulus_mpa=..&porosity=..``.

Bad input is shown next to its field (status 422), as in the contact form.
"""

from __future__ import annotations

import math
from html import escape
from urllib.parse import urlencode

from fastapi import FastAPI, Request
from fastapi.responses import HTMLResponse
from skisnow.app import flex
from skisnow.app.access import visible_catalogue
from skisnow.app.service import UnknownItemError
from skisnow.app.web.contact import _page
from skisnow.app.web.plots import flex_profile_svg
from skisnow.solvers.errors import SkisnowError

TABS = (("/flex", "Flex sheet"), ("/flex/pair", "Pair"), ("/flex/ranking", "Ranking"))
DEFAULTS = {"body_weight_kg": "75", "snow_modulus_mpa": "20", "porosity": "0.5"}


def _tabs(active: str) -> str:
    items = "".join(
        f'<a href="{href}" class="tab{" active" if href == active else ""}"'
        f"{' aria-current=page' if href == active else ''}>{label}</a>"
        for href, label in TABS
    )
    return f'<nav class="tabs" id="flex-tabs">{items}</nav>'


def _v(value, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.{digits}g}"
    return escape(str(value))


def _pm(value, band, digits: int = 4) -> str:
    text = _v(value, digits)
    if band:
        text += f" ± {_v(band, 2)}"
    return text


def _number(q: dict, name: str, label: str, errors: dict, required: bool = True) -> str:
    err = errors.get(name)
    return (
        f'<label for="{name}">{label}</label> <input id="{name}" name="{name}" '
        f'type="number" step="any" value="{escape(q.get(name, ""))}"'
        f"{' required' if required else ''}{' aria-invalid=true' if err else ''}>"
        + (f' <span class="field-error" id="{name}-error">{escape(err)}</span>' if err else "")
    )


def _select(name: str, options: list[str], chosen: str | None, errors: dict, label: str) -> str:
    opts = "".join(
        f'<option value="{escape(o)}"{" selected" if o == chosen else ""}>{escape(o)}</option>'
        for o in options
    )
    err = errors.get(name)
    return (
        f'<label for="{name}">{label}</label> <select id="{name}" name="{name}">{opts}</select>'
        + (f' <span class="field-error" id="{name}-error">{escape(err)}</span>' if err else "")
    )


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


def _fail(exc: Exception, errors: dict, default: str) -> None:
    field = getattr(exc, "field", None)
    if isinstance(exc, UnknownItemError) and field is None:
        field = exc.kind
    errors[field or default] = str(exc)


def _request(q: dict, errors: dict, ski: str, snow_required: bool) -> flex.FlexRequest | None:
    w = _float(q, "body_weight_kg", errors)
    e = _float(q, "snow_modulus_mpa", errors, snow_required)
    n = _float(q, "porosity", errors, snow_required)
    if w is not None and not 0 < w <= 300:
        errors["body_weight_kg"] = "must be in (0, 300] kg"
    if e is not None and not 1 <= e <= 2000:
        errors["snow_modulus_mpa"] = "must be in [1, 2000] MPa"
    if n is not None and not 0 <= n < 1:
        errors["porosity"] = "must be in [0, 1)"
    if errors:
        return None
    return flex.FlexRequest(ski, w, e, n)


def _closing_note(c: dict) -> str:
    if c["closed_at_min_load"]:
        return f"≤ {_v(c['min_load_kg'])} (closed at the lightest load the camber model covers)"
    return "" if c["closes_below_max"] else f"(does not close up to {_v(c['max_load_kg'])} kg)"


def _sheet_html(ans: dict) -> str:
    rows = "".join(
        f"<tr><td>≥ {p['gap_mm']:.2f} mm</td>"
        f"<td>{_pm(p['half_weight']['length_mm'], p['half_weight']['length_band_mm'])}</td>"
        f"<td>{_v(p['half_weight']['start_mm'])} … {_v(p['half_weight']['end_mm'])}</td>"
        f"<td>{_pm(p['full_weight']['length_mm'], p['full_weight']['length_band_mm'])}</td>"
        f"<td>{_v(p['full_weight']['start_mm'])} … {_v(p['full_weight']['end_mm'])}</td></tr>"
        for p in ans["pockets"]
    )
    c, k, wb, g = ans["closing_load"], ans["kick_zone"], ans["wheelbase"], ans["glide_check"]
    snow = k["snow"]
    snow_row = ""
    if snow and snow.get("available"):
        half = _pm(snow["half_weight_percent"], snow["half_weight_band_percent"])
        band = snow["full_weight_band_percent"]
        snow_row = (
            f'<tr data-number="kick_snow"><th>Kick-zone load on snow '
            f"({_v(snow['snow_modulus_mpa'])} MPa) [%]</th><td>half {half}, full "
            f"<span class=value>{_v(snow['full_weight_percent'])}</span>"
            f"{' ± ' + _v(band, 2) if band else ''}</td></tr>"
        )
    w = ans["inputs"]["body_weight_kg"]
    return f"""
<h2>Flex sheet of {escape(ans["inputs"]["ski"])} for {_v(w)} kg</h2>
<div class="table-wrap"><table id="pockets"><caption>Wax pocket (foot
{_v(ans["inputs"]["pocket_position_mm"])} mm from the balance point) [mm]</caption>
<tr><th>gap</th><th>half weight: length</th><th>start … end</th><th>full weight: length</th>
<th>start … end</th></tr>{rows}</table></div>
<table id="flex-numbers">
<tr data-number="closing_load_kg"><th>Closing load (0.10 mm under the foot) [kg]</th><td><span
class=value>{_v(c["load_kg"])}</span>{" ± " + _v(c["band_kg"], 2) if c["band_kg"] else ""}
{_closing_note(c)}</td></tr>
<tr><th>Open at half weight / closed at full weight</th><td>{_v(c["open_at_half_weight"])} /
{_v(c["closes_at_full_weight"])}</td></tr>
<tr><th>Kick-zone load on the flat [%]</th><td>half {_v(k["flat"]["half_weight_percent"])}, full
{_pm(k["flat"]["full_weight_percent"], k["flat"]["full_weight_band_percent"])}
(shops aim for 33–50 % at full weight)</td></tr>
{snow_row}
<tr data-number="wheelbase_mm"><th>Wheelbase at full weight [mm]</th><td><span class=value>
{_v(wb["wheelbase_mm"])}</span>{" ± " + _v(wb["band_mm"], 2) if wb["band_mm"] else ""}</td></tr>
<tr data-number="glide"><th>Glide check (full weight at {_v(g["load_position_mm"])} mm)</th><td>
<span class=value>{"passed" if g["passed"] else "failed"}</span>: min gap ahead of the foot
{_v(g["min_gap_mm"])} mm, open {_v(g["open_length_mm"])} mm</td></tr>
</table>
<p class="note">Band: 90 %, from the camber model — {escape(ans["band"]["source"])}.
Conventions and units: docs/flex.md.</p>
<figure id="plot-flex-profile">{flex_profile_svg(ans)}<figcaption>Loaded gap under half and
full weight, wax-layer lines and the wax zone.</figcaption></figure>
"""


def _catalogue(request: Request):
    """The caller's catalogue, with the skis and grinds the query names loaded if another
    process finished them (:func:`skisnow.app.access.visible_catalogue`)."""
    qp = request.query_params
    named = qp.getlist("ski") + [v for k in ("left", "right") if (v := qp.get(k))]
    return visible_catalogue(request, skis=named, grinds=qp.getlist("grind"))


def render_sheet(request: Request) -> HTMLResponse:
    cat = _catalogue(request)
    q = {**DEFAULTS, **dict(request.query_params)}
    skis = sorted(cat.skis)
    errors: dict[str, str] = {}
    body_result, status = "", 200
    if "ski" in request.query_params:
        req = _request(q, errors, q["ski"], snow_required=False)
        if req is not None:
            try:
                ans = flex.flex_sheet_answer(cat, req)
                csv_q = {
                    "body_weight_kg": req.body_weight_kg,
                    **({"snow_modulus_mpa": req.snow_modulus_mpa} if req.snow_modulus_mpa else {}),
                    "format": "csv",
                }
                body_result = _sheet_html(ans) + (
                    f'<p><a id="csv" href="/v1/skis/{escape(req.ski)}/flex?{urlencode(csv_q)}">'
                    'CSV</a> · <a id="json" href="/v1/skis/'
                    f'{escape(req.ski)}/flex?{urlencode({**csv_q, "format": "json"})}">JSON</a></p>'
                )
            except SkisnowError as exc:
                _fail(exc, errors, "body_weight_kg")
            except UnknownItemError as exc:
                _fail(exc, errors, "ski")
        status = 422 if errors else 200
    form = f"""
<form action="/flex" method="get" id="flex-form" class="flex-form">
<p>{_select("ski", skis, q.get("ski"), errors, "Ski")}</p>
<p>{_number(q, "body_weight_kg", "Body weight [kg]", errors)}</p>
<p>{_number(q, "snow_modulus_mpa", "Snow modulus [MPa] (kick share on snow)", errors, False)}</p>
<p><button type="submit" id="submit">Flex sheet</button></p>
</form>"""
    body = f"<h1>Flex sheet</h1>{_tabs('/flex')}{form}{body_result}"
    return _page("skisnow — flex sheet", body, status)


def render_pair(request: Request) -> HTMLResponse:
    cat = _catalogue(request)
    q = {**DEFAULTS, **dict(request.query_params)}
    skis = sorted(cat.skis)
    grinds = ["", *sorted(cat.grinds)]
    errors: dict[str, str] = {}
    result, status = "", 200
    if "left" in request.query_params:
        grind = q.get("grind") or None
        req = _request(q, errors, q.get("left", ""), snow_required=grind is not None)
        if req is not None:
            try:
                out = flex.flex_pair(cat, q["left"], q.get("right", ""), req, grind=grind)
                rows = "".join(
                    f'<tr class="{"flagged" if r["flagged"] else ""}" data-flagged='
                    f'"{str(r["flagged"]).lower()}"><td>{escape(r["quantity"])}</td>'
                    f"<td>{_v(r['left'])}</td><td>{_v(r['right'])}</td>"
                    f"<td>{_v(r['difference'])}</td><td>{_v(r['allowed'])}</td>"
                    f"<td>{'⚑ flagged' if r['flagged'] else ''}</td></tr>"
                    for r in out["flex_differences"] + (out["metric_differences"] or [])
                )
                verdict = (
                    f"flagged: {escape(', '.join(out['flagged_quantities']))}"
                    if out["flagged"]
                    else "not flagged: every difference is within the camber band"
                )
                result = f"""
<h2>Pair {escape(out["inputs"]["left"])} | {escape(out["inputs"]["right"])}</h2>
<p id="pair-verdict" class="{"alert" if out["flagged"] else "ok"}">{verdict}</p>
<div class="table-wrap"><table id="pair"><tr><th>quantity</th><th>left</th><th>right</th>
<th>left − right</th><th>allowed</th><th></th></tr>{rows}</table></div>
<p class="note">{escape(out["rule"])}</p>"""
            except (SkisnowError, UnknownItemError) as exc:
                _fail(exc, errors, "left")
        status = 422 if errors else 200
    form = f"""
<form action="/flex/pair" method="get" id="pair-form" class="flex-form">
<p>{_select("left", skis, q.get("left"), errors, "Left ski")}
{_select("right", skis, q.get("right", skis[-1] if skis else None), errors, "Right ski")}</p>
<p>{_number(q, "body_weight_kg", "Body weight [kg]", errors)}</p>
<p>{_select("grind", grinds, q.get("grind", ""), errors, "Grind (contact metrics)")}
{_number(q, "snow_modulus_mpa", "Snow modulus [MPa]", errors, False)}
{_number(q, "porosity", "Porosity [-]", errors, False)}</p>
<p><button type="submit" id="submit">Compare the pair</button></p>
</form>"""
    body = f"<h1>Pair matching</h1>{_tabs('/flex/pair')}{form}{result}"
    return _page("skisnow — pair", body, status)


def render_ranking(request: Request) -> HTMLResponse:
    cat = _catalogue(request)
    q = {**DEFAULTS, **dict(request.query_params)}
    chosen_skis = request.query_params.getlist("ski")
    chosen_grinds = request.query_params.getlist("grind")
    criterion = q.get("criterion", "real_area")
    errors: dict[str, str] = {}
    result, status = "", 200
    if "body_weight_kg" in request.query_params:
        if not chosen_skis:
            errors["skis"] = "choose at least one ski"
        if not chosen_grinds:
            errors["grinds"] = "choose at least one grind"
        req = _request(q, errors, chosen_skis[0] if chosen_skis else "", snow_required=True)
        if req is not None and not errors:
            try:
                out = flex.flex_ranking(cat, chosen_skis, chosen_grinds, req, criterion=criterion)
                key = out["criterion"]["metric"]
                rows = "".join(
                    f"<tr><td>{e['rank']}</td><td>{escape(e['ski'])}</td>"
                    f"<td>{escape(e['grind'])}</td><td class=value>{_v(e[key])}</td>"
                    f"<td>{_v(e['band_low'])} … {_v(e['band_high'])}</td>"
                    f"<td>{', '.join(map(str, e['not_distinguishable_from'])) or '–'}</td></tr>"
                    for e in out["ranking"]
                )
                left = "".join(
                    f"<li>{escape(o['ski'])}: {escape(o['reason'])}</li>" for o in out["left_out"]
                )
                result = f"""
<h2>Ranking by {escape(key)} ({out["criterion"]["better"]} is better)</h2>
<p class="note">{escape(out["criterion"]["mechanism"])}</p>
<div class="table-wrap"><table id="ranking"><tr><th>rank</th><th>ski</th><th>grind</th>
<th>{escape(key)}</th><th>90 % band</th><th>not distinguishable from rank</th></tr>{rows}
</table></div>
{f'<h3>Left out</h3><ul id="left-out">{left}</ul>' if left else ""}"""
            except (SkisnowError, UnknownItemError) as exc:
                _fail(exc, errors, "skis")
        status = 422 if errors else 200

    def boxes(name: str, items: list[str], chosen: list[str]) -> str:
        return " ".join(
            f'<label><input type="checkbox" name="{name}" value="{escape(i)}"'
            f"{' checked' if i in chosen else ''}> {escape(i)}</label>"
            for i in items
        )

    crit = " ".join(
        f'<label><input type="radio" name="criterion" value="{k}"'
        f"{' checked' if k == criterion else ''}> {k}</label>"
        for k in flex.CRITERIA
    )
    errs = "".join(
        f'<span class="field-error" id="{k}-error">{escape(errors[k])}</span>'
        for k in ("skis", "grinds", "criterion")
        if k in errors
    )
    form = f"""
<form action="/flex/ranking" method="get" id="ranking-form" class="flex-form">
<p>Skis: {boxes("ski", sorted(cat.skis), chosen_skis)}</p>
<p>Grinds: {boxes("grind", sorted(cat.grinds), chosen_grinds)}</p>
<p>{_number(q, "body_weight_kg", "Body weight [kg]", errors)}
{_number(q, "snow_modulus_mpa", "Snow modulus [MPa]", errors)}
{_number(q, "porosity", "Porosity [-]", errors)}</p>
<p>Criterion: {crit}</p>{errs}
<p><button type="submit" id="submit">Rank</button></p>
</form>"""
    body = f"<h1>A skier's best ski</h1>{_tabs('/flex/ranking')}{form}{result}"
    return _page("skisnow — ranking", body, status)


def mount(app: FastAPI) -> None:
    """Add the flex tab's pages to ``app``."""

    @app.get("/flex", response_class=HTMLResponse, include_in_schema=False)
    def flex_page(request: Request) -> HTMLResponse:
        return render_sheet(request)

    @app.get("/flex/pair", response_class=HTMLResponse, include_in_schema=False)
    def pair_page(request: Request) -> HTMLResponse:
        return render_pair(request)

    @app.get("/flex/ranking", response_class=HTMLResponse, include_in_schema=False)
    def ranking_page(request: Request) -> HTMLResponse:
        return render_ranking(request)
