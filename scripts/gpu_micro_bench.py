"""Cold micro solves, the project's CPU solver against the torch backend on one machine.

Times :func:`skisnow.solvers.micro.solve_micro` (numpy/scipy + pyFFTW FFTs, ``backend="auto"``,
``workers`` = the usable cores) against :func:`skisnow.solvers.micro_torch.solve_micro_torch`
(``device="cuda"``; ``--device cpu`` runs torch on the CPU, to test this script without a GPU)
on the shipped texture grind-2 refined to each grid size (the same surface on a finer grid,
:func:`skisnow.app.storage.textures.refined_texture`), at E' = 100 MPa and one nominal pressure
``P = ratio · E'`` (partial contact), tol 1e-6, at most 2000 iterations.

Cold solve: each call builds its half-space (FFT plans, kernels) and starts from the nested-grid
continuation; no warm start, nothing passed between calls. What the process keeps from one
call to the next is not cold: numba's compiled kernels, the CUDA context, torch's cuFFT plan
cache and caching allocator. Hence, before anything is timed, one untimed solve of each solver
on the stored 1024² texture (numba compilation, CUDA context and cuFFT start-up). The first
torch repeat at a size still includes that size's cuFFT plans and the allocator's growth (the
plan cache and the allocator are emptied between sizes); ``first_s`` and ``median_rest_s``
separate it. The torch wall time is the whole call: the input checks on the host, the heights
moved to the device, the half-space kernels, the result moved back and its gap statistics.

Sizes of 1024 and more are 1024 · 2^k up to 16384 (refine 2^k of the stored 1024² texture,
:func:`refined_heights`); smaller sizes are the top-left crop of the 1024² texture,
which is not the same periodic surface, marked "crop (test only)".

The JSON is rewritten (atomically) after every solve, so a killed run leaves what it measured.
Runs from a copy of the repository without an install (a ``skisnow`` shim is made). On the GPU
machine (pyFFTW carried as a wheel in ``.whl/``, ignored by .git/info/exclude; without it the CPU
solver falls back to scipy.fft, recorded as fft_backend_cpu_solver):

    python3 -m pip install -q --no-index --no-deps --no-compile --target /tmp/site .whl/*.whl
    PYTHONPATH=/tmp/site python3 scripts/gpu_micro_bench.py --sizes 1024 2048 4096 8192 16384 \\
        --cpu-max-size 8192 --time-budget-s 150 --out $OUT/bench.json --chart $OUT/bench.png

Here, on the CPU (a few minutes):

    python3 scripts/gpu_micro_bench.py --sizes 256 512 --device cpu --cpu-max-size 512 \\
        --out /tmp/b.json --chart /tmp/b.png

``--replot JSON --chart PNG`` redraws the chart of a finished (or killed) run.
"""

from __future__ import annotations

import os

# the OpenMP spin of app/__init__.py, before any runtime starts (numba, pyFFTW, torch)
os.environ.setdefault("GOMP_SPINCOUNT", "1000")

import argparse
import datetime as _dt
import gc
import json
import platform
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

T_START = time.perf_counter()
REPO = Path(__file__).resolve().parents[1]
SCHEMA = "skisnow.gpu_micro_bench/1"
TEXTURE = "grind-2"
BASE_SIZE = 1024  # the stored texture's grid
E_EFF_PA = 100e6
#: CPU sizes from which one repeat is run (a cold 8192² CPU solve takes tens of seconds)
CPU_SINGLE_REPEAT_FROM = 8192

_SHIM: tempfile.TemporaryDirectory | None = None


def _import_skisnow() -> None:
    """Make ``skisnow`` importable: the install if there is one, else a shim folder whose
    ``skisnow`` package is this checkout (its app/, solvers/ and tables/)."""
    global _SHIM
    try:
        import skisnow.solvers  # noqa: F401
    except ModuleNotFoundError as exc:
        if exc.name not in ("skisnow", "skisnow.solvers"):
            raise
        _SHIM = tempfile.TemporaryDirectory(prefix="skisnow-shim-")
        pkg = Path(_SHIM.name) / "skisnow"
        pkg.mkdir()
        for name in ("app", "solvers", "tables"):
            (pkg / name).symlink_to(REPO / name)
        sys.path.insert(0, _SHIM.name)
        for mod in [m for m in sys.modules if m == "skisnow" or m.startswith("skisnow.")]:
            del sys.modules[mod]


