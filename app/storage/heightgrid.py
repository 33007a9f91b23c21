"""Raw height grids: the parsing and unit primitives shared by texture files
(:mod:`app.storage.textures`) and user topographies (:mod:`app.storage.topography`).

Pure: text and numbers in, float64 arrays and SI floats out; no file access. Imports only
``solvers``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
from skisnow.solvers.errors import DataFileError, InputError

__all__ = [
    "HEIGHT_UNITS",
    "TextTopography",
    "height_factor",
    "parse_csv_grid",
    "parse_text_topography",
    "pixel_size_m",
]

#: Accepted height units of raw maps and their factor to metres
HEIGHT_UNITS: dict[str, float] = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "nm": 1e-9}


def height_factor(height_unit) -> float:
    """Factor from ``height_unit`` (:data:`HEIGHT_UNITS`) to metres [m per unit]."""
    if not isinstance(height_unit, str) or height_unit.strip() not in HEIGHT_UNITS:
        raise InputError(
            f"height_unit must be one of {', '.join(HEIGHT_UNITS)}, got {height_unit!r}"
        )
    return HEIGHT_UNITS[height_unit.strip()]


def pixel_size_m(pixel_size_um) -> float:
    """Pixel size [m] from a user's ``pixel_size_um`` [µm] (finite, > 0)."""
    try:
        value = float(pixel_size_um)
    except (TypeError, ValueError):
        raise InputError(f"pixel_size_um must be a number, got {pixel_size_um!r}") from None
    if not (np.isfinite(value) and value > 0):
        raise InputError(f"pixel_size_um must be finite and > 0, got {pixel_size_um!r}")
    return value * 1e-6


def parse_csv_grid(text: str, label: str) -> np.ndarray:
    """Numbers of a csv height grid (comma or whitespace separated, ``#`` comments, empty cell
    or NaN for a missing point) as a float64 array; ``label`` names the file in errors."""
    rows = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        cells = line.split(",") if "," in line else stripped.split()
        try:
            rows.append([float(c) if c.strip() else np.nan for c in cells])
        except ValueError as exc:
            raise DataFileError(f"{label}, line {lineno}: {exc}") from None
    if not rows:
        raise DataFileError(f"{label} holds no numbers")
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        raise DataFileError(
            f"{label} is not a rectangular grid (row lengths {sorted(widths)}); truncated file?"
        )
    return np.array(rows, dtype=np.float64)


# --------------------------------------------------------------------------- text files

#: Lengths of the text headers and their factor to metres
_LENGTH_UNITS = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "nm": 1e-9}


@dataclass
class TextTopography:
    """A text height file as parsed (:func:`parse_text_topography`).

    Attributes
    ----------
    kind : str
        "grid" (a matrix of heights) or "xyz" (a point list on a regular grid, made a grid).
    values : numpy.ndarray
        The heights as numbers of the file, 2-D, NaN where not measured; axis 0 = the file's x
        (a calibrated matrix's columns, an xyz file's x column; a plain grid's rows).
    pixel_size_m : float or None
        Pixel size [m] from the file's header (Wyko ``pixel size=``, Gwyddion ``# Width:``);
        ``None``: not in the file.
    height_to_m : float or None
        Factor from the file's numbers to metres, from its header; ``None``: not in the file.
    spacing : float or None
        xyz only: the grid spacing in the file's coordinate unit.
    notes : list of str
        What was skipped or converted, in words (for the answer).
    """

    kind: str
    values: np.ndarray
    pixel_size_m: float | None = None
    height_to_m: float | None = None
    spacing: float | None = None
    notes: list[str] = field(default_factory=list)


def _is_even_progression(row: np.ndarray) -> bool:
    """Strictly monotone, evenly spaced (to 1e-6 of the step), at least 4 values."""
    if row.size < 4 or not np.isfinite(row).all():
        return False
    step = np.diff(row)
    if not (np.all(step > 0) or np.all(step < 0)):
        return False
    return bool(np.ptp(step) <= 1e-6 * abs(step.mean()) + 1e-12 * np.abs(row).max())


def _length(text: str, label: str, what: str) -> float:
    """'12.34 µm' or '3.7e-7 m' [m]."""
    parts = text.replace("\u00b5", "µ").split()
    try:
        value = float(parts[0])
        unit = parts[1] if len(parts) > 1 else "m"
    except (IndexError, ValueError):
        raise DataFileError(f"{label}: header {what} {text!r} is not a length") from None
    if unit not in _LENGTH_UNITS:
        raise DataFileError(f"{label}: header {what} has an unknown unit {unit!r}")
    return value * _LENGTH_UNITS[unit]


