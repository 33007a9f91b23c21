"""Bring-your-own skis and grinds: validate uploads, run their jobs, keep the live catalogue.

Storage layout under the data directory (``Settings.data_dir``)::

    catalogue.db                 SQLite catalogue (default database URL)
    uploads/<item id>.texture.h5 detrended texture of an uploaded grind (until its table is built)
    uploads/<item id>.csv        camber CSV of an uploaded ski (kept: the ski's raw data)
    work/<item id>/              a job's scratch space (table checkpoints; removed when done)
    grinds/<item id>.h5          finished texture table (schema skisnow.table/…)
    skis/<item id>.h5            finished ski file with its network (schema skisnow.ski/1)
    cache/ski-figures/<stem>.json the figures of a ski's page, drawn by the ski's job or on the
                                 page's first view (:mod:`app.web.ski_figures`; ``<stem>``: the
                                 ski file's name, ``<item id>`` for an upload; removed with it)

Files are named by item id so renaming touches only the database. Every file is written
atomically (:func:`app.storage.common.atomic_path`) or moved in with one ``os.replace`` from
``work/`` on the same file system: the catalogue never points at a half-written file, and a
rejected upload leaves nothing behind.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import re
import shutil
import threading
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from skisnow.app import service
from skisnow.app.jobs import JobContext
from skisnow.app.settings import Settings
from skisnow.app.storage.catalogue import CatalogueDB, ItemRow
from skisnow.app.storage.common import atomic_path, provenance, sha256_file
from skisnow.solvers.errors import DataFileError, InputError, SkisnowError

log = logging.getLogger(__name__)

NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")
GRIND_JOB = "grind-table"
SKI_JOB = "ski-network"

NPY_MAGIC = b"\x93NUMPY"
HDF5_MAGIC = b"\x89HDF\r\n\x1a\n"
#: plausible ranges of a ski-base texture, to catch wrong units [m]
SQ_RANGE_M = (1e-9, 1e-3)
PIXEL_UM_RANGE = (0.01, 1000.0)
#: coarsest camber sampling that still resolves the contact zones [mm]
MAX_SAMPLE_SPACING_MM = 10.0
SKI_LENGTH_MM_RANGE = (1000.0, 2600.0)
SKI_WIDTH_MM_RANGE = (30.0, 80.0)


# ------------------------------------------------------------------------------- errors


class UnsupportedContentError(SkisnowError):
    """The upload's bytes are not what its kind or name promises (HTTP 415)."""


class ConflictError(SkisnowError):
    """A name is taken, or the item is used by a job (HTTP 409)."""


class ForbiddenError(SkisnowError):
    """A shipped read-only item, or another team's item (HTTP 403)."""


class UnauthorizedError(SkisnowError):
    """Teams are configured and the request has no valid bearer token (HTTP 401)."""


class UploadTooLargeError(SkisnowError):
    """The uploaded file exceeds ``max_upload_bytes`` (HTTP 413)."""


class QuotaError(SkisnowError):
    """Too many jobs queued or running, for the team or for the service (HTTP 429 with
    ``Retry-After: retry_after_s``)."""

    #: what the answer's ``Retry-After`` asks [s]: about the time a table build at the default
    #: settings takes on one worker, so that a retry is likely to find a free slot
    retry_after_s = 60


# -------------------------------------------------------------------------------- quotas


@dataclass(frozen=True)
class JobLimits:
    """Queued + running jobs allowed per team and in total (``Settings.max_jobs_per_team``,
    ``Settings.max_queued_jobs``); without team tokens every upload is of one anonymous team."""

    per_team: int
    total: int


def check_name_free(db: CatalogueDB, kind: str, name: str) -> str:
    """The checked ``name`` (:func:`check_name`) of a new ``kind`` item; :class:`ConflictError`
    (409) when an item of that kind has it. Asked before the job quota: a name that is taken
    stays taken, so "retry later" (429) would be the wrong answer. Names are one namespace for
    all teams; the answer does not say whose the item is."""
    name = check_name(name)
    if db.item_by_name(kind, name) is not None:
        raise ConflictError(f"a {kind} named {name!r} already exists; choose another name")
    return name


def check_job_quota(db: CatalogueDB, team: str | None, limits: JobLimits | None) -> None:
    """Raise :class:`QuotaError` when ``team`` (None: no team) may not queue another job."""
    if limits is None:
        return
    counts = db.active_job_counts()
    mine = counts.get(team, 0)
    who = f"team {team!r}" if team is not None else "the service (no team tokens: one team)"
    if mine >= limits.per_team:
        raise QuotaError(
            f"{who} has {mine} jobs queued or running, the limit max_jobs_per_team "
            f"(SKISNOW_MAX_JOBS_PER_TEAM) = {limits.per_team}; retry when one has finished"
        )
    total = sum(counts.values())
    if total >= limits.total:
        raise QuotaError(
            f"{total} jobs are queued or running, the limit max_queued_jobs "
            f"(SKISNOW_MAX_QUEUED_JOBS) = {limits.total}; retry when one has finished"
        )


