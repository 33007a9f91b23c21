"""Micro-scale lookup tables: interpolation of tabulated texture solves (docs/physics.md §5).

A table holds, for one texture, the results of :func:`solvers.micro.solve_micro` over the
dimensionless nominal pressure ratio ``P_n / E'`` (by linear elasticity the contact set and the
gap field of a rigid texture depend only on that ratio), plus the separated-regime curve
``⟨1 / (h_0 + H)⟩`` of the unloaded texture lifted by a clearance ``H``. This module is pure: it
never opens files (see :mod:`app.storage.tables` for reading and writing).

Lookup rules
------------
- **Pressure ratio.** ``r = P_n / E'`` with ``P_n = P (1 − n)`` (docs/physics.md eq. 2,
  :func:`nominal_pressure_ratio`).
- **Interpolation** is shape-preserving piecewise-cubic Hermite (PCHIP, monotone wherever the
  data are monotone) in ``x = ln r``:

  * real contact area fraction ``a_r``: in ``ln a_r`` (it spans orders of magnitude and is > 0
    for every solved point, because a loaded texture touches on at least one pixel);
  * mean gap ``h̄_n``: in ``ln h̄_n`` over the partial-contact points (it falls steeply
    towards full contact); on the last segment, from the last partial-contact point to the
    full-contact ratio where ``h̄_n = 0`` exactly, linearly in ``r`` (no logarithm of 0);
  * floored mean reciprocal gap ``(1/h)‾_n``: in ``ln`` of the value.

- **Full contact.** If the table reached full contact (some grid point at or above the
  full-contact ratio ``r_fc = p_fc / E'``), the exact full-contact state ``a_r = 1``,
  ``h̄_n = 0``, ``(1/h)‾_n = 1/h_c`` (the floor: the last gaps close) is an interpolation node at
  ``r_fc`` and every ``r ≥ r_fc`` returns it exactly — this is physics, not extrapolation.
- **Zero load.** ``r = 0`` returns the unloaded texture exactly: ``a_r = 0``, ``h̄_n = ⟨h_0⟩``,
  ``(1/h)‾_n = ⟨1/max(h_0, h_c)⟩``.
- **Out of range.** ``0 < r < r_min`` and (without full contact) ``r > r_max`` are outside the
  table: they raise :class:`~solvers.errors.OutOfRangeError`, or with ``out_of_range="flag"``
  return NaN there plus a boolean mask of the flagged points. Nothing is extrapolated. Ratios
  within a relative 1e-9 of a table end are snapped onto it (round-off of ``P·(1 − n)/E'``).
- **Separated regime** (``P = 0``, clearance ``H > 0``): ``⟨1/(h_0 + H)⟩`` is interpolated by
  PCHIP in ``ln H``/``ln value`` over the tabulated clearances, out-of-range as above;
  the mean separation ``⟨h_0⟩ + H`` is exact for any ``H ≥ 0``.
- The tabulated reciprocal gaps are eq. (5) with ``n = 0``; the porosity prefactor ``(1 − n)``
  of eq. (5) is applied by the caller (the multi-scale integration), not here.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from scipy.interpolate import PchipInterpolator

from .errors import InputError, OutOfRangeError

__all__ = [
    "ADAPTIVE_LEVEL_PREFIX",
    "ERROR_FIELDS",
    "ESTIMATE_RANGE_A_R",
    "LIGHT_LOAD_PREFIX",
    "LIGHT_LOAD_RANGE_A_R",
    "PIXEL_EXTRAPOLATION_ORDERS",
    "POINT_FIELDS",
    "TABLE_SCHEMA",
    "MicroTable",
    "chunk_bounds",
    "combine_pixel_levels",
    "combine_three_pixel_levels",
    "combine_with_fourth_level",
    "combine_with_light_load_levels",
    "mean_gap_m",
    "mean_reciprocal_gap_per_m",
    "nominal_pressure_ratio",
    "observed_order",
    "pressure_ratio_grid",
    "real_contact_area_fraction",
    "relative_error_estimate",
    "richardson",
    "select_fourth_level_nodes",
    "select_light_load_nodes",
    "separated_curve",
    "separated_mean_gap_m",
    "separated_reciprocal_gap_per_m",
    "solve_table_chunk",
    "unloaded_statistics",
    "with_fourth_level",
    "with_light_load_levels",
]

#: Schema identifier written into (and required from) every table file
TABLE_SCHEMA = "skisnow.table/1"

#: Relative distance from a table end within which a query is snapped onto it [-]
_EDGE_RTOL = 1e-9


#: the per-pressure-point arrays of a :class:`MicroTable`, pressure axis first
POINT_FIELDS = (
    "pressure_ratio",
    "real_contact_area_fraction",
    "mean_gap_m",
    "mean_reciprocal_gap_per_m",
    "mean_reciprocal_gap_raw_per_m",
    "iterations",
    "residual",
    "converged",
    "full_contact",
)


#: per-point error estimate of each extrapolated quantity: (quantity, error array name)
ERROR_FIELDS = {
    "real_contact_area_fraction": "real_contact_area_fraction_error",
    "mean_gap_m": "mean_gap_error_m",
    "mean_reciprocal_gap_per_m": "mean_reciprocal_gap_error_per_m",
}

#: order p of the leading pixel-size error term used to extrapolate each quantity to zero pixel
#: size (error ∝ Δ^p); ``None``: no clear order, the finest level is kept. Measured on the
#: shipped grinds (docs/benchmarks.md, micro stage; docs/tables.md, Pixel size): a_r
#: converges at first order (contact-edge pixels: successive changes 1.5 → 0.75 → 0.375 µm
#: shrink 1.99–2.14× on grind-2 at a_r = 2.5e-3 … 0.17; slower, about 1.5×, only at
#: a_r < 1e-3), the mean gap at second order (observed 1.7–2.1), the floored reciprocal gap
#: has no stable order (CHOICE).
PIXEL_EXTRAPOLATION_ORDERS = {
    "real_contact_area_fraction": 1.0,
    "mean_gap_m": 2.0,
    "mean_reciprocal_gap_per_m": None,
}

#: largest |observed − assumed| order [-] for which three levels count as being in the
#: asymptotic range (:func:`combine_three_pixel_levels`). CHOICE: 0.25 takes the successive
#: changes' ratio k^p_obs within 1.68–2.38 for p = 1, k = 2; the shipped grind-2 a_r has
#: 1.99–2.14 at a_r 2.5e-3…0.17 (docs/tables.md, Pixel size).
ORDER_TOLERANCE = 0.25

#: the partial-contact range of a_r over which issue #13 (point 3) asks the pixel-size error
#: estimate to be ≤ 3 % [-] (inclusive ends, on the table's value of a_r). The adaptive fourth
#: level (:func:`select_fourth_level_nodes`) is solved only at nodes in it: below 1e-3 a
#: 1024² cell has a few contact pixels and no asymptotic order to recover.
ESTIMATE_RANGE_A_R = (1e-3, 0.9)

#: prefix of the ``levels`` entries of the adaptive fourth pixel level (one value per refined
#: node, :func:`with_fourth_level`); tables without it read as before
ADAPTIVE_LEVEL_PREFIX = "adaptive_"

#: the light-load a_r range [-] (low end inclusive, high end exclusive: the estimate range
#: above starts there) over which issue #29 asks the estimate to be ≤ 3 % too, from a_r 1e-4.
#: Its nodes get several finer pixel levels at once (:func:`select_light_load_nodes`,
#: :func:`with_light_load_levels`; app/jobs/table_light_levels.py), since one extra level does
#: not reach the asymptotic range there (docs/tables.md, Light-load levels).
LIGHT_LOAD_RANGE_A_R = (1e-4, 1e-3)

#: prefix of the ``levels`` entries of the light-load levels (first axis: extra level, coarse
#: first; second: refined node); tables without them read as before
LIGHT_LOAD_PREFIX = "light_"


@dataclass
class MicroTable:
    """One texture's micro-scale table (arrays as stored in the file, plus metadata).

    Attributes
    ----------
    name : str
        Texture name (e.g. "grind-1").
    pixel_size_m : float
        Pixel size of the texture the table was computed on [m].
    grid_shape : (int, int)
        Texture grid shape [-].
    effective_modulus_pa : float
        E' used for the solves [Pa] (results depend only on ``P_n / E'``).
    gap_floor_m : float
        Floor h_c of the floored mean reciprocal gap [m].
    tol : float
        Solver tolerance [-].
    pressure_ratio : ndarray, shape (N,)
        Nominal pressure ratio ``P_n / E'`` [-], strictly increasing, > 0.
    real_contact_area_fraction : ndarray, shape (N,)
        a_r [-] (docs/physics.md eq. 3).
    mean_gap_m : ndarray, shape (N,)
        Mean gap h̄_n over the whole cell [m] (eq. 4 with H = 0).
    mean_reciprocal_gap_per_m : ndarray, shape (N,)
        Mean over the gap set of ``1/max(h_n, h_c)`` [1/m] (eq. 5 with H = 0, n = 0).
    mean_reciprocal_gap_raw_per_m : ndarray, shape (N,)
        The same without the floor [1/m] (resolution dependent; stored for diagnosis).
    iterations : ndarray of int, shape (N,)
        Solver iterations per point [-] (0 for full-contact points).
    residual : ndarray, shape (N,)
        Final solver residual per point [-].
    converged : ndarray of bool, shape (N,)
        Whether each solve met the tolerance.
    full_contact : ndarray of bool, shape (N,)
        Points at or above the full-contact ratio (exact state a_r = 1, gap 0, not solved).
    full_contact_pressure_ratio : float
        ``r_fc = p_fc / E'`` [-], the lowest ratio at which the texture is in full contact.
    unloaded_mean_gap_m : float
        ⟨h_0⟩, mean unloaded gap (``h_0 = max h* − h*``) [m].
    unloaded_mean_reciprocal_gap_per_m : float
        ⟨1/max(h_0, h_c)⟩ over the cell [1/m], the zero-load value.
    clearance_m : ndarray, shape (M,)
        Clearances H of the separated-regime curve [m], strictly increasing, > 0.
    separated_mean_reciprocal_gap_per_m : ndarray, shape (M,)
        ⟨1/(h_0 + H)⟩ over the whole cell [1/m].
    iso_parameters : dict
        ISO 25178 parameters of the texture (units in the keys), may be empty.
    attrs : dict
        Remaining file attributes (provenance: code version, git commit, command line, ...).
    real_contact_area_fraction_error : ndarray, shape (N,), optional
        Estimated error of the tabulated a_r against the zero-pixel limit [-] (two-level
        tables, :func:`combine_pixel_levels`); ``None`` for tables built on one pixel size.
    mean_gap_error_m : ndarray, shape (N,), optional
        The same for the mean gap [m].
    mean_reciprocal_gap_error_per_m : ndarray, shape (N,), optional
        The same for the floored mean reciprocal gap [1/m].
    levels : dict, optional
        Per-level results of a two-level table: ``{"pixel_size_m": [...], "<quantity>":
        ndarray (levels, N), ...}``, coarse first; ``None`` for one-level tables. Three-level
        tables add ``observed_order_<q>`` and ``three_level_estimate_<q>`` (N,); a table with
        the adaptive fourth level adds the ``adaptive_*`` entries of :func:`with_fourth_level`.
    """

    name: str
    pixel_size_m: float
    grid_shape: tuple[int, int]
    effective_modulus_pa: float
    gap_floor_m: float
    tol: float
    pressure_ratio: np.ndarray
    real_contact_area_fraction: np.ndarray
    mean_gap_m: np.ndarray
    mean_reciprocal_gap_per_m: np.ndarray
    mean_reciprocal_gap_raw_per_m: np.ndarray
    iterations: np.ndarray
    residual: np.ndarray
    converged: np.ndarray
    full_contact: np.ndarray
    full_contact_pressure_ratio: float
    unloaded_mean_gap_m: float
    unloaded_mean_reciprocal_gap_per_m: float
    clearance_m: np.ndarray
    separated_mean_reciprocal_gap_per_m: np.ndarray
    iso_parameters: dict = field(default_factory=dict)
    attrs: dict = field(default_factory=dict)
    real_contact_area_fraction_error: np.ndarray | None = None
    mean_gap_error_m: np.ndarray | None = None
    mean_reciprocal_gap_error_per_m: np.ndarray | None = None
    levels: dict | None = None

    @property
    def has_error_estimates(self) -> bool:
        """True if every point carries its pixel-size error estimate (two-level tables)."""
        return all(getattr(self, name) is not None for name in ERROR_FIELDS.values())

    def __post_init__(self) -> None:
        r = np.asarray(self.pressure_ratio, dtype=float)
        n = r.size
        if r.ndim != 1 or n < 2:
            raise InputError(f"pressure_ratio must be 1-D with >= 2 points, got shape {r.shape}")
        if not (np.all(np.isfinite(r)) and r[0] > 0 and np.all(np.diff(r) > 0)):
            raise InputError("pressure_ratio must be finite, > 0 and strictly increasing")
        for name in POINT_FIELDS[1:]:
            arr = np.asarray(getattr(self, name))
            if arr.shape != (n,):
                raise InputError(f"{name} has shape {arr.shape}, expected ({n},)")
        for name in ERROR_FIELDS.values():
            err = getattr(self, name)
            if err is None:
                continue
            err = np.asarray(err, dtype=float)
            if err.shape != (n,) or not np.all(np.isfinite(err) & (err >= 0)):
                raise InputError(f"{name} must be finite, >= 0 and of shape ({n},)")
        h = np.asarray(self.clearance_m, dtype=float)
        if h.ndim != 1 or h.size < 2 or h[0] <= 0 or np.any(np.diff(h) <= 0):
            raise InputError("clearance_m must be 1-D, > 0 and strictly increasing")
        if np.shape(self.separated_mean_reciprocal_gap_per_m) != h.shape:
            raise InputError("separated_mean_reciprocal_gap_per_m must match clearance_m")
        if not (np.isfinite(self.gap_floor_m) and self.gap_floor_m > 0):
            raise InputError(f"gap_floor_m must be > 0, got {self.gap_floor_m!r}")
        full = np.asarray(self.full_contact, dtype=bool)
        if full.any() and not np.all(full[np.argmax(full) :]):
            raise InputError("full_contact must be False below and True above one ratio")
        if np.count_nonzero(~full) < 2:
            raise InputError("a table needs at least 2 partial-contact points")
        if np.any(np.asarray(self.real_contact_area_fraction)[~full] <= 0):
            raise InputError("real_contact_area_fraction must be > 0 at every loaded point")

    # ------------------------------------------------------------------ derived quantities
    @property
    def fourth_level_nodes(self) -> np.ndarray:
        """Indices of the nodes recombined with the adaptive fourth pixel level (may be empty)."""
        nodes = (self.levels or {}).get(f"{ADAPTIVE_LEVEL_PREFIX}node")
        return np.zeros(0, dtype=np.int64) if nodes is None else np.asarray(nodes, np.int64)

    @property
    def light_load_nodes(self) -> np.ndarray:
        """Indices of the nodes recombined with the light-load levels (may be empty)."""
        nodes = (self.levels or {}).get(f"{LIGHT_LOAD_PREFIX}node")
        return np.zeros(0, dtype=np.int64) if nodes is None else np.asarray(nodes, np.int64)

    @property
    def full_contact_reached(self) -> bool:
        """True if the grid reaches full contact (then every r ≥ r_fc is exact)."""
        return bool(np.any(self.full_contact))

    @property
    def pressure_ratio_range(self) -> tuple[float, float]:
        """Ratios covered by interpolation ``(r_min, r_max)``; r_max is inf at full contact."""
        hi = np.inf if self.full_contact_reached else float(self.pressure_ratio[-1])
        return float(self.pressure_ratio[0]), hi

    @cached_property
    def _loaded_interpolants(self) -> dict[str, PchipInterpolator]:
        partial = ~np.asarray(self.full_contact, dtype=bool)
        x = np.log(np.asarray(self.pressure_ratio, dtype=float)[partial])
        ar = np.asarray(self.real_contact_area_fraction, dtype=float)[partial]
        gap = np.asarray(self.mean_gap_m, dtype=float)[partial]
        rec = np.asarray(self.mean_reciprocal_gap_per_m, dtype=float)[partial]
        if self.full_contact_reached:
            x = np.append(x, np.log(self.full_contact_pressure_ratio))
            ar = np.append(ar, 1.0)
            gap = np.append(gap, 0.0)
            rec = np.append(rec, 1.0 / self.gap_floor_m)
        return {
            "ar": PchipInterpolator(x, np.log(ar)),
            "gap": PchipInterpolator(x[gap > 0], np.log(gap[gap > 0])),
            "rec": PchipInterpolator(x, np.log(rec)),
        }

    @cached_property
    def _last_partial_ratio(self) -> float:
        partial = ~np.asarray(self.full_contact, dtype=bool)
        return float(np.asarray(self.pressure_ratio)[partial][-1])

    @cached_property
    def _separated_interpolant(self) -> PchipInterpolator:
        return PchipInterpolator(
            np.log(np.asarray(self.clearance_m, dtype=float)),
            np.log(np.asarray(self.separated_mean_reciprocal_gap_per_m, dtype=float)),
        )


# ---------------------------------------------------------------------------- helpers


def nominal_pressure_ratio(pressure_pa, porosity, effective_modulus_pa) -> np.ndarray | float:
    """Dimensionless nominal pressure ``P_n / E' = P (1 − n) / E'`` (docs/physics.md eq. 2).

    Parameters
    ----------
    pressure_pa : float or array_like
        Apparent (macro-scale) pressure P ≥ 0 [Pa].
    porosity : float or array_like
        Snow porosity n, 0 ≤ n < 1 [-].
    effective_modulus_pa : float or array_like
        Effective modulus E' > 0 of docs/physics.md eq. (1) [Pa].

    Returns
    -------
    float or ndarray
        ``P_n / E'`` [-], broadcast over the inputs.
    """
    p = _finite("pressure_pa", pressure_pa)
    n = _finite("porosity", porosity)
    e = _finite("effective_modulus_pa", effective_modulus_pa)
    if np.any(p < 0):
        raise InputError(f"pressure_pa must be >= 0, got min {np.min(p)!r}")
    if np.any((n < 0) | (n >= 1)):
        raise InputError(f"porosity must be in [0, 1), got {porosity!r}")
    if np.any(e <= 0):
        raise InputError(f"effective_modulus_pa must be > 0, got {effective_modulus_pa!r}")
    return _out(p * (1.0 - n) / e)


def _finite(name: str, value) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} must be numeric, got {value!r}") from exc
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} must be finite, got {value!r}")
    return arr


def _out(arr: np.ndarray):
    return float(arr) if arr.ndim == 0 else arr


def _check_mode(out_of_range: str) -> None:
    if out_of_range not in ("raise", "flag"):
        raise InputError(f"out_of_range must be 'raise' or 'flag', got {out_of_range!r}")


def _snap(v: np.ndarray, lo: float, hi: float) -> np.ndarray:
    v = np.where((v < lo) & (v >= lo * (1 - _EDGE_RTOL)), lo, v)
    if np.isfinite(hi):
        v = np.where((v > hi) & (v <= hi * (1 + _EDGE_RTOL)), hi, v)
    return v


def _finish(values, flagged, what: str, lo: float, hi: float, bad, out_of_range: str):
    if np.any(flagged):
        if out_of_range == "raise":
            first = float(np.asarray(bad)[flagged].ravel()[0])
            raise OutOfRangeError(
                f"{what} {first:.6g} outside the table range [{lo:.6g}, {hi:.6g}] "
                f"({int(np.count_nonzero(flagged))} point(s)); not extrapolated"
            )
        values = np.where(flagged, np.nan, values)
    values = _out(values)
    if out_of_range == "flag":
        return values, (bool(flagged) if np.ndim(flagged) == 0 else flagged)
    return values


def _loaded(
    table: MicroTable, nominal_pressure_pa, effective_modulus_pa, quantity: str, out_of_range: str
):
    _check_mode(out_of_range)
    p = _finite("nominal_pressure_pa", nominal_pressure_pa)
    e = _finite("effective_modulus_pa", effective_modulus_pa)
    if np.any(p < 0):
        raise InputError(f"nominal_pressure_pa must be >= 0, got min {np.min(p)!r}")
    if np.any(e <= 0):
        raise InputError(f"effective_modulus_pa must be > 0, got {effective_modulus_pa!r}")
    ratio = np.asarray(p / e, dtype=float)
    lo, hi = table.pressure_ratio_range
    r = _snap(ratio, lo, hi)
    zero = r == 0
    flagged = ~zero & ((r < lo) | (r > hi))
    full = table.full_contact_reached & (r >= table.full_contact_pressure_ratio)
    inside = ~zero & ~flagged & ~full
    x = np.log(np.where(inside, r, lo))
    f = table._loaded_interpolants[quantity](x)
    if quantity == "ar":
        values = np.where(inside, np.exp(f), np.where(full, 1.0, 0.0))
    elif quantity == "gap":
        values = np.where(inside, np.exp(f), np.where(full, 0.0, table.unloaded_mean_gap_m))
        last = table._last_partial_ratio
        closing = inside & (r > last)
        if np.any(closing):  # last segment to full contact: linear in r down to gap 0
            r_fc = table.full_contact_pressure_ratio
            gap_last = float(table.mean_gap_m[~np.asarray(table.full_contact)][-1])
            values = np.where(closing, gap_last * (r_fc - r) / (r_fc - last), values)
    else:
        values = np.where(
            inside,
            np.exp(f),
            np.where(full, 1.0 / table.gap_floor_m, table.unloaded_mean_reciprocal_gap_per_m),
        )
    return _finish(values, flagged, "pressure ratio P_n/E'", lo, hi, ratio, out_of_range)


# ---------------------------------------------------------------------------- lookups


def real_contact_area_fraction(
    table: MicroTable, nominal_pressure_pa, effective_modulus_pa, *, out_of_range: str = "raise"
):
    """Real contact area fraction a_r(P_n) [-] (docs/physics.md eq. 3).

    Parameters
    ----------
    table : MicroTable
        The texture's table.
    nominal_pressure_pa : float or array_like
        Nominal pressure P_n = P (1 − n) ≥ 0 [Pa].
    effective_modulus_pa : float or array_like
        E' [Pa], broadcast against the pressures.
    out_of_range : {"raise", "flag"}
        Raise :class:`~solvers.errors.OutOfRangeError` for a ratio outside the table, or
        return ``(values, flagged)`` with NaN at the flagged points.

    Returns
    -------
    float or ndarray, or (values, flagged)
        a_r [-]; 0 at zero load, exactly 1 at or above full contact (if tabulated).
    """
    return _loaded(table, nominal_pressure_pa, effective_modulus_pa, "ar", out_of_range)


def mean_gap_m(
    table: MicroTable, nominal_pressure_pa, effective_modulus_pa, *, out_of_range: str = "raise"
):
    """Mean interfacial separation h̄_n(P_n) over the cell [m] (docs/physics.md eq. 4, H = 0).

    Parameters and return as :func:`real_contact_area_fraction`; ⟨h_0⟩ at zero load, 0 at
    full contact.
    """
    return _loaded(table, nominal_pressure_pa, effective_modulus_pa, "gap", out_of_range)


def mean_reciprocal_gap_per_m(
    table: MicroTable, nominal_pressure_pa, effective_modulus_pa, *, out_of_range: str = "raise"
):
    """Floored mean reciprocal separation (1/h)‾_n(P_n) over the gap set [1/m].

    Method.md eq. (5) with H = 0 and n = 0 (multiply by ``1 − n`` for eq. 5), gap floor
    ``table.gap_floor_m``. Parameters and return as :func:`real_contact_area_fraction`;
    ``⟨1/max(h_0, h_c)⟩`` at zero load, ``1/h_c`` at full contact.
    """
    return _loaded(table, nominal_pressure_pa, effective_modulus_pa, "rec", out_of_range)


def separated_reciprocal_gap_per_m(table: MicroTable, clearance_m, *, out_of_range: str = "raise"):
    """⟨1/(h_0 + H)⟩ over the cell for an unloaded texture at clearance H [1/m].

    Method.md eq. (5) where P = 0 (ω_g = ω), with n = 0 (multiply by ``1 − n``).

    Parameters
    ----------
    table : MicroTable
        The texture's table.
    clearance_m : float or array_like
        Clearance H > 0 between the texture's highest point and the snow [m], within
        ``[table.clearance_m[0], table.clearance_m[-1]]``.
    out_of_range : {"raise", "flag"}
        As in :func:`real_contact_area_fraction`.
    """
    _check_mode(out_of_range)
    h = _finite("clearance_m", clearance_m)
    if np.any(h < 0):
        raise InputError(f"clearance_m must be >= 0, got min {np.min(h)!r}")
    lo, hi = float(table.clearance_m[0]), float(table.clearance_m[-1])
    hh = _snap(h, lo, hi)
    flagged = (hh < lo) | (hh > hi)
    f = table._separated_interpolant(np.log(np.where(flagged, lo, hh)))
    return _finish(np.exp(f), flagged, "clearance_m", lo, hi, h, out_of_range)


def separated_mean_gap_m(table: MicroTable, clearance_m) -> np.ndarray | float:
    """Mean separation ⟨h_0⟩ + H of an unloaded texture at clearance H ≥ 0 [m] (exact)."""
    h = _finite("clearance_m", clearance_m)
    if np.any(h < 0):
        raise InputError(f"clearance_m must be >= 0, got min {np.min(h)!r}")
    return _out(table.unloaded_mean_gap_m + h)


def relative_error_estimate(
    table: MicroTable, nominal_pressure_pa, effective_modulus_pa, quantity: str
) -> np.ndarray | float | None:
    """Estimated relative error against the zero-pixel limit at interpolated points [-].

    The tabulated relative error ``error / value`` of ``quantity`` (a key of
    :data:`ERROR_FIELDS`) is interpolated linearly in ``ln r`` between the table points; 0 at
    zero load and at or above full contact (exact states); NaN outside the table. ``None`` if
    the table carries no estimates (tables built on one pixel size).
    """
    if quantity not in ERROR_FIELDS:
        raise InputError(f"quantity must be one of {sorted(ERROR_FIELDS)}, got {quantity!r}")
    if not table.has_error_estimates:
        return None
    p = _finite("nominal_pressure_pa", nominal_pressure_pa)
    e = _finite("effective_modulus_pa", effective_modulus_pa)
    ratio = np.asarray(p / e, dtype=float)
    lo, hi = table.pressure_ratio_range
    r = _snap(ratio, lo, hi)
    partial = ~np.asarray(table.full_contact, dtype=bool)
    value = np.asarray(getattr(table, quantity), dtype=float)[partial]
    err = np.asarray(getattr(table, ERROR_FIELDS[quantity]), dtype=float)[partial]
    rel = np.divide(err, np.abs(value), out=np.zeros_like(err), where=value != 0)
    x = np.log(np.asarray(table.pressure_ratio, dtype=float)[partial])
    full = table.full_contact_reached & (r >= table.full_contact_pressure_ratio)
    inside = (r > 0) & (r >= lo) & (r <= hi) & ~full
    out = np.interp(np.log(np.where(inside, r, lo)), x, rel)
    out = np.where(inside, out, np.where((r == 0) | full, 0.0, np.nan))
    return _out(out)


# ---------------------------------------------------------------------------- pixel levels


def richardson(
    coarse: np.ndarray, fine: np.ndarray, order: float | None, refinement: float = 2.0
) -> tuple[np.ndarray, np.ndarray]:
    """Zero-pixel extrapolation of a quantity from two pixel sizes, with its error estimate.

    ``f_0 ≈ f_fine + (f_fine − f_coarse) / (k^p − 1)`` (Richardson), k the pixel-size ratio,
    p the order of the leading error term. The error estimate is the size of the correction,
    ``|f_0 − f_fine|``: the extrapolated value is taken to be at least as close to the limit
    as the finest level is to it (conservative where the order holds; Roache's grid
    convergence index of the fine level with safety factor 1). ``order=None`` (no clear
    order): ``f_fine`` is kept and the estimate is the last change ``|f_fine − f_coarse|``.

    Parameters
    ----------
    coarse, fine : array_like
        The quantity at pixel sizes ``k·Δ`` and ``Δ`` [any unit].
    order : float or None
        p > 0 [-].
    refinement : float
        k > 1 [-].

    Returns
    -------
    (ndarray, ndarray)
        Extrapolated value and error estimate [unit of the input].
    """
    c = np.asarray(coarse, dtype=float)
    f = np.asarray(fine, dtype=float)
    if not refinement > 1:
        raise InputError(f"refinement must be > 1, got {refinement!r}")
    if order is None:
        return f.copy(), np.abs(f - c)
    if not order > 0:
        raise InputError(f"order must be > 0 or None, got {order!r}")
    correction = (f - c) / (refinement**order - 1)
    return f + correction, np.abs(correction)


def combine_pixel_levels(
    coarse: dict[str, np.ndarray],
    fine: dict[str, np.ndarray],
    refinement: float = 2.0,
    orders: dict[str, float | None] | None = None,
) -> dict[str, np.ndarray]:
    """Table arrays of the zero-pixel limit from two levels of :func:`solve_table_chunk`.

    Points where both levels are in partial contact are extrapolated by :func:`richardson`
    with the order of each quantity (:data:`PIXEL_EXTRAPOLATION_ORDERS`). Where the levels
    differ in full contact, or an extrapolated a_r leaves (0, 1] or a mean gap leaves
    ``(0, ∞)`` (a few contact pixels), the fine level is kept and its estimate is the change
    ``|fine − coarse|``. Full contact at both levels is exact (estimate 0). Flags
    (``full_contact``, ``converged`` of both levels) and solver diagnostics follow the fine
    level; the raw reciprocal gap (diagnosis only) is the fine level's.

    Returns
    -------
    dict of ndarray
        The keys of :func:`solve_table_chunk` plus the error arrays of :data:`ERROR_FIELDS`.
    """
    orders = PIXEL_EXTRAPOLATION_ORDERS if orders is None else orders
    fc = np.asarray(coarse["full_contact"], dtype=bool)
    ff = np.asarray(fine["full_contact"], dtype=bool)
    both = ~fc & ~ff
    out = {k: np.array(v, copy=True) for k, v in fine.items()}
    out["converged"] = np.asarray(fine["converged"], bool) & np.asarray(coarse["converged"], bool)
    for quantity, err_name in ERROR_FIELDS.items():
        c = np.asarray(coarse[quantity], dtype=float)
        f = np.asarray(fine[quantity], dtype=float)
        value, err = richardson(c, f, orders.get(quantity), refinement)
        bad = ~both | (value <= 0)
        if quantity == "real_contact_area_fraction":
            bad |= value > 1
        value = np.where(bad, f, value)
        err = np.where(bad, np.abs(f - c), err)
        exact = fc & ff
        out[quantity] = np.where(exact, f, value)
        out[err_name] = np.where(exact, 0.0, err)
    return out


def observed_order(coarse, middle, fine, refinement: float = 2.0) -> np.ndarray:
    """Observed order of convergence from three pixel sizes ``k²Δ, kΔ, Δ`` [-].

    ``p_obs = ln((f_middle − f_coarse) / (f_fine − f_middle)) / ln k``; NaN where the two
    changes differ in sign or one is zero (no monotone convergence, no order).
    """
    if not refinement > 1:
        raise InputError(f"refinement must be > 1, got {refinement!r}")
    d_coarse = np.asarray(middle, dtype=float) - np.asarray(coarse, dtype=float)
    d_fine = np.asarray(fine, dtype=float) - np.asarray(middle, dtype=float)
    ok = d_coarse * d_fine > 0
    ratio = np.divide(d_coarse, d_fine, out=np.ones_like(d_fine), where=ok)
    return np.where(ok, np.log(np.abs(ratio)) / np.log(refinement), np.nan)


def combine_three_pixel_levels(
    coarse: dict[str, np.ndarray],
    middle: dict[str, np.ndarray],
    fine: dict[str, np.ndarray],
    refinement: float = 2.0,
    orders: dict[str, float | None] | None = None,
    order_tolerance: float = ORDER_TOLERANCE,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Table arrays of the zero-pixel limit from three levels (pixel sizes ``k²Δ, kΔ, Δ``).

    The value is the two-level result of the two finest levels
    (:func:`combine_pixel_levels` of ``middle`` and ``fine``: Richardson extrapolant
    ``R(kΔ, Δ)`` with the assumed order of :data:`PIXEL_EXTRAPOLATION_ORDERS`, the same
    fall-backs). The error estimate uses all three levels where they are all in partial
    contact and the quantity has an order p:

    - the observed order :func:`observed_order` is within ``order_tolerance`` of p (the levels
      are in the asymptotic range): the difference of the successive extrapolants,
      ``|R(kΔ, Δ) − R(k²Δ, kΔ)|``. With a next error term of order q > p this is
      ``(k^q − 1)`` times the remaining error of ``R(kΔ, Δ)`` (≥ it for k = 2, q ≥ 1);
    - otherwise (no stable order): the larger of that difference and the two-level estimate
      ``|R(kΔ, Δ) − f_fine|`` (conservative).

    Elsewhere (no order, full contact at a level, failed extrapolation) the estimate of
    :func:`combine_pixel_levels` of the two finest levels is kept.

    Returns
    -------
    (dict of ndarray, dict of ndarray)
        The table arrays as :func:`combine_pixel_levels` returns them, and per quantity
        ``observed_order_<quantity>`` [-] (NaN where undefined) and
        ``three_level_estimate_<quantity>`` (1 where the three-level estimate is used, 0 where
        the conservative fall-back is, -1 where only two levels enter) [-].
    """
    orders = PIXEL_EXTRAPOLATION_ORDERS if orders is None else orders
    if not (np.isfinite(order_tolerance) and order_tolerance > 0):
        raise InputError(f"order_tolerance must be > 0, got {order_tolerance!r}")
    out = combine_pixel_levels(middle, fine, refinement, orders)
    out["converged"] = out["converged"] & np.asarray(coarse["converged"], bool)
    partial = ~(
        np.asarray(coarse["full_contact"], bool)
        | np.asarray(middle["full_contact"], bool)
        | np.asarray(fine["full_contact"], bool)
    )
    info: dict[str, np.ndarray] = {}
    for quantity, err_name in ERROR_FIELDS.items():
        c, m, f = (np.asarray(d[quantity], dtype=float) for d in (coarse, middle, fine))
        p_obs = np.where(partial, observed_order(c, m, f, refinement), np.nan)
        info[f"observed_order_{quantity}"] = p_obs
        method = np.full(f.shape, -1.0)
        order = orders.get(quantity)
        if order is not None:
            r_fine, _ = richardson(m, f, order, refinement)
            r_coarse, _ = richardson(c, m, order, refinement)
            # where combine_pixel_levels extrapolated (its fall-backs: see there)
            extrapolated = partial & (r_fine > 0)
            if quantity == "real_contact_area_fraction":
                extrapolated &= r_fine <= 1
            successive = np.abs(r_fine - r_coarse)
            stable = np.abs(p_obs - order) <= order_tolerance  # False where p_obs is NaN
            err = np.where(stable, successive, np.maximum(successive, out[err_name]))
            out[err_name] = np.where(extrapolated, err, out[err_name])
            method = np.where(extrapolated, np.where(stable, 1.0, 0.0), method)
        info[f"three_level_estimate_{quantity}"] = method
    return out, info


