"""``skisnow bench micro --work-precision``: a like-for-like peer benchmark (issue #13 point 5).

Every solver (ours and each installed peer: ContactMechanics, Tamaas, ASPHER) solves the same
seeded surface at the same nominal pressure at 3–4 of its own tolerances; its error is measured
against one tight common reference (skisnow at ``REFERENCE_TOL``, cross-checked by every
peer's tightest point) in three quantities: contact area fraction a_r, mean gap ḡ and the
pressure field (relative L2). Work-precision curves (time against error) compare solvers at
equal error, whatever their stopping criteria mean.

Rules, the same for every solver:

- **Own process, pinned threads.** Each solver runs in a fresh worker process
  (``python -m skisnow.app.evidence.peers worker``) whose environment sets ``OMP_NUM_THREADS``,
  ``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS``, ``NUMBA_NUM_THREADS`` and
  ``VECLIB_MAXIMUM_THREADS`` to ``threads`` before anything is imported; our FFTs get
  ``workers=threads``. The worker records the environment, ``threadpoolctl``'s view of the
  loaded thread pools (when installed) and the package versions.
- **Timer.** The timer wraps one whole adapter call: model/system/half-space construction from
  the height array, the solve, and nothing else (extracting a_r, ḡ and the pressure field is
  outside). Nothing is prepared for one solver and not for another.
- **Warm-up.** One untimed solve per solver, size and tolerance before its ``repeats`` timed
  ones (JIT compilation, FFT planning and library caches are paid once, as a service pays them).
- **Repeats.** ``repeats`` (≥ 5 in the docs run) timed solves; the median is reported, all
  times are kept.
- **Configuration.** Each peer is called as its own documentation's examples call it
  (``PEER_CONFIG``): ContactMechanics ``make_system(...).minimize_proxy`` with its penetration
  tolerance; Tamaas ``PolonskyKeerRey`` (its rough-contact tutorial) with its relative
  tolerance; ASPHER ``solve_nested(backend="periodic")`` in its quick start's scaled units
  (E* = 1, domain side = 1).

Whole-process times: ``python -m skisnow.app.evidence.peers once ...`` run ``repeats`` times,
timed from outside (interpreter start, imports, surface, solve, exit), side by side with the
in-process median. ``aspher_probe`` measures ASPHER under the conditions the old benchmark
mixed (inside a process that had already run our solver, unpinned threads, SI against scaled
units, our surface against ASPHER's own generator).
"""

from __future__ import annotations

import importlib.metadata
import itertools
import json
import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

E_STAR_PA = 200e6  # Johnson's composite modulus of the benchmark [Pa]; E' = 2 E*
PIXEL_M = 1e-6  # [m]
SQ_M = 2e-6  # RMS height of the benchmark surface [m]
PRESSURE_PA = 1e6  # nominal pressure of the curves [Pa] (the case)
REFERENCE_TOL = 1e-10  # skisnow's tolerance for the common reference [-]
THREAD_ENV = (
    "OMP_NUM_THREADS",
    "OPENBLAS_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMBA_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
)

#: each solver's own tolerance parameter and the values swept (loosest first)
TOLERANCES: dict[str, tuple[str, tuple[float, ...]]] = {
    "skisnow": ("tol (RMS gap on contact / RMS height)", (1e-3, 1e-4, 1e-5, 1e-6)),
    "contactmechanics": ("pentol / Sq (max penetration)", (1e-2, 1e-3, 1e-4, 1e-5)),
    "tamaas": ("tolerance (relative)", (1e-4, 1e-6, 1e-8, 1e-10)),
    "aspher": ("tol (certified FW gap and penetration)", (1e-4, 1e-6, 1e-8, 1e-10)),
}

PEER_CONFIG = {
    "skisnow": "solve_micro(heights, pixel, P, E', tol=..., workers=threads): nested grids, "
    "pyFFTW when installed (the default)",
    "contactmechanics": "make_system(substrate='periodic', surface=Topography(periodic=True), "
    "young=E*).minimize_proxy(external_force=P·A, pentol=t·Sq, maxiter=20000)",
    "tamaas": "ModelFactory.createModel(basic_2d); PolonskyKeerRey(model, surface, tol)"
    ".solve(P) (its rough-contact example), E = E*, nu = 0",
    "aspher": "solve_nested(N, gap=-h/L, p_nominal=P/E*, backend='periodic', tol=t) in the "
    "quick start's scaled units (E* = 1, domain side L = 1), other options at their defaults",
}