# ------------------------------------------------------------------------------- layout


@dataclass(frozen=True)
class Layout:
    """Paths of the data directory (see the module docstring)."""

    root: Path

    @property
    def uploads(self) -> Path:
        return self.root / "uploads"

    def work(self, item_id: str) -> Path:
        return self.root / "work" / item_id

    def grind_texture(self, item_id: str) -> Path:
        return self.uploads / f"{item_id}.texture.h5"

    def ski_csv(self, item_id: str) -> Path:
        return self.uploads / f"{item_id}.csv"

    def grind_table(self, item_id: str) -> Path:
        return self.root / "grinds" / f"{item_id}.h5"

    def ski_file(self, item_id: str) -> Path:
        return self.root / "skis" / f"{item_id}.h5"

    def ski_figures(self, stem: str) -> Path:
        """The ski page's figures of ski file ``{stem}.h5`` (:mod:`app.web.ski_figures`)."""
        return self.root / "cache" / "ski-figures" / f"{stem}.json"

    def remove_item_files(self, item_id: str) -> None:
        for path in (
            self.grind_texture(item_id),
            self.ski_csv(item_id),
            self.grind_table(item_id),
            self.ski_file(item_id),
            self.ski_figures(item_id),
        ):
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
        shutil.rmtree(self.work(item_id), ignore_errors=True)


def check_name(name: str, field: str = "name") -> str:
    name = (name or "").strip()
    if not NAME_RE.match(name):
        raise InputError(
            f"{field} {name!r} must be 1-64 letters, digits, '.', '_' or '-', starting with a "
            "letter or digit"
        )
    return name


# ------------------------------------------------------------------------------- grinds


def _topography():
    """The module :mod:`app.storage.topography` (instrument formats) if it is installed."""
    try:
        from skisnow.app.storage import topography
    except ModuleNotFoundError as exc:
        if exc.name != "skisnow.app.storage.topography":
            raise
        return None
    return topography if hasattr(topography, "read_topography") else None


def _npy_shape(path: Path) -> tuple[int, ...]:
    """Shape declared in a .npy header (read before any array is allocated)."""
    from skisnow.app.storage.topography import npy_header

    with open(path, "rb") as fh:
        shape, dtype = npy_header(fh, "file")
    if dtype.hasobject:
        raise UnsupportedContentError(".npy holds Python objects; only numeric arrays are read")
    return shape


def check_solve_grid(shape: tuple[int, ...], periodic: str, settings: Settings) -> None:
    """Refuse a map whose periodised grid, the one its table is solved on, exceeds
    ``max_solve_grid_points`` (``mirror`` doubles each side: 4× the uploaded points)."""
    from skisnow.solvers.texture import periodic_shape

    solve = periodic_shape(shape, periodic)
    n = math.prod(solve)
    if n > settings.max_solve_grid_points:
        raise InputError(
            f"file: grid {shape[0]}×{shape[1]} with periodic={periodic} is solved on "
            f"{solve[0]}×{solve[1]} = {n} points, over the limit of "
            f"{settings.max_solve_grid_points} points (max_solve_grid_points, "
            "SKISNOW_MAX_SOLVE_GRID_POINTS); crop or resample the map, or choose periodic=window "
            "or none (solved on the grid as measured)"
        )


def _check_grid_shape(shape: tuple[int, ...], settings: Settings) -> None:
    if len(shape) != 2:
        raise InputError(f"file: a height map must be a 2-D grid, got shape {shape}")
    n = shape[0] * shape[1]
    if min(shape) < settings.min_grid_side:
        raise InputError(
            f"file: grid {shape[0]}×{shape[1]} is too small; each side needs at least "
            f"{settings.min_grid_side} points"
        )
    if n > settings.max_grid_points:
        raise InputError(
            f"file: grid {shape[0]}×{shape[1]} = {n} points exceeds the limit of "
            f"{settings.max_grid_points} points (max_grid_points)"
        )


