"""``bench accuracy`` stage ``table``: PCHIP interpolation of the shipped tables, thinned to
fewer pressure points, against direct solves (see :mod:`app.evidence.accuracy`)."""

from __future__ import annotations

import logging
import statistics
import time
from dataclasses import replace

import h5py
import numpy as np
from skisnow.app.build_tables import refinements
from skisnow.app.evidence.accuracy_common import (
    TABLE_METRICS,
    TABLES,
    AccuracyConfig,
    median_time,
)
from skisnow.solvers.elastic import PeriodicHalfSpace
from skisnow.solvers.lookup import (
    ERROR_FIELDS,
    PIXEL_EXTRAPOLATION_ORDERS,
    POINT_FIELDS,
    MicroTable,
)
from skisnow.solvers.lookup import richardson as richardson_levels
from skisnow.solvers.micro import solve_micro
from tqdm import tqdm

log = logging.getLogger(__name__)


#: ratios of one vectorised lookup, timed per ratio [-]
LOOKUP_BATCH = 10_000


def thin_table(table: MicroTable, points: int) -> MicroTable:
    """The table restricted to ``points`` of its pressure nodes, ends kept, near-even in ln r."""
    n = len(table.pressure_ratio)
    idx = np.unique(np.round(np.linspace(0, n - 1, points)).astype(int))
    arrays = {name: np.asarray(getattr(table, name))[idx] for name in POINT_FIELDS}
    if table.has_error_estimates:
        arrays.update(
            {name: np.asarray(getattr(table, name))[idx] for name in ERROR_FIELDS.values()}
        )
    return replace(table, **arrays, levels=None)


def _lookup(table: MicroTable, ratio: np.ndarray) -> dict[str, np.ndarray]:
    from skisnow.solvers import lookup as L

    return {
        "real_contact_area_fraction": np.asarray(L.real_contact_area_fraction(table, ratio, 1.0)),
        "mean_gap_m": np.asarray(L.mean_gap_m(table, ratio, 1.0)),
        "mean_reciprocal_gap_per_m": np.asarray(L.mean_reciprocal_gap_per_m(table, ratio, 1.0)),
    }


