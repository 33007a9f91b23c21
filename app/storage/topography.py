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
HDF5, Zygo ``MetaData``   Zygo ``.datx``                        ``SurfaceTopography``
instrument magic          ``.sur``, ``.sdf``, ``.opd``,         ``SurfaceTopography``
                          ``.al3d``, ``.frt``, ``.vk*``, …
(no magic, by extension)  ``.plu``, ``.opdx``                   ``SurfaceTopography``
``\\x93NUMPY``             raw ``.npy`` grid (no pickles)        numpy, ``allow_pickle=False``
UTF-8 text of numbers     raw ``.csv`` grid                     :mod:`.heightgrid`
========================= ===================================== =============================

Raw grids (``.npy``/``.csv``) carry no calibration: ``pixel_size_um`` and ``height_unit`` are
required for them and refused for the calibrated formats (whose own units are used).

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

import io
import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from skisnow.solvers.errors import DataFileError, InputError
from skisnow.solvers.texture import Texture, check_detrend, level_heights

from .common import NPY_READ_ERRORS
from .heightgrid import height_factor, parse_csv_grid, pixel_size_m
from .textures import (
    SCHEMA,
    SHIPPED_TEXTURES_DIR,
    detrend_texture,
    list_shipped_textures,
    read_texture,
)

__all__ = [
    "DEFAULT_MAX_FILE_BYTES",
    "DEFAULT_MAX_PIXELS",
    "DEFAULT_MAX_ZIP_MEMBERS",
    "INSTRUMENT_FORMATS",
    "RawTopography",
    "detect_format",
    "load_texture",
    "read_raw_topography",
    "read_topography",
]

#: Largest accepted grid (points) by default [-]
DEFAULT_MAX_PIXELS = 4096 * 4096
#: Largest accepted file by default [bytes]
DEFAULT_MAX_FILE_BYTES = 512 * 1024 * 1024
#: Most members of a zip container (x3p) by default [-]
DEFAULT_MAX_ZIP_MEMBERS = 64
#: Declared uncompressed bytes allowed per grid point in a zip container, plus a fixed allowance:
#: heights, two absolute coordinate arrays and validity bits as float64, or XML text of them.
_ZIP_BYTES_PER_PIXEL = 64
_ZIP_FIXED_BYTES = 16 * 1024 * 1024
#: Largest relative difference of the x and y pixel sizes accepted as square [-]
_SQUARE_TOLERANCE = 1e-3

_MAGIC_ZIP = (b"PK\x03\x04", b"PK\x05\x06")  # local header; empty archive
_MAGIC_HDF5 = b"\x89HDF\r\n\x1a\n"
_MAGIC_NPY = b"\x93NUMPY"

#: SurfaceTopography formats we accept, with their magic (offset, bytes); ``None``: no magic,
#: accepted by extension only
INSTRUMENT_FORMATS: dict[str, tuple[tuple[int, bytes], ...] | None] = {
    "sur": ((0, b"DIGITAL SURF"),),
    "sdf": ((0, b"aISO-1.0"), (0, b"bISO-1.0")),
    "opd": ((2, b"Directory"),),
    "al3d": ((0, b"AliconaImaging\x00\r\n"),),
    "frt": ((0, b"FRTM_GLIDERV"),),
    "vk": ((0, b"VK3_"), (0, b"VK4_"), (0, b"VK6"), (0, b"VK7")),
    "zon": ((0, b"KPK0"), (0, b"KPK1")),
    "os3d": ((0, b"OmniSurf3D"),),
    "tmd": ((0, b"Binary TrueMap Data File v2.0"),),
    "zmg": ((0, b"Zeta-Instruments"),),
    "metropro": ((0, b"\x88\x1b\x03o"), (0, b"\x88\x1b\x03p"), (0, b"\x88\x1b\x03q")),
    "gwy": ((0, b"GWYP"),),
    "datx": None,  # HDF5, recognised by its content (see detect_format)
    "plu": None,
    "opdx": None,
}
_EXTENSION_ONLY = {".plu": "plu", ".apx": "plu", ".opdx": "opdx"}


@dataclass
class RawTopography:
    """A height map as read, before levelling.

    Attributes
    ----------
    heights_m : numpy.ndarray
        Heights [m], 2-D float64, axis 0 = the file's x axis, NaN where not measured.
    pixel_size_m : float
        Pixel size [m] (square pixels).
    format : str
        Detected format ("x3p", "sur", "datx", "npy", "csv", ...).
    details : str
        What the reader found (revision, channel, unit), for the texture's ``source``.
    texture : Texture, optional
        The texture itself when the file is a skisnow texture (already levelled; kept as is).
    """

    heights_m: np.ndarray
    pixel_size_m: float
    format: str
    details: str = ""
    texture: Texture | None = None