def elapsed() -> float:
    return time.perf_counter() - T_START


def log(msg: str) -> None:
    print(f"[{elapsed():7.1f} s] {msg}", flush=True)


# --------------------------------------------------------------------------- surfaces


def refined_heights(refine: int):
    """(heights [m], pixel size [m], note) of grind-2 refined ``refine``× (1, 2, 4, 8 or 16):
    :func:`skisnow.app.storage.textures.refined_texture`, the same surface on a finer grid."""
    from skisnow.app.storage import textures

    tx = textures.refined_texture(TEXTURE, refine)
    return tx.heights_m, tx.pixel_size_m, f"refined_texture({TEXTURE!r}, {refine})"


def make_surface(size: int) -> dict:
    """The heights of one grid size with where they come from, and their generation time."""
    t0 = time.perf_counter()
    if size < BASE_SIZE:
        h, dx, note = refined_heights(1)
        h = h[:size, :size].copy()
        method, refine = "crop (test only)", None
        note = (
            f"top-left {size}x{size} crop of the stored {BASE_SIZE}² texture: not the same "
            "periodic surface (test only)"
        )
    else:
        refine = size // BASE_SIZE
        h, dx, note = refined_heights(refine)
        method = "refined"
    return {
        "heights": h,
        "pixel_size_m": float(dx),
        "info": {
            "texture": TEXTURE,
            "method": method,
            "refine": refine,
            "pixel_size_m": float(dx),
            "note": note,
            "generation_s": time.perf_counter() - t0,
        },
    }


# --------------------------------------------------------------------------- solves