PACKAGES = {
    "skisnow": ("numpy", "scipy", "pyFFTW", "numba"),
    "contactmechanics": ("ContactMechanics", "SurfaceTopography", "muFFT", "numpy"),
    "tamaas": ("tamaas", "numpy"),
    "aspher": ("aspher", "numpy"),
}


def bench_surface(n: int, seed: int = 2026) -> np.ndarray:
    """The benchmark surface: self-affine, H = 0.8, Sq 2 µm, 1 µm pixels, seeded [m]."""
    from skisnow.solvers.texture import self_affine_surface

    rng = np.random.default_rng(seed)
    return self_affine_surface((n, n), PIXEL_M, hurst=0.8, rms_height_m=SQ_M, rng=rng)


# --------------------------------------------------------------------------- adapters
# Each adapter: (heights [m], pressure [Pa], E' [Pa], tol, threads) -> dict with "pressure_pa"
# (field), "mean_gap_m", "iterations", "converged". The call is what the timer wraps.


def _solve_skisnow(h: np.ndarray, p: float, e_eff: float, tol: float, threads: int) -> dict:
    from skisnow.solvers.micro import solve_micro

    res = solve_micro(h, PIXEL_M, p, e_eff, tol=tol, max_iterations=20000, workers=threads)
    return {
        "pressure_pa": res.pressure_pa,
        "mean_gap_m": res.mean_gap_m,
        "iterations": res.iterations,
        "converged": res.converged,
    }


def _solve_contactmechanics(
    h: np.ndarray, p: float, e_eff: float, tol: float, threads: int
) -> dict:
    from ContactMechanics.Factory import make_system
    from SurfaceTopography import Topography

    n, m = h.shape
    size = (n * PIXEL_M, m * PIXEL_M)
    topo = Topography(h, physical_sizes=size, periodic=True)
    system = make_system(substrate="periodic", surface=topo, young=e_eff / 2)
    res = system.minimize_proxy(
        external_force=p * size[0] * size[1], pentol=tol * SQ_M, maxiter=20000
    )
    forces = np.asarray(res.jac)  # contact force per pixel [N]
    return {
        "pressure_pa": forces / (PIXEL_M * PIXEL_M),
        "mean_gap_m": float(np.asarray(system.compute_gap(res.x, res.offset)).mean()),
        "iterations": int(getattr(res, "nit", -1)),
        "converged": bool(res.success),
    }


def _solve_tamaas(h: np.ndarray, p: float, e_eff: float, tol: float, threads: int) -> dict:
    import tamaas as tm

    tm.set_log_level(tm.LogLevel.warning)  # its per-solve iteration log goes to stdout
    n, m = h.shape
    model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [n * PIXEL_M, m * PIXEL_M], [n, m])
    model.E = e_eff / 2
    model.nu = 0.0
    solver = tm.PolonskyKeerRey(model, h, tol)
    solver.max_iter = 20000
    err = solver.solve(p)  # the final relative error; above tol means not converged
    trac = np.asarray(model.traction).reshape(n, m)
    disp = np.asarray(model.displacement).reshape(n, m)
    gap = disp - h
    gap -= gap[trac > 0].mean() if np.any(trac > 0) else gap.min()
    err = float(err) if err is not None else float("nan")
    return {
        "pressure_pa": trac,
        "mean_gap_m": float(np.maximum(gap, 0).mean()),
        "iterations": -1,  # not exposed by PolonskyKeerRey.solve
        "converged": bool(np.isfinite(err) and err <= tol),
        "final_error": err,
    }


def _solve_aspher(h: np.ndarray, p: float, e_eff: float, tol: float, threads: int) -> dict:
    return _aspher_call(h, p, e_eff, tol, scaled=True)


def _aspher_call(h: np.ndarray, p: float, e_eff: float, tol: float, *, scaled: bool) -> dict:
    import aspher

    n = h.shape[0]
    if h.shape[1] != n or n % 64:
        raise ValueError(f"aspher.solve_nested needs a square grid of 64·2^k pixels, got {h.shape}")
    e_star = e_eff / 2
    side = n * PIXEL_M
    if scaled:  # lengths in units of the domain side, stresses in units of E*
        res = aspher.solve_nested(
            n, (-h / side).ravel(), p / e_star, backend="periodic", tol=tol, max_iter=20000
        )
        p_unit, l_unit = e_star, side
    else:  # SI, as the old benchmark called it
        res = aspher.solve_nested(
            n,
            (h.max() - h).ravel(),
            p,
            domain_size=side,
            E_star=e_star,
            backend="periodic",
            tol=tol,
            max_iter=20000,
        )
        p_unit, l_unit = 1.0, 1.0
    return {
        "pressure_pa": np.asarray(res.pressure).reshape(n, n) * p_unit,
        "mean_gap_m": float(np.mean(np.asarray(res.gap))) * l_unit,
        "iterations": int(res.iterations),
        "converged": bool(res.converged),
    }