# ---------------------------------------------------------------------------- fourth level
# An adaptive fourth pixel level at the nodes where three levels do not show a stable order
# (docs/tables.md, "Adaptive fourth level"). The rule is fixed in advance, not tuned to the
# outcome: select (:func:`select_fourth_level_nodes`), solve those nodes once more at half the
# finest pixel (app/jobs/table_fourth_level.py), recombine them from their three finest levels
# with the unchanged three-level rule (:func:`combine_with_fourth_level`). One extra level at
# most.

#: per-point keys of a level (as :func:`solve_table_chunk` returns them, without time)
_LEVEL_KEYS = (
    "real_contact_area_fraction",
    "mean_gap_m",
    "mean_reciprocal_gap_per_m",
    "mean_reciprocal_gap_raw_per_m",
    "iterations",
    "converged",
    "full_contact",
)


def select_fourth_level_nodes(
    real_contact_area_fraction,
    three_level_estimate: dict[str, np.ndarray],
    orders: dict[str, float | None] | None = None,
    a_r_range: tuple[float, float] = ESTIMATE_RANGE_A_R,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Nodes of a three-level table that get the adaptive fourth pixel level.

    A node is selected when its a_r (the table's value) lies in ``a_r_range`` (inclusive) and
    the three-level rule fell back (``three_level_estimate_<q> == 0``:
    :func:`combine_three_pixel_levels` found no observed order within the tolerance of the
    assumed one) for at least one quantity q with an order (:data:`PIXEL_EXTRAPOLATION_ORDERS`
    not None: a_r and the mean gap).

    Parameters
    ----------
    real_contact_area_fraction : array_like, shape (N,)
        The table's a_r [-].
    three_level_estimate : dict of str to array_like, shape (N,)
        ``three_level_estimate_<q>`` per quantity q, keyed by q (1 stable, 0 fall-back,
        -1 two levels) [-].
    orders : dict, optional
        Assumed orders (default :data:`PIXEL_EXTRAPOLATION_ORDERS`).
    a_r_range : (float, float)
        The a_r range [-] (default :data:`ESTIMATE_RANGE_A_R`).

    Returns
    -------
    (ndarray of int, dict of str to ndarray of bool)
        The selected node indices, rising, and per quantity with an order whether it fell
        back at each selected node (which quantities triggered the node).
    """
    orders = PIXEL_EXTRAPOLATION_ORDERS if orders is None else orders
    a = np.asarray(real_contact_area_fraction, dtype=float)
    lo, hi = a_r_range
    if not 0 < lo < hi <= 1:
        raise InputError(f"a_r_range must satisfy 0 < low < high <= 1, got {a_r_range!r}")
    in_range = (a >= lo) & (a <= hi)
    fell_back = {}
    for quantity, order in orders.items():
        if order is None:
            continue
        if quantity not in three_level_estimate:
            raise InputError(f"three_level_estimate has no entry for {quantity!r}")
        method = np.asarray(three_level_estimate[quantity], dtype=float)
        if method.shape != a.shape:
            raise InputError(
                f"three_level_estimate[{quantity!r}] has shape {method.shape}, expected {a.shape}"
            )
        fell_back[quantity] = in_range & (method == 0)
    selected = np.zeros(a.shape, dtype=bool)
    for mask in fell_back.values():
        selected |= mask
    nodes = np.flatnonzero(selected).astype(np.int64)
    return nodes, {q: mask[nodes] for q, mask in fell_back.items()}


def combine_with_fourth_level(
    levels: dict[str, np.ndarray],
    nodes,
    fourth: dict[str, np.ndarray],
    refinement: float = 2.0,
    orders: dict[str, float | None] | None = None,
    order_tolerance: float = ORDER_TOLERANCE,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Recombine nodes of a three-level table from its two finest levels and a fourth one.

    :func:`combine_three_pixel_levels` (same orders, tolerance and fall-backs) of the stored
    middle and finest levels and the fourth level, pixel sizes ``kΔ, Δ, Δ/k``; the coarsest
    stored level no longer enters.

    Parameters
    ----------
    levels : dict
        A three-level table's ``levels`` (per-level arrays of shape (3, N), coarse first).
    nodes : array_like of int, shape (K,)
        The recombined node indices.
    fourth : dict of str to ndarray, shape (K,)
        The fourth level at those nodes: the keys of :func:`solve_table_chunk`.

    Returns
    -------
    (dict of ndarray, dict of ndarray)
        As :func:`combine_three_pixel_levels`, over the K nodes.
    """
    idx = np.asarray(nodes, dtype=np.int64)
    count = np.shape(levels["real_contact_area_fraction"])[0]
    if count != 3:
        raise InputError(f"a fourth level needs a three-level table, got {count} level(s)")
    stored = [{key: np.asarray(levels[key])[i, idx] for key in _LEVEL_KEYS} for i in (1, 2)]
    finest = {key: np.asarray(value) for key, value in fourth.items() if key != "solve_time_s"}
    for key in _LEVEL_KEYS:
        if np.shape(finest.get(key)) != idx.shape:
            raise InputError(f"fourth level {key!r} must have shape {idx.shape}")
    return combine_three_pixel_levels(
        *stored, finest, refinement=refinement, orders=orders, order_tolerance=order_tolerance
    )


def _rising_nodes(table: MicroTable, nodes) -> np.ndarray:
    """``nodes`` as rising int64 indices into ``table`` (InputError otherwise)."""
    idx = np.asarray(nodes, dtype=np.int64)
    n = table.pressure_ratio.size
    if idx.size and (np.any(np.diff(idx) <= 0) or idx[0] < 0 or idx[-1] >= n):
        raise InputError(f"nodes must be rising indices into the table, got {idx.tolist()}")
    return idx


def _recombined_fields(table: MicroTable, idx: np.ndarray, out: dict) -> tuple[dict, dict]:
    """Copies of the table's point and error arrays with nodes ``idx`` replaced by ``out``
    (a combination's values, estimates, and the finest level's raw reciprocal gap,
    iterations and residual where it has them; ``converged`` of every level), and the values
    and estimates the nodes had before (``previous_<name>``)."""
    fields = {
        name: np.array(getattr(table, name), copy=True)
        for name in (*POINT_FIELDS[1:], *ERROR_FIELDS.values())
    }
    previous = {}
    for quantity, err_name in ERROR_FIELDS.items():
        previous[f"previous_{quantity}"] = fields[quantity][idx]
        previous[f"previous_{err_name}"] = fields[err_name][idx]
    if not idx.size:
        return fields, previous
    for quantity, err_name in ERROR_FIELDS.items():
        fields[quantity][idx] = out[quantity]
        fields[err_name][idx] = out[err_name]
    for name in ("mean_reciprocal_gap_raw_per_m", "iterations", "residual"):
        if name in out:  # residual: only levels solved by the pass carry it
            fields[name][idx] = out[name]
    fields["converged"][idx] = fields["converged"][idx] & out["converged"]
    return fields, previous


def _with_fields(table: MicroTable, fields: dict, levels: dict) -> MicroTable:
    """A copy of ``table`` with new point arrays and levels (and its non-converged count)."""
    return replace(
        table,
        **fields,
        levels=levels,
        attrs={**table.attrs, "points_not_converged": int(np.count_nonzero(~fields["converged"]))},
    )


def with_fourth_level(
    table: MicroTable,
    nodes,
    fourth: dict[str, np.ndarray],
    *,
    pixel_size_m: float,
    full_contact_pressure_ratio: float,
    selected_by: dict[str, np.ndarray],
    refinement: float = 2.0,
) -> MicroTable:
    """A copy of a three-level table with ``nodes`` recombined from the fourth level.

    At each node the values, error estimates, iterations, residual and raw reciprocal gap
    of ``table`` are replaced by :func:`combine_with_fourth_level`'s (``converged``: all four
    levels). ``levels`` gains, with prefix :data:`ADAPTIVE_LEVEL_PREFIX`: ``node`` (K,),
    ``pressure_ratio`` (K,), ``pixel_size_m`` and ``full_contact_pressure_ratio`` of the fourth
    level (scalars), the fourth level's values (the keys of :func:`solve_table_chunk` and
    ``residual``, (K,)), the rule used per node and quantity
    (``observed_order_<q>``, ``three_level_estimate_<q>`` from the three finest levels),
    which quantities selected the node (``selected_by_<q>``), and the three-level values and
    estimates the node had before (``previous_<q>``, ``previous_<error name>``).

    Parameters
    ----------
    table : MicroTable
        A three-level table without a fourth level.
    nodes : array_like of int, shape (K,)
        Node indices (:func:`select_fourth_level_nodes`).
    fourth : dict of str to ndarray, shape (K,)
        The fourth level's results at the nodes.
    pixel_size_m : float
        Pixel size of the fourth level [m].
    full_contact_pressure_ratio : float
        ``p_fc / E'`` of the fourth-level surface [-].
    selected_by : dict of str to ndarray of bool, shape (K,)
        Per quantity, whether it selected the node.
    refinement : float
        Pixel-size ratio between successive levels [-].
    """
    if table.levels is None or f"{ADAPTIVE_LEVEL_PREFIX}node" in table.levels:
        raise InputError(
            "a fourth level is added once, to a three-level table without one"
            + ("" if table.levels is None else f" ({table.name!r} already has it)")
        )
    idx = _rising_nodes(table, nodes)
    out, info = combine_with_fourth_level(table.levels, idx, fourth, refinement)
    fields, previous = _recombined_fields(table, idx, out)
    p = ADAPTIVE_LEVEL_PREFIX
    levels = dict(table.levels)
    levels[f"{p}node"] = idx
    levels[f"{p}pressure_ratio"] = np.asarray(table.pressure_ratio, dtype=float)[idx]
    levels[f"{p}pixel_size_m"] = np.asarray(float(pixel_size_m))
    levels[f"{p}full_contact_pressure_ratio"] = np.asarray(float(full_contact_pressure_ratio))
    for key in (*_LEVEL_KEYS, "residual"):
        levels[f"{p}{key}"] = np.asarray(fourth[key])
    for key, value in info.items():
        levels[f"{p}{key}"] = value
    for quantity, mask in selected_by.items():
        levels[f"{p}selected_by_{quantity}"] = np.asarray(mask, dtype=bool)
    for key, value in previous.items():
        levels[f"{p}{key}"] = value
    return _with_fields(table, fields, levels)


# ---------------------------------------------------------------------------- light loads
# Several finer pixel levels at the light-load nodes (a_r in LIGHT_LOAD_RANGE_A_R), where a
# 1024² cell holds a few hundred contact pixels and the order is not yet asymptotic. The rule
# is fixed in advance, not tuned to the outcome: select (:func:`select_light_load_nodes`),
# solve every selected node cold on each finer level down to a target grid
# (app/jobs/table_light_levels.py), recombine each node from its three finest levels with the
# unchanged three-level rule (:func:`combine_with_light_load_levels`).


def select_light_load_nodes(
    real_contact_area_fraction,
    full_contact=None,
    exclude=(),
    a_r_range: tuple[float, float] = LIGHT_LOAD_RANGE_A_R,
) -> np.ndarray:
    """Nodes of a table that get the light-load levels.

    Every partial-contact node whose a_r (the table's value) lies in ``[low, high)``, and the
    node just below the lowest of them (when it is in partial contact with a_r > 0), so that
    the table interpolates between refined nodes over the whole range. ``exclude`` (e.g. the
    nodes of the adaptive fourth level) are left out.

    Parameters
    ----------
    real_contact_area_fraction : array_like, shape (N,)
        The table's a_r [-] (rising with the pressure ratio).
    full_contact : array_like of bool, shape (N,), optional
        The table's full-contact flags (default: none).
    exclude : iterable of int
        Node indices never selected.
    a_r_range : (float, float)
        ``(low, high)`` [-] (default :data:`LIGHT_LOAD_RANGE_A_R`).

    Returns
    -------
    ndarray of int
        The selected node indices, rising.
    """
    a = np.asarray(real_contact_area_fraction, dtype=float)
    lo, hi = a_r_range
    if not 0 < lo < hi <= 1:
        raise InputError(f"a_r_range must satisfy 0 < low < high <= 1, got {a_r_range!r}")
    partial = np.ones(a.shape, bool) if full_contact is None else ~np.asarray(full_contact, bool)
    if partial.shape != a.shape:
        raise InputError(f"full_contact has shape {partial.shape}, expected {a.shape}")
    selected = partial & (a >= lo) & (a < hi)
    if selected.any():
        below = int(np.argmax(selected)) - 1
        if below >= 0 and partial[below] and a[below] > 0:
            selected[below] = True
    for node in exclude:
        selected[int(node)] = False
    return np.flatnonzero(selected).astype(np.int64)


def _stored_levels_at(levels: dict[str, np.ndarray], idx: np.ndarray) -> list[dict]:
    """The stored levels of a table at nodes ``idx``, coarse first (one dict per level)."""
    count = np.shape(levels["real_contact_area_fraction"])[0]
    return [{key: np.asarray(levels[key])[i, idx] for key in _LEVEL_KEYS} for i in range(count)]


def combine_with_light_load_levels(
    levels: dict[str, np.ndarray],
    nodes,
    extra: list[dict[str, np.ndarray]],
    refinement: float = 2.0,
    orders: dict[str, float | None] | None = None,
    order_tolerance: float = ORDER_TOLERANCE,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Recombine nodes from their three finest levels: stored levels, then ``extra`` ones.

    :func:`combine_three_pixel_levels` (same orders, tolerance and fall-backs) of the three
    finest of the table's stored levels at ``nodes`` followed by the ``extra`` levels (each
    ``refinement``× finer than the one before).

    Parameters
    ----------
    levels : dict
        The table's ``levels`` (per-level arrays (L, N), coarse first; L ≥ 2).
    nodes : array_like of int, shape (K,)
        The recombined node indices.
    extra : list of dict of str to ndarray, shape (K,)
        The extra levels at those nodes, coarse first: the keys of :func:`solve_table_chunk`.

    Returns
    -------
    (dict of ndarray, dict of ndarray)
        As :func:`combine_three_pixel_levels`, over the K nodes.
    """
    idx = np.asarray(nodes, dtype=np.int64)
    if levels is None:
        raise InputError("light-load levels need a table of two or more pixel levels")
    stack = _stored_levels_at(levels, idx)
    for j, level in enumerate(extra):
        for key in _LEVEL_KEYS:
            if np.shape(level.get(key)) != idx.shape:
                raise InputError(f"extra level {j} {key!r} must have shape {idx.shape}")
        stack.append({key: np.asarray(v) for key, v in level.items() if key != "solve_time_s"})
    if len(stack) < 3:
        raise InputError(f"three levels are needed, got {len(stack)} with the extra ones")
    return combine_three_pixel_levels(
        *stack[-3:], refinement=refinement, orders=orders, order_tolerance=order_tolerance
    )


def with_light_load_levels(
    table: MicroTable,
    nodes,
    extra: list[dict[str, np.ndarray]],
    *,
    pixel_sizes_m,
    full_contact_pressure_ratios,
    refinement: float = 2.0,
) -> MicroTable:
    """A copy of a table with ``nodes`` recombined from their three finest levels.

    At each node the values, error estimates, iterations, residual and raw reciprocal gap are
    replaced by :func:`combine_with_light_load_levels`'s (``converged``: also every level
    before). ``levels`` gains, with prefix :data:`LIGHT_LOAD_PREFIX`: ``node`` (K,),
    ``pressure_ratio`` (K,), ``pixel_size_m`` and ``full_contact_pressure_ratio`` of the extra
    levels (E,), their values (the keys of :func:`solve_table_chunk` and ``residual``,
    (E, K)), the rule used per node and quantity (``observed_order_<q>``,
    ``three_level_estimate_<q>``, (K,)) and the values and estimates the nodes had before
    (``previous_<q>``, ``previous_<error name>``, (K,)).

    Parameters
    ----------
    table : MicroTable
        A table of two or three stored levels (with or without the adaptive fourth level:
        its nodes are never light-load nodes) and without light-load levels.
    nodes : array_like of int, shape (K,)
        Rising node indices (:func:`select_light_load_nodes`).
    extra : list of dict of str to ndarray, shape (K,)
        The extra levels at the nodes, coarse first (each ``refinement``× finer).
    pixel_sizes_m : array_like, shape (E,)
        Pixel size of each extra level [m].
    full_contact_pressure_ratios : array_like, shape (E,)
        ``p_fc / E'`` of each extra level's surface [-].
    refinement : float
        Pixel-size ratio between successive levels [-].
    """
    p = LIGHT_LOAD_PREFIX
    if table.levels is None:
        raise InputError(f"{table.name!r} has one pixel level: light-load levels need two or more")
    if f"{p}node" in table.levels:
        raise InputError(f"{table.name!r} already has light-load levels")
    idx = _rising_nodes(table, nodes)
    overlap = np.intersect1d(idx, table.fourth_level_nodes)
    if overlap.size:
        raise InputError(f"nodes {overlap.tolist()} have the adaptive fourth level already")
    pixel_sizes = np.asarray(pixel_sizes_m, dtype=float).reshape(-1)
    ratios_fc = np.asarray(full_contact_pressure_ratios, dtype=float).reshape(-1)
    if pixel_sizes.size != len(extra) or ratios_fc.size != len(extra):
        raise InputError("one pixel size and full-contact ratio per extra level")
    if idx.size:
        out, info = combine_with_light_load_levels(table.levels, idx, extra, refinement)
    else:
        out, info = {}, {}
    fields, previous = _recombined_fields(table, idx, out)
    levels = dict(table.levels or {})
    levels[f"{p}node"] = idx
    levels[f"{p}pressure_ratio"] = np.asarray(table.pressure_ratio, dtype=float)[idx]
    levels[f"{p}pixel_size_m"] = pixel_sizes
    levels[f"{p}full_contact_pressure_ratio"] = ratios_fc
    for key in (*_LEVEL_KEYS, "residual"):
        levels[f"{p}{key}"] = (
            np.stack([np.asarray(level[key]) for level in extra])
            if extra
            else np.zeros((0, idx.size))
        )
    for key, value in info.items():
        levels[f"{p}{key}"] = value
    for key, value in previous.items():
        levels[f"{p}{key}"] = value
    return _with_fields(table, fields, levels)


# ---------------------------------------------------------------------------- building
# Pure kernels of the table build (the job itself, with files and scheduling, lives in
# app/jobs/table_build.py).


def pressure_ratio_grid(ratio_min: float, ratio_max: float, points: int) -> np.ndarray:
    """Log-spaced grid of nominal pressure ratios ``P_n / E'`` [-] (``numpy.geomspace``)."""
    if not (np.isfinite(ratio_min) and np.isfinite(ratio_max) and 0 < ratio_min < ratio_max):
        raise InputError(
            f"need 0 < ratio_min < ratio_max, got ratio_min={ratio_min!r}, ratio_max={ratio_max!r}"
        )
    if int(points) != points or points < 2:
        raise InputError(f"points must be an integer >= 2, got {points!r}")
    return np.geomspace(ratio_min, ratio_max, int(points))


def chunk_bounds(points: int, chunk_size: int) -> list[tuple[int, int]]:
    """Contiguous ``[start, stop)`` index ranges of a grid, fixed by its size and chunk size only.

    The chunks never depend on the number of workers, so a table is the same however many
    workers compute it.
    """
    if int(chunk_size) != chunk_size or chunk_size < 1:
        raise InputError(f"chunk_size must be an integer >= 1, got {chunk_size!r}")
    return [(s, min(s + int(chunk_size), int(points))) for s in range(0, int(points), chunk_size)]


def unloaded_statistics(heights_m: np.ndarray, gap_floor_m: float) -> tuple[float, float]:
    """⟨h_0⟩ [m] and ⟨1/max(h_0, h_c)⟩ [1/m] of the unloaded texture, ``h_0 = max h* − h*``."""
    h = np.asarray(heights_m, dtype=float)
    h0 = h.max() - h
    return float(h0.mean()), float(np.mean(1.0 / np.maximum(h0, gap_floor_m)))


def separated_curve(heights_m: np.ndarray, clearance_m: np.ndarray) -> np.ndarray:
    """⟨1/(h_0 + H)⟩ over the whole cell for each clearance H > 0 [1/m] (no solve needed)."""
    h = np.asarray(heights_m, dtype=float)
    h0 = (h.max() - h).ravel()
    clearance = np.asarray(clearance_m, dtype=float)
    if np.any(clearance <= 0):
        raise InputError("clearance_m must be > 0")
    return np.array([float(np.mean(1.0 / (h0 + c))) for c in clearance])


def solve_table_chunk(
    heights_m: np.ndarray,
    pixel_size_m: float,
    pressure_ratio: np.ndarray,
    *,
    effective_modulus_pa: float,
    full_contact_pressure_ratio: float,
    tol: float,
    max_iterations: int,
    gap_floor_m: float,
    device: str = "cpu",
) -> dict[str, np.ndarray]:
    """Solve one chunk of a table: its ratios in rising order, each warm-started from the last.

    The first point starts from the solver's nested-grid start, so the chunk is a deterministic
    function of its inputs (whichever worker runs it). Points at or above the full-contact ratio
    are not solved: they are the exact full-contact state (a_r = 1, gaps 0).

    Parameters
    ----------
    heights_m : ndarray
        Texture heights h* [m].
    pixel_size_m : float
        Pixel size [m].
    pressure_ratio : ndarray
        Rising ratios ``P_n / E'`` of the chunk [-].
    effective_modulus_pa : float
        E' used for the solves [Pa].
    full_contact_pressure_ratio : float
        ``p_fc / E'`` of the texture [-].
    tol, max_iterations, gap_floor_m :
        Passed to :func:`solvers.micro.solve_micro` (single FFT thread).
    device : str
        ``"cpu"``: the numpy/pyFFTW solver (:func:`solvers.micro.solve_micro`); ``"cuda"``:
        the same algorithm on the GPU (:func:`solvers.micro_torch.solve_micro_torch`, torch
        imported only then); ``"torch-cpu"``: that backend on the CPU (checks). The results
        agree within the solver tolerance (tests/solvers/test_micro_torch.py), so the device
        is not a table setting.

    Returns
    -------
    dict of ndarray
        ``real_contact_area_fraction``, ``mean_gap_m``, ``mean_reciprocal_gap_per_m``,
        ``mean_reciprocal_gap_raw_per_m``, ``iterations``, ``residual``, ``converged``,
        ``full_contact``, ``solve_time_s`` (one entry per ratio).
    """
    from .elastic import PeriodicHalfSpace
    from .micro import solve_micro

    ratios = np.asarray(pressure_ratio, dtype=float)
    if ratios.ndim != 1 or np.any(np.diff(ratios) <= 0):
        raise InputError("pressure_ratio of a chunk must be 1-D and strictly increasing")
    n = ratios.size
    out = {
        "real_contact_area_fraction": np.ones(n),
        "mean_gap_m": np.zeros(n),
        "mean_reciprocal_gap_per_m": np.full(n, 1.0 / gap_floor_m),
        "mean_reciprocal_gap_raw_per_m": np.full(n, 1.0 / gap_floor_m),
        "iterations": np.zeros(n, dtype=np.int64),
        "residual": np.zeros(n),
        "converged": np.ones(n, dtype=bool),
        "full_contact": np.ones(n, dtype=bool),
        "solve_time_s": np.zeros(n),
    }
    if device == "cpu":
        hs = PeriodicHalfSpace(np.shape(heights_m), pixel_size_m, effective_modulus_pa, workers=1)
        solve = functools.partial(solve_micro, workers=1, halfspace=hs)
    elif device in ("cuda", "torch-cpu"):
        from .micro_torch import TorchHalfSpace, solve_micro_torch

        torch_device = "cuda" if device == "cuda" else "cpu"
        hs = TorchHalfSpace(np.shape(heights_m), pixel_size_m, effective_modulus_pa, torch_device)
        solve = functools.partial(solve_micro_torch, device=torch_device, halfspace=hs)
    else:
        raise InputError(f"device must be 'cpu', 'cuda' or 'torch-cpu', got {device!r}")
    previous = None
    for i, ratio in enumerate(ratios):
        if ratio >= full_contact_pressure_ratio:
            continue
        res = solve(
            heights_m,
            pixel_size_m,
            ratio * effective_modulus_pa,
            effective_modulus_pa,
            tol=tol,
            max_iterations=max_iterations,
            initial_pressure_pa=previous,
            gap_floor_m=gap_floor_m,
        )
        out["real_contact_area_fraction"][i] = res.real_contact_area_fraction
        out["mean_gap_m"][i] = res.mean_gap_m
        out["mean_reciprocal_gap_per_m"][i] = res.mean_reciprocal_gap_per_m
        out["mean_reciprocal_gap_raw_per_m"][i] = res.mean_reciprocal_gap_raw_per_m
        out["iterations"][i] = res.iterations
        out["residual"][i] = res.residual
        out["converged"][i] = res.converged
        out["full_contact"][i] = res.full_contact
        out["solve_time_s"][i] = res.solve_time_s
        previous = None if res.full_contact else res.pressure_pa
    return out
