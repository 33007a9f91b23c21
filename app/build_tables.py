"""``skisnow build-tables``: the micro-scale lookup tables, built on a Dask cluster.

For each texture the job computes (method.md §5):

1. the full-contact ratio ``p_fc / E'`` (one FFT), the unloaded statistics and the
   separated-regime curve ``⟨1/(h_0 + H)⟩`` (no solve);
2. the table over a log grid of ``P_n / E'``, split into chunks of ``--chunk-size``
   consecutive points. The chunk boundaries depend only on the grid and the chunk size, never
   on the number of workers; inside a chunk the points are solved in rising order, each
   warm-started from the previous one (:func:`solvers.lookup.solve_table_chunk`), so every
   chunk is a deterministic computation and the table does not depend on the scheduling.

Chunks of all textures are submitted together to a Dask ``LocalCluster`` (processes, one
thread each) or to an existing scheduler (``--scheduler``). Every finished chunk is written
atomically to ``OUT/.checkpoints/<texture>/<key>/chunk-NNN.h5``, where ``key`` hashes the
texture heights, pixel size, pressure grid, chunk size, solver settings, code version and the
solver source code: a killed job rerun skips the finished chunks and gives the same table, and
a stale checkpoint is never reused. The table file appears (atomic rename) only once complete;
then ``OUT/manifest.json`` is rewritten and the texture's checkpoints are removed.

The texture is solved as periodic, as given. ``--detrend`` says what is removed from a height
map file's heights first (:func:`solvers.texture.level_heights`: plane, mean or none; default
plane for a raw or measured map, a stored texture as it is, synthetic ones with their mean
removed). The choice is the table's ``/texture`` attribute ``detrend`` and its root attribute
``texture_detrend``.
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import inspect
import logging
import re
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from solvers import elastic as _elastic
from solvers import lookup as _lookup
from solvers import micro as _micro
from solvers.elastic import PeriodicHalfSpace
from solvers.errors import InputError
from solvers.lookup import (
    MicroTable,
    chunk_bounds,
    pressure_ratio_grid,
    separated_curve,
    solve_table_chunk,
    unloaded_statistics,
)
from solvers.micro import DEFAULT_GAP_FLOOR_M, full_contact_pressure
from solvers.texture import DETREND_METHODS, Texture, iso25178_parameters

from .storage.common import code_version
from .storage.tables import read_checkpoint, write_checkpoint, write_manifest, write_table

__all__ = ["BuildSettings", "build_tables", "checkpoint_key", "register"]

log = logging.getLogger(__name__)

_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")


@dataclass(frozen=True)
class BuildSettings:
    """Settings of a table build (every one recorded in the file).

    Attributes
    ----------
    points : int
        Points of the pressure-ratio grid [-].
    ratio_min, ratio_max : float
        Ends of the log grid of ``P_n / E'`` [-].
    chunk_size : int
        Consecutive grid points per task [-].
    tol : float
        Solver tolerance [-].
    max_iterations : int
        Solver iteration cap [-].
    gap_floor_m : float
        Gap floor h_c of the floored mean reciprocal gap [m].
    effective_modulus_pa : float
        E' of the solves [Pa] (results depend only on ``P_n / E'``).
    clearance_min_m, clearance_max_m : float
        Ends of the log grid of clearances of the separated curve [m].
    clearance_points : int
        Points of the clearance grid [-].
    """

    points: int = 48
    ratio_min: float = 1e-8
    ratio_max: float = 1e-1
    chunk_size: int = 4
    tol: float = 1e-6
    max_iterations: int = 2000
    gap_floor_m: float = DEFAULT_GAP_FLOOR_M
    effective_modulus_pa: float = 1e8
    clearance_min_m: float = 1e-8
    clearance_max_m: float = 1e-2
    clearance_points: int = 64

    def __post_init__(self) -> None:
        pressure_ratio_grid(self.ratio_min, self.ratio_max, self.points)
        pressure_ratio_grid(self.clearance_min_m, self.clearance_max_m, self.clearance_points)
        chunk_bounds(self.points, self.chunk_size)
        for name in ("tol", "gap_floor_m", "effective_modulus_pa"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise InputError(f"{name} must be finite and > 0, got {value!r}")
        if int(self.max_iterations) != self.max_iterations or self.max_iterations < 1:
            raise InputError(f"max_iterations must be an integer >= 1, got {self.max_iterations}")

    @property
    def pressure_ratio(self) -> np.ndarray:
        """The grid of ``P_n / E'`` [-]."""
        return pressure_ratio_grid(self.ratio_min, self.ratio_max, self.points)

    @property
    def clearance_m(self) -> np.ndarray:
        """The clearance grid of the separated curve [m]."""
        return pressure_ratio_grid(
            self.clearance_min_m, self.clearance_max_m, self.clearance_points
        )


