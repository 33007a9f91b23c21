"""Micro scale: a rigid periodic texture pressed into an elastic half-space (docs/physics.md §5).

Load-controlled constrained conjugate gradients after Polonsky & Keer (Wear 231, 1999, 206-219),
on the periodic FFT half-space of :mod:`solvers.elastic` (FFT convention stated there), with
a spectral preconditioner and Polak–Ribière+ directions that survive contact-set changes. One
iteration costs three single-precision FFT pairs (preconditioner, ``u(t)`` of the direction,
``u`` of the clipping correction when the set changed) and six fused element-wise passes; the
displacement ``u(p)`` itself is kept in double precision and recomputed exactly in double
precision every 50 iterations and before convergence is accepted (see :func:`_pk_cg`).

Gap convention (docs/physics.md §5): the texture's highest point touches first, so the unloaded gap
is ``h_0 = max h* − h*``; under load ``g = h_0 + u(p) − δ ≥ 0`` with rigid approach ``δ``,
``p ≥ 0`` and ``p·g = 0``. The contact set ``ω_c`` is decided by the pressure (``p > 0``); the
gap is exactly zero there.

Speed: the solve starts from the warm start given, else from a nested-grid continuation (the
problem is solved on 2×-coarsened grids first and the pressure prolonged to the finer grid),
which removes most of the fine-grid iterations.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from . import _pk_kernels as _k
from .elastic import PeriodicHalfSpace
from .errors import InputError

__all__ = [
    "DEFAULT_GAP_FLOOR_M",
    "MicroResult",
    "check_micro_inputs",
    "full_contact_pressure",
    "solve_micro",
]

log = logging.getLogger(__name__)

#: Gap floor h_c of the reported mean reciprocal gap (docs/physics.md §5, our choice) [m]
DEFAULT_GAP_FLOOR_M = 10e-9
#: tolerance of the nested coarse levels [-]: they only supply the fine level's start; solving
#: them to 1e-4 instead gave the same fine iterations (260 vs 258 over the 12-point benchmark
#: sweep at 1024²) for more coarse work
COARSE_TOL = 1e-3


@dataclass
class MicroResult:
    """Result of one micro-scale solve. Fields are SI; the unit is in each name.

    Attributes
    ----------
    pressure_pa : ndarray
        Contact pressure p_n(x, y) [Pa].
    gap_m : ndarray
        Gap h_n(x, y) ≥ 0 [m], zero on the contact set.
    nominal_pressure_pa : float
        Imposed nominal (mean) pressure P_n [Pa].
    effective_modulus_pa : float
        E' [Pa].
    pixel_size_m : tuple of float
        Pixel size (dx, dy) [m].
    real_contact_area_fraction : float
        a_r = |ω_c| / |ω| [-] (docs/physics.md eq. 3).
    mean_gap_m : float
        (1/|ω|) ∬ h_n [m] (docs/physics.md eq. 4 with H = 0).
    mean_reciprocal_gap_per_m : float
        Mean over the gap set ω_g of 1/max(h_n, h_c) [1/m] (eq. 5 with H = 0, n = 0, floored).
    mean_reciprocal_gap_raw_per_m : float
        Mean over ω_g of 1/h_n without floor [1/m] (resolution dependent, see docs/physics.md §5).
    gap_floor_m : float
        h_c used for the floored value [m].
    rigid_approach_m : float
        δ [m], measured from first touch.
    full_contact : bool
        True when the imposed pressure reaches full contact (state returned exactly).
    converged : bool
        True if the residual met the tolerance within ``max_iterations``.
    iterations : int
        Conjugate-gradient iterations on the finest grid (coarse levels in ``level_iterations``).
    residual : float
        Final residual: RMS gap on the contact set over the RMS height, plus the relative
        pressure carried by penetrating points [-].
    message : str
        Human-readable status.
    solve_time_s : float
        Wall time of the solve [s].
    """

    pressure_pa: np.ndarray
    gap_m: np.ndarray
    nominal_pressure_pa: float
    effective_modulus_pa: float
    pixel_size_m: tuple[float, float]
    real_contact_area_fraction: float
    mean_gap_m: float
    mean_reciprocal_gap_per_m: float
    mean_reciprocal_gap_raw_per_m: float
    gap_floor_m: float
    rigid_approach_m: float
    full_contact: bool
    converged: bool
    iterations: int
    residual: float
    message: str
    solve_time_s: float = 0.0
    level_iterations: list[int] = field(default_factory=list)


def _check_heights(heights_m: np.ndarray) -> np.ndarray:
    h = np.asarray(heights_m, dtype=float)
    if h.ndim != 2:
        raise InputError(f"heights_m must be a 2-D array, got shape {h.shape}")
    if h.shape[0] < 2 or h.shape[1] < 2:
        raise InputError(f"heights_m must be at least 2x2 pixels, got {h.shape}")
    if not np.all(np.isfinite(h)):
        raise InputError("heights_m contains NaN or inf values")
    return h


def full_contact_pressure(
    heights_m: np.ndarray,
    pixel_size_m: float | tuple[float, float],
    effective_modulus_pa: float,
    *,
    halfspace: PeriodicHalfSpace | None = None,
) -> tuple[float, np.ndarray]:
    """Nominal pressure at which the texture first comes into full contact [Pa].

    In full contact ``u = δ − h_0`` everywhere, so the pressure field is
    ``p = P + p̃`` with ``p̃ = irfft2(E'|q|/4 · rfft2(h))``; it stays ≥ 0 while
    ``P ≥ −min p̃``.

    Returns
    -------
    (float, ndarray)
        The full-contact pressure [Pa] and the zero-mean fluctuation p̃ [Pa].
    """
    h = _check_heights(heights_m)
    hs = halfspace or PeriodicHalfSpace(h.shape, pixel_size_m, effective_modulus_pa)
    fluct = hs.pressure(h - h.mean())
    return float(max(-fluct.min(), 0.0)), fluct


def _gap_statistics(gap: np.ndarray, contact: np.ndarray, floor_m: float) -> tuple[float, float]:
    free = ~contact
    if not free.any():
        return 1.0 / floor_m, 1.0 / floor_m
    g = gap[free]
    floored = float(np.mean(1.0 / np.maximum(g, floor_m)))
    pos = g > 0
    raw = float(np.sum(1.0 / g[pos]) / g.size) if pos.any() else 1.0 / floor_m
    if not pos.all():
        # points of the gap set with an exactly zero gap are counted at the floor
        raw += float(np.count_nonzero(~pos) / g.size / floor_m)
    return floored, raw


def _coarsen(h: np.ndarray) -> np.ndarray:
    """2×2 block mean of a periodic field with even sizes."""
    nx, ny = h.shape
    return h.reshape(nx // 2, 2, ny // 2, 2).mean(axis=(1, 3))


def _prolong(p: np.ndarray) -> np.ndarray:
    return np.repeat(np.repeat(p, 2, axis=0), 2, axis=1)


def _pk_cg(
    hs: PeriodicHalfSpace,
    h0: np.ndarray,
    mean_pressure: float,
    p_init: np.ndarray | None,
    tol: float,
    max_iterations: int,
    callback: Callable[[int, float], None] | None,
    precondition: bool = True,
    refresh_every: int = 50,
) -> tuple[np.ndarray, np.ndarray, float, int, float, bool]:
    """Preconditioned Polonsky-Keer CG; returns (p, g, δ, iterations, residual, converged).

    One iteration, with ``c = {p > 0}`` the current contact set:

    1. gap ``g = h_0 + u(p) − δ`` with δ the mean of ``h_0 + u`` over ``c``; residual ``g|_c``;
    2. preconditioned residual ``z = K(g|_c)|_c − mean`` with the stiffness ``K = E'|q|/4``
       (the inverse of the full-cell compliance; one FFT pair);
    3. conjugate direction ``t = z + β t`` on ``c`` with the Polak–Ribière+ β (which restarts
       itself, β = 0, when the new residual is not conjugate to the old one); Polonsky–Keer's
       Fletcher–Reeves β with a restart at every contact-set change needed twice as many
       iterations (35 → 18 at 1024², 60 kPa; 93 → 33 at 1 MPa). If ``t`` is not a descent
       direction the step is retried with β = 0;
    4. step ``τ = ⟨g|_c, t⟩ / ⟨u(t) − mean, t⟩`` (one FFT pair for ``u(t)``);
    5. ``p ← max(p − τ t, 0)`` on ``c``; free points that penetrate get ``−τ g``;
       rescale to the imposed mean pressure.

    ``u(p)`` is updated by linearity, ``u ← factor·(u − τ u(t) + u(corr))`` with ``corr`` the
    clipped and added pressures (non-zero on a few points), and recomputed exactly every
    ``refresh_every`` iterations and before convergence is accepted. The preconditioner,
    ``u(t)`` and ``u(corr)`` are evaluated in single precision: they steer the iteration or
    are small increments, so their ~1e-7 relative rounding does not limit the converged
    residual, which is always measured on the exact double-precision ``u(p)``. The
    element-wise work is fused in :mod:`solvers._pk_kernels`.
    """
    shape = h0.shape
    n = h0.size
    total = mean_pressure * n
    h0f = np.ascontiguousarray(h0, dtype=float).ravel()
    scale_h = float(np.sqrt(np.mean((h0f - h0f.mean()) ** 2))) or 1.0
    # fields the FFTs read and write in place (pyFFTW plans bound to them); flat views of
    # the same memory go to the element-wise kernels
    p2, u2 = hs.workspace(2)
    p, u = p2.ravel(), u2.ravel()
    # single precision: the preconditioner's input and output, and the displacement of the
    # clipping/adding correction (small against u, so its float32 error is negligible)
    gc32_2, z32_2, corr32_2, du32_2, t32_2, w32_2 = hs.workspace(6, np.float32)
    gc32, z, corr32, du32, t32, w = (
        a.ravel() for a in (gc32_2, z32_2, corr32_2, du32_2, t32_2, w32_2)
    )
    if p_init is None:
        p[:] = mean_pressure
    else:
        np.maximum(np.asarray(p_init, dtype=float).reshape(shape), 0.0, out=p2)
        s = p.sum()
        if s > 0:
            p *= total / s
        else:
            p[:] = mean_pressure
    hs.displacement(p2, out=u2)
    nc, sum_c = _k.contact_mean_gap(p, h0f, u)
    t = np.zeros(n)
    g = np.empty(n)
    gc_prev = np.zeros(n)
    rz_old = 1.0
    first = True
    residual = np.inf
    delta = 0.0
    it = 0
    converged = False
    since_refresh = 0
    while True:
        if nc:
            delta = sum_c / nc
        else:
            delta = float(np.min(h0f + u))
        g_norm, pen_norm = _k.gap_and_norms(p, h0f, u, delta, g, gc32)
        residual = (np.sqrt(g_norm / max(nc, 1)) + np.sqrt(pen_norm / max(nc, 1))) / scale_h
        if callback is not None:
            callback(it, residual)
        if residual < tol:
            if since_refresh:  # confirm on a freshly computed displacement
                hs.displacement(p2, out=u2)
                nc, sum_c = _k.contact_mean_gap(p, h0f, u)
                since_refresh = 0
                continue
            converged = True
            break
        if it >= max_iterations:
            break
        it += 1
        if precondition and nc:
            hs.pressure(gc32_2, out=z32_2)
        else:
            z[:] = gc32
        z_sum, rz, z_gp, gp_sum = _k.mask_and_dots(p, z, g, gc_prev)
        z_mean = z_sum / nc if nc else 0.0
        cross = z_gp - z_mean * gp_sum
        # Polak-Ribière+: β = max(0, ⟨z̃, gc − gc_prev⟩ / ⟨z̃_prev, gc_prev⟩), z̃ = z − z̄ on c
        # (Σ_c gc = 0, so ⟨z̃, gc⟩ = rz); the previous residual is then replaced by gc
        beta = 0.0 if first or rz_old <= 0 else max(0.0, (rz - cross) / rz_old)
        first = False
        _k.update_direction(p, z, z_mean, beta, t, t32)
        rz_old = rz
        hs.displacement(t32_2, out=w32_2)
        sw, swt, st, sgt = _k.step_sums(p, w, t, g)
        w_mean = sw / nc if nc else 0.0
        denom = swt - w_mean * st
        tau = sgt / denom if denom > 0 else 0.0
        if not tau > 0 and beta != 0.0:
            # not a descent direction: restart from the preconditioned residual
            _k.update_direction(p, z, z_mean, 0.0, t, t32)
            hs.displacement(t32_2, out=w32_2)
            sw, swt, st, sgt = _k.step_sums(p, w, t, g)
            w_mean = sw / nc if nc else 0.0
            denom = swt - w_mean * st
            tau = sgt / denom if denom > 0 else 0.0
        if not tau > 0:
            # degenerate step (e.g. a single contact point has no gap residual): fall back to
            # the Jacobi step so that penetrating points can still enter the contact set
            tau = 1.0 / hs.self_compliance
        s, clipped, added = _k.update_pressure(p, t, g, tau, pen_norm > 0, corr32)
        changed = clipped > 0 or added > 0
        refresh = False
        if s <= 0:
            p[:] = mean_pressure
            refresh = first = True
            s = total
        factor = total / s
        since_refresh += 1
        refresh = refresh or since_refresh >= refresh_every
        if changed and not refresh:
            hs.displacement(corr32_2, out=du32_2)
        nc, sum_c = _k.scale_and_update(p, factor, u, w, tau, not refresh, du32, changed, h0f)
        if refresh:
            hs.displacement(p2, out=u2)
            nc, sum_c = _k.contact_mean_gap(p, h0f, u)
            since_refresh = 0
    p = p2.copy()  # the workspace is reused by the next solve on this half-space
    g = g.reshape(shape)
    gap = np.where(p > 0, 0.0, np.maximum(g, 0.0))
    return p, gap, delta, it, float(residual), converged


def check_micro_inputs(
    heights_m,
    nominal_pressure_pa: float,
    effective_modulus_pa: float,
    *,
    tol: float,
    gap_floor_m: float,
    initial_pressure_pa,
) -> tuple[np.ndarray, float, float, np.ndarray | None]:
    """The checks of :func:`solve_micro`'s inputs, shared with the torch backend
    (:func:`solvers.micro_torch.solve_micro_torch`). Returns the heights [m] as a float array,
    the nominal pressure [Pa], the effective modulus [Pa] and the initial pressure [Pa] (a
    float array, or None); raises :class:`InputError` naming the bad argument."""
    h = _check_heights(heights_m)
    p_nom = float(nominal_pressure_pa)
    if not np.isfinite(p_nom) or p_nom < 0:
        raise InputError(
            f"nominal_pressure_pa must be finite and >= 0, got {nominal_pressure_pa!r}"
        )
    e_eff = float(effective_modulus_pa)
    if not np.isfinite(e_eff) or e_eff <= 0:
        raise InputError(
            f"effective_modulus_pa must be finite and > 0, got {effective_modulus_pa!r}"
        )
    if not np.isfinite(gap_floor_m) or gap_floor_m <= 0:
        raise InputError(f"gap_floor_m must be finite and > 0, got {gap_floor_m!r}")
    if not (np.isfinite(tol) and tol > 0):
        raise InputError(f"tol must be finite and > 0, got {tol!r}")
    if initial_pressure_pa is not None:
        initial_pressure_pa = np.asarray(initial_pressure_pa, dtype=float)
        if initial_pressure_pa.shape != h.shape:
            raise InputError(
                f"initial_pressure_pa has shape {initial_pressure_pa.shape}, expected {h.shape}"
            )
        if not np.all(np.isfinite(initial_pressure_pa)):
            raise InputError("initial_pressure_pa contains NaN or inf values")
    if np.ptp(h) == 0:
        raise InputError("heights_m is flat (peak-to-valley 0): no texture to solve")
    return h, p_nom, e_eff, initial_pressure_pa


def solve_micro(
    heights_m: np.ndarray,
    pixel_size_m: float | tuple[float, float],
    nominal_pressure_pa: float,
    effective_modulus_pa: float,
    *,
    tol: float = 1e-6,
    max_iterations: int = 2000,
    initial_pressure_pa: np.ndarray | None = None,
    nested: bool = True,
    gap_floor_m: float = DEFAULT_GAP_FLOOR_M,
    backend: str = "auto",
    workers: int | None = None,
    halfspace: PeriodicHalfSpace | None = None,
    callback: Callable[[int, float], None] | None = None,
) -> MicroResult:
    """Press a rigid periodic texture into the elastic half-space at a nominal pressure.

    Parameters
    ----------
    heights_m : ndarray, shape (nx, ny)
        Texture heights h* [m], finite; peaks point towards the snow.
    pixel_size_m : float or (float, float)
        Pixel size [m].
    nominal_pressure_pa : float
        Nominal (mean) pressure P_n ≥ 0 [Pa].
    effective_modulus_pa : float
        E' of docs/physics.md eq. (1) [Pa].
    tol : float
        Tolerance on the relative residual (RMS gap on the contact set over RMS height) [-].
    max_iterations : int
        Iteration cap on each grid level; reaching it returns ``converged=False``.
    initial_pressure_pa : ndarray, optional
        Warm start (e.g. the previous point of a rising pressure sequence) [Pa]; rescaled to
        the requested mean pressure. Without it a nested-grid continuation is used.
    nested : bool
        Use the nested-grid start when no warm start is given.
    gap_floor_m : float
        h_c of the floored mean reciprocal gap [m].
    backend, workers :
        FFT backend (``"auto"``: pyFFTW when installed, else ``"scipy"``) and threads.
    halfspace : PeriodicHalfSpace, optional
        Reuse a prepared half-space (same shape, pixel size and modulus).
    callback : callable(iteration, residual), optional
        Progress hook (finest grid only).

    Returns
    -------
    MicroResult
    """
    t0 = time.perf_counter()
    h, p_nom, e_eff, initial_pressure_pa = check_micro_inputs(
        heights_m,
        nominal_pressure_pa,
        effective_modulus_pa,
        tol=tol,
        gap_floor_m=gap_floor_m,
        initial_pressure_pa=initial_pressure_pa,
    )
    hs = halfspace or PeriodicHalfSpace(
        h.shape, pixel_size_m, e_eff, backend=backend, workers=workers
    )
    dxy = hs.pixel_size_m
    h0 = h.max() - h

    def finish(p, gap, delta, full, conv, its, res, msg, levels):
        contact = p > 0
        rec, rec_raw = _gap_statistics(gap, contact, gap_floor_m)
        return MicroResult(
            pressure_pa=p,
            gap_m=gap,
            nominal_pressure_pa=p_nom,
            effective_modulus_pa=e_eff,
            pixel_size_m=dxy,
            real_contact_area_fraction=float(np.count_nonzero(contact) / p.size),
            mean_gap_m=float(gap.mean()),
            mean_reciprocal_gap_per_m=rec,
            mean_reciprocal_gap_raw_per_m=rec_raw,
            gap_floor_m=float(gap_floor_m),
            rigid_approach_m=float(delta),
            full_contact=full,
            converged=conv,
            iterations=its,
            residual=float(res),
            message=msg,
            solve_time_s=time.perf_counter() - t0,
            level_iterations=levels,
        )

    if p_nom == 0.0:
        return finish(
            np.zeros_like(h),
            h0.copy(),
            0.0,
            False,
            True,
            0,
            0.0,
            "zero load: unloaded texture, no contact",
            [],
        )
    p_fc, fluct = full_contact_pressure(h, dxy, e_eff, halfspace=hs)
    if p_nom >= p_fc:
        p = p_nom + fluct
        p = np.maximum(p, 0.0)
        # the partial-contact convention (periodic u of zero mean): h0 + u − δ = 0 everywhere,
        # so δ = mean(h0); continuous with the partial-contact δ as P → p_fc
        delta = float(h0.mean())
        return finish(
            p,
            np.zeros_like(h),
            delta,
            True,
            True,
            0,
            0.0,
            f"full contact: nominal pressure {p_nom:.6g} Pa >= full-contact pressure {p_fc:.6g} Pa",
            [],
        )

    levels: list[int] = []
    p_start = initial_pressure_pa
    if p_start is None and nested:
        p_start = _nested_start(h, hs, p_nom, tol, max_iterations, levels)
    p, gap, delta, its, res, conv = _pk_cg(hs, h0, p_nom, p_start, tol, max_iterations, callback)
    levels.append(its)
    msg = (
        f"converged in {its} iterations (residual {res:.3g} < tol {tol:.3g})"
        if conv
        else f"not converged: {its} iterations reached max_iterations, residual {res:.3g}"
    )
    return finish(p, gap, delta, False, conv, its, res, msg, levels)


def _nested_start(
    h: np.ndarray,
    hs: PeriodicHalfSpace,
    p_nom: float,
    tol: float,
    max_iterations: int,
    levels: list[int],
    min_size: int = 64,
) -> np.ndarray | None:
    """Pressure guess from solves on 2×-coarsened grids (None if the grid cannot coarsen).

    The coarse half-spaces are built once per fine half-space (:meth:`coarsened`), so a
    table build that reuses its half-space pays their set-up once.
    """
    nx, ny = h.shape
    if nx % 2 or ny % 2 or min(nx, ny) < 2 * min_size:
        return None
    hc = _coarsen(h)
    hsc = hs.coarsened()
    p_fc, _ = full_contact_pressure(hc, hsc.pixel_size_m, hsc.effective_modulus_pa, halfspace=hsc)
    if p_nom >= p_fc:
        return None
    p_coarse_start = _nested_start(hc, hsc, p_nom, tol, max_iterations, levels, min_size)
    p, _, _, its, _, _ = _pk_cg(
        hsc, hc.max() - hc, p_nom, p_coarse_start, max(tol, COARSE_TOL), max_iterations, None
    )
    levels.append(its)
    return _prolong(p)
