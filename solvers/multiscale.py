"""Multi-scale step: from the apparent contact (macro) to the four functional parameters.

For every pixel of the ski's footprint Ω (docs/physics.md §5, §6), with P(X, Y) and H(X, Y) from
:func:`solvers.macro.solve_macro` and the texture's :class:`~solvers.lookup.MicroTable`:

- loaded pixels (P > 0, H = 0): ``P_n = P (1 − n)`` (eq. 2) and, from the table at ``P_n/E'``,
  ``a_r`` (eq. 3), ``h̄_n`` (eq. 4 with H = 0) and ``(1/h)‾_n = (1 − n) · ⟨1/max(h_n, h_c)⟩_{ω_g}``
  (eq. 5, floored);
- separated pixels (P = 0, H ≥ 0): the unloaded texture lifted by H: ``a_r = 0``,
  ``h̄_n = ⟨h_0⟩ + H`` (exact) and ``(1/h)‾_n = (1 − n) ⟨1/(h_0 + H)⟩`` from the table's
  separated curve. **(choice)** Below the curve's lowest clearance (= the gap floor h_c, 10 nm)
  the value at h_c is used — the same floor as in the loaded regime; above its highest
  clearance (10 mm) ``1/(⟨h_0⟩ + H)`` is used, exact to ``Var(h_0)/H² < 1e-4`` there.
- loaded pixels below the table's lowest ratio (the fringe of a contact zone, where P → 0):
  **(choice)** linear interpolation in ``P_n/E'`` between the exact zero-load state and the
  first table point — interpolation between two known states, never extrapolation; their number
  and load are reported in the diagnostics. A ratio above the table (without full contact)
  raises :class:`~solvers.errors.OutOfRangeError`.

Distributions along the ski are width averages over the footprint; the metrics are integrals
over Ω (areas in m², the reciprocal separation in m):

- total real contact area ``A_tot = ∬ a_r dA`` [m²];
- average real contact pressure ``F / A_tot`` [Pa] (the full load F, not F (1 − n));
- minimum average interfacial separation ``min_X h̄_n(X)`` [m];
- total average reciprocal separation ``∬ (1/h)‾_n dA`` [m].
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import lookup
from .errors import InputError, OutOfRangeError
from .lookup import MicroTable
from .macro import MacroResult

__all__ = ["MultiscaleResult", "ZoneMetrics", "multiscale"]


@dataclass
class ZoneMetrics:
    """Per-zone (rear to front) real contact.

    Attributes
    ----------
    start_m, end_m : float
        Zone edges [m].
    load_n, load_share : float
        Load [N] and its share of F [-].
    apparent_area_m2, real_area_m2 : float
        Apparent (P > 0) and real contact area in the zone [m²].
    """

    start_m: float
    end_m: float
    load_n: float
    load_share: float
    apparent_area_m2: float
    real_area_m2: float


@dataclass
class MultiscaleResult:
    """The four functional parameters, the apparent contact and the distributions (SI).

    Attributes
    ----------
    total_real_contact_area_m2 : float
        A_tot [m²].
    average_real_contact_pressure_pa : float
        F / A_tot [Pa].
    min_average_separation_m : float
        min over X of h̄_n(X) [m].
    total_reciprocal_separation_m : float
        ∬ (1/h)‾_n dA [m].
    apparent_contact_area_m2, mean_apparent_pressure_pa : float
        From the macro solve [m²], [Pa].
    positions_m, pressure_pa, clearance_m, real_area_fraction, average_separation_m,
    reciprocal_separation_per_m : ndarray (nx,)
        Width-averaged distributions along the ski [m], [Pa], [m], [-], [m], [1/m].
    zones : list of ZoneMetrics
    real_area_fraction_map : ndarray (nx, ny)
        a_r(X, Y) per pixel [-], NaN outside the footprint.
    porosity, effective_modulus_pa, load_n : float
        Inputs n [-], E' [Pa], F [N].
    diagnostics : dict
        Pixels below the table range and their load share, gap floor, table name.
    """

    total_real_contact_area_m2: float
    average_real_contact_pressure_pa: float
    min_average_separation_m: float
    total_reciprocal_separation_m: float
    apparent_contact_area_m2: float
    mean_apparent_pressure_pa: float
    positions_m: np.ndarray
    pressure_pa: np.ndarray
    clearance_m: np.ndarray
    real_area_fraction: np.ndarray
    average_separation_m: np.ndarray
    reciprocal_separation_per_m: np.ndarray
    zones: list[ZoneMetrics]
    real_area_fraction_map: np.ndarray
    porosity: float
    effective_modulus_pa: float
    load_n: float
    diagnostics: dict = field(default_factory=dict)


def _loaded_fields(table: MicroTable, ratio: np.ndarray) -> tuple[np.ndarray, ...]:
    """a_r, h̄_n, ⟨1/max(h, h_c)⟩_{ω_g} at ratios r > 0 (1-D), low fringe interpolated."""
    e = 1.0  # lookups take P_n and E'; pass the ratio directly with E' = 1
    lo, hi = table.pressure_ratio_range
    above = ratio > hi * (1 + 1e-9)
    if np.any(above):
        raise OutOfRangeError(
            f"nominal pressure ratio P_n/E' up to {ratio.max():.3g} exceeds the table of "
            f"{table.name!r} (max {hi:.3g}); lower the load or raise the snow modulus"
        )
    below = ratio < lo * (1 - 1e-9)
    r = np.where(below, lo, ratio)
    ar = np.asarray(lookup.real_contact_area_fraction(table, r, e), dtype=float)
    gap = np.asarray(lookup.mean_gap_m(table, r, e), dtype=float)
    rec = np.asarray(lookup.mean_reciprocal_gap_per_m(table, r, e), dtype=float)
    if np.any(below):
        w = ratio[below] / lo  # 0 at zero load, 1 at the first table point
        ar[below] = w * ar[below]
        gap[below] = (1 - w) * table.unloaded_mean_gap_m + w * gap[below]
        rec[below] = (1 - w) * table.unloaded_mean_reciprocal_gap_per_m + w * rec[below]
    return ar, gap, rec, below


def _separated_reciprocal(table: MicroTable, clearance_m: np.ndarray) -> np.ndarray:
    lo, hi = float(table.clearance_m[0]), float(table.clearance_m[-1])
    h = np.clip(clearance_m, lo, None)
    inside = h <= hi
    out = np.empty_like(h)
    if np.any(inside):
        out[inside] = lookup.separated_reciprocal_gap_per_m(table, h[inside])
    out[~inside] = 1.0 / (table.unloaded_mean_gap_m + h[~inside])
    return out


def multiscale(
    macro: MacroResult, table: MicroTable, porosity: float, effective_modulus_pa: float
) -> MultiscaleResult:
    """Combine a macro solve with a texture table (docs/physics.md eqs. 2–5 and §6).

    Parameters
    ----------
    macro : MacroResult
        Apparent contact of the ski (pressure and clearance maps on the footprint).
    table : MicroTable
        The grind's micro-scale table.
    porosity : float
        Snow porosity n, 0 ≤ n < 1 [-].
    effective_modulus_pa : float
        E' of docs/physics.md eq. (1) [Pa]; must be the one the macro solve used.

    Returns
    -------
    MultiscaleResult
    """
    n = float(porosity)
    if not np.isfinite(n) or not (0 <= n < 1):
        raise InputError(f"porosity must be in [0, 1), got {porosity!r}")
    e = float(effective_modulus_pa)
    if not np.isfinite(e) or e <= 0:
        raise InputError(f"effective_modulus_pa must be finite and > 0, got {e!r}")
    p = np.asarray(macro.pressure_pa, dtype=float)
    hmap = np.asarray(macro.clearance_map_m, dtype=float)
    foot = np.isfinite(p) & np.isfinite(hmap)
    dx, dy = macro.pixel_size_m
    da = dx * dy
    loaded = foot & (p > 0)
    free = foot & ~loaded

    ar = np.zeros_like(p)
    avg_sep = np.full_like(p, np.nan)
    rec = np.full_like(p, np.nan)
    ratio = p[loaded] * (1 - n) / e
    ar_l, gap_l, rec_l, below = _loaded_fields(table, ratio)
    ar[loaded] = ar_l
    avg_sep[loaded] = gap_l
    rec[loaded] = (1 - n) * rec_l
    hf = np.maximum(hmap[free], 0.0)
    avg_sep[free] = table.unloaded_mean_gap_m + hf
    rec[free] = (1 - n) * _separated_reciprocal(table, hf)
    ar[~foot] = np.nan

    load = float(macro.load_n)
    a_tot = float(np.nansum(ar[foot]) * da)
    rec_tot = float(np.sum(rec[foot]) * da)

    rows = foot.any(axis=1)
    width = np.count_nonzero(foot, axis=1) * dy

    def line(field_: np.ndarray) -> np.ndarray:
        s = np.where(foot, field_, 0.0).sum(axis=1) * dy
        out = np.full(field_.shape[0], np.nan)
        out[rows] = s[rows] / width[rows]
        return out

    sep_line = line(avg_sep)
    zones = []
    x = np.asarray(macro.positions_m, dtype=float)
    for z in macro.zones:
        in_zone = (x >= z.start_m - 1e-12) & (x <= z.end_m + 1e-12)
        zl = loaded & in_zone[:, None]
        zones.append(
            ZoneMetrics(
                start_m=z.start_m,
                end_m=z.end_m,
                load_n=z.load_n,
                load_share=z.load_share,
                apparent_area_m2=z.apparent_area_m2,  # sub-pixel edges, sums to the total
                real_area_m2=float(ar[zl].sum() * da),
            )
        )
    below_load = float(np.sum(p[loaded][below]) * da)
    return MultiscaleResult(
        total_real_contact_area_m2=a_tot,
        average_real_contact_pressure_pa=load / a_tot if a_tot > 0 else float("inf"),
        min_average_separation_m=float(np.nanmin(sep_line[rows])),
        total_reciprocal_separation_m=rec_tot,
        apparent_contact_area_m2=macro.apparent_contact_area_m2,
        mean_apparent_pressure_pa=macro.mean_apparent_pressure_pa,
        positions_m=x,
        pressure_pa=line(np.where(foot, p, 0.0)),
        clearance_m=line(np.where(foot, hmap, 0.0)),
        real_area_fraction=line(ar),
        average_separation_m=sep_line,
        reciprocal_separation_per_m=line(rec),
        zones=zones,
        real_area_fraction_map=ar,
        porosity=n,
        effective_modulus_pa=e,
        load_n=load,
        diagnostics={
            "table": table.name,
            "gap_floor_m": table.gap_floor_m,
            "texture_pixel_size_m": table.pixel_size_m,
            "pixels_below_table_range": int(np.count_nonzero(below)),
            "load_share_below_table_range": below_load / load if load > 0 else 0.0,
        },
    )