def read_grind_upload(
    path: Path,
    filename: str,
    settings: Settings,
    *,
    pixel_size_um: float | None,
    height_unit: str | None,
    along_ski: str = "x",
    detrend: str | None = None,
):
    """Check the content of an uploaded topography file and read it as a detrended texture.

    The bytes decide, not the name: a name that promises a format the bytes do not have
    (``.npy`` without the NumPy magic, ``.h5``/``.datx`` without HDF5's, ``.x3p`` without
    zip's) and content of no accepted format are refused (415). The grid size is checked from
    the header before the heights are decoded. Reading, unit conversion and detrending are
    :func:`app.storage.topography.read_topography` (x3p, instrument formats, ``.npy``,
    ``.csv``, skisnow ``.h5``); without that module, ``.npy``/``.csv``/``.h5`` only.
    ``detrend`` ("plane", "mean", "none"; ``None``: "plane" for a measured map, a skisnow
    texture as stored) is what is removed from the heights, kept in the texture's
    ``detrend``.

    Returns
    -------
    solvers.texture.Texture
        Detrended texture in metres, axis 0 along the ski (named ``upload``).

    Raises
    ------
    UnsupportedContentError, InputError, DataFileError
    """
    from skisnow.app.storage.textures import detrend_texture, read_heightmap, read_texture
    from skisnow.solvers.texture import check_detrend

    if detrend is not None:
        check_detrend(detrend)
    suffix = Path(filename).suffix.lower()
    with open(path, "rb") as fh:
        head = fh.read(4096)
    if not head:
        raise DataFileError("file: the uploaded file is empty")
    promised = {".npy": (NPY_MAGIC,), ".h5": (HDF5_MAGIC,), ".hdf5": (HDF5_MAGIC,)}
    promised |= {".datx": (HDF5_MAGIC,), ".x3p": (b"PK\x03\x04", b"PK\x05\x06")}
    if suffix in promised and not head.startswith(promised[suffix]):
        raise UnsupportedContentError(
            f"file {filename!r} is named {suffix} but its content is not (magic bytes)"
        )
    if head.startswith(NPY_MAGIC):
        _check_grid_shape(_npy_shape(path), settings)
    if head.startswith(b"\x80") or head.startswith(b"(dp"):
        raise UnsupportedContentError(f"file {filename!r} is a Python pickle; never loaded")
    topo = _topography()
    if topo is not None:
        try:
            topo.detect_format(head, suffix=suffix)
        except DataFileError as exc:
            raise UnsupportedContentError(f"file {filename!r}: {exc}") from None
        texture = topo.read_topography(
            path,
            pixel_size_um=pixel_size_um,
            height_unit=height_unit,
            along_ski=along_ski,
            detrend=detrend,
            max_pixels=settings.max_grid_points,
            min_side=settings.min_grid_side,
            max_file_bytes=settings.max_upload_bytes,
        )
    else:
        if suffix in (".npy", ".csv", ".txt"):
            missing = [
                n
                for n, v in (("pixel_size_um", pixel_size_um), ("height_unit", height_unit))
                if v is None
            ]
            if missing:
                raise InputError(f"{' and '.join(missing)} must be given for a {suffix} height map")
        raw_detrend = "plane" if detrend is None else detrend
        if suffix == ".npy" or (suffix in (".csv", ".txt") and b"\x00" not in head):
            texture = read_heightmap(
                path, pixel_size_um=pixel_size_um, height_unit=height_unit, detrend=raw_detrend
            )
        elif suffix == ".h5":
            texture = detrend_texture(read_texture(path), detrend)
        else:
            raise UnsupportedContentError(
                f"file {filename!r}: unsupported topography format; accepted: .npy, .csv, .h5 "
                "(instrument formats need app.storage.topography)"
            )
        if along_ski == "y":
            texture = replace(texture, heights_m=np.asarray(texture.heights_m).T.copy())
    heights = np.asarray(texture.heights_m, dtype=float)
    _check_grid_shape(heights.shape, settings)
    px_um = texture.pixel_size_m * 1e6
    if not PIXEL_UM_RANGE[0] <= px_um <= PIXEL_UM_RANGE[1]:
        raise InputError(
            f"pixel_size_um {px_um:g} is outside the plausible range "
            f"{PIXEL_UM_RANGE[0]:g}–{PIXEL_UM_RANGE[1]:g} µm of a texture measurement"
        )
    sq = float(np.std(heights))  # about the mean: detrend "none" keeps an offset
    if not SQ_RANGE_M[0] <= sq <= SQ_RANGE_M[1]:
        raise InputError(
            f"height_unit: the detrended heights have Sq = {sq:.3g} m, outside the plausible "
            f"range {SQ_RANGE_M[0]:g}–{SQ_RANGE_M[1]:g} m of a ski-base grind; wrong height unit?"
        )
    return replace(texture, name="upload")