def _solver_source_sha256() -> str:
    h = hashlib.sha256()
    for module in (_micro, _elastic):
        h.update(inspect.getsource(module).encode())
    h.update(inspect.getsource(_lookup.solve_table_chunk).encode())
    return h.hexdigest()


def checkpoint_key(texture: Texture, settings: BuildSettings) -> str:
    """Hash of everything a chunk result depends on (stale checkpoints never match)."""
    heights = np.ascontiguousarray(texture.heights_m, dtype=np.float64)
    h = hashlib.sha256()
    h.update(f"{heights.shape}".encode())
    h.update(heights.tobytes())
    h.update(f"{float(texture.pixel_size_m)!r}".encode())
    h.update(settings.pressure_ratio.tobytes())
    for key, value in sorted(asdict(settings).items()):
        h.update(f"{key}={value!r};".encode())
    h.update(code_version().encode())
    h.update(_solver_source_sha256().encode())
    return h.hexdigest()


@dataclass
class _Job:
    texture: Texture
    key: str
    directory: Path
    full_contact_pressure_ratio: float
    bounds: list[tuple[int, int]]
    results: dict[int, dict[str, np.ndarray]]

    def chunk_path(self, index: int) -> Path:
        return self.directory / f"chunk-{index:03d}.h5"


def _prepare(texture: Texture, settings: BuildSettings, out_dir: Path) -> _Job:
    if not _NAME_RE.match(texture.name or ""):
        raise InputError(f"texture name {texture.name!r} cannot be a file name")
    heights = np.asarray(texture.heights_m, dtype=float)
    if heights.ndim != 2 or not np.all(np.isfinite(heights)) or np.ptp(heights) == 0:
        raise InputError(f"texture {texture.name!r}: heights must be 2-D, finite and not flat")
    e_eff = settings.effective_modulus_pa
    hs = PeriodicHalfSpace(heights.shape, texture.pixel_size_m, e_eff, workers=1)
    p_fc, _ = full_contact_pressure(heights, texture.pixel_size_m, e_eff, halfspace=hs)
    key = checkpoint_key(texture, settings)
    job = _Job(
        texture=texture,
        key=key,
        directory=out_dir / ".checkpoints" / texture.name / key[:16],
        full_contact_pressure_ratio=p_fc / e_eff,
        bounds=chunk_bounds(settings.points, settings.chunk_size),
        results={},
    )
    for index in range(len(job.bounds)):
        done = read_checkpoint(job.chunk_path(index), key)
        if done is not None:
            job.results[index] = done
    return job


def _assemble(job: _Job, settings: BuildSettings) -> tuple[MicroTable, dict]:
    parts = [job.results[i] for i in range(len(job.bounds))]
    arrays = {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}
    diagnostics = {"solve_time_s": arrays.pop("solve_time_s")}
    heights = np.asarray(job.texture.heights_m, dtype=float)
    mean_h0, mean_rec0 = unloaded_statistics(heights, settings.gap_floor_m)
    clearance = settings.clearance_m
    try:
        iso = iso25178_parameters(heights, job.texture.pixel_size_m, periodic=True)
    except InputError as exc:  # pragma: no cover - flat textures are rejected earlier
        log.warning("no ISO parameters for %s: %s", job.texture.name, exc)
        iso = {}
    table = MicroTable(
        name=job.texture.name,
        pixel_size_m=float(job.texture.pixel_size_m),
        grid_shape=tuple(int(v) for v in heights.shape),
        effective_modulus_pa=float(settings.effective_modulus_pa),
        gap_floor_m=float(settings.gap_floor_m),
        tol=float(settings.tol),
        pressure_ratio=settings.pressure_ratio,
        full_contact_pressure_ratio=float(job.full_contact_pressure_ratio),
        unloaded_mean_gap_m=mean_h0,
        unloaded_mean_reciprocal_gap_per_m=mean_rec0,
        clearance_m=clearance,
        separated_mean_reciprocal_gap_per_m=separated_curve(heights, clearance),
        iso_parameters=iso,
        attrs={
            "max_iterations": int(settings.max_iterations),
            "chunk_size": int(settings.chunk_size),
            "checkpoint_key": job.key,
            "solver_source_sha256": _solver_source_sha256(),
            "points_not_converged": int(np.count_nonzero(~arrays["converged"])),
            "texture_detrend": job.texture.detrend,
        },
        **arrays,
    )
    return table, diagnostics