# --------------------------------------------------------------------------- detection


def detect_format(head: bytes, *, suffix: str = "") -> str:
    """Format of a file from its first bytes (at least 512 if the file has them).

    Returns "zip", "hdf5", "npy", "csv", one of :data:`INSTRUMENT_FORMATS`, or raises.
    Containers ("zip", "hdf5") are resolved by :func:`read_raw_topography` from their content.
    ``suffix`` (e.g. ".plu") is used only for formats without a magic number.

    Raises
    ------
    DataFileError
        Empty file, or content that matches no accepted format.
    """
    if not head:
        raise DataFileError("the file is empty")
    if head.startswith(_MAGIC_ZIP):
        return "zip"
    if head.startswith(_MAGIC_HDF5):
        return "hdf5"
    if head.startswith(_MAGIC_NPY):
        return "npy"
    for fmt, magics in INSTRUMENT_FORMATS.items():
        for offset, magic in magics or ():
            if head[offset : offset + len(magic)] == magic:
                return fmt
    if _looks_like_number_text(head):
        return "csv"
    fmt = _EXTENSION_ONLY.get(suffix.lower())
    if fmt is not None:
        return fmt
    if head.startswith((b"\x80", b"(dp", b"cnumpy")):
        raise DataFileError("the file looks like a Python pickle; pickles are never loaded")
    raise DataFileError(
        "unknown content: not x3p (zip), Zygo datx (HDF5), npy, csv, nor an instrument format "
        f"with a known signature ({', '.join(f for f, m in INSTRUMENT_FORMATS.items() if m)}); "
        ".plu and .opdx files are recognised by their extension"
    )


def _looks_like_number_text(head: bytes) -> bool:
    try:
        text = head.decode("utf-8-sig")
    except UnicodeDecodeError:
        # the buffer may end inside a multi-byte character
        try:
            text = head[:-3].decode("utf-8-sig")
        except UnicodeDecodeError:
            return False
    if "\x00" in text:
        return False
    allowed = set("0123456789+-.eEnaNAinfINF,;\t \r\n#")
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        return text.strip().startswith("#")
    body = lines[0] if len(lines) == 1 else "\n".join(lines[:-1])  # the last may be cut short
    return set(body) <= allowed and any(c.isdigit() for c in body)


# --------------------------------------------------------------------------- limits


def _check_grid_size(shape, max_pixels: int, min_side: int, label: str) -> None:
    shape = tuple(int(s) for s in shape)
    if len(shape) != 2:
        raise InputError(f"{label}: a 2-D height map is needed, got {len(shape)}-D {shape}")
    n = shape[0] * shape[1]
    if n > max_pixels:
        raise InputError(
            f"{label}: grid {shape[0]} x {shape[1]} = {n} points is larger than the limit "
            f"max_pixels={max_pixels}; crop or resample the map"
        )
    if min(shape) < min_side:
        raise InputError(
            f"{label}: grid {shape[0]} x {shape[1]} is too small; at least {min_side} points "
            "are needed along each axis"
        )


def _check_zip(data: bytes, label: str, max_members: int, max_uncompressed: int) -> set[str]:
    """Inspect a zip's central directory before anything is extracted; return member names."""
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
    except (zipfile.BadZipFile, OSError, ValueError) as exc:
        raise DataFileError(f"{label}: damaged or truncated zip container: {exc}") from None
    with zf:
        infos = zf.infolist()
        if len(infos) > max_members:
            raise InputError(
                f"{label}: zip container holds {len(infos)} members, more than the limit "
                f"{max_members}"
            )
        total = sum(i.file_size for i in infos)
        if total > max_uncompressed:
            raise InputError(
                f"{label}: zip container would unpack to {total} bytes, more than the limit "
                f"{max_uncompressed} bytes (zip bomb?)"
            )
        if any(i.flag_bits & 0x1 for i in infos):
            raise InputError(f"{label}: zip container holds encrypted members")
        return {i.filename.replace("\\", "/") for i in infos}


# --------------------------------------------------------------------------- readers


