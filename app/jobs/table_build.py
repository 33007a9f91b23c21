"""The micro-scale lookup tables, built on a Dask cluster (``skisnow build-tables``,
:mod:`app.commands.build_tables`; the grind-table job of an upload).

For each texture the job computes (docs/physics.md §5):

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

**Adaptive fourth level** (``--adaptive-level``, docs/tables.md "Adaptive fourth level"): after
a three-level (``refine3``) table is assembled, :func:`fourth_level_pass` solves the nodes of
:func:`solvers.lookup.select_fourth_level_nodes` (a_r in the estimate range, three-level rule
fell back for a_r or the mean gap) once more at half the finest pixel, one node at a time in
this process (an 8192² solve needs ~12 GB: never two at once, whatever ``--workers`` says),
each cold from the solver's nested-grid start, each checkpointed atomically under
``OUT/.checkpoints/<texture>.level4/<key>/``; the nodes are recombined from their three finest
levels (:func:`solvers.lookup.with_fourth_level`). With ``--from-table PATH`` only the pass
runs, on an existing three-level table. A from-scratch build keeps its level checkpoints until
the pass is done, so a build killed during the pass resumes without solving a chunk again.

The texture is solved as periodic, as given. ``--detrend`` says what is removed from a height
map file's heights first (:func:`solvers.texture.level_heights`: plane, mean or none; default
plane for a raw or measured map, a stored texture as it is, synthetic ones with their mean
removed). The choice is the table's ``/texture`` attribute ``detrend`` and its root attribute
``texture_detrend``.
"""

from __future__ import annotations

import contextlib
import logging
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path

import numpy as np
from skisnow.app.jobs.table_fourth_level import fourth_level_pass
from skisnow.app.jobs.table_levels import _assemble, _Job, _level_name, _levels, _prepare
from skisnow.app.jobs.table_settings import BuildSettings
from skisnow.app.storage.tables import (
    write_checkpoint,
    write_manifest,
    write_table,
)
from skisnow.solvers.errors import InputError
from skisnow.solvers.lookup import (
    solve_table_chunk,
)
from skisnow.solvers.texture import Texture

__all__ = ["BuildSettings", "build_tables"]

log = logging.getLogger(__name__)


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
    fourth_level: dict[str, Callable[[int], Texture]] | None = None,
    on_node_done: Callable[[int], None] | None = None,
    device: str = "cpu",
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
    fourth_level : dict of str to callable(refine) -> Texture, optional
        Run the adaptive fourth-level pass (:func:`fourth_level_pass`, ``refine3`` only) on
        these textures' tables: the callable gives the surface refined ``refine``× (8 for
        ``refine3``), called only if a node is selected.
    on_node_done : callable(node), optional
        Passed to :func:`fourth_level_pass`.
    device : str
        Where the chunks are solved (:func:`solvers.lookup.solve_table_chunk`): ``"cpu"`` (the
        numpy/pyFFTW solver), ``"cuda"`` (the torch backend on a GPU; torch imported only in
        the workers that solve) or ``"torch-cpu"``. With ``cuda``, give each Dask worker one
        GPU (docs/deployment.md, Table builds on GPUs).

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
    fourth_level = fourth_level or {}
    if fourth_level and settings.pixel_levels != "refine3":
        raise InputError(
            f"the adaptive fourth level needs --pixel-levels refine3, got {settings.pixel_levels}"
        )
    if set(fourth_level) - set(names):
        raise InputError(f"fourth_level names no texture: {sorted(set(fourth_level) - set(names))}")
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
            computed = _run(client, jobs, pending, settings, progress, on_chunk_done, device)
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
        adaptive = name in fourth_level
        # with the pass, the three-level table waits beside the checkpoints (kept until the
        # pass is done) and OUT/<name>.h5 appears only with the fourth level in it
        three_level_path = out_dir / ".checkpoints" / f"{name}.levels3.h5"
        paths[name] = write_table(
            three_level_path if adaptive else out_dir / f"{name}.h5",
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
        if adaptive:
            paths[name] = fourth_level_pass(
                three_level_path,
                out_dir,
                fourth_level[name],
                progress=progress,
                keep_checkpoints=keep_checkpoints,
                on_node_done=on_node_done,
                write_out_manifest=False,
                device=device,
            )
            three_level_path.unlink()
        if not keep_checkpoints:
            for job in level_jobs:
                shutil.rmtree(job.directory, ignore_errors=True)
                for parent in (job.directory.parent, job.directory.parent.parent):
                    with contextlib.suppress(OSError):
                        parent.rmdir()  # only if empty
        bad = int(np.count_nonzero(~table.converged))  # the fourth level's: the pass logs
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


def _run(client, jobs, pending, settings, progress, on_chunk_done, device="cpu") -> int:
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
            device=device,
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