def accept_grind(
    db: CatalogueDB,
    layout: Layout,
    settings: Settings,
    *,
    upload_path: Path,
    filename: str,
    name: str,
    metadata: dict,
    pixel_size_um: float | None,
    height_unit: str | None,
    team: str | None,
    along_ski: str = "x",
    periodic: str = "mirror",
    detrend: str | None = None,
    limits: JobLimits | None = None,
) -> tuple[ItemRow, str, dict]:
    """Validate and detrend an uploaded grind, store it, and queue its table build.

    The table is built on ``solvers.texture.make_periodic(heights, periodic)``: ``mirror``
    (default for measured maps; a 2n0 × 2n1 grid), ``window`` or ``none`` (docs/topography.md).
    ``detrend`` is what is removed from the heights first (``solvers.texture.level_heights``):
    ``plane``, ``mean`` or ``none``; by default ``plane``, or ``mean`` when the map is declared
    periodic (``periodic="none"``); a skisnow texture file is kept as stored unless it is
    given. The choice is recorded in the item's metadata (``detrend``), the stored texture
    and the table. The periodised grid must hold at most ``settings.max_solve_grid_points``
    (422), and ``team`` must be within the job ``limits`` (:class:`QuotaError`, 429).

    Returns
    -------
    item, job_id, iso25178
        The new item (state ``pending``), the build job's id and the texture's ISO 25178
        parameters (SI, unit in each name; gradients not wrapped: measured maps are not
        periodic).
    """
    from skisnow.app.storage.textures import write_texture
    from skisnow.solvers.texture import iso25178_parameters, make_periodic

    name = check_name_free(db, "grind", name)
    if detrend is None and periodic == "none":  # declared periodic: no plane to remove
        detrend = "mean"
    texture = read_grind_upload(
        upload_path,
        filename,
        settings,
        pixel_size_um=pixel_size_um,
        height_unit=height_unit,
        along_ski=along_ski,
        detrend=detrend,
    )
    check_solve_grid(np.shape(texture.heights_m), periodic, settings)
    iso = iso25178_parameters(texture.heights_m, texture.pixel_size_m, periodic=False)
    solve_heights = make_periodic(texture.heights_m, periodic)
    meta = {
        **metadata,
        "original_filename": Path(filename).name,
        "upload_sha256": sha256_file(upload_path),
        "grid": list(np.shape(texture.heights_m)),
        "detrend": texture.detrend,
        "periodic": periodic,
        "solve_grid": list(solve_heights.shape),
        "pixel_size_um": texture.pixel_size_m * 1e6,
        "missing_fraction": float(texture.missing_fraction),
        "iso25178": iso,
    }
    check_job_quota(db, team, limits)
    item = _add_item(db, "grind", name, meta, team)
    try:
        stored = replace(
            texture,
            heights_m=solve_heights,
            name=f"g{item.id}",
            source=(
                f"upload {Path(filename).name}; detrend={texture.detrend}; periodic={periodic}"
            ),
        )
        write_texture(
            stored,
            layout.grind_texture(item.id),
            extra_attrs={"item_name": name, "periodic_method": periodic},
            periodic=periodic != "none",
        )
        job = db.add_job(GRIND_JOB, item.id, "queued: table build")
    except BaseException:
        layout.remove_item_files(item.id)
        db.delete_item(item.id)
        raise
    return item, job.id, iso


def _add_item(db: CatalogueDB, kind: str, name: str, meta: dict, team: str | None) -> ItemRow:
    from skisnow.app.storage.catalogue import NameTakenError

    try:
        return db.add_item(kind, name, metadata=meta, team=team)
    except NameTakenError as exc:
        raise ConflictError(str(exc)) from None


def build_settings(settings: Settings):
    from skisnow.app.build_tables import BuildSettings

    return BuildSettings(points=settings.table_points, chunk_size=settings.table_chunk_size)


def run_grind_job(ctx: JobContext, layout: Layout, settings: Settings, on_ready) -> str:
    """Job ``grind-table``: build the table with :func:`app.build_tables.build_tables`.

    Chunks are checkpointed under ``work/<item id>/.checkpoints``; a rerun (service restart)
    computes only the missing chunks. The finished table is moved into ``grinds/`` with one
    ``os.replace``.
    """
    from skisnow.app.build_tables import build_tables
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
        progress=False,
        on_chunk_done=on_chunk,
    )
    ctx.check_stop()
    built = paths[texture.name]
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


# --------------------------------------------------------------------------------- skis


