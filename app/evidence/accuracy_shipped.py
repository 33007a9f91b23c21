"""``bench accuracy`` stage ``shipped``: the shipped tables' own pixel-size error estimates
over the partial-contact range (issue #13 point 3: ≤ 3 % in a_r for a_r in
:data:`solvers.lookup.ESTIMATE_RANGE_A_R`; issue #29: from the light-load range's low end,
a_r 1e-4, :data:`SHIPPED_RANGE_A_R`). No solve: the estimates the table files store
(:func:`solvers.lookup.combine_pixel_levels` and the three- and four-level rules), read from
the files the service answers with, and its section of ``docs/benchmarks.md``.
"""

from __future__ import annotations

import numpy as np
from skisnow.app.evidence.accuracy_common import AccuracyConfig
from skisnow.app.storage.common import tables_dir
from skisnow.app.storage.tables import read_table
from skisnow.solvers.lookup import ERROR_FIELDS, ESTIMATE_RANGE_A_R, LIGHT_LOAD_RANGE_A_R

__all__ = ["TARGET_A_R_ESTIMATE", "bench_shipped", "shipped_section"]

#: the issue's target for the a_r estimate over the range [-]
TARGET_A_R_ESTIMATE = 0.03
#: the a_r range the shipped tables' estimates are reported over [-]: issue #29's 1e-4 … 0.9
#: (the light-load levels' range, then issue #13's estimate range)
SHIPPED_RANGE_A_R = (LIGHT_LOAD_RANGE_A_R[0], ESTIMATE_RANGE_A_R[1])
_LABELS = {
    "real_contact_area_fraction": "a_r",
    "mean_gap_m": "h̄_n",
    "mean_reciprocal_gap_per_m": "(1/h)‾ floored",
}


def shipped_estimates(table) -> dict:
    """Largest stored relative estimate per quantity over the nodes with a_r in the range."""
    a_r = np.asarray(table.real_contact_area_fraction, dtype=float)
    lo, hi = SHIPPED_RANGE_A_R
    in_range = (a_r >= lo) & (a_r <= hi)
    levels = table.levels or {}
    out: dict = {
        "grind": table.name,
        "pixel_levels": str(table.attrs.get("pixel_levels", "none")),
        "level_pixel_size_um": [float(v) * 1e6 for v in levels.get("pixel_size_m", [])],
        "fourth_level_node_ratios": [
            float(table.pressure_ratio[i]) for i in np.asarray(table.fourth_level_nodes, int)
        ],
        "range_a_r": list(SHIPPED_RANGE_A_R),
        "light_load_node_ratios": [
            float(table.pressure_ratio[i]) for i in np.asarray(table.light_load_nodes, int)
        ],
        "light_load_pixel_size_um": [float(v) * 1e6 for v in levels.get("light_pixel_size_m", [])],
        "nodes_in_range": int(in_range.sum()),
        "max_rel_estimate": {},
    }
    for quantity, err_name in ERROR_FIELDS.items():
        err = getattr(table, err_name, None)
        if err is None or not in_range.any():
            out["max_rel_estimate"][quantity] = None
            continue
        value = np.asarray(getattr(table, quantity), dtype=float)[in_range]
        rel = np.asarray(err, dtype=float)[in_range] / np.abs(value)
        k = int(np.argmax(rel))
        out["max_rel_estimate"][quantity] = {
            "rel": float(rel[k]),
            "pressure_ratio": float(np.asarray(table.pressure_ratio)[in_range][k]),
            "a_r": float(a_r[in_range][k]),
        }
    return out


def bench_shipped(cfg: AccuracyConfig, bar=None) -> dict:
    """The stage: :func:`shipped_estimates` of each of ``cfg.table_grinds``' shipped tables."""
    rows = [shipped_estimates(read_table(tables_dir() / f"{g}.h5")) for g in cfg.table_grinds]
    return {"target_a_r_rel": TARGET_A_R_ESTIMATE, "tables": rows}


def _cell(entry: dict | None) -> str:
    if entry is None:
        return "none stored"
    return f"{entry['rel'] * 100:.2f} % (a_r {entry['a_r']:.3g}, r = {entry['pressure_ratio']:.3g})"


def shipped_section(d: dict) -> list[str]:
    """Section of docs/benchmarks.md for the ``shipped`` stage."""
    st = d["shipped"]
    target = st["target_a_r_rel"]
    rows = st["tables"]
    lo, hi = rows[0]["range_a_r"] if rows else SHIPPED_RANGE_A_R
    worst = [r["max_rel_estimate"]["real_contact_area_fraction"] for r in rows]
    met = all(w is not None and w["rel"] <= target for w in worst)
    out = [
        "",
        "### Shipped tables: their own pixel-size error estimate",
        "",
        f"The largest relative error estimate each shipped table stores for itself, over its "
        f"nodes with a_r from {lo:g} to {hi:g} (the partial-contact range of issue #13 from "
        "1e-3, of issue #29 from 1e-4: docs/tables.md, Pixel size and Light-load levels), per "
        "quantity, with where it is. Target for a_r: "
        f"≤ {target * 100:g} %: {'met by every table' if met else '**not met**'}.",
        "",
        "| table | pixel levels [µm] | fourth level at r | light-load levels [µm] at nodes | "
        "nodes in range | " + " | ".join(f"largest {v} estimate" for v in _LABELS.values()) + " |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        sizes = ", ".join(f"{v:g}" for v in r["level_pixel_size_um"]) or "one level"
        fourth = ", ".join(f"{v:.3g}" for v in r["fourth_level_node_ratios"]) or "—"
        light = r.get("light_load_node_ratios") or []
        light_cell = (
            ", ".join(f"{v:g}" for v in r.get("light_load_pixel_size_um", []))
            + f" at {len(light)} nodes, r = {light[0]:.3g} … {light[-1]:.3g}"
            if light
            else "—"
        )
        cells = " | ".join(_cell(r["max_rel_estimate"][q]) for q in _LABELS)
        out.append(
            f"| {r['grind']} ({r['pixel_levels']}) | {sizes} | {fourth} | {light_cell} | "
            f"{r['nodes_in_range']} | {cells} |"
        )
    return [*out, ""]
