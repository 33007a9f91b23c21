"""Technician web form at ``/`` (server-rendered HTML with inline SVG plots).

Routes (all ``GET`` so that every result is a link; no multipart, no JavaScript required):

``/``
    The form: skis and grinds from the catalogue, load [kg] and its position [mm] with presets,
    snow modulus [MPa] and porosity (or snow density [kg/m³]), advanced base modulus and
    Poisson's ratio. Query parameters, if any, pre-fill it.
``/results``
    The four metrics for every ski × grind, a comparison table, plots and provenance.
``/results.csv``
    The comparison table as CSV (one row per combination, units in the column names).
``/skis/{name}``
    One ski's page: its served profile model and why, the beam identified from its camber
    measurements (provenance, held-out check), EI(X) and c(X) with their bands and the misfit
    per camber case, the same figures as ``GET /v1/skis/{name}``; why there is no beam when
    there is none. An unknown name is a 404 page.
``/upload``
    Upload a ski's camber CSV or a grind's topography with their metadata. The two forms post
    multipart to the REST routes (``POST /v1/skis``, ``POST /v1/grinds``, checks in
    :mod:`app.uploads`) from ``static/upload.js``, show the problem+json errors next to the
    field they name, then follow the job (``GET /v1/jobs/{id}`` every second) with a progress
    bar and, when it is done, link back to the form with the new item selected (and, for a
    ski, to its page ``/skis/{name}``: the beam its job identified, or why there is none).
    This page is the one that needs JavaScript (uploads are multipart, progress needs
    polling).

The query is validated with the bounds of :class:`app.schemas.ContactBody`; bad input re-shows
the form with a message next to the offending field (422; 404 for an unknown ski or grind).
Each combination is one :func:`app.service.contact` call; answers are kept in a small
in-memory cache so that the CSV download after a results page costs nothing. The cache is keyed
on the inputs and the sha256 of the ski and grind files, so a renamed item, or one deleted and
uploaded again under its name, is never served an earlier item's answer. With team tokens the
pages show what :func:`app.access.visible_catalogue` lets the request see (a browser sends no
bearer token with a page request: the shipped items and those of no team).
"""

from __future__ import annotations

import csv
import io
import math
import threading
import time
from collections import OrderedDict
from dataclasses import astuple, dataclass, field
from html import escape
from importlib import resources
from pathlib import Path
from string import Template
from urllib.parse import quote, urlencode

from fastapi import FastAPI, Request
from fastapi.responses import HTMLResponse, Response
from pydantic import ValidationError
from skisnow.app import service, units, uploads
from skisnow.app.access import caller, visible_catalogue
from skisnow.app.presets import DEFAULT_PRESET
from skisnow.app.presets import PRESETS as ACCURACY_PRESETS
from skisnow.app.profiles import SERVED_MISFIT_LIMIT
from skisnow.app.schemas import ContactBody
from skisnow.app.web import plots
from skisnow.app.web.ski_figures import ski_figures
from skisnow.solvers.band import Z90
from skisnow.solvers.errors import SkisnowError
from skisnow.solvers.identify import HELD_OUT_LIMIT

#: density of ice used to turn snow density into porosity, n = 1 − ρ/ρ_ice [kg/m³]
ICE_DENSITY_KG_M3 = 917.0

#: the published case (method.md §2): 40 kg at 160 mm behind the balance point, E_snow 200 MPa
DEFAULTS = {
    "load_kg": "40",
    "load_position_mm": "-160",
    "snow_modulus_mpa": "200",
    "porosity": "0.5",
    "snow_density_kg_m3": "458.5",
    "snow_input": "porosity",
    "base_modulus_mpa": "700",
    "poisson_ratio": "0.3",
    "body_weight_kg": "80",
}

#: load presets: (button label, data attributes read by static/web.js)
PRESETS = (
    ("½ body weight at −80 mm", 'data-body-fraction="0.5" data-position-mm="-80"'),
    ("Full body weight at −150 mm", 'data-body-fraction="1" data-position-mm="-150"'),
    ("Published case: 40 kg at −160 mm", 'data-load-kg="40" data-position-mm="-160"'),
)

#: (query name, label, unit, hint) of the numeric inputs; names are those of ContactBody
FIELDS = {
    "body_weight_kg": ("Skier's body weight", "kg", "used by the body-weight presets only"),
    "load_kg": ("Equivalent load on the ski", "kg", "one point load per ski (g = 9.82 m/s²)"),
    "load_position_mm": (
        "Load position from the balance point",
        "mm",
        "negative = behind the balance point (towards the tail)",
    ),
    "snow_modulus_mpa": ("Snow Young's modulus E_snow", "MPa", "papers' study value 200 MPa"),
    "porosity": ("Snow porosity n", "–", "0 ≤ n < 1; groomed track ≈ 0.5"),
    "snow_density_kg_m3": ("Snow density ρ", "kg/m³", "porosity n = 1 − ρ/917"),
    "base_modulus_mpa": ("Ski-base Young's modulus E_base", "MPa", "sintered UHMWPE ≈ 700 MPa"),
    "poisson_ratio": ("Poisson's ratio ν (snow and base)", "–", "0 ≤ ν < 0.5"),
}

#: numeric inputs passed on to ContactBody / service.ContactInputs
NUMERIC = (
    "load_kg",
    "load_position_mm",
    "snow_modulus_mpa",
    "porosity",
    "base_modulus_mpa",
    "poisson_ratio",
)

#: the four functional parameters: (key in "metrics", label, unit, format)
METRICS = (
    ("total_real_contact_area_mm2", "Total real contact area", "mm²", "{:.4g}"),
    ("average_real_contact_pressure_mpa", "Average real contact pressure", "MPa", "{:.4g}"),
    ("min_average_separation_um", "Minimum average separation", "µm", "{:.4g}"),
    ("total_reciprocal_separation_m", "Total average reciprocal separation", "m", "{:.4g}"),
)

#: CSV columns, units in the names as in the JSON API
CSV_COLUMNS = (
    "ski",
    "grind",
    "load_kg",
    "load_position_mm",
    "snow_modulus_mpa",
    "porosity",
    "base_modulus_mpa",
    "poisson_ratio",
    "total_real_contact_area_mm2",
    "average_real_contact_pressure_mpa",
    "min_average_separation_um",
    "total_reciprocal_separation_m",
    "apparent_contact_area_cm2",
    "mean_apparent_pressure_kpa",
    "apparent_contact_area_band90_rel",
    "total_real_contact_area_band90_rel",
    "average_real_contact_pressure_band90_rel",
    "min_average_separation_band90_rel",
    "total_reciprocal_separation_band90_rel",
    "rear_zone_load_share",
    "mid_zone_load_share",
    "front_zone_load_share",
    "ski_model",
    "table_file",
    "table_sha256",
    "texture_pixel_size_um",
    "gap_floor_nm",
    "ski_file",
    "ski_sha256",
    "code_version",
    "compute_time_ms",
    "warnings",
    "error",
)


# ----------------------------------------------------------------------------- parsing


