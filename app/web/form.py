"""The contact form at ``/``: its fields, the validation of its query and its page.

The query is validated with the bounds of :class:`app.bounds.CaseInputs` (plus the snow
density's, :func:`porosity_from_density`); bad input re-shows the form with a message next to
the offending field (422; 404 for an unknown ski or grind). Query parameters, if any, pre-fill
the form. With team tokens the page shows what :func:`app.api.access.visible_catalogue` lets the
request see.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from urllib.parse import parse_qs, quote, unquote, urlencode

from fastapi import Request
from fastapi.responses import HTMLResponse
from pydantic import ValidationError
from skisnow.app import service
from skisnow.app.bounds import CaseInputs, out_of_bounds_message
from skisnow.app.presets import DEFAULT_PRESET
from skisnow.app.presets import PRESETS as ACCURACY_PRESETS
from skisnow.app.snow import DEFAULT_SNOW, SNOW_PRESETS, snow_choices
from skisnow.app.web.templating import page

#: density of ice used to turn snow density into porosity, n = 1 − ρ/ρ_ice [kg/m³]
ICE_DENSITY_KG_M3 = 917.0

#: the published case (docs/physics.md §2): 40 kg at 160 mm behind the balance point, E_snow 200 MPa
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

#: load presets: (button label, data attributes ``data-NAME`` read by static/web.js)
PRESETS = (
    ("½ body weight at −80 mm", (("body-fraction", "0.5"), ("position-mm", "-80"))),
    ("Full body weight at −150 mm", (("body-fraction", "1"), ("position-mm", "-150"))),
    ("Published case: 40 kg at −160 mm", (("load-kg", "40"), ("position-mm", "-160"))),
)

#: (query name, label, unit, hint) of the numeric inputs; names are those of CaseInputs
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

#: the snow numbers a snow preset sets (shown, disabled, in the form)
SNOW_NUMBERS = {
    "snow_modulus_mpa": lambda p: f"{p.snow_modulus_mpa:g}",
    "porosity": lambda p: f"{p.porosity:g}",
    "snow_density_kg_m3": lambda p: f"{p.density_kg_m3:g}",
}

#: numeric inputs passed on to CaseInputs / service.ContactInputs
NUMERIC = (
    "load_kg",
    "load_position_mm",
    "snow_modulus_mpa",
    "porosity",
    "base_modulus_mpa",
    "poisson_ratio",
)

#: the ski-model choices of the form, with the words a technician reads
SKI_MODEL_LABELS = {
    "auto": "auto — rigid where within 2 % of the bending ski, else bending",
    "rigid": "rigid — the shape on the measuring device (the papers' model)",
    "flexible": "flexible — the ski bends on the snow",
}


#: pydantic's error types of a number outside its bounds
BOUND_ERRORS = ("greater_than", "greater_than_equal", "less_than", "less_than_equal")


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
    #: the skis and grinds of the last results page this browser showed (cookie)
    last: dict[str, list[str]] = field(default_factory=dict)

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


def porosity_from_density(text: str) -> tuple[str | None, str | None]:
    """The porosity (as text for :class:`CaseInputs`) of a snow density [kg/m³] typed in the
    form, or the error message: the one bound the form checks itself (the others are
    :class:`CaseInputs`'s)."""
    rho = _finite(text)
    if rho is None or not 0 <= rho < ICE_DENSITY_KG_M3:
        return None, f"snow density must be a number from 0 to below {ICE_DENSITY_KG_M3:g} kg/m³"
    return str(1.0 - rho / ICE_DENSITY_KG_M3), None


def parse_query(request: Request, cat: service.Catalogue, max_cells: int) -> Query:
    """Read and validate the form's query parameters (bounds of :class:`CaseInputs`)."""
    qp = request.query_params
    raw = {k: qp.get(k, "").strip() for k in (*FIELDS, "snow_input", "preset", "ski_model")}
    raw["snow"] = chosen_snow(qp)
    q = Query(_unique(qp.getlist("ski")), _unique(qp.getlist("grind")), raw)
    q.last = last_used(request)
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
    snow = {}
    if raw["snow"] and raw["snow"] not in SNOW_PRESETS:
        q.errors["snow"] = f"unknown snow {raw['snow']!r}; choose {', '.join(SNOW_PRESETS)}"
        raw["snow"] = ""
    if raw["snow"]:  # a named snow: its numbers, the fields were not sent (disabled)
        snow = {"snow": raw["snow"]}
        for key in ("snow_modulus_mpa", "porosity"):
            values.pop(key)
            raw[key] = ""
        raw["snow_density_kg_m3"] = ""
    elif raw["snow_input"] == "density":
        values.pop("porosity")
        porosity, error = porosity_from_density(raw["snow_density_kg_m3"])
        if error:
            q.errors["snow_density_kg_m3"] = error
        else:
            values["porosity"] = porosity
    for key in ("base_modulus_mpa", "poisson_ratio"):  # optional in CaseInputs
        if values[key] == "":
            values.pop(key)
    for key, text in values.items():
        if text != "" and _finite(text) is None:
            q.errors[key] = "must be a finite number"
    try:
        body = CaseInputs(preset=raw["preset"], ski_model=raw["ski_model"], **snow, **values)
    except ValidationError as exc:
        for err in exc.errors():
            key = str(err["loc"][0]) if err.get("loc") else "form"
            if key == "porosity" and raw["snow_input"] == "density":
                key = "snow_density_kg_m3"
            reason = err.get("msg", "invalid")
            if err.get("type") == "missing":
                reason = "required"
            elif err.get("type") in BOUND_ERRORS:  # pydantic's words → plain ones
                reason = out_of_bounds_message(str(err["loc"][0]), _finite(str(err.get("input"))))
            q.errors.setdefault(key, reason)
    else:
        q.numbers = body.model_dump()
    if q.errors and q.status == 200:
        q.status = 422
    return q


def chosen_snow(qp) -> str:
    """The snow preset a query names: ``snow`` when given (empty: custom numbers); without it,
    custom when a snow number is given (links from before the presets), else the default."""
    if "snow" in qp:
        return qp.get("snow", "").strip()
    if any(qp.get(k, "").strip() for k in ("snow_modulus_mpa", "porosity", "snow_density_kg_m3")):
        return ""
    return DEFAULT_SNOW


def _finite(text: str) -> float | None:
    try:
        v = float(text)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def failure_field(message: str) -> str:
    """The form field a solver message is about (messages start with the input's name)."""
    first = message.split(" ", 1)[0]
    return first if first in FIELDS else "form"


# ----------------------------------------------------------------------------- page


def ski_url(name: str) -> str:
    """The path of a ski's page (the name percent-encoded as one path segment)."""
    return "/skis/" + quote(name, safe="")


def _number_field(q: Query, name: str, *, disabled: bool = False) -> dict:
    """What ``form_macros.number_field`` shows of input ``name``; HTML min/max are the bounds of
    :class:`CaseInputs`."""
    label, unit, hint = FIELDS[name]
    value = q.raw.get(name, "")
    preset = SNOW_PRESETS.get(q.raw.get("snow") or "")
    if preset is not None and name in SNOW_NUMBERS:
        value = str(SNOW_NUMBERS[name](preset))
        disabled = True
    if not value and name not in q.errors:
        value = DEFAULTS[name]
    bounds = []
    info = CaseInputs.model_fields.get(name)
    for c in info.metadata if info else ():
        for attr, html_attr in (("ge", "min"), ("gt", "min"), ("le", "max"), ("lt", "max")):
            if getattr(c, attr, None) is not None:
                bounds.append((html_attr, getattr(c, attr)))
    return {
        "name": name,
        "label": label,
        "unit": unit,
        "hint": hint,
        "value": value,
        "bounds": bounds,
        "disabled": disabled,
        "error": q.errors.get(name),
    }


#: the cookie that remembers the skis and grinds of the last results page (a query string)
LAST_USED_COOKIE = "skisnow_last"


def last_used(request: Request) -> dict[str, list[str]]:
    """The skis and grinds of the last results page this browser showed (its cookie)."""
    text = unquote(request.cookies.get(LAST_USED_COOKIE, ""))
    pairs = parse_qs(text, keep_blank_values=False)
    return {kind: _unique(pairs.get(kind, []))[:16] for kind in ("ski", "grind")}


def last_used_cookie(q: Query) -> str:
    """The cookie value that makes ``q``'s skis and grinds the form's next defaults."""
    return quote(urlencode([("ski", s) for s in q.skis] + [("grind", g) for g in q.grinds]))


def default_choice(kind: str, items: dict, shipped_dir, last: list[str]) -> list[str]:
    """What the form pre-checks when the query names no ``kind``: the last ones used (cookie)
    that still exist, else the first shipped item by name (never an upload just because its
    name sorts first: an upload named ``Grind-1`` became every technician's default), else the
    first item."""
    known = [name for name in last if name in items]
    if known:
        return known
    shipped = sorted(n for n, obj in items.items() if _is_shipped(obj, shipped_dir))
    return (shipped or sorted(items))[:1]


def _is_shipped(obj, shipped_dir) -> bool:
    try:
        return Path(obj.path).resolve().is_relative_to(Path(shipped_dir).resolve())
    except (OSError, TypeError, ValueError):
        return False


def upload_labels(request: Request) -> dict[tuple[str, str], str]:
    """``(kind, name)`` → the metadata line of each ready upload (shop, machine, brand…), so
    uploads are told apart from the shipped items and from each other on the pages."""
    state = getattr(request.app.state, "uploads", None)
    if state is None:
        return {}
    out = {}
    for row in state.db.items(state="ready"):
        if not row.read_only:
            out[(row.kind, row.name)] = metadata_label(row.kind, row.metadata)
    return out


#: (metadata key, words) shown for uploads, in this order
_LABEL_KEYS = {
    "grind": (
        ("shop_code", "shop"),
        ("machine", "machine"),
        ("pattern_family", "pattern"),
        ("coarseness_grade", "grade"),
        ("temperature_window", "for"),
    ),
    "ski": (("brand_model", "brand"), ("style", "style"), ("owner_team", "team")),
}


def metadata_label(kind: str, metadata: dict) -> str:
    """ "uploaded; shop S1; machine Wintersteiger" from an upload's metadata (empty fields left
    out)."""
    parts = ["uploaded"]
    for key, words in _LABEL_KEYS.get(kind, ()):
        value = str(metadata.get(key) or "").strip()
        if value:
            parts.append(f"{words} {value}")
    return "; ".join(parts)


def _choices(
    q: Query,
    kind: str,
    items: dict,
    describe,
    pages: bool = False,
    *,
    shipped_dir=None,
    labels: dict | None = None,
) -> dict:
    """The checkboxes of ``items``; ``pages``: each links to its ski page. With nothing chosen,
    :func:`default_choice` pre-checks one; ``labels``: upload metadata lines by name."""
    chosen = q.skis if kind == "ski" else q.grinds
    if not chosen and not q.errors:
        chosen = default_choice(kind, items, shipped_dir, q.last.get(kind, []))
    labels = labels or {}
    return {
        "kind": kind,
        "options": [
            {
                "name": name,
                "checked": name in chosen,
                "description": "; ".join(
                    x for x in (labels.get((kind, name)), describe(items[name])) if x
                ),
                "page": ski_url(name) if pages else None,
            }
            for name in sorted(items)
        ],
        "error": q.errors.get(kind),
    }


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


def _describe_grind(grind: service.Grind) -> str:
    t = grind.table
    sa_m = (t.iso_parameters or {}).get("Sa_m")
    kind = str(t.attrs.get("texture_provenance") or "synthetic").split(":")[0]
    return (
        f"{kind}; {'Sa ' + format(sa_m * 1e6, '.3g') + ' µm; ' if sa_m is not None else ''}"
        "texture pixel "
        f"{t.pixel_size_m * 1e6:.3g} µm; gap floor {t.gap_floor_m * 1e9:.3g} nm"
    )


def render_form(
    request: Request, cat: service.Catalogue, q: Query, status: int = 200
) -> HTMLResponse:
    density_mode = q.raw.get("snow_input") == "density"
    labels = upload_labels(request)
    advanced = {"base_modulus_mpa", "poisson_ratio", "preset", "ski_model"}
    advanced_open = (
        bool(advanced & set(q.errors))
        or q.raw.get("preset") not in (None, "", DEFAULT_PRESET)
        or q.raw.get("ski_model") not in (None, "", "auto")
    )
    fields = {
        name: _number_field(
            q,
            name,
            disabled=(name == "porosity" and density_mode)
            or (name == "snow_density_kg_m3" and not density_mode),
        )
        for name in FIELDS
    }
    return page(
        request,
        "form.html",
        "skisnow — contact form",
        status,
        errors=[(FIELDS.get(k, (k,))[0], v) for k, v in q.errors.items()],
        skis=_choices(
            q,
            "ski",
            cat.skis,
            _describe_ski,
            pages=True,
            shipped_dir=cat.tables_dir,
            labels=labels,
        ),
        grinds=_choices(
            q, "grind", cat.grinds, _describe_grind, shipped_dir=cat.tables_dir, labels=labels
        ),
        fields=fields,
        load_presets=PRESETS,
        density_mode=density_mode,
        advanced_open=advanced_open,
        accuracy_presets=list(ACCURACY_PRESETS.items()),
        preset=q.raw.get("preset") or DEFAULT_PRESET,
        ski_models=list(SKI_MODEL_LABELS.items()),
        ski_model=q.raw.get("ski_model") or "auto",
        snow_choices=snow_choices(),
        snow_presets=[p.as_json() for p in SNOW_PRESETS.values()],
        snow=q.raw.get("snow", DEFAULT_SNOW),
        snow_error=q.errors.get("snow"),
    )
