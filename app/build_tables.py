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

**Pixel levels** (``--pixel-levels``, docs/tables.md "Pixel size"): ``none`` solves the texture
on its own grid only. ``refine`` also solves the same synthetic surface on a 2× finer grid
(:func:`app.storage.textures.refined_texture`), ``refine3`` on a 2× and a 4× finer grid,
``coarsen`` also solves the texture block-averaged onto a 2× coarser grid (any texture). Each
level is its own set of chunks and checkpoints; the table holds the zero-pixel extrapolation of
the two finest levels (:func:`solvers.lookup.combine_pixel_levels`), a per-point error estimate
of each quantity (three levels: from the successive extrapolants where the observed order is
stable, :func:`solvers.lookup.combine_three_pixel_levels`) and the per-level values under
``/levels``.

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
import json
import logging
import re
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from skisnow.solvers import elastic as _elastic
from skisnow.solvers import lookup as _lookup
from skisnow.solvers import micro as _micro
from skisnow.solvers.elastic import PeriodicHalfSpace
from skisnow.solvers.errors import InputError
from skisnow.solvers.lookup import (
    ERROR_FIELDS,
    ORDER_TOLERANCE,
    PIXEL_EXTRAPOLATION_ORDERS,
    MicroTable,
    chunk_bounds,
    combine_pixel_levels,
    combine_three_pixel_levels,
    pressure_ratio_grid,
    separated_curve,
    solve_table_chunk,
    unloaded_statistics,
)
from skisnow.solvers.micro import DEFAULT_GAP_FLOOR_M, full_contact_pressure
from skisnow.solvers.texture import DETREND_METHODS, Texture, iso25178_parameters

from .storage.common import code_version
from .storage.tables import read_checkpoint, write_checkpoint, write_manifest, write_table

__all__ = ["BuildSettings", "build_tables", "checkpoint_key", "register"]

log = logging.getLogger(__name__)

_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")

#: ``--pixel-levels`` choices
PIXEL_LEVEL_MODES = ("none", "refine", "refine3", "coarsen")
#: pixel-size ratio between successive levels of a table [-]
LEVEL_REFINEMENT = 2


def refinements(pixel_levels: str) -> list[int]:
    """Refinement factors of the finer levels of ``--pixel-levels`` (``refine3``: [2, 4])."""
    return {"refine": [LEVEL_REFINEMENT], "refine3": [LEVEL_REFINEMENT, LEVEL_REFINEMENT**2]}.get(
        pixel_levels, []
    )


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
    pixel_levels : str
        ``"none"`` (the texture's grid only), ``"refine"`` (plus the same synthetic surface
        at half the pixel size), ``"refine3"`` (plus the surface at a half and a quarter of
        the pixel size) or ``"coarsen"`` (plus the texture at twice the pixel size); the
        levels are extrapolated to zero pixel size with a per-point error estimate.
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
    pixel_levels: str = "none"

    def __post_init__(self) -> None:
        if self.pixel_levels not in PIXEL_LEVEL_MODES:
            raise InputError(
                f"pixel_levels must be one of {PIXEL_LEVEL_MODES}, got {self.pixel_levels!r}"
            )
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
    texture: Texture  # the level's heights and pixel size
    key: str
    directory: Path
    full_contact_pressure_ratio: float
    bounds: list[tuple[int, int]]
    results: dict[int, dict[str, np.ndarray]]

    def chunk_path(self, index: int) -> Path:
        return self.directory / f"chunk-{index:03d}.h5"