@dataclass
class Query:
    """The form's state: raw strings to re-fill it, parsed inputs and errors per field."""

    skis: list[str]
    grinds: list[str]
    raw: dict[str, str]
    errors: dict[str, str] = field(default_factory=dict)
    numbers: dict[str, float] = field(default_factory=dict)
    status: int = 200

    @property
    def ok(self) -> bool:
        return not self.errors

    def combinations(self) -> list[service.ContactInputs]:
        return [
            service.ContactInputs(ski=s, grind=g, **self.numbers)
            for s in self.skis
            for g in self.grinds
        ]

    def link_query(self) -> str:
        """The query string that reproduces this request."""
        pairs = [("ski", s) for s in self.skis] + [("grind", g) for g in self.grinds]
        pairs += [(k, v) for k, v in self.raw.items() if v != ""]
        return urlencode(pairs)


def _unique(values: list[str]) -> list[str]:
    return list(dict.fromkeys(v.strip() for v in values if v.strip()))


def parse_query(request: Request, cat: service.Catalogue, max_cells: int) -> Query:
    """Read and validate the form's query parameters (bounds of :class:`ContactBody`)."""
    qp = request.query_params
    raw = {k: qp.get(k, "").strip() for k in (*FIELDS, "snow_input", "preset", "ski_model")}
    q = Query(_unique(qp.getlist("ski")), _unique(qp.getlist("grind")), raw)
    if raw["snow_input"] not in ("porosity", "density"):
        raw["snow_input"] = "porosity"

    for kind, chosen, known in (("ski", q.skis, cat.skis), ("grind", q.grinds, cat.grinds)):
        unknown = [n for n in chosen if n not in known]
        if not chosen:
            q.errors[kind] = f"choose at least one {kind}"
        elif unknown:
            q.errors[kind] = (
                f"unknown {kind} {', '.join(map(repr, unknown))}; "
                f"known: {', '.join(sorted(known)) or 'none'}"
            )
            q.status = 404
    if q.skis and q.grinds and len(q.skis) * len(q.grinds) > max_cells:
        q.errors["grind"] = (
            f"{len(q.skis)} skis × {len(q.grinds)} grinds = {len(q.skis) * len(q.grinds)} "
            f"combinations; at most {max_cells} per page"
        )

    if raw["preset"] == "":
        raw["preset"] = DEFAULT_PRESET
    elif raw["preset"] not in ACCURACY_PRESETS:
        q.errors["preset"] = (
            f"unknown accuracy preset {raw['preset']!r}; choose {', '.join(ACCURACY_PRESETS)}"
        )
        raw["preset"] = DEFAULT_PRESET
    if raw["ski_model"] == "":
        raw["ski_model"] = "auto"
    elif raw["ski_model"] not in service.SKI_MODELS:
        q.errors["ski_model"] = (
            f"unknown ski model {raw['ski_model']!r}; choose {', '.join(service.SKI_MODELS)}"
        )
        raw["ski_model"] = "auto"
    values = {k: raw[k] for k in NUMERIC}
    if raw["snow_input"] == "density":
        values.pop("porosity")
        rho = _finite(raw["snow_density_kg_m3"])
        if rho is None or not 0 <= rho < ICE_DENSITY_KG_M3:
            q.errors["snow_density_kg_m3"] = (
                f"snow density must be a number from 0 to below {ICE_DENSITY_KG_M3:g} kg/m³"
            )
        else:
            values["porosity"] = str(1.0 - rho / ICE_DENSITY_KG_M3)
    for key in ("base_modulus_mpa", "poisson_ratio"):  # optional in ContactBody
        if values[key] == "":
            values.pop(key)
    for key, text in values.items():
        if text != "" and _finite(text) is None:
            q.errors[key] = "must be a finite number"
    try:
        body = ContactBody(
            ski="-", grind="-", preset=raw["preset"], ski_model=raw["ski_model"], **values
        )
    except ValidationError as exc:
        for err in exc.errors():
            key = str(err["loc"][0]) if err.get("loc") else "form"
            if key == "porosity" and raw["snow_input"] == "density":
                key = "snow_density_kg_m3"
            reason = err.get("msg", "invalid")
            if err.get("type") == "missing":
                reason = "required"
            q.errors.setdefault(key, reason)
    else:
        q.numbers = body.model_dump(exclude={"ski", "grind"})
    if q.errors and q.status == 200:
        q.status = 422
    return q


def _finite(text: str) -> float | None:
    try:
        v = float(text)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


# ----------------------------------------------------------------------------- computing


class _ResultCache:
    """Thread-safe LRU of :func:`service.contact` answers keyed by the inputs."""

    def __init__(self, maxsize: int = 32) -> None:
        self.maxsize = maxsize
        self._data: OrderedDict[tuple, dict] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: tuple) -> dict | None:
        with self._lock:
            if key in self._data:
                self._data.move_to_end(key)
                return self._data[key]
        return None

    def put(self, key: tuple, value: dict) -> None:
        with self._lock:
            self._data[key] = value
            self._data.move_to_end(key)
            while len(self._data) > self.maxsize:
                self._data.popitem(last=False)


@dataclass
class Outcome:
    """Answers for the combinations that worked, and a message for those that did not."""

    results: list[dict]
    failures: list[tuple[service.ContactInputs, str]]
    wall_ms: float


def compute(cat: service.Catalogue, q: Query, cache: _ResultCache) -> Outcome:
    t0 = time.perf_counter()
    results, failures = [], []
    for inp in q.combinations():
        # keyed on content, not names: a renamed, deleted or re-uploaded item is never served
        # an earlier item's answer
        ski, grind = cat.skis.get(inp.ski), cat.grinds.get(inp.grind)
        key = (astuple(inp), ski and ski.sha256, grind and grind.sha256)
        answer = cache.get(key)
        if answer is None:
            try:
                answer = service.contact(cat, inp)
            except SkisnowError as exc:
                failures.append((inp, str(exc)))
                continue
            cache.put(key, answer)
        results.append(answer)
    return Outcome(results, failures, (time.perf_counter() - t0) * 1e3)


def _failure_field(message: str) -> str:
    """The form field a solver message is about (messages start with the input's name)."""
    first = message.split(" ", 1)[0]
    return first if first in FIELDS else "form"


# ----------------------------------------------------------------------------- HTML


_PAGE = Template(
    resources.files("skisnow.app.web").joinpath("templates/page.html").read_text("utf-8")
)
_CSS = resources.files("skisnow.app.web").joinpath("static/web.css").read_text("utf-8")
_JS = resources.files("skisnow.app.web").joinpath("static/web.js").read_text("utf-8")
_UPLOAD_CSS = resources.files("skisnow.app.web").joinpath("static/upload.css").read_text("utf-8")
_UPLOAD_JS = resources.files("skisnow.app.web").joinpath("static/upload.js").read_text("utf-8")


def _page(
    title: str, body: str, status: int = 200, *, css: str = _CSS, js: str = _JS
) -> HTMLResponse:
    html = _PAGE.substitute(
        title=escape(title), css=css, js=js, body=body, version=service.code_version()
    )
    return HTMLResponse(html, status_code=status)


def _fmt(value, spec: str = "{:.4g}") -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    return spec.format(value)


def _number_field(q: Query, name: str, *, disabled: bool = False) -> str:
    label, unit, hint = FIELDS[name]
    value = q.raw.get(name, "")
    if not value and name not in q.errors:
        value = DEFAULTS[name]
    bounds = ""
    info = ContactBody.model_fields.get(name)
    for c in info.metadata if info else ():
        for attr, html_attr in (("ge", "min"), ("gt", "min"), ("le", "max"), ("lt", "max")):
            if getattr(c, attr, None) is not None:
                bounds += f' {html_attr}="{getattr(c, attr)}"'
    err = q.errors.get(name)
    return (
        f'<div class="field{" has-error" if err else ""}">'
        f'<label for="{name}">{escape(label)} [{unit}]</label>'
        f'<input type="number" step="any" id="{name}" name="{name}" value="{escape(value)}"'
        f"{bounds}{' disabled' if disabled else ''}"
        f"{f' aria-invalid=true aria-describedby={name}-error' if err else ''}>"
        + (f' <span class="error" id="{name}-error">{escape(err)}</span>' if err else "")
        + f'<div class="hint">{escape(hint)}</div></div>'
    )


