"""Macro scale: the rigid loaded ski pressed into the non-periodic half-space (method.md §4).

Problem
-------
The running surface is rigid; its loaded camber profile H*(X, Y) ≥ 0 [m] (from the measuring
device, the camber network or the beam model) is pressed into the infinite half-space of
effective modulus E' (method.md eq. 1) by the equivalent load F at x_F. With the rigid approach
δ and the tilt θ (rotation about the Y axis, small angle, positive when the tip goes down) the
clearance is

    H(X, Y) = H*(X, Y) + u(X, Y) − δ − θ (X − x_F) ≥ 0,   P ≥ 0,   P · H = 0,

with ``u = 2/(π E') ∬ P/r`` (Love's rectangles, zero-padded FFT convolution of
:class:`solvers.elastic.NonPeriodicHalfSpace`, whose FFT convention applies here), force balance
``Σ P dA = F`` and, with the tilt on, moment balance about the load point ``Σ P (X − x_F) dA = 0``.
With the tilt off (θ = 0) only force balance holds.

Solver
------
Load-controlled constrained conjugate gradients after Polonsky & Keer (Wear 231, 1999), extended
by one Lagrange multiplier for the tilt: on the current contact set the gap is projected on the
orthogonal complement of ``span{1, X − x_F}`` (a least-squares fit of δ + θ(X − x_F) is removed),
so every search direction keeps both force and moment; after the positivity projection both are
restored by the multiplicative correction ``P ← P (α + β (X − x_F))`` (2×2 solve). At
convergence the fitted δ, θ are the approach and the tilt. Force and moment hold to rounding.

Window ("model no more than the scene needs")
---------------------------------------------
Only pixels whose unloaded clearance H* is below a threshold can carry pressure; the FFT grid is
the bounding box of those rows. After the solve the window is checked rigorously: the elastic
displacement of a positive pressure is positive everywhere, so a pixel outside the window has
``H ≥ H* − δ − θ (X − x_F)``; if that bound is negative anywhere the threshold is raised and the
solve repeated (warm started). The reported clearance everywhere uses the full displacement.

Outputs along the ski are width averages over the footprint: ``P(X) = (1/w) ∫ P dY`` [Pa] and
``H(X) = (1/w) ∫ H dY`` [m].
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.fft

from .elastic import NonPeriodicHalfSpace
from .errors import InputError

__all__ = [
    "DEFAULT_PIXEL_ACROSS",
    "DEFAULT_PIXEL_ALONG_M",
    "ContactZone",
    "GapMap",
    "MacroResult",
    "extrude_profile",
    "interpolate_sides",
    "solve_macro",
]

#: Default pixel length along the ski [m] (coarsest meeting 1 % in area, see docs/macro.md)
DEFAULT_PIXEL_ALONG_M = 2e-3
#: Default number of pixels across the width [-]
DEFAULT_PIXEL_ACROSS = 4


@dataclass(frozen=True)
class GapMap:
    """Unloaded-by-snow clearance H*(X, Y) of a rigid running surface on a uniform grid.

    Attributes
    ----------
    gap_m : ndarray (nx, ny)
        H* [m] at pixel centres, NaN outside the footprint; axis 0 along the ski.
    positions_m : ndarray (nx,)
        Pixel-centre positions X from the balance point, positive towards the tip [m]; uniform.
    pixel_size_m : tuple of float
        (dx, dy) [m].
    """

    gap_m: np.ndarray
    positions_m: np.ndarray
    pixel_size_m: tuple[float, float]

    def __post_init__(self) -> None:
        h = np.asarray(self.gap_m, dtype=float)
        x = np.asarray(self.positions_m, dtype=float)
        if h.ndim != 2 or h.shape[0] < 2 or h.shape[1] < 1:
            raise InputError(f"gap_m must be a 2-D array (nx >= 2, ny >= 1), got {h.shape}")
        if x.shape != (h.shape[0],):
            raise InputError(f"positions_m has shape {x.shape}, expected ({h.shape[0]},)")
        dx, dy = (float(v) for v in np.broadcast_to(np.asarray(self.pixel_size_m, float), (2,)))
        if not (np.isfinite(dx) and np.isfinite(dy) and dx > 0 and dy > 0):
            raise InputError(f"pixel_size_m must be finite and > 0, got {self.pixel_size_m!r}")
        if not np.all(np.isfinite(x)) or np.any(np.abs(np.diff(x) - dx) > 1e-6 * dx):
            raise InputError(f"positions_m must be uniformly spaced by dx = {dx} m")
        if np.any(np.isinf(h)):
            raise InputError("gap_m contains inf values (use NaN outside the footprint)")
        inside = np.isfinite(h)
        if not inside.any():
            raise InputError("gap_m has no pixel inside the footprint (all NaN)")
        if np.any(h[inside] < 0):
            raise InputError(f"gap_m must be >= 0 on the footprint, got min {h[inside].min()!r}")
        object.__setattr__(self, "gap_m", h)
        object.__setattr__(self, "positions_m", x)
        object.__setattr__(self, "pixel_size_m", (dx, dy))


def _grid_along(positions_m: np.ndarray, pixel_size_m: float) -> np.ndarray:
    x0, x1 = float(positions_m[0]), float(positions_m[-1])
    nx = int(np.floor((x1 - x0) / pixel_size_m + 1e-9))
    if nx < 2:
        raise InputError(f"pixel_size_m {pixel_size_m} leaves fewer than 2 pixels along the ski")
    return x0 + pixel_size_m * (np.arange(nx) + 0.5)


def _check_profile(positions_m: np.ndarray, gap_m: np.ndarray, name: str) -> tuple:
    x = np.asarray(positions_m, dtype=float)
    g = np.asarray(gap_m, dtype=float)
    if x.ndim != 1 or x.size < 2 or g.shape != x.shape:
        raise InputError(f"{name}: positions_m and gap_m must be 1-D of equal length >= 2")
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(g))):
        raise InputError(f"{name}: positions_m and gap_m must be finite")
    if np.any(np.diff(x) <= 0):
        raise InputError(f"{name}: positions_m must be strictly increasing")
    return x, g


def interpolate_sides(
    positions_m: np.ndarray,
    left_gap_m: np.ndarray,
    right_gap_m: np.ndarray,
    width_m: float | np.ndarray,
    *,
    pixel_along_m: float = DEFAULT_PIXEL_ALONG_M,
    pixels_across: int = DEFAULT_PIXEL_ACROSS,
    width_positions_m: np.ndarray | None = None,
) -> GapMap:
    """Gap map from left and right edge profiles, linear across the width.

    Parameters
    ----------
    positions_m : ndarray (M,)
        Sample positions X of the profiles [m], increasing.
    left_gap_m, right_gap_m : ndarray (M,)
        Loaded gap H* along the left (Y = −w/2) and right (Y = +w/2) edges [m]; negative
        samples (device noise) are clipped to 0.
    width_m : float or ndarray
        Ski width [m], constant, or sampled at ``width_positions_m``.
    pixel_along_m : float
        Pixel length dx along the ski [m].
    pixels_across : int
        Number of pixels across the maximum width [-].
    width_positions_m : ndarray, optional
        Positions [m] of a width profile given in ``width_m``.

    Returns
    -------
    GapMap
        Pixels whose centre lies outside the local width are NaN.
    """
    x, gl = _check_profile(positions_m, left_gap_m, "left")
    _, gr = _check_profile(positions_m, right_gap_m, "right")
    if not np.isfinite(pixel_along_m) or pixel_along_m <= 0:
        raise InputError(f"pixel_along_m must be finite and > 0, got {pixel_along_m!r}")
    if int(pixels_across) != pixels_across or pixels_across < 1:
        raise InputError(f"pixels_across must be an integer >= 1, got {pixels_across!r}")
    xc = _grid_along(x, pixel_along_m)
    if width_positions_m is None:
        w = np.full(xc.shape, float(np.asarray(width_m, dtype=float)))
    else:
        w = np.interp(xc, np.asarray(width_positions_m, float), np.asarray(width_m, float))
    if not np.all(np.isfinite(w)) or np.any(w <= 0):
        raise InputError(f"width_m must be finite and > 0, got {width_m!r}")
    w_max = float(w.max())
    dy = w_max / pixels_across
    yc = -w_max / 2 + dy * (np.arange(pixels_across) + 0.5)
    hl = np.interp(xc, x, np.maximum(gl, 0.0))
    hr = np.interp(xc, x, np.maximum(gr, 0.0))
    frac = yc[None, :] / w[:, None] + 0.5  # 0 at the left edge, 1 at the right edge
    h = hl[:, None] * (1 - frac) + hr[:, None] * frac
    h[np.abs(yc[None, :]) > w[:, None] / 2 + 1e-12] = np.nan
    return GapMap(h, xc, (float(pixel_along_m), dy))


def extrude_profile(
    positions_m: np.ndarray,
    gap_m: np.ndarray,
    width_m: float | np.ndarray,
    *,
    pixel_along_m: float = DEFAULT_PIXEL_ALONG_M,
    pixels_across: int = DEFAULT_PIXEL_ACROSS,
    width_positions_m: np.ndarray | None = None,
) -> GapMap:
    """Gap map of a 1-D profile H*(X) held constant across the width (method.md §4.3).

    Parameters as :func:`interpolate_sides` with one profile ``gap_m`` [m] for both edges.
    """
    return interpolate_sides(
        positions_m,
        gap_m,
        gap_m,
        width_m,
        pixel_along_m=pixel_along_m,
        pixels_across=pixels_across,
        width_positions_m=width_positions_m,
    )


@dataclass
class ContactZone:
    """One contiguous contact zone along the ski.

    Attributes
    ----------
    start_m, end_m, length_m : float
        Rear and front edge (pixel edges) and length [m].
    load_n : float
        Load carried [N].
    load_share : float
        Fraction of F [-].
    """

    start_m: float
    end_m: float
    length_m: float
    load_n: float
    load_share: float


@dataclass
class MacroResult:
    """Result of one macro-scale solve; SI units, unit in each name.

    Attributes
    ----------
    pressure_pa : ndarray (nx, ny)
        Apparent contact pressure P(X, Y) [Pa]; NaN outside the footprint.
    clearance_map_m : ndarray (nx, ny)
        Clearance H(X, Y) ≥ 0 [m]; NaN outside the footprint.
    positions_m : ndarray (nx,)
        Pixel-centre positions X [m].
    pressure_line_pa : ndarray (nx,)
        Width-averaged pressure P(X) [Pa].
    clearance_m : ndarray (nx,)
        Width-averaged clearance H(X) [m].
    apparent_contact_area_m2 : float
        Area where P > 0 [m²] (pixel count × dx·dy).
    mean_apparent_pressure_pa : float
        F / A_app [Pa].
    peak_pressure_pa : float
        Largest pixel pressure [Pa] (grid dependent at zone edges).
    zones : list of ContactZone
        Contact zones from rear to front.
    approach_m, tilt_rad : float
        Rigid approach δ at x_F [m] and tilt θ [rad] (positive: tip down).
    load_n, load_position_m, effective_modulus_pa : float
        Inputs F [N], x_F [m], E' [Pa].
    force_residual, moment_residual : float
        |ΣP dA − F| / F and |ΣP (X − x_F) dA| / (F · window length) [-].
    pixel_size_m : tuple of float
        (dx, dy) [m].
    window_m : tuple of float
        Rear and front edge of the solved window [m].
    window_gap_m : float
        Threshold on H* that defined the window [m].
    window_pixels : int
        Pixels that could carry pressure [-].
    converged, iterations, residual, message :
        Diagnostics; ``residual`` is the RMS clearance on the contact set plus the RMS
        penetration outside it, over the largest elastic displacement [-].
    solve_time_s : float
        Wall time [s].
    """

    pressure_pa: np.ndarray
    clearance_map_m: np.ndarray
    positions_m: np.ndarray
    pressure_line_pa: np.ndarray
    clearance_m: np.ndarray
    apparent_contact_area_m2: float
    mean_apparent_pressure_pa: float
    peak_pressure_pa: float
    zones: list[ContactZone]
    approach_m: float
    tilt_rad: float
    load_n: float
    load_position_m: float
    effective_modulus_pa: float
    force_residual: float
    moment_residual: float
    pixel_size_m: tuple[float, float]
    window_m: tuple[float, float]
    window_gap_m: float
    window_pixels: int
    converged: bool
    iterations: int
    residual: float
    message: str
    solve_time_s: float = 0.0
    extra: dict = field(default_factory=dict)


@functools.lru_cache(maxsize=16)
def _halfspace(shape: tuple[int, int], dx: float, dy: float, e_eff: float) -> NonPeriodicHalfSpace:
    """Cached half-space kernel per grid (the kernel FFT dominates small solves)."""
    return NonPeriodicHalfSpace(shape, (dx, dy), e_eff, workers=1)


def _fast_rows(n: int) -> int:
    """Smallest m ≥ n whose zero-padded FFT length 2m is 5-smooth (fast)."""
    m = n
    while scipy.fft.next_fast_len(2 * m, real=True) != 2 * m:
        m += 1
    return m


def _fit_rigid(g: np.ndarray, s: np.ndarray, xs: np.ndarray, tilt: bool) -> tuple[float, float]:
    """Least-squares δ + θ xs fitted to g on the set s."""
    n = np.count_nonzero(s)
    if n == 0:
        return 0.0, 0.0
    gs = g[s]
    if not tilt:
        return float(gs.mean()), 0.0
    xv = xs[s]
    s1, s2 = xv.sum(), np.dot(xv, xv)
    det = n * s2 - s1 * s1
    if det <= 1e-14 * n * max(s2, 1e-30):
        return float(gs.mean()), 0.0
    b0, b1 = gs.sum(), np.dot(xv, gs)
    return float((s2 * b0 - s1 * b1) / det), float((n * b1 - s1 * b0) / det)


def _restore_balance(p: np.ndarray, xs: np.ndarray, total: float, tilt: bool) -> np.ndarray:
    """Scale p (≥ 0) so that Σp = total and, with tilt, Σ p xs = 0 (multiplicative, linear)."""
    for _ in range(20):
        s0 = p.sum()
        if s0 <= 0:
            return p
        if not tilt:
            return p * (total / s0)
        s1 = np.dot(p.ravel(), xs.ravel())
        s2 = np.dot(p.ravel(), (xs * xs).ravel())
        det = s0 * s2 - s1 * s1
        if det <= 0:
            return p * (total / s0)
        alpha = total * s2 / det
        beta = -total * s1 / det
        factor = alpha + beta * xs
        p = p * factor
        if np.all(factor[p != 0] > 0) or not np.any(p < 0):
            return np.maximum(p, 0.0)
        p = np.maximum(p, 0.0)
    return p


def _pk_tilt(
    hs: NonPeriodicHalfSpace,
    h0: np.ndarray,
    mask: np.ndarray,
    xs: np.ndarray,
    total: float,
    tilt: bool,
    p_init: np.ndarray | None,
    tol: float,
    max_iterations: int,
) -> tuple[np.ndarray, np.ndarray, float, float, int, float, bool]:
    """Constrained CG; pressures are per pixel [Pa], total = F / (dx dy)."""
    if p_init is None:
        p = np.where(mask, 1.0, 0.0)
    else:
        p = np.where(mask, np.maximum(p_init, 0.0), 0.0)
        if p.sum() <= 0:
            p = np.where(mask, 1.0, 0.0)
    p = _restore_balance(p, xs, total, tilt)
    t = np.zeros_like(p)
    g_old = 1.0
    restart = True
    delta = theta = 0.0
    residual = np.inf
    converged = False
    it = 0
    g = h0.copy()
    while it < max_iterations:
        it += 1
        s = p > 0
        u = hs.displacement(p)
        g = h0 + u
        delta, theta = _fit_rigid(g, s, xs, tilt)
        g = g - delta - theta * xs
        gc = np.where(s, g, 0.0)
        g_norm = float(np.dot(gc.ravel(), gc.ravel()))
        nc = max(int(np.count_nonzero(s)), 1)
        u_ref = max(float(u[mask].max()), 1e-30)
        pen = mask & ~s & (g < 0)
        residual = np.sqrt(g_norm / nc) / u_ref
        if pen.any():
            residual += float(np.sqrt(np.sum(g[pen] ** 2) / nc)) / u_ref
        if residual < tol:
            converged = True
            it -= 1
            break
        beta = 0.0 if restart else g_norm / g_old
        t = gc + beta * np.where(s, t, 0.0)
        g_old = g_norm
        r = hs.displacement(t)
        d0, d1 = _fit_rigid(r, s, xs, tilt)
        r = r - d0 - d1 * xs
        denom = float(np.dot(np.where(s, r, 0.0).ravel(), t.ravel()))
        tau = float(np.dot(gc.ravel(), t.ravel())) / denom if denom > 0 else 0.0
        if not tau > 0:
            tau = 1.0 / hs.self_compliance
        p_new = np.where(s, p - tau * t, 0.0)
        p_new[p_new < 0] = 0.0
        restart = bool(pen.any())
        if restart:
            p_new[pen] -= tau * g[pen]
        if p_new.sum() <= 0:
            p_new = np.where(mask, 1.0, 0.0)
            restart = True
        p = _restore_balance(p_new, xs, total, tilt)
    return p, g, delta, theta, it, float(residual), converged


def solve_macro(
    gap_map: GapMap,
    load_n: float,
    load_position_m: float,
    effective_modulus_pa: float,
    *,
    tilt: bool = True,
    tol: float = 1e-8,
    max_iterations: int = 3000,
    window_gap_m: float | None = None,
    initial_pressure_pa: np.ndarray | None = None,
) -> MacroResult:
    """Press the rigid loaded running surface into the snow half-space.

    Parameters
    ----------
    gap_map : GapMap
        Loaded camber clearance H*(X, Y) [m] on its grid (NaN outside the footprint).
    load_n : float
        Equivalent load F ≥ 0 [N].
    load_position_m : float
        Load position x_F from the balance point [m].
    effective_modulus_pa : float
        E' of method.md eq. (1) [Pa].
    tilt : bool
        Solve for the tilt θ with moment balance about x_F (default); False: θ = 0, force only.
    tol : float
        Relative residual (RMS clearance on the contact set over the largest displacement) [-].
    max_iterations : int
        CG iterations per window; exhausting them returns ``converged=False``.
    window_gap_m : float, optional
        Initial threshold on H* for the solved window [m]; default ``50 F / (E' · w)`` (a few
        times the displacement scale), raised automatically until the window check passes.
    initial_pressure_pa : ndarray (nx, ny), optional
        Warm start [Pa].

    Returns
    -------
    MacroResult
    """
    t0 = time.perf_counter()
    h = gap_map.gap_m
    x = gap_map.positions_m
    dx, dy = gap_map.pixel_size_m
    f = float(load_n)
    xf = float(load_position_m)
    e_eff = float(effective_modulus_pa)
    if not np.isfinite(f) or f < 0:
        raise InputError(f"load_n must be finite and >= 0, got {load_n!r}")
    if not np.isfinite(e_eff) or e_eff <= 0:
        raise InputError(
            f"effective_modulus_pa must be finite and > 0, got {effective_modulus_pa!r}"
        )
    if not np.isfinite(xf):
        raise InputError(f"load_position_m must be finite, got {load_position_m!r}")
    if not (np.isfinite(tol) and tol > 0):
        raise InputError(f"tol must be finite and > 0, got {tol!r}")
    inside = np.isfinite(h)
    foot_x = x[inside.any(axis=1)]
    if tilt and not (foot_x.min() - dx / 2 < xf < foot_x.max() + dx / 2):
        raise InputError(
            f"load_position_m {xf} m lies outside the footprint "
            f"({foot_x.min() - dx / 2:.4g} .. {foot_x.max() + dx / 2:.4g} m): no moment balance"
        )
    width = float(inside.sum(axis=1).max() * dy)
    hz = np.where(inside, h, np.inf)
    xs_full = np.broadcast_to((x - xf)[:, None], h.shape)
    if f == 0.0:
        zero = np.where(inside, 0.0, np.nan)
        return _finish(
            gap_map,
            zero,
            np.where(inside, h - np.nanmin(h), np.nan),
            f,
            xf,
            e_eff,
            0.0,
            0.0,
            (float(x[0]), float(x[-1])),
            0.0,
            0,
            0.0,
            0.0,
            True,
            0,
            0.0,
            "zero load: no contact",
            t0,
        )
    thr = float(window_gap_m) if window_gap_m is not None else 50.0 * f / (e_eff * width)
    if not np.isfinite(thr) or thr <= 0:
        raise InputError(f"window_gap_m must be finite and > 0, got {window_gap_m!r}")
    h_min = float(hz.min())
    p_warm = initial_pressure_pa
    total_its = 0
    for _attempt in range(30):
        cand = hz <= h_min + thr
        rows = np.flatnonzero(cand.any(axis=1))
        i0, i1 = int(rows[0]), int(rows[-1]) + 1
        n_sub = _fast_rows(i1 - i0)
        extra = n_sub - (i1 - i0)
        sub_mask = np.pad(cand[i0:i1], ((0, extra), (0, 0)))
        xs = np.broadcast_to((x[i0] + dx * np.arange(n_sub) - xf)[:, None], sub_mask.shape)
        if tilt and not (np.any(sub_mask & (xs < 0)) and np.any(sub_mask & (xs > 0))):
            thr *= 2.0
            continue
        hs = _halfspace(sub_mask.shape, dx, dy, e_eff)
        h0 = np.where(sub_mask, np.pad(np.nan_to_num(h[i0:i1]), ((0, extra), (0, 0))), 0.0)
        p_init = None if p_warm is None else np.pad(p_warm[i0:i1], ((0, extra), (0, 0)))
        p_sub, _g_sub, delta, theta, its, res, conv = _pk_tilt(
            hs, h0, sub_mask, xs, f / (dx * dy), tilt, p_init, tol, max_iterations
        )
        p_sub = p_sub[: i1 - i0]
        sub_mask = sub_mask[: i1 - i0]
        total_its += its
        # rigorous window check: outside the window H >= H* - δ - θ (X - x_F)
        outside = inside & ~np.pad(sub_mask, ((i0, h.shape[0] - i1), (0, 0)))
        bound = np.where(outside, h - delta - theta * xs_full, np.inf)
        if bound.min() >= 0 or not conv:
            break
        thr = max(
            2.0 * thr,
            1.5 * float(np.max(np.where(outside, delta + theta * xs_full - h + h_min, 0.0))),
        )
        p_warm = np.zeros(h.shape)
        p_warm[i0:i1] = p_sub
    p = np.zeros(h.shape)
    p[i0:i1] = p_sub
    # clearance everywhere on the footprint from the full displacement field
    u_full = _halfspace(h.shape, dx, dy, e_eff).displacement(p)
    clear = np.where(inside, h + u_full - delta - theta * xs_full, np.nan)
    clear[p > 0] = 0.0
    clear = np.where(inside, np.maximum(clear, 0.0), np.nan)
    msg = (
        f"converged in {total_its} iterations (residual {res:.3g} < tol {tol:.3g})"
        if conv
        else f"not converged: {total_its} iterations, residual {res:.3g} (tol {tol:.3g})"
    )
    return _finish(
        gap_map,
        np.where(inside, p, np.nan),
        clear,
        f,
        xf,
        e_eff,
        delta,
        theta,
        (float(x[i0] - dx / 2), float(x[i1 - 1] + dx / 2)),
        thr,
        int(sub_mask.sum()),
        0.0,
        0.0,
        conv,
        total_its,
        res,
        msg,
        t0,
        window_length=float((i1 - i0) * dx),
    )


def _finish(
    gap_map: GapMap,
    pressure: np.ndarray,
    clearance: np.ndarray,
    f: float,
    xf: float,
    e_eff: float,
    delta: float,
    theta: float,
    window: tuple[float, float],
    thr: float,
    n_window: int,
    _fr: float,
    _mr: float,
    conv: bool,
    its: int,
    res: float,
    msg: str,
    t0: float,
    window_length: float = 1.0,
) -> MacroResult:
    x = gap_map.positions_m
    dx, dy = gap_map.pixel_size_m
    inside = np.isfinite(gap_map.gap_m)
    p0 = np.where(inside, pressure, 0.0)
    width_x = inside.sum(axis=1) * dy
    with np.errstate(invalid="ignore", divide="ignore"):
        p_line = np.where(width_x > 0, p0.sum(axis=1) * dy / width_x, 0.0)
        h_line = np.where(width_x > 0, np.nansum(clearance, axis=1) * dy / width_x, np.nan)
    contact = p0 > 0
    area = float(np.count_nonzero(contact) * dx * dy)
    force = float(p0.sum() * dx * dy)
    moment = float(np.sum(p0 * (x - xf)[:, None]) * dx * dy)
    zones: list[ContactZone] = []
    row = contact.any(axis=1).astype(np.int8)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], row, [0]])))
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        load = float(p0[a:b].sum() * dx * dy)
        zones.append(
            ContactZone(
                start_m=float(x[a] - dx / 2),
                end_m=float(x[b - 1] + dx / 2),
                length_m=float((b - a) * dx),
                load_n=load,
                load_share=load / force if force > 0 else 0.0,
            )
        )
    return MacroResult(
        pressure_pa=pressure,
        clearance_map_m=clearance,
        positions_m=x,
        pressure_line_pa=p_line,
        clearance_m=h_line,
        apparent_contact_area_m2=area,
        mean_apparent_pressure_pa=f / area if area > 0 else 0.0,
        peak_pressure_pa=float(p0.max()),
        zones=zones,
        approach_m=float(delta),
        tilt_rad=float(theta),
        load_n=f,
        load_position_m=xf,
        effective_modulus_pa=e_eff,
        force_residual=abs(force - f) / f if f > 0 else 0.0,
        moment_residual=abs(moment) / (f * window_length) if f > 0 else 0.0,
        pixel_size_m=(dx, dy),
        window_m=window,
        window_gap_m=float(thr),
        window_pixels=int(n_window),
        converged=conv,
        iterations=int(its),
        residual=float(res),
        message=msg,
        solve_time_s=time.perf_counter() - t0,
    )
