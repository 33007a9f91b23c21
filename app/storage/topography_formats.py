"""The readers behind :func:`app.storage.topography.read_topography`: format detection by
content, the size and safety checks that run before heights are decoded, and one reader per
format (x3p, the instrument formats of SurfaceTopography, raw ``.npy``/``.csv``, our texture
files). See :mod:`app.storage.topography` for the table of formats and the rules.
"""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass, field

import numpy as np
from skisnow.solvers.errors import DataFileError, InputError
from skisnow.solvers.texture import Texture

from .common import NPY_READ_ERRORS
from .heightgrid import TextTopography, height_factor, parse_text_topography, pixel_size_m
from .textures import (
    SCHEMA,
)

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
    # TrueMap .tmd states no unit: its lengths and heights are read in the user's height_unit
    "plu": None,
    "opdx": None,
}
#: Instrument formats whose reading is pinned by a real file in tests/data/topography
#: (tests/storage/test_real_files.py): grid, pixel size and Sq. The others are recognised and
#: refused (no real file has proven skisnow's reading of them).
PROVEN_FORMATS = ("sur", "sdf", "al3d", "frt", "tmd", "metropro", "plu")
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
    notes : list of str
        What the reader skipped or converted (header lines, a row of positions), for the answer.
    """

    heights_m: np.ndarray
    pixel_size_m: float
    format: str
    details: str = ""
    texture: Texture | None = None
    notes: list[str] = field(default_factory=list)


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


def _decode_text(head: bytes) -> str | None:
    """Text of a file head (UTF-16 with a byte-order mark, else UTF-8), or None if binary."""
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        codec, cut = "utf-16", 2
    else:
        codec, cut = "utf-8-sig", 3
    try:
        text = head.decode(codec)
    except UnicodeDecodeError:
        # the buffer may end inside a multi-byte character
        try:
            text = head[:-cut].decode(codec)
        except UnicodeDecodeError:
            return None
    return None if "\x00" in text else text


def _looks_like_number_text(head: bytes) -> bool:
    """Numbers as text, after at most 20 header lines (``#`` comments, ``key=value``, names)."""
    text = _decode_text(head)
    if text is None:
        return False
    allowed = set("0123456789+-.eEnaNAinfINF,;\t \r\n#")
    lines = [ln for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    if not lines:
        return text.strip().startswith("#")
    skipped = 0
    while lines and skipped < 20 and not (set(lines[0]) <= allowed):
        lines, skipped = lines[1:], skipped + 1
    if not lines:
        return False
    body = lines if len(lines) == 1 else lines[:-1]  # the last may be cut short
    joined = "\n".join(body)
    return set(joined) <= allowed and any(c.isdigit() for c in joined)


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
    if info.feature_type == x3pio.FeatureType.PROFILE:
        raise InputError(f"{label}: x3p file holds a profile, a line scan: a grind needs a 2-D map")
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
    data: bytes,
    fmt: str,
    label: str,
    max_pixels: int,
    min_side: int,
    channel: int | None,
    unit: str | None = None,
) -> RawTopography:
    """Read an instrument file with SurfaceTopography. ``unit`` (a :data:`HEIGHT_UNITS` key):
    the unit of the file's numbers, for formats that do not state it (TrueMap ``.tmd``), in
    place of the one the library assumes."""
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
            raise InputError(
                f"{label}: channel {info.name!r} is a line scan ({info.dim}-D): a grind needs "
                "a 2-D map"
            )
        if fmt not in PROVEN_FORMATS:
            raise InputError(
                f"{label}: a {fmt} file is recognised but not read: no real {fmt} file has "
                "proven skisnow's reading of it (grid, pixel size, height unit); export the map "
                f"as x3p, or as one of {', '.join(PROVEN_FORMATS)}"
            )
        _check_grid_size(info.nb_grid_pts, max_pixels, min_side, label)
        try:
            top = reader.topography(channel_index=info.index)
        except Exception as exc:  # third-party parser
            raise DataFileError(f"{label}: damaged {fmt} file: {exc}") from None
        if not top.is_uniform:
            raise InputError(f"{label}: {fmt} channel is not on a uniform grid")
        library_unit = top.unit
        if unit is not None:  # the user's unit for a format that states none
            factor, unit = (
                height_factor(unit),
                f"{unit} (given; the library assumed {library_unit})",
            )
        else:
            unit = library_unit
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


def _read_csv(data: bytes, label: str, max_pixels: int, min_side: int) -> TextTopography:
    text = _decode_text(data)
    if text is None:
        raise DataFileError(f"{label}: text file is neither UTF-8 nor UTF-16")
    parsed = parse_text_topography(text, label)
    _check_grid_size(parsed.values.shape, max_pixels, min_side, label)
    return parsed


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


def _text_grid(parsed: TextTopography, label: str, pixel_size_um, height_unit) -> RawTopography:
    """Calibrate a parsed text file: what its header gives is refused from the user, what it
    lacks must be given."""
    notes = list(parsed.notes)
    if parsed.kind == "xyz":
        if pixel_size_um is not None:
            raise InputError(
                f"{label}: an x y z point list gives its own pixel size (the x/y spacing); do "
                "not give pixel_size_um"
            )
        if height_unit is None:
            raise InputError(
                f"{label}: an x y z point list without units: height_unit (the unit of x, y "
                "and z) must be given"
            )
        factor = height_factor(height_unit)
        px = parsed.spacing * factor
        details = f"x y z point list, x y z in {height_unit}"
        return RawTopography(parsed.values * factor, px, "xyz", details, notes=notes)
    from_file = [
        n
        for n, v, f in (
            ("pixel_size_um", pixel_size_um, parsed.pixel_size_m),
            ("height_unit", height_unit, parsed.height_to_m),
        )
        if v is not None and f is not None
    ]
    if from_file:
        raise InputError(
            f"{label}: the file's header gives its own calibration; do not give "
            f"{' or '.join(from_file)}"
        )
    if parsed.pixel_size_m is None and parsed.height_to_m is None:
        raw = _raw_grid(parsed.values, "csv", label, pixel_size_um, height_unit)
        raw.notes = notes
        return raw
    missing = [
        n
        for n, v, f in (
            ("pixel_size_um", pixel_size_um, parsed.pixel_size_m),
            ("height_unit", height_unit, parsed.height_to_m),
        )
        if v is None and f is None
    ]
    if missing:
        raise InputError(
            f"{label}: the file's header lacks part of the calibration: "
            f"{' and '.join(missing)} must be given"
        )
    px = parsed.pixel_size_m if parsed.pixel_size_m is not None else pixel_size_m(pixel_size_um)
    factor = parsed.height_to_m if parsed.height_to_m is not None else height_factor(height_unit)
    details = f"text matrix with header, pixel {px * 1e6:.6g} µm, heights × {factor:g} m"
    return RawTopography(parsed.values * factor, px, "text", details, notes=notes)


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
