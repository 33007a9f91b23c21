"""The micro-scale parts of the ``accuracy`` section of ``docs/benchmarks.md``: grid size
(stage ``micro``) and table interpolation (stage ``table``), with the number formats and words
the whole section shares (:mod:`app.evidence.accuracy_md` assembles the page).

Every number in the prose is read from the JSON or from the constant that produced it.
"""

from __future__ import annotations

import math

import numpy as np
from skisnow.app.evidence.accuracy_common import (
    CONVERGENCE_RATIO_MIN,
    MICRO_METRICS,
    MICRO_PATCH_M,
    PRESSURE_STEP,
    SHIPPED_N,
    SNOW_MODULUS_PA,
    TABLE_METRICS,
    convergence,
    rel_diff,
    richardson,
)
from skisnow.app.evidence.accuracy_table import LOOKUP_BATCH
from skisnow.solvers.lookup import PIXEL_EXTRAPOLATION_ORDERS
from skisnow.solvers.micro import DEFAULT_GAP_FLOOR_M

#: |d ln f / d ln P_n| above which a micro metric hangs on the gaps of a few pixels [-]
ILL_POSED_SENSITIVITY = 20
#: contact pixels below which a tabulated a_r is step-like (pixel counting) [-]
FEW_PIXELS = 1000

_SUPERSCRIPT = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")


def _pct(v: float | None) -> str:
    return "—" if v is None or not np.isfinite(v) else f"{100 * v:+.3g} %"


def _apct(v: float | None) -> str:
    return "—" if v is None or not np.isfinite(v) else f"{100 * abs(v):.3g} %"


def _pixel_um(n: int) -> float:
    """Pixel of an n×n grid on the micro patch [µm]."""
    return MICRO_PATCH_M / n * 1e6


def _power_of_ten(n: int) -> str:
    """``10⁴`` for 10 000 (n a power of ten)."""
    return "10" + str(round(math.log10(n))).translate(_SUPERSCRIPT)


def _order_words(order: float | None, finest: int) -> str:
    """How the two-level tables extrapolate a metric (:data:`PIXEL_EXTRAPOLATION_ORDERS`)."""
    if order is None:
        return f"the {finest}² value"
    words = {1.0: "first", 2.0: "second", 3.0: "third"}
    return f"{words.get(order, f'order {order:g}')} order"


# --------------------------------------------------------------------------- micro


def _micro_error_text(d: dict) -> str:
    """Range of the micro-scale error of the shipped tables, in words."""
    return _micro_error(d)[0]


def _micro_error(d: dict) -> tuple[str, float | None]:
    """Range of the micro-scale error of the shipped tables, from the micro stage: the
    two-level value where the series has it (tables built with ``--pixel-levels refine``),
    else the shipped grid; with the largest |error| of a_r and the floored reciprocal gap
    (None without a micro stage)."""
    none = "the micro-scale error of the shipped tables (micro stage)", None
    mi = d.get("micro")
    if not mi:
        return none
    ar, rec, ar_before = [], [], []
    for s_ in mi["series"]:
        rows = s_["rows"]
        ns = [r["n"] for r in rows]
        if SHIPPED_N not in ns[:-1]:
            continue
        r_shipped = rows[ns.index(SHIPPED_N)]
        c = convergence([r["real_contact_area_fraction"] for r in rows])
        if c["verdict"] == "converges":
            lim = richardson([r["real_contact_area_fraction"] for r in rows], c["observed_order"])
            before = r_shipped["real_contact_area_fraction"] / lim - 1
        else:
            before = r_shipped["rel_error"]["real_contact_area_fraction"]
        two = s_.get("two_level")
        shipped = (s_.get("shipped_table") or {}).get("pixel_levels", "none")
        if two and shipped != "none":
            ar_before.append(before)
            ar.append(two["after_rel_error"]["real_contact_area_fraction"])
            rec.append(two["after_rel_error"]["mean_reciprocal_gap_per_m"])
        else:
            ar.append(before)
            rec.append(r_shipped["rel_error"]["mean_reciprocal_gap_per_m"])
    if not ar:
        return none
    largest = max(abs(v) for v in ar + rec)
    if ar_before:
        return (
            f"two-level tables: a_r {_pct(min(ar))} … {_pct(max(ar))} against the zero-pixel "
            f"limit ({_pixel_um(SHIPPED_N):g} µm alone: {_pct(min(ar_before))} … "
            f"{_pct(max(ar_before))}), floored reciprocal gap {_pct(min(rec))} … {_pct(max(rec))}",
            largest,
        )
    return (
        f"a_r {_pct(min(ar))} … {_pct(max(ar))} against the zero-pixel limit, floored "
        f"reciprocal gap {_pct(min(rec))} … {_pct(max(rec))} against "
        f"{_pixel_um(2 * SHIPPED_N):g} µm pixels",
        largest,
    )