def _decode_text(data: bytes, filename: str) -> str:
    if b"\x00" in data[:4096]:
        raise UnsupportedContentError(f"file {filename!r} is not a text CSV (binary bytes)")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise UnsupportedContentError(
            f"file {filename!r} is not UTF-8 text (byte {exc.start})"
        ) from None


def _parse_mm_list(text: str, field: str) -> np.ndarray:
    try:
        values = np.array([float(v) for v in str(text).replace(";", ",").split(",") if v.strip()])
    except ValueError:
        raise InputError(
            f"{field} must be a number or comma-separated numbers, got {text!r}"
        ) from None
    if values.size == 0 or not np.all(np.isfinite(values)):
        raise InputError(f"{field} must hold finite numbers, got {text!r}")
    return values


def check_ski_upload(
    data: bytes, filename: str, *, length_mm: float, width_mm: str, width_positions_mm: str | None
):
    """Validate a camber CSV upload and the outline; refuse data too sparse to train on.

    Returns
    -------
    CamberData, SkiOutline, dict
        The measurements, the outline and figures of the data (cases, spacing, side used).
    """
    from skisnow.app.storage.skis import SkiOutline, read_camber_csv
    from skisnow.app.train_camber import camber_training_arrays, split_load_cases

    if Path(filename).suffix.lower() not in (".csv", ".txt"):
        raise UnsupportedContentError(
            f"file {filename!r}: camber measurements must be a neutral .csv file"
        )
    text = _decode_text(data, filename)
    if "\n" not in text:
        text += "\n"  # read_camber_csv takes a one-line string for a path: never here
    camber_data = read_camber_csv(text)
    _, x, f, xf, _h, side = camber_training_arrays(camber_data)
    spacing_mm = float(np.median(np.diff(x))) * 1e3
    if spacing_mm > MAX_SAMPLE_SPACING_MM:
        raise InputError(
            f"file: samples every {spacing_mm:g} mm are too sparse to resolve the contact zones; "
            f"the accuracy check needs at most {MAX_SAMPLE_SPACING_MM:g} mm"
        )
    try:
        split_load_cases(f, xf)
    except InputError as exc:
        raise InputError(
            f"file: data too sparse for the accuracy check on held-out load cases: {exc}"
        ) from None
    if not SKI_LENGTH_MM_RANGE[0] <= length_mm <= SKI_LENGTH_MM_RANGE[1]:
        raise InputError(
            f"length_mm must be in [{SKI_LENGTH_MM_RANGE[0]:g}, {SKI_LENGTH_MM_RANGE[1]:g}], "
            f"got {length_mm:g}"
        )
    span_mm = (x[-1] - x[0]) * 1e3
    if span_mm > length_mm + 1e-6:
        raise InputError(
            f"length_mm {length_mm:g} is shorter than the measured span {span_mm:g} mm"
        )
    widths = _parse_mm_list(width_mm, "width_mm")
    if widths.min() < SKI_WIDTH_MM_RANGE[0] or widths.max() > SKI_WIDTH_MM_RANGE[1]:
        raise InputError(
            f"width_mm must be in [{SKI_WIDTH_MM_RANGE[0]:g}, {SKI_WIDTH_MM_RANGE[1]:g}] mm, "
            f"got {width_mm!r}"
        )
    if width_positions_mm:
        positions = _parse_mm_list(width_positions_mm, "width_positions_mm")
        if positions.size != widths.size or not np.all(np.diff(positions) > 0):
            raise InputError(
                "width_positions_mm must be increasing, one per width_mm value, got "
                f"{positions.size} positions for {widths.size} widths"
            )
    elif widths.size == 1:
        positions = np.array([x[0] * 1e3, x[-1] * 1e3])
        widths = np.repeat(widths, 2)
    else:
        raise InputError("width_positions_mm is needed when width_mm lists several widths")
    outline = SkiOutline(
        length_m=length_mm * 1e-3,
        balance_point_from_tail_m=-x[0] + (length_mm * 1e-3 - (x[-1] - x[0])) / 2,
        positions_m=positions * 1e-3,
        width_m=widths * 1e-3,
    )
    figures = {
        "load_cases": int(f.size),
        "samples_per_case": int(x.size),
        "sample_spacing_mm": spacing_mm,
        "measured_side": side,
        "load_range_kg": [float(f.min() / 9.82), float(f.max() / 9.82)],
        "load_position_range_mm": [float(xf.min() * 1e3), float(xf.max() * 1e3)],
    }
    return camber_data, outline, figures