def _choices(q: Query, kind: str, items: dict, describe, link=None) -> str:
    """Checkboxes of ``items``; ``link(name)``, when given, is an HTML link after each hint."""
    chosen = q.skis if kind == "ski" else q.grinds
    if not chosen and not q.errors:
        chosen = sorted(items)[:1]
    rows = []
    for name in sorted(items):
        rows.append(
            f'<label class="choice"><input type="checkbox" name="{kind}" value="{escape(name)}"'
            f"{' checked' if name in chosen else ''}> <b>{escape(name)}</b>"
            f'<span class="hint">{escape(describe(items[name]))}'
            f"{' · ' + link(name) if link else ''}</span></label>"
        )
    err = q.errors.get(kind)
    if err:
        rows.append(f'<p class="error" id="{kind}-error">{escape(err)}</p>')
    return "".join(rows)


def _describe_ski(ski: service.Ski) -> str:
    """One line per ski in the form: description, length, load positions and the profile model
    that serves it (the name ``GET /v1/skis`` gives)."""
    lo, hi = ski.position_range_m
    model = service.profile_report(ski)["name"] or "none"
    desc = ski.record.metadata.get("description") or ""
    length = ski.record.outline.length_m * 1e3
    return (
        f"{desc + '; ' if desc else ''}length {length:.0f} mm; load positions "
        f"{lo * 1e3:.0f} … {hi * 1e3:.0f} mm; profile model: {model}"
    )


def ski_url(name: str) -> str:
    """The path of a ski's page (the name percent-encoded as one path segment)."""
    return "/skis/" + quote(name, safe="")


def _ski_page_link(name: str) -> str:
    return (
        f'<a class="ski-link" href="{escape(ski_url(name))}" title="the profile model, beam, '
        f'camber and misfit per case of {escape(name)}">ski page</a>'
    )


def _describe_grind(grind: service.Grind) -> str:
    t = grind.table
    sa_m = (t.iso_parameters or {}).get("Sa_m")
    return (
        f"{'Sa ' + format(sa_m * 1e6, '.3g') + ' µm; ' if sa_m is not None else ''}texture pixel "
        f"{t.pixel_size_m * 1e6:.3g} µm; gap floor {t.gap_floor_m * 1e9:.3g} nm"
    )


def _preset_field(q: Query) -> str:
    chosen = q.raw.get("preset") or DEFAULT_PRESET
    options = "".join(
        f'<option value="{name}"{" selected" if name == chosen else ""}>{name} — '
        f"{p.pixel_along_m * 1e3:g} mm × {p.pixels_across} macro pixels</option>"
        for name, p in ACCURACY_PRESETS.items()
    )
    return (
        '<label class="field" for="preset"><span>Accuracy preset</span>'
        f'<select id="preset" name="preset">{options}</select>'
        '<span class="hint">the macro grid\'s error against a converged grid (90th percentile '
        "of the accuracy benchmark): default 1.3 % in apparent area, fine 1.4 % (better but "
        "for a short tip/tail contact) at about 6.5× the time, fast 18 %; every answer shows "
        "its own band (docs/benchmarks.md)"
        "</span></label>"
    )


#: the ski-model choices of the form, with the words a technician reads
SKI_MODEL_LABELS = {
    "auto": "auto — rigid where within 2 % of the bending ski, else bending",
    "rigid": "rigid — the shape on the measuring device (the papers' model)",
    "flexible": "flexible — the ski bends on the snow",
}


def _ski_model_field(q: Query) -> str:
    chosen = q.raw.get("ski_model") or "auto"
    options = "".join(
        f'<option value="{name}"{" selected" if name == chosen else ""}>{escape(label)}</option>'
        for name, label in SKI_MODEL_LABELS.items()
    )
    return (
        '<label class="field" for="ski_model"><span>Ski model</span>'
        f'<select id="ski_model" name="ski_model">{options}</select>'
        '<span class="hint">how far apart the two are over the snow range: '
        "docs/rigid-vs-flexible.md</span></label>"
    )


def render_form(cat: service.Catalogue, q: Query, status: int = 200) -> HTMLResponse:
    alert = ""
    if q.errors:
        items = "".join(
            f"<li><b>{escape(FIELDS.get(k, (k,))[0])}</b>: {escape(v)}</li>"
            for k, v in q.errors.items()
        )
        alert = (
            '<div class="alert" role="alert"><b>Please correct the input:</b>'
            f"<ul>{items}</ul></div>"
        )
    density_mode = q.raw.get("snow_input") == "density"
    advanced = {"base_modulus_mpa", "poisson_ratio", "preset", "ski_model"}
    advanced_open = (
        " open"
        if advanced & set(q.errors)
        or q.raw.get("preset")
        not in (
            None,
            "",
            DEFAULT_PRESET,
        )
        or q.raw.get("ski_model") not in (None, "", "auto")
        else ""
    )
    presets = "\n".join(
        f'<button type="button" {data}>{escape(label)}</button>' for label, data in PRESETS
    )
    body = f"""
<h1>Ski–snow contact for a ski, a grind, a load and a snow</h1>
<p class="hint"><a href="/upload" id="upload-link">Upload your own ski (camber CSV) or grind
(topography)</a></p>
{alert}
<form id="contact-form" method="get" action="/results">
<div class="grid2">
<fieldset><legend>Skis</legend>
{_choices(q, "ski", cat.skis, _describe_ski, _ski_page_link)}</fieldset>
<fieldset><legend>Base grinds</legend>{_choices(q, "grind", cat.grinds, _describe_grind)}</fieldset>
</div>
<div class="grid2">
<fieldset><legend>Load</legend>
{_number_field(q, "body_weight_kg")}
<div class="presets" role="group" aria-label="load presets">
{presets}
</div>
{_number_field(q, "load_kg")}
{_number_field(q, "load_position_mm")}
</fieldset>
<fieldset><legend>Snow</legend>
{_number_field(q, "snow_modulus_mpa")}
<div class="field"><span>Porosity given as:</span>
<label><input type="radio" name="snow_input" value="porosity"{"" if density_mode else " checked"}>
porosity n</label>
<label><input type="radio" name="snow_input" value="density"{" checked" if density_mode else ""}>
snow density ρ</label></div>
{_number_field(q, "porosity", disabled=density_mode)}
{_number_field(q, "snow_density_kg_m3", disabled=not density_mode)}
<div class="hint" id="porosity-from-density" aria-live="polite"></div>
</fieldset>
</div>
<fieldset><details class="advanced"{advanced_open}>
<summary>Advanced: ski-base elasticity, accuracy preset, ski model</summary>
{_number_field(q, "base_modulus_mpa")}
{_number_field(q, "poisson_ratio")}
{_preset_field(q)}
{_ski_model_field(q)}
</details></fieldset>
<button type="submit" id="submit" class="primary">Compute contact</button>
<span class="hint">One ski × grind takes about 25–55 ms on the server with its error band
(median 43 ms with the default ski model, docs/benchmarks.md).</span>
</form>
"""
    return _page("skisnow — contact form", body, status)


