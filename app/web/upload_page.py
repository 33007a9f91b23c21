"""The upload page ``/upload``: a grind form and a ski form, each with its job panel.

The two forms post multipart to the REST routes (``POST /v1/skis``, ``POST /v1/grinds``, checks
in :mod:`app.jobs.uploads`) from ``static/upload.js``, show the problem+json errors next to the
field
they name, then follow the job (``GET /v1/jobs/{id}`` every second) with a progress bar and,
when it is done, link back to the form with the new item selected (and, for a ski, to its page
``/skis/{name}``). The ski form states the smallest grid that gets a served beam and links an
example CSV (:func:`example_camber_csv`); the uploads whose job failed are listed with their
reason and a delete button (``static/delete.js``, ``DELETE /v1/{skis|grinds}/{name}``), as is
the item of a job that fails while the page follows it. This page is the one that needs
JavaScript (uploads are multipart, progress needs polling). The upload checks and jobs are not
here: only the page.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from urllib.parse import quote, urlencode

import numpy as np
from fastapi import Request
from fastapi.responses import HTMLResponse
from skisnow.app import service
from skisnow.app.jobs import uploads
from skisnow.app.web.form import DEFAULTS, NUMERIC, ski_url
from skisnow.app.web.templating import CSS, DELETE_JS, UPLOAD_CSS, UPLOAD_JS, page


@dataclass(frozen=True)
class UploadField:
    """One input of an upload form; ``name`` is the multipart field of the REST route."""

    name: str
    label: str
    kind: str = "text"  # text | number | textarea | select | radio | file
    hint: str = ""
    required: bool = False
    options: tuple[tuple[str, str], ...] = ()  # (value, label) of select and radio
    attrs: tuple[tuple[str, str], ...] = ()  # (name, value) HTML attributes of the input
    advanced: bool = False


def _bounds(lo: float, hi: float) -> tuple[tuple[str, str], ...]:
    return (("step", "any"), ("min", f"{lo:g}"), ("max", f"{hi:g}"))


def _maxlength(n: int, *more: tuple[str, str]) -> tuple[tuple[str, str], ...]:
    return (("maxlength", str(n)), *more)


_NAME_HINT = "letters, digits, '.', '_' or '-' (at most 64); shown in the contact form"
_NAME_ATTRS = _maxlength(
    64, ("pattern", "[A-Za-z0-9][A-Za-z0-9._\\-]{0,63}"), ("autocomplete", "off")
)

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
    UploadField("shop_code", "Shop code", attrs=_maxlength(64)),
    UploadField("machine", "Grinding machine", attrs=_maxlength(128)),
    UploadField(
        "pattern_family",
        "Pattern family",
        hint="e.g. linear, cross, broken",
        attrs=_maxlength(128),
    ),
    UploadField(
        "coarseness_grade",
        "Coarseness grade",
        hint="e.g. fine, medium, coarse",
        attrs=_maxlength(64),
    ),
    UploadField(
        "temperature_window",
        "Temperature window",
        hint="e.g. −10 … −2 °C",
        attrs=_maxlength(64),
    ),
    UploadField("notes", "Notes", "textarea", attrs=_maxlength(2000, ("rows", "3"))),
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
        "raw grids (.npy, a plain text grid), x y z lists and TrueMap .tmd only: the unit of "
        "the numbers in the file (calibrated files refuse it)",
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
        "reduce",
        "Reduction of a large map",
        "select",
        "a map too large for the solver is block-averaged (default; keeps the contact area "
        "closest), cropped to a centred window, or refused (docs/topography.md)",
        options=(("block", "block average"), ("crop", "centred crop"), ("none", "none")),
        advanced=True,
    ),
    UploadField(
        "detrend",
        "Detrending",
        "select",
        "removed from the measured heights before the solve; default: the least-squares "
        "plane, whatever the tiling; recorded with the grind",
        options=(
            ("", "default (plane)"),
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
        attrs=(("accept", ".csv,.txt,text/csv"),),
    ),
    UploadField("name", "Ski name", hint=_NAME_HINT, required=True, attrs=_NAME_ATTRS),
    UploadField("brand_model", "Brand / model", attrs=_maxlength(128)),
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
        attrs=(("inputmode", "decimal"),),
    ),
    UploadField("style", "Style", "radio", options=(("classic", "classic"), ("skate", "skate"))),
    UploadField("owner_team", "Owner / team", attrs=_maxlength(64)),
    UploadField("notes", "Notes", "textarea", attrs=_maxlength(2000, ("rows", "3"))),
    UploadField(
        "width_positions_mm",
        "Width positions [mm]",
        hint="from the balance point, one per width, increasing",
        advanced=True,
    ),
    UploadField(
        "unmeasured",
        "Unmeasured samples",
        "select",
        "samples without a gap (an empty cell, NaN, -, #N/A; a row a case leaves out of the "
        "positions the other cases list): near the tip or tail their "
        "positions are dropped from every case, inside the span their case is left out, "
        "whichever sets aside fewer samples (default; nothing is filled in; recorded with the "
        "ski), or the file is refused",
        options=(("drop", "drop their positions or cases"), ("refuse", "refuse the file")),
        advanced=True,
    ),
)

#: the example camber CSV of the upload page (:func:`example_camber_csv`)
EXAMPLE_CSV_URL = "/upload/example-camber.csv"
#: shipped demo ski it is sub-sampled from, its loads [kg], load positions [mm], step [mm]
EXAMPLE_SKI = "ski-a"
EXAMPLE_LOADS_KG = (10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0)
EXAMPLE_LOAD_POSITIONS_MM = (-300.0, -200.0, -100.0, 0.0, 100.0)
EXAMPLE_STEP_MM = 5.0
#: the demo ski's length, the example's length_mm [mm]
EXAMPLE_LENGTH_MM = 2000.0


@functools.lru_cache(maxsize=1)
def example_camber_csv() -> str:
    """A realistic camber-device file in the neutral format, from shipped demo ski A's
    measurements: the unloaded profile (0 kg) first, then :data:`EXAMPLE_LOADS_KG` ×
    :data:`EXAMPLE_LOAD_POSITIONS_MM`, sampled every :data:`EXAMPLE_STEP_MM` mm (every 5th
    sample of the 1 mm shipped grid; the gaps as measured, 0.1 µm rounding).

    The unloaded profile is the shipped one when the demo file has it (a case with F = 0);
    otherwise it is measured from the demo ski's beam by the same virtual device and noise
    (:func:`solvers.beam.measure_unloaded`, the ski's ``noise_m``, seed = the ski's seed + 1;
    docs/uploads.md says so).
    """
    from skisnow.app.storage.skis import (
        SHIPPED_SKI_DIR,
        CamberData,
        camber_csv_text,
        read_ski,
        unloaded_mask,
    )
    from skisnow.solvers.beam import G_STANDARD, measure_unloaded

    rec = read_ski(SHIPPED_SKI_DIR / f"{EXAMPLE_SKI}.h5")
    m = rec.measurements
    x_mm = m.positions_m * 1e3
    step = np.round(np.diff(x_mm).min(), 9)
    sel = np.arange(0, x_mm.size, round(float(EXAMPLE_STEP_MM / step)))
    kg = np.round(m.loads_n / G_STANDARD, 6)
    xf = np.round(m.load_positions_m * 1e3, 6)
    cases = []
    for load in EXAMPLE_LOADS_KG:
        for pos in EXAMPLE_LOAD_POSITIONS_MM:
            hit = np.flatnonzero((kg == load) & (xf == pos) & (np.asarray(m.sides) == "mean"))
            if hit.size != 1:
                raise LookupError(f"{EXAMPLE_SKI}: no single case {load:g} kg at {pos:g} mm")
            cases.append(int(hit[0]))
    unloaded = np.flatnonzero(unloaded_mask(m))
    if unloaded.size:
        zero = m.profiles_m[unloaded[0]]
    else:
        seed = int(rec.metadata.get("seed", 0)) + 1
        zero = measure_unloaded(rec.beam, noise_m=float(rec.metadata["noise_m"]), rng=seed)
        zero = np.interp(m.positions_m, rec.beam.positions_m, zero)
    data = CamberData(
        f"example-{EXAMPLE_SKI}",
        m.positions_m[sel],
        np.concatenate([[0.0], m.loads_n[cases]]),
        np.concatenate([[0.0], m.load_positions_m[cases]]),
        ["mean"] * (1 + len(cases)),
        np.vstack([zero[sel], m.profiles_m[cases][:, sel]]),
    )
    return camber_csv_text(data)


#: (kind, job kind of app.jobs.uploads, REST route, form fields, title)
UPLOAD_FORMS = (
    ("grind", uploads.GRIND_JOB, "/v1/grinds", GRIND_UPLOAD_FIELDS, "Grind: topography"),
    ("ski", uploads.SKI_JOB, "/v1/skis", SKI_UPLOAD_FIELDS, "Ski: camber measurements"),
)


def _return_query(cat: service.Catalogue, kind: str) -> str:
    """The contact form's query that the done link extends with ``&{kind}=NAME``: the other
    kind's first item and the default load and snow."""
    other, items = ("ski", cat.skis) if kind == "grind" else ("grind", cat.grinds)
    pairs = [(other, n) for n in sorted(items)[:1]]
    pairs += [(k, DEFAULTS[k]) for k in (*NUMERIC, "snow_input", "body_weight_kg")]
    return urlencode(pairs)