def _read_x3p(data: bytes, label: str, max_pixels: int, min_side: int) -> RawTopography:
    try:
        import x3pio
    except ImportError as exc:  # pragma: no cover - a main dependency
        raise DataFileError(f"{label}: reading x3p needs the x3pio package: {exc}") from None
    try:
        info = x3pio.info(io.BytesIO(data))
    except (x3pio.X3pError, ValueError, OSError, EOFError) as exc:
        raise DataFileError(f"{label}: not a readable x3p file: {exc}") from None
    if info.feature_type != x3pio.FeatureType.SURFACE:
        raise InputError(
            f"{label}: x3p file holds a {info.feature_type.name.lower()}, not a surface (SUR)"
        )
    _check_grid_size(info.shape, max_pixels, min_side, label)
    try:
        surface = x3pio.read(io.BytesIO(data))
    except (x3pio.X3pError, ValueError, OSError, EOFError) as exc:
        raise DataFileError(f"{label}: damaged x3p file: {exc}") from None
    if not surface.is_regular_grid:
        raise InputError(f"{label}: x3p surface is not on a regular grid (absolute x/y axes)")
    layer = surface.layers[0]
    dx, dy = layer.spacing  # [m]
    z = np.asarray(layer.z, dtype=np.float64)  # (rows, columns) = (y, x)
    details = f"x3p revision {surface.revision.name}"
    if len(surface.layers) > 1:
        details += f", layer 1 of {len(surface.layers)}"
    return RawTopography(z.T.copy(), _square_pixel(dx, dy, label), "x3p", details)


def _read_surfacetopography(
    data: bytes, fmt: str, label: str, max_pixels: int, min_side: int, channel: int | None
) -> RawTopography:
    try:
        from SurfaceTopography.IO import open_topography
        from SurfaceTopography.Support.UnitConversion import get_unit_conversion_factor
    except ImportError as exc:  # pragma: no cover - a main dependency
        raise DataFileError(
            f"{label}: reading {fmt} needs the SurfaceTopography package: {exc}"
        ) from None
    try:
        reader = open_topography(io.BytesIO(data), format=fmt)
    except Exception as exc:  # third-party parser: any failure means a bad file
        raise DataFileError(f"{label}: not a readable {fmt} file: {exc}") from None
    try:
        channels = reader.height_channels or reader.channels
        if not channels:
            raise InputError(f"{label}: {fmt} file holds no height channel")
        if channel is None:
            info = reader.default_channel
        elif 0 <= channel < len(reader.channels):
            info = reader.channels[channel]
        else:
            raise InputError(
                f"{label}: channel {channel} does not exist; the file has "
                f"{len(reader.channels)} channel(s) (0-based)"
            )
        if info.dim != 2:
            raise InputError(f"{label}: channel {info.name!r} is a {info.dim}-D line scan")
        _check_grid_size(info.nb_grid_pts, max_pixels, min_side, label)
        try:
            top = reader.topography(channel_index=info.index)
        except Exception as exc:  # third-party parser
            raise DataFileError(f"{label}: damaged {fmt} file: {exc}") from None
        if not top.is_uniform:
            raise InputError(f"{label}: {fmt} channel is not on a uniform grid")
        unit = top.unit
        factor = get_unit_conversion_factor(unit, "m") if unit else None
        if factor is None:
            raise InputError(f"{label}: {fmt} file has no length unit for its heights ({unit!r})")
        heights = top.heights()  # (nx, ny): x along axis 0
        if np.ma.isMaskedArray(heights):
            heights = heights.astype(np.float64).filled(np.nan)
        heights = np.asarray(heights, dtype=np.float64) * factor
        dx, dy = (float(v) * factor for v in top.pixel_size)
    finally:
        try:
            reader.close()
        except Exception:  # pragma: no cover - closing a BytesIO-backed reader
            pass
    details = f"{fmt} channel {info.index} {info.name!r}, unit {unit}"
    return RawTopography(heights, _square_pixel(dx, dy, label), fmt, details)


def _square_pixel(dx: float, dy: float, label: str) -> float:
    if not (np.isfinite(dx) and np.isfinite(dy) and dx > 0 and dy > 0):
        raise InputError(f"{label}: pixel sizes must be finite and > 0, got {dx!r}, {dy!r} m")
    if abs(dx - dy) > _SQUARE_TOLERANCE * max(dx, dy):
        raise InputError(
            f"{label}: pixels are not square (dx = {dx * 1e6:.6g} µm, dy = {dy * 1e6:.6g} µm); "
            "resample the map to one pixel size first"
        )
    return 0.5 * (dx + dy)


def npy_header(fh, label: str) -> tuple[tuple[int, ...], np.dtype]:
    """Shape and dtype declared in a ``.npy`` header, read before any array is allocated.

    Raises
    ------
    DataFileError
        Not a readable ``.npy`` header.
    """
    try:
        version = np.lib.format.read_magic(fh)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(fh)
        else:
            shape, _, dtype = np.lib.format.read_array_header_2_0(fh)
    except NPY_READ_ERRORS as exc:
        raise DataFileError(f"{label}: damaged npy header: {exc}") from None
    return tuple(int(v) for v in shape), dtype