def _coarsened(texture: Texture) -> Texture:
    h = np.asarray(texture.heights_m, dtype=float)
    k = LEVEL_REFINEMENT
    if h.shape[0] % k or h.shape[1] % k:
        raise InputError(
            f"texture {texture.name!r}: --pixel-levels coarsen needs grid sizes divisible by "
            f"{k}, got {h.shape}"
        )
    coarse = h.reshape(h.shape[0] // k, k, h.shape[1] // k, k).mean(axis=(1, 3))
    return Texture(
        coarse,
        texture.pixel_size_m * k,
        texture.name,
        texture.missing_fraction,
        f"{texture.source}; block-averaged {k}x{k}",
        detrend=texture.detrend,
    )


def _levels(
    texture: Texture, settings: BuildSettings, refined: dict[str, Texture] | None
) -> list[Texture]:
    """The level textures of one table, coarse first (the texture itself is one of them)."""
    if settings.pixel_levels == "none":
        return [texture]
    if settings.pixel_levels == "coarsen":
        return [_coarsened(texture), texture]
    fine = (refined or {}).get(texture.name)
    finer = [fine] if isinstance(fine, Texture) else list(fine or [])
    factors = refinements(settings.pixel_levels)
    if len(finer) != len(factors):
        raise InputError(
            f"texture {texture.name!r}: --pixel-levels {settings.pixel_levels} needs its "
            f"surface refined {factors}x (app.storage.textures.refined_texture), got "
            f"{len(finer)} refined texture(s)"
        )
    shape = tuple(np.shape(texture.heights_m))
    for k, level in zip(factors, finer, strict=True):
        if np.shape(level.heights_m) != (shape[0] * k, shape[1] * k) or not np.isclose(
            level.pixel_size_m * k, texture.pixel_size_m, rtol=1e-12
        ):
            raise InputError(f"refined texture of {texture.name!r} is not {k}x finer")
    return [texture, *finer]


def _level_name(name: str, index: int, count: int) -> str:
    return name if count == 1 else f"{name}.level{index}"


def _prepare(texture: Texture, settings: BuildSettings, out_dir: Path, job_name: str) -> _Job:
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
        directory=out_dir / ".checkpoints" / job_name / key[:16],
        full_contact_pressure_ratio=p_fc / e_eff,
        bounds=chunk_bounds(settings.points, settings.chunk_size),
        results={},
    )
    for index in range(len(job.bounds)):
        done = read_checkpoint(job.chunk_path(index), key)
        if done is not None:
            job.results[index] = done
    return job


