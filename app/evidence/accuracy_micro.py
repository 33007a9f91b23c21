"""``bench accuracy`` stage ``micro``: one texture solve at 256² … 4096² pixels on the same
patch, against the finest grid and the zero-pixel limit (see :mod:`app.evidence.accuracy`)."""

from __future__ import annotations

import json
import logging

import h5py
import numpy as np
from skisnow.app.evidence.accuracy_common import (
    MICRO_E_EFF_PA,
    MICRO_METRICS,
    MICRO_PATCH_M,
    PRESSURE_STEP,
    SHIPPED_N,
    TABLES,
    AccuracyConfig,
    convergence,
    median_time,
    rel_diff,
    zero_pixel_limit,
)
from skisnow.solvers.elastic import PeriodicHalfSpace
from skisnow.solvers.lookup import (
    ERROR_FIELDS,
    PIXEL_EXTRAPOLATION_ORDERS,
    relative_error_estimate,
)
from skisnow.solvers.lookup import richardson as richardson_levels
from skisnow.solvers.micro import solve_micro
from skisnow.solvers.texture import GrindParameters, linear_grind
from tqdm import tqdm

log = logging.getLogger(__name__)


def grind_generator(name: str) -> tuple[GrindParameters, int, float]:
    """Generator parameters, seed and pixel size [m] of a shipped synthetic grind."""
    with h5py.File(TABLES / "textures" / f"{name}.h5", "r") as f:
        params = GrindParameters(**json.loads(f.attrs["generator_parameters_json"]))
        return params, int(f.attrs["generator_seed"]), float(f.attrs["pixel_size_m"])


def block_average(h: np.ndarray, n: int) -> np.ndarray:
    """Average ``h`` (N×N) over k×k blocks down to n×n, k = N/n."""
    k = h.shape[0] // n
    if k * n != h.shape[0]:
        raise ValueError(f"grid {h.shape[0]} is not a multiple of {n}")
    return h.reshape(n, k, n, k).mean(axis=(1, 3))


def _shipped_surface(name: str, n: int) -> np.ndarray:
    """The shipped texture's surface on an n×n grid of the same patch [m]: refined by its
    generator when n > 1024 (n/1024 in 2, 4, 8), else the generator on n² (other draws)."""
    params, seed, _ = grind_generator(name)
    if n > SHIPPED_N and n % SHIPPED_N == 0 and n // SHIPPED_N in (2, 4, 8):
        return linear_grind(
            (SHIPPED_N, SHIPPED_N), MICRO_PATCH_M / SHIPPED_N, params, seed, refine=n // SHIPPED_N
        )
    return linear_grind((n, n), MICRO_PATCH_M / n, params, seed)


def _two_level(rows: list[dict], limit: dict) -> dict | None:
    """The shipped tables' two-level value at one pressure (1024², 2048²) against ``limit``."""
    ns = [r["n"] for r in rows]
    if SHIPPED_N not in ns or 2 * SHIPPED_N not in ns[:-1]:
        return None
    c, f = rows[ns.index(SHIPPED_N)], rows[ns.index(2 * SHIPPED_N)]
    out = {"value": {}, "estimate_rel": {}, "before_rel_error": {}, "after_rel_error": {}}
    for m in ERROR_FIELDS:
        value, err = richardson_levels(c[m], f[m], PIXEL_EXTRAPOLATION_ORDERS[m])
        out["value"][m] = float(value)
        out["estimate_rel"][m] = float(err / abs(value))
        out["before_rel_error"][m] = rel_diff(c[m], limit[m])
        out["after_rel_error"][m] = rel_diff(float(value), limit[m])
    out["time_s"] = c["median_time_s"] + f["median_time_s"]
    return out


def _shipped_table_at(grind: str, pressure_ratio: float) -> dict | None:
    """What the shipped table returns at a ratio, with its stored relative estimate."""
    from skisnow.app.storage.tables import read_table
    from skisnow.solvers import lookup as L

    table = read_table(TABLES / f"{grind}.h5")
    e = table.effective_modulus_pa
    p = pressure_ratio * e
    out = {
        "pixel_levels": table.attrs.get("pixel_levels", "none"),
        "real_contact_area_fraction": float(L.real_contact_area_fraction(table, p, e)),
        "mean_gap_m": float(L.mean_gap_m(table, p, e)),
        "mean_reciprocal_gap_per_m": float(L.mean_reciprocal_gap_per_m(table, p, e)),
    }
    out["estimate_rel"] = {m: relative_error_estimate(table, p, e, m) for m in ERROR_FIELDS}
    return out


def bench_micro_grid(cfg: AccuracyConfig, bar: tqdm) -> dict:
    sizes = sorted(cfg.micro_sizes)
    n_ref = sizes[-1]
    out = {
        "sizes": sizes,
        "patch_mm": MICRO_PATCH_M * 1e3,
        "surface": "shipped texture refined by its generator"
        if n_ref > SHIPPED_N
        else "generator at the finest grid",
        "series": [],
    }
    for grind in cfg.micro_grinds:
        fine = _shipped_surface(grind, n_ref)
        for p_n in cfg.micro_pressures_pa:
            rows = []
            for n in sizes:
                h = block_average(fine, n)
                dx = MICRO_PATCH_M / n
                hs = PeriodicHalfSpace(h.shape, dx, MICRO_E_EFF_PA)
                med, times, res = median_time(
                    lambda h=h, dx=dx, hs=hs, p_n=p_n: solve_micro(
                        h, dx, p_n, MICRO_E_EFF_PA, halfspace=hs
                    ),
                    cfg.micro_repeats if n <= 2 * SHIPPED_N else 1,  # the 4096² reference once
                )
                # well-posedness: d ln f / d ln P_n from a +0.1 % pressure step (O(1) for a
                # well-posed metric; huge when a metric hangs on the gaps of a few pixels)
                step = PRESSURE_STEP
                pert = solve_micro(h, dx, p_n * (1 + step), MICRO_E_EFF_PA, halfspace=hs)
                sens = {
                    k: rel_diff(float(getattr(pert, k)), float(getattr(res, k))) / step
                    for k in MICRO_METRICS
                }
                rows.append(
                    {
                        "n": n,
                        "pixel_um": dx * 1e6,
                        "median_time_s": med,
                        "times_s": times,
                        "iterations": res.iterations,
                        "converged": res.converged,
                        **{k: float(getattr(res, k)) for k in MICRO_METRICS},
                        "log_sensitivity_to_pressure": sens,
                    }
                )
                bar.update(1)
            ref = rows[-1]
            for r in rows:
                r["rel_error"] = {k: rel_diff(r[k], ref[k]) for k in MICRO_METRICS}
                r["time_ratio_vs_reference"] = r["median_time_s"] / ref["median_time_s"]
            conv = {k: convergence([r[k] for r in rows]) for k in MICRO_METRICS}
            limit = {k: zero_pixel_limit([r[k] for r in rows], conv[k]) for k in ERROR_FIELDS}
            series = {
                "grind": grind,
                "nominal_pressure_kpa": p_n / 1e3,
                "pressure_ratio": p_n / MICRO_E_EFF_PA,
                "rows": rows,
                "convergence": conv,
                "zero_pixel_limit": limit,
                "two_level": _two_level(rows, limit),
            }
            try:
                series["shipped_table"] = _shipped_table_at(grind, p_n / MICRO_E_EFF_PA)
            except Exception as exc:
                series["shipped_table"] = {"error": str(exc)}
            out["series"].append(series)
    return out
