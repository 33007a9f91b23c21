"""Measured height maps made ready for the solver: unmeasured points and large maps.

Pure: arrays in, arrays and a record of every change out; no file access (the readers are in
``app/storage/topography.py``). The rules are documented in docs/topography.md.

Unmeasured points (:func:`prepare_measured_map`)
    1. The trend (``detrend``: plane, mean or nothing) is fitted to the measured points only.
    2. The ISO 25178 parameters are computed on the measured points only
       (:func:`iso25178_measured`), as ISO 25178 defines them.
    3. A *small hole* is a connected group of unmeasured points (8-connected) that does not
       touch the map's edge and holds at most ``max_hole_points`` points. Every other
       unmeasured point (an unmeasured border, a large hole) is *not fillable*.
    4. The map the solver gets is the largest rectangle holding only measured points and small
       holes (found on a coarse mask, then grown line by line). Everything outside it is cut
       off, so stray measured pixels in an unmeasured border (a column of zeros, spikes) never
       reach the solver and are never copied anywhere.
    5. Each small hole inside the rectangle takes the median of the measured points that touch
       it (one spike among its neighbours cannot set its value; a hole cannot carry a value
       further than its own few points).
    6. Refused (InputError, with the reason): a rectangle with less than ``min_kept_fraction`` of
       the points or a side shorter than ``min_side``; more than ``max_filled_fraction`` of the
       rectangle in small holes.
    7. The trend is removed again from the rectangle; the record gives the points cut and
       filled, and Sq of the solver's map against Sq of the measured points.

Large maps (:func:`reduce_map`)
    A map whose periodised grid (``solvers.texture.periodic_shape``) exceeds the solver's limit is
    reduced by a recorded rule: ``"crop"`` (a centred window, pixel size kept), ``"block"``
    (the mean of k × k blocks, pixel size × k) or ``"none"`` (refused).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .errors import InputError
from .texture import (
    _check_pixel_size,
    _material_ratio_parameters,
    _plane_fit,
    check_detrend,
    periodic_shape,
)

__all__ = [
    "MAX_FILLED_FRACTION",
    "MAX_HOLE_POINTS",
    "MIN_KEPT_FRACTION",
    "REDUCTION_METHODS",
    "PreparedMap",
    "ReducedMap",
    "iso25178_measured",
    "largest_usable_rectangle",
    "prepare_measured_map",
    "reduce_map",
]

#: Largest unmeasured group filled (a small hole) [points]
MAX_HOLE_POINTS = 64
#: Largest share of the kept rectangle that may be filled [-]
MAX_FILLED_FRACTION = 0.02
#: Smallest share of the map the kept rectangle must hold [-]
MIN_KEPT_FRACTION = 0.25
#: Reductions of a map too large for the solver (:func:`reduce_map`)
REDUCTION_METHODS = ("crop", "block", "none")
#: Side of the coarse mask the rectangle search runs on [points]
_COARSE_SIDE = 256


@dataclass
class PreparedMap:
    """A measured map made ready for the solver, with what was done to it.

    Attributes
    ----------
    heights_m : numpy.ndarray
        The solver's map [m]: finite, detrended (``detrend``), axis 0 as given.
    iso_measured : dict
        ISO 25178 parameters of the measured points (:func:`iso25178_measured`), SI.
    measured_points, unmeasured_points : int
        Points of the whole map with and without a height [-].
    crop : tuple of int
        The kept rectangle ``(row0, row1, col0, col1)``, end exclusive [points].
    cut_points : int
        Points of the map outside the rectangle [-] (measured or not).
    cut_measured_points : int
        Measured points among them [-].
    filled_points : int
        Small-hole points filled inside the rectangle [-].
    sq_measured_m, sq_map_m : float
        Sq of the measured points and of the solver's map [m].
    detrend : str
        The trend removed ("plane", "mean", "none").
    """

    heights_m: np.ndarray
    iso_measured: dict
    measured_points: int
    unmeasured_points: int
    crop: tuple[int, int, int, int]
    cut_points: int
    cut_measured_points: int
    filled_points: int
    sq_measured_m: float
    sq_map_m: float
    detrend: str

    @property
    def sq_change_percent(self) -> float:
        """(Sq of the map − Sq of the measured points) / Sq of the measured points [%]."""
        return 100.0 * (self.sq_map_m - self.sq_measured_m) / self.sq_measured_m

    def record(self) -> dict:
        """What was done, for an answer or metadata (plain types, units in the names)."""
        r0, r1, c0, c1 = self.crop
        return {
            "measured_points": self.measured_points,
            "unmeasured_points": self.unmeasured_points,
            "crop_rows": [r0, r1],
            "crop_columns": [c0, c1],
            "cut_points": self.cut_points,
            "cut_measured_points": self.cut_measured_points,
            "filled_points": self.filled_points,
            "fill_rule": (
                f"largest rectangle of measured points and small holes (<= {MAX_HOLE_POINTS} "
                "points, not touching the edge); each hole takes the median of its measured "
                "neighbours"
            ),
            "sq_measured_um": self.sq_measured_m * 1e6,
            "sq_map_um": self.sq_map_m * 1e6,
            "sq_change_percent": self.sq_change_percent,
        }


@dataclass
class ReducedMap:
    """A map reduced for the solver (:func:`reduce_map`).

    Attributes
    ----------
    heights_m : numpy.ndarray
        Reduced heights [m] (mean removed again).
    pixel_size_m : float
        Pixel size after the reduction [m].
    method : str
        "crop", "block" or "none" (unchanged).
    factor : int
        Block side k of "block" (1 otherwise) [-].
    window : tuple of int
        The part of the input used ``(row0, row1, col0, col1)``, end exclusive [points].
    notes : list of str
        What was done, in words.
    """

    heights_m: np.ndarray
    pixel_size_m: float
    method: str
    factor: int = 1
    window: tuple[int, int, int, int] = (0, 0, 0, 0)
    notes: list[str] = field(default_factory=list)

    def record(self, original_shape) -> dict:
        """The reduction for an answer or metadata (plain types, units in the names)."""
        return {
            "method": self.method,
            "original_grid": [int(n) for n in original_shape],
            "grid": [int(n) for n in self.heights_m.shape],
            "window_rows": [self.window[0], self.window[1]],
            "window_columns": [self.window[2], self.window[3]],
            "block_factor": self.factor,
            "pixel_size_um": self.pixel_size_m * 1e6,
            "notes": list(self.notes),
        }


# --------------------------------------------------------------------------- ISO 25178


def iso25178_measured(heights_m, pixel_size_m: float) -> dict[str, float]:
    """ISO 25178-2 parameters over the measured (finite) points of a levelled map.

    Height parameters use every measured point; gradient parameters (``Sdq``, ``Sdr_percent``)
    use the points whose neighbours needed by the finite difference are measured too.

    Parameters
    ----------
    heights_m : array_like
        Levelled heights [m], 2-D, NaN where not measured. The mean of the measured points is
        removed; a tilt is not.
    pixel_size_m : float
        Pixel size Δ [m].

    Returns
    -------
    dict
        The keys of :func:`solvers.texture.iso25178_parameters` (SI, unit in each name).

    Raises
    ------
    InputError
        Fewer than 3 measured points, or a flat map.
    """
    dx = _check_pixel_size(pixel_size_m)
    h = np.asarray(heights_m, dtype=np.float64)
    valid = np.isfinite(h)
    if valid.sum() < 3:
        raise InputError(f"heights_m has only {int(valid.sum())} measured point(s); need >= 3")
    z = h[valid] - h[valid].mean()
    sq = float(np.sqrt(np.mean(z**2)))
    if sq == 0:
        raise InputError("heights_m is flat (Sq = 0): ISO parameters are undefined")
    g0, g1 = np.gradient(np.where(valid, h, np.nan), dx, dx, edge_order=1)
    grad2 = g0**2 + g1**2
    grad2 = grad2[np.isfinite(grad2)]
    if grad2.size == 0:
        sdq = sdr = float("nan")
    else:
        sdq = float(np.sqrt(np.mean(grad2)))
        sdr = float(100 * np.mean(np.sqrt(1 + grad2) - 1))
    out = {
        "Sa_m": float(np.mean(np.abs(z))),
        "Sq_m": sq,
        "Ssk": float(np.mean(z**3) / sq**3),
        "Sku": float(np.mean(z**4) / sq**4),
        "Sdq": sdq,
        "Sdr_percent": sdr,
    }
    out.update(_material_ratio_parameters(z))
    return out


# --------------------------------------------------------------------------- rectangle


def _largest_rectangle_all_true(mask: np.ndarray) -> tuple[int, int, int, int, int]:
    """Largest axis-aligned rectangle of True cells: (area, row0, row1, col0, col1)."""
    n0, n1 = mask.shape
    heights = np.zeros(n1, dtype=np.int64)
    best = (0, 0, 0, 0, 0)
    for i in range(n0):
        heights = np.where(mask[i], heights + 1, 0)
        stack: list[int] = []
        hs = [*heights.tolist(), 0]
        for j, hj in enumerate(hs):
            while stack and hs[stack[-1]] >= hj:
                top = stack.pop()
                start_col = stack[-1] + 1 if stack else 0
                area = hs[top] * (j - start_col)
                if area > best[0]:
                    best = (area, i + 1 - hs[top], i + 1, start_col, j)
            stack.append(j)
    return best


def largest_usable_rectangle(usable: np.ndarray) -> tuple[int, int, int, int]:
    """A large rectangle of True points in ``usable``: ``(row0, row1, col0, col1)``.

    The exact largest rectangle is found on a coarse mask (blocks of k × k points, a block is
    usable when all its points are; k makes the coarse side at most 256), then each side is
    moved outwards one line at a time while the added line is all usable. Returns an empty
    rectangle (zero size) when no point is usable.
    """
    usable = np.asarray(usable, dtype=bool)
    n0, n1 = usable.shape
    k = max(1, math.ceil(max(n0, n1) / _COARSE_SIDE))
    m0, m1 = math.ceil(n0 / k), math.ceil(n1 / k)
    pad = np.zeros((m0 * k, m1 * k), dtype=bool)
    pad[:n0, :n1] = usable
    coarse = pad.reshape(m0, k, m1, k).all(axis=(1, 3))
    area, r0, r1, c0, c1 = _largest_rectangle_all_true(coarse)
    if area == 0:
        if k == 1 or not usable.any():
            return (0, 0, 0, 0)
        area, r0, r1, c0, c1 = _largest_rectangle_all_true(usable)
        return (r0, r1, c0, c1)
    r0, r1, c0, c1 = r0 * k, min(r1 * k, n0), c0 * k, min(c1 * k, n1)
    grown = True
    while grown:
        grown = False
        if r0 > 0 and usable[r0 - 1, c0:c1].all():
            r0, grown = r0 - 1, True
        if r1 < n0 and usable[r1, c0:c1].all():
            r1, grown = r1 + 1, True
        if c0 > 0 and usable[r0:r1, c0 - 1].all():
            c0, grown = c0 - 1, True
        if c1 < n1 and usable[r0:r1, c1].all():
            c1, grown = c1 + 1, True
    return (r0, r1, c0, c1)


def _fill_holes_with_neighbour_median(part: np.ndarray, valid: np.ndarray) -> None:
    """Give each 8-connected group of unmeasured points of ``part`` (in place) the median of
    the measured points touching it (each counted once per hole it touches)."""
    from scipy import ndimage

    eight = np.ones((3, 3), dtype=bool)
    labels, n = ndimage.label(~valid, structure=eight)
    if n == 0:
        return
    n0, n1 = part.shape
    padded = np.pad(labels, 1)
    flat = np.arange(part.size).reshape(part.shape)
    keys = []
    for a in (-1, 0, 1):
        for b in (-1, 0, 1):
            if a == b == 0:
                continue
            neighbour = padded[1 + a : 1 + a + n0, 1 + b : 1 + b + n1]
            touch = valid & (neighbour > 0)
            keys.append(neighbour[touch].astype(np.int64) * part.size + flat[touch])
    pairs = np.unique(np.concatenate(keys))  # (hole, measured point), each once
    owners, points = np.divmod(pairs, part.size)
    index = np.arange(1, n + 1)
    has = np.bincount(owners, minlength=n + 1)[1:] > 0
    medians = np.full(n + 1, np.median(part[valid]))  # a hole without measured neighbours
    if has.any():
        medians[1:][has] = ndimage.median(part.ravel()[points], labels=owners, index=index[has])
    holes = labels > 0
    part[holes] = medians[labels[holes]]


def _remove_trend(h: np.ndarray, valid: np.ndarray, detrend: str) -> np.ndarray:
    if detrend == "plane":
        return h - _plane_fit(h, valid)
    if detrend == "mean":
        return h - h[valid].mean()
    return h


def prepare_measured_map(
    heights_m,
    pixel_size_m: float,
    *,
    detrend: str = "plane",
    max_hole_points: int = MAX_HOLE_POINTS,
    max_filled_fraction: float = MAX_FILLED_FRACTION,
    min_kept_fraction: float = MIN_KEPT_FRACTION,
    min_side: int = 2,
) -> PreparedMap:
    """Level a measured map on its measured points and build the solver's map by the rules of
    this module's docstring (crop to the largest well-measured rectangle, fill small holes).

    Parameters
    ----------
    heights_m : array_like
        Raw heights [m], 2-D, NaN where not measured.
    pixel_size_m : float
        Pixel size Δ [m].
    detrend : str
        "plane" (default), "mean" or "none": removed from the measured points, and again from
        the kept rectangle.
    max_hole_points : int
        Largest unmeasured group that is filled [points].
    max_filled_fraction : float
        Largest share of the kept rectangle that may be filled [-].
    min_kept_fraction : float
        Smallest share of the map the kept rectangle must hold [-].
    min_side : int
        Fewest points along each side of the kept rectangle [-].

    Returns
    -------
    PreparedMap

    Raises
    ------
    InputError
        ±inf heights, no or too few measured points, a kept rectangle too small, too many holes
        to fill, a flat map, an unknown ``detrend``.
    """
    from scipy import ndimage

    _check_pixel_size(pixel_size_m)
    detrend = check_detrend(detrend)
    h = np.array(heights_m, dtype=np.float64)
    if h.ndim != 2:
        raise InputError(f"heights_m must be 2-D, got shape {h.shape}")
    if np.isinf(h).any():
        raise InputError(
            f"heights_m contains {int(np.isinf(h).sum())} infinite value(s); "
            "mark unmeasured points with NaN"
        )
    valid = np.isfinite(h)
    n_valid = int(valid.sum())
    if n_valid < 3:
        raise InputError(f"the map has only {n_valid} measured point(s); need >= 3")
    if np.ptp(h[valid]) == 0:
        raise InputError("the map is flat (every measured height is the same): no texture")
    levelled = _remove_trend(h, valid, detrend)
    levelled[~valid] = np.nan
    iso = iso25178_measured(levelled, pixel_size_m)

    # small holes: unmeasured groups that do not touch the edge and are small
    labels, n_groups = ndimage.label(~valid, structure=np.ones((3, 3), dtype=bool))
    small = np.zeros(n_groups + 1, dtype=bool)
    if n_groups:
        sizes = np.bincount(labels.ravel(), minlength=n_groups + 1)
        small[: n_groups + 1] = sizes <= max_hole_points
        edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
        small[edge] = False
    small[0] = False
    usable = valid | small[labels]
    r0, r1, c0, c1 = largest_usable_rectangle(usable)
    kept = (r1 - r0) * (c1 - c0)
    share = kept / h.size
    if kept == 0 or share < min_kept_fraction or min(r1 - r0, c1 - c0) < min_side:
        raise InputError(
            f"the largest rectangle of measured points (holes of at most {max_hole_points} "
            f"points filled) is {r1 - r0} x {c1 - c0} points, {share:.1%} of the map; at least "
            f"{min_kept_fraction:.0%} and {min_side} points a side are needed: too much of the "
            "map is unmeasured"
        )
    part = levelled[r0:r1, c0:c1].copy()
    part_valid = valid[r0:r1, c0:c1]
    holes = ~part_valid
    n_filled = int(holes.sum())
    if n_filled > max_filled_fraction * kept:
        raise InputError(
            f"{n_filled} points ({n_filled / kept:.1%}) of the kept {r1 - r0} x {c1 - c0} "
            f"rectangle are unmeasured, more than {max_filled_fraction:.0%}: too many holes to "
            "fill without inventing texture"
        )
    if n_filled:
        _fill_holes_with_neighbour_median(part, part_valid)
    part = _remove_trend(part, np.ones_like(part_valid), detrend)
    if detrend != "none":
        part -= part.mean()
    if np.ptp(part) == 0:
        raise InputError("the kept rectangle of the map is flat: no texture")
    sq_map = float(np.sqrt(np.mean((part - part.mean()) ** 2)))
    n_cut_measured = n_valid - int(part_valid.sum())
    return PreparedMap(
        heights_m=part,
        iso_measured=iso,
        measured_points=n_valid,
        unmeasured_points=int(h.size - n_valid),
        crop=(int(r0), int(r1), int(c0), int(c1)),
        cut_points=int(h.size - kept),
        cut_measured_points=n_cut_measured,
        filled_points=n_filled,
        sq_measured_m=float(iso["Sq_m"]),
        sq_map_m=sq_map,
        detrend=detrend,
    )


# --------------------------------------------------------------------------- large maps


def reduce_map(
    heights_m,
    pixel_size_m: float,
    method: str,
    *,
    max_solve_points: int,
    periodic: str = "mirror",
) -> ReducedMap:
    """Reduce a map so that its periodised grid holds at most ``max_solve_points`` points.

    ``"crop"``: the centred window whose sides are the map's times one factor (aspect kept),
    pixel size kept. ``"block"``: the mean of k × k blocks with the smallest integer k that
    fits (the last rows/columns that do not fill a block are dropped, half at each end), pixel
    size × k. ``"none"``: refused if it does not fit. A map that fits is returned unchanged.

    Parameters
    ----------
    heights_m : array_like
        Levelled, finite heights [m], 2-D.
    pixel_size_m : float
        Pixel size Δ [m].
    method : str
        One of :data:`REDUCTION_METHODS`.
    max_solve_points : int
        Largest periodised grid [points].
    periodic : str
        The periodisation the table is solved with (``solvers.texture.periodic_shape``).

    Returns
    -------
    ReducedMap

    Raises
    ------
    InputError
        Unknown method; ``"none"`` with a map that does not fit.
    """
    if method not in REDUCTION_METHODS:
        raise InputError(f"reduce must be one of {', '.join(REDUCTION_METHODS)}, got {method!r}")
    dx = _check_pixel_size(pixel_size_m)
    h = np.asarray(heights_m, dtype=np.float64)
    n0, n1 = h.shape

    def points(shape) -> int:
        return math.prod(periodic_shape(shape, periodic))

    if points((n0, n1)) <= max_solve_points:
        return ReducedMap(h, dx, "none", 1, (0, n0, 0, n1), [])
    solve = periodic_shape((n0, n1), periodic)
    if method == "none":
        raise InputError(
            f"grid {n0}×{n1} with periodic={periodic} is solved on {solve[0]}×{solve[1]} = "
            f"{math.prod(solve)} points, over the limit of {max_solve_points} points; choose "
            "reduce=crop (a centred window) or reduce=block (block average)"
        )
    if method == "crop":
        f = math.sqrt(max_solve_points / points((n0, n1)))
        w0, w1 = max(2, int(n0 * f)), max(2, int(n1 * f))
        while points((w0, w1)) > max_solve_points:
            w0, w1 = max(2, w0 - 1), max(2, w1 - 1)
        a0, a1 = (n0 - w0) // 2, (n1 - w1) // 2
        out = h[a0 : a0 + w0, a1 : a1 + w1]
        out = out - out.mean()
        note = (
            f"centred window {w0}×{w1} of {n0}×{n1} points (rows {a0}–{a0 + w0}, columns "
            f"{a1}–{a1 + w1}), pixel size {dx * 1e6:.4g} µm kept"
        )
        return ReducedMap(out, dx, "crop", 1, (a0, a0 + w0, a1, a1 + w1), [note])
    k = 2
    while points((n0 // k, n1 // k)) > max_solve_points:
        k += 1
    m0, m1 = n0 // k, n1 // k
    a0, a1 = (n0 - m0 * k) // 2, (n1 - m1 * k) // 2
    part = h[a0 : a0 + m0 * k, a1 : a1 + m1 * k]
    out = part.reshape(m0, k, m1, k).mean(axis=(1, 3))
    out = out - out.mean()
    note = (
        f"block average {k}×{k}: {n0}×{n1} → {m0}×{m1} points, pixel size "
        f"{dx * 1e6:.4g} → {dx * k * 1e6:.4g} µm"
    )
    if (m0 * k, m1 * k) != (n0, n1):
        note += f"; {n0 - m0 * k} rows and {n1 - m1 * k} columns at the edges dropped"
    return ReducedMap(out, dx * k, "block", k, (a0, a0 + m0 * k, a1, a1 + m1 * k), [note])