class Bench:
    def __init__(self, args: argparse.Namespace):
        import numpy as np
        from skisnow.solvers.elastic import resolve_backend

        self.args = args
        self.np = np
        self.torch = None
        self.cuda = args.device == "cuda"
        self.workers = args.cpu_workers or len(os.sched_getaffinity(0))
        self.fft_backend = resolve_backend("auto")
        self.p_nom = args.ratio * E_EFF_PA
        self.out = Path(args.out)
        self.doc: dict = {
            "schema": SCHEMA,
            "status": "running",
            "command_line": " ".join([sys.executable, *sys.argv]),
            "settings": {
                "texture": TEXTURE,
                "effective_modulus_pa": E_EFF_PA,
                "ratio_p_over_e": args.ratio,
                "nominal_pressure_pa": self.p_nom,
                "tol": args.tol,
                "max_iterations": args.max_iterations,
                "sizes": args.sizes,
                "cpu_max_size": args.cpu_max_size,
                "gpu_repeats": args.gpu_repeats,
                "cpu_repeats": args.cpu_repeats,
                "cpu_single_repeat_from": CPU_SINGLE_REPEAT_FROM,
                "torch_device": args.device,
                "cpu_solver": (
                    f"skisnow.solvers.micro.solve_micro(backend='auto' -> "
                    f"{self.fft_backend!r}, workers={self.workers})"
                ),
                "torch_solver": (
                    f"skisnow.solvers.micro_torch.solve_micro_torch(device={args.device!r})"
                ),
                "time_budget_s": args.time_budget_s,
                "notes": [
                    "cold solves: a new half-space and the nested-grid start in every call, "
                    "no warm start",
                    "before timing: one untimed solve of each solver on the stored 1024² "
                    "texture (numba compilation, CUDA context and cuFFT start-up excluded)",
                    "torch: the first repeat at a size includes its cuFFT plans and the "
                    "caching allocator's growth (both emptied between sizes): first_s vs "
                    "median_rest_s",
                    "torch wall time: the whole call (host kernels, transfers, gap "
                    "statistics on the host); torch.cuda.synchronize() before the clock "
                    "starts and stops",
                    "phases (each repeat): before_fine_cg_s (half-space kernels, heights to "
                    "the device, full-contact check, nested coarse solves), fine_cg_s (the "
                    "finest grid's iterations), after_fine_cg_s (result to the host, gap "
                    "statistics), from the solvers' per-iteration callback; printed as "
                    "(before + fine + after)",
                    "speedup = CPU median / torch median (all repeats)",
                    "agreement: the last repeat of each solver",
                ],
            },
            "environment": {},
            "warmup": {},
            "results": [],
            "skipped": [],
        }

    # ---- bookkeeping

    def over_budget(self) -> bool:
        return self.args.time_budget_s is not None and elapsed() > self.args.time_budget_s

    def skip(self, size: int, backend: str, repeat: int | None, reason: str) -> None:
        self.doc["skipped"].append(
            {"size": size, "backend": backend, "repeat": repeat, "reason": reason}
        )
        log(f"{size}² {backend} repeat {repeat}: skipped ({reason})")

    def write(self) -> None:
        self.doc["elapsed_s"] = elapsed()
        self.out.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=self.out.name + ".", suffix=".tmp", dir=self.out.parent)
        try:
            with os.fdopen(fd, "w") as f:
                json.dump(self.doc, f, indent=1, default=_jsonable)
                f.write("\n")
            os.replace(tmp, self.out)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise

    # ---- environment

    def environment(self) -> dict:
        import numba
        import numpy as np
        import scipy
        from skisnow.app.storage.common import git_commit
        from skisnow.solvers.elastic import pyfftw_available

        torch = self.torch
        env = {
            "date_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
            "git_commit": self.args.git_commit or git_commit(),
            "skisnow_solvers": str(Path(sys.modules["skisnow.solvers"].__file__).parent),
            "python": sys.version.split()[0],
            "platform": platform.platform(),
            "cpu_model": _cpu_model(),
            "os_cpu_count": os.cpu_count(),
            "sched_affinity_cpus": len(os.sched_getaffinity(0)),
            "cpu_solver_workers": self.workers,
            "fft_backend_cpu_solver": self.fft_backend,
            "pyfftw_available": pyfftw_available(),
            "pyfftw_version": _version("pyfftw"),
            "numpy": np.__version__,
            "scipy": scipy.__version__,
            "numba": numba.__version__,
            "numba_num_threads": numba.config.NUMBA_NUM_THREADS,
            "numba_threading_layer": _numba_layer(),
            "GOMP_SPINCOUNT": os.environ.get("GOMP_SPINCOUNT"),
            "OMP_NUM_THREADS": os.environ.get("OMP_NUM_THREADS"),
            "torch": torch.__version__,
            "torch_cuda": torch.version.cuda,
            "torch_num_threads": torch.get_num_threads(),
            "torch_device": self.args.device,
            "gpu_name": None,
            "gpu_memory_bytes": None,
        }
        if self.cuda and torch.cuda.is_available():
            props = torch.cuda.get_device_properties(0)
            env["gpu_name"] = torch.cuda.get_device_name(0)
            env["gpu_memory_bytes"] = int(props.total_memory)
            env["gpu_multiprocessors"] = int(props.multi_processor_count)
        return env

    # ---- solves

    def _sync(self) -> None:
        if self.cuda:
            self.torch.cuda.synchronize()

    def solve(self, backend: str, h, dx):
        """One cold solve; (result, wall seconds, phases).

        The phases come from the solvers' progress callback, called once per iteration of the
        finest grid after its residual is on the host (so the GPU has caught up):
        ``before_fine_cg_s`` (half-space kernels, transfer of the heights, full-contact check,
        the nested coarse solves), ``fine_cg_s`` (the finest grid's iterations) and
        ``after_fine_cg_s`` (the result moved to the host, its gap statistics).
        """
        from skisnow.solvers.micro import solve_micro
        from skisnow.solvers.micro_torch import solve_micro_torch

        a = self.args
        stamps: list[float] = []

        def callback(_it, _residual):
            stamps.append(time.perf_counter())

        common = dict(tol=a.tol, max_iterations=a.max_iterations, callback=callback)
        self._sync()
        t0 = time.perf_counter()
        if backend == "cpu":
            r = solve_micro(
                h, dx, self.p_nom, E_EFF_PA, backend="auto", workers=self.workers, **common
            )
        else:
            r = solve_micro_torch(h, dx, self.p_nom, E_EFF_PA, device=a.device, **common)
            self._sync()
        t1 = time.perf_counter()
        phases = None
        if stamps:
            phases = {
                "before_fine_cg_s": stamps[0] - t0,
                "fine_cg_s": stamps[-1] - stamps[0],
                "after_fine_cg_s": t1 - stamps[-1],
            }
        return r, t1 - t0, phases

    @staticmethod
    def record(r, wall: float, phases: dict | None) -> dict:
        return {
            "wall_s": wall,
            "phases": phases,
            "solver_solve_time_s": r.solve_time_s,
            "iterations": r.iterations,
            "level_iterations": list(r.level_iterations),
            "real_contact_area_fraction": r.real_contact_area_fraction,
            "mean_gap_m": r.mean_gap_m,
            "converged": bool(r.converged),
            "residual": r.residual,
            "message": r.message,
        }

    def free_gpu(self) -> None:
        gc.collect()
        if self.cuda:
            self.torch.cuda.synchronize()
            self.torch.backends.cuda.cufft_plan_cache.clear()
            self.torch.cuda.empty_cache()

    def warmup(self) -> None:
        from skisnow.solvers.micro_torch import check_device

        check_device(self.args.device)  # a clear error now when no GPU is visible
        surf = make_surface(BASE_SIZE)
        for backend in ("torch", "cpu"):
            r, wall, phases = self.solve(backend, surf["heights"], surf["pixel_size_m"])
            self.doc["warmup"][backend] = {"size": BASE_SIZE, **self.record(r, wall, phases)}
            log(f"warm-up {BASE_SIZE}² {backend} (untimed): {wall:.3f} s, it {r.iterations}")
            del r
        self.free_gpu()

    def run_backend(self, backend: str, size: int, surf: dict, repeats: int):
        entry = {"repeats": [], "complete": False}
        last = None
        if backend == "torch" and self.cuda:
            self.torch.cuda.reset_peak_memory_stats()
        for k in range(1, repeats + 1):
            if self.over_budget():
                for j in range(k, repeats + 1):
                    self.skip(size, backend, j, f"time budget {self.args.time_budget_s} s spent")
                break
            last = None  # free the previous result before the next solve
            gc.collect()
            r, wall, phases = self.solve(backend, surf["heights"], surf["pixel_size_m"])
            rec = self.record(r, wall, phases)
            entry["repeats"].append(rec)
            last = r
            split = (
                " ({before_fine_cg_s:.2f} + {fine_cg_s:.2f} + {after_fine_cg_s:.2f})".format(
                    **phases
                )
                if phases
                else ""
            )
            log(
                f"{size}² {backend:5s} repeat {k}/{repeats}: {wall:8.3f} s{split}, it "
                f"{r.iterations} {list(r.level_iterations)}, a_r "
                f"{r.real_contact_area_fraction:.5f}, mean gap {r.mean_gap_m:.4e} m, "
                f"converged {r.converged}"
            )
            self._summarise(entry, backend)
            self.write()
        entry["complete"] = len(entry["repeats"]) == repeats
        return entry, last

    def _summarise(self, entry: dict, backend: str) -> None:
        walls = [x["wall_s"] for x in entry["repeats"]]
        last = entry["repeats"][-1]
        entry.update(
            median_s=statistics.median(walls),
            min_s=min(walls),
            first_s=walls[0],
            median_rest_s=statistics.median(walls[1:]) if len(walls) > 1 else None,
            iterations=last["iterations"],
            level_iterations=last["level_iterations"],
            real_contact_area_fraction=last["real_contact_area_fraction"],
            mean_gap_m=last["mean_gap_m"],
            converged=all(x["converged"] for x in entry["repeats"]),
            host_peak_rss_bytes=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
        )
        phases = [x["phases"] for x in entry["repeats"] if x["phases"]]
        entry["median_phases_s"] = (
            {k: statistics.median(p[k] for p in phases) for k in phases[0]} if phases else None
        )
        if backend == "torch" and self.cuda:
            entry["gpu_peak_memory_allocated_bytes"] = int(self.torch.cuda.max_memory_allocated())
            entry["gpu_peak_memory_reserved_bytes"] = int(self.torch.cuda.max_memory_reserved())
        elif backend == "torch":
            entry["gpu_peak_memory_allocated_bytes"] = None

    def agreement(self, rc, rt) -> dict:
        np = self.np
        mc, mt = rc.pressure_pa > 0, rt.pressure_pa > 0
        differing = int(np.count_nonzero(mc != mt))
        gap_c = rc.mean_gap_m
        return {
            "contact_sets_identical": differing == 0,
            "contact_pixels_differing": differing,
            "contact_pixels_cpu": int(np.count_nonzero(mc)),
            "abs_delta_a_r": abs(rc.real_contact_area_fraction - rt.real_contact_area_fraction),
            "rel_delta_mean_gap": abs(rt.mean_gap_m - gap_c) / abs(gap_c) if gap_c else None,
            "delta_iterations_torch_minus_cpu": rt.iterations - rc.iterations,
            "max_abs_delta_pressure_over_p_nom": float(
                np.max(np.abs(rt.pressure_pa - rc.pressure_pa)) / self.p_nom
            ),
            "delta_rigid_approach_m": rt.rigid_approach_m - rc.rigid_approach_m,
        }

    def run(self) -> None:
        a = self.args
        log(f"skisnow from {Path(sys.modules['skisnow.solvers'].__file__).parent}")
        import torch

        self.torch = torch
        self.doc["environment"] = self.environment()
        self.write()
        self.warmup()
        self.doc["environment"] = self.environment()  # numba's threading layer now known
        env = self.doc["environment"]
        log(
            f"torch {env['torch']} (CUDA {env['torch_cuda']}) on {a.device} "
            f"{env['gpu_name'] or ''}; CPU solver: {self.workers} workers, FFT "
            f"{self.fft_backend}; P = {a.ratio:g} E' = {self.p_nom:g} Pa"
        )
        self.write()
        for size in a.sizes:
            run_cpu = size <= a.cpu_max_size
            cpu_repeats = 1 if size >= CPU_SINGLE_REPEAT_FROM else a.cpu_repeats
            if self.over_budget():
                for j in range(1, a.gpu_repeats + 1):
                    self.skip(size, "torch", j, "time budget spent before the size began")
                for j in range(1, cpu_repeats + 1 if run_cpu else 1):
                    self.skip(size, "cpu", j, "time budget spent before the size began")
                continue
            surf = make_surface(size)
            info = surf["info"]
            log(f"{size}² surface: {info['method']}, {info['generation_s']:.2f} s")
            res = {"size": size, "pixels": size * size, "surface": info}
            self.doc["results"].append(res)
            res["torch"], rt = self.run_backend("torch", size, surf, a.gpu_repeats)
            self.free_gpu()
            if run_cpu:
                res["cpu"], rc = self.run_backend("cpu", size, surf, cpu_repeats)
            else:
                res["cpu"], rc = None, None
                self.doc["skipped"].append(
                    {"size": size, "backend": "cpu", "repeat": None, "reason": "> cpu-max-size"}
                )
            if rc is not None and rt is not None:
                res["speedup_cpu_over_torch"] = res["cpu"]["median_s"] / res["torch"]["median_s"]
                res["agreement"] = self.agreement(rc, rt)
                ag = res["agreement"]
                log(
                    f"{size}² speed-up {res['speedup_cpu_over_torch']:.1f}x; contact pixels "
                    f"differing {ag['contact_pixels_differing']}, |Δa_r| "
                    f"{ag['abs_delta_a_r']:.2e}, rel Δ mean gap {ag['rel_delta_mean_gap']:.2e}, "
                    f"Δ iterations {ag['delta_iterations_torch_minus_cpu']}"
                )
            del surf, rt, rc
            self.free_gpu()
            self.write()
        budget = any("budget" in s["reason"] for s in self.doc["skipped"])
        self.doc["status"] = "stopped: time budget spent" if budget else "complete"
        self.write()
        log(f"wrote {self.out} ({self.doc['status']})")


