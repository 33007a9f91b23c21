"""Job ``grind-table`` of an uploaded grind: its table, built from chunk checkpoints in the
job's scratch space, moved into ``grinds/`` when complete (:func:`run_grind_job`)."""

from __future__ import annotations

import logging
import os
import shutil

import numpy as np
from skisnow.app.jobs.runner import JobContext
from skisnow.app.settings import Settings
from skisnow.app.storage.common import sha256_file
from skisnow.app.storage.layout import Layout

log = logging.getLogger(__name__)


def build_settings(settings: Settings):
    from skisnow.app.jobs.table_settings import BuildSettings

    return BuildSettings(points=settings.table_points, chunk_size=settings.table_chunk_size)


def _record_measured_iso(path, iso: dict | None) -> None:
    """Give the table the ISO 25178 parameters of the upload's measured points (those of the
    upload's answer), in place of those of the periodised map it was solved on (a ``window``
    taper lowers Sq by a quarter), so the grind list and the answer agree."""
    import h5py

    with h5py.File(path, "r+") as f:
        f.attrs["texture_provenance"] = "uploaded: a height map file (app.jobs.uploads)"
        if not iso:
            return
        attrs = f["texture"].attrs
        for key in [k for k in attrs if k.startswith("iso_")]:
            del attrs[key]
        for key, value in iso.items():
            attrs[f"iso_{key}"] = float(value)


def run_grind_job(ctx: JobContext, layout: Layout, settings: Settings, on_ready) -> str:
    """Job ``grind-table``: build the table with :func:`app.jobs.table_build.build_tables`.

    Chunks are checkpointed under ``work/<item id>/.checkpoints``; a rerun (service restart)
    computes only the missing chunks. The finished table is moved into ``grinds/`` with one
    ``os.replace``.
    """
    from skisnow.app.jobs.table_build import build_tables
    from skisnow.app.storage.tables import read_table
    from skisnow.app.storage.textures import read_texture
    from skisnow.solvers.lookup import chunk_bounds

    item = ctx.item
    texture = read_texture(layout.grind_texture(item.id))
    bs = build_settings(settings)
    work = layout.work(item.id)
    total = len(chunk_bounds(bs.points, bs.chunk_size))

    def done_chunks() -> int:
        return sum(1 for _ in work.glob(".checkpoints/*/*/chunk-*.h5"))

    ctx.progress(done_chunks() / (total + 1), f"building the table ({total} chunks)")

    def on_chunk(_name: str, _index: int) -> None:
        n = done_chunks()
        ctx.progress(n / (total + 1), f"table chunk {n}/{total}")

    paths = build_tables(
        [texture],
        work,
        bs,
        scheduler=settings.dask_scheduler,
        workers=settings.table_workers,
        processes=settings.table_processes,
        device=settings.table_device,
        progress=False,
        on_chunk_done=on_chunk,
    )
    ctx.check_stop()
    built = paths[texture.name]
    _record_measured_iso(built, item.metadata.get("iso25178"))
    final = layout.grind_table(item.id)
    final.parent.mkdir(parents=True, exist_ok=True)
    os.replace(built, final)
    table = read_table(final)
    sha = sha256_file(final)
    meta = {
        **item.metadata,
        "table_points": int(table.pressure_ratio.size),
        "table_points_not_converged": int(np.count_nonzero(~table.converged)),
    }
    db_item = ctx.db.update_item(
        item.id, state="ready", file_path=str(final), sha256=sha, metadata=meta
    )
    layout.grind_texture(item.id).unlink(missing_ok=True)
    shutil.rmtree(work, ignore_errors=True)
    on_ready(db_item)
    return f"table built: {table.pressure_ratio.size} points, {total} chunks"