ADAPTERS: dict[str, Callable[..., dict]] = {
    "skisnow": _solve_skisnow,
    "contactmechanics": _solve_contactmechanics,
    "tamaas": _solve_tamaas,
    "aspher": _solve_aspher,
}
IMPORT_NAME = {
    "skisnow": "skisnow.solvers.micro",
    "contactmechanics": "ContactMechanics",
    "tamaas": "tamaas",
    "aspher": "aspher",
}


def versions(solver: str) -> dict[str, str]:
    out = {}
    for pkg in PACKAGES[solver]:
        try:
            out[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def thread_state() -> dict:
    """The thread settings this process runs with: env variables and loaded pools."""
    state: dict = {"env": {k: os.environ.get(k) for k in THREAD_ENV}}
    try:
        from threadpoolctl import threadpool_info

        state["threadpools"] = [
            {k: d.get(k) for k in ("user_api", "internal_api", "num_threads", "version")}
            for d in threadpool_info()
        ]
    except ImportError:
        state["threadpools"] = "threadpoolctl not installed"
    return state


def _summary(out: dict) -> dict:
    p = np.asarray(out["pressure_pa"], dtype=float)
    return {
        "contact_fraction": float(np.mean(p > 0)),
        "mean_gap_m": float(out["mean_gap_m"]),
        "mean_pressure_pa": float(p.mean()),
        "iterations": int(out["iterations"]),
        "converged": bool(out["converged"]),
        **({"final_error": out["final_error"]} if "final_error" in out else {}),
    }


def errors_against(p: np.ndarray, summ: dict, ref_p: np.ndarray, ref: dict) -> dict:
    """Relative errors of one solution against the reference: a_r, ḡ, pressure L2 [-]."""
    return {
        "err_contact_fraction": abs(summ["contact_fraction"] / ref["contact_fraction"] - 1),
        "err_mean_gap": abs(summ["mean_gap_m"] / ref["mean_gap_m"] - 1),
        "err_pressure_l2": float(np.linalg.norm(p - ref_p) / np.linalg.norm(ref_p)),
    }


def run_worker(
    solver: str,
    n: int,
    pressure_pa: float,
    tols: list[float],
    repeats: int,
    threads: int,
    fields_dir: Path,
) -> dict:
    """In one (pinned) process: per tolerance one warm-up and ``repeats`` timed solves.

    The last solution's pressure field of each tolerance is saved to ``fields_dir`` so the
    parent computes every error against the same reference."""
    h = bench_surface(n)
    e_eff = 2 * E_STAR_PA
    fn = ADAPTERS[solver]
    points = []
    for k, tol in enumerate(tols):
        fn(h, pressure_pa, e_eff, tol, threads)  # warm-up, untimed
        times = []
        out = None
        for _ in range(repeats):
            t0 = time.perf_counter()
            out = fn(h, pressure_pa, e_eff, tol, threads)
            times.append(time.perf_counter() - t0)
        field_path = fields_dir / f"{solver}-{n}-{k}.npy"
        np.save(field_path, np.asarray(out["pressure_pa"], dtype=float))
        points.append(
            {
                "tol": tol,
                "median_time_s": statistics.median(times),
                "times_s": times,
                "field": str(field_path),
                **_summary(out),
            }
        )
    return {
        "solver": solver,
        "n": n,
        "pressure_pa": pressure_pa,
        "points": points,
        "threads": thread_state(),
        "versions": versions(solver),
    }


def pinned_env(threads: int | None) -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(Path(__file__).resolve().parents[2]), *filter(None, [env.get("PYTHONPATH")])]
    )
    if threads is not None:
        for k in THREAD_ENV:
            env[k] = str(threads)
    return env


