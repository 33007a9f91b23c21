"""``skisnow bench accuracy``: error against a converged reference versus time, for each stage.

Stages (issue #6 §2), each measured in the same run so that times compare as ratios:

- ``micro``: one texture solve at 256² … 4096² pixels on the **same 1.536 mm patch** (finer
  pixels on the same area, not a larger area). The grind is the shipped texture's surface
  refined to the finest grid (:func:`solvers.texture.linear_grind` with ``refine``: same
  parameters, seed and random draws); coarser grids are block averages of it (area-averaged
  pixels, as an interferometer records them), so 1024² is the shipped texture. Reference: the
  finest grid. The two-level value of the shipped tables (zero-pixel extrapolation from 1024²
  and 2048², :func:`solvers.lookup.combine_pixel_levels`) is compared with the limit from the
  finer grids (before: 1024² alone; after: the two-level value).
  Every metric of :class:`solvers.micro.MicroResult` is checked for convergence: the floored
  reciprocal gap should converge, the raw one (no floor) is expected not to (method.md §5).
- ``table``: PCHIP interpolation of the shipped 72-point tables and of tables thinned to fewer
  pressure points against direct solves of the same texture at off-grid pressures (and at the
  72-point nodes a thinned table leaves out).
- ``macro`` and ``end-to-end``: :func:`app.service.contact` (the computation of
  ``POST /v1/contact``) at candidate macro grids against a fine reference grid, on the same
  table; the named presets of :mod:`app.presets` are marked on the error-versus-time front.
- ``network``: the camber network of each ski against the beam model it learned, through the
  whole computation.

Results go to ``docs/bench/accuracy.json`` and charts ``docs/bench/accuracy-<stage>.png`` via
:func:`app.bench._write_stage`, which regenerates ``docs/benchmarks.md``.
"""

from __future__ import annotations

import argparse
import json
import logging
import statistics
import tempfile
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import h5py
import numpy as np
from skisnow.app.build_tables import refinements
from skisnow.app.presets import DEFAULT_PRESET, PRESETS, Preset
from skisnow.app.storage.common import provenance, tables_dir
from skisnow.solvers.beam import G_STANDARD, BeamFlexibility, solve_beam_contact
from skisnow.solvers.elastic import PeriodicHalfSpace, effective_modulus
from skisnow.solvers.lookup import (
    ERROR_FIELDS,
    PIXEL_EXTRAPOLATION_ORDERS,
    POINT_FIELDS,
    MicroTable,
    relative_error_estimate,
)
from skisnow.solvers.lookup import richardson as richardson_levels
from skisnow.solvers.micro import solve_micro
from skisnow.solvers.texture import GrindParameters, linear_grind
from tqdm import tqdm

TABLES = tables_dir()
log = logging.getLogger(__name__)

#: metrics of one micro solve (MicroResult attribute, label with unit)
MICRO_METRICS = {
    "real_contact_area_fraction": "real contact area fraction a_r",
    "mean_gap_m": "mean gap h̄_n",
    "mean_reciprocal_gap_per_m": "reciprocal gap (1/h)‾, floored at 10 nm",
    "mean_reciprocal_gap_raw_per_m": "reciprocal gap (1/h)‾, raw (no floor)",
}
#: metrics a table interpolates (MicroTable array, lookup function name)
TABLE_METRICS = {
    "real_contact_area_fraction": "real_contact_area_fraction",
    "mean_gap_m": "mean_gap_m",
    "mean_reciprocal_gap_per_m": "mean_reciprocal_gap_per_m",
}
#: metrics of an answer of /v1/contact compared between settings (path in the answer)
ANSWER_METRICS = {
    "apparent_contact_area": ("apparent", "contact_area_cm2"),
    "total_real_contact_area": ("metrics", "total_real_contact_area_mm2"),
    "average_real_contact_pressure": ("metrics", "average_real_contact_pressure_mpa"),
    "min_average_separation": ("metrics", "min_average_separation_um"),
    "total_reciprocal_separation": ("metrics", "total_reciprocal_separation_m"),
}
#: the minimum average separation is a minimum over X of a pointwise quantity: where it sits
#: at a short contact (tip or tail point) it follows the edge-singular peak pressure and does
#: not converge with the macro grid (like the peak pressure, docs/macro.md); presets are
#: chosen on the other metrics and it is reported beside them
CONVERGING_METRICS = tuple(m for m in ANSWER_METRICS if m != "min_average_separation")
#: largest error of the converging metrics each preset may have against the reference [-]:
#: `default` stays at the size of the micro-scale error the shipped tables carry at 1.5 µm
#: pixels (a_r +2 … +21 %, floored reciprocal gap 1 … 3 %, micro stage), so the macro grid is
#: not the dominant error; `fine` for comparisons closer than 1 %; `fast` for previews: the
#: grids between it and the default save no time measurable on a loaded machine (1–2 ms)
PRESET_TOLERANCES = {"fast": 0.15, "default": 0.025, "fine": 0.01}


#: (load_kg, load_position_mm, snow_modulus_mpa, porosity) of the end-to-end cases
LOAD_CASES = ((40.0, -160.0, 200.0, 0.5), (70.0, -80.0, 100.0, 0.4), (20.0, -250.0, 400.0, 0.6))


@dataclass(frozen=True)
class AccuracyConfig:
    """Sizes of one accuracy run (``--quick`` shrinks every stage to a smoke test)."""

    micro_sizes: tuple[int, ...] = (256, 512, 1024, 2048, 4096)
    micro_grinds: tuple[str, ...] = ("grind-1", "grind-2")
    #: nominal pressures P_n of the micro study [Pa] (at E' of 200 MPa snow on 0.7 GPa base)
    micro_pressures_pa: tuple[float, ...] = (15e3, 60e3)
    micro_repeats: int = 3
    table_grinds: tuple[str, ...] = ("grind-1", "grind-2")
    table_points: tuple[int, ...] = (9, 18, 36, 72)
    #: off-grid pressure ratios solved directly (0: held-out nodes only)
    table_direct_points: int = 8
    table_ratio_range: tuple[float, float] = (1e-6, 1e-2)
    #: candidate macro grids (pixel along [mm], pixels across); the presets are added
    grids: tuple[tuple[float, int], ...] = (
        (8.0, 4),
        (8.0, 8),
        (6.0, 8),
        (4.0, 4),
        (4.0, 8),
        (2.0, 8),
        (2.0, 16),
        (1.0, 8),
        (1.0, 16),
        (0.5, 16),
        (0.5, 32),
        (0.25, 16),
    )
    reference_grid: tuple[float, int] = (0.5, 64)
    #: end-to-end cases: (ski, grind, load_kg, load_position_mm, snow_modulus_mpa, porosity)
    cases: tuple[tuple, ...] = tuple(
        (ski, grind, *load)
        for ski in ("ski-a", "ski-b")
        for grind in ("grind-1", "grind-2")
        for load in LOAD_CASES
    )
    e2e_repeats: int = 5
    reference_repeats: int = 2
    network_skis: tuple[str, ...] = ("ski-a", "ski-b")
    network_loads_kg: tuple[float, ...] = (15.0, 30.0, 45.0, 60.0, 75.0)
    network_positions_mm: tuple[float, ...] = (-275.0, -175.0, -125.0, -25.0, 75.0)
    network_grind: str = "grind-1"
    network_repeats: int = 5
    stages: tuple[str, ...] = ("micro", "table", "end-to-end", "network")
    extra: dict = field(default_factory=dict)