# --------------------------------------------------------------------------- helpers


def _jsonable(x):
    import numpy as np

    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"not JSON serialisable: {type(x).__name__}")


def _version(name: str) -> str | None:
    from importlib import metadata

    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def _numba_layer() -> str | None:
    import numba

    try:
        return numba.threading_layer()
    except ValueError:  # no parallel region has run yet
        return None


def _cpu_model() -> str | None:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return None


# --------------------------------------------------------------------------- chart


def chart(doc: dict, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    env, st = doc.get("environment", {}), doc["settings"]
    rows = doc["results"]
    fig, ax = plt.subplots(figsize=(7.5, 5.2), dpi=120)
    labels = {
        "cpu": f"CPU solver ({env.get('fft_backend_cpu_solver')}, "
        f"{env.get('cpu_solver_workers')} threads)",
        "torch": f"torch on {st['torch_device']}"
        + (f" ({env['gpu_name']})" if env.get("gpu_name") else ""),
    }
    for backend, style, color in (("cpu", "o-", "C0"), ("torch", "s-", "C1")):
        pts = [
            (r["size"], r[backend]["median_s"])
            for r in rows
            if r.get(backend) and r[backend].get("median_s") is not None
        ]
        if pts:
            xs, ys = zip(*pts, strict=True)
            ax.plot(xs, ys, style, color=color, label=labels[backend] + ", median")
        every = [
            (r["size"], x["wall_s"]) for r in rows if r.get(backend) for x in r[backend]["repeats"]
        ]
        if every:
            xs, ys = zip(*every, strict=True)
            ax.plot(xs, ys, ".", color=color, alpha=0.4, markersize=4)
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    for r in rows:
        if r.get("speedup_cpu_over_torch"):
            y = (r["cpu"]["median_s"] * r["torch"]["median_s"]) ** 0.5
            ax.annotate(
                f"{r['speedup_cpu_over_torch']:.3g}×",
                (r["size"], y),
                ha="left",
                va="center",
                xytext=(5, 0),
                textcoords="offset points",
                fontsize=9,
            )
            ax.plot(
                [r["size"]] * 2,
                [r["cpu"]["median_s"], r["torch"]["median_s"]],
                ":",
                color="0.5",
                lw=0.8,
            )
    sizes = [r["size"] for r in rows]
    if sizes:
        ax.set_xticks(sizes)
        ax.set_xticklabels([f"{n}²" for n in sizes])
        ax.xaxis.set_minor_locator(matplotlib.ticker.NullLocator())
        ax.set_xlim(min(sizes) / 1.3, max(sizes) * 1.5)
    ax.set_xlabel("grid (pixels); annotated: speed-up, CPU median / torch median")
    ax.set_ylabel("median wall time of one cold solve [s]")
    crop = any(r["surface"]["method"].startswith("crop") for r in rows)
    ax.set_title(
        f"micro solver, {st['texture']}{' (crops: test only)' if crop else ''}, "
        f"P/E' = {st['ratio_p_over_e']:g}, tol {st['tol']:g}\n"
        f"{env.get('cpu_model') or ''} ({env.get('os_cpu_count')} CPUs), "
        f"{env.get('date_utc', '')[:10]}",
        fontsize=9,
    )
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=9)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