def _spawn(args: list[str], threads: int | None, timeout_s: float = 3600) -> dict:
    cmd = [sys.executable, "-m", "skisnow.app.evidence.peers", *args]
    proc = subprocess.run(
        cmd, env=pinned_env(threads), capture_output=True, text=True, timeout=timeout_s
    )
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {proc.stderr[-2000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def available(solver: str) -> bool:
    try:
        importlib.import_module(IMPORT_NAME[solver])
    except ImportError:
        return False
    return True


def whole_process_s(
    solver: str, n: int, pressure_pa: float, tol: float, repeats: int, threads: int | None
) -> dict:
    """Median wall time of ``repeats`` fresh processes that import, build the surface, solve
    once and exit, timed from outside [s]; with the in-process solve time each one reports."""
    walls, inner = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        rep = _spawn(
            ["once", solver, str(n), repr(pressure_pa), repr(tol), str(threads or 0)], threads
        )
        walls.append(time.perf_counter() - t0)
        inner.append(rep["solve_s"])
    return {
        "tol": tol,
        "process_median_s": statistics.median(walls),
        "process_times_s": walls,
        "cold_solve_in_process_median_s": statistics.median(inner),
    }


def aspher_probe(n: int, pressure_pa: float, repeats: int, threads: int) -> dict:
    """ASPHER at tol 1e-8 (the old benchmark's setting) under the conditions the old benchmark
    and the issue's stand-alone run differed in; each row: median time, iterations, ms/iteration.
    """
    rows = {}
    cases = {
        "own process, pinned, scaled units, our surface": ("probe", "scaled", "ours", threads),
        "own process, pinned, SI units, our surface": ("probe", "si", "ours", threads),
        "own process, pinned, scaled units, ASPHER's rfgen surface": (
            "probe",
            "scaled",
            "rfgen",
            threads,
        ),
        "own process, threads not pinned, SI units, our surface": ("probe", "si", "ours", None),
        "after skisnow in the same process (old bench), SI, our surface": (
            "probe-after-ours",
            "si",
            "ours",
            None,
        ),
    }
    for label, (mode, units, surf, thr) in cases.items():
        rows[label] = _spawn(
            [mode, str(n), repr(pressure_pa), units, surf, str(repeats), str(thr or 0)], thr
        )
    return rows


def _probe(
    n: int, pressure_pa: float, units: str, surface: str, repeats: int, after_ours: bool
) -> dict:
    e_eff = 2 * E_STAR_PA
    if surface == "rfgen":
        import rfgen

        z = rfgen.selfaffine_field(
            N=n, Hurst=0.8, k_low=4 / n, k_high=64 / n, rng=np.random.default_rng(2026)
        )
        h = np.asarray(z).reshape(n, n)
        h = (h - h.mean()) * SQ_M / h.std()
    else:
        h = bench_surface(n)
    if after_ours:  # the old benchmark: our solver (pyFFTW, numba) ran first in this process
        for _ in range(2):
            _solve_skisnow(h, pressure_pa, e_eff, 1e-6, None)
    t0 = time.perf_counter()
    _aspher_call(h, pressure_pa, e_eff, 1e-8, scaled=units == "scaled")  # warm-up
    first_s = time.perf_counter() - t0
    times, its = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = _aspher_call(h, pressure_pa, e_eff, 1e-8, scaled=units == "scaled")
        times.append(time.perf_counter() - t0)
        its.append(out["iterations"])
    med = statistics.median(times)
    return {
        "median_time_s": med,
        "times_s": times,
        "iterations": its[0],
        "ms_per_iteration": 1e3 * med / max(its[0], 1),
        "first_call_s": first_s,
        "contact_fraction": float(np.mean(out["pressure_pa"] > 0)),
        "threads": thread_state(),
    }


def bench_work_precision(
    sizes: list[int],
    repeats: int,
    solvers: list[str],
    threads: int,
    process_repeats: int,
    probe_size: int | None,
    work_dir: Path,
) -> dict:
    """The whole stage; see the module docstring. Workers write pressure fields to work_dir."""
    work_dir.mkdir(parents=True, exist_ok=True)
    present = [s for s in solvers if available(s)]
    out: dict = {
        "pressure_pa": PRESSURE_PA,
        "e_star_pa": E_STAR_PA,
        "surface": "self-affine H = 0.8, Sq 2 µm, 1 µm pixels, seed 2026 (bench_surface)",
        "threads": threads,
        "repeats": repeats,
        "reference": f"skisnow at tol {REFERENCE_TOL:g}, max_iterations 20000",
        "tolerances": {s: {"parameter": TOLERANCES[s][0]} for s in present},
        "config": {s: PEER_CONFIG[s] for s in present},
        "missing": [s for s in solvers if s not in present],
        "timer": "one adapter call: model/half-space construction from the height array and "
        "the solve; one untimed warm-up per tolerance; median of the repeats",
        "sizes": [],
    }
    for n in sizes:
        ref_rep = _spawn(
            [
                "worker",
                "skisnow",
                str(n),
                repr(PRESSURE_PA),
                repr(REFERENCE_TOL),
                "1",
                str(threads),
                str(work_dir),
                "ref",
            ],
            threads,
        )
        ref = ref_rep["points"][0]
        ref_p = np.load(ref["field"])
        Path(ref["field"]).unlink(missing_ok=True)
        block: dict = {
            "n": n,
            "reference": {k: v for k, v in ref.items() if k != "field"},
            "solvers": {},
        }
        for s in present:
            tols = TOLERANCES[s][1]
            rep = _spawn(
                [
                    "worker",
                    s,
                    str(n),
                    repr(PRESSURE_PA),
                    ",".join(map(repr, tols)),
                    str(repeats),
                    str(threads),
                    str(work_dir),
                    "",
                ],
                threads,
            )
            for pt in rep["points"]:
                pt.update(errors_against(np.load(pt["field"]), pt, ref_p, ref))
                Path(pt.pop("field")).unlink(missing_ok=True)
            if process_repeats > 0:
                rep["whole_process"] = whole_process_s(
                    s, n, PRESSURE_PA, tols[-2], process_repeats, threads
                )
            block["solvers"][s] = rep
        block["equal_error"] = equal_error_table(block["solvers"])
        out["sizes"].append(block)
    if probe_size and available("aspher"):
        out["aspher_probe"] = {
            "n": probe_size,
            "rows": aspher_probe(probe_size, PRESSURE_PA, repeats, threads),
        }
    return out


def time_at_error(points: list[dict], key: str, target: float) -> float:
    """Time to reach ``target`` relative error in ``key``, interpolated log-log between the
    two points that bracket it (nan when no point reaches it) [s]."""
    pts = sorted(
        ((max(p[key], 1e-16), p["median_time_s"]) for p in points if p["converged"]),
        key=lambda x: -x[0],
    )
    for (e0, t0), (e1, t1) in itertools.pairwise(pts):
        if e1 <= target <= e0:
            if e0 == e1:
                return min(t0, t1)
            w = (np.log(target) - np.log(e0)) / (np.log(e1) - np.log(e0))
            return float(np.exp(np.log(t0) + w * (np.log(t1) - np.log(t0))))
    reached = [t for e, t in pts if e <= target]
    return min(reached) if reached else float("nan")


EQUAL_ERROR_TARGETS = {
    "err_contact_fraction": (1e-2, 1e-3, 1e-4),
    "err_pressure_l2": (1e-3, 1e-4, 1e-5),
}


def equal_error_table(per_solver: dict) -> list[dict]:
    rows = []
    for key, targets in EQUAL_ERROR_TARGETS.items():
        for target in targets:
            times = {s: time_at_error(r["points"], key, target) for s, r in per_solver.items()}
            rows.append({"error": key, "target": target, "time_s": times})
    return rows


def _main(argv: list[str]) -> int:
    mode = argv[0]
    if mode == "worker":
        solver, n, p, tols, reps, thr, wdir, tag = argv[1:9]
        rep = run_worker(
            solver,
            int(n),
            float(p),
            [float(t) for t in tols.split(",")],
            int(reps),
            int(thr),
            Path(wdir),
        )
        if tag:
            for pt in rep["points"]:
                new = Path(pt["field"]).with_name(f"{tag}-{Path(pt['field']).name}")
                Path(pt["field"]).rename(new)
                pt["field"] = str(new)
        print(json.dumps(rep, default=float))
    elif mode == "once":
        solver, n, p, tol, thr = argv[1:6]
        h = bench_surface(int(n))
        t0 = time.perf_counter()
        ADAPTERS[solver](h, float(p), 2 * E_STAR_PA, float(tol), int(thr) or None)
        print(json.dumps({"solve_s": time.perf_counter() - t0}))
    elif mode in ("probe", "probe-after-ours"):
        n, p, units, surf, reps, _thr = argv[1:7]
        print(
            json.dumps(
                _probe(int(n), float(p), units, surf, int(reps), mode == "probe-after-ours"),
                default=float,
            )
        )
    else:
        raise SystemExit(f"unknown mode {mode!r}")
    return 0


if __name__ == "__main__":
    raise SystemExit(_main(sys.argv[1:]))


# --------------------------------------------------------------------------- report