#: the band's name of each metric card
BAND_KEYS = {
    "total_real_contact_area_mm2": "total_real_contact_area",
    "average_real_contact_pressure_mpa": "average_real_contact_pressure",
    "min_average_separation_um": "min_average_separation",
    "total_reciprocal_separation_m": "total_reciprocal_separation",
}


def _band_text(w: float | None) -> str:
    """A relative 90 % half-width as the technician reads it."""
    if w is None:
        return "(no band: not grid-converged)"
    return f"± {100 * w:.1f} % (90 %)"


def _interval(band: list | None, value: float) -> str:
    if not band or band[0] is None:
        return f"{value:.4g}"
    return f"{band[0]:.4g} … {band[1]:.4g}"


def _band_note(r: dict) -> str:
    """What the band holds and what it leaves out, in one folded paragraph."""
    b = r.get("band")
    if not b:
        return ""
    parts = "".join(
        f"<li>{escape(src.replace('_', ' '))}: "
        + ", ".join(f"{escape(q.replace('_', ' '))} ±{100 * w:.1f} %" for q, w in ws.items() if w)
        + "</li>"
        for src, ws in b["components"].items()
    )
    missing = "".join(f"<li>{escape(t)}</li>" for t in b["not_covered"])
    cm = b["camber_model"]
    return (
        '<details class="band"><summary>How sure is this? (90 % error band)</summary>'
        f"<p>Sources, combined in quadrature:</p><ul>{parts}</ul>"
        f"<p>Camber model: {escape(cm['source'])}.</p>"
        f"<p>Not in the band:</p><ul>{missing}</ul></details>"
    )


def _metric_cards(results: list[dict]) -> str:
    cards = []
    for r in results:
        inp, m, prov = r["inputs"], r["metrics"], r["provenance"]
        rel = r.get("band", {}).get("relative_half_width", {})
        metrics = "".join(
            f'<div class="metric" data-metric="{key}"><span class="name">{label}</span>'
            f'<span class="value">{_fmt(m[key], spec)}</span><span class="unit">{unit}</span>'
            f'<span class="band">{_band_text(rel.get(BAND_KEYS[key]))}</span></div>'
            for key, label, unit, spec in METRICS
        )
        zones = "".join(
            f'<tr><td class="text">{escape(z["name"])}</td>'
            f'<td class="nowrap">{z["start_mm"]:.0f} … {z["end_mm"]:.0f}</td>'
            f"<td>{100 * z['load_share']:.1f}</td>"
            f"<td>{_interval(z.get('load_band_90_n'), z['load_n'])}</td>"
            f"<td>{z['apparent_area_cm2']:.4g}</td>"
            f"<td>{z['real_area_mm2']:.4g}</td></tr>"
            for z in r["apparent"]["zones"]
        )
        a, table, ski = r["apparent"], prov["table"], prov["ski"]
        warn = "".join(f"<li>{escape(w['detail'])}</li>" for w in r.get("warnings", []))
        if warn:
            warn = (
                '<div class="alert warnings" role="note"><b>Not trustworthy:</b>'
                f"<ul>{warn}</ul></div>"
            )
        cards.append(
            f"""<section class="card"><h3>{escape(inp["ski"])} × {escape(inp["grind"])}</h3>
{warn}<div class="metrics">{metrics}</div>
<p class="summary">Apparent contact {a["contact_area_cm2"]:.4g} cm²
{_band_text(rel.get("apparent_contact_area"))} at a mean apparent pressure of
{a["mean_pressure_kpa"]:.4g} kPa; computed in {r["timing_ms"]["total"]:.0f} ms.</p>
{_band_note(r)}
<div class="table-wrap"><table class="zones"><tr><th class="text">contact zone</th>
<th>from … to X [mm]</th><th>load share [%]</th><th>zone load, 90 % band [N]</th>
<th>apparent area [cm²]</th>
<th>real area [mm²]</th></tr>{zones}</table></div>
<details><summary>Provenance</summary><dl>
<dt>texture table</dt><dd>{escape(table["file"])} · sha256 {table["sha256"][:12]}</dd>
<dt>texture pixel</dt><dd>{table["texture_pixel_size_um"]:.4g} µm</dd>
<dt>gap floor h_c</dt><dd>{table["gap_floor_nm"]:.4g} nm</dd>
<dt>ski file</dt><dd>{escape(ski["file"])} · sha256 {ski["sha256"][:12]}</dd>
<dt>profile model</dt><dd>{escape(str(ski["profile_model"]))} ·
<a href="{escape(ski_url(inp["ski"]))}">ski page</a></dd>
<dt>ski model</dt><dd>{escape(str(prov["ski_model"]["used"]))}:
{escape(str(prov["ski_model"]["reason"]))}</dd>
<dt>macro solve</dt><dd>{prov["macro"]["iterations"]} iterations, converged
{prov["macro"]["converged"]}, pixel {" × ".join(f"{v:g}" for v in prov["macro"]["pixel_size_mm"])}
mm</dd>
<dt>accuracy preset</dt><dd>{escape(str(prov.get("preset", {}).get("name", "default")))}</dd>
<dt>E′ effective</dt><dd>{inp["effective_modulus_mpa"]:.4g} MPa</dd>
<dt>code version</dt><dd>{escape(str(prov["code_version"]))}</dd>
<dt>time</dt><dd>profile {r["timing_ms"]["profile"]:.0f} ms, macro
{r["timing_ms"]["macro"]:.0f} ms, multiscale {r["timing_ms"]["multiscale"]:.0f} ms</dd>
</dl></details></section>"""
        )
    return '<div class="cards">' + "".join(cards) + "</div>"


def _comparison_table(results: list[dict], failures) -> str:
    head = "".join(f"<th>{label} [{unit}]</th>" for _, label, unit, _ in METRICS)
    rows = []
    for r in results:
        m, a = r["metrics"], r["apparent"]
        shares = ", ".join(f"{z['name']} {100 * z['load_share']:.0f}" for z in a["zones"])
        rows.append(
            f'<tr><td class="text">{escape(r["inputs"]["ski"])}</td>'
            f'<td class="text">{escape(r["inputs"]["grind"])}</td>'
            + "".join(f"<td>{_fmt(m[k], spec)}</td>" for k, _, _, spec in METRICS)
            + f"<td>{a['contact_area_cm2']:.4g}</td><td>{a['mean_pressure_kpa']:.4g}</td>"
            f'<td class="text">{escape(shares)}</td>'
            f"<td>{r['timing_ms']['total']:.0f}</td></tr>"
        )
    for inp, msg in failures:
        rows.append(
            f'<tr><td class="text">{escape(inp.ski)}</td><td class="text">{escape(inp.grind)}</td>'
            f'<td class="text error" colspan="{len(METRICS) + 4}">{escape(msg)}</td></tr>'
        )
    return (
        '<div class="table-wrap"><table id="comparison"><tr><th class="text">ski</th>'
        f'<th class="text">grind</th>{head}<th>apparent area [cm²]</th>'
        '<th>mean apparent pressure [kPa]</th><th class="text">zone load shares [%]</th>'
        f"<th>time [ms]</th></tr>{''.join(rows)}</table></div>"
    )