def _open_client(scheduler: str | None, workers: int, processes: bool):
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError as exc:  # pragma: no cover - a core dependency
        raise ImportError(
            "build-tables needs dask[distributed]: pip install 'dask[distributed]'"
        ) from exc
    if scheduler:
        return Client(scheduler), None
    if int(workers) != workers or workers < 1:
        raise InputError(f"workers must be an integer >= 1, got {workers!r}")
    cluster = LocalCluster(
        n_workers=int(workers),
        threads_per_worker=1,
        processes=processes,
        dashboard_address=":0",
        silence_logs=logging.WARNING,
    )
    return Client(cluster), cluster


def build_tables(
    textures: Sequence[Texture],
    out_dir: str | Path,
    settings: BuildSettings | None = None,
    *,
    scheduler: str | None = None,
    workers: int = 2,
    processes: bool = True,
    client=None,
    progress: bool = True,
    keep_checkpoints: bool = False,
    on_chunk_done: Callable[[str, int], None] | None = None,
) -> dict[str, Path]:
    """Build one table file ``OUT/<texture name>.h5`` per texture, and ``OUT/manifest.json``.

    Parameters
    ----------
    textures : sequence of Texture
        Textures to tabulate (distinct names).
    out_dir : path-like
        Output directory (created).
    settings : BuildSettings, optional
        Grid and solver settings (defaults of :class:`BuildSettings`).
    scheduler : str, optional
        Address of an existing Dask scheduler; default a new ``LocalCluster``.
    workers : int
        Worker processes of the ``LocalCluster`` (one thread each).
    processes : bool
        ``LocalCluster`` with processes (default) or threads.
    client : dask.distributed.Client, optional
        Use this client (the caller owns it); overrides ``scheduler`` and ``workers``.
    progress : bool
        Show a tqdm progress bar over the chunks (stderr).
    keep_checkpoints : bool
        Keep the chunk checkpoints after a table is written.
    on_chunk_done : callable(texture_name, chunk_index), optional
        Called after each computed chunk is checkpointed (tests use it to interrupt a build).

    Returns
    -------
    dict
        Texture name → path of its table file.
    """
    settings = settings or BuildSettings()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    names = [t.name for t in textures]
    if not names:
        raise InputError("no textures given")
    if len(set(names)) != len(names):
        raise InputError(f"texture names must be distinct, got {names}")
    t0 = time.perf_counter()
    jobs = {t.name: _prepare(t, settings, out_dir) for t in textures}
    pending = [
        (name, index)
        for name, job in jobs.items()
        for index in range(len(job.bounds))
        if index not in job.results
    ]
    resumed = sum(len(job.results) for job in jobs.values())
    if resumed:
        log.info("resuming: %d chunk(s) already done, %d to compute", resumed, len(pending))
    computed = 0
    if pending:
        own_client = client is None
        cluster = None
        if own_client:
            client, cluster = _open_client(scheduler, workers, processes)
        try:
            computed = _run(client, jobs, pending, settings, progress, on_chunk_done)
        finally:
            if own_client:
                client.close()
                if cluster is not None:
                    cluster.close()
    paths = {}
    ratio_grid = settings.pressure_ratio
    for name, job in jobs.items():
        table, diagnostics = _assemble(job, settings)
        table.attrs["build_time_s"] = round(time.perf_counter() - t0, 3)
        table.attrs["chunks_resumed"] = len(job.bounds) - sum(1 for n, _ in pending if n == name)
        paths[name] = write_table(
            out_dir / f"{name}.h5",
            table,
            heights_m=job.texture.heights_m,
            texture_attrs={
                "source": job.texture.source,
                "missing_fraction": float(job.texture.missing_fraction),
                "detrend": job.texture.detrend,
            },
            diagnostics=diagnostics,
            parameters={**asdict(settings), "texture": name, "grid_points": ratio_grid.size},
        )
        if not keep_checkpoints:
            shutil.rmtree(job.directory, ignore_errors=True)
            for parent in (job.directory.parent, job.directory.parent.parent):
                with contextlib.suppress(OSError):
                    parent.rmdir()  # only if empty
        bad = int(np.count_nonzero(~table.converged))
        if bad:
            log.warning("%s: %d point(s) did not converge (see /loaded/converged)", name, bad)
    write_manifest(out_dir)
    log.info(
        "built %d table(s), %d chunk(s) computed, in %.1f s",
        len(paths),
        computed,
        time.perf_counter() - t0,
    )
    return paths


