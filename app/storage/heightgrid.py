"""Raw height grids: the parsing and unit primitives shared by texture files
(:mod:`app.storage.textures`) and user topographies (:mod:`app.storage.topography`).

Pure: text and numbers in, float64 arrays and SI floats out; no file access. Imports only
``solvers``.
"""

from __future__ import annotations

import numpy as np
from skisnow.solvers.errors import DataFileError, InputError

__all__ = ["HEIGHT_UNITS", "height_factor", "parse_csv_grid", "pixel_size_m"]

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