def render_results(q: Query, out: Outcome) -> HTMLResponse:
    n = q.numbers
    link = q.link_query()
    failures = ""
    if out.failures:
        items = "".join(
            f"<li><b>{escape(i.ski)} × {escape(i.grind)}</b>: {escape(m)}</li>"
            for i, m in out.failures
        )
        failures = (
            f'<div class="notice" role="status"><b>Some combinations could not be computed'
            f'</b><ul>{items}</ul><a href="/?{escape(link)}">Change the inputs</a></div>'
        )
    svgs = "".join(
        f'<figure class="plot" id="plot-{key}">{svg}<figcaption>{escape(caption)}</figcaption>'
        "</figure>"
        for key, caption, svg in plots.all_svgs(out.results)
    )
    body = f"""
<h1>Contact results</h1>
<p class="summary">Load {n["load_kg"]:g} kg ({n["load_kg"] * 9.82:.1f} N) at
{n["load_position_mm"]:g} mm from the balance point · snow E {n["snow_modulus_mpa"]:g} MPa,
porosity n = {n["porosity"]:.4g} · base E {n["base_modulus_mpa"]:g} MPa, ν
{n["poisson_ratio"]:g} · {len(out.results)} combination(s) in {out.wall_ms:.0f} ms.</p>
<div class="actions"><a class="button" href="/?{escape(link)}">Change inputs</a>
<a class="button primary" id="csv" href="/results.csv?{escape(link)}" download>Download CSV</a>
</div>
{failures}
<h2>Comparison</h2>
{_comparison_table(out.results, out.failures)}
<h2>Functional parameters per ski × grind</h2>
{_metric_cards(out.results)}
<h2>Along the ski</h2>
<div class="plots">{svgs}</div>
"""
    return _page("skisnow — results", body)


def render_csv(out: Outcome) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for r in out.results:
        inp, m, a, p = r["inputs"], r["metrics"], r["apparent"], r["provenance"]
        share = {"rear": 0.0, "mid": 0.0, "front": 0.0}
        for z in a["zones"]:
            if z["name"] in share:
                share[z["name"]] += z["load_share"]
        row = {
            **{k: inp[k] for k in CSV_COLUMNS[:8]},
            **m,
            "apparent_contact_area_cm2": a["contact_area_cm2"],
            "mean_apparent_pressure_kpa": a["mean_pressure_kpa"],
            **{
                f"{q}_band90_rel": w
                for q, w in r.get("band", {}).get("relative_half_width", {}).items()
            },
            "rear_zone_load_share": share["rear"],
            "mid_zone_load_share": share["mid"],
            "front_zone_load_share": share["front"],
            "ski_model": p["ski_model"]["used"],
            "table_file": p["table"]["file"],
            "table_sha256": p["table"]["sha256"],
            "texture_pixel_size_um": p["table"]["texture_pixel_size_um"],
            "gap_floor_nm": p["table"]["gap_floor_nm"],
            "ski_file": p["ski"]["file"],
            "ski_sha256": p["ski"]["sha256"],
            "code_version": p["code_version"],
            "compute_time_ms": round(r["timing_ms"]["total"], 1),
            "warnings": ";".join(w["code"] for w in r.get("warnings", [])),
            "error": "",
        }
        w.writerow([_csv_value(row.get(c)) for c in CSV_COLUMNS])
    for inp, msg in out.failures:
        row = {k: getattr(inp, k) for k in CSV_COLUMNS[:8]} | {"error": msg}
        w.writerow([_csv_value(row.get(c)) for c in CSV_COLUMNS])
    return buf.getvalue()


def _csv_value(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.8g}" if math.isfinite(v) else ""
    return str(v)


# ----------------------------------------------------------------------------- ski page

#: the served profile models (``GET /v1/skis``'s ``profile_model``) as a technician reads them
PROFILE_MODEL_LABELS = {
    "identified_beam": "beam identified from the ski's camber measurements",
    "network": "camber network trained on the ski's measurements",
    "design_beam": "design beam stored with the ski",
}


def _dl(rows: list[tuple[str, str]]) -> str:
    """A definition list of (term, HTML) rows; the terms are escaped here."""
    return (
        '<dl class="facts">'
        + "".join(f"<dt>{escape(t)}</dt><dd>{v}</dd>" for t, v in rows if v != "")
        + "</dl>"
    )


def _figure_html(key: str, svg: str, caption: str) -> str:
    return (
        f'<figure class="plot" id="plot-{key}">{svg}<figcaption>{escape(caption)}</figcaption>'
        "</figure>"
    )


def _ski_summary(ski: service.Ski) -> str:
    rec = ski.record
    m, o = rec.measurements, rec.outline
    loads_kg = units.n_to_kg(m.loads_n)
    desc = rec.metadata.get("description") or rec.metadata.get("brand_model") or ""
    sides = ", ".join(sorted(set(m.sides)))
    return (
        f'<p class="summary">{escape(desc) + " · " if desc else ""}length '
        f"{o.length_m * 1e3:.0f} mm, running-surface width {o.width_m.min() * 1e3:.3g} … "
        f"{o.width_m.max() * 1e3:.3g} mm · {m.loads_n.size} measured camber profiles "
        f"({escape(sides)}): loads {loads_kg.min():.3g} … {loads_kg.max():.3g} kg at "
        f"{m.load_positions_m.min() * 1e3:.0f} … {m.load_positions_m.max() * 1e3:.0f} mm from the "
        f"balance point, {m.positions_m.size} samples every "
        f"{(m.positions_m[1] - m.positions_m[0]) * 1e3:.3g} mm · file {escape(ski.path.name)} "
        f"(sha256 {escape(ski.sha256[:12])})</p>"
    )


def _identification_section(ident: dict) -> str:
    """Verdict, summary numbers and provenance of the beam identification."""
    verdict = (
        '<p class="ok">The identification passed: the beam fits the camber cases at the device '
        "noise and predicts the held-out cases.</p>"
        if ident["ok"]
        else '<div class="alert" role="note" id="identification-failed"><b>No beam was '
        f"identified:</b> {escape(ident['reason'] or 'no reason recorded')}</div>"
    )
    held = ident["held_out_cases"]
    numbers = (
        ("noise_um", "Device noise σ (from the data)", ident["noise_um"], "µm", "{:.3f}"),
        ("misfit_um", "Misfit, RMS over the identified cases", ident["misfit_um"], "µm", "{:.3f}"),
        ("misfit_to_noise", "Misfit / noise", ident["misfit_to_noise"], "–", "{:.3f}"),
        (
            "held_out_rms_um",
            f"Held-out error, RMS over {held} cases",
            ident["held_out_rms_um"],
            "µm",
            "{:.3f}",
        ),
        ("held_out_to_noise", "Held-out error / noise", ident["held_out_to_noise"], "–", "{:.3f}"),
    )
    cards = "".join(
        f'<div class="metric" data-number="{key}"><span class="name">{escape(label)}</span>'
        f'<span class="value">{_fmt(value, spec)}</span><span class="unit">{unit}</span></div>'
        for key, label, value, unit, spec in numbers
        if value is not None
    )
    cases = len(ident["case_misfit_um"])
    limits = (
        f'<p class="hint">An identified beam serves as the profile model when its misfit is '
        f"within {SERVED_MISFIT_LIMIT:g}× the noise and its held-out error within "
        f"{HELD_OUT_LIMIT:g}× the noise; here {cases} cases were identified and {held} held out "
        "(method.md §4c, docs/camber-identification.md).</p>"
    )
    cards = f'<div class="metrics ski-numbers">{cards}</div>' if cards else ""
    pv = ident.get("provenance", {})
    solve = pv.get("solve_time_s")
    rows = [
        ("created (UTC)", escape(str(pv.get("created_utc", "")))),
        ("code version", escape(str(pv.get("code_version", "")))),
        ("git commit", escape(str(pv.get("git_commit", "")))),
        ("command", escape(str(pv.get("command_line", "")))),
        ("profiles", escape(str(pv.get("profiles") or ""))),
        ("held-out draw seed", escape(str(pv.get("held_out_seed", "")))),
        ("held-out errors", _held_out_origin((ident.get("held_out") or {}).get("provenance"))),
        (
            "fit",
            ""
            if pv.get("iterations") is None
            else f"{pv['iterations']} Gauss–Newton steps over {pv.get('contact_passes')} contact "
            f"passes" + (f", {solve:.1f} s" if solve is not None else ""),
        ),
    ]
    return (
        f'<h2 id="identification">Beam identification</h2>{verdict}'
        f"{cards}{limits}"
        f"<details><summary>Provenance of the identification</summary>{_dl(rows)}</details>"
    )