QUICK = AccuracyConfig(
    micro_sizes=(64, 128, 256),
    micro_grinds=("grind-1",),
    micro_pressures_pa=(60e3,),
    micro_repeats=1,
    table_grinds=("grind-1",),
    table_direct_points=0,
    grids=((8.0, 4), (4.0, 8)),
    reference_grid=(2.0, 8),
    cases=(("ski-a", "grind-1", 40.0, -160.0, 200.0, 0.5),),
    e2e_repeats=1,
    reference_repeats=1,
    network_skis=("ski-a",),
    network_loads_kg=(45.0,),
    network_positions_mm=(-175.0,),
    network_repeats=1,
)

#: E' of the micro study: 200 MPa snow on a 0.7 GPa base, ν = 0.3 [Pa]
MICRO_E_EFF_PA = effective_modulus(200e6, 0.7e9, 0.3)
#: physical size of the micro patch: the shipped textures' 1024 × 1.5 µm [m]
MICRO_PATCH_M = 1024 * 1.5e-6


def _median_time(fn, repeats: int) -> tuple[float, list[float], object]:
    times, out = [], None
    for _ in range(max(repeats, 1)):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times, out


def _rel(value: float, ref: float) -> float:
    return float(value / ref - 1) if ref != 0 else float("nan")


def convergence(values: list[float], ratio_min: float = 1.4, bound: float = 0.05) -> dict:
    """Classify a refinement sequence (coarse → fine) by its successive differences.

    ``converges``: every successive difference is smaller than the previous one by at least
    ``ratio_min`` (halving the pixel should shrink the change); the observed order is ``log2``
    of the last ratio. Otherwise ``converges slowly`` if the sequence is monotone and its last
    change is at most half its first, ``bounded`` if every change relative to the finest value
    stays within ``bound`` (no clear order, but small), else ``does not converge``.
    """
    v = np.asarray(values, dtype=float)
    steps = np.diff(v)
    d = np.abs(steps)
    ratios = d[:-1] / np.maximum(d[1:], 1e-300)
    ok = bool(len(ratios) > 0 and np.all(ratios >= ratio_min))
    rel = d / abs(v[-1]) if v[-1] != 0 else d * np.inf
    monotone = bool(np.all(steps >= 0) or np.all(steps <= 0))
    if ok:
        verdict = "converges"
    elif monotone and len(d) > 1 and d[-1] <= d[0] / 2:
        verdict = "converges slowly"
    elif np.all(rel <= bound):
        verdict = "bounded"
    else:
        verdict = "does not converge"
    return {
        "converges": ok,
        "verdict": verdict,
        "max_relative_change": float(rel.max()) if rel.size else 0.0,
        "successive_differences": d.tolist(),
        "difference_ratios": ratios.tolist(),
        "observed_order": float(np.log2(ratios[-1])) if len(ratios) and ratios[-1] > 0 else None,
    }


def richardson(values: list[float], order: float) -> float:
    """Zero-pixel limit from the two finest values of a halving sequence with ``order``."""
    p = min(max(order, 0.5), 4.0)
    return values[-1] + (values[-1] - values[-2]) / (2**p - 1)


def zero_pixel_limit(values: list[float], conv: dict) -> float:
    """The bench's estimate of the zero-pixel limit: Richardson from the two finest values
    with the observed order where the sequence converges, else the finest value."""
    if conv["verdict"] == "converges" and conv["observed_order"] is not None:
        return float(richardson(values, conv["observed_order"]))
    return float(values[-1])


# --------------------------------------------------------------------------- micro


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


