"""A ski's page ``/skis/{name}`` and the 404 page of an unknown ski.

The page shows the ski's served profile model and why, the beam identified from its camber
measurements (provenance, held-out check), EI(X) and c(X) with their bands and the
identification's alternative beams, and the misfit per camber case, the same figures as
``GET /v1/skis/{name}``; why there is no beam when there is none. An uploaded ski's page has
a delete button (``static/delete.js``).
"""

from __future__ import annotations

import json
from urllib.parse import quote, urlencode

from fastapi import Request
from fastapi.responses import HTMLResponse
from skisnow.app import service, units
from skisnow.app.jobs.uploads import sampling_note
from skisnow.app.service.profiles import CHOICE_RULE, model_choice
from skisnow.app.service.ski_figures import ski_figures
from skisnow.app.storage.skis import dropped_words, mm_ranges
from skisnow.app.web.form import DEFAULTS, NUMERIC, metadata_label, ski_url
from skisnow.app.web.templating import DELETE_JS, JS, fmt, page, svg
from skisnow.solvers.band import Z90
from skisnow.solvers.identify import ALTERNATIVE_MISFIT_RANGE, HELD_OUT_LIMIT

#: the served profile models (``GET /v1/skis``'s ``profile_model``) as a technician reads them
PROFILE_MODEL_LABELS = {
    "identified_beam": "beam identified from the ski's camber measurements",
    "network": "camber network trained on the ski's measurements",
    "design_beam": "design beam stored with the ski",
}


def _summary(ski: service.Ski) -> dict:
    """The numbers of the page's summary line (technician units)."""
    rec = ski.record
    m, o = rec.measurements, rec.outline
    loads_kg = units.n_to_kg(m.loads_n)
    return {
        # an upload: its metadata (brand, style, team), not "uploaded ski NAME"
        "description": metadata_label("ski", rec.metadata)
        if rec.metadata.get("item_id")
        else rec.metadata.get("description") or rec.metadata.get("brand_model") or "",
        "length_mm": o.length_m * 1e3,
        "width_min_mm": o.width_m.min() * 1e3,
        "width_max_mm": o.width_m.max() * 1e3,
        "profiles": m.loads_n.size,
        "sides": ", ".join(sorted(set(m.sides))),
        "load_min_kg": loads_kg.min(),
        "load_max_kg": loads_kg.max(),
        "position_min_mm": m.load_positions_m.min() * 1e3,
        "position_max_mm": m.load_positions_m.max() * 1e3,
        "samples": m.positions_m.size,
        "step_mm": m.sample_spacing_mm,
        # what a sampling coarser than the recommended costs (the upload's note, again here)
        "sampling_note": sampling_note(m.sample_spacing_mm),
        # positions dropped for unmeasured samples (the upload's note, again here)
        "unmeasured_note": _unmeasured_note(rec.metadata),
        "file": ski.path.name,
        "sha256": ski.sha256,
    }


def _unmeasured_note(metadata: dict) -> str | None:
    """What the upload did to the positions, in words (None: nothing): those dropped for
    unmeasured or absent samples, positions written rounded read as their grid."""
    try:
        dropped = json.loads(metadata.get("positions_dropped_mm") or "[]")
    except ValueError:
        return None
    try:
        shift = float(metadata.get("position_shift_mm") or 0.0)
        absent = json.loads(metadata.get("positions_absent_mm") or "[]")
        left_out = json.loads(metadata.get("cases_dropped") or "[]")
    except ValueError:
        shift, absent, left_out = 0.0, [], []
    rounded = (
        f"the positions, written rounded, were read as the uniform grid they round (largest "
        f"shift {shift:.3g} mm)"
        if shift
        else ""
    )
    if not dropped and not left_out:
        return rounded[0].upper() + rounded[1:] if rounded else None
    why = f"{metadata.get('unmeasured_samples', '?')} samples of the file had no gap"
    omitted = int(metadata.get("omitted_samples") or 0)
    if omitted:
        listed = f"{omitted} samples of the grid were not listed by their case"
        why = listed if metadata.get("unmeasured_samples") == "0" else f"{why}, {listed}"
    if absent:
        plural = "s" if len(absent) > 1 else ""
        why += f" and {len(absent)} position{plural} of the grid ({mm_ranges(absent)}) none"
    done = dropped_words(dropped, left_out, past=True)
    return f"{why}: {' and '.join(done)}; nothing was filled in" + (
        f"; {rounded}" if rounded else ""
    )