def bench_table(cfg: AccuracyConfig, bar: tqdm) -> dict:
    from skisnow.app.storage.tables import read_table, read_table_heights

    out = {"points": list(cfg.table_points), "grinds": []}
    for grind in cfg.table_grinds:
        path = TABLES / f"{grind}.h5"
        table = read_table(path)
        with h5py.File(path, "r") as f:
            node_times = np.asarray(f["diagnostics/solve_time_s"]) if "diagnostics" in f else None
        r_all = np.asarray(table.pressure_ratio)
        lo, hi = cfg.table_ratio_range
        partial = ~np.asarray(table.full_contact)
        # off-grid test ratios: geometric midpoints of the 72-point grid inside the range
        mids = np.sqrt(r_all[:-1] * r_all[1:])
        mids = mids[(mids >= lo) & (mids <= hi) & partial[1:]]
        if cfg.table_direct_points > 0 and mids.size:
            pick = np.unique(
                np.round(np.linspace(0, mids.size - 1, cfg.table_direct_points)).astype(int)
            )
            mids = mids[pick]
        else:
            mids = mids[:0]
        direct = []
        if mids.size:
            # the reference is computed like the table's value: one level, or the two finest
            # pixel levels extrapolated to zero pixel size (two- and three-level tables)
            h, _ = read_table_heights(path)
            levels = [(h, table.pixel_size_m)]
            factors = refinements(table.attrs.get("pixel_levels", "none"))
            if factors:
                from skisnow.app.storage.textures import refined_texture

                for k in factors:
                    fine = refined_texture(grind, k)
                    levels.append((fine.heights_m, fine.pixel_size_m))
                levels = levels[-2:]
            e = table.effective_modulus_pa
            spaces = [PeriodicHalfSpace(hh.shape, dx, e) for hh, dx in levels]
            for r in mids:
                t0 = time.perf_counter()
                res = [
                    solve_micro(
                        hh,
                        dx,
                        r * e,
                        e,
                        tol=table.tol,
                        gap_floor_m=table.gap_floor_m,
                        halfspace=hs,
                    )
                    for (hh, dx), hs in zip(levels, spaces, strict=True)
                ]
                values = {k: float(getattr(res[-1], k)) for k in TABLE_METRICS}
                if len(res) == 2:
                    for k in TABLE_METRICS:
                        values[k] = float(
                            richardson_levels(
                                getattr(res[0], k),
                                getattr(res[1], k),
                                PIXEL_EXTRAPOLATION_ORDERS[k],
                            )[0]
                        )
                direct.append(
                    {
                        "pressure_ratio": float(r),
                        "time_s": time.perf_counter() - t0,
                        "converged": all(x.converged for x in res),
                        "levels": len(res),
                        **values,
                    }
                )
                bar.update(1)
        direct_time = statistics.median(d["time_s"] for d in direct) if direct else None
        node_time = float(np.median(node_times[node_times > 0])) if node_times is not None else None
        rows = []
        for k in cfg.table_points:
            sub = thin_table(table, k)
            row = {"points": len(sub.pressure_ratio)}
            # held-out nodes of the 72-point table inside the test range (partial contact)
            held = np.setdiff1d(r_all[partial], sub.pressure_ratio)
            held = held[(held >= lo) & (held <= hi)]
            if held.size:
                got = _lookup(sub, held)
                idx = np.searchsorted(r_all, held)
                err = {
                    m: np.abs(got[m] / np.asarray(getattr(table, m))[idx] - 1)
                    for m in TABLE_METRICS
                }
                row["held_out_nodes"] = int(held.size)
                row["held_out_max_rel_error"] = {m: float(e.max()) for m, e in err.items()}
                row["held_out_median_rel_error"] = {m: float(np.median(e)) for m, e in err.items()}
                row["held_out_max_at"] = {
                    m: {
                        "pressure_ratio": float(held[np.argmax(e)]),
                        "real_contact_area_fraction": float(
                            table.real_contact_area_fraction[idx[np.argmax(e)]]
                        ),
                    }
                    for m, e in err.items()
                }
            if direct:
                rr = np.array([d["pressure_ratio"] for d in direct])
                got = _lookup(sub, rr)  # also builds the interpolants (once per table)
                row["lookup_time_per_query_s"] = median_time(
                    lambda sub=sub, r1=rr[:1]: _lookup(sub, r1), 21
                )[0]
                many = np.geomspace(lo, hi, LOOKUP_BATCH)
                row["lookup_time_per_ratio_vectorised_s"] = (
                    median_time(lambda sub=sub, many=many: _lookup(sub, many), 5)[0] / many.size
                )
                err = {
                    m: np.abs(got[m] / np.array([d[m] for d in direct]) - 1) for m in TABLE_METRICS
                }
                row["direct_max_rel_error"] = {m: float(e.max()) for m, e in err.items()}
                row["direct_median_rel_error"] = {m: float(np.median(e)) for m, e in err.items()}
            # None: not measured (the full table has no held-out nodes; --quick has no solves)
            row["max_rel_error"] = {
                m: max(
                    (
                        row[k][m]
                        for k in ("held_out_max_rel_error", "direct_max_rel_error")
                        if k in row
                    ),
                    default=None,
                )
                for m in TABLE_METRICS
            }
            if node_time is not None:
                row["build_cost_s"] = row["points"] * node_time
            rows.append(row)
        out["grinds"].append(
            {
                "grind": grind,
                "texture_pixel_um": table.pixel_size_m * 1e6,
                "grid_shape": list(table.grid_shape),
                "table_points": len(r_all),
                "test_ratio_range": [lo, hi],
                "node_solve_time_s": node_time,
                "direct_solve_median_s": direct_time,
                "direct": direct,
                "rows": rows,
            }
        )
    return out