def accept_ski(
    db: CatalogueDB,
    layout: Layout,
    *,
    data: bytes,
    filename: str,
    name: str,
    metadata: dict,
    length_mm: float,
    width_mm: str,
    width_positions_mm: str | None,
    team: str | None,
    limits: JobLimits | None = None,
) -> tuple[ItemRow, str, dict]:
    """Validate a ski upload, store its CSV and queue the network training (``team`` within
    the job ``limits``, else :class:`QuotaError`)."""
    name = check_name_free(db, "ski", name)
    _, outline, figures = check_ski_upload(
        data,
        filename,
        length_mm=length_mm,
        width_mm=width_mm,
        width_positions_mm=width_positions_mm,
    )
    meta = {
        **metadata,
        "length_mm": length_mm,
        "outline": {
            "positions_mm": [float(v * 1e3) for v in outline.positions_m],
            "width_mm": [float(v * 1e3) for v in outline.width_m],
            "balance_point_from_tail_mm": outline.balance_point_from_tail_m * 1e3,
        },
        "original_filename": Path(filename).name,
        "data": figures,
    }
    check_job_quota(db, team, limits)
    item = _add_item(db, "ski", name, meta, team)
    try:
        with atomic_path(layout.ski_csv(item.id)) as tmp:
            tmp.write_bytes(data)
        job = db.add_job(SKI_JOB, item.id, "queued: network training")
    except BaseException:
        layout.remove_item_files(item.id)
        db.delete_item(item.id)
        raise
    return item, job.id, figures


def run_ski_job(ctx: JobContext, layout: Layout, settings: Settings, on_ready) -> str:
    """Job ``ski-network``: train the camber network, check it, write the ski file."""
    from skisnow.app.storage.skis import SkiOutline, SkiRecord, read_camber_csv, read_ski, write_ski
    from skisnow.app.train_camber import (
        camber_training_arrays,
        train_camber_network,
        write_network_to_ski,
    )

    item = ctx.item
    data = read_camber_csv(layout.ski_csv(item.id))
    _, x, f, xf, h, side = camber_training_arrays(data)
    total = settings.train_ensemble * (settings.train_epochs + settings.train_lbfgs_epochs)
    calls = 0

    def progress(phase: str, epoch: int, loss_tr: float, loss_va: float) -> None:
        nonlocal calls
        calls += 1
        ctx.progress(0.95 * calls / total, f"training ({phase}, epoch {epoch})")

    ctx.progress(0.0, "training the camber network")
    result = train_camber_network(
        x,
        f,
        xf,
        h,
        epochs=settings.train_epochs,
        lbfgs_epochs=settings.train_lbfgs_epochs,
        ensemble=settings.train_ensemble,
        ski_id=item.name,
        metadata={"measured_side": side, "measurements_source": f"upload {item.id}.csv"},
        progress=progress,
    )
    m = result.metrics
    rmse_um = float(m.get("test_rmse_band_m", math.nan)) * 1e6
    limit = settings.ski_max_test_rmse_um
    figures = (
        f"held-out RMSE where H* < 0.2 mm = {rmse_um:.2f} µm on {m.get('test_n_cases', 0)} test "
        f"case(s) (limit {limit:g} µm), validation {m.get('validation_rmse_band_m', 0) * 1e6:.2f}"
        f" µm, train {m.get('train_rmse_band_m', 0) * 1e6:.2f} µm"
    )
    if not (math.isfinite(rmse_um) and rmse_um <= limit):
        raise InputError(
            f"accuracy check failed: {figures}; measure more load cases or denser positions"
        )
    ctx.check_stop()
    o = item.metadata["outline"]
    record = SkiRecord(
        measurements=data,
        outline=SkiOutline(
            length_m=float(item.metadata["length_mm"]) * 1e-3,
            balance_point_from_tail_m=float(o["balance_point_from_tail_mm"]) * 1e-3,
            positions_m=np.asarray(o["positions_mm"]) * 1e-3,
            width_m=np.asarray(o["width_mm"]) * 1e-3,
        ),
        metadata={
            k: str(v)
            for k, v in item.metadata.items()
            if k in ("brand_model", "style", "owner_team", "notes", "original_filename")
        }
        | {"description": f"uploaded ski {item.name}", "item_id": item.id},
    )
    ctx.progress(0.96, "identifying the ski's beam from its camber cases")
    record.identified, beam_note = _identify(
        data,
        item,
        lambda frac, msg: ctx.progress(0.96 + 0.03 * frac, f"identifying the ski's beam: {msg}"),
    )
    work = layout.work(item.id)
    work.mkdir(parents=True, exist_ok=True)
    staged = work / "ski.h5"
    write_ski(staged, record, parameters={"item": item.id, "name": item.name})
    write_network_to_ski(staged, result.network)
    read_ski(staged)  # verify before it enters the catalogue
    final = layout.ski_file(item.id)
    final.parent.mkdir(parents=True, exist_ok=True)
    os.replace(staged, final)
    shutil.rmtree(work, ignore_errors=True)
    ctx.progress(0.98, "drawing the ski page's figures")
    _draw_page_figures(item, final, layout)
    meta = {**item.metadata, "accuracy": {k: v for k, v in m.items() if isinstance(v, float)}}
    db_item = ctx.db.update_item(
        item.id, state="ready", file_path=str(final), sha256=sha256_file(final), metadata=meta
    )
    on_ready(db_item)
    return f"network trained; {figures}; {beam_note}"


