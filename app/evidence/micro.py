"""``skisnow bench``: benchmarks that compare against peers in the same run.

Results go to ``docs/bench/<stage>.json`` (machine-readable, with provenance) and charts to
``docs/bench/<stage>.png``; ``docs/benchmarks.md`` is regenerated from every JSON present.
Times are medians over repeats; comparisons are ratios measured in the same process, because
these machines are noisy.
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import platform
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import scipy.fft
from skisnow.app.storage.common import atomic_path, provenance
from skisnow.app.storage.common import docs_dir as _docs_dir
from skisnow.solvers.elastic import FFTBackend, PeriodicHalfSpace, resolve_backend
from skisnow.solvers.micro import solve_micro
from skisnow.solvers.texture import self_affine_surface

log = logging.getLogger(__name__)

DOCS = _docs_dir()
E_STAR_PA = 200e6  # Johnson's composite modulus of the benchmark [Pa]; E' = 2 E*
PIXEL_M = 1e-6
SQ_M = 2e-6
PRESSURES_PA = (60e3, 1e6)


def bench_surface(n: int, seed: int = 2026) -> np.ndarray:
    """The benchmark surface: self-affine, H = 0.8, Sq 2 µm, 1 µm pixels, seeded [m]."""
    rng = np.random.default_rng(seed)
    return self_affine_surface((n, n), PIXEL_M, hurst=0.8, rms_height_m=SQ_M, rng=rng)


# --------------------------------------------------------------------------- peers


def _peer_contactmechanics() -> Callable | None:
    try:
        from ContactMechanics.Factory import make_system
        from SurfaceTopography import Topography
    except ImportError:
        return None

    def solve(h: np.ndarray, pressure_pa: float, e_eff_pa: float) -> dict:
        n = h.shape[0]
        size = (n * PIXEL_M, h.shape[1] * PIXEL_M)
        topo = Topography(h, physical_sizes=size, periodic=True)
        system = make_system(substrate="periodic", surface=topo, young=e_eff_pa / 2)
        t0 = time.perf_counter()
        res = system.minimize_proxy(
            external_force=pressure_pa * size[0] * size[1], pentol=1e-6 * SQ_M, maxiter=20000
        )
        dt = time.perf_counter() - t0
        return {
            "time_s": dt,
            "iterations": int(getattr(res, "nit", -1)),
            "converged": bool(res.success),
            "contact_fraction": float(np.mean(res.jac > 0)),
            "mean_gap_m": float(system.compute_gap(res.x, res.offset).mean()),
        }

    return solve


def _peer_tamaas() -> Callable | None:
    try:
        tm = importlib.import_module("tamaas")
    except ImportError:
        return None

    def solve(h: np.ndarray, pressure_pa: float, e_eff_pa: float) -> dict:
        n, m = h.shape
        model = tm.ModelFactory.createModel(
            tm.model_type.basic_2d, [n * PIXEL_M, m * PIXEL_M], [n, m]
        )
        model.E = e_eff_pa / 2
        model.nu = 0.0
        solver = tm.PolonskyKeerRey(model, h, 1e-12)
        t0 = time.perf_counter()
        solver.solve(pressure_pa)
        dt = time.perf_counter() - t0
        trac = np.asarray(model.traction)
        disp = np.asarray(model.displacement)
        gap = disp - h
        gap -= gap[trac > 0].mean() if np.any(trac > 0) else gap.min()
        return {
            "time_s": dt,
            "iterations": -1,
            "converged": True,
            "contact_fraction": float(np.mean(trac > 0)),
            "mean_gap_m": float(np.maximum(gap, 0).mean()),
        }

    return solve


def _peer_aspher() -> Callable | None:
    try:
        aspher = importlib.import_module("aspher")
    except ImportError:
        return None

    def solve(h: np.ndarray, pressure_pa: float, e_eff_pa: float) -> dict:
        n = h.shape[0]
        if h.shape[1] != n or n % 64:
            raise ValueError("aspher.solve_nested needs a square grid of 64·2^k pixels")
        t0 = time.perf_counter()
        res = aspher.solve_nested(
            n,
            h.max() - h,
            pressure_pa,
            domain_size=n * PIXEL_M,
            E_star=e_eff_pa / 2,
            backend="periodic",
            tol=1e-8,
        )
        dt = time.perf_counter() - t0
        return {
            "time_s": dt,
            "iterations": int(res.iterations),
            "converged": bool(res.converged),
            "contact_fraction": float(res.contact_area),
            "mean_gap_m": float(np.mean(np.asarray(res.gap))),
        }

    return solve


PEERS: dict[str, Callable[[], Callable | None]] = {
    "contactmechanics": _peer_contactmechanics,
    "aspher": _peer_aspher,
    "tamaas": _peer_tamaas,
}


# --------------------------------------------------------------------------- micro


def fft_floor_s(n: int, backend: str, repeats: int = 15, single: bool = False) -> float:
    """Median time of one bare rfft2 + irfft2 pair at n×n [s] (float32 if ``single``).

    pyFFTW: the solver's own plans (FFTW_ESTIMATE) executed on preallocated arrays, nothing
    else; scipy: ``rfft2`` then ``irfft2``.
    """
    fft = FFTBackend((n, n), backend=backend)
    dtype = np.float32 if single else np.float64
    a = np.random.default_rng(0).random((n, n)).astype(dtype)
    if fft.backend == "pyfftw":
        src, out = fft.workspace(2, dtype)
        src[...] = a
        fwd, inv, _ = fft.bound_plans(src, out)  # the plans the solver itself executes

        def pair() -> None:
            fwd.execute()
            inv.execute()
    else:

        def pair() -> None:
            spec = scipy.fft.rfft2(a, workers=fft.workers)
            scipy.fft.irfft2(spec, s=a.shape, workers=fft.workers)

    pair()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        pair()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def _ours(h: np.ndarray, pressure_pa: float, e_eff: float, backend: str) -> dict:
    hs = PeriodicHalfSpace(h.shape, PIXEL_M, e_eff, backend=backend)
    hs.self_compliance  # noqa: B018 - prepare outside the timing
    marks: list[tuple[float, int, int]] = []

    def on_fine_iteration(_it: int, _residual: float) -> None:
        marks.append((time.perf_counter(), hs.fft_pairs, hs.fft_pairs32))

    res = solve_micro(h, PIXEL_M, pressure_pa, e_eff, halfspace=hs, callback=on_fine_iteration)
    # the finest level's iterations: from its first residual to its last (coarse levels,
    # set-up and statistics excluded), with the FFT pairs applied in between
    (t0, a0, b0), (t1, a1, b1) = marks[0], marks[-1]
    return {
        "time_s": res.solve_time_s,
        "iterations": res.iterations,
        "level_iterations": res.level_iterations,
        "fine_time_s": t1 - t0,
        "fine_fft_pairs": a1 - a0,
        "fine_fft_pairs32": b1 - b0,
        "converged": res.converged,
        "contact_fraction": res.real_contact_area_fraction,
        "mean_gap_m": res.mean_gap_m,
    }


def bench_micro(
    sizes: list[int],
    repeats: int,
    peers: list[str],
    table_size: int,
    table_points: int,
    table_peers: list[str] | None = None,
) -> dict:
    """Single solves at each size and pressure against the installed ``peers``; then a table
    sweep at ``table_size`` against ``table_peers`` (default: every available peer)."""
    e_eff = 2 * E_STAR_PA
    backends = ["scipy"]
    try:
        import pyfftw  # noqa: F401

        backends.append("pyfftw")
    except ImportError:
        pass
    out: dict = {"sizes": sizes, "pressures_pa": list(PRESSURES_PA), "runs": [], "fft": []}
    available = {}
    for name in peers:
        solver = PEERS[name]()
        if solver is None:
            log.warning("peer %s is not installed; skipped", name)
        else:
            available[name] = solver
    out["peers"] = sorted(available)
    # peers are compared with what ``solve_micro`` uses by default (backend "auto")
    default_solver = f"skisnow[{resolve_backend('auto')}]"
    out["default_solver"] = default_solver
    for n in sizes:
        h = bench_surface(n)
        floors = {b: fft_floor_s(n, b) for b in backends}
        floors32 = {b: fft_floor_s(n, b, single=True) for b in backends}
        out["fft"].append(
            {
                "n": n,
                **{f"pair_s_{b}": v for b, v in floors.items()},
                **{f"pair32_s_{b}": v for b, v in floors32.items()},
            }
        )
        for pressure in PRESSURES_PA:
            for backend in backends:
                # one untimed solve first: kernel compilation and FFT planning are not the
                # solver's steady-state cost (the service and table builds pay them once)
                _ours(h, pressure, e_eff, backend)
                runs = [_ours(h, pressure, e_eff, backend) for _ in range(repeats)]
                med = statistics.median(r["time_s"] for r in runs)
                r0 = runs[0]
                # finest level: its time over the bare FFT time of the pairs it applied
                fine_time = statistics.median(r["fine_time_s"] for r in runs)
                floor_time = (
                    r0["fine_fft_pairs"] * floors[backend]
                    + r0["fine_fft_pairs32"] * floors32[backend]
                )
                per_pair = fine_time / floor_time if floor_time > 0 else float("nan")
                out["runs"].append(
                    {
                        "n": n,
                        "pressure_pa": pressure,
                        "solver": f"skisnow[{backend}]",
                        "median_time_s": med,
                        "times_s": [r["time_s"] for r in runs],
                        "iterations": r0["iterations"],
                        "level_iterations": r0["level_iterations"],
                        "fft_pairs_finest": r0["fine_fft_pairs"],
                        "fft_pairs32_finest": r0["fine_fft_pairs32"],
                        "fine_level_time_s": fine_time,
                        "time_per_fft_pair_over_floor": per_pair,
                        "converged": r0["converged"],
                        "contact_fraction": r0["contact_fraction"],
                        "mean_gap_m": r0["mean_gap_m"],
                    }
                )
                log.info("n=%d P=%g %s: %.3f s", n, pressure, backend, med)
            ref = next(
                r
                for r in out["runs"]
                if r["n"] == n and r["pressure_pa"] == pressure and r["solver"] == default_solver
            )
            for name, solver in available.items():
                res = solver(h, pressure, e_eff)
                out["runs"].append(
                    {
                        "n": n,
                        "pressure_pa": pressure,
                        "solver": name,
                        "median_time_s": res["time_s"],
                        "times_s": [res["time_s"]],
                        "iterations": res["iterations"],
                        "converged": res["converged"],
                        "contact_fraction": res["contact_fraction"],
                        "mean_gap_m": res["mean_gap_m"],
                        "contact_fraction_rel_diff_vs_skisnow": (
                            res["contact_fraction"] / ref["contact_fraction"] - 1
                        ),
                        "mean_gap_rel_diff_vs_skisnow": res["mean_gap_m"] / ref["mean_gap_m"] - 1,
                        "time_ratio_vs_skisnow": res["time_s"] / ref["median_time_s"],
                    }
                )
                log.info("n=%d P=%g %s: %.3f s", n, pressure, name, res["time_s"])
    if table_points > 0:
        chosen = (
            available
            if table_peers is None
            else {k: v for k, v in available.items() if k in table_peers}
        )
        out["table"] = bench_table(table_size, table_points, chosen, e_eff)
    return out


def bench_table(n: int, points: int, peers: dict, e_eff: float) -> dict:
    """A table sweep by continuation (ours) against the same grid solved cold by each peer."""
    h = bench_surface(n, seed=7)
    ratios = np.logspace(-5, -2.3, points)  # P/E' from 4 kPa to 2 MPa at E' = 400 MPa
    hs = PeriodicHalfSpace(h.shape, PIXEL_M, e_eff)
    t0 = time.perf_counter()
    p_prev = None
    ours = []
    for r in ratios:
        res = solve_micro(h, PIXEL_M, r * e_eff, e_eff, halfspace=hs, initial_pressure_pa=p_prev)
        p_prev = None if res.full_contact else res.pressure_pa
        ours.append(res.real_contact_area_fraction)
    t_ours = time.perf_counter() - t0
    t_cold0 = time.perf_counter()
    for r in ratios:
        solve_micro(h, PIXEL_M, r * e_eff, e_eff, halfspace=hs)
    t_ours_cold = time.perf_counter() - t_cold0
    result = {
        "n": n,
        "points": points,
        "pressure_ratio_range": [float(ratios[0]), float(ratios[-1])],
        "skisnow_continuation_s": t_ours,
        "skisnow_cold_s": t_ours_cold,
        "skisnow_best": "continuation" if t_ours <= t_ours_cold else "cold (nested grids)",
        "peers": {},
    }
    for name, solver in peers.items():
        t1 = time.perf_counter()
        fr = [solver(h, r * e_eff, e_eff)["contact_fraction"] for r in ratios]
        dt = time.perf_counter() - t1
        result["peers"][name] = {
            "cold_sweep_s": dt,
            "speedup_of_skisnow": dt / min(t_ours, t_ours_cold),
            "max_contact_fraction_rel_diff": float(
                np.max(np.abs(np.array(fr) / np.array(ours) - 1))
            ),
        }
    return result


def _plot_micro(data: dict, path: Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(9, 4))
    for k, pressure in enumerate(data["pressures_pa"]):
        ax = fig.add_subplot(1, 2, k + 1)
        solvers = sorted({r["solver"] for r in data["runs"]})
        for s in solvers:
            rows = [r for r in data["runs"] if r["solver"] == s and r["pressure_pa"] == pressure]
            if rows:
                ax.loglog([r["n"] for r in rows], [r["median_time_s"] for r in rows], "o-", label=s)
        ax.set_xlabel("grid size N (N×N pixels)")
        ax.set_ylabel("median solve time [s]")
        ax.set_title(f"nominal pressure {pressure / 1e3:g} kPa, E* = 200 MPa")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)


def _write_stage(
    stage: str,
    data: dict,
    plot: Callable[[dict, Path], None] | None,
    docs_dir: Path | None = None,
) -> Path:
    docs_dir = DOCS if docs_dir is None else Path(docs_dir)
    bench_dir = docs_dir / "bench"
    bench_dir.mkdir(parents=True, exist_ok=True)
    data = {
        "stage": stage,
        "machine": {"cpus": __import__("os").cpu_count(), "platform": platform.platform()},
        "provenance": provenance(),
        **data,
    }
    path = bench_dir / f"{stage}.json"
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=1, default=float))
    if plot is not None:
        plot(data, bench_dir / f"{stage}.png")
    write_benchmarks_md(docs_dir)
    return path


def _over_float64_floor(r: dict, fft: dict) -> float:
    """Finest-level time over the pairs it applied, all counted at the float64 pair floor
    (the issue's definition of the FFT floor), or nan for peers and older records."""
    backend = r["solver"].removeprefix("skisnow[").removesuffix("]")
    floor = fft.get(f"pair_s_{backend}")
    pairs = r.get("fft_pairs_finest", 0) + r.get("fft_pairs32_finest", 0)
    if "fine_level_time_s" not in r or not floor or not pairs:
        return float("nan")
    return r["fine_level_time_s"] / (pairs * floor)


def _micro_md(d: dict) -> list[str]:
    lines = [
        "## Micro scale: one solve (`skisnow bench micro`)",
        "",
        "Self-affine surface (H = 0.8, Sq = 2 µm, 1 µm pixels, seeded), E* = 200 MPa. "
        "Median of repeats, our solver with each FFT backend against the bare FFT floor. "
        "Peers are compared in the work-precision section (`--work-precision`): single peer "
        "runs at their own stopping criteria, one cold run each, are not like-for-like "
        "(issue #13), so any such rows in this file are not shown.",
        "",
        "| N | P [kPa] | solver | median time [s] | iterations (levels) | a_r | "
        "time ratio peer/skisnow | a_r diff | mean-gap diff | finest level: time / FFT floor | "
        "… / float64 floor |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    floors = {f["n"]: f for f in d["fft"]}
    for r in d["runs"]:
        if not r["solver"].startswith("skisnow"):
            continue  # old peer rows: not like-for-like (issue #13); see the next section
        lv = r.get("level_iterations")
        its = f"{r['iterations']}" + (f" ({'/'.join(map(str, lv))})" if lv else "")
        lines.append(
            f"| {r['n']} | {r['pressure_pa'] / 1e3:g} | {r['solver']} | "
            f"{r['median_time_s']:.3g} | {its} | {r['contact_fraction']:.4g} | "
            f"{r.get('time_ratio_vs_skisnow', float('nan')):.3g} | "
            f"{r.get('contact_fraction_rel_diff_vs_skisnow', 0):+.2e} | "
            f"{r.get('mean_gap_rel_diff_vs_skisnow', 0):+.2e} | "
            f"{r.get('time_per_fft_pair_over_floor', float('nan')):.2f} | "
            f"{_over_float64_floor(r, floors.get(r['n'], {})):.2f} |"
        )
    lines += [
        "",
        "Last two columns: time of the finest level's iterations over the bare FFT time of "
        "the pairs they applied, first with float64 and float32 pairs each at their own floor, "
        "then with every pair at the float64 floor (the FFT floor as the issue defines it); "
        "1.0 would be an iteration that costs nothing but its FFTs.",
        "",
        "FFT floor (median of one bare rfft2 + irfft2 pair; `pair32` in single precision):",
        "",
    ]
    lines += ["| N | " + " | ".join(k for k in d["fft"][0] if k != "n") + " |"]
    lines += ["|---" * len(d["fft"][0]) + "|"]
    for f in d["fft"]:
        lines.append(
            f"| {f['n']} | "
            + " | ".join(f"{v * 1e3:.1f} ms" for k, v in f.items() if k != "n")
            + " |"
        )
    if "table" in d:
        t = d["table"]
        lines += [
            "",
            f"Table sweep, {t['n']}², {t['points']} pressures (P/E' "
            f"{t['pressure_ratio_range'][0]:.1e} … {t['pressure_ratio_range'][1]:.1e}): "
            f"skisnow by continuation {t['skisnow_continuation_s']:.1f} s, cold point by point "
            f"{t['skisnow_cold_s']:.1f} s; speed-ups below use the faster of the two "
            f"({t.get('skisnow_best', 'continuation')}).",
            "",
        ]
        for name, p in (t["peers"] if d.get("peers_like_for_like") else {}).items():
            lines.append(
                f"- {name}, cold sweep: {p['cold_sweep_s']:.1f} s — skisnow is "
                f"{p['speedup_of_skisnow']:.2f}× faster; largest a_r difference "
                f"{p['max_contact_fraction_rel_diff']:.1e}"
            )
    lines += ["", "![micro benchmark](bench/micro.png)", ""]
    return lines


def _service_md(d: dict) -> list[str]:
    s, c = d["single"], d["concurrent"]
    return [
        f"## Service load test (`python scripts/loadtest.py`, stage `{d['stage']}`)",
        "",
        f"`skisnow serve` with {d.get('server_workers')} worker processes on this machine, "
        f"{d['distinct_inputs']} distinct seeded `/v1/contact` inputs (skis, grinds, loads, "
        "positions, moduli, porosities).",
        "",
        "| run | requests | p50 [ms] | p99 [ms] | throughput [req/s] | 5xx | answers ≠ single |",
        "|---|---|---|---|---|---|---|",
        f"| 1 client, sequential | {s['requests']} | {s['p50_ms']:.1f} | {s['p99_ms']:.1f} | "
        f"{1e3 / s['p50_ms']:.1f} (1/p50) | {s['non_200']} non-200 | — |",
        f"| {c['clients']} concurrent clients | {c['requests']} | {c['p50_ms']:.1f} | "
        f"{c['p99_ms']:.1f} | {c['throughput_rps']:.1f} | {c['server_errors_5xx']} | "
        f"{c['answers_differing_from_single_client']} |",
        "",
        f"Server memory (RSS, all workers): {c['server_rss_mb_before']:.0f} MB before the "
        f"concurrent run, {c['server_rss_mb_after']:.0f} MB after"
        + (
            f"; sampled every second during it ({c['server_rss_mb_samples']} samples): "
            f"max {c['server_rss_mb_max']:.0f} MB, drift (last tenth − first tenth, medians) "
            f"{c['server_rss_mb_drift']:+.1f} MB."
            if c.get("server_rss_mb_samples")
            else "."
        )
        + (
            " Median RSS per tenth of the run: "
            + ", ".join(f"{v:.0f}" for v in c["server_rss_mb_by_tenth"])
            + f" MB; drift over the second half {c['server_rss_mb_drift_second_half']:+.1f} MB."
            if c.get("server_rss_mb_by_tenth")
            else ""
        ),
        "",
        *(
            [
                "Median RSS by minute [MB]: "
                + ", ".join(f"{v:.0f}" for v in c["server_rss_mb_by_minute"])
                + f" ({c['wall_s'] / 60:.0f} min).",
                "",
            ]
            if len(c.get("server_rss_mb_by_minute", [])) >= 5
            else []
        ),
    ]


def bench_macro_stage(
    repeats: int = 7, inference_calls: int = 300, identification: bool = True
) -> dict:
    """``skisnow bench macro``: one macro solve per demo ski at the default grid against the
    fine reference (``app.commands.macro.bench_macro``), the bending ski, the network inference
    time and (``identification``) the beam identification of both demo skis (about 1.5–2 min
    each on 2 cores; the tests leave it out, tests/test_identify*.py cover it)."""
    from skisnow.app.commands.macro import SKI_DIR, bench_macro
    from skisnow.app.storage.skis import read_ski
    from skisnow.solvers import camber
    from skisnow.solvers.beam import G_STANDARD

    out = {"skis": bench_macro(repeats=repeats), "inference": {}}
    out["flexible"] = bench_flexible(repeats=repeats)
    if identification:
        out["identification"] = bench_identification()
    for name in out["skis"]:
        net = read_ski(SKI_DIR / f"{name}.h5").network
        if net is None:
            continue
        camber.predict_profile(net, 40 * G_STANDARD, -0.160)  # warm-up
        times = []
        for _ in range(inference_calls):
            t0 = time.perf_counter()
            camber.predict_profile(net, 40 * G_STANDARD, -0.160)
            times.append(time.perf_counter() - t0)
        out["inference"][name] = {"calls": inference_calls, "median_s": statistics.median(times)}
    return out


def bench_identification(skis: tuple[str, ...] = ("ski-a", "ski-b")) -> dict:
    """Beam identification of each demo ski from its shipped measurements, as ``skisnow
    identify-ski`` runs it (20 % held out, seed 0): wall time, misfit, held-out errors against
    the measurements and against the design beam near contact (one run each; target ≤ 2 min)."""
    from skisnow.app.commands.identify import identify_report
    from skisnow.app.commands.macro import SKI_DIR
    from skisnow.app.storage.skis import read_ski

    out = {}
    for name in skis:
        rec = read_ski(SKI_DIR / f"{name}.h5")
        rep = identify_report(rec.measurements, rec.beam, 0.2, 0)
        out[name] = {
            k: rep.get(k)
            for k in (
                "identified",
                "cases",
                "held_out_cases",
                "time_s",
                "start_time_s",
                "forward_time_s",
                "noise_um",
                "misfit_um",
                "held_out_vs_measured_rms_um",
                "held_out_vs_design_beam_rms_um",
            )
        }
    return out


def _identification_md(d: dict) -> list[str]:
    if not d:
        return []
    lines = [
        "### Beam identification (issue #12)",
        "",
        "Each demo ski's beam identified from its 425 shipped cases (3 µm noise), 20 % held out "
        "(seed 0), as `skisnow identify-ski` runs it: variable-projection start on 30 cases, then "
        "the forward fit of the exact device model (docs/camber-identification.md). One run each "
        "(target ≤ 2 min per ski; held-out profile ≤ 0.3 µm from the truth where H* < 0.2 mm).",
        "",
        "| ski | time [s] (start + forward) | misfit / noise [µm] | held-out vs measured [µm] "
        "| held-out vs truth near contact [µm] |",
        "|---|---|---|---|---|",
    ]
    for name, r in d.items():
        lines.append(
            f"| {name} | {r['time_s']:.0f} ({r['start_time_s']:.0f} + {r['forward_time_s']:.0f}) "
            f"| {r['misfit_um']:.2f} / {r['noise_um']:.2f} | "
            f"{r['held_out_vs_measured_rms_um']:.2f} | {r['held_out_vs_design_beam_rms_um']:.3f} |"
        )
    lines.append("")
    return lines


def bench_flexible(repeats: int = 7, skis: tuple[str, ...] = ("ski-a", "ski-b")) -> dict:
    """Per demo ski at the papers' case, default grid, in one run: the beam's loaded profile on
    the flat (cached flexibility), the rigid solve of that profile, the flexible solve (cold, from
    its own row-level start, as the service calls it; and warm-started from the rigid pressure),
    and one whole ``/v1/contact`` computation (``service.contact``) with ``ski_model`` rigid and
    auto. Medians [s]."""
    from skisnow.app import service
    from skisnow.app.commands.macro import SKI_DIR
    from skisnow.app.profiles import profile_model
    from skisnow.solvers.beam import G_STANDARD
    from skisnow.solvers.elastic import effective_modulus
    from skisnow.solvers.flexible import prepare_flexible, solve_flexible
    from skisnow.solvers.macro import extrude_profile, solve_macro

    e_eff = effective_modulus(200e6, 0.7e9, 0.3)
    load_n, xf = 40.0 * G_STANDARD, -0.160
    cat = service.load_catalogue(SKI_DIR.parent)
    grind = sorted(cat.grinds)[0]

    def median_of(fn) -> tuple[float, object]:
        res = fn()  # warm-up
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            res = fn()
            times.append(time.perf_counter() - t0)
        return float(np.median(times)), res

    out: dict = {}
    for name in skis:
        rec = cat.ski(name).record
        beam, _ = cat.ski(name).beam()
        if beam is None:
            continue
        pm = profile_model(rec)
        t_prof, (x_prof, gap_prof) = median_of(lambda pm=pm: pm(load_n, xf))
        gm = extrude_profile(
            x_prof, gap_prof, rec.outline.width_m, width_positions_m=rec.outline.positions_m
        )
        t_rigid, rigid = median_of(lambda gm=gm: solve_macro(gm, load_n, xf, e_eff))
        model = prepare_flexible(
            beam, rec.outline.width_m, width_positions_m=rec.outline.positions_m
        )
        t_cold, flex = median_of(lambda m=model: solve_flexible(m, load_n, xf, e_eff))
        t_warm, _ = median_of(
            lambda m=model, r=rigid: solve_flexible(
                m, load_n, xf, e_eff, initial_pressure_pa=r.pressure_pa
            )
        )
        req = {}
        for mode in ("rigid", "auto"):
            inp = service.ContactInputs(name, grind, 40.0, -160.0, 200.0, 0.5, ski_model=mode)
            req[mode], _ = median_of(lambda inp=inp: service.contact(cat, inp))
            req[mode + "_no_band"], _ = median_of(
                lambda inp=inp: service.contact(cat, inp, error_band=False)
            )
        out[name] = {
            "profile_model": pm.source,
            "beam_profile_s": t_prof,
            "rigid_solve_s": t_rigid,
            "flexible_cold_s": t_cold,
            "flexible_warm_s": t_warm,
            "flexible_iterations": flex.iterations,
            "rigid_area_cm2": rigid.apparent_contact_area_m2 * 1e4,
            "flexible_area_cm2": flex.apparent_contact_area_m2 * 1e4,
            "contact_rigid_s": req["rigid"],
            "contact_auto_s": req["auto"],
            "contact_rigid_no_band_s": req["rigid_no_band"],
            "contact_auto_no_band_s": req["auto_no_band"],
            "grind": grind,
        }
    return out


def _flexible_md(d: dict) -> list[str]:
    if not d:
        return []
    lines = [
        "### The bending ski (issue #12)",
        "",
        "Papers' case, default grid, same run. Profile: the ski's profile model as the service "
        "calls it (identified beam: one device solve on the flat with the cached flexibility; "
        "target ≤ 10 ms). Flexible "
        "solve: beam and snow as one complementarity problem (target ≤ 2 × rigid and ≤ 40 ms), "
        "cold (its own row-level start, as the service calls it) and warm-started from the rigid "
        "pressure. Request: one "
        "`service.contact` computation (profile, macro, multiscale; auto also solves the "
        "flexible ski), with its 90 % error band and without it (the band re-solves a rigid "
        "answer 9 times on a grid twice as coarse, an answer of the bending ski once plus once "
        "per plausible beam drawn from the identification; docs/limits.md, Error band).",
        "",
        "| ski | profile model | profile [ms] | rigid solve [ms] | flexible cold [ms] | "
        "flexible warm [ms] | cold / rigid | request rigid [ms] (no band) | request auto [ms] "
        "(no band) | area rigid → flexible [cm²] |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in d.items():
        nb_rigid = 1e3 * r.get("contact_rigid_no_band_s", float("nan"))
        nb_auto = 1e3 * r.get("contact_auto_no_band_s", float("nan"))
        lines.append(
            f"| {name} | {r.get('profile_model', 'design_beam')} | "
            f"{1e3 * r['beam_profile_s']:.2f} | {1e3 * r['rigid_solve_s']:.1f} | "
            f"{1e3 * r['flexible_cold_s']:.1f} | {1e3 * r['flexible_warm_s']:.1f} | "
            f"{r['flexible_cold_s'] / r['rigid_solve_s']:.1f} | "
            f"{1e3 * r['contact_rigid_s']:.1f} ({nb_rigid:.1f}) | "
            f"{1e3 * r['contact_auto_s']:.1f} ({nb_auto:.1f}) | "
            f"{r['rigid_area_cm2']:.2f} → {r['flexible_area_cm2']:.2f} |"
        )
    lines.append("")
    return lines


def _macro_md(d: dict) -> list[str]:
    lines = [
        "## Macro scale: one ski-on-snow solve (`skisnow bench macro`)",
        "",
        "Papers' case (40 kg at −160 mm, E_snow 200 MPa), each demo ski's network profile; "
        "default grid against the 0.5 mm × 16 reference. Targets: ≤ 30 ms per solve, apparent "
        "area within 1 %, network inference ≤ 1 ms.",
        "",
        "| ski | grid [mm] | median solve [ms] | apparent area [cm²] | peak pressure [kPa] "
        "| iterations | area error | peak error | reference time / default |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in d["skis"].items():
        dflt, fine = r["default"], r["fine"]
        for label, row in (("default", dflt), ("fine", fine)):
            err = (
                f"{100 * r['area_error']:+.2f} % | {100 * r['peak_pressure_error']:+.1f} %"
                if label == "default"
                else "— | —"
            )
            ratio = (
                f"{fine['median_time_s'] / dflt['median_time_s']:.1f}" if label == "fine" else ""
            )
            lines.append(
                f"| {name} ({label}) | {row['pixel_mm'][0]:g} × {row['pixel_mm'][1]:.2f} | "
                f"{1e3 * row['median_time_s']:.1f} | {row['area_cm2']:.2f} | "
                f"{row['peak_pressure_kpa']:.0f} | {row['iterations']} | {err} | {ratio} |"
            )
    for name, r in d.get("inference", {}).items():
        lines.append("")
        lines.append(
            f"Network inference, {name}: median {1e3 * r['median_s']:.2f} ms over "
            f"{r['calls']} calls."
        )
    lines.append("")
    lines += _flexible_md(d.get("flexible", {}))
    lines += _identification_md(d.get("identification", {}))
    return lines


def _micro_peers_md(d: dict) -> list[str]:
    from skisnow.app.evidence.peers import render_md

    return render_md(d)


def _accuracy_md(d: dict) -> list[str]:
    from skisnow.app.evidence.accuracy import render_md

    return render_md(d)


STAGE_RENDERERS: dict[str, Callable[[dict], list[str]]] = {
    "micro": _micro_md,
    "macro": _macro_md,
    "accuracy": _accuracy_md,
    "service": _service_md,
    "service-32": _service_md,
    "memory": _service_md,
    "micro-peers": _micro_peers_md,
}


def write_benchmarks_md(docs_dir: Path | None = None) -> Path:
    """Regenerate docs/benchmarks.md from every docs/bench/*.json."""
    docs_dir = DOCS if docs_dir is None else Path(docs_dir)
    bench_dir = docs_dir / "bench"
    lines = [
        "# Benchmarks",
        "",
        "Generated by `skisnow bench STAGE`; do not edit by hand. Each section records the "
        "machine, the commit and the command in `docs/bench/STAGE.json`. Times are medians; "
        "compare ratios measured in the same run, not absolute times across runs.",
        "",
    ]
    for path in sorted(bench_dir.glob("*.json")):
        data = json.loads(path.read_text())
        if "stage" not in data or "machine" not in data:
            log.warning("%s is not a benchmark stage file (no stage/machine); skipped", path)
            continue
        stage = data["stage"]
        render = STAGE_RENDERERS.get(stage)
        prov = data.get("provenance", {})
        if render is None:
            lines += [f"## {stage}", "", f"See `docs/bench/{path.name}`.", ""]
        else:
            lines += render(data)
        lines += [
            f"_Measured {prov.get('created_utc', '?')} at commit {prov.get('git_commit', '?')[:12]}"
            f" with `{prov.get('command_line', '?')}` on {data['machine']['cpus']} cores._",
            "",
        ]
    out = docs_dir / "benchmarks.md"
    with atomic_path(out) as tmp:
        tmp.write_text("\n".join(lines))
    return out


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("bench", help="benchmarks against peers; results into docs/")
    bsub = p.add_subparsers(dest="stage", required=True, metavar="STAGE")
    m = bsub.add_parser("micro", help="micro-scale solver against installed peers")
    m.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
    m.add_argument("--repeats", type=int, default=3)
    m.add_argument(
        "--peers",
        nargs="*",
        default=[],
        choices=list(PEERS),
        help="old single-run peer rows (not like-for-like; --work-precision replaces them)",
    )
    m.add_argument(
        "--work-precision",
        action="store_true",
        help="the fair peer benchmark instead: work-precision curves of every installed solver "
        "(app/bench_peers.py), written to docs/bench/micro-peers.json and .png",
    )
    m.add_argument("--wp-sizes", type=int, nargs="+", default=[256, 512])
    m.add_argument("--wp-repeats", type=int, default=5)
    m.add_argument("--threads", type=int, default=2, help="threads pinned for every solver")
    m.add_argument("--process-repeats", type=int, default=5)
    m.add_argument(
        "--solvers",
        nargs="*",
        default=["skisnow", "contactmechanics", "tamaas", "aspher"],
        choices=["skisnow", "contactmechanics", "tamaas", "aspher"],
    )
    m.add_argument("--aspher-probe-size", type=int, default=1024, help="0 skips the ASPHER probe")
    m.add_argument("--table-size", type=int, default=1024)
    m.add_argument("--table-points", type=int, default=12, help="0 skips the table sweep")
    m.add_argument(
        "--table-peers",
        nargs="*",
        default=[],
        choices=list(PEERS),
        help="peers that solve the table sweep cold (slow peers take tens of minutes at 1024²)",
    )
    m.set_defaults(func=_run_micro)
    mac = bsub.add_parser("macro", help="macro BEM per demo ski: default grid vs fine reference")
    mac.add_argument("--repeats", type=int, default=7)
    mac.set_defaults(func=_run_macro)
    from skisnow.app.evidence import accuracy as bench_accuracy

    bench_accuracy.register(bsub)


def _run_micro(args: argparse.Namespace) -> int:
    if args.work_precision:
        import tempfile

        from skisnow.app.evidence import peers as bench_peers

        with tempfile.TemporaryDirectory(prefix="skisnow-wp-") as tmp:
            data = bench_peers.bench_work_precision(
                args.wp_sizes,
                args.wp_repeats,
                args.solvers,
                args.threads,
                args.process_repeats,
                args.aspher_probe_size or None,
                Path(tmp),
            )
        path = _write_stage("micro-peers", data, bench_peers.plot_work_precision)
        print(f"wrote {path} and {DOCS / 'benchmarks.md'}")
        return 0
    data = bench_micro(
        args.sizes,
        args.repeats,
        args.peers,
        args.table_size,
        args.table_points,
        args.table_peers,
    )
    path = _write_stage("micro", data, _plot_micro)
    print(f"wrote {path} and {DOCS / 'benchmarks.md'}")
    return 0


def _run_macro(args: argparse.Namespace) -> int:
    path = _write_stage("macro", bench_macro_stage(args.repeats), None)
    print(f"wrote {path} and {DOCS / 'benchmarks.md'}")
    return 0
