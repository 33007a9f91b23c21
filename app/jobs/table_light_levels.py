"""The light-load levels of a table (``--light-load-levels``; docs/tables.md "Light-load
levels"): the nodes with a_r in ``LIGHT_LOAD_RANGE_A_R`` solved cold on every finer pixel
level down to a target grid (16384² by default: a GPU's job, ``--device cuda``), each
(level, node) checkpointed, and the nodes recombined from their three finest levels.
Imports ``storage`` and ``solvers``.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from skisnow.app.jobs.table_fourth_level import (
    fourth_level_key,
    refined_level,
    solve_node,
    write_pass_table,
)
from skisnow.app.jobs.table_settings import solver_source_sha256
from skisnow.app.storage.common import code_version, provenance
from skisnow.app.storage.tables import (
    LEVEL_REFINEMENT,
    read_checkpoint,
    read_table,
    read_table_extras,
    read_table_heights,
    write_checkpoint,
)
from skisnow.solvers.errors import InputError
from skisnow.solvers.lookup import (
    ERROR_FIELDS,
    LIGHT_LOAD_RANGE_A_R,
    ORDER_TOLERANCE,
    PIXEL_EXTRAPOLATION_ORDERS,
    select_light_load_nodes,
    with_light_load_levels,
)
from skisnow.solvers.texture import Texture

log = logging.getLogger(__name__)

#: default grid of the finest light-load level [pixels per side]: 16384² (issue #29); a
#: solve there needs ~35 GB, a GPU's memory (docs/deployment.md, Table builds on GPUs)
DEFAULT_FINEST_GRID = 16384

#: the rule of the light-load pass, as recorded in the table (fixed in advance)
LIGHT_LOAD_RULE = (
    "every partial-contact node whose a_r lies in light_load_range_a_r = [low, high), and the "
    "node just below the lowest of them, except nodes of the adaptive fourth level, is solved "
    "on every finer pixel level (each half the pixel of the one before) down to the finest "
    "grid, cold from the solver's nested-grid start, and recombined from its three finest "
    "levels with solvers.lookup.combine_three_pixel_levels (same orders, order_tolerance and "
    "fall-back)"
)


def light_load_refinements(
    grid_shape, base_pixel_m: float, finest_pixel_m: float, finest_grid: int
) -> list[int]:
    """Refinement factors (against the texture) of the extra levels: each twice the last,
    starting at twice the table's finest, while the grid stays within ``finest_grid``.

    Raises
    ------
    InputError
        Not one extra level fits in ``finest_grid``.
    """
    start = round(base_pixel_m / finest_pixel_m)
    factors = []
    k = start * LEVEL_REFINEMENT
    while max(int(n) for n in grid_shape) * k <= int(finest_grid):
        factors.append(k)
        k *= LEVEL_REFINEMENT
    if not factors:
        raise InputError(
            f"--finest-grid {finest_grid} leaves no level finer than the table's "
            f"{max(grid_shape) * start}² (pixel {finest_pixel_m * 1e6:.4g} µm)"
        )
    return factors


def light_load_pass(
    table_path: str | Path,
    out_dir: str | Path,
    refined_surface: Callable[[int], Texture],
    *,
    finest_grid: int = DEFAULT_FINEST_GRID,
    a_r_range: tuple[float, float] = LIGHT_LOAD_RANGE_A_R,
    progress: bool = True,
    keep_checkpoints: bool = False,
    on_node_done: Callable[[int, int], None] | None = None,
    write_out_manifest: bool = True,
    device: str = "cpu",
) -> Path:
    """Add the light-load levels to a table of two or more levels; write ``OUT/<name>.h5``.

    The nodes of :func:`solvers.lookup.select_light_load_nodes` (the adaptive fourth level's
    nodes excluded) are solved one at a time in this process on each extra level of
    :func:`light_load_refinements` (:func:`solvers.lookup.solve_table_chunk` of the one node:
    cold, nested-grid start), level by level (one refined surface in memory at a time), each
    (level, node) checkpointed atomically to
    ``OUT/.checkpoints/<name>.light/<key>/node-NNN.h5`` (one key per level); a rerun solves
    only the missing ones and writes the same ``data_sha256``. The nodes are recombined by
    :func:`solvers.lookup.with_light_load_levels`; the rest of the table is unchanged. The
    input table's provenance is kept; the pass adds ``light_load_levels_json`` (rule, range,
    levels, input ``data_sha256``, device, code version, command, time) and
    ``/diagnostics/light_solve_time_s`` (levels × nodes).

    Parameters
    ----------
    table_path : path-like
        A table of two or three pixel levels without light-load levels.
    out_dir : path-like
        Output directory (may hold the input: the file is replaced atomically).
    refined_surface : callable(refine) -> Texture
        The table's surface refined ``refine``× against its texture (for shipped grinds
        :func:`app.storage.textures.refined_texture`); called once per extra level, only if
        a node is selected.
    finest_grid : int
        The finest level's grid [pixels per side] (default 16384).
    a_r_range : (float, float)
        The selected a_r range [-] (default :data:`solvers.lookup.LIGHT_LOAD_RANGE_A_R`;
        tests narrow strips with another), recorded in the table.
    progress : bool
        tqdm progress bar over the (level, node) solves (stderr).
    keep_checkpoints : bool
        Keep the checkpoints after the table is written.
    on_node_done : callable(refine, node), optional
        Called after each solve is checkpointed (tests interrupt the pass with it).
    write_out_manifest : bool
        Rewrite ``OUT/manifest.json`` afterwards.
    device : str
        Where the solves run (:func:`solvers.lookup.solve_table_chunk`): "cpu", "cuda" or
        "torch-cpu". Not part of the checkpoint key (the backends agree within tolerance).

    Returns
    -------
    Path
        The written table.
    """
    from tqdm import tqdm

    t0 = time.perf_counter()
    table_path, out_dir = Path(table_path), Path(out_dir)
    table = read_table(table_path)
    if table.levels is None:
        raise InputError(
            f"{table_path}: light-load levels need a table of several pixel levels "
            "(--pixel-levels refine or refine3), this one has one"
        )
    if table.light_load_nodes.size or "light_load_levels_json" in table.attrs:
        raise InputError(f"{table_path}: already has light-load levels")
    heights_m, base_pixel_m = read_table_heights(table_path)
    texture_attrs, diagnostics = read_table_extras(table_path)
    finest_pixel_m = float(table.levels["pixel_size_m"][-1])
    factors = light_load_refinements(np.shape(heights_m), base_pixel_m, finest_pixel_m, finest_grid)
    if len(table.levels["pixel_size_m"]) + len(factors) < 3:
        raise InputError(
            f"{table_path}: {len(table.levels['pixel_size_m'])} stored and {len(factors)} "
            f"extra level(s) are fewer than the three the rule needs: raise --finest-grid"
        )
    nodes = select_light_load_nodes(
        table.real_contact_area_fraction,
        table.full_contact,
        exclude=table.fourth_level_nodes,
        a_r_range=a_r_range,
    )
    log.info("%s: light-load levels %s at node(s) %s", table.name, factors, nodes.tolist())
    input_sha = str(table.attrs["data_sha256"])
    max_iterations = int(table.attrs["max_iterations"])
    extra: list[dict[str, np.ndarray]] = []
    pixel_sizes = [base_pixel_m / k for k in factors]
    fc_ratios = []
    solve_time = np.zeros((len(factors), nodes.size))
    resumed = 0
    directories = []
    sources = []
    with tqdm(
        total=nodes.size * len(factors),
        desc=f"{table.name} light-load levels",
        unit="solve",
        disable=not progress,
    ) as bar:
        for j, refine in enumerate(factors):
            if not nodes.size:
                fc_ratios.append(np.nan)
                continue
            shape = tuple(int(v) * refine for v in np.shape(heights_m))
            fine, p_fc_ratio = refined_level(
                refined_surface,
                table,
                refine,
                shape,
                pixel_sizes[j],
                fft_workers=os.cpu_count() or 1,
            )
            sources.append(fine.source)
            key = fourth_level_key(input_sha, fine, table, max_iterations, refine)
            directory = out_dir / ".checkpoints" / f"{table.name}.light" / key[:16]
            directories.append(directory)
            fc_ratios.append(p_fc_ratio)
            results = {}
            for node in nodes:
                node = int(node)
                done = read_checkpoint(directory / f"node-{node:03d}.h5", key)
                if done is not None:
                    results[node] = done
                    resumed += 1
                    bar.update(1)
                    continue
                results[node] = solve_node(fine, table, node, p_fc_ratio, max_iterations, device)
                write_checkpoint(directory / f"node-{node:03d}.h5", results[node], key)
                bar.update(1)
                if on_node_done is not None:
                    on_node_done(refine, node)
            del fine
            level = {
                name: np.concatenate([results[int(n)][name] for n in nodes])
                for name in results[int(nodes[0])]
            }
            solve_time[j] = level.pop("solve_time_s")
            extra.append(level)
    new = with_light_load_levels(
        table,
        nodes,
        extra,
        pixel_sizes_m=pixel_sizes if nodes.size else [],
        full_contact_pressure_ratios=fc_ratios if nodes.size else [],
        refinement=LEVEL_REFINEMENT,
    )
    stamp = provenance()
    new.attrs["light_load_levels_json"] = json.dumps(
        {
            "rule": LIGHT_LOAD_RULE,
            "light_load_range_a_r": [float(v) for v in a_r_range],
            "order_tolerance": ORDER_TOLERANCE,
            "orders": PIXEL_EXTRAPOLATION_ORDERS,
            "refinement": LEVEL_REFINEMENT,
            "nodes": nodes.tolist(),
            "refine": factors if nodes.size else [],
            "pixel_size_m": pixel_sizes if nodes.size else [],
            "grid_shape": [
                [int(v) * k for v in np.shape(heights_m)] for k in (factors if nodes.size else [])
            ],
            "finest_grid": int(finest_grid),
            "source": sources[0] if sources else None,
            "start": "cold, the solver's nested-grid start, one node at a time",
            "device": device,
            "input_data_sha256": input_sha,
            "solves_resumed": resumed,
            "time_s": round(time.perf_counter() - t0, 3),
            "solver_source_sha256": solver_source_sha256(),
            "quantities": list(ERROR_FIELDS),
            **{k: stamp[k] for k in ("code_version", "git_commit", "command_line", "created_utc")},
        },
        sort_keys=True,
    )
    diagnostics["light_solve_time_s"] = solve_time if nodes.size else np.zeros((0, 0))
    path = write_pass_table(
        out_dir,
        new,
        heights_m=heights_m,
        texture_attrs=texture_attrs,
        diagnostics=diagnostics,
        checkpoints=[] if keep_checkpoints else directories,
        write_out_manifest=write_out_manifest,
    )
    bad = sum(int(np.count_nonzero(~np.asarray(x["converged"], bool))) for x in extra)
    if bad:
        log.warning("%s: %d light-load solve(s) did not converge", table.name, bad)
    log.info(
        "%s: light-load levels at %d node(s) (%d solves resumed) in %.1f s, code %s",
        table.name,
        nodes.size,
        resumed,
        time.perf_counter() - t0,
        code_version(),
    )
    return path