def _read_npy(data: bytes, label: str, max_pixels: int, min_side: int) -> np.ndarray:
    shape, dtype = npy_header(io.BytesIO(data), label)
    if dtype.hasobject:
        raise InputError(f"{label}: npy holds Python objects; pickles are never loaded")
    if not np.issubdtype(dtype, np.number) or np.issubdtype(dtype, np.complexfloating):
        raise InputError(f"{label}: npy holds {dtype} values, not real numbers")
    _check_grid_size(shape, max_pixels, min_side, label)
    try:
        arr = np.load(io.BytesIO(data), allow_pickle=False)
    except NPY_READ_ERRORS as exc:
        raise DataFileError(f"{label}: damaged or truncated npy file: {exc}") from None
    return np.asarray(arr, dtype=np.float64)


def _read_csv(data: bytes, label: str, max_pixels: int, min_side: int) -> np.ndarray:
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise DataFileError(f"{label}: csv is not UTF-8 text: {exc}") from None
    arr = parse_csv_grid(text, label)
    _check_grid_size(arr.shape, max_pixels, min_side, label)
    return arr


def _raw_grid(arr: np.ndarray, fmt: str, label: str, pixel_size_um, height_unit) -> RawTopography:
    missing = [
        n for n, v in (("pixel_size_um", pixel_size_um), ("height_unit", height_unit)) if v is None
    ]
    if missing:
        raise InputError(
            f"{label} is a raw {fmt} height grid without calibration: "
            f"{' and '.join(missing)} must be given"
        )
    factor = height_factor(height_unit)
    return RawTopography(
        arr * factor, pixel_size_m(pixel_size_um), fmt, f"raw {fmt}, heights in {height_unit}"
    )


def _hdf5_kind(data: bytes, label: str) -> str:
    import h5py

    try:
        with h5py.File(io.BytesIO(data), "r") as f:
            schema = f.attrs.get("schema")
            if isinstance(schema, bytes):
                schema = schema.decode(errors="replace")
            if schema == SCHEMA:
                return "texture"
            if "MetaData" in f:
                return "datx"
    except (OSError, ValueError) as exc:
        raise DataFileError(f"{label}: damaged or truncated HDF5 file: {exc}") from None
    raise DataFileError(
        f"{label}: HDF5 file is neither a skisnow texture ({SCHEMA}) nor a Zygo datx file"
    )


# --------------------------------------------------------------------------- entry points


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
        arr = _read_csv(data, label, max_pixels, min_side)
        return _raw_grid(arr, "csv", label, pixel_size_um, height_unit)
    # a calibrated instrument format: its own units are used
    given = [n for n, v in (("pixel_size_um", pixel_size_um), ("height_unit", height_unit)) if v]
    if given:
        raise InputError(
            f"{label}: {fmt} files carry their own calibration; do not give {' or '.join(given)}"
        )
    return _read_surfacetopography(data, fmt, label, max_pixels, min_side, channel)


def read_topography(
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
    max_missing_fraction: float = 0.5,
    detrend: str | None = None,
) -> Texture:
    """Read a measured (or raw) height map, convert it to metres, detrend it, return a Texture.

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
        Largest fraction of non-measured points [-] (see :func:`solvers.texture.level_heights`).
    detrend : str, optional
        What is removed from the heights (:func:`solvers.texture.level_heights`): "plane"
        (the least-squares plane; the default for measured maps), "mean" (for maps that are
        periodic: a plane fit would tilt them and put a step at the wrap) or "none". A skisnow
        texture file is kept as stored unless ``detrend`` is given
        (:func:`app.storage.textures.detrend_texture`).

    Returns
    -------
    Texture
        Detrended, filled heights [m] with axis 0 along the ski, the pixel size [m], a
        ``source`` naming the file, its format and sha256, and the ``detrend`` applied.

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
        return detrend_texture(tex, detrend)
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
        levelled, missing = level_heights(
            heights,
            raw.pixel_size_m,
            detrend=detrend,
            max_missing_fraction=max_missing_fraction,
        )
    except InputError as exc:
        raise InputError(f"{label}: {exc}") from None
    source_text = f"{file_name or 'upload'} ({raw.details}; sha256 {digest})"
    if along_ski == "y":
        source_text += "; transposed: file y along the ski"
    return Texture(levelled, raw.pixel_size_m, stem, missing, source_text, detrend)


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