def _assemble(
    texture: Texture, level_jobs: list[_Job], settings: BuildSettings
) -> tuple[MicroTable, dict]:
    level_arrays = []
    for job in level_jobs:
        parts = [job.results[i] for i in range(len(job.bounds))]
        level_arrays.append({name: np.concatenate([p[name] for p in parts]) for name in parts[0]})
    diagnostics = {"solve_time_s": np.sum([a.pop("solve_time_s") for a in level_arrays], axis=0)}
    extra: dict = {}
    order_info: dict = {}
    if len(level_arrays) == 1:
        arrays = level_arrays[0]
    else:
        if len(level_arrays) == 2:
            arrays = combine_pixel_levels(*level_arrays, refinement=LEVEL_REFINEMENT)
        else:
            arrays, order_info = combine_three_pixel_levels(
                *level_arrays, refinement=LEVEL_REFINEMENT
            )
        for name in ERROR_FIELDS.values():
            extra[name] = arrays.pop(name)
        extra["levels"] = {
            **order_info,
            "pixel_size_m": np.array([float(j.texture.pixel_size_m) for j in level_jobs]),
            "full_contact_pressure_ratio": np.array(
                [j.full_contact_pressure_ratio for j in level_jobs]
            ),
            **{
                name: np.stack([a[name] for a in level_arrays])
                for name in level_arrays[0]
                if name != "residual"
            },
        }
    finest = level_jobs[-1]
    heights = np.asarray(texture.heights_m, dtype=float)
    mean_h0, mean_rec0 = unloaded_statistics(heights, settings.gap_floor_m)
    clearance = settings.clearance_m
    try:
        iso = iso25178_parameters(heights, texture.pixel_size_m, periodic=True)
    except InputError as exc:  # pragma: no cover - flat textures are rejected earlier
        log.warning("no ISO parameters for %s: %s", texture.name, exc)
        iso = {}
    attrs = {
        "max_iterations": int(settings.max_iterations),
        "chunk_size": int(settings.chunk_size),
        "checkpoint_key": ",".join(j.key for j in level_jobs),
        "solver_source_sha256": _solver_source_sha256(),
        "points_not_converged": int(np.count_nonzero(~arrays["converged"])),
        "texture_detrend": texture.detrend,
        "pixel_levels": settings.pixel_levels,
    }
    if len(level_jobs) == 2:
        method = (
            "Richardson extrapolation to zero pixel size from two levels "
            "(solvers.lookup.combine_pixel_levels); error estimate = |correction| "
            "(order None: finest level kept, estimate = last change)"
        )
    else:
        method = (
            "Richardson extrapolation to zero pixel size from the two finest of three levels "
            "(solvers.lookup.combine_three_pixel_levels); error estimate = |difference of the "
            "successive extrapolants| where the observed order is within order_tolerance of "
            "the assumed one (/levels/three_level_estimate_* = 1), else the larger of that and "
            "the two-level |correction| (= 0); order None: finest level kept, estimate = last "
            "change"
        )
    if len(level_jobs) > 1:
        attrs["pixel_extrapolation_json"] = json.dumps(
            {
                "method": method,
                "levels": len(level_jobs),
                "order_tolerance": ORDER_TOLERANCE if len(level_jobs) > 2 else None,
                "level_pixel_size_m": [float(j.texture.pixel_size_m) for j in level_jobs],
                "level_grid_shape": [list(np.shape(j.texture.heights_m)) for j in level_jobs],
                "level_source": [j.texture.source for j in level_jobs],
                "refinement": LEVEL_REFINEMENT,
                "orders": PIXEL_EXTRAPOLATION_ORDERS,
                "flags_from": "finest level (full_contact, iterations); converged = all levels",
            },
            sort_keys=True,
        )
    table = MicroTable(
        name=texture.name,
        pixel_size_m=float(texture.pixel_size_m),
        grid_shape=tuple(int(v) for v in heights.shape),
        effective_modulus_pa=float(settings.effective_modulus_pa),
        gap_floor_m=float(settings.gap_floor_m),
        tol=float(settings.tol),
        pressure_ratio=settings.pressure_ratio,
        full_contact_pressure_ratio=float(finest.full_contact_pressure_ratio),
        unloaded_mean_gap_m=mean_h0,
        unloaded_mean_reciprocal_gap_per_m=mean_rec0,
        clearance_m=clearance,
        separated_mean_reciprocal_gap_per_m=separated_curve(heights, clearance),
        iso_parameters=iso,
        attrs=attrs,
        **arrays,
        **extra,
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
    refined: dict[str, Texture] | None = None,
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
    on_chunk_done : callable(level_name, chunk_index), optional
        Called after each computed chunk is checkpointed (tests use it to interrupt a build);
        the level name is the texture name, or ``<name>.level<i>`` (i = 0 coarse) for
        several pixel levels.
    refined : dict of str to Texture or list of Texture, optional
        For ``settings.pixel_levels`` ``"refine"``: each texture's surface on the 2× finer
        grid (:func:`app.storage.textures.refined_texture`); ``"refine3"``: the list of its
        surfaces on the 2× and 4× finer grids.

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
    levels_of: dict[str, list[str]] = {}
    jobs: dict[str, _Job] = {}
    for texture in textures:
        levels = _levels(texture, settings, refined)
        names_ = [_level_name(texture.name, i, len(levels)) for i in range(len(levels))]
        levels_of[texture.name] = names_
        for level, job_name in zip(levels, names_, strict=True):
            jobs[job_name] = _prepare(level, settings, out_dir, job_name)
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
    for texture in textures:
        name = texture.name
        level_jobs = [jobs[n] for n in levels_of[name]]
        table, diagnostics = _assemble(texture, level_jobs, settings)
        table.attrs["build_time_s"] = round(time.perf_counter() - t0, 3)
        table.attrs["chunks_resumed"] = sum(len(j.bounds) for j in level_jobs) - sum(
            1 for n, _ in pending if n in levels_of[name]
        )
        paths[name] = write_table(
            out_dir / f"{name}.h5",
            table,
            heights_m=texture.heights_m,
            texture_attrs={
                "source": texture.source,
                "missing_fraction": float(texture.missing_fraction),
                "detrend": texture.detrend,
            },
            diagnostics=diagnostics,
            parameters={**asdict(settings), "texture": name, "grid_points": ratio_grid.size},
        )
        if not keep_checkpoints:
            for job in level_jobs:
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

    # costly chunks first (finer grids, high ratios), so the last to finish are the short ones
    def cost(item):
        name, index = item
        return -np.size(jobs[name].texture.heights_m), -index

    for name, index in sorted(pending, key=cost):
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
        from skisnow.app.storage.topography import load_texture
    except ModuleNotFoundError as exc:
        if exc.name != "skisnow.app.storage.textures":
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
        pixel_levels=args.pixel_levels,
    )
    textures = _load_textures(args.textures, args.detrend)
    refined = None
    factors = refinements(args.pixel_levels)
    if factors:
        from skisnow.app.storage.textures import refined_texture

        if args.detrend is not None:
            raise InputError(
                f"--pixel-levels {args.pixel_levels} takes the stored synthetic texture as is"
            )
        refined = {
            t.name: [refined_texture(spec, k) for k in factors]
            for t, spec in zip(textures, args.textures, strict=True)
        }
    t0 = time.perf_counter()
    paths = build_tables(
        textures,
        args.out,
        settings,
        scheduler=args.scheduler,
        workers=args.workers,
        keep_checkpoints=args.keep_checkpoints,
        refined=refined,
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
        "--pixel-levels",
        choices=PIXEL_LEVEL_MODES,
        default=d.pixel_levels,
        help=(
            "none: the texture's grid only; refine: plus the same synthetic surface at half "
            "the pixel (shipped grinds); refine3: plus the surface at a half and a quarter of "
            "the pixel; coarsen: plus the texture at twice the pixel (any map). Several "
            "levels: zero-pixel extrapolation with a per-point error estimate"
        ),
    )
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