def _held_out_origin(origin: dict | None) -> str:
    """Where the held-out errors come from: stored in the file (with when and by which command)
    or computed on reading it."""
    if not origin:
        return ""
    when = ", ".join(
        f"{label} {origin[k]}"
        for k, label in (("created_utc", "on"), ("command_line", "by"))
        if origin.get(k)
    )
    text = origin.get("source", "") + (f" ({when})" if when else "")
    return f'<span id="held-out-source">{escape(text)}</span>'


def _beam_table(beam: dict) -> str:
    """EI(X) and c(X) at the points of ``GET /v1/skis/{name}``, with their bands."""
    band = beam.get("bending_stiffness_band_90_nm2")
    cband = beam.get("camber_band_90_um")
    head = "<th>X [mm]</th><th>EI [N·m²]</th>"
    head += "<th>EI 90 % band [N·m²]</th>" if band else ""
    head += "<th>c [µm]</th>" + ("<th>c 90 % band [µm]</th>" if cband else "")
    rows = []
    for i, x in enumerate(beam["position_mm"]):
        cells = f"<td>{_fmt(x, '{:g}')}</td><td>{_fmt(beam['bending_stiffness_nm2'][i], '{:g}')}"
        cells += "</td>"
        if band:
            cells += f"<td>{_fmt(band[0][i], '{:g}')} … {_fmt(band[1][i], '{:g}')}</td>"
        cells += f"<td>{_fmt(beam['camber_um'][i], '{:g}')}</td>"
        if cband:
            cells += f"<td>{_fmt(cband[0][i], '{:g}')} … {_fmt(cband[1][i], '{:g}')}</td>"
        rows.append(f"<tr>{cells}</tr>")
    return (
        f"<details><summary>EI(X) and c(X) at {len(rows)} points (as in the JSON API)</summary>"
        f'<div class="table-wrap"><table id="beam-table"><tr>{head}</tr>{"".join(rows)}'
        "</table></div></details>"
    )


def _misfit_table(ident: dict) -> str:
    """The misfit of every identified case and the error of every held-out case."""
    rows = [
        f'<tr class="identified"><td>{_fmt(f, "{:g}")}</td><td>{_fmt(x, "{:g}")}</td>'
        f'<td>{_fmt(e, "{:g}")}</td><td class="text">identified</td></tr>'
        for f, x, e in zip(
            ident["case_load_kg"], ident["case_position_mm"], ident["case_misfit_um"], strict=True
        )
    ]
    held = ident.get("held_out") or {}
    rows += [
        f'<tr class="held-out"><td>{_fmt(f, "{:g}")}</td><td>{_fmt(x, "{:g}")}</td>'
        f'<td>{_fmt(e, "{:g}")}</td><td class="text">held out</td></tr>'
        for f, x, e in zip(
            held.get("load_kg", []),
            held.get("position_mm", []),
            held.get("error_um", []),
            strict=True,
        )
    ]
    return (
        f"<details><summary>Misfit per case ({len(rows)} cases)</summary>"
        '<div class="table-wrap"><table id="misfit-table"><tr><th>load [kg]</th>'
        '<th>load position [mm]</th><th>RMS misfit [µm]</th><th class="text">case</th></tr>'
        f"{''.join(rows)}</table></div></details>"
    )


def _ski_figures(ski: service.Ski, beam: dict, cache_file=None) -> list[str]:
    """The ski page's figures (EI(X), c(X), misfit per case) with their captions; drawn once
    per ski file and kept (:mod:`app.ski_figures`)."""
    svgs = ski_figures(ski, cache_file)
    if beam.get("bending_stiffness_band_90_nm2"):
        ei_note = "with its 90 % band from the identification's covariance"
        c_note = f"with its 90 % band (± {Z90:.3f} σ of the identification)"
    else:
        ei_note = c_note = "of the design beam stored with the ski: not identified, no band"
    captions = {
        "stiffness": f"Bending stiffness EI(X) [N·m²] {ei_note}",
        "camber": f"Unloaded camber c(X) [mm] {c_note}",
        "misfit": "RMS misfit per camber case [µm] against load [kg] and load position [mm], "
        "with the device noise σ estimated from the data",
    }
    return [_figure_html(k, svgs[k], captions[k]) for k in captions if k in svgs]


def render_ski(cat: service.Catalogue, ski: service.Ski, figure_cache=None) -> HTMLResponse:
    """A ski's page: profile model and why, identification, EI(X), c(X), misfit per case
    (``figure_cache``: the file keeping its figures between processes, or None)."""
    name = ski.name
    profile = service.profile_report(ski)
    beam = service.beam_report(ski)
    ident = beam.get("identification")
    model = profile["name"]
    model_html = (
        f"<code>{escape(model)}</code> — {escape(PROFILE_MODEL_LABELS.get(model, model))}"
        if model
        else "none"
    )
    if beam["available"]:
        beam_html = f"available — {escape(beam['source'])}"
        no_beam = ""
    else:
        beam_html = "none"
        no_beam = (
            '<div class="notice" role="note" id="no-beam"><b>This ski has no beam.</b> '
            f"{escape(beam['source'])}. Contacts use the rigid shape (``auto`` falls back to "
            "it with a warning; ``flexible`` answers 422), and the profile comes from the "
            f"{escape(PROFILE_MODEL_LABELS.get(model, str(model)))}.</div>"
        ).replace("``", "")
    sections = [
        f'<h2 id="profile-model">Profile model</h2>{no_beam}'
        + _dl(
            [
                ("served profile model", model_html),
                ("why", f'<span id="profile-reason">{escape(profile["reason"])}</span>'),
                ("beam for the bending ski", f'<span id="beam-source">{beam_html}</span>'),
            ]
        )
    ]
    if ident:
        sections.append(_identification_section(ident))
    figures = _ski_figures(ski, beam, figure_cache)
    if figures:
        sections.append(
            f'<h2 id="plots">Along the ski and per case</h2><div class="plots">'
            f"{''.join(figures)}</div>"
        )
    tables = (_beam_table(beam) if beam["available"] else "") + (
        _misfit_table(ident) if ident and "case_load_kg" in ident else ""
    )
    if tables:
        sections.append(f"<h2>Numbers</h2>{tables}")
    api = "/v1/skis/" + quote(name, safe="")
    form = "/?" + urlencode(
        [("ski", name)]
        + [(k, DEFAULTS[k]) for k in (*NUMERIC, "snow_input")]
        + [("grind", g) for g in sorted(cat.grinds)[:1]]
    )
    body = f"""
<h1>Ski <span id="ski-name">{escape(name)}</span></h1>
{_ski_summary(ski)}
<div class="actions"><a class="button primary" href="{escape(form)}">Compute a contact with
this ski</a> <a class="button" href="{escape(api)}">The same as JSON</a>
<a class="button" href="/">All skis</a></div>
{"".join(sections)}
"""
    return _page(f"skisnow — ski {name}", body)