# --------------------------------------------------------------------------- command line


def _size(text: str) -> int:
    n = int(text)
    if n < BASE_SIZE:
        if n < 128 or n % 2:
            raise argparse.ArgumentTypeError(f"{n}: a crop size must be even and >= 128")
        return n
    refine = n // BASE_SIZE
    if n % BASE_SIZE or refine & (refine - 1):
        raise argparse.ArgumentTypeError(f"{n}: sizes >= {BASE_SIZE} are {BASE_SIZE}·2^k")
    return n


def parse(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=_size, nargs="+", default=[1024, 2048, 4096, 8192, 16384])
    ap.add_argument("--cpu-max-size", type=int, default=8192, help="CPU solver up to this size")
    ap.add_argument("--gpu-repeats", type=int, default=3)
    ap.add_argument(
        "--cpu-repeats", type=int, default=2, help=f"(1 at >= {CPU_SINGLE_REPEAT_FROM})"
    )
    ap.add_argument("--device", choices=("cuda", "cpu"), default="cuda", help="torch's device")
    ap.add_argument("--ratio", type=float, default=1e-3, help="P/E' (E' = 100 MPa)")
    ap.add_argument("--tol", type=float, default=1e-6)
    ap.add_argument("--max-iterations", type=int, default=2000)
    ap.add_argument("--cpu-workers", type=int, default=None, help="default: usable cores")
    ap.add_argument(
        "--time-budget-s",
        type=float,
        default=None,
        help="no new solve starts after this many seconds from the start",
    )
    ap.add_argument("--out", default="gpu_micro_bench.json")
    ap.add_argument("--chart", default=None, help="PNG: median time against grid size")
    ap.add_argument("--git-commit", default=None, help="record this commit (no .git there)")
    ap.add_argument("--replot", default=None, help="only draw --chart from this JSON")
    ap.add_argument(
        "--import-stage",
        default=None,
        metavar="JSON",
        help="only import this run's JSON (and the PNG beside it) into docs/bench as the "
        "stage gpu-micro and regenerate docs/benchmarks.md",
    )
    ap.add_argument(
        "--session-command",
        default="OUT=… GIT_COMMIT=… bash scripts/gpu_session.sh",
        help="with --import-stage: the command recorded for the stage",
    )
    args = ap.parse_args(argv)
    if args.replot and not args.chart:
        ap.error("--replot needs --chart")
    if min(args.gpu_repeats, args.cpu_repeats) < 1:
        ap.error("repeats must be >= 1")
    args.sizes = sorted(set(args.sizes))
    return args