def _micro_rows(d: dict) -> list[str]:
    mi = d["micro"]
    lines = [
        "### Micro scale: grid size",
        "",
        f"Finer pixels on the **same** {mi['patch_mm']:.3f} mm patch (not a larger area): "
        + (
            "the shipped texture's surface refined by its generator (same parameters, "
            "seed and draws) to "
            if mi.get("surface", "").startswith("shipped")
            else "the shipped grind's generator (same parameters and seed) at "
        )
        + f"{mi['sizes'][-1]}², block-averaged to the coarser grids; reference "
        f"{mi['sizes'][-1]}² ({mi['series'][0]['rows'][-1]['pixel_um']:g} µm pixels). The "
        f"shipped tables use the {SHIPPED_N}² grid ({_pixel_um(SHIPPED_N):g} µm). E' = "
        f"{d['micro_effective_modulus_pa'] / 1e6:.0f} MPa ({SNOW_MODULUS_PA / 1e6:g} MPa snow).",
        "",
        "| grind | P_n [kPa] | N | pixel [µm] | median time [s] | time / ref | a_r | h̄_n | "
        "(1/h)‾ floored | (1/h)‾ raw |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in mi["series"]:
        for r in s["rows"]:
            e = r["rel_error"]
            lines.append(
                f"| {s['grind']} | {s['nominal_pressure_kpa']:g} | {r['n']} | "
                f"{r['pixel_um']:g} | {r['median_time_s']:.3g} | "
                f"{r['time_ratio_vs_reference']:.3f} | "
                f"{_pct(e['real_contact_area_fraction'])} | "
                f"{_pct(e['mean_gap_m'])} | {_pct(e['mean_reciprocal_gap_per_m'])} | "
                f"{_pct(e['mean_reciprocal_gap_raw_per_m'])} |"
            )
    return lines


def _verdict_cell(c: dict) -> str:
    verdict, order = c["verdict"], c["observed_order"]
    if verdict == "converges slowly":
        return (
            f"converges slowly (monotone; changes up to {_apct(c['max_relative_change'])} "
            "per halving)"
        )
    if verdict == "converges":
        return "converges" + (f" (p ≈ {order:.1f})" if order is not None else "")
    if verdict == "bounded":
        return f"no clear order, changes ≤ {_apct(c['max_relative_change'])} per halving"
    return f"**does not converge** (changes up to {_apct(c['max_relative_change'])})"


def _convergence_table(mi: dict) -> list[str]:
    lines = [
        "",
        f"Convergence with refinement (successive differences shrink ≥ "
        f"{CONVERGENCE_RATIO_MIN:g}× per halving of the pixel; observed order from the last "
        "pair):",
        "",
        "| metric | "
        + " | ".join(f"{s['grind']} {s['nominal_pressure_kpa']:g} kPa" for s in mi["series"])
        + " |",
        "|---" * (1 + len(mi["series"])) + "|",
    ]
    for m, label in MICRO_METRICS.items():
        # recomputed from the values
        cells = [_verdict_cell(convergence([r[m] for r in s["rows"]])) for s in mi["series"]]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return lines


def _shipped_grid_estimate(mi: dict) -> list[str]:
    """Richardson estimate of the shipped grid's error, where the series has an order."""
    est = []
    for s_ in mi["series"]:
        rows = s_["rows"]
        ns = [r["n"] for r in rows]
        if SHIPPED_N not in ns[:-1] or len(rows) < 3:
            continue
        cells = []
        for m in ("real_contact_area_fraction", "mean_gap_m", "mean_reciprocal_gap_per_m"):
            c = convergence([r[m] for r in rows])
            if c["verdict"] != "converges":
                cells.append("— (no order)")
                continue
            extrap = richardson([r[m] for r in rows], c["observed_order"])
            cells.append(_pct(rows[ns.index(SHIPPED_N)][m] / extrap - 1))
        est.append(
            f"| {s_['grind']} {s_['nominal_pressure_kpa']:g} kPa | " + " | ".join(cells) + " |"
        )
    if not est:
        return []
    return [
        "",
        f"Estimated error of the shipped tables' grid ({SHIPPED_N}², "
        f"{_pixel_um(SHIPPED_N):g} µm) against the limit of zero pixel size "
        "(Richardson extrapolation from the two finest grids with the observed order, "
        "where there is one):",
        "",
        "| series | a_r | h̄_n | (1/h)‾ floored |",
        "|---|---|---|---|",
        *est,
    ]


def _well_posedness(mi: dict) -> list[str]:
    sens = {
        m: max(
            abs(r.get("log_sensitivity_to_pressure", {}).get(m, 0.0))
            for s in mi["series"]
            for r in s["rows"]
        )
        for m in MICRO_METRICS
    }
    step_pct = 100 * PRESSURE_STEP
    raw = sens["mean_reciprocal_gap_raw_per_m"]
    return [
        "",
        f"Well-posedness: each solve repeated at a {step_pct:g} % higher pressure gives "
        "d ln f / d ln P_n; largest |value| over all grids: "
        + ", ".join(f"{MICRO_METRICS[m]} {v:.3g}" for m, v in sens.items())
        + " (a well-posed metric is of order 1)."
        + (
            " The raw reciprocal gap is decided by the gaps of a few pixels next to contact: "
            f"a {step_pct:g} % change of the load moves it by up to {raw * step_pct:.0f} %, so "
            "where it looks convergent in one series that is chance."
            if raw > ILL_POSED_SENSITIVITY
            else ""
        ),
    ]


def _shipped_levels_words(rows: list[dict]) -> str:
    """Which pixel levels each shipped file has, as the run recorded them."""
    levels = {}
    for s_ in rows:
        levels.setdefault(s_["grind"], (s_.get("shipped_table") or {}).get("pixel_levels", "none"))
    return "; ".join(f"{g}: `--pixel-levels {lv}`" for g, lv in levels.items()) + (
        "; the shipped tables' own estimates over the whole range are in the table below"
    )


def _before_after_lines(mi: dict) -> list[str]:
    """Shipped tables before (shipped grid alone) and after (two-level extrapolation), against
    the zero-pixel limit of this run's finest grids."""
    rows = [s for s in mi["series"] if s.get("two_level")]
    if not rows:
        return []
    finest = mi["sizes"][-2:]
    fine = 2 * SHIPPED_N
    orders = {m: _order_words(o, fine) for m, o in PIXEL_EXTRAPOLATION_ORDERS.items()}
    out = [
        "",
        f"**Shipped tables, before and after (issue #13 point 3).** Before: one level, "
        f"{SHIPPED_N}² ({_pixel_um(SHIPPED_N):g} µm). After: two levels, {SHIPPED_N}² and "
        f"{fine}² ({_pixel_um(fine):g} µm) of the same surface, extrapolated to zero pixel size "
        f"(a_r {orders['real_contact_area_fraction']}, h̄_n {orders['mean_gap_m']}, (1/h)‾ "
        f"{orders['mean_reciprocal_gap_per_m']}; what `skisnow build-tables --pixel-levels "
        f"refine` stores, docs/tables.md), computed in this run. Both against the zero-pixel "
        f"limit from {finest[0]}² and {finest[1]}² (observed order of the three finest grids "
        "where it converges, else the finest value); `estimate` is the error the two-level "
        "value carries for itself, `table` what the shipped file returns there (interpolated; "
        f"{_shipped_levels_words(rows)}).",
        "",
        "| series | a_r before | a_r after | a_r estimate | a_r table (estimate) | h̄_n before "
        "| h̄_n after | (1/h)‾ before | (1/h)‾ after | (1/h)‾ estimate |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    ar, gap, rec = "real_contact_area_fraction", "mean_gap_m", "mean_reciprocal_gap_per_m"
    for s in rows:
        t = s["two_level"]
        shipped = s.get("shipped_table") or {}
        if ar in shipped:
            est = (shipped.get("estimate_rel") or {}).get(ar)
            cell = f"{_pct(rel_diff(shipped[ar], s['zero_pixel_limit'][ar]))}" + (
                f" ({_apct(est)})" if est is not None else " (none stored)"
            )
        else:
            cell = "—"
        out.append(
            f"| {s['grind']} {s['nominal_pressure_kpa']:g} kPa | "
            f"{_pct(t['before_rel_error'][ar])} | {_pct(t['after_rel_error'][ar])} | "
            f"{_apct(t['estimate_rel'][ar])} | {cell} | "
            f"{_pct(t['before_rel_error'][gap])} | {_pct(t['after_rel_error'][gap])} | "
            f"{_pct(t['before_rel_error'][rec])} | {_pct(t['after_rel_error'][rec])} | "
            f"{_apct(t['estimate_rel'][rec])} |"
        )
    out += ["", "![shipped tables before and after](bench/accuracy-tables-before-after.png)"]
    notes = [
        f"{s['grind']} {s['nominal_pressure_kpa']:g} kPa: {s['shipped_table_note']}"
        for s in rows
        if s.get("shipped_table_note")
    ]
    if notes:
        out += ["", "The `a_r table (estimate)` column, " + "; ".join(notes) + "."]
    return out


def _raw_gap_note() -> list[str]:
    floor_nm = DEFAULT_GAP_FLOOR_M * 1e9
    return [
        "",
        "The raw reciprocal gap (no floor) is not expected to converge: next to a contact "
        "spot the gap opens like distance^1.5, so finer pixels sample ever smaller gaps "
        "there and the mean of 1/h keeps moving with the pixel size (docs/physics.md §5). The "
        f"floored value ⟨1/max(h, {floor_nm:g} nm)⟩ is what the tables and the API report; the "
        "raw value is stored in the tables for diagnosis only. Every answer of `/v1/contact` "
        "carries the micro error of its table's pixel size, so the answer reports it: "
        "`provenance.preset` holds the preset name, the macro pixel sizes (mm) and "
        "`texture_pixel_size_um`.",
        "",
        "![micro grid size](bench/accuracy-micro.png)",
        "",
    ]


def micro_section(d: dict) -> list[str]:
    """Micro scale: grid size, convergence, the shipped grid's error, well-posedness."""
    mi = d["micro"]
    return [
        *_micro_rows(d),
        *_convergence_table(mi),
        *_shipped_grid_estimate(mi),
        *_well_posedness(mi),
        *_before_after_lines(mi),
        *_raw_gap_note(),
    ]


# --------------------------------------------------------------------------- table


def _table_cell(r: dict, m: str) -> str:
    med = [r[k][m] for k in ("held_out_median_rel_error", "direct_median_rel_error") if k in r]
    return _apct(r["max_rel_error"][m]) + (f" ({_apct(max(med))})" if med else "")


def _table_row(g: dict, r: dict) -> str:
    lk = r.get("lookup_time_per_query_s")
    de = r.get("direct_max_rel_error")
    return (
        f"| {g['grind']} | {r['points']} | {r.get('build_cost_s', float('nan')):.0f} | "
        + " | ".join(_table_cell(r, m) for m in TABLE_METRICS)
        + " | "
        + (" / ".join(_apct(de[m]) for m in TABLE_METRICS) if de else "—")
        + " | "
        + (
            f"{lk * 1e6:.0f} µs / {r['lookup_time_per_ratio_vectorised_s'] * 1e9:.0f} ns"
            if lk
            else "—"
        )
        + " |"
    )


def _table_worst(g: dict) -> list[str]:
    """Where the thinned tables' largest a_r errors sit; where a_r is so small that the
    texture touches on few pixels, why more points cannot help."""
    worst = [
        (r["points"], r["held_out_max_at"]["real_contact_area_fraction"])
        for r in g["rows"]
        if "held_out_max_at" in r
    ]
    if not worst:
        return []
    n_px = g["grid_shape"][0] * g["grid_shape"][1]
    few = [w for _k, w in worst if w["real_contact_area_fraction"] * n_px < FEW_PIXELS]
    text = f"{g['grind']}: the largest a_r errors of the thinned tables sit at " + ", ".join(
        f"P_n/E' = {w['pressure_ratio']:.2g} (a_r = "
        f"{w['real_contact_area_fraction']:.2g}, {k} points)"
        for k, w in worst
    )
    if few:
        a_max = max(w["real_contact_area_fraction"] for w in few)
        text += (
            f" — at a_r ≤ {a_max:.2g} the {g['grid_shape'][0]}² texture touches on "
            f"{a_max * n_px:.0f} pixels or fewer, so the tabulated a_r is itself step-like "
            "(pixel counting) and more pressure points cannot make interpolation agree better "
            "than that"
            + ("" if len(few) == len(worst) else "; the others are interpolation error")
            + "."
        )
    else:
        text += "."
    return ["", text]


def table_section(d: dict) -> list[str]:
    """Micro tables: interpolation of thinned tables against direct solves."""
    grinds = d["table"]["grinds"]
    lo, hi = grinds[0]["test_ratio_range"]
    lines = [
        "### Micro tables: interpolation vs a direct solve (pressure-grid density)",
        "",
        "PCHIP interpolation (in ln r) of the shipped tables thinned to fewer pressure "
        "points (ends kept), against direct solves of the same texture at the same pixel "
        "size and tolerance at off-grid ratios (geometric midpoints of the "
        f"{grinds[0]['table_points']}-point grid) and against the "
        f"{grinds[0]['table_points']}-point nodes a thinned table leaves out; test "
        f"range P_n/E' {lo:.0e} … {hi:.0e} (partial contact). Build "
        "cost = points × the median solve time recorded in the table file.",
        "",
        "Cells: largest error (median in brackets) over the held-out nodes and the direct solves.",
        "",
        "| grind | points | build cost [s] | a_r | h̄_n | (1/h)‾ floored | "
        "vs direct solves only (a_r / h̄_n / (1/h)‾) | lookup: one ratio / per ratio of "
        f"{_power_of_ten(LOOKUP_BATCH)} |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for g in grinds:
        lines += [_table_row(g, r) for r in g["rows"]]
        lines += _table_worst(g)
        if g["direct_solve_median_s"]:
            lines += [
                "",
                f"{g['grind']}: a direct solve ({g['grid_shape'][0]}², cold) takes "
                f"{g['direct_solve_median_s']:.2f} s median over {len(g['direct'])} ratios.",
                "",
            ]
    return [*lines, "", "![table interpolation](bench/accuracy-table.png)", ""]