def parse_text_topography(text: str, label: str) -> TextTopography:
    """Parse a text height file: a matrix (comma or whitespace separated), with an optional
    Wyko header (``h=… w=…``, ``pixel size=… m``, ``height conversion factor (-> m)=…``) or
    Gwyddion header (``# Width: …``, ``# Height: …``, ``# Value units: m``), or an x y z point
    list on a regular grid.

    Rules: lines before the first row of numbers that are not numbers are a header (skipped,
    with a note); a first row that is an evenly spaced increasing or decreasing sequence while
    the second is not lists positions, not heights (skipped, with a note), and so does such a
    first column; one or two columns are a line scan (refused: a grind needs a 2-D map); three
    columns are an x y z point list, read as a map when its x and y lie on a regular grid.

    Raises
    ------
    InputError
        A line scan; a point list not on a regular grid; a header that contradicts the data.
    DataFileError
        Text that is not a rectangular table of numbers.
    """
    notes: list[str] = []
    header: dict[str, str] = {}
    rows: list[list[float]] = []
    for lineno, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            key, sep, value = stripped.lstrip("#").partition(":")
            if sep:
                header[key.strip().lower()] = value.strip()
            continue
        cells = line.split(",") if "," in line else stripped.split()
        try:
            rows.append([float(c) if c.strip() else np.nan for c in cells])
        except ValueError as exc:
            if rows:
                raise DataFileError(f"{label}, line {lineno}: {exc}") from None
            pairs = re.fullmatch(r"h\s*=\s*(\d+)\s+w\s*=\s*(\d+)", stripped)
            if pairs:  # Wyko: "h=650 w=650" on one line
                header["h"], header["w"] = pairs.groups()
                continue
            key, sep, value = stripped.partition("=")
            if sep:
                header[key.strip().lower()] = value.strip()
                continue
            shown = stripped if len(stripped) <= 60 else stripped[:57] + "..."
            notes.append(f"line {lineno} is not numbers, taken as a header and skipped: {shown!r}")
    if not rows:
        raise DataFileError(f"{label} holds no numbers")
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        raise DataFileError(
            f"{label} is not a rectangular table (row lengths {sorted(widths)}); truncated file?"
        )
    arr = np.array(rows, dtype=np.float64)
    n_rows, n_cols = arr.shape
    if n_cols <= 2:
        what = "one column of heights" if n_cols == 1 else "x, z pairs"
        raise InputError(f"{label}: a line scan ({n_rows} rows of {what}): a grind needs a 2-D map")
    if n_cols == 3 and n_rows > 3:
        return _xyz_grid(arr, label, notes)
    # a row (and column) of positions: evenly spaced while the next is not; with both, the
    # corner cell belongs to neither
    col_header = _is_even_progression(arr[1:, 0]) and not _is_even_progression(arr[1:, 1])
    first = 1 if col_header else 0
    row_header = (
        n_rows >= 3
        and _is_even_progression(arr[0, first:])
        and not _is_even_progression(arr[1, first:])
    )
    if row_header:
        notes.append(
            f"row 1 is an evenly spaced sequence ({arr[0, first]:g} … {arr[0, -1]:g}), "
            "positions rather than heights: skipped"
        )
        arr = arr[1:]
    if _is_even_progression(arr[:, 0]) and not _is_even_progression(arr[:, 1]):
        notes.append(
            f"column 1 is an evenly spaced sequence ({arr[0, 0]:g} … {arr[-1, 0]:g}), "
            "positions rather than heights: skipped"
        )
        arr = arr[:, 1:]
    if "h" in header or "w" in header:  # Wyko: h rows (y), w columns (x)
        try:
            h_rows, w_cols = int(header["h"]), int(header["w"])
        except (KeyError, ValueError):
            raise DataFileError(f"{label}: header h=… w=… is incomplete") from None
        if (h_rows, w_cols) != arr.shape:
            raise InputError(
                f"{label}: the header says h={h_rows} w={w_cols}, the data are "
                f"{arr.shape[0]} x {arr.shape[1]}"
            )
        px = _length(header["pixel size"], label, "pixel size") if "pixel size" in header else None
        factor = None
        conv = header.get("height conversion factor (-> m)")
        if conv is not None:
            try:
                factor = float(conv)
            except ValueError:
                raise DataFileError(f"{label}: height conversion factor {conv!r}") from None
        notes.append(
            f"Wyko text header: {h_rows} rows (y) x {w_cols} columns (x), data unit "
            f"{header.get('data unit', '?')}"
        )
        return TextTopography("grid", arr.T.copy(), px, factor, None, notes)
    width = header.get("width", header.get("breite"))
    if width is not None:  # Gwyddion export: Width along the columns (x)
        px = _length(width, label, "Width") / arr.shape[1]
        unit = header.get("value units")
        factor = _LENGTH_UNITS.get(unit.replace("\u00b5", "µ")) if unit else None
        if unit and factor is None:
            raise InputError(f"{label}: heights in {unit!r}, not a length")
        notes.append(f"Gwyddion text header: Width {width} over {arr.shape[1]} columns (x)")
        return TextTopography("grid", arr.T.copy(), px, factor, None, notes)
    return TextTopography("grid", arr, None, None, None, notes)


def _xyz_grid(arr: np.ndarray, label: str, notes: list[str]) -> TextTopography:
    x, y, z = arr[:, 0], arr[:, 1], arr[:, 2]
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise InputError(f"{label}: an x y z point list with missing coordinates")
    ux, uy = np.unique(x), np.unique(y)
    regular = ux.size * uy.size == x.size and ux.size >= 2 and uy.size >= 2
    if regular:
        dx, dy = np.diff(ux), np.diff(uy)
        step = dx.mean()
        regular = (
            np.ptp(dx) <= 1e-6 * step
            and np.ptp(dy) <= 1e-6 * dy.mean()
            and abs(dy.mean() - step) <= 1e-3 * step
        )
    if not regular:
        raise InputError(
            f"{label}: an x y z point list ({x.size} points) that is not on a regular square "
            "grid; a grind needs a height map on a grid"
        )
    i = np.searchsorted(ux, x)
    j = np.searchsorted(uy, y)
    grid = np.full((ux.size, uy.size), np.nan)
    grid[i, j] = z
    if np.isnan(grid).sum() != np.isnan(z).sum():
        raise InputError(f"{label}: an x y z point list with repeated points")
    notes.append(
        f"x y z point list: {x.size} points on a {ux.size} x {uy.size} grid, spacing {step:g} "
        "(in the file's unit)"
    )
    return TextTopography("xyz", grid, None, None, float(step), notes)