def import_stage(path: Path, command_line: str, docs_dir: Path | None = None) -> Path:
    """Write ``docs/bench/gpu-micro.json`` (and ``.png`` from the PNG beside ``path``, if any)
    from one run's JSON and regenerate docs/benchmarks.md."""
    import shutil

    _import_skisnow()
    from skisnow.app.evidence.gpu_md import stage_from_bench
    from skisnow.app.evidence.writer import DOCS, write_benchmarks_md
    from skisnow.app.storage.common import atomic_path

    docs_dir = DOCS if docs_dir is None else Path(docs_dir)
    stage = stage_from_bench(json.loads(Path(path).read_text()), command_line)
    out = docs_dir / "bench" / "gpu-micro.json"
    with atomic_path(out) as tmp:
        tmp.write_text(json.dumps(stage, indent=1))
    png = Path(path).with_suffix(".png")
    if png.exists():
        shutil.copyfile(png, out.with_suffix(".png"))
    write_benchmarks_md(docs_dir)
    return out


def main(argv=None) -> None:
    args = parse(argv)
    if args.import_stage:
        print(f"wrote {import_stage(Path(args.import_stage), args.session_command)}")
        return
    if args.replot:
        chart(json.loads(Path(args.replot).read_text()), args.chart)
        print(f"wrote {args.chart}")
        return
    _import_skisnow()
    import skisnow.app.storage.textures  # noqa: F401  (skisnow.app first: GOMP_SPINCOUNT)

    bench = Bench(args)
    try:
        bench.run()
    except BaseException as exc:
        bench.doc["status"] = f"failed: {type(exc).__name__}: {exc}"
        bench.write()
        raise
    finally:
        if args.chart and bench.doc["results"]:
            try:
                chart(bench.doc, args.chart)
                log(f"wrote {args.chart}")
            except Exception as exc:  # the JSON is what counts; --replot redraws
                log(f"chart failed: {type(exc).__name__}: {exc}")


if __name__ == "__main__":
    main()