def render_unknown_ski(cat: service.Catalogue, name: str, state: str | None) -> HTMLResponse:
    """The 404 page of a ski name the catalogue does not serve."""
    why = (
        f"is an upload that is {escape(state)}, not ready to use"
        if state not in (None, "ready")
        else "is not in the catalogue"
    )
    known = "".join(
        f'<li><a href="{escape(ski_url(n))}">{escape(n)}</a></li>' for n in sorted(cat.skis)
    )
    body = (
        f'<h1>Unknown ski</h1><div class="alert" role="alert">Ski <b id="ski-name">'
        f"{escape(name)}</b> {why}.</div><p>Skis you can open:</p><ul>{known or '<li>none</li>'}"
        '</ul><p><a href="/">Back to the contact form</a> · <a href="/upload">Upload a ski</a></p>'
    )
    return _page("skisnow — unknown ski", body, 404)


# ----------------------------------------------------------------------------- upload page


@dataclass(frozen=True)
class UploadField:
    """One input of an upload form; ``name`` is the multipart field of the REST route."""

    name: str
    label: str
    kind: str = "text"  # text | number | textarea | select | radio | file
    hint: str = ""
    required: bool = False
    options: tuple[tuple[str, str], ...] = ()  # (value, label) of select and radio
    attrs: str = ""
    advanced: bool = False


def _bounds(lo: float, hi: float) -> str:
    return f'step="any" min="{lo:g}" max="{hi:g}"'


_NAME_HINT = "letters, digits, '.', '_' or '-' (at most 64); shown in the contact form"
_NAME_ATTRS = 'maxlength="64" pattern="[A-Za-z0-9][A-Za-z0-9._\\-]{0,63}" autocomplete="off"'

#: the grind form: fields of ``POST /v1/grinds`` (docs/uploads.md)
GRIND_UPLOAD_FIELDS = (
    UploadField(
        "file",
        "Topography file",
        "file",
        "x3p, instrument files (SurfaceTopography formats), or a raw height grid .npy / .csv",
        required=True,
    ),
    UploadField("name", "Grind name", hint=_NAME_HINT, required=True, attrs=_NAME_ATTRS),
    UploadField("shop_code", "Shop code", attrs='maxlength="64"'),
    UploadField("machine", "Grinding machine", attrs='maxlength="128"'),
    UploadField(
        "pattern_family",
        "Pattern family",
        hint="e.g. linear, cross, broken",
        attrs='maxlength="128"',
    ),
    UploadField(
        "coarseness_grade",
        "Coarseness grade",
        hint="e.g. fine, medium, coarse",
        attrs='maxlength="64"',
    ),
    UploadField(
        "temperature_window",
        "Temperature window",
        hint="e.g. −10 … −2 °C",
        attrs='maxlength="64"',
    ),
    UploadField("notes", "Notes", "textarea", attrs='maxlength="2000" rows="3"'),
    UploadField(
        "pixel_size_um",
        "Pixel size [µm]",
        "number",
        "raw grids (.npy, .csv) only: calibrated formats carry their own",
        attrs=_bounds(*uploads.PIXEL_UM_RANGE),
    ),
    UploadField(
        "height_unit",
        "Height unit",
        "select",
        "raw grids (.npy, .csv) only: the unit of the numbers in the file",
        options=(("", "from the file"), ("m", "m"), ("mm", "mm"), ("um", "µm"), ("nm", "nm")),
    ),
    UploadField(
        "along_ski",
        "Ski length along the instrument's",
        "radio",
        options=(("x", "x axis"), ("y", "y axis")),
        advanced=True,
    ),
    UploadField(
        "periodic",
        "Periodic tiling for the solver",
        "select",
        "mirror (default for measured maps), window, or none (docs/topography.md)",
        options=(("mirror", "mirror"), ("window", "window"), ("none", "none")),
        advanced=True,
    ),
    UploadField(
        "detrend",
        "Detrending",
        "select",
        "removed from the heights before the solve; default: the least-squares plane, or the "
        "mean when the tiling is none (a periodic map); recorded with the grind",
        options=(
            ("", "default (plane; mean if tiling is none)"),
            ("plane", "plane"),
            ("mean", "mean"),
            ("none", "none"),
        ),
        advanced=True,
    ),
)

#: the ski form: fields of ``POST /v1/skis`` (docs/uploads.md, the neutral CSV of docs/macro.md)
SKI_UPLOAD_FIELDS = (
    UploadField(
        "file",
        "Camber CSV",
        "file",
        "the neutral camber CSV (docs/macro.md): gaps per position for every load case",
        required=True,
        attrs='accept=".csv,.txt,text/csv"',
    ),
    UploadField("name", "Ski name", hint=_NAME_HINT, required=True, attrs=_NAME_ATTRS),
    UploadField("brand_model", "Brand / model", attrs='maxlength="128"'),
    UploadField(
        "length_mm",
        "Ski length [mm]",
        "number",
        required=True,
        attrs=_bounds(*uploads.SKI_LENGTH_MM_RANGE),
    ),
    UploadField(
        "width_mm",
        "Running-surface width [mm]",
        hint="one width, or a comma-separated list with the positions below",
        required=True,
        attrs='inputmode="decimal"',
    ),
    UploadField("style", "Style", "radio", options=(("classic", "classic"), ("skate", "skate"))),
    UploadField("owner_team", "Owner / team", attrs='maxlength="64"'),
    UploadField("notes", "Notes", "textarea", attrs='maxlength="2000" rows="3"'),
    UploadField(
        "width_positions_mm",
        "Width positions [mm]",
        hint="from the balance point, one per width, increasing",
        advanced=True,
    ),
)

#: (kind, job kind of app.uploads, REST route, form fields, title)
UPLOAD_FORMS = (
    ("grind", uploads.GRIND_JOB, "/v1/grinds", GRIND_UPLOAD_FIELDS, "Grind: topography"),
    ("ski", uploads.SKI_JOB, "/v1/skis", SKI_UPLOAD_FIELDS, "Ski: camber measurements"),
)


def _upload_input(kind: str, f: UploadField) -> str:
    fid = f"{kind}-{f.name}"
    req = " required" if f.required else ""
    common = f'id="{fid}" name="{f.name}" aria-describedby="{fid}-error"{req}'
    if f.kind == "textarea":
        control = f"<textarea {common} {f.attrs}></textarea>"
    elif f.kind == "select":
        opts = "".join(
            f'<option value="{escape(v)}">{escape(label)}</option>' for v, label in f.options
        )
        control = f"<select {common}>{opts}</select>"
    elif f.kind == "radio":
        control = "".join(
            f'<label class="inline"><input type="radio" name="{f.name}" value="{escape(v)}"'
            f"{' checked' if i == 0 else ''}> {escape(label)}</label>"
            for i, (v, label) in enumerate(f.options)
        )
        return (
            f'<div class="field" data-field="{f.name}" role="radiogroup" id="{fid}"'
            f' aria-describedby="{fid}-error"><span class="label">{escape(f.label)}</span> '
            f'{control} <span class="error" id="{fid}-error" hidden></span>'
            + (f'<div class="hint">{escape(f.hint)}</div>' if f.hint else "")
            + "</div>"
        )
    else:
        control = f'<input type="{f.kind}" {common} {f.attrs}>'
    return (
        f'<div class="field" data-field="{f.name}"><label for="{fid}">{escape(f.label)}'
        f"{' <abbr title=required>*</abbr>' if f.required else ''}</label>{control}"
        f' <span class="error" id="{fid}-error" hidden></span>'
        + (f'<div class="hint">{escape(f.hint)}</div>' if f.hint else "")
        + "</div>"
    )


