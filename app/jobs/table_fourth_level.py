"""The adaptive fourth pixel level of a three-level table (``--adaptive-level``; docs/tables.md
"Adaptive fourth level"): the nodes the rule fixed in advance selects, solved one at a time on
the next finer pixel, each checkpointed, and the table recombined from its three finest levels.
Imports ``storage`` and ``solvers``.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import shutil
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from skisnow.app.jobs.table_settings import solver_source_sha256
from skisnow.app.storage.common import code_version, provenance
from skisnow.app.storage.tables import (
    LEVEL_REFINEMENT,
    read_checkpoint,
    read_table,
    read_table_extras,
    read_table_heights,
    write_checkpoint,
    write_manifest,
    write_table,
)
from skisnow.solvers.elastic import PeriodicHalfSpace
from skisnow.solvers.errors import InputError
from skisnow.solvers.lookup import (
    ERROR_FIELDS,
    ESTIMATE_RANGE_A_R,
    ORDER_TOLERANCE,
    PIXEL_EXTRAPOLATION_ORDERS,
    MicroTable,
    select_fourth_level_nodes,
    solve_table_chunk,
    with_fourth_level,
)
from skisnow.solvers.micro import full_contact_pressure
from skisnow.solvers.texture import Texture

log = logging.getLogger(__name__)


#: the rule of the fourth-level pass, as recorded in the table (fixed in advance)
FOURTH_LEVEL_RULE = (
    "after the three-level combination, every node whose a_r lies in estimate_range_a_r and "
    "where the three-level rule fell back (three_level_estimate_<q> == 0) for a quantity with "
    "an order (a_r, mean gap) is solved once more at half the finest pixel, cold from the "
    "solver's nested-grid start, and recombined from its three finest levels with "
    "solvers.lookup.combine_three_pixel_levels (same orders, order_tolerance and fall-back); "
    "one extra level at most"
)


def fourth_level_key(
    table_data_sha256: str, fine: Texture, table: MicroTable, max_iterations: int, refine: int
) -> str:
    """Hash of everything a fourth-level node depends on (stale checkpoints never match)."""
    h = hashlib.sha256()
    h.update(table_data_sha256.encode())
    heights = np.ascontiguousarray(fine.heights_m, dtype=np.float64)
    h.update(f"{heights.shape};{float(fine.pixel_size_m)!r};refine={refine}".encode())
    h.update(heights.tobytes())
    for name in ("effective_modulus_pa", "tol", "gap_floor_m"):
        h.update(f"{name}={float(getattr(table, name))!r};".encode())
    h.update(f"max_iterations={int(max_iterations)};".encode())
    h.update(code_version().encode())
    h.update(solver_source_sha256().encode())
    return h.hexdigest()


def refined_level(
    refined_surface: Callable[[int], Texture],
    table: MicroTable,
    refine: int,
    shape,
    pixel_size_m: float,
    *,
    fft_workers: int = 1,
) -> tuple[Texture, float]:
    """The table's surface refined ``refine``× (checked: ``shape`` pixels of ``pixel_size_m``)
    and its full-contact ratio ``p_fc / E'`` [-], for a pass over the table's nodes."""
    fine = refined_surface(refine)
    if np.shape(fine.heights_m) != tuple(shape) or not np.isclose(
        fine.pixel_size_m, pixel_size_m, rtol=1e-12
    ):
        raise InputError(
            f"refined surface of {table.name!r} is not {refine}x finer than its texture"
        )
    e_eff = table.effective_modulus_pa
    hs = PeriodicHalfSpace(tuple(shape), fine.pixel_size_m, e_eff, workers=fft_workers)
    p_fc, _ = full_contact_pressure(fine.heights_m, fine.pixel_size_m, e_eff, halfspace=hs)
    return fine, p_fc / e_eff


def solve_node(
    fine: Texture,
    table: MicroTable,
    node: int,
    full_contact_pressure_ratio: float,
    max_iterations: int,
    device: str,
) -> dict[str, np.ndarray]:
    """One table node solved cold on a refined surface (:func:`solve_table_chunk` of the one
    node, the table's tolerance and gap floor)."""
    return solve_table_chunk(
        fine.heights_m,
        float(fine.pixel_size_m),
        table.pressure_ratio[node : node + 1],
        effective_modulus_pa=table.effective_modulus_pa,
        full_contact_pressure_ratio=full_contact_pressure_ratio,
        tol=table.tol,
        max_iterations=max_iterations,
        gap_floor_m=table.gap_floor_m,
        device=device,
    )


def write_pass_table(
    out_dir: Path,
    table,
    *,
    heights_m,
    texture_attrs,
    diagnostics,
    checkpoints: list[Path],
    write_out_manifest: bool,
) -> Path:
    """The end of a pass over a table's nodes: write ``OUT/<name>.h5`` (atomically), remove
    the pass's checkpoint folders (and their parents when empty), rewrite the manifest."""
    path = write_table(
        out_dir / f"{table.name}.h5",
        table,
        heights_m=heights_m,
        texture_attrs=texture_attrs,
        diagnostics=diagnostics,
    )
    for directory in checkpoints:
        shutil.rmtree(directory, ignore_errors=True)
        for parent in (directory.parent, directory.parent.parent):
            with contextlib.suppress(OSError):
                parent.rmdir()  # only if empty
    if write_out_manifest:
        write_manifest(out_dir)
    return path


def fourth_level_pass(
    table_path: str | Path,
    out_dir: str | Path,
    refined_surface: Callable[[int], Texture],
    *,
    progress: bool = True,
    keep_checkpoints: bool = False,
    on_node_done: Callable[[int], None] | None = None,
    write_out_manifest: bool = True,
    device: str = "cpu",
) -> Path:
    """Add the adaptive fourth pixel level to a three-level table; write ``OUT/<name>.h5``.

    The nodes of :func:`solvers.lookup.select_fourth_level_nodes` are solved one at a time in
    this process at half the finest pixel (:func:`solvers.lookup.solve_table_chunk` of the
    one node: cold, nested-grid start, one FFT thread), each checkpointed atomically to
    ``OUT/.checkpoints/<name>.level4/<key>/node-NNN.h5``; a rerun solves only the missing
    nodes and writes the same ``data_sha256``. The nodes are recombined by
    :func:`solvers.lookup.with_fourth_level`; the rest of the table is unchanged. The input
    table's provenance is kept; the pass adds ``adaptive_level_json`` (rule, range, input
    ``data_sha256``, code version, command, time) and ``/diagnostics/adaptive_solve_time_s``.

    Parameters
    ----------
    table_path : path-like
        A three-level (``refine3``) table without a fourth level.
    out_dir : path-like
        Output directory (may hold the input: the file is replaced atomically).
    refined_surface : callable(refine) -> Texture
        The table's surface refined ``refine``× against its texture (for shipped grinds
        :func:`app.storage.textures.refined_texture`); called once, only if a node is selected.
    progress : bool
        tqdm progress bar over the nodes (stderr).
    keep_checkpoints : bool
        Keep the node checkpoints after the table is written.
    on_node_done : callable(node), optional
        Called after each solved node is checkpointed (tests interrupt the pass with it).
    write_out_manifest : bool
        Rewrite ``OUT/manifest.json`` afterwards.

    Returns
    -------
    Path
        The written table.
    """
    from tqdm import tqdm

    t0 = time.perf_counter()
    table_path, out_dir = Path(table_path), Path(out_dir)
    table = read_table(table_path)
    if table.attrs.get("pixel_levels") != "refine3" or table.levels is None:
        raise InputError(
            f"{table_path}: the fourth level needs a table built with --pixel-levels refine3, "
            f"got {table.attrs.get('pixel_levels', 'none')!r}"
        )
    if table.fourth_level_nodes.size or "adaptive_level_json" in table.attrs:
        raise InputError(f"{table_path}: already has the fourth level (one extra level at most)")
    heights_m, base_pixel_m = read_table_heights(table_path)
    texture_attrs, diagnostics = read_table_extras(table_path)
    finest_pixel_m = float(table.levels["pixel_size_m"][-1])
    refine = LEVEL_REFINEMENT * round(base_pixel_m / finest_pixel_m)
    nodes, selected_by = select_fourth_level_nodes(
        table.real_contact_area_fraction,
        {q: table.levels[f"three_level_estimate_{q}"] for q in ERROR_FIELDS},
    )
    log.info("%s: fourth level at node(s) %s", table.name, nodes.tolist())
    input_sha = str(table.attrs["data_sha256"])
    max_iterations = int(table.attrs["max_iterations"])
    fourth: dict[str, np.ndarray] = {}
    solve_time = np.zeros(nodes.size)
    resumed = 0
    directory = None
    fine_pixel_m = finest_pixel_m / LEVEL_REFINEMENT
    fine_shape = [int(v) * refine for v in np.shape(heights_m)]
    p_fc_ratio = np.nan
    source = None
    if nodes.size:
        fine, p_fc_ratio = refined_level(refined_surface, table, refine, fine_shape, fine_pixel_m)
        source = fine.source
        key = fourth_level_key(input_sha, fine, table, max_iterations, refine)
        directory = out_dir / ".checkpoints" / f"{table.name}.level4" / key[:16]
        results = {}
        for node in nodes:
            done = read_checkpoint(directory / f"node-{node:03d}.h5", key)
            if done is not None:
                results[int(node)] = done
        resumed = len(results)
        with tqdm(
            total=nodes.size,
            initial=resumed,
            desc=f"{table.name} fourth level",
            unit="node",
            disable=not progress,
        ) as bar:
            for node in nodes:
                node = int(node)
                if node in results:
                    continue
                results[node] = solve_node(fine, table, node, p_fc_ratio, max_iterations, device)
                write_checkpoint(directory / f"node-{node:03d}.h5", results[node], key)
                bar.update(1)
                if on_node_done is not None:
                    on_node_done(node)
        del fine
        for name in results[int(nodes[0])]:
            fourth[name] = np.concatenate([results[int(n)][name] for n in nodes])
        solve_time = fourth.pop("solve_time_s")
    else:
        for name, dtype in (
            *((k, float) for k in ERROR_FIELDS),
            ("mean_reciprocal_gap_raw_per_m", float),
            ("iterations", np.int64),
            ("residual", float),
            ("converged", bool),
            ("full_contact", bool),
        ):
            fourth[name] = np.zeros(0, dtype=dtype)
    new = with_fourth_level(
        table,
        nodes,
        fourth,
        pixel_size_m=fine_pixel_m,
        full_contact_pressure_ratio=p_fc_ratio,
        selected_by=selected_by,
        refinement=LEVEL_REFINEMENT,
    )
    stamp = provenance()
    new.attrs["adaptive_level_json"] = json.dumps(
        {
            "rule": FOURTH_LEVEL_RULE,
            "estimate_range_a_r": list(ESTIMATE_RANGE_A_R),
            "order_tolerance": ORDER_TOLERANCE,
            "orders": PIXEL_EXTRAPOLATION_ORDERS,
            "refinement": LEVEL_REFINEMENT,
            "nodes": nodes.tolist(),
            "pixel_size_m": fine_pixel_m,
            "grid_shape": fine_shape,
            "source": source,
            "start": "cold, the solver's nested-grid start, one node at a time (1 FFT thread)",
            "input_data_sha256": input_sha,
            "nodes_resumed": resumed,
            "time_s": round(time.perf_counter() - t0, 3),
            "solver_source_sha256": solver_source_sha256(),
            **{k: stamp[k] for k in ("code_version", "git_commit", "command_line", "created_utc")},
        },
        sort_keys=True,
    )
    diagnostics["adaptive_solve_time_s"] = solve_time
    path = write_pass_table(
        out_dir,
        new,
        heights_m=heights_m,
        texture_attrs=texture_attrs,
        diagnostics=diagnostics,
        checkpoints=[] if directory is None or keep_checkpoints else [directory],
        write_out_manifest=write_out_manifest,
    )
    bad = int(np.count_nonzero(~np.asarray(fourth["converged"], bool)))
    if bad:
        log.warning("%s: %d fourth-level node(s) did not converge", table.name, bad)
    log.info(
        "%s: fourth level at %d node(s) (%d resumed) in %.1f s",
        table.name,
        nodes.size,
        resumed,
        time.perf_counter() - t0,
    )
    return path