def _numbers(ident: dict) -> list[tuple]:
    """(key, label, value, unit, format) of the identification's summary numbers."""
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
        (
            "held_out_rms_band_um",
            "Held-out error where the measured gap < 0.2 mm (the check's)",
            ident.get("held_out_rms_band_um"),
            "µm",
            "{:.3f}",
        ),
        (
            "model_spacing_mm",
            "Beam model's node spacing",
            ident.get("model_spacing_mm"),
            "mm",
            "{:.3g}",
        ),
    )
    return [n for n in numbers if n[2] is not None]


def _choice(identified: dict | None) -> dict | None:
    """The held-out comparison of the two profile models in µm (None: not stored)."""
    a = model_choice(identified)
    if a is None:
        return None
    um = {k: float(a.get(k, float("nan"))) * 1e6 for k in a if k.endswith("_m")}
    return {
        "served": str(a["served"]),
        "reason": str(a["reason"]),
        "cases": int(a.get("held_out_cases", 0)),
        "seed": a.get("seed"),
        **{k[:-2] + "_um": v for k, v in um.items()},
    }


def _provenance(ident: dict) -> list[tuple[str, str]]:
    """(term, text) rows of the identification's provenance; empty texts are not shown."""
    pv = ident.get("provenance", {})
    solve = pv.get("solve_time_s")
    return [
        ("created (UTC)", str(pv.get("created_utc", ""))),
        ("code version", str(pv.get("code_version", ""))),
        ("git commit", str(pv.get("git_commit", ""))),
        ("command", str(pv.get("command_line", ""))),
        ("profiles", str(pv.get("profiles") or "")),
        ("held-out draw seed", str(pv.get("held_out_seed", ""))),
        ("held-out errors", _held_out_origin((ident.get("held_out") or {}).get("provenance"))),
        (
            "fit",
            ""
            if pv.get("iterations") is None
            else f"{pv['iterations']} Gauss–Newton steps over {pv.get('contact_passes')} contact "
            f"passes" + (f", {solve:.1f} s" if solve is not None else ""),
        ),
    ]


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
    return origin.get("source", "") + (f" ({when})" if when else "")


def _beam_table(beam: dict) -> dict:
    """EI(X) and c(X) at the points of ``GET /v1/skis/{name}``, with their bands."""
    band = beam.get("bending_stiffness_band_90_nm2")
    cband = beam.get("camber_band_90_um")
    share = beam.get("bending_stiffness_data_share")
    rows = []
    for i, x in enumerate(beam["position_mm"]):
        cells = [fmt(x, "{:g}"), fmt(beam["bending_stiffness_nm2"][i], "{:g}")]
        if band:
            cells.append(f"{fmt(band[0][i], '{:g}')} … {fmt(band[1][i], '{:g}')}")
        if share:
            cells.append(fmt(None if share[i] is None else 100 * share[i], "{:.0f}"))
        cells.append(fmt(beam["camber_um"][i], "{:g}"))
        if cband:
            cells.append(f"{fmt(cband[0][i], '{:g}')} … {fmt(cband[1][i], '{:g}')}")
        rows.append(cells)
    return {"ei_band": bool(band), "ei_share": bool(share), "c_band": bool(cband), "rows": rows}


def _misfit_rows(ident: dict) -> list[tuple]:
    """(row class, load [kg], position [mm], error [µm], label) of every identified case and
    every held-out case."""
    rows = [
        ("identified", f, x, e, "identified")
        for f, x, e in zip(
            ident["case_load_kg"], ident["case_position_mm"], ident["case_misfit_um"], strict=True
        )
    ]
    held = ident.get("held_out") or {}
    rows += [
        ("held-out", f, x, e, "held out")
        for f, x, e in zip(
            held.get("load_kg", []),
            held.get("position_mm", []),
            held.get("error_um", []),
            strict=True,
        )
    ]
    return rows