def _run(client, jobs, pending, settings, progress, on_chunk_done) -> int:
    from dask.distributed import as_completed
    from tqdm import tqdm

    ratio_grid = settings.pressure_ratio
    heights_future = {
        name: client.scatter(
            np.asarray(jobs[name].texture.heights_m, dtype=float), broadcast=True, hash=False
        )
        for name in {n for n, _ in pending}
    }
    futures = {}
    # costly high-ratio chunks first, so the last chunks to finish are the short ones
    for name, index in sorted(pending, key=lambda item: -item[1]):
        job = jobs[name]
        start, stop = job.bounds[index]
        future = client.submit(
            solve_table_chunk,
            heights_future[name],
            float(job.texture.pixel_size_m),
            ratio_grid[start:stop],
            effective_modulus_pa=settings.effective_modulus_pa,
            full_contact_pressure_ratio=job.full_contact_pressure_ratio,
            tol=settings.tol,
            max_iterations=settings.max_iterations,
            gap_floor_m=settings.gap_floor_m,
            pure=False,
            key=f"table-chunk-{name}-{index:03d}-{job.key[:12]}",
        )
        futures[future] = (name, index)
    computed = 0
    try:
        with tqdm(
            total=len(futures), desc="table chunks", unit="chunk", disable=not progress
        ) as bar:
            for future in as_completed(futures):
                name, index = futures[future]
                result = future.result()
                job = jobs[name]
                write_checkpoint(job.chunk_path(index), result, job.key)
                job.results[index] = result
                computed += 1
                bar.update(1)
                if on_chunk_done is not None:
                    on_chunk_done(name, index)
    finally:
        client.cancel([f for f in futures if not f.done()])
    return computed


# ---------------------------------------------------------------------------- CLI


def _load_textures(specs: Sequence[str], detrend: str | None = None) -> list[Texture]:
    try:
        from app.storage.textures import load_texture
    except ModuleNotFoundError as exc:
        if exc.name != "app.storage.textures":
            raise
        raise InputError("texture loading is not available (app.storage.textures missing)") from exc
    return [load_texture(spec, detrend=detrend) for spec in specs]


def _command(args: argparse.Namespace) -> int:
    settings = BuildSettings(
        points=args.points,
        ratio_min=args.ratio_min,
        ratio_max=args.ratio_max,
        chunk_size=args.chunk_size,
        tol=args.tol,
        max_iterations=args.max_iterations,
        gap_floor_m=args.gap_floor_nm * 1e-9,
    )
    textures = _load_textures(args.textures, args.detrend)
    t0 = time.perf_counter()
    paths = build_tables(
        textures,
        args.out,
        settings,
        scheduler=args.scheduler,
        workers=args.workers,
        keep_checkpoints=args.keep_checkpoints,
    )
    for name, path in paths.items():
        print(f"{name}: {path}")
    print(f"manifest: {Path(args.out) / 'manifest.json'} ({time.perf_counter() - t0:.1f} s)")
    return 0


def register(subparsers) -> None:
    """Add the ``build-tables`` subcommand."""
    d = BuildSettings()
    p = subparsers.add_parser(
        "build-tables",
        help="build micro-scale lookup tables (Dask)",
        description="Tabulate texture contact over P_n/E' on a Dask cluster; resumable.",
    )
    p.add_argument("textures", nargs="+", metavar="TEXTURE", help="shipped name or file path")
    p.add_argument("--out", required=True, type=Path, help="output directory")
    p.add_argument("--points", type=int, default=d.points, help=f"ratio grid points ({d.points})")
    p.add_argument("--ratio-min", type=float, default=d.ratio_min, help="lowest P_n/E' [-]")
    p.add_argument("--ratio-max", type=float, default=d.ratio_max, help="highest P_n/E' [-]")
    p.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    p.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes (2)")
    p.add_argument("--chunk-size", type=int, default=d.chunk_size, help="points per task")
    p.add_argument("--tol", type=float, default=d.tol, help="solver tolerance [-]")
    p.add_argument("--max-iterations", type=int, default=d.max_iterations)
    p.add_argument(
        "--gap-floor-nm", type=float, default=d.gap_floor_m * 1e9, help="gap floor h_c [nm]"
    )
    p.add_argument("--keep-checkpoints", action="store_true", help="keep chunk checkpoints")
    p.add_argument(
        "--detrend",
        choices=DETREND_METHODS,
        default=None,
        help=(
            "what is removed from a height map file's heights: plane, mean (for a periodic "
            "map) or none; default plane for raw/measured maps, a stored texture (.h5, "
            "shipped grind) as it is (synthetic: mean); recorded in the table"
        ),
    )
    p.set_defaults(func=_command)