def _draw_page_figures(item, path: Path, layout: Layout) -> None:
    """Draw the figures of the ski's page into its figure cache (:mod:`app.web.ski_figures`), so
    that its first view is fast. A failure is logged, never fails the job: the page then draws
    them on its first view."""
    from skisnow.app.storage.skis import read_ski
    from skisnow.app.web.ski_figures import ski_figures

    try:
        ski = service.Ski(item.name, path, sha256_file(path), read_ski(path))
        ski_figures(ski, layout.ski_figures(path.stem))
    except Exception as exc:  # a cache not filled must not fail the upload
        log.warning(
            "figures of ski %r not drawn in its job (%s): its page draws them", item.name, exc
        )


def _identify(data, item, callback=None) -> tuple[dict, str]:
    """Identify the beam of an uploaded ski (method.md §4c): the stored ``identified`` group and
    one sentence for the job result. A failure is recorded, never raised: the ski still works
    with the rigid model and its network. ``callback(fraction, message)``: the
    identification's progress (the job shows it; minutes on a loaded machine)."""
    from skisnow.app.path_pool import path_pool
    from skisnow.app.profiles import identification_group, served_beam_note
    from skisnow.app.storage.skis import mean_profiles
    from skisnow.solvers.identify import identify_beam_checked

    try:
        f, xf, y, note = mean_profiles(data)
        with path_pool() as pmap:
            ident, check = identify_beam_checked(
                data.positions_m, f, xf, y, callback=callback, path_map=pmap
            )
    except SkisnowError as exc:
        reason = f"beam not identified: {exc}"
        failed = {"attrs": {"ok": False, "reason": reason, **provenance({"item": item.id})}}
        return failed, reason + " (rigid model only)"
    group = identification_group(ident, check, note, f, xf, {"item": item.id}, y)
    if not ident.ok:
        return group, f"beam not identified: {ident.reason} (rigid model only)"
    if served_beam_note(group):
        return group, f"beam identified but not used: {served_beam_note(group)}"
    return group, (
        f"beam identified: misfit {ident.misfit_m * 1e6:.2f} µm against device noise "
        f"{ident.noise_m * 1e6:.2f} µm over {f.size - check['held_out_cases']} cases, "
        f"{(check['held_out_rms_m'] or 0.0) * 1e6:.2f} µm on {check['held_out_cases']} held-out "
        f"cases ({note})"
    )


def on_job_failure(ctx: JobContext, layout: Layout) -> None:
    """A failed job leaves its item ``failed`` with no files (the job row keeps the error)."""
    if ctx.item is None:
        return
    layout.remove_item_files(ctx.item.id)
    with contextlib.suppress(Exception):
        ctx.db.update_item(ctx.item.id, state="failed", file_path=None, sha256=None)


# --------------------------------------------------------------------- live catalogue


def load_live(item: ItemRow):
    """The :mod:`app.service` object of a ready item (file verified against its sha256)."""
    from skisnow.app.storage.skis import read_ski
    from skisnow.app.storage.tables import read_table

    path = Path(item.file_path)
    if not path.is_file():
        raise DataFileError(f"{item.kind} {item.name!r}: file {path} is missing")
    sha = sha256_file(path)
    if sha != item.sha256:
        raise DataFileError(f"{item.kind} {item.name!r}: {path.name} does not match its sha256")
    if item.kind == "grind":
        return service.Grind(item.name, path, sha, read_table(path))
    return service.Ski(item.name, path, sha, read_ski(path))


def _locked(method):
    def wrapper(self, *args, **kwargs):
        with self.lock:
            return method(self, *args, **kwargs)

    wrapper.__name__ = method.__name__
    wrapper.__doc__ = method.__doc__
    return wrapper


