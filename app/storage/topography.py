"""Measured topography files in: format detected by content, heights in metres, one Texture out.

:func:`read_topography` is the single entry for every height map a user gives us, from the
command line (a path) or from an upload (bytes). It never trusts the file name: the format is
decided by the first bytes (and, for zip and HDF5 containers, by what the container holds); the
name's extension is consulted only for the instrument formats that have no magic number
(``.plu``, ``.opdx``), and only when the content matches no other format.

========================= ===================================== =============================
content                   format                                read by
========================= ===================================== =============================
zip with ``main.xml``     ISO 25178-72 x3p (ISO 5436-2000 and   ``x3pio`` (both revisions)
                          the newer Amd 1:2020 revision)
HDF5, ``skisnow`` schema  our texture file (paths only)         :func:`.textures.read_texture`
instrument magic          ``.sur``, ``.sdf``, ``.al3d``,        ``SurfaceTopography``
                          ``.frt``, MetroPro ``.dat``, ``.tmd``
                          (``height_unit`` required)
(no magic, by extension)  ``.plu``                              ``SurfaceTopography``
``\\x93NUMPY``             raw ``.npy`` grid (no pickles)        numpy, ``allow_pickle=False``
UTF-8/16 text of numbers  text grid, Wyko/Gwyddion matrix with  :mod:`.heightgrid`
                          its header, x y z list on a grid
========================= ===================================== =============================

Each format read is pinned by a real file (tests/storage/test_real_files.py). Formats
SurfaceTopography reads but no real file has proven here (``.datx``, ``.opd``, ``.opdx``,
``.vk*``, ``.zon``, ``.os3d``, ``.zmg``, ``.gwy``) are recognised and refused
(``topography_formats.PROVEN_FORMATS``); line scans are refused as line scans.

Files without calibration (``.npy``, a plain text grid) need ``pixel_size_um`` and
``height_unit``; calibrated formats refuse them (their own units are used), and a text header
refuses what it gives. An x y z list needs ``height_unit`` (of x, y and z); a TrueMap
``.tmd`` states no unit and needs ``height_unit`` for its lengths and heights.

Unmeasured points: :func:`solvers.measured.prepare_measured_map` (the plane fitted to the
measured points, ISO parameters on them, the solver's map cropped to the largest
well-measured rectangle with small holes filled; docs/topography.md).

Axis order. skisnow's textures have axis 0 along the ski (x) and axis 1 across it (y)
(:mod:`solvers.texture`). The libraries differ:

- ``x3pio`` returns ``z`` shaped ``(rows, columns)`` = ``(SizeY, SizeX)``: x runs along the
  columns (axis 1). We transpose it.
- ``SurfaceTopography`` returns ``heights()`` shaped ``(nx, ny)``: x runs along axis 0 (its
  readers transpose the row-major instrument data). We keep it.
- raw ``.npy``/``.csv`` grids are taken as they are: axis 0 is x.

So after reading, axis 0 is the file's x axis for every format. ``along_ski="y"`` transposes
the map when the sample was measured with the ski's length along the instrument's y axis.

Limits and safety (uploads go through the same function): the file size is capped before it is
read; a zip container is inspected from its central directory *before* anything is extracted
(member count, total declared uncompressed size, no encryption; the readers stop at the
declared size); the grid size is checked from the header before the heights are decoded
(``max_pixels``, ``min_side``); files are parsed, never executed or unpickled. Every failure is
an :class:`~solvers.errors.InputError` (a readable file whose content we refuse) or a
:class:`~solvers.errors.DataFileError` (unreadable, truncated, corrupt, unknown format), with
the file named in the message.

Pixels must be square (the texture model has one pixel size); maps whose x and y spacings
differ by more than 0.1 % are refused, not resampled.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from skisnow.solvers.errors import DataFileError, InputError
from skisnow.solvers.measured import MIN_KEPT_FRACTION, PreparedMap, prepare_measured_map
from skisnow.solvers.texture import Texture, check_detrend

from .textures import (
    SHIPPED_TEXTURES_DIR,
    detrend_texture,
    list_shipped_textures,
    read_texture,
)
from .topography_formats import (
    _ZIP_BYTES_PER_PIXEL,
    _ZIP_FIXED_BYTES,
    DEFAULT_MAX_FILE_BYTES,
    DEFAULT_MAX_PIXELS,
    DEFAULT_MAX_ZIP_MEMBERS,
    INSTRUMENT_FORMATS,
    RawTopography,
    _check_grid_size,
    _check_zip,
    _hdf5_kind,
    _raw_grid,
    _read_csv,
    _read_npy,
    _read_surfacetopography,
    _read_x3p,
    _text_grid,
    detect_format,
)

#: formats without calibration: pixel size and height unit come from the user
_RAW_FORMATS = ("npy", "csv")
#: calibrated formats whose unit is not in the file: height_unit required (lengths and heights)
_UNITLESS_FORMATS = ("tmd",)


@dataclass
class MeasuredTopography:
    """A height map file read for the solver (:func:`read_measured_topography`).

    Attributes
    ----------
    texture : Texture
        The solver's map [m] (the kept rectangle, small holes filled, detrended).
    prepared : PreparedMap or None
        What was done to the measured points (``None``: a skisnow texture file, kept as is).
    notes : list of str
        What the reader skipped or converted (header lines, a row of positions).
    """

    texture: Texture
    prepared: PreparedMap | None
    notes: list[str] = field(default_factory=list)


__all__ = [
    "DEFAULT_MAX_FILE_BYTES",
    "DEFAULT_MAX_PIXELS",
    "DEFAULT_MAX_ZIP_MEMBERS",
    "INSTRUMENT_FORMATS",
    "MeasuredTopography",
    "RawTopography",
    "detect_format",
    "load_texture",
    "read_measured_topography",
    "read_raw_topography",
    "read_topography",
]


def _load_bytes(
    source, name: str | None, max_file_bytes: int
) -> tuple[bytes, str, str, Path | None]:
    """(content, label, suffix, path or None) of a path or an in-memory file."""
    if isinstance(source, bytes | bytearray | memoryview):
        data = bytes(source)
        label = name or "uploaded file"
        if len(data) > max_file_bytes:
            raise InputError(
                f"{label}: {len(data)} bytes is larger than the limit {max_file_bytes} bytes"
            )
        return data, label, Path(name or "").suffix, None
    path = Path(os.fspath(source))
    label = f"height map {path}"
    if not path.is_file():
        raise DataFileError(f"{label} does not exist")
    size = path.stat().st_size
    if size > max_file_bytes:
        raise InputError(f"{label}: {size} bytes is larger than the limit {max_file_bytes} bytes")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise DataFileError(f"cannot read {label}: {exc}") from None
    return data, label, path.suffix, path


def read_raw_topography(
    source,
    *,
    name: str | None = None,
    pixel_size_um: float | None = None,
    height_unit: str | None = None,
    channel: int | None = None,
    max_pixels: int = DEFAULT_MAX_PIXELS,
    min_side: int = 2,
    max_file_bytes: int = DEFAULT_MAX_FILE_BYTES,
    max_zip_members: int = DEFAULT_MAX_ZIP_MEMBERS,
    max_uncompressed_bytes: int | None = None,
) -> RawTopography:
    """Read a height map of any accepted format, unlevelled; see :func:`read_topography`."""
    data, label, suffix, path = _load_bytes(source, name, max_file_bytes)
    fmt = detect_format(data[:512], suffix=suffix)
    if fmt in _UNITLESS_FORMATS:
        if pixel_size_um is not None:
            raise InputError(
                f"{label}: {fmt} files give their own pixel size; do not give pixel_size_um"
            )
        if height_unit is None:
            raise InputError(
                f"{label}: TrueMap .{fmt} files do not state their unit (SurfaceTopography "
                "1.27 reads them in mm, later versions in µm): height_unit must be given, the "
                "unit of the file's lengths and heights (mm or um)"
            )
        return _read_surfacetopography(
            data, fmt, label, max_pixels, min_side, channel, unit=height_unit
        )
    if fmt not in _RAW_FORMATS:
        # a calibrated format (x3p, datx, a texture, an instrument file): its own units are used
        given = [
            n for n, v in (("pixel_size_um", pixel_size_um), ("height_unit", height_unit)) if v
        ]
        if given:
            what = {"zip": "x3p", "hdf5": "HDF5 (datx or texture)"}.get(fmt, fmt)
            raise InputError(
                f"{label}: {what} files carry their own calibration; do not give "
                f"{' or '.join(given)}"
            )
    if fmt == "zip":
        cap = max_uncompressed_bytes
        if cap is None:
            cap = _ZIP_FIXED_BYTES + _ZIP_BYTES_PER_PIXEL * max_pixels
        members = _check_zip(data, label, max_zip_members, cap)
        if "main.xml" in members or any(
            m.count("/") == 1 and m.endswith("/main.xml") for m in members
        ):
            return _read_x3p(data, label, max_pixels, min_side)
        raise DataFileError(f"{label}: zip archive without main.xml, not an x3p file")
    if fmt == "hdf5":
        kind = _hdf5_kind(data, label)
        if kind == "datx":
            return _read_surfacetopography(data, "datx", label, max_pixels, min_side, channel)
        if path is None:
            raise InputError(f"{label}: skisnow texture files are accepted from disk only")
        tex = read_texture(path)
        _check_grid_size(tex.heights_m.shape, max_pixels, min_side, label)
        return RawTopography(tex.heights_m, tex.pixel_size_m, "texture", tex.source, tex)
    if fmt == "npy":
        arr = _read_npy(data, label, max_pixels, min_side)
        return _raw_grid(arr, "npy", label, pixel_size_um, height_unit)
    if fmt == "csv":
        parsed = _read_csv(data, label, max_pixels, min_side)
        return _text_grid(parsed, label, pixel_size_um, height_unit)
    return _read_surfacetopography(data, fmt, label, max_pixels, min_side, channel)


def read_measured_topography(
    source,
    *,
    name: str | None = None,
    pixel_size_um: float | None = None,
    height_unit: str | None = None,
    along_ski: str = "x",
    channel: int | None = None,
    max_pixels: int = DEFAULT_MAX_PIXELS,
    min_side: int = 2,
    max_file_bytes: int = DEFAULT_MAX_FILE_BYTES,
    max_zip_members: int = DEFAULT_MAX_ZIP_MEMBERS,
    max_uncompressed_bytes: int | None = None,
    max_missing_fraction: float = 1 - MIN_KEPT_FRACTION,
    detrend: str | None = None,
) -> MeasuredTopography:
    """Read a measured (or raw) height map, convert it to metres, level it on its measured
    points, make the solver's map (:func:`solvers.measured.prepare_measured_map`: crop to the
    largest well-measured rectangle, fill small holes only) and say what was done.

    Parameters
    ----------
    source : str, os.PathLike or bytes
        A file path, or the file's content (an upload).
    name : str, optional
        For bytes: the original file name (its stem names the texture, its extension is used
        only for formats without a magic number). Paths are named by their stem.
    pixel_size_um : float, optional
        Pixel size [µm] of a raw ``.npy``/``.csv`` grid (required there, refused otherwise).
    height_unit : str, optional
        Height unit of a raw grid: "m", "mm", "um"/"µm", "nm" (required there, refused
        otherwise).
    along_ski : str
        Which axis of the file runs along the ski: "x" (default; the file's x axis becomes
        axis 0) or "y" (the map is transposed).
    channel : int, optional
        0-based channel of a multi-channel instrument file (default: its default channel).
    max_pixels : int
        Largest accepted grid [points]; checked from the header before decoding.
    min_side : int
        Fewest points along each axis [-] (>= 2).
    max_file_bytes : int
        Largest accepted file [bytes].
    max_zip_members : int
        Most members of a zip container [-].
    max_uncompressed_bytes : int, optional
        Largest total declared uncompressed size of a zip container [bytes]; default
        16 MiB + 64 bytes per allowed point.
    max_missing_fraction : float
        Largest share of the map outside the kept rectangle [-] (the rectangle must hold at
        least ``1 - max_missing_fraction`` of the points).
    detrend : str, optional
        What is removed from the heights (:func:`solvers.texture.level_heights`): "plane"
        (the least-squares plane; the default for measured maps), "mean" (for maps that are
        periodic: a plane fit would tilt them and put a step at the wrap) or "none". A skisnow
        texture file is kept as stored unless ``detrend`` is given
        (:func:`app.storage.textures.detrend_texture`).

    Returns
    -------
    MeasuredTopography
        ``texture``: detrended heights [m] of the kept rectangle with axis 0 along the ski,
        the pixel size [m], a ``source`` naming the file, its format and sha256, and the
        ``detrend`` applied; ``prepared``: the record of the preparation (ISO 25178 on the
        measured points, points cut and filled, Sq moved; ``None`` for a skisnow texture);
        ``notes``: what the reader skipped.

    Raises
    ------
    InputError
        Refused content: too large or too small a grid, a zip bomb, non-square pixels, a
        profile or point cloud, missing or superfluous calibration, an all-NaN or flat map,
        an unknown ``detrend``.
    DataFileError
        Missing, empty, truncated or corrupt file, or content of no accepted format.
    """
    import hashlib

    if along_ski not in ("x", "y"):
        raise InputError(f"along_ski must be 'x' or 'y', got {along_ski!r}")
    if detrend is not None:
        check_detrend(detrend)
    try:
        max_pixels = int(max_pixels)
        min_side = max(2, int(min_side))
    except (TypeError, ValueError):
        raise InputError(f"max_pixels and min_side must be integers, got {max_pixels!r}") from None
    raw = read_raw_topography(
        source,
        name=name,
        pixel_size_um=pixel_size_um,
        height_unit=height_unit,
        channel=channel,
        max_pixels=max_pixels,
        min_side=min_side,
        max_file_bytes=max_file_bytes,
        max_zip_members=max_zip_members,
        max_uncompressed_bytes=max_uncompressed_bytes,
    )
    if raw.texture is not None:  # a skisnow texture file: detrended when written, kept as is
        tex = raw.texture
        if along_ski == "y":
            tex = Texture(
                tex.heights_m.T.copy(),
                tex.pixel_size_m,
                tex.name,
                tex.missing_fraction,
                tex.source + "; transposed: file y along the ski",
                tex.detrend,
            )
        return MeasuredTopography(detrend_texture(tex, detrend), None, list(raw.notes))
    if isinstance(source, bytes | bytearray | memoryview):
        digest = hashlib.sha256(bytes(source)).hexdigest()
        label, stem, file_name = name or "uploaded file", Path(name or "upload").stem, name
    else:
        path = Path(os.fspath(source))
        with open(path, "rb") as fh:
            digest = hashlib.file_digest(fh, "sha256").hexdigest()
        label, stem, file_name = f"height map {path}", path.stem, path.name
    heights = raw.heights_m if along_ski == "x" else raw.heights_m.T
    if not np.isfinite(heights).any():
        raise InputError(f"{label}: no valid point (every height is NaN)")
    detrend = "plane" if detrend is None else detrend
    try:
        prepared = prepare_measured_map(
            heights,
            raw.pixel_size_m,
            detrend=detrend,
            min_kept_fraction=1 - float(max_missing_fraction),
            min_side=min_side,
        )
    except InputError as exc:
        raise InputError(f"{label}: {exc}") from None
    source_text = f"{file_name or 'upload'} ({raw.details}; sha256 {digest})"
    if along_ski == "y":
        source_text += "; transposed: file y along the ski"
    r0, r1, c0, c1 = prepared.crop
    if prepared.cut_points:
        source_text += f"; kept rows {r0}-{r1}, columns {c0}-{c1}"
    if prepared.filled_points:
        source_text += f"; {prepared.filled_points} points in small holes filled"
    missing = prepared.filled_points / prepared.heights_m.size
    texture = Texture(prepared.heights_m, raw.pixel_size_m, stem, missing, source_text, detrend)
    return MeasuredTopography(texture, prepared, list(raw.notes))


def read_topography(source, **options) -> Texture:
    """The solver's texture of a height map file: :func:`read_measured_topography`'s
    ``texture`` (same arguments)."""
    return read_measured_topography(source, **options).texture


def load_texture(
    spec: str | os.PathLike,
    *,
    pixel_size_um: float | None = None,
    height_unit: str | None = None,
    detrend: str | None = None,
    **topography_options,
) -> Texture:
    """Texture from a shipped name or a height map file of any format
    :func:`read_topography` accepts (detected by content: x3p,
    instrument formats, ``.h5`` texture, raw ``.npy``/``.csv``).

    Parameters
    ----------
    spec : str or os.PathLike
        Shipped name (see :func:`list_shipped_textures`, e.g. "grind-1") or a file path.
    pixel_size_um : float, optional
        Pixel size of a raw map [µm]; required for ``.npy``/``.csv``.
    height_unit : str, optional
        Height unit of a raw map ("m", "mm", "um", "nm"); required for ``.npy``/``.csv``.
    detrend : str, optional
        "plane", "mean" or "none" (:func:`solvers.texture.level_heights`). ``None``: "plane"
        for a raw or measured map; a texture (shipped name or ``.h5``) is kept as stored. A
        texture given a ``detrend`` has it applied to its stored heights; its
        :attr:`Texture.detrend` is then the combination of both
        (:func:`solvers.texture.combined_detrend`).
    **topography_options
        ``along_ski``, ``channel``, ``max_pixels``, ... of
        :func:`read_topography`.
    """
    spec_str = os.fspath(spec)
    shipped = list_shipped_textures()
    if detrend is not None:
        check_detrend(detrend)
    if spec_str in shipped:
        return detrend_texture(read_texture(SHIPPED_TEXTURES_DIR / f"{spec_str}.h5"), detrend)
    if not Path(spec_str).is_file():
        raise InputError(
            f"unknown texture {spec_str!r}: give a shipped name ({', '.join(shipped) or 'none'}) "
            "or a height map file (.x3p, .sur, .datx, .plu, .opd, ..., texture .h5, .npy, .csv)"
        )
    # the format is decided by the content (app.storage.topography), not by the file name
    return read_topography(
        spec_str,
        pixel_size_um=pixel_size_um,
        height_unit=height_unit,
        detrend=detrend,
        **topography_options,
    )