def render_upload(request: Request, cat: service.Catalogue, settings) -> HTMLResponse:
    """The upload page: a grind form and a ski form, each with its job panel."""
    forms = [
        {
            "kind": kind,
            "job_kind": job_kind,
            "route": route,
            "fields": fields,
            "title": title,
            "return_query": _return_query(cat, kind),
        }
        for kind, job_kind, route, fields, title in UPLOAD_FORMS
    ]
    from skisnow.app.api.access import caller, failed_views

    failed = [
        (kind, {**item, "delete_url": f"/v1/{kind}s/{quote(item['name'], safe='')}"})
        for kind in ("ski", "grind")
        for item in failed_views(request, kind)
    ]
    return page(
        request,
        "upload.html",
        "skisnow — upload",
        css=CSS + UPLOAD_CSS,
        js=UPLOAD_JS + DELETE_JS,
        failed=failed,
        forms=forms,
        # logged in (the login cookie): the page's requests carry the team's token already
        token=bool(settings.team_tokens) and caller(request).team is None,
        max_bytes=settings.max_upload_bytes,
        max_mib=settings.max_upload_bytes / 2**20,
        ski_pages=[(n, ski_url(n)) for n in sorted(cat.skis)],
        example_csv_url=EXAMPLE_CSV_URL,
        example_length_mm=EXAMPLE_LENGTH_MM,
        minimum_grid=uploads.minimum_grid_sentence(),
        min_span_percent=100 * uploads.MIN_SPAN_FRACTION,
    )