class LiveCatalogue:
    """Keeps ``app.state.catalogue`` in step with the database's ready uploaded items.

    Dicts are replaced, never mutated in place, so a request iterating over them is safe.
    """

    def __init__(self, get_catalogue: Callable[[], service.Catalogue], db: CatalogueDB) -> None:
        self._get = get_catalogue
        self.db = db
        self.lock = threading.RLock()
        # item id -> (kind, name, sha256, team)
        self.loaded: dict[str, tuple[str, str, str, str | None]] = {}

    def _dicts(self, kind: str) -> tuple[service.Catalogue, str]:
        return self._get(), "grinds" if kind == "grind" else "skis"

    @_locked
    def put(self, item: ItemRow) -> None:
        obj = load_live(item)
        cat, attr = self._dicts(item.kind)
        d = dict(getattr(cat, attr))
        old = self.loaded.get(item.id)
        if old is not None:
            d.pop(old[1], None)
        d[item.name] = obj
        setattr(cat, attr, d)
        self.loaded[item.id] = (item.kind, item.name, item.sha256, item.team)

    @_locked
    def drop(self, item_id: str) -> None:
        old = self.loaded.pop(item_id, None)
        if old is None:
            return
        cat, attr = self._dicts(old[0])
        d = dict(getattr(cat, attr))
        d.pop(old[1], None)
        setattr(cat, attr, d)

    @_locked
    def drop_all(self) -> None:
        """Take every loaded upload out of the catalogue (the service stops): the catalogue is
        the shipped one again, and a new start loads the uploads afresh."""
        for item_id in list(self.loaded):
            self.drop(item_id)

    @_locked
    def rename(self, item: ItemRow) -> None:
        old = self.loaded.get(item.id)
        if old is None:
            return
        cat, attr = self._dicts(item.kind)
        d = dict(getattr(cat, attr))
        obj = d.pop(old[1], None)
        if obj is not None:
            d[item.name] = replace(obj, name=item.name)
        setattr(cat, attr, d)
        self.loaded[item.id] = (item.kind, item.name, item.sha256, item.team)

    @_locked
    def owned_by_others(self, team: str | None) -> set[tuple[str, str]]:
        """``(kind, name)`` of the served uploads that belong to a team other than ``team``
        (items of no team belong to nobody; shipped items are never here)."""
        return {(k, n) for k, n, _, owner in self.loaded.values() if owner not in (None, team)}

    def catch_up(self, kind: str, name: str) -> bool:
        """Load ``name`` now when this process does not serve it and the database holds it
        ready (another process finished its job before this one's next poll). True when it is
        served afterwards. Costs nothing for a served name, one query for an unknown one."""
        cat, attr = self._dicts(kind)
        if name in getattr(cat, attr):
            return True
        row = self.db.item_by_name(kind, name)
        if row is None or row.state != "ready" or row.read_only:
            return False
        self.sync()
        cat, attr = self._dicts(kind)
        return name in getattr(cat, attr)

    @_locked
    def sync(self) -> None:
        """Load new ready items, drop deleted ones, follow renames (other processes too)."""
        ready = {i.id: i for i in self.db.items(state="ready") if not i.read_only}
        for item_id in list(self.loaded):
            if item_id not in ready:
                self.drop(item_id)
        for item in ready.values():
            old = self.loaded.get(item.id)
            if old == (item.kind, item.name, item.sha256, item.team):
                continue
            if old is not None and old[2] == item.sha256:
                self.rename(item)
                continue
            cat, attr = self._dicts(item.kind)
            if old is None and item.name in getattr(cat, attr):
                continue  # a shipped item of that name is served (see register_shipped)
            try:
                self.put(item)
            except SkisnowError as exc:
                log.error("cannot load %s %r: %s", item.kind, item.name, exc)


def register_shipped(db: CatalogueDB, cat: service.Catalogue) -> None:
    """Record the shipped demo items as read-only rows (names reserved, never deletable)."""
    shipped = {("grind", n): g for n, g in cat.grinds.items()}
    shipped |= {("ski", n): s for n, s in cat.skis.items()}
    for row in db.items():
        if row.read_only and (row.kind, row.name) not in shipped:
            db.delete_item(row.id)
    for (kind, name), obj in shipped.items():
        row = db.item_by_name(kind, name)
        if row is None:
            with contextlib.suppress(SkisnowError):
                db.add_item(
                    kind,
                    name,
                    metadata={"shipped": True},
                    state="ready",
                    file_path=str(obj.path),
                    sha256=obj.sha256,
                    read_only=True,
                )
        elif row.read_only:
            if row.sha256 != obj.sha256 or row.file_path != str(obj.path):
                db.update_item(row.id, file_path=str(obj.path), sha256=obj.sha256)
        else:
            log.warning(
                "uploaded %s %r has the name of a shipped one; the shipped one is served",
                kind,
                name,
            )