def _return_query(cat: service.Catalogue, kind: str) -> str:
    """The contact form's query that the done link extends with ``&{kind}=NAME``: the other
    kind's first item and the default load and snow."""
    other, items = ("ski", cat.skis) if kind == "grind" else ("grind", cat.grinds)
    pairs = [(other, n) for n in sorted(items)[:1]]
    pairs += [(k, DEFAULTS[k]) for k in (*NUMERIC, "snow_input", "body_weight_kg")]
    return urlencode(pairs)


def render_upload(cat: service.Catalogue, settings) -> HTMLResponse:
    """The upload page: a grind form and a ski form, each with its job panel."""
    token = bool(settings.team_tokens)
    max_mib = settings.max_upload_bytes / 2**20
    sections = []
    for kind, job_kind, route, fields, title in UPLOAD_FORMS:
        basic = "".join(_upload_input(kind, f) for f in fields if not f.advanced)
        advanced = "".join(_upload_input(kind, f) for f in fields if f.advanced)
        token_field = (
            f'<div class="field"><label for="{kind}-token">Team token</label>'
            f'<input type="password" id="{kind}-token" data-token autocomplete="off">'
            '<div class="hint">uploads need your team\'s bearer token</div></div>'
            if token
            else ""
        )
        item_link = (
            f' <a class="button item-link" id="{kind}-item-link" hidden href="/">Open the '
            "ski's page</a>"
            if kind == "ski"
            else ""
        )
        sections.append(
            f"""<section class="upload" id="{kind}-upload">
<h2>{escape(title)}</h2>
<form id="{kind}-form" class="upload-form" method="post" action="{route}"
 enctype="multipart/form-data" novalidate data-kind="{kind}" data-job-kind="{job_kind}"
 data-max-bytes="{settings.max_upload_bytes}" data-return="/?{escape(_return_query(cat, kind))}">
<div class="alert" id="{kind}-alert" role="alert" hidden></div>
{basic}
<details class="advanced"><summary>Advanced</summary>{advanced}</details>
{token_field}
<button type="submit" class="primary" id="{kind}-submit">Upload {kind}</button>
<span class="hint">files up to {max_mib:.3g} MiB; checked at once, then processed in the
background</span>
</form>
<div class="job" id="{kind}-job" hidden aria-live="polite">
<h3>Job <code class="job-id"></code></h3>
<p class="accepted"></p>
<progress max="1" value="0" id="{kind}-progress"></progress>
<span class="percent">0 %</span>
<p>State: <b class="state" id="{kind}-job-state">queued</b> <span class="message"></span></p>
<p class="error job-error" role="alert" hidden></p>
<p class="actions"><a class="button primary done-link" id="{kind}-done-link" hidden href="/">
Use it in the contact form</a>{item_link}</p>
</div>
</section>"""
        )
    ski_pages = " · ".join(
        f'<a href="{escape(ski_url(n))}">{escape(n)}</a>' for n in sorted(cat.skis)
    )
    body = f"""
<h1>Upload a ski or a grind</h1>
<p class="summary">The file is checked at once; a background job then builds the grind's lookup
table, or trains the ski's camber network and identifies its beam (progress below). When it is
done the item is in the <a href="/">contact form</a> and the JSON API (docs/uploads.md), and a
ski has its own page.</p>
<p class="hint" id="ski-pages">Ski pages (profile model, beam, misfit per case):
{ski_pages or "none yet"}</p>
<noscript><p class="alert">This page needs JavaScript to upload and to follow the job; the
REST API (<a href="/docs">/docs</a>) does the same.</p></noscript>
<div class="grid2">{"".join(sections)}</div>
"""
    return _page("skisnow — upload", body, css=_CSS + _UPLOAD_CSS, js=_UPLOAD_JS)


# ----------------------------------------------------------------------------- routes


def mount(app: FastAPI) -> None:
    """Add the web-form routes to ``app``."""
    cache = _ResultCache()

    def _named_catalogue(request: Request) -> service.Catalogue:
        qp = request.query_params
        return visible_catalogue(request, skis=qp.getlist("ski"), grinds=qp.getlist("grind"))

    def _query(request: Request, cat: service.Catalogue) -> Query:
        return parse_query(request, cat, request.app.state.settings.max_compare_cells)

    @app.get("/", response_class=HTMLResponse, include_in_schema=False)
    def form(request: Request) -> HTMLResponse:
        cat = _named_catalogue(request)
        q = _query(request, cat)
        if not request.query_params:
            q.errors.clear()
        # a pre-filled form shows only the errors of what was given
        elif not q.skis and not q.grinds:
            q.errors.pop("ski", None)
            q.errors.pop("grind", None)
        return render_form(cat, q)

    @app.get("/results", response_class=HTMLResponse, include_in_schema=False)
    def results(request: Request) -> HTMLResponse:
        cat = _named_catalogue(request)
        q = _query(request, cat)
        if not q.ok:
            return render_form(cat, q, q.status)
        out = compute(cat, q, cache)
        if not out.results:
            for inp, msg in out.failures:
                q.errors.setdefault(_failure_field(msg), f"{inp.ski} × {inp.grind}: {msg}")
            return render_form(cat, q, 422)
        return render_results(q, out)

    @app.get("/skis/{name:path}", response_class=HTMLResponse, include_in_schema=False)
    def ski_page(request: Request, name: str) -> HTMLResponse:
        cat = visible_catalogue(request, skis=[name])
        ski = cat.skis.get(name)
        if ski is None:
            state = None
            uploads_state = getattr(request.app.state, "uploads", None)
            if uploads_state is not None:
                row = uploads_state.db.item_by_name("ski", name)
                if row is not None and caller(request).sees(row.team, row.read_only):
                    state = row.state
            return render_unknown_ski(cat, name, state)
        settings = getattr(request.app.state, "settings", None)
        cache = None
        if settings is not None:
            cache = uploads.Layout(Path(settings.data_dir)).ski_figures(ski.path.stem)
        return render_ski(cat, ski, cache)

    @app.get("/upload", response_class=HTMLResponse, include_in_schema=False)
    def upload(request: Request) -> HTMLResponse:
        return render_upload(visible_catalogue(request), request.app.state.settings)

    @app.get("/results.csv", include_in_schema=False)
    def results_csv(request: Request) -> Response:
        cat = _named_catalogue(request)
        q = _query(request, cat)
        if not q.ok:
            return render_form(cat, q, q.status)
        out = compute(cat, q, cache)
        return Response(
            render_csv(out),
            media_type="text/csv; charset=utf-8",
            headers={"Content-Disposition": 'attachment; filename="skisnow-contact.csv"'},
        )