#: grid of the shipped textures [-]; levels of the two-level tables (this and twice as fine)
SHIPPED_N = 1024


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
        out["before_rel_error"][m] = _rel(c[m], limit[m])
        out["after_rel_error"][m] = _rel(float(value), limit[m])
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
                med, times, res = _median_time(
                    lambda h=h, dx=dx, hs=hs, p_n=p_n: solve_micro(
                        h, dx, p_n, MICRO_E_EFF_PA, halfspace=hs
                    ),
                    cfg.micro_repeats if n <= 2 * SHIPPED_N else 1,  # the 4096² reference once
                )
                # well-posedness: d ln f / d ln P_n from a +0.1 % pressure step (O(1) for a
                # well-posed metric; huge when a metric hangs on the gaps of a few pixels)
                step = 1e-3
                pert = solve_micro(h, dx, p_n * (1 + step), MICRO_E_EFF_PA, halfspace=hs)
                sens = {
                    k: _rel(float(getattr(pert, k)), float(getattr(res, k))) / step
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
                r["rel_error"] = {k: _rel(r[k], ref[k]) for k in MICRO_METRICS}
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


# --------------------------------------------------------------------------- table


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
                row["lookup_time_per_query_s"] = _median_time(
                    lambda sub=sub, r1=rr[:1]: _lookup(sub, r1), 21
                )[0]
                many = np.geomspace(lo, hi, 10_000)
                row["lookup_time_per_ratio_vectorised_s"] = (
                    _median_time(lambda sub=sub, many=many: _lookup(sub, many), 5)[0] / many.size
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


# --------------------------------------------------------------------------- end to end


def _catalogue():
    """The shipped catalogue, verified against its manifests when they match.

    Other jobs may be rewriting the demo ski files (retraining the camber networks) while a
    benchmark runs; then the files are read as they are, unverified, and the stage records
    the sha256 of every file it used (``catalogue``) instead of failing.
    """
    from skisnow.app import service
    from skisnow.app.storage.common import sha256_file
    from skisnow.app.storage.skis import read_ski
    from skisnow.app.storage.tables import read_table
    from skisnow.solvers.errors import DataFileError

    try:
        cat = service.load_catalogue(TABLES)
        verified = True
    except DataFileError as exc:
        log.warning("catalogue not verified (%s); reading the files as they are", exc)
        cat = service.Catalogue(tables_dir=TABLES)
        for path in sorted(TABLES.glob("grind-*.h5")):
            table = read_table(path)
            cat.grinds[table.name] = service.Grind(table.name, path, sha256_file(path), table)
        for path in sorted((TABLES / "skis").glob("*.h5")):
            cat.skis[path.stem] = service.Ski(path.stem, path, sha256_file(path), read_ski(path))
        verified = False
    files = {
        "verified_against_manifest": verified,
        "files": {
            **{g.path.name: g.sha256 for g in cat.grinds.values()},
            **{f"skis/{s.path.name}": s.sha256 for s in cat.skis.values()},
        },
    }
    return cat, files


def _grid_name(dx_mm: float, ny: int) -> str:
    return f"{dx_mm:g} mm × {ny}"


def candidate_presets(cfg: AccuracyConfig) -> dict[str, Preset]:
    """The candidate grids as presets, plus the named presets and the reference."""
    out: dict[str, Preset] = {}
    grids = list(cfg.grids) + [(p.pixel_along_m * 1e3, p.pixels_across) for p in PRESETS.values()]
    for dx, ny in grids:
        name = _grid_name(dx, ny)
        out.setdefault(name, Preset(name, dx * 1e-3, int(ny), float("nan"), "candidate"))
    dx, ny = cfg.reference_grid
    out["reference"] = Preset("reference", dx * 1e-3, int(ny), 0.0, "reference")
    return out


def _answer_value(ans: dict, metric: str) -> float:
    a, b = ANSWER_METRICS[metric]
    return float(ans[a][b])


def pareto_front(points: list[tuple[float, float, str]]) -> list[str]:
    """Names of the points no other point beats in both time and error (time, error, name)."""
    front, best = [], float("inf")
    for _t, e, name in sorted(points):
        if e < best:
            front.append(name)
            best = e
    return front


def bench_end_to_end(cfg: AccuracyConfig, bar: tqdm) -> dict:
    from skisnow.app import service

    cat, verified = _catalogue()
    cands = candidate_presets(cfg)
    named = {_grid_name(p.pixel_along_m * 1e3, p.pixels_across): k for k, p in PRESETS.items()}
    cases = []
    for ski, grind, kg, pos, snow, por in cfg.cases:
        # rigid: the stages' errors are measured on one model (auto could switch models
        # between a preset and its reference)
        inp = service.ContactInputs(ski, grind, kg, pos, snow, por, ski_model="rigid")
        case = {
            "ski": ski,
            "grind": grind,
            "load_kg": kg,
            "load_position_mm": pos,
            "snow_modulus_mpa": snow,
            "porosity": por,
            "settings": {},
        }
        for name in cands:
            inp_p = replace(inp, preset=name)
            service.contact(cat, inp_p, presets=cands)  # warm-up: kernel caches, numba
            reps = cfg.reference_repeats if name == "reference" else cfg.e2e_repeats
            answers = [service.contact(cat, inp_p, presets=cands) for _ in range(reps)]
            ans = answers[0]
            case["settings"][name] = {
                "median_total_s": statistics.median(a["timing_ms"]["total"] for a in answers) / 1e3,
                "median_macro_s": statistics.median(a["timing_ms"]["macro"] for a in answers) / 1e3,
                "median_profile_s": statistics.median(a["timing_ms"]["profile"] for a in answers)
                / 1e3,
                "macro_iterations": ans["provenance"]["macro"]["iterations"],
                **{m: _answer_value(ans, m) for m in ANSWER_METRICS},
            }
            bar.update(1)
        ref = case["settings"]["reference"]
        for s in case["settings"].values():
            s["rel_error"] = {m: _rel(s[m], ref[m]) for m in ANSWER_METRICS}
        cases.append(case)
    settings = []
    for name, preset in cands.items():
        rows = [c["settings"][name] for c in cases]
        max_err = {m: max(abs(r["rel_error"][m]) for r in rows) for m in ANSWER_METRICS}
        settings.append(
            {
                "name": name,
                "preset": named.get(name, "reference" if name == "reference" else None),
                "pixel_along_mm": preset.pixel_along_m * 1e3,
                "pixels_across": preset.pixels_across,
                "median_total_s": statistics.median(r["median_total_s"] for r in rows),
                "median_macro_s": statistics.median(r["median_macro_s"] for r in rows),
                "max_rel_error": max_err,
                "max_rel_error_converging": max(max_err[m] for m in CONVERGING_METRICS),
            }
        )
    base = next(s for s in settings if s["preset"] == DEFAULT_PRESET)
    for s in settings:
        s["time_ratio_vs_default"] = s["median_total_s"] / base["median_total_s"]
    cand = [s for s in settings if s["name"] != "reference"]
    front = pareto_front(
        [(s["median_total_s"], s["max_rel_error_converging"], s["name"]) for s in cand]
    )
    macro_front = pareto_front(
        [
            (s["median_macro_s"], s["max_rel_error"]["apparent_contact_area"], s["name"])
            for s in cand
        ]
    )
    choice = {}
    for label, tol in PRESET_TOLERANCES.items():
        ok = [s for s in cand if s["name"] in front and s["max_rel_error_converging"] <= tol]
        choice[label] = {
            "tolerance": tol,
            "fastest_on_front": min(ok, key=lambda s: s["median_total_s"])["name"] if ok else None,
        }
    return {
        "reference": _grid_name(*cfg.reference_grid),
        "catalogue": verified,
        "presets": {k: asdict(p) for k, p in PRESETS.items()},
        "cases": cases,
        "settings": settings,
        "front": front,
        "macro_front": macro_front,
        "rule": choice,
    }


# --------------------------------------------------------------------------- network


def bench_network(cfg: AccuracyConfig, bar: tqdm) -> dict:
    from skisnow.solvers import camber
    from skisnow.solvers.macro import extrude_profile, solve_macro
    from skisnow.solvers.multiscale import multiscale

    cat, verified = _catalogue()
    grind = cat.grind(cfg.network_grind)
    e_eff = MICRO_E_EFF_PA
    porosity = 0.5
    out = {"grind": cfg.network_grind, "skis": [], "catalogue": verified}
    for name in cfg.network_skis:
        ski = cat.ski(name)
        rec = ski.record
        if rec.network is None or rec.beam is None:
            out["skis"].append({"ski": name, "skipped": "needs both a network and a beam"})
            continue
        flex = BeamFlexibility(rec.beam)
        outline = rec.outline
        rows, t_net, t_beam, t_beam_cached = [], [], [], []
        for kg in cfg.network_loads_kg:
            for pos in cfg.network_positions_mm:
                f, xf = kg * G_STANDARD, pos * 1e-3
                net, beam_ski = rec.network, rec.beam
                tn, _, (xn, gn) = _median_time(
                    lambda f=f, xf=xf, net=net: camber.predict_profile(net, f, xf),
                    cfg.network_repeats,
                )
                tb, _, beam = _median_time(
                    lambda f=f, xf=xf, b=beam_ski: solve_beam_contact(b, f, xf), 1
                )
                tbc, _, _ = _median_time(
                    lambda f=f, xf=xf, b=beam_ski, fl=flex: solve_beam_contact(
                        b, f, xf, flexibility=fl
                    ),
                    cfg.network_repeats,
                )
                t_net.append(tn)
                t_beam.append(tb)
                t_beam_cached.append(tbc)
                gb = np.interp(xn, beam.positions_m, beam.gap_m)
                row = {
                    "load_kg": kg,
                    "load_position_mm": pos,
                    "contact_band_rmse_um": camber.contact_band_rmse_m(gn, gb) * 1e6,
                    "max_abs_profile_error_um": float(np.max(np.abs(gn - gb))) * 1e6,
                }
                vals = {}
                for label, g in (("network", gn), ("beam", gb)):
                    gm = extrude_profile(
                        xn, g, outline.width_m, width_positions_m=outline.positions_m
                    )
                    mac = solve_macro(gm, f, xf, e_eff)
                    ms = multiscale(mac, grind.table, porosity, e_eff)
                    vals[label] = {
                        "apparent_contact_area": mac.apparent_contact_area_m2,
                        "total_real_contact_area": ms.total_real_contact_area_m2,
                        "average_real_contact_pressure": ms.average_real_contact_pressure_pa,
                        "min_average_separation": ms.min_average_separation_m,
                        "total_reciprocal_separation": ms.total_reciprocal_separation_m,
                        "converged": bool(mac.converged),
                    }
                row["rel_error"] = {
                    m: _rel(vals["network"][m], vals["beam"][m]) for m in ANSWER_METRICS
                }
                row["converged"] = vals["network"]["converged"] and vals["beam"]["converged"]
                rows.append(row)
                bar.update(1)
        attrs = rec.network.get("attrs", {})
        out["skis"].append(
            {
                "ski": name,
                "sha256": ski.sha256,
                "network_metrics": attrs.get("metrics_json"),
                "median_network_s": statistics.median(t_net),
                "median_beam_s": statistics.median(t_beam),
                "median_beam_cached_flexibility_s": statistics.median(t_beam_cached),
                "max_rel_error": {
                    m: max(abs(r["rel_error"][m]) for r in rows) for m in ANSWER_METRICS
                },
                "median_abs_rel_error": {
                    m: statistics.median(abs(r["rel_error"][m]) for r in rows)
                    for m in ANSWER_METRICS
                },
                "max_contact_band_rmse_um": max(r["contact_band_rmse_um"] for r in rows),
                "rows": rows,
            }
        )
    return out


# --------------------------------------------------------------------------- run


def _work_items(cfg: AccuracyConfig) -> int:
    n = 0
    if "micro" in cfg.stages:
        n += len(cfg.micro_grinds) * len(cfg.micro_pressures_pa) * len(cfg.micro_sizes)
    if "table" in cfg.stages:
        n += len(cfg.table_grinds) * cfg.table_direct_points
    if "end-to-end" in cfg.stages:
        n += len(cfg.cases) * len(candidate_presets(cfg))
    if "network" in cfg.stages:
        n += len(cfg.network_skis) * len(cfg.network_loads_kg) * len(cfg.network_positions_mm)
    return n


def bench_accuracy(cfg: AccuracyConfig, progress: bool = True) -> dict:
    """Run the stages of ``cfg``; returns the JSON-ready result.

    Each stage's entry carries ``wall_time_s`` and ``measured`` (provenance and the config),
    so stages kept from an earlier run (``--stages``) still say when and how they were run.
    """
    data: dict = {"config": asdict(cfg), "micro_effective_modulus_pa": MICRO_E_EFF_PA}
    runners = {
        "micro": ("micro", "micro grid", bench_micro_grid),
        "table": ("table", "table vs direct", bench_table),
        "end-to-end": ("end_to_end", "macro grid / presets", bench_end_to_end),
        "network": ("network", "network vs beam", bench_network),
    }
    with tqdm(total=_work_items(cfg), disable=not progress, desc="bench accuracy") as bar:
        for stage, (key, label, run) in runners.items():
            if stage not in cfg.stages:
                continue
            bar.set_postfix_str(label)
            t0 = time.perf_counter()
            data[key] = run(cfg, bar)
            data[key]["wall_time_s"] = time.perf_counter() - t0
            data[key]["measured"] = {**provenance(), "config": asdict(cfg)}
    return data


# --------------------------------------------------------------------------- charts


def _fig(n: int):
    """A figure with n panels, two per row from three panels on."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import NullFormatter

    cols = n if n < 3 else 2
    rows = -(-n // cols)
    fig = Figure(figsize=(5.2 * cols, 4.2 * rows))
    axes = [fig.add_subplot(rows, cols, k + 1) for k in range(n)]
    for ax in axes:
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_minor_formatter(NullFormatter())
    return fig, axes


def _save(fig, path: Path) -> None:
    from skisnow.app.storage.common import atomic_path

    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)


def _floor(v: float) -> float:
    return max(abs(v), 1e-6)


def _plot_before_after(mi: dict, path: Path) -> None:
    """|error| against the zero-pixel limit of the shipped tables' value, before (1024²) and
    after (two-level extrapolation, with the estimate it stores as an error bar)."""
    series = [s for s in mi["series"] if s.get("two_level")]
    if not series:
        return
    metrics = list(ERROR_FIELDS)
    fig, axes = _fig(len(metrics))
    x = np.arange(len(series))
    for ax, m in zip(axes, metrics, strict=True):
        before = [abs(s["two_level"]["before_rel_error"][m]) for s in series]
        after = [abs(s["two_level"]["after_rel_error"][m]) for s in series]
        est = [s["two_level"]["estimate_rel"][m] for s in series]
        ax.bar(x - 0.2, [100 * v for v in before], 0.4, label="before: 1024² (1.5 µm)")
        ax.bar(x + 0.2, [100 * v for v in after], 0.4, label="after: 1024² + 2048² extrapolated")
        ax.errorbar(
            x + 0.2,
            [0.0] * len(est),
            yerr=[[0.0] * len(est), [100 * v for v in est]],
            fmt="none",
            ecolor="k",
            capsize=4,
            label="after: stored estimate",
        )
        if m == "real_contact_area_fraction":
            ax.axhline(3.0, color="r", lw=0.8, ls="--", label="aim: 3 %")
        ax.set_xticks(x, [f"{s['grind']}\n{s['nominal_pressure_kpa']:g} kPa" for s in series])
        ax.set_title(MICRO_METRICS[m], fontsize=9)
        ax.set_ylabel("|rel. error| vs zero-pixel limit [%]")
        ax.grid(True, axis="y", alpha=0.3)
    for ax in axes[len(metrics) :]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7)
    fig.suptitle(
        f"shipped tables before/after; limit from {mi['sizes'][-2]}² and {mi['sizes'][-1]}²",
        fontsize=10,
    )
    _save(fig, path)


def plot_accuracy(data: dict, path: Path) -> None:
    """Charts ``accuracy-<stage>.png`` beside ``path`` (the stage's own png is the front)."""
    out = path.parent
    if "micro" in data:
        fig, axes = _fig(len(MICRO_METRICS))
        for ax, (m, label) in zip(axes, MICRO_METRICS.items(), strict=True):
            for s in data["micro"]["series"]:
                rows = s["rows"][:-1]
                ax.loglog(
                    [r["median_time_s"] for r in rows],
                    [_floor(r["rel_error"][m]) for r in rows],
                    "o-",
                    label=f"{s['grind']}, {s['nominal_pressure_kpa']:g} kPa",
                )
                for r in rows:
                    ax.annotate(
                        f"{r['n']}²", (r["median_time_s"], _floor(r["rel_error"][m])), fontsize=7
                    )
                t = s.get("two_level")
                if t and m in t["value"]:  # after: the two-level table value (vs the finest)
                    y = _floor(_rel(t["value"][m], s["rows"][-1][m]))
                    ax.loglog(t["time_s"], y, "*", ms=11, color=ax.lines[-1].get_color())
                    ax.annotate("1024²+2048² extrap.", (t["time_s"], y), fontsize=6)
            ax.set_title(label, fontsize=9)
            ax.set_xlabel("median solve time [s]")
            ax.set_ylabel(f"|rel. error| vs {data['micro']['sizes'][-1]}²")
            ax.grid(True, which="both", alpha=0.3)
        axes[0].legend(fontsize=7)
        fig.suptitle(f"micro: grid size on a {data['micro']['patch_mm']:.3f} mm patch", fontsize=10)
        _save(fig, out / "accuracy-micro.png")
        _plot_before_after(data["micro"], out / "accuracy-tables-before-after.png")
    if "table" in data:
        fig, axes = _fig(len(TABLE_METRICS))
        for ax, m in zip(axes, TABLE_METRICS, strict=True):
            for g in data["table"]["grinds"]:
                rows = [
                    r
                    for r in g["rows"]
                    if "build_cost_s" in r and r["max_rel_error"][m] is not None
                ]
                ax.loglog(
                    [r["build_cost_s"] for r in rows],
                    [_floor(r["max_rel_error"][m]) for r in rows],
                    "o-",
                    label=g["grind"],
                )
                for r in rows:
                    ax.annotate(
                        f"{r['points']} pts",
                        (r["build_cost_s"], _floor(r["max_rel_error"][m])),
                        fontsize=7,
                    )
            ax.set_title(MICRO_METRICS[m], fontsize=9)
            ax.set_xlabel("table build cost (points × median solve) [s]")
            ax.set_ylabel("max |rel. error| vs direct solve")
            ax.grid(True, which="both", alpha=0.3)
        axes[0].legend(fontsize=7)
        fig.suptitle("table: PCHIP interpolation vs direct solves (pressure-grid density)")
        _save(fig, out / "accuracy-table.png")
    if "end_to_end" in data:
        e2e = data["end_to_end"]
        cand = [s for s in e2e["settings"] if s["name"] != "reference"]
        for key, tkey, fname, title, front_key in (
            (
                "apparent_contact_area",
                "median_macro_s",
                "accuracy-macro.png",
                "macro: grid spacing (apparent contact area)",
                "macro_front",
            ),
            (None, "median_total_s", "accuracy-end-to-end.png", "end to end: /v1/contact", "front"),
        ):
            fig, axes = _fig(1 if key else 2)
            fig.set_size_inches(7 if key else 13, 5)
            ax = axes[0]

            def err(s, key=key):
                return s["max_rel_error"][key] if key else s["max_rel_error_converging"]

            if not key:  # the minimum average separation beside, on its own panel
                ax2 = axes[1]
                for s in cand:
                    x, y = s[tkey], _floor(s["max_rel_error"]["min_average_separation"])
                    ax2.loglog(x, y, "s" if s["preset"] else "o", color="C1", ms=5)
                    ax2.annotate(
                        s["name"] + (f"  [{s['preset']}]" if s["preset"] else ""),
                        (x, y),
                        fontsize=7,
                        xytext=(3, 3),
                        textcoords="offset points",
                    )
                ax2.set_xlabel("whole request median time [s]")
                ax2.set_ylabel(f"max |rel. error| of min h̄ vs {e2e['reference']}")
                ax2.set_title(
                    "minimum average separation (does not converge where it sits at a "
                    "short tip/tail contact)",
                    fontsize=8,
                )
                ax2.grid(True, which="both", alpha=0.3)

            for s in cand:
                x, y = s[tkey], _floor(err(s))
                style = "s" if s["preset"] else "o"
                ax.loglog(
                    x, y, style, color="C3" if s["preset"] else "C0", ms=7 if s["preset"] else 5
                )
                lab = s["name"] + (f"  [{s['preset']}]" if s["preset"] else "")
                ax.annotate(lab, (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
            fr = sorted((s for s in cand if s["name"] in e2e[front_key]), key=lambda s: s[tkey])
            ax.loglog([s[tkey] for s in fr], [_floor(err(s)) for s in fr], "-", color="grey", lw=1)
            for tol in PRESET_TOLERANCES.values():
                ax.axhline(tol, ls=":", color="grey", lw=0.8)
            ax.set_xlabel(("macro solve" if key else "whole request") + " median time [s]")
            ax.set_ylabel(
                "max |rel. error| "
                + ("of the apparent area" if key else "of A_app, A_tot, p̄_real, Σ(1/h)")
                + f" vs {e2e['reference']}"
            )
            ax.set_title(title + " (grey: front; red squares: named presets)", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
            _save(fig, out / fname)
    if "network" in data:
        fig, (ax,) = _fig(1)
        fig.set_size_inches(7, 4.5)
        for k, s in enumerate(x for x in data["network"]["skis"] if "rows" in x):
            for j, m in enumerate(ANSWER_METRICS):
                ax.loglog(
                    s["median_network_s"],
                    _floor(s["max_rel_error"][m]),
                    "os^vD"[j],
                    color=f"C{j}",
                    label=m.replace("_", " ") if k == 0 else None,
                )
            ax.annotate(
                s["ski"],
                (s["median_network_s"], _floor(s["max_rel_error"]["apparent_contact_area"])),
                fontsize=8,
            )
            ax.axvline(
                s["median_beam_s"],
                color=f"C{5 + k}",
                ls="--",
                lw=1,
                label=f"beam {s['ski']} (truth, error 0)",
            )
            ax.axvline(
                s["median_beam_cached_flexibility_s"],
                color=f"C{5 + k}",
                ls=":",
                lw=1,
                label=f"beam {s['ski']}, cached flexibility",
            )
        ax.set_xlabel("median time of the loaded profile [s]")
        ax.set_ylabel("max |rel. error| network vs beam")
        ax.set_title("network vs the beam model it learned", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        _save(fig, out / "accuracy-network.png")


# --------------------------------------------------------------------------- markdown


def _pct(v: float | None) -> str:
    return "—" if v is None or not np.isfinite(v) else f"{100 * v:+.3g} %"


def _apct(v: float | None) -> str:
    return "—" if v is None or not np.isfinite(v) else f"{100 * abs(v):.3g} %"


def _micro_error_text(d: dict) -> str:
    """Range of the micro-scale error of the shipped tables, from the micro stage: the
    two-level value where the series has it (tables built with ``--pixel-levels refine``),
    else the 1024² grid."""
    mi = d.get("micro")
    if not mi:
        return "the micro-scale error of the shipped tables (micro stage)"
    ar, rec, ar_before = [], [], []
    for s_ in mi["series"]:
        rows = s_["rows"]
        ns = [r["n"] for r in rows]
        if 1024 not in ns[:-1]:
            continue
        r1024 = rows[ns.index(1024)]
        c = convergence([r["real_contact_area_fraction"] for r in rows])
        if c["verdict"] == "converges":
            lim = richardson([r["real_contact_area_fraction"] for r in rows], c["observed_order"])
            before = r1024["real_contact_area_fraction"] / lim - 1
        else:
            before = r1024["rel_error"]["real_contact_area_fraction"]
        two = s_.get("two_level")
        shipped = (s_.get("shipped_table") or {}).get("pixel_levels", "none")
        if two and shipped != "none":
            ar_before.append(before)
            ar.append(two["after_rel_error"]["real_contact_area_fraction"])
            rec.append(two["after_rel_error"]["mean_reciprocal_gap_per_m"])
        else:
            ar.append(before)
            rec.append(r1024["rel_error"]["mean_reciprocal_gap_per_m"])
    if not ar:
        return "the micro-scale error of the shipped tables (micro stage)"
    if ar_before:
        return (
            f"two-level tables: a_r {_pct(min(ar))} … {_pct(max(ar))} against the zero-pixel "
            f"limit (1.5 µm alone: {_pct(min(ar_before))} … {_pct(max(ar_before))}), floored "
            f"reciprocal gap {_pct(min(rec))} … {_pct(max(rec))}"
        )
    return (
        f"a_r {_pct(min(ar))} … {_pct(max(ar))} against the zero-pixel limit, floored "
        f"reciprocal gap {_pct(min(rec))} … {_pct(max(rec))} against 0.75 µm pixels"
    )


def _why_default(e2e: dict, micro_text: str = "") -> list[str]:
    """The reason for the default preset, read off the measured front."""
    by_name = {s["name"]: s for s in e2e["settings"]}
    by_preset = {s["preset"]: s for s in e2e["settings"] if s["preset"]}
    d, f, fi = by_preset.get("default"), by_preset.get("fast"), by_preset.get("fine")
    if d is None:
        return []
    rule = e2e["rule"]["default"]
    tol = 100 * rule["tolerance"]
    front = [by_name[n] for n in e2e["front"]]
    faster = [s for s in front if s["median_total_s"] < d["median_total_s"]]
    text = (
        f"**Why the default is {d['name']}.** "
        + (
            f"It is the fastest grid on the front with A_app, A_tot, p̄_real and Σ(1/h) within "
            f"{tol:g} % of the reference on every case "
            if rule["fastest_on_front"] == d["name"]
            else f"The rule would pick {rule['fastest_on_front']}; the shipped default stays "
            f"{d['name']} "
        )
        + f"(largest error {_apct(d['max_rel_error_converging'])}, "
        f"{d['median_total_s'] * 1e3:.0f} ms per request)"
    )
    if faster:
        g = max(faster, key=lambda s: s["median_total_s"])
        text += (
            f"; the next faster point on the front, {g['name']}, saves only "
            f"{(d['median_total_s'] - g['median_total_s']) * 1e3:.0f} ms but reaches "
            f"{_apct(g['max_rel_error_converging'])}"
        )
    if fi is not None:
        text += (
            f"; `fine` ({fi['name']}) costs {fi['time_ratio_vs_default']:.1f}× the time for "
            f"{_apct(fi['max_rel_error_converging'])}"
        )
    if f is not None:
        text += (
            f"; `fast` ({f['name']}) takes {f['time_ratio_vs_default']:.2f}× the time at "
            f"{_apct(f['max_rel_error_converging'])}"
        )
    text += (
        f". The {tol:g} % line is set by the micro scale: every preset carries the error of the "
        f"shipped tables' texture pixels ({micro_text}; micro section above), so a "
        "finer macro grid than the default buys little accuracy for its time. The preset "
        "changes only the macro grid."
    )
    return [text, ""]


def _min_separation(e2e: dict) -> list[str]:
    """Where the minimum average separation does not converge, with the worst case."""
    cases = e2e["cases"]
    default = next(s["name"] for s in e2e["settings"] if s["preset"] == DEFAULT_PRESET)
    errs = [abs(c["settings"][default]["rel_error"]["min_average_separation"]) for c in cases]
    worst = cases[int(np.argmax(errs))]
    grids = sorted(
        (
            s
            for s in e2e["settings"]
            if s["preset"] == DEFAULT_PRESET
            or (s["pixels_across"] == 16 and not s["preset"])
            or s["preset"] == "fine"
        ),
        key=lambda s: -s["pixel_along_mm"],
    )
    seq = [
        f"{g['name']} {_pct(worst['settings'][g['name']]['rel_error']['min_average_separation'])}"
        for g in grids
    ]
    ok = sum(e <= 0.01 for e in errs)
    return [
        f"**Minimum average separation.** At the default grid it is within 1 % of the "
        f"reference in {ok} of {len(cases)} cases. In {worst['ski']} × {worst['grind']}, "
        f"{worst['load_kg']:g} kg at {worst['load_position_mm']:g} mm, the minimum sits in a "
        "short tip or tail contact whose pressure peaks at the contact edge; refining the grid "
        "along the ski raises that peak pixel by pixel, so min h̄ keeps falling ("
        + "; ".join(seq)
        + "): like the peak pressure (docs/macro.md) it does not converge with the macro grid "
        "there. It is reported with the pixel size (`provenance.preset.macro_pixel_size_mm`) "
        "and left out of the preset rule.",
        "",
    ]


def _unverified(stage: dict) -> list[str]:
    cat = stage.get("catalogue") or {}
    if cat.get("verified_against_manifest", True):
        return []
    return [
        "_The demo ski files did not match their manifest during this run (another job was "
        "rewriting them); this stage read them as they were — sha256 of every file used in "
        "`docs/bench/accuracy.json`._",
        "",
    ]


def _before_after_lines(mi: dict) -> list[str]:
    """Shipped tables before (1024² alone) and after (two-level extrapolation), against the
    zero-pixel limit of this run's finest grids."""
    rows = [s for s in mi["series"] if s.get("two_level")]
    if not rows:
        return []
    finest = mi["sizes"][-2:]
    out = [
        "",
        "**Shipped tables, before and after (issue #13 point 3).** Before: one level, 1024² "
        "(1.5 µm). After: two levels, 1024² and 2048² (0.75 µm) of the same surface, "
        "extrapolated to zero pixel size (a_r first order, h̄_n second order, (1/h)‾ the "
        "2048² value; `skisnow build-tables --pixel-levels refine`, docs/tables.md). Both "
        f"against the zero-pixel limit from {finest[0]}² and {finest[1]}² (observed order of "
        "the three finest grids where it converges, else the finest value); `estimate` is the "
        "error the table stores for itself, `table` what the shipped file returns there "
        "(interpolated).",
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
            cell = f"{_pct(_rel(shipped[ar], s['zero_pixel_limit'][ar]))}" + (
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
    return out


def render_md(d: dict) -> list[str]:
    """Section of docs/benchmarks.md for the ``accuracy`` stage."""
    lines = [
        "## Accuracy: error against a converged reference versus time (`skisnow bench accuracy`)",
        "",
        "Every stage is measured in one run; times are medians, compare them as ratios within "
        "the run. Error is relative, `value / reference − 1`.",
        "",
    ]
    if "micro" in d:
        mi = d["micro"]
        lines += [
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
            "shipped tables use the 1024² grid (1.5 µm). E' = "
            f"{d['micro_effective_modulus_pa'] / 1e6:.0f} MPa (200 MPa snow).",
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
        lines += [
            "",
            "Convergence with refinement (successive differences shrink ≥ 1.4× "
            "per halving of the pixel; observed order from the last pair):",
            "",
        ]
        lines += [
            "| metric | "
            + " | ".join(f"{s['grind']} {s['nominal_pressure_kpa']:g} kPa" for s in mi["series"])
            + " |"
        ]
        lines += ["|---" * (1 + len(mi["series"])) + "|"]
        for m, label in MICRO_METRICS.items():
            cells = []
            for s in mi["series"]:
                c = convergence([r[m] for r in s["rows"]])  # recomputed from the values
                order = c["observed_order"]
                verdict = c["verdict"]
                if verdict == "converges slowly":
                    cells.append(
                        f"converges slowly (monotone; changes up to "
                        f"{_apct(c['max_relative_change'])} per halving)"
                    )
                elif verdict == "converges":
                    cells.append("converges" + (f" (p ≈ {order:.1f})" if order is not None else ""))
                elif verdict == "bounded":
                    cells.append(
                        f"no clear order, changes ≤ {_apct(c['max_relative_change'])} per halving"
                    )
                else:
                    cells.append(
                        f"**does not converge** (changes up to {_apct(c['max_relative_change'])})"
                    )
            lines.append(f"| {label} | " + " | ".join(cells) + " |")
        shipped_n = 1024
        est = []
        for s_ in mi["series"]:
            rows = s_["rows"]
            ns = [r["n"] for r in rows]
            if shipped_n not in ns[:-1] or len(rows) < 3:
                continue
            cells = []
            for m in ("real_contact_area_fraction", "mean_gap_m", "mean_reciprocal_gap_per_m"):
                c = convergence([r[m] for r in rows])
                if c["verdict"] != "converges":
                    cells.append("— (no order)")
                    continue
                extrap = richardson([r[m] for r in rows], c["observed_order"])
                cells.append(_pct(rows[ns.index(shipped_n)][m] / extrap - 1))
            est.append(
                f"| {s_['grind']} {s_['nominal_pressure_kpa']:g} kPa | " + " | ".join(cells) + " |"
            )
        if est:
            lines += [
                "",
                f"Estimated error of the shipped tables' grid ({shipped_n}², "
                f"{MICRO_PATCH_M / shipped_n * 1e6:g} µm) against the limit of zero pixel size "
                "(Richardson extrapolation from the two finest grids with the observed order, "
                "where there is one):",
                "",
                "| series | a_r | h̄_n | (1/h)‾ floored |",
                "|---|---|---|---|",
                *est,
            ]
        sens = {
            m: max(
                abs(r.get("log_sensitivity_to_pressure", {}).get(m, 0.0))
                for s in mi["series"]
                for r in s["rows"]
            )
            for m in MICRO_METRICS
        }
        lines += [
            "",
            "Well-posedness: each solve repeated at a 0.1 % higher pressure gives "
            "d ln f / d ln P_n; largest |value| over all grids: "
            + ", ".join(f"{MICRO_METRICS[m]} {v:.3g}" for m, v in sens.items())
            + " (a well-posed metric is of order 1)."
            + (
                " The raw reciprocal gap is decided by the gaps of a few pixels next to contact: "
                "a 0.1 % change of the load moves it by up to "
                f"{sens['mean_reciprocal_gap_raw_per_m'] * 0.1:.0f} %, so where it looks "
                "convergent in one series that is chance."
                if sens["mean_reciprocal_gap_raw_per_m"] > 20
                else ""
            ),
        ]
        lines += _before_after_lines(mi)
        lines += [
            "",
            "The raw reciprocal gap (no floor) is not expected to converge: next to a contact "
            "spot the gap opens like distance^1.5, so finer pixels sample ever smaller gaps "
            "there and the mean of 1/h keeps moving with the pixel size (method.md §5). The "
            "floored value ⟨1/max(h, 10 nm)⟩ is what the tables and the API report; the raw "
            "value is stored in the tables for diagnosis only. Every answer of `/v1/contact` "
            "carries the micro error of its table's pixel size, so the answer reports it: "
            "`provenance.preset` holds the preset name, the macro pixel sizes (mm) and "
            "`texture_pixel_size_um`.",
            "",
            "![micro grid size](bench/accuracy-micro.png)",
            "",
        ]
    if "table" in d:
        lines += [
            "### Micro tables: interpolation vs a direct solve (pressure-grid density)",
            "",
            "PCHIP interpolation (in ln r) of the shipped tables thinned to fewer pressure "
            "points (ends kept), against direct solves of the same texture at the same pixel "
            "size and tolerance at off-grid ratios (geometric midpoints of the 72-point grid) "
            "and against the 72-point nodes a thinned table leaves out; test range P_n/E' "
            f"{d['table']['grinds'][0]['test_ratio_range'][0]:.0e} … "
            f"{d['table']['grinds'][0]['test_ratio_range'][1]:.0e} (partial contact). Build "
            "cost = points × the median solve time recorded in the table file.",
            "",
            "Cells: largest error (median in brackets) over the held-out nodes and the direct "
            "solves.",
            "",
            "| grind | points | build cost [s] | a_r | h̄_n | (1/h)‾ floored | "
            "vs direct solves only (a_r / h̄_n / (1/h)‾) | lookup: one ratio / per ratio of 10⁴ |",
            "|---|---|---|---|---|---|---|---|",
        ]

        def cell(r: dict, m: str) -> str:
            med = [
                r[k][m] for k in ("held_out_median_rel_error", "direct_median_rel_error") if k in r
            ]
            return _apct(r["max_rel_error"][m]) + (f" ({_apct(max(med))})" if med else "")

        for g in d["table"]["grinds"]:
            for r in g["rows"]:
                lk = r.get("lookup_time_per_query_s")
                de = r.get("direct_max_rel_error")
                lines.append(
                    f"| {g['grind']} | {r['points']} | {r.get('build_cost_s', float('nan')):.0f} | "
                    + " | ".join(cell(r, m) for m in TABLE_METRICS)
                    + " | "
                    + (" / ".join(_apct(de[m]) for m in TABLE_METRICS) if de else "—")
                    + " | "
                    + (
                        f"{lk * 1e6:.0f} µs / "
                        f"{r['lookup_time_per_ratio_vectorised_s'] * 1e9:.0f} ns"
                        if lk
                        else "—"
                    )
                    + " |"
                )
            worst = [
                (r["points"], r["held_out_max_at"]["real_contact_area_fraction"])
                for r in g["rows"]
                if "held_out_max_at" in r
            ]
            if worst:
                lines += [
                    "",
                    f"{g['grind']}: the largest a_r errors of the thinned tables sit at "
                    + ", ".join(
                        f"P_n/E' = {w['pressure_ratio']:.2g} (a_r = "
                        f"{w['real_contact_area_fraction']:.2g}, {k} points)"
                        for k, w in worst
                    )
                    + f" — at a_r ≲ 1e-3 the {g['grid_shape'][0]}² texture touches on a few "
                    "hundred pixels or fewer, so the tabulated a_r is itself step-like "
                    "(pixel counting) and more pressure points cannot make interpolation "
                    "agree better than that.",
                ]
            if g["direct_solve_median_s"]:
                lines += [
                    "",
                    f"{g['grind']}: a direct solve ({g['grid_shape'][0]}², cold) takes "
                    f"{g['direct_solve_median_s']:.2f} s median over {len(g['direct'])} ratios.",
                    "",
                ]
        lines += ["", "![table interpolation](bench/accuracy-table.png)", ""]
    if "end_to_end" in d:
        e2e = d["end_to_end"]
        cases = e2e["cases"]
        lines += [
            "### Macro grid spacing and end to end: presets of `/v1/contact`",
            "",
            f"`app.service.contact` (the computation of `POST /v1/contact`) on {len(cases)} "
            "cases (skis × grinds × loads "
            + ", ".join(
                sorted(
                    {
                        f"{c['load_kg']:g} kg at {c['load_position_mm']:g} mm, "
                        f"{c['snow_modulus_mpa']:g} MPa, n = {c['porosity']:g}"
                        for c in cases
                    }
                )
            )
            + f"), each candidate macro grid against the reference grid {e2e['reference']} on "
            "the same table (the micro error above adds to these and is fixed by the table). "
            "Errors are the largest over the cases; times the median over the cases of "
            "per-case medians (one warm-up first).",
            "",
            "| grid (along × across) | preset | request [s] | macro [s] | time / default | "
            "A_app | A_tot | p̄_real | min h̄ | Σ(1/h) | max without min h̄ |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for s in sorted(e2e["settings"], key=lambda s: s["median_total_s"]):
            e = s["max_rel_error"]
            mark = "**" if s["name"] in e2e["front"] else ""
            lines.append(
                f"| {mark}{s['name']}{mark} | {s['preset'] or ''} | {s['median_total_s']:.3g} | "
                f"{s['median_macro_s']:.3g} | {s['time_ratio_vs_default']:.2f} | "
                + " | ".join(_apct(e[m]) for m in ANSWER_METRICS)
                + f" | {_apct(s['max_rel_error_converging'])} |"
            )
        rule = e2e["rule"]
        lines += [
            "",
            "Bold: on the error-versus-time front (no other grid is both faster and more "
            "accurate). Rule: each preset is the fastest grid on the front within its "
            "tolerance — "
            + "; ".join(
                f"`{k}` ≤ {100 * v['tolerance']:g} %: {v['fastest_on_front'] or 'none'}"
                for k, v in rule.items()
            )
            + ". Presets shipped: "
            + "; ".join(
                f"`{k}` = {_grid_name(p['pixel_along_m'] * 1e3, p['pixels_across'])}"
                for k, p in e2e["presets"].items()
            )
            + ".",
            "",
            *_why_default(e2e, _micro_error_text(d)),
            *_min_separation(e2e),
            *_unverified(e2e),
            "![macro grid](bench/accuracy-macro.png)",
            "",
            "![end to end](bench/accuracy-end-to-end.png)",
            "",
        ]
    if "network" in d:
        nw = d["network"]
        lines += [
            "### Camber network vs the beam model it learned",
            "",
            "Each ski's network against its beam model (the truth the network was trained on) at "
            "held-out loads × positions, through the whole computation (default grid, "
            f"{nw['grind']}, 200 MPa snow, n = 0.5). Beam timed as the service would call it "
            "(flexibility rebuilt) and with a cached flexibility.",
            "",
            "| ski | cases | network [ms] | beam [ms] | beam, cached [ms] | max band RMSE [µm] | "
            "A_app | A_tot | p̄_real | min h̄ | Σ(1/h) |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for s in nw["skis"]:
            if "rows" not in s:
                lines.append(f"| {s['ski']} | {s['skipped']} |||||||||")
                continue
            e = s["max_rel_error"]
            lines.append(
                f"| {s['ski']} | {len(s['rows'])} | {s['median_network_s'] * 1e3:.2f} | "
                f"{s['median_beam_s'] * 1e3:.0f} | "
                f"{s['median_beam_cached_flexibility_s'] * 1e3:.1f} | "
                f"{s['max_contact_band_rmse_um']:.1f} | "
                + " | ".join(
                    f"{_apct(e[m])} ({_apct(s['median_abs_rel_error'][m])})" for m in ANSWER_METRICS
                )
                + " |"
            )
        lines += [
            "",
            *_unverified(nw),
            "Cells: largest error over the cases (median in brackets). The profile error is "
            "small where it matters for the network's training target (RMSE in the 0.2 mm "
            "contact band), but at light loads the apparent area is set by clearances of a few "
            "µm and moves by several per cent; the macro-grid error above adds to this. The "
            "network replaces a beam solve that costs hundreds of times more (flexibility "
            "rebuilt per request, as without the network).",
            "",
            "![network vs beam](bench/accuracy-network.png)",
            "",
        ]
    walls = {
        k: d[k].get("wall_time_s") for k in ("micro", "table", "end_to_end", "network") if k in d
    }
    lines += [
        "Wall time per stage: "
        + ", ".join(f"{k.replace('_', ' ')} {v / 60:.1f} min" for k, v in walls.items() if v)
        + f" (total {sum(v for v in walls.values() if v) / 60:.1f} min). Stages run separately "
        "(`--stages`) record their own command and commit under `measured` in the JSON.",
        "",
    ]
    return lines


# --------------------------------------------------------------------------- command


def register(bsub: argparse._SubParsersAction) -> None:
    """Add ``bench accuracy`` to the ``bench`` subcommands."""
    a = bsub.add_parser("accuracy", help="error against a converged reference versus time")
    a.add_argument("--quick", action="store_true", help="CI-sized smoke run (tiny sizes)")
    a.add_argument(
        "--stages",
        nargs="+",
        choices=list(AccuracyConfig.stages),
        help="run only these stages (default: all)",
    )
    a.add_argument(
        "--micro-sizes", type=int, nargs="+", help="micro grid sizes, finest is the reference"
    )
    a.add_argument(
        "--out",
        type=Path,
        help="docs directory to write (default: docs/; with --quick a temporary directory, "
        "so a smoke run never replaces the committed results)",
    )
    a.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from skisnow.app.evidence import micro as bench

    cfg = QUICK if args.quick else AccuracyConfig()
    if args.stages:
        cfg = replace(cfg, stages=tuple(args.stages))
    if args.micro_sizes:
        cfg = replace(cfg, micro_sizes=tuple(sorted(args.micro_sizes)))
    data = bench_accuracy(cfg)
    if args.out is not None:
        docs_dir = args.out
    elif args.quick:
        docs_dir = Path(tempfile.gettempdir()) / "skisnow-bench-accuracy-quick"
    else:
        docs_dir = bench.DOCS
    previous = docs_dir / "bench" / "accuracy.json"
    if args.stages and previous.is_file():  # keep the stages not re-run from the last run
        old = json.loads(previous.read_text())
        for stage in set(AccuracyConfig.stages) - set(args.stages):
            key = stage.replace("-", "_")
            if key in old:
                data[key] = old[key]
                if key == "micro":  # derived fields follow the current classifier
                    for series in data[key]["series"]:
                        series["convergence"] = {
                            m: convergence([r[m] for r in series["rows"]]) for m in MICRO_METRICS
                        }
                data.setdefault("kept_from_previous_run", []).append(stage)
    path = bench._write_stage("accuracy", data, plot_accuracy, docs_dir=docs_dir)
    print(f"wrote {path} and {path.parent.parent / 'benchmarks.md'}")
    return 0
