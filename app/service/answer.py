"""One contact computation per request: macro solve (rigid flat or bending ski), table
interpolation, warnings, error band and provenance (:func:`contact`).

Routes in :mod:`app.api` validate the request and call :func:`contact`; all unit conversion
from technician units happens in :mod:`app.units`.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass

import numpy as np
from skisnow.app import units
from skisnow.app.presets import DEFAULT_PRESET, Preset, get_preset
from skisnow.app.service.band import (
    answer_band,
    band_json,
    footprint_ends_m,
    min_separation_unresolved,
    touches_profile_end,
    zone_unresolved_reasons,
)
from skisnow.app.service.catalogue import (
    AUTO_RIGID_TOLERANCE,
    SKI_MODELS,
    Catalogue,
    ModelUnavailableError,
    Ski,
)
from skisnow.app.service.gate import gated
from skisnow.app.service.profiles import (
    profile_model,
)
from skisnow.app.service.rounding import finite_list
from skisnow.app.snow import snow_record
from skisnow.app.storage.common import code_version
from skisnow.solvers.band import end_pixel_share
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.errors import NotConvergedError, OutOfRangeError, SkisnowError
from skisnow.solvers.flexible import solve_flexible
from skisnow.solvers.lookup import ERROR_FIELDS, MicroTable, relative_error_estimate
from skisnow.solvers.macro import extrude_profile, solve_macro
from skisnow.solvers.multiscale import multiscale

log = logging.getLogger(__name__)

# ----------------------------------------------------------------------------- compute


@dataclass
class ContactInputs:
    """One request in technician units (validated by the API schema)."""

    ski: str
    grind: str
    load_kg: float
    load_position_mm: float
    snow_modulus_mpa: float
    porosity: float
    base_modulus_mpa: float = 700.0
    poisson_ratio: float = 0.3
    preset: str = DEFAULT_PRESET
    ski_model: str = "auto"
    snow: str | None = None


def loaded_profile(ski: Ski, load_n: float, load_position_m: float):
    """Positions [m] and loaded gap [m] of the ski on the rigid flat
    (:mod:`app.service.profiles`)."""
    return profile_model(ski.record)(load_n, load_position_m)


def warm_up(cat: Catalogue) -> float:
    """Solve one mid-range case so that compiled kernels and caches are ready before the first
    request (the first solve in a process costs ~1 s of kernel loading). Failures are logged,
    never raised: start-up does not depend on a demo case. Returns the time taken [s]."""
    t0 = time.perf_counter()
    try:
        ski = next(iter(cat.skis.values()))
        grind = next(iter(cat.grinds.values()))
        lo, hi = ski.position_range_m
        contact(
            cat,
            ContactInputs(
                ski=ski.name,
                grind=grind.name,
                load_kg=40.0,
                load_position_mm=0.5 * (lo + hi) * 1e3,
                snow_modulus_mpa=200.0,
                porosity=0.5,
            ),
        )
    except Exception as exc:  # a failed warm-up must not stop the service
        log.warning("warm-up solve failed (%s); the first request will be slower", exc)
    return time.perf_counter() - t0


#: porosity above which the answers are flagged: P_n = P/(1 − n) grows without bound as n → 1
POROSITY_WARN = 0.9
#: load share on pixels below the table's pressure range above which the answer is flagged
BELOW_TABLE_WARN = 0.01


def result_warnings(inp: ContactInputs, gmap, macro, ms) -> list[dict]:
    """Conditions under which an answer is computed but not trustworthy (docs/limits.md).

    Each warning is ``{"code", "detail"}``; the answer is still returned (HTTP 200) so that a
    user can see it, but these flags travel with it in the API, the CSV and the web page.
    """
    out = []
    if inp.porosity >= POROSITY_WARN:
        out.append(
            {
                "code": "porosity_near_one",
                "detail": f"porosity {inp.porosity:g} ≥ {POROSITY_WARN:g}: the texture carries "
                "only P·(1 − n) (docs/physics.md eq. 2), so the real contact area shrinks towards "
                "zero while the average real contact pressure F/A_tot (full load F, §6) grows "
                "without bound; very loose snow is outside what the method was made for",
            }
        )
    if touches_profile_end(gmap, macro):
        rows = np.flatnonzero(np.any(np.isfinite(gmap.gap_m), axis=1))
        first, last = gmap.positions_m[rows[0]], gmap.positions_m[rows[-1]]
        out.append(
            {
                "code": "contact_at_ski_end",
                "detail": "contact reaches the end of the measured profile "
                f"({first * 1e3:.0f} … {last * 1e3:.0f} mm): the tip or tail shape beyond "
                "the measurement is not modelled, and the minimum average separation has no "
                "grid-converged value there (no band); try a stiffer snow or a lighter load",
            }
        )
    share = float(ms.diagnostics.get("load_share_below_table_range", 0.0))
    if share > BELOW_TABLE_WARN:
        out.append(
            {
                "code": "below_table_range",
                "detail": f"{share:.1%} of the load sits where the nominal pressure is below "
                "the texture table's range; there the real contact is interpolated towards the "
                "unloaded texture, not solved",
            }
        )
    return out


@gated
def contact(
    cat: Catalogue,
    inp: ContactInputs,
    *,
    presets: dict[str, Preset] | None = None,
    error_band: bool = True,
) -> dict:
    """Compute one ski × grind case; returns the JSON-ready answer of ``POST /v1/contact``.

    ``inp.preset`` names the discretisation settings (:mod:`app.presets`); ``presets`` replaces
    the table of named presets (the accuracy benchmark passes candidate settings this way).
    ``error_band=False`` leaves the band out (benchmarks measure its cost this way; every
    answer of the API and the web form has one).

    Raises
    ------
    UnknownItemError, InputError, OutOfRangeError, NotConvergedError
    """
    t0 = time.perf_counter()
    preset = get_preset(inp.preset, presets)
    ski = cat.ski(inp.ski)
    grind = cat.grind(inp.grind)
    load_n = units.kg_to_n(inp.load_kg)
    x_f = units.mm_to_m(inp.load_position_mm)
    lo, hi = ski.position_range_m
    if not (lo - 1e-12 <= x_f <= hi + 1e-12):
        raise OutOfRangeError(
            f"load_position_mm {inp.load_position_mm:g} is outside the range the ski "
            f"{ski.name!r} covers ({lo * 1e3:g} … {hi * 1e3:g} mm)"
        )
    f_lo, f_hi = ski.load_range_n
    if not (f_lo * (1 - 1e-9) <= load_n <= f_hi * (1 + 1e-9)):
        raise OutOfRangeError(
            f"load_kg {inp.load_kg:g} is outside the range the ski {ski.name!r} covers "
            f"({units.n_to_kg(f_lo):.4g} … {units.n_to_kg(f_hi):.4g} kg): "
            f"{profile_model(ski.record).load_range_rule}"
        )
    e_eff = effective_modulus(
        units.mpa_to_pa(inp.snow_modulus_mpa),
        units.mpa_to_pa(inp.base_modulus_mpa),
        inp.poisson_ratio,
    )
    t1 = time.perf_counter()
    x, gap = loaded_profile(ski, load_n, x_f)
    t2 = time.perf_counter()
    outline = ski.record.outline
    gmap = extrude_profile(
        x,
        gap,
        outline.width_m,
        width_positions_m=outline.positions_m,
        pixel_along_m=preset.pixel_along_m,
        pixels_across=preset.pixels_across,
    )
    macro = solve_macro(gmap, load_n, x_f, e_eff)
    if not macro.converged:
        raise NotConvergedError(
            f"the ski-on-snow solve did not converge ({macro.message}); try a load position "
            "nearer the balance point or a different snow modulus"
        )
    t3 = time.perf_counter()
    ms = multiscale(macro, grind.table, inp.porosity, e_eff)
    t4 = time.perf_counter()
    macro, ms, model_info = _choose_ski_model(inp, ski, preset, macro, ms, grind, e_eff)
    t5 = time.perf_counter()
    band = None
    if error_band:
        band = answer_band(
            record=ski.record,
            positions_m=x,
            gap_m=gap,
            preset=preset,
            macro=macro,
            ms=ms,
            table=grind.table,
            porosity=inp.porosity,
            e_eff=e_eff,
            ski_model_used=model_info["used"],
            beam_is_design=ski.beam_is_design,
            rigid_minus_flexible=model_info.get("rigid_minus_flexible")
            if model_info["requested"] == "auto"
            else None,
            flexible_end_pixel_share=model_info.get("flexible", {}).get("end_pixel_share")
            if model_info["requested"] == "auto"
            else None,
            bending_ignored=bending_ignored(model_info),
            min_separation_unresolved=min_separation_unresolved(gmap, macro, ms),
        )
    t6 = time.perf_counter()
    rows = np.isfinite(ms.average_separation_m)
    answer = {
        "inputs": {
            "ski": inp.ski,
            "grind": inp.grind,
            "load_kg": inp.load_kg,
            "load_position_mm": inp.load_position_mm,
            "snow_modulus_mpa": inp.snow_modulus_mpa,
            "porosity": inp.porosity,
            "snow": snow_record(inp.snow, inp.snow_modulus_mpa, inp.porosity),
            "base_modulus_mpa": inp.base_modulus_mpa,
            "poisson_ratio": inp.poisson_ratio,
            "preset": preset.name,
            "load_n": load_n,
            "effective_modulus_mpa": e_eff / 1e6,
        },
        "metrics": {
            "total_real_contact_area_mm2": ms.total_real_contact_area_m2 * 1e6,
            "average_real_contact_pressure_mpa": ms.average_real_contact_pressure_pa / 1e6,
            "min_average_separation_um": ms.min_average_separation_m * 1e6,
            "total_reciprocal_separation_m": ms.total_reciprocal_separation_m,
        },
        "apparent": {
            "contact_area_cm2": ms.apparent_contact_area_m2 * 1e4,
            "mean_pressure_kpa": ms.mean_apparent_pressure_pa / 1e3,
            "zones": [
                {
                    "name": name,
                    "start_mm": z.start_m * 1e3,
                    "end_mm": z.end_m * 1e3,
                    "length_mm": (z.end_m - z.start_m) * 1e3,
                    "load_n": z.load_n,
                    "load_share": z.load_share,
                    "apparent_area_cm2": z.apparent_area_m2 * 1e4,
                    "real_area_mm2": z.real_area_m2 * 1e6,
                    "min_average_separation_um": zone_min_separation_um(ms, z),
                    "unresolved": why,
                }
                for z, name, why in zip(
                    ms.zones,
                    zone_names(ms.zones, *footprint_ends_m(gmap)),
                    zone_unresolved_reasons(gmap, ms),
                    strict=True,
                )
            ],
        },
        "warnings": result_warnings(inp, gmap, macro, ms) + model_info.pop("warnings"),
        "distributions": {
            "position_mm": finite_list(ms.positions_m[rows], 1e3),
            "pressure_kpa": finite_list(ms.pressure_pa[rows], 1e-3),
            "clearance_um": finite_list(ms.clearance_m[rows], 1e6),
            "real_area_fraction": finite_list(ms.real_area_fraction[rows]),
            "average_separation_um": finite_list(ms.average_separation_m[rows], 1e6),
            "reciprocal_separation_per_m": finite_list(ms.reciprocal_separation_per_m[rows]),
        },
        "provenance": {
            "code_version": code_version(),
            "preset": {
                **preset.provenance(),
                "macro_pixel_size_mm": [v * 1e3 for v in macro.pixel_size_m],
                "texture_pixel_size_um": grind.table.pixel_size_m * 1e6,
            },
            "table": {
                "file": grind.path.name,
                "sha256": grind.sha256,
                "texture_pixel_size_um": grind.table.pixel_size_m * 1e6,
                "gap_floor_nm": grind.table.gap_floor_m * 1e9,
                "pixel_error_estimate": pixel_error_estimate(
                    grind.table, macro.pressure_pa, ms.real_area_fraction_map, inp.porosity, e_eff
                ),
            },
            "ski": {
                "file": ski.path.name,
                "sha256": ski.sha256,
                "profile_model": profile_model(ski.record).answer_source(load_n),
                "profile_model_reason": profile_model(ski.record).answer_reason(load_n),
            },
            "ski_model": model_info,
            "macro": {
                "converged": macro.converged,
                "iterations": macro.iterations,
                "residual": macro.residual,
                "pixel_size_mm": [v * 1e3 for v in macro.pixel_size_m],
                "force_residual": macro.force_residual,
                "moment_residual": macro.moment_residual,
            },
            "multiscale": ms.diagnostics,
        },
        "timing_ms": {
            "profile": (t2 - t1) * 1e3,
            "macro": (t3 - t2) * 1e3,
            "multiscale": (t4 - t3) * 1e3,
            "ski_model": (t5 - t4) * 1e3,
            "band": (t6 - t5) * 1e3,
        },
    }
    if band is None:
        answer["timing_ms"]["total"] = (time.perf_counter() - t0) * 1e3
        return answer
    answer["band"], band_warnings = band_json(band, answer)
    answer["warnings"] += band_warnings
    if band.pressure_line_band_pa is not None:
        lo, hi = band.pressure_line_band_pa
        # two columns like every other distribution (one value per position)
        answer["distributions"]["pressure_band_low_kpa"] = finite_list(lo[rows], 1e-3)
        answer["distributions"]["pressure_band_high_kpa"] = finite_list(hi[rows], 1e-3)
    answer["timing_ms"]["total"] = (time.perf_counter() - t0) * 1e3
    return answer


def pixel_error_estimate(
    table: MicroTable, pressure_pa, real_area_fraction_map, porosity: float, e_eff: float
) -> dict:
    """The table's error estimate against the zero-pixel limit at this answer's pressures.

    For each loaded macro cell the tabulated relative estimate is interpolated at its
    ``P_n / E'`` (:func:`solvers.lookup.relative_error_estimate`). Reported: the largest over
    the cells for a_r (``real_contact_area_fraction_rel_max``), the mean gap and the floored
    reciprocal gap, and the a_r-weighted mean for a_r, the relative estimate of the total
    real contact area (equal cells). Tables built on one pixel size: ``estimated`` false.
    Tables with the adaptive fourth level (docs/tables.md) also report its pixel size, its
    nodes' ``P_n / E'`` and how many loaded cells interpolate next to one of them (their
    ratio between the node's neighbours); tables with light-load levels report theirs
    (``light_load_levels``: pixel sizes, nodes' ``P_n / E'``, cells near) the same way.
    """
    levels = json.loads(table.attrs.get("pixel_extrapolation_json", "null") or "null")
    if not table.has_error_estimates or levels is None:
        return {"estimated": False, "pixel_levels": table.attrs.get("pixel_levels", "none")}
    p = np.asarray(pressure_pa, dtype=float)
    loaded = np.isfinite(p) & (p > 0)
    p_n = p[loaded] * (1 - porosity)
    out: dict = {
        "estimated": True,
        "pixel_levels": table.attrs.get("pixel_levels"),
        "level_pixel_size_um": [v * 1e6 for v in levels["level_pixel_size_m"]],
        "orders": levels["orders"],
        # three levels: estimate from successive extrapolants where the order is stable
        "estimate_rule": "successive_extrapolants"
        if len(levels["level_pixel_size_m"]) > 2
        else "richardson_correction",
    }
    short = {
        "real_contact_area_fraction": "real_contact_area_fraction",
        "mean_gap_m": "mean_gap",
        "mean_reciprocal_gap_per_m": "mean_reciprocal_gap",
    }
    for name, nodes, pixel in (
        ("fourth_level", table.fourth_level_nodes, "adaptive_pixel_size_m"),
        ("light_load_levels", table.light_load_nodes, "light_pixel_size_m"),
    ):
        if not nodes.size:
            continue
        r = np.asarray(table.pressure_ratio, dtype=float)
        lo, hi = r[np.maximum(nodes - 1, 0)], r[np.minimum(nodes + 1, r.size - 1)]
        ratio = p_n[:, None] / e_eff
        near = ((ratio > lo) & (ratio < hi)) | np.isclose(ratio, r[nodes], rtol=1e-9, atol=0)
        sizes_um = np.asarray(table.levels[pixel], dtype=float) * 1e6
        out[name] = {
            "pixel_size_um": float(sizes_um) if sizes_um.ndim == 0 else sizes_um.tolist(),
            "pressure_ratio": [float(v) for v in r[nodes]],
            "cells_near": int(np.count_nonzero(np.any(near, axis=1))),
        }
    for quantity in ERROR_FIELDS:
        rel = np.atleast_1d(relative_error_estimate(table, p_n, e_eff, quantity))
        finite = rel[np.isfinite(rel)]
        out[f"{short[quantity]}_rel_max"] = float(finite.max()) if finite.size else None
        if quantity == "real_contact_area_fraction":
            ar = np.asarray(real_area_fraction_map, dtype=float)[loaded]
            ok = np.isfinite(rel) & np.isfinite(ar)
            total = float(np.sum(ar[ok]))
            out["total_real_contact_area_rel"] = (
                float(np.sum(ar[ok] * rel[ok]) / total) if total > 0 else None
            )
    return out


def zone_min_separation_um(ms, zone) -> float | None:
    """The smallest average interfacial separation inside one contact zone [µm] (rows of the
    zone with a finite value; None without any)."""
    x = ms.positions_m
    inside = (x >= zone.start_m - 1e-12) & (x <= zone.end_m + 1e-12)
    h = ms.average_separation_m[inside]
    h = h[np.isfinite(h)]
    return float(h.min() * 1e6) if h.size else None


def resolved_min_separation(zones: list[dict]) -> dict:
    """The minimum average separation over the grid-resolved contact zones of an answer's
    ``apparent.zones`` (each with ``min_average_separation_um`` and ``unresolved``): its value
    [µm] (None when no zone is resolved), the zone it lies in, and the unresolved zones with
    their reasons. The answer's own minimum (``metrics``) is over the whole ski."""
    resolved = [z for z in zones if not z.get("unresolved")]
    resolved = [z for z in resolved if z.get("min_average_separation_um") is not None]
    best = min(resolved, key=lambda z: z["min_average_separation_um"], default=None)
    return {
        "value_um": best["min_average_separation_um"] if best else None,
        "zone": best["name"] if best else None,
        "unresolved": [
            {"zone": z["name"], "reason": z["unresolved"]} for z in zones if z.get("unresolved")
        ],
    }


def zone_names(zones, tail_m: float = -np.inf, tip_m: float = np.inf) -> list[str]:
    """Names of contact zones by their position along the ski, whatever the load: the middle
    of a zone behind the balance point (X < 0) names it ``rear``, or ``tail`` when it lies in
    the rear half of the way to the tail end ``tail_m`` [m]; ahead of it ``front``, or ``tip``
    in the front half of the way to the tip end ``tip_m`` [m] (the ends of the footprint).
    Several zones in one section are numbered from the tail (``front 1``, ``front 2``). The foot
    zone is thus ``rear`` at 13, 40 and 70 kg, whether or not a tail or tip contact appears."""
    mids = [0.5 * (z.start_m + z.end_m) for z in zones]
    sections = [
        ("tail" if m < 0.5 * tail_m else "rear")
        if m < 0.0
        else ("tip" if m > 0.5 * tip_m else "front")
        for m in mids
    ]
    order = sorted(range(len(zones)), key=lambda i: zones[i].start_m)
    count = {section: sections.count(section) for section in set(sections)}
    seen: dict[str, int] = {}
    names = [""] * len(zones)
    for i in order:
        section = sections[i]
        seen[section] = seen.get(section, 0) + 1
        names[i] = section if count[section] == 1 else f"{section} {seen[section]}"
    return names


def rigid_minus_flexible(rigid, flex, ms_rigid=None, ms_flex=None) -> dict[str, float]:
    """What ``auto`` compares: relative differences (rigid − flexible) / flexible of the
    apparent area and, when the multiscale results are given, the four metrics; the rear load
    share (behind the load point) as an absolute difference [-]."""

    def values(macro, ms) -> dict[str, float]:
        out = {"apparent_area": macro.apparent_contact_area_m2}
        if ms is not None:
            out |= {
                "total_real_contact_area": ms.total_real_contact_area_m2,
                "average_real_contact_pressure": ms.average_real_contact_pressure_pa,
                "min_average_separation": ms.min_average_separation_m,
                "total_reciprocal_separation": ms.total_reciprocal_separation_m,
            }
        return out

    def rear_share(macro) -> float:
        p = np.nan_to_num(macro.pressure_pa)
        rear = macro.positions_m < macro.load_position_m
        return float(p[rear].sum() / max(p.sum(), 1e-300))

    a, b = values(rigid, ms_rigid), values(flex, ms_flex)
    diff = {k: (a[k] - b[k]) / b[k] if b[k] else 0.0 for k in a}
    diff["rear_load_share"] = rear_share(rigid) - rear_share(flex)
    return diff


def auto_uses_flexible(diff: dict[str, float]) -> tuple[bool, str]:
    """``auto``'s rule on :func:`rigid_minus_flexible`: flexible when any compared quantity
    differs by more than :data:`AUTO_RIGID_TOLERANCE`; returns the choice and the reason."""
    worst = max(diff, key=lambda k: abs(diff[k]))
    if abs(diff[worst]) <= AUTO_RIGID_TOLERANCE:
        return False, (
            f"the rigid shape is within {AUTO_RIGID_TOLERANCE:.0%} of the flexible ski in every "
            f"compared quantity (largest: {worst} {diff[worst]:+.1%})"
        )
    return True, (
        f"the rigid shape differs from the bending ski by {diff[worst]:+.1%} in {worst} "
        f"(more than {AUTO_RIGID_TOLERANCE:.0%})"
    )


#: the words every ``auto`` answer of the rigid shape without a comparison adds to its warning
BENDING_IGNORED = (
    ". auto answers with the rigid shape and ignores how the ski bends on the snow: on "
    "comparable skis that changes the apparent contact area by up to 60–69 % (docs/studies/"
    "auto-without-beam.json); the band includes that difference (band.components.ski_model)"
)


def bending_ignored(model_info: dict) -> str | None:
    """Why ``auto`` answered with the rigid shape without comparing it to the bending ski
    (no beam, or the flexible solve failed), or None."""
    if model_info.get("requested") != "auto" or model_info.get("used") != "rigid":
        return None
    if "rigid_minus_flexible" in model_info:
        return None
    return str(model_info.get("reason", "no bending model"))


def _choose_ski_model(inp: ContactInputs, ski: Ski, preset: Preset, rigid, ms_rigid, grind, e_eff):
    """Apply ``inp.ski_model``: the rigid answer, the flexible one, or (``auto``) the rigid one
    when it is within :data:`AUTO_RIGID_TOLERANCE` of the flexible one in every compared
    quantity. Returns (macro, multiscale, provenance dict with a ``warnings`` list)."""
    if inp.ski_model not in SKI_MODELS:
        raise ModelUnavailableError(
            f"ski_model must be one of {', '.join(SKI_MODELS)}, got {inp.ski_model!r}"
        )
    info: dict = {"requested": inp.ski_model, "warnings": []}
    if inp.ski_model == "rigid":
        info.update(used="rigid", reason="requested")
        return rigid, ms_rigid, info
    beam, why = ski.beam()
    if beam is None:
        if inp.ski_model == "flexible":
            raise ModelUnavailableError(why)
        info.update(used="rigid", reason=why)
        info["warnings"].append({"code": "flexible_unavailable", "detail": why + BENDING_IGNORED})
        return rigid, ms_rigid, info
    try:
        model = ski.flexible_model(preset.pixel_along_m, preset.pixels_across)
        # no warm start from the rigid answer: the solver's own row-level start is closer
        # (measured: 3-5 pixel sets instead of 9-11 on the demo skis at the papers' case)
        flex = solve_flexible(model, rigid.load_n, rigid.load_position_m, e_eff)
    except SkisnowError as exc:
        if inp.ski_model == "flexible":
            raise
        reason = f"the flexible model cannot answer this case ({exc})"
        info.update(used="rigid", reason=reason)
        info["warnings"].append(
            {"code": "flexible_unavailable", "detail": reason + BENDING_IGNORED}
        )
        return rigid, ms_rigid, info
    info["beam_source"] = why
    info["flexible"] = {
        "converged": flex.converged,
        "iterations": flex.iterations,
        "message": flex.message,
        "solve_time_ms": flex.solve_time_s * 1e3,
    }
    if not flex.converged:
        if inp.ski_model == "flexible":
            raise NotConvergedError(
                f"the flexible ski-on-snow solve did not converge: {flex.message}"
            )
        info.update(used="rigid", reason=f"the flexible solve did not converge ({flex.message})")
        info["warnings"].append(
            {"code": "flexible_not_converged", "detail": info["reason"] + BENDING_IGNORED}
        )
        return rigid, ms_rigid, info
    ms_flex = multiscale(flex, grind.table, inp.porosity, e_eff)
    diff = rigid_minus_flexible(rigid, flex, ms_rigid, ms_flex)
    info["rigid_minus_flexible"] = diff
    # the bending ski's own grid estimate: an ``auto`` answer of the rigid shape is judged
    # against the bending ski, so its band takes the apparent area's grid part from it
    share = end_pixel_share([z.length_m for z in flex.zones], flex.pixel_size_m[0])
    info["flexible"]["end_pixel_share"] = share if np.isfinite(share) else None
    if inp.ski_model == "flexible":
        info.update(used="flexible", reason="requested")
        return flex, ms_flex, info
    use_flexible, reason = auto_uses_flexible(diff)
    info.update(used="flexible" if use_flexible else "rigid", reason=reason)
    return (flex, ms_flex, info) if use_flexible else (rigid, ms_rigid, info)