def _figures(ski: service.Ski, beam: dict, cache_file=None) -> list[tuple]:
    """(key, caption, SVG) of the page's figures (EI(X), c(X), misfit per case); drawn once per
    ski file and kept (:mod:`app.service.ski_figures`)."""
    svgs = ski_figures(ski, cache_file)
    if beam.get("bending_stiffness_band_90_nm2"):
        ei_note = "with its 90 % band from the identification's covariance"
        stretch = beam.get("bending_stiffness_measured_mm")
        if stretch:
            ei_note += (
                f". The camber cases set EI between {stretch[0]:g} and {stretch[1]:g} mm (at "
                "least a quarter of each estimate from the data); outside that stretch the "
                "device's loads did not bend the ski, the fit's smoothing prior sets EI and the "
                "band is the prior's"
            )
        c_note = f"with its 90 % band (± {Z90:.3f} σ of the identification)"
    else:
        ei_note = c_note = "of the design beam stored with the ski: not identified, no band"
    captions = {
        "stiffness": f"Bending stiffness EI(X) [N·m²] {ei_note}",
        "camber": f"Unloaded camber c(X) [mm] {c_note}",
        "misfit": "RMS misfit per camber case [µm] against load [kg] and load position [mm], "
        "with the device noise σ estimated from the data",
    }
    return [(k, captions[k], svg(svgs[k])) for k in captions if k in svgs]


def render_ski(
    request: Request, cat: service.Catalogue, ski: service.Ski, figure_cache=None
) -> HTMLResponse:
    """A ski's page: profile model and why, identification, EI(X), c(X), misfit per case
    (``figure_cache``: the file keeping its figures between processes, or None)."""
    name = ski.name
    profile = service.profile_report(ski)
    beam = service.beam_report(ski)
    ident = beam.get("identification")
    model = profile["name"]
    deletable = _uploaded(request, name)
    form_url = "/?" + urlencode(
        [("ski", name)]
        + [(k, DEFAULTS[k]) for k in (*NUMERIC, "snow_input")]
        + [("grind", g) for g in sorted(cat.grinds)[:1]]
    )
    return page(
        request,
        "ski.html",
        f"skisnow — ski {name}",
        name=name,
        summary=_summary(ski),
        form_url=form_url,
        api_url="/v1/skis/" + quote(name, safe=""),
        profile=profile,
        model=model,
        model_label=PROFILE_MODEL_LABELS.get(model, str(model)),
        beam=beam,
        ident=ident,
        numbers=_numbers(ident) if ident else [],
        provenance=_provenance(ident) if ident else [],
        choice=_choice(ski.record.identified),
        choice_rule=CHOICE_RULE,
        held_out_limit=HELD_OUT_LIMIT,
        alternative_range_pct=100 * ALTERNATIVE_MISFIT_RANGE,
        figures=_figures(ski, beam, figure_cache),
        beam_table=_beam_table(beam) if beam["available"] else None,
        misfit_rows=_misfit_rows(ident) if ident and "case_load_kg" in ident else [],
        delete_url=("/v1/skis/" + quote(name, safe="")) if deletable else None,
        token=_asks_token(request),
        js=JS + DELETE_JS,
    )


def _asks_token(request: Request) -> bool:
    """Whether the delete button needs a token field: teams are on and the caller is not
    logged in (the login cookie carries the token, app/web/login.py)."""
    settings = getattr(request.app.state, "settings", None)
    if not getattr(settings, "team_tokens", None):
        return False
    from skisnow.app.api.access import caller

    return caller(request).team is None


def _uploaded(request: Request, name: str) -> bool:
    """Whether ``name`` is an uploaded ski of the catalogue database (not a shipped, read-only
    one): its page has a delete button (``DELETE /v1/skis/{name}``, ``static/delete.js``)."""
    state = getattr(request.app.state, "uploads", None)
    row = state.db.item_by_name("ski", name) if state is not None else None
    return row is not None and not row.read_only


def render_unknown_ski(
    request: Request, cat: service.Catalogue, name: str, state: str | None
) -> HTMLResponse:
    """The 404 page of a ski name the catalogue does not serve; for an upload whose job failed,
    the reason and a delete button."""
    from skisnow.app.api.access import failed_views

    failed = None
    if state == "failed":
        failed = next((f for f in failed_views(request, "ski") if f["name"] == name), None)
    return page(
        request,
        "unknown_ski.html",
        "skisnow — unknown ski",
        404,
        name=name,
        state=state,
        known=[(n, ski_url(n)) for n in sorted(cat.skis)],
        failed=failed,
        delete_url="/v1/skis/" + quote(name, safe="") if failed else None,
        token=_asks_token(request),
        js=JS + DELETE_JS,
    )
