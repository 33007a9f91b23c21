"""Macro scale: the rigid loaded ski pressed into the non-periodic half-space (docs/physics.md §4).

Problem
-------
The running surface is rigid; its loaded camber profile H*(X, Y) ≥ 0 [m] (from the measuring
device, the camber network or the beam model) is pressed into the infinite half-space of
effective modulus E' (docs/physics.md eq. 1) by the equivalent load F at x_F. With the rigid
approach δ and the tilt θ (rotation about the Y axis, small angle, positive when the tip goes
down) the clearance is

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

Operator and FFT convention
---------------------------
Exactly the zero-padded Love convolution of :class:`solvers.elastic.NonPeriodicHalfSpace`
(pressure constant per pixel, displacement at pixel centres), evaluated as a real FFT of length
2n along X only (``scipy.fft.rfft``/``irfft``, ``norm="backward"``: 1/N on the inverse; the X
offset n is never reached and set to zero, so the convolution is linear, not circular; no q = 0
special case — the rigid approach is the multiplier δ). Love's kernel is even in X, so its
transform is real; across the few pixels of the width the coupling is a dense ``ny × ny``
product per wavenumber (:class:`_LineOperator`, for ``ny ≤ 8``; wider grids use the 2-D
operator). Kernel transforms are cached per window shape.

Window ("model no more than the scene needs")
---------------------------------------------
A coarse line problem (8 mm pixels, one pixel across, width-mean H*) gives δ0, θ0; only pixels
whose rigid interference ``H* − δ0 − θ0 (X − x_F)`` is below a margin (a quarter of the coarse
displacement scale) can carry pressure, and the FFT grid is the bounding box of their rows;
the CG vectors live on those pixels only. After the solve the window is checked rigorously: the
elastic displacement of a positive pressure is positive everywhere, so a pixel outside the
window has ``H ≥ H* − δ − θ (X − x_F)``; if that bound is negative anywhere the margin is raised
and the solve repeated (warm started). The reported clearance everywhere uses the full
displacement. The element-wise passes of the CG are fused with numba (serial: the vectors are
a few hundred pixels long).

Apparent contact area
---------------------
Zone edges are estimated below the pixel size: outside a smooth contact edge H ∝ d^{3/2}, so
the zero crossing of H^{2/3}, linear through the first two free pixels beyond each run of
contact pixels along X, is the edge (clipped between the last contact and first free pixel
centres; pixel counting puts it midway). ``apparent_contact_area_m2`` = Σ (edge-to-edge length)
× dy over the pixel columns, and ``mean_apparent_pressure_pa = F / apparent_contact_area_m2``.
Across the width (partial-width contact) pixels are still counted.

Outputs along the ski are width averages over the footprint: ``P(X) = (1/w) ∫ P dY`` [Pa] and
``H(X) = (1/w) ∫ H dY`` [m].
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field

import numba
import numpy as np
import scipy.fft

from .elastic import NonPeriodicHalfSpace, love_rectangle_influence
from .errors import InputError

__all__ = [
    "DEFAULT_PIXEL_ACROSS",
    "DEFAULT_PIXEL_ALONG_M",
    "ContactZone",
    "GapMap",
    "MacroResult",
    "ProfileExtruder",
    "extrude_profile",
    "interpolate_sides",
    "solve_macro",
]

#: Default pixel length along the ski [m] (area within 1 % of the 0.5 mm × 16 reference with
#: margin, see docs/macro.md "Time vs error")
DEFAULT_PIXEL_ALONG_M = 4e-3
#: Default number of pixels across the width [-] (the area converges slowest across the width)
DEFAULT_PIXEL_ACROSS = 8


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


class ProfileExtruder:
    """Gap maps of many profiles on one grid: the grid, the width and the footprint are set up
    once, each call interpolates one profile (the error band's perturbed solves extrude nine
    profiles per answer). ``ProfileExtruder(...)(gap_m)`` is :func:`extrude_profile` and
    ``.sides(left, right)`` is :func:`interpolate_sides`, with the same numbers.

    Parameters
    ----------
    positions_m : ndarray (M,)
        Sample positions X of the profiles [m], increasing.
    width_m, pixel_along_m, pixels_across, width_positions_m :
        As :func:`interpolate_sides`.
    """

    def __init__(
        self,
        positions_m: np.ndarray,
        width_m: float | np.ndarray,
        *,
        pixel_along_m: float = DEFAULT_PIXEL_ALONG_M,
        pixels_across: int = DEFAULT_PIXEL_ACROSS,
        width_positions_m: np.ndarray | None = None,
    ) -> None:
        x = np.asarray(positions_m, dtype=float)
        if x.ndim != 1 or x.size < 2:
            raise InputError("positions_m must be 1-D of length >= 2")
        if not np.all(np.isfinite(x)):
            raise InputError("positions_m must be finite")
        if np.any(np.diff(x) <= 0):
            raise InputError("positions_m must be strictly increasing")
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
        self.positions_m = x
        self._xc = xc
        self._pixel = (float(pixel_along_m), dy)
        self._frac = yc[None, :] / w[:, None] + 0.5  # 0 at the left edge, 1 at the right edge
        self._outside = np.abs(yc[None, :]) > w[:, None] / 2 + 1e-12

    def _edge(self, gap_m: np.ndarray, name: str) -> np.ndarray:
        g = np.asarray(gap_m, dtype=float)
        if g.shape != self.positions_m.shape:
            raise InputError(f"{name}: positions_m and gap_m must be 1-D of equal length >= 2")
        if not np.all(np.isfinite(g)):
            raise InputError(f"{name}: positions_m and gap_m must be finite")
        return np.interp(self._xc, self.positions_m, np.maximum(g, 0.0))

    def _map(self, hl: np.ndarray, hr: np.ndarray) -> GapMap:
        h = hl[:, None] * (1 - self._frac) + hr[:, None] * self._frac
        h[self._outside] = np.nan
        return GapMap(h, self._xc, self._pixel)

    def sides(self, left_gap_m: np.ndarray, right_gap_m: np.ndarray) -> GapMap:
        """Gap map from left and right edge profiles [m], linear across the width."""
        return self._map(self._edge(left_gap_m, "left"), self._edge(right_gap_m, "right"))

    def __call__(self, gap_m: np.ndarray) -> GapMap:
        """Gap map of one profile [m] held constant across the width."""
        h = self._edge(gap_m, "left")
        return self._map(h, h)


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
    return ProfileExtruder(
        x,
        width_m,
        pixel_along_m=pixel_along_m,
        pixels_across=pixels_across,
        width_positions_m=width_positions_m,
    ).sides(gl, gr)


def extrude_profile(
    positions_m: np.ndarray,
    gap_m: np.ndarray,
    width_m: float | np.ndarray,
    *,
    pixel_along_m: float = DEFAULT_PIXEL_ALONG_M,
    pixels_across: int = DEFAULT_PIXEL_ACROSS,
    width_positions_m: np.ndarray | None = None,
) -> GapMap:
    """Gap map of a 1-D profile H*(X) held constant across the width (docs/physics.md §4.3).

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
    start_m, end_m : float
        Rear and front pixel edges of the zone's pixel rows [m]: a pixel belongs to the zone
        when its centre lies in [start_m, end_m].
    edge_start_m, edge_end_m : float
        Sub-pixel contact edges [m] (clearance zero crossing, see :func:`_edge_lengths`); the
        extreme over the pixel columns.
    length_m : float
        ``end_m − start_m`` [m] (pixel rows; the sub-pixel length is
        ``edge_end_m − edge_start_m``).
    load_n : float
        Load carried [N].
    load_share : float
        Fraction of F [-].
    apparent_area_m2 : float
        Sub-pixel apparent contact area of the zone [m²].
    """

    start_m: float
    end_m: float
    length_m: float
    load_n: float
    load_share: float
    edge_start_m: float = float("nan")
    edge_end_m: float = float("nan")
    apparent_area_m2: float = 0.0


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
        Apparent contact area [m²] with sub-pixel zone edges along X (module docstring).
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


class _LineOperator:
    """Exact zero-padded Love convolution on an ``(n, ny)`` window, FFT along X only.

    The kernel is even in X, so its transform is real. Along X the convolution is a real FFT of
    length ``2n`` (zero padding: linear, not circular); across the few pixels of the width the
    coupling is a dense ``ny × ny`` product per wavenumber. Exactly the same operator as
    :class:`solvers.elastic.NonPeriodicHalfSpace` (same coefficients, same convention), cheaper
    when ``ny`` is small.

    The kernel is proportional to 1/E': its transform is built once per window shape and pixel
    size for E' = 1 Pa (:func:`_unit_line_coupling`) and divided by E' here, so that a request
    at a new snow modulus does not rebuild it (~1 ms per solve of the Love integrals and the
    transform; issue #29).
    """

    def __init__(self, n: int, ny: int, dx: float, dy: float, e_eff: float) -> None:
        self.n, self.ny = n, ny
        self.padded = 2 * n
        unit_self, unit_coupling = _unit_line_coupling(n, ny, float(dx), float(dy))
        self.self_compliance = unit_self / e_eff
        #: coupling[f, j, k] = K̂(f; |j − k|) [m/Pa]
        self.coupling = unit_coupling / e_eff

    def displacement(self, pressure_pa: np.ndarray) -> np.ndarray:
        """Displacement [m] at the pixel centres of the window under ``pressure_pa`` [Pa]."""
        return line_convolution(pressure_pa, self.coupling, self.n)


try:  # scipy.fft's own C++ pocketfft, called without scipy.fft's per-call Python dispatch
    from scipy.fft._pocketfft import pypocketfft as _pocketfft
except ImportError:  # pragma: no cover - a SciPy without it: the public functions, same result
    _pocketfft = None


def line_convolution(pressure_pa: np.ndarray, coupling: np.ndarray, n: int) -> np.ndarray:
    """The zero-padded convolution of :class:`_LineOperator`: ``irfft(K̂ · rfft(P, 2n))[:n]``
    along X (axis 0), ``K̂`` coupled densely across the width per wavenumber.

    ``pressure_pa`` (n, ny) [Pa]; ``coupling`` (n + 1, ny, ny) the kernel transform [m/Pa].
    Returns the displacement (n, ny) [m]. The transforms are those of ``scipy.fft.rfft`` /
    ``irfft`` (``norm="backward"``, one thread), called through SciPy's pocketfft module
    directly: on the few-hundred-pixel windows of the macro solves the public functions spend
    more time checking and padding their arguments than transforming (84 → 39 µs per
    displacement at 120 × 8 pixels); the results are bit for bit the same
    (tests/solvers/test_macro.py)."""
    padded = 2 * n
    ny = pressure_pa.shape[1]
    if _pocketfft is None:  # pragma: no cover
        ph = scipy.fft.rfft(pressure_pa, n=padded, axis=0)
    else:
        buf = np.zeros((padded, ny))
        buf[:n] = pressure_pa
        ph = _pocketfft.r2c(buf, (0,), True, 0, None, 1)
    uh = ph * coupling[:, 0, :] if ny == 1 else _couple_across(coupling, ph)
    if _pocketfft is None:  # pragma: no cover
        return scipy.fft.irfft(uh, n=padded, axis=0)[:n]
    return _pocketfft.c2r(uh, (0,), padded, False, 2, None, 1)[:n]


@numba.njit(cache=True)
def _couple_across(coupling: np.ndarray, ph: np.ndarray) -> np.ndarray:
    """uh[f, j] = Σ_k coupling[f, j, k] ph[f, k] (dense across the width, per wavenumber).

    The coupling is real, so the real and imaginary parts are summed apart: two products per
    term instead of the four of a complex product whose imaginary factor is zero (the same
    sums, up to the sign of an exact zero)."""
    nf, ny = ph.shape
    out = np.empty_like(ph)
    for f in range(nf):
        for j in range(ny):
            sr = 0.0
            si = 0.0
            for k in range(ny):
                c = coupling[f, j, k]
                v = ph[f, k]
                sr += c * v.real
                si += c * v.imag
            out[f, j] = complex(sr, si)
    return out


#: widest window (pixels across) solved with :class:`_LineOperator`; wider uses 2-D FFTs
_LINE_OPERATOR_MAX_ACROSS = 8


#: window shapes × pixel sizes whose unit-modulus kernel transform is kept (a few hundred KB
#: each: (n + 1) × ny² doubles; a process serves a few presets and window lengths)
UNIT_KERNELS_MAX = 64


@functools.lru_cache(maxsize=UNIT_KERNELS_MAX)
def _unit_line_coupling(n: int, ny: int, dx: float, dy: float) -> tuple[float, np.ndarray]:
    """Self-compliance [m/Pa · Pa] and kernel transform (n + 1, ny, ny) of
    :class:`_LineOperator` for E' = 1 Pa (read-only; divide by E')."""
    padded = 2 * n
    ix = np.arange(padded)
    ix = np.where(ix < n, ix, ix - padded).astype(float)
    iy = np.arange(ny, dtype=float)
    kern = (
        2.0 / np.pi * love_rectangle_influence(ix[:, None] * dx, iy[None, :] * dy, dx / 2, dy / 2)
    )
    kern[n, :] = 0.0  # an offset that an n-long window never reaches
    kh = scipy.fft.rfft(kern, axis=0).real  # (nf, ny), real: the kernel is even in X
    j = np.arange(ny)
    coupling = np.ascontiguousarray(kh[:, np.abs(j[:, None] - j[None, :])])
    coupling.flags.writeable = False
    return float(kern[0, 0]), coupling


@functools.lru_cache(maxsize=32)
def _halfspace(shape: tuple[int, int], dx: float, dy: float, e_eff: float):
    """Cached exact operator per window shape (the kernel transform dominates small solves)."""
    if shape[1] <= _LINE_OPERATOR_MAX_ACROSS:
        return _LineOperator(shape[0], shape[1], dx, dy, e_eff)
    return NonPeriodicHalfSpace(shape, (dx, dy), e_eff, workers=1)


def _fast_rows(n: int) -> int:
    """Smallest m ≥ n whose zero-padded FFT length 2m is 5-smooth (fast)."""
    m = n
    while scipy.fft.next_fast_len(2 * m, real=True) != 2 * m:
        m += 1
    return m


@numba.njit(cache=True)
def _fit_rigid(g, p, xs, tilt):
    """Least-squares δ + θ xs fitted to g on the contact set p > 0 (θ = 0 without tilt)."""
    n = 0
    sx = sxx = sg = sxg = 0.0
    for i in range(p.size):
        if p[i] > 0.0:
            n += 1
            sx += xs[i]
            sxx += xs[i] * xs[i]
            sg += g[i]
            sxg += xs[i] * g[i]
    if n == 0:
        return 0.0, 0.0
    det = n * sxx - sx * sx
    if not tilt or det <= 1e-14 * n * max(sxx, 1e-30):
        return sg / n, 0.0
    return (sxx * sg - sx * sxg) / det, (n * sxg - sx * sg) / det


@numba.njit(cache=True)
def _gap_pass(p, h0, u, xs, tilt, g, gc):
    """g = h0 + u − δ − θ xs with the fitted (δ, θ); gc = g on contact, 0 elsewhere.

    Returns (δ, θ, Σ gc², Σ penetration², contact count, max u).
    """
    for i in range(p.size):
        g[i] = h0[i] + u[i]
    delta, theta = _fit_rigid(g, p, xs, tilt)
    gn = pn = 0.0
    nc = 0
    umax = 0.0
    for i in range(p.size):
        gi = g[i] - delta - theta * xs[i]
        g[i] = gi
        umax = max(umax, u[i])
        if p[i] > 0.0:
            nc += 1
            gc[i] = gi
            gn += gi * gi
        else:
            gc[i] = 0.0
            if gi < 0.0:
                pn += gi * gi
    return delta, theta, gn, pn, nc, umax


@numba.njit(cache=True)
def _step_length(p, r, t, gc, xs, tilt):
    """τ = (gc · t) / (t · (r − fit)) over the contact set; r is the response to t."""
    d0, d1 = _fit_rigid(r, p, xs, tilt)
    num = den = 0.0
    for i in range(p.size):
        if p[i] > 0.0:
            num += gc[i] * t[i]
            den += (r[i] - d0 - d1 * xs[i]) * t[i]
    return num / den if den > 0.0 else 0.0


@numba.njit(cache=True)
def _restore_balance(p, xs, total, tilt):
    """Scale p ≥ 0 in place so that Σp = total and, with tilt, Σ p xs = 0 (multiplicative).

    Returns False if no positive pressure is left (the factor α + β xs clipped everything).
    """
    for _ in range(20):
        s0 = s1 = s2 = 0.0
        for i in range(p.size):
            s0 += p[i]
            s1 += p[i] * xs[i]
            s2 += p[i] * xs[i] * xs[i]
        if s0 <= 0.0:
            return False
        det = s0 * s2 - s1 * s1
        if not tilt or det <= 1e-12 * s0 * s2:
            c = total / s0
            for i in range(p.size):
                p[i] *= c
            # with tilt: all pressure at one X, balanced only if that X is the load point
            return not tilt or abs(s1) <= 1e-12 * s0 * max(np.sqrt(s2 / s0), 1e-300)
        alpha = total * s2 / det
        beta = -total * s1 / det
        clipped = False
        for i in range(p.size):
            if p[i] != 0.0:
                p[i] *= alpha + beta * xs[i]
                if p[i] < 0.0:
                    p[i] = 0.0
                    clipped = True
        if not clipped:
            return True
    s0 = s1 = 0.0
    for i in range(p.size):
        s0 += p[i]
        s1 += p[i] * xs[i]
    return s0 > 0.0 and (not tilt or abs(s1) <= 1e-9 * s0 * _max_abs(xs))


@numba.njit(cache=True)
def _max_abs(v):
    m = 0.0
    for i in range(v.size):
        m = max(m, abs(v[i]))
    return m


@numba.njit(cache=True)
def _update_pressure(p, t, g, tau, restart):
    """p ← max(p − τ t, 0) on contact; penetrating free pixels get −τ g (restart). Σp returned."""
    s = 0.0
    for i in range(p.size):
        if p[i] > 0.0:
            v = p[i] - tau * t[i]
            p[i] = v if v > 0.0 else 0.0
        elif restart and g[i] < 0.0:
            p[i] = -tau * g[i]
        s += p[i]
    return s


@numba.njit(cache=True)
def _new_direction(p, gc, t, beta):
    """t ← gc + β t on contact, 0 elsewhere."""
    for i in range(p.size):
        t[i] = gc[i] + beta * t[i] if p[i] > 0.0 else 0.0


def _pk_tilt(
    hs,
    h0: np.ndarray,
    mask: np.ndarray,
    xs: np.ndarray,
    total: float,
    tilt: bool,
    p_init: np.ndarray | None,
    tol: float,
    max_iterations: int,
) -> tuple[np.ndarray, float, float, int, float, bool]:
    """Constrained CG on the window pixels ``mask`` of the operator's box.

    Pressures are per pixel [Pa], ``total = F / (dx dy)``. The CG vectors live on the window
    pixels only (compressed); the operator sees them scattered into its box.
    """
    idx = np.flatnonzero(mask)
    hc = np.ascontiguousarray(h0.ravel()[idx])
    xc = np.ascontiguousarray(np.broadcast_to(xs, mask.shape).ravel()[idx])
    box = np.zeros(mask.shape)
    flat = box.reshape(-1)

    def apply(v: np.ndarray) -> np.ndarray:
        flat[idx] = v
        return hs.displacement(box).reshape(-1)[idx]

    p = None if p_init is None else np.maximum(p_init.ravel()[idx], 0.0)
    if p is None or not p.sum() > 0:
        p = np.ones(idx.size)
    p = np.ascontiguousarray(p, dtype=float)
    if not _restore_balance(p, xc, total, tilt):
        p[:] = 1.0
        _restore_balance(p, xc, total, tilt)
    t = np.zeros_like(p)
    g = np.empty_like(p)
    gc = np.empty_like(p)
    g_old = 1.0
    restart = True
    delta = theta = 0.0
    residual = np.inf
    converged = False
    it = 0
    while it < max_iterations:
        it += 1
        delta, theta, g_norm, pen_norm, nc, umax = _gap_pass(p, hc, apply(p), xc, tilt, g, gc)
        u_ref = max(umax, 1e-30)
        nc = max(nc, 1)
        residual = (np.sqrt(g_norm / nc) + np.sqrt(pen_norm / nc)) / u_ref
        if residual < tol and p.sum() > 0:
            converged = True
            it -= 1
            break
        _new_direction(p, gc, t, 0.0 if restart else g_norm / g_old)
        g_old = g_norm
        tau = _step_length(p, apply(t), t, gc, xc, tilt)
        if not tau > 0:
            tau = 1.0 / hs.self_compliance
        restart = pen_norm > 0.0
        p_prev = p.copy()
        for _halving in range(40):
            if _update_pressure(p, t, g, tau, restart) > 0 and _restore_balance(p, xc, total, tilt):
                break
            # the projection left no pressure that can balance force and moment: shorter step
            tau *= 0.5
            p[:] = p_prev
            restart = True
        else:  # pragma: no cover - a balanced p_prev makes a short enough step succeed
            p[:] = 1.0
            _restore_balance(p, xc, total, tilt)
    out = np.zeros(mask.size)
    out[idx] = p
    return out.reshape(mask.shape), delta, theta, it, float(residual), converged


#: pixel length along the ski of the coarse line problem that locates the window [m]
_COARSE_PIXEL_M = 8e-3


@dataclass
class _WindowSolve:
    """Solution of the contact problem on a window of candidate pixels (internal)."""

    pressure: np.ndarray  # (nx, ny) [Pa], zero outside the window
    delta: float
    theta: float
    rows: tuple[int, int]
    n_window: int
    margin: float
    iterations: int
    residual: float
    converged: bool


def _solve_windowed(
    h: np.ndarray,
    inside: np.ndarray,
    x: np.ndarray,
    dx: float,
    dy: float,
    f: float,
    xf: float,
    e_eff: float,
    tilt: bool,
    tol: float,
    max_iterations: int,
    delta0: float,
    theta0: float,
    margin: float,
    p_warm: np.ndarray | None,
) -> _WindowSolve:
    """Solve on W = {H* − δ0 − θ0 (X − x_F) ≤ margin}; grow W until the window check passes.

    Check (rigorous, u ≥ 0 for p ≥ 0): every pixel outside W has H ≥ H* − δ − θ (X − x_F);
    if that bound is ≥ 0 the window solution, with P = 0 outside, solves the whole problem.
    """
    xs_full = np.broadcast_to((x - xf)[:, None], h.shape)
    hz = np.where(inside, h, np.inf)
    cand = hz - delta0 - theta0 * xs_full <= margin
    total_its = 0
    for _attempt in range(40):
        rows = np.flatnonzero(cand.any(axis=1))
        if rows.size == 0:
            margin *= 2.0
            cand = hz - delta0 - theta0 * xs_full <= margin
            continue
        i0, i1 = int(rows[0]), int(rows[-1]) + 1
        xw = cand[i0:i1]
        if tilt and not (np.any(xw & (xs_full[i0:i1] < 0)) and np.any(xw & (xs_full[i0:i1] > 0))):
            margin *= 2.0
            cand |= hz - delta0 - theta0 * xs_full <= margin
            continue
        n_sub = _fast_rows(i1 - i0)
        extra = n_sub - (i1 - i0)
        sub_mask = np.pad(xw, ((0, extra), (0, 0)))
        xs = np.broadcast_to((x[i0] + dx * np.arange(n_sub) - xf)[:, None], sub_mask.shape)
        op = _halfspace(sub_mask.shape, dx, dy, e_eff)
        h0 = np.where(sub_mask, np.pad(np.nan_to_num(h[i0:i1]), ((0, extra), (0, 0))), 0.0)
        p_init = None if p_warm is None else np.pad(p_warm[i0:i1], ((0, extra), (0, 0)))
        p_sub, delta, theta, its, res, conv = _pk_tilt(
            op, h0, sub_mask, xs, f / (dx * dy), tilt, p_init, tol, max_iterations
        )
        total_its += its
        p = np.zeros(h.shape)
        p[i0:i1] = p_sub[: i1 - i0]
        bound = np.where(cand, np.inf, hz - delta - theta * xs_full)
        worst = float(bound.min())
        if worst >= 0 or not conv:
            break
        margin = max(2.0 * margin, -1.5 * worst)
        delta0, theta0 = delta, theta
        cand |= hz - delta - theta * xs_full <= margin
        p_warm = p
    return _WindowSolve(
        p, delta, theta, (i0, i1), int(np.count_nonzero(cand)), margin, total_its, res, conv
    )


def _coarse_guess(
    h: np.ndarray,
    inside: np.ndarray,
    x: np.ndarray,
    dx: float,
    width: float,
    f: float,
    xf: float,
    e_eff: float,
    tilt: bool,
) -> tuple[float, float, float, np.ndarray, np.ndarray] | None:
    """δ, θ, displacement scale and line pressure of a coarse 1-pixel-wide line problem.

    The line H*(X) is the width mean of H* over blocks of ``_COARSE_PIXEL_M``; only used to
    place the window (and to warm start), never as a result. None if the grid is too short.
    """
    k = max(2, round(_COARSE_PIXEL_M / dx))
    nxc = h.shape[0] // k
    if nxc < 16:
        return None
    cnt = inside[: nxc * k].sum(axis=1).reshape(nxc, k).sum(axis=1)
    tot = np.where(inside, h, 0.0)[: nxc * k].sum(axis=1).reshape(nxc, k).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        hc = np.where(cnt > 0, tot / np.maximum(cnt, 1), np.nan)[:, None]
    xc = x[: nxc * k].reshape(nxc, k).mean(axis=1)
    inside_c = np.isfinite(hc)
    if tilt and not (xc[inside_c[:, 0]].min() < xf < xc[inside_c[:, 0]].max()):
        return None
    dxc = k * dx
    sol = _solve_windowed(
        hc,
        inside_c,
        xc,
        dxc,
        width,
        f,
        xf,
        e_eff,
        tilt,
        1e-6,
        500,
        float(np.nanmin(hc)),
        0.0,
        50.0 * f / (e_eff * width),
        None,
    )
    i0, i1 = sol.rows
    u_scale = f / (e_eff * width * max((i1 - i0) * dxc, dxc))
    return sol.delta, sol.theta, u_scale, xc, sol.pressure[:, 0]


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
    initial_rigid_body: tuple[float, float] | None = None,
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
        E' of docs/physics.md eq. (1) [Pa].
    tilt : bool
        Solve for the tilt θ with moment balance about x_F (default); False: θ = 0, force only.
    tol : float
        Relative residual (RMS clearance on the contact set over the largest displacement) [-].
    max_iterations : int
        CG iterations per window; exhausting them returns ``converged=False``.
    window_gap_m : float, optional
        Initial margin [m] on the rigid interference ``H* − δ0 − θ0 (X − x_F)`` that defines
        the solved window (δ0, θ0 from a coarse line problem); default a quarter of the coarse
        displacement scale. Raised automatically until the window check passes.
    initial_pressure_pa : ndarray (nx, ny), optional
        Warm start [Pa].
    initial_rigid_body : (float, float), optional
        Approach δ0 [m] and tilt θ0 [rad] of a nearby solution (for example the same ski with
        a slightly different profile): with it, the coarse line problem that places the window
        is skipped and the window is ``H* − δ0 − θ0 (X − x_F) ≤ window_gap_m`` (give
        ``window_gap_m`` too, e.g. the nearby solution's). The window check still holds: the
        window grows until it passes, so the answer is the same, only cheaper.

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
    if window_gap_m is not None and not (np.isfinite(window_gap_m) and window_gap_m > 0):
        raise InputError(f"window_gap_m must be finite and > 0, got {window_gap_m!r}")
    inside = np.isfinite(h)
    foot_x = x[inside.any(axis=1)]
    if tilt and not (foot_x.min() - dx / 2 < xf < foot_x.max() + dx / 2):
        raise InputError(
            f"load_position_m {xf} m lies outside the footprint "
            f"({foot_x.min() - dx / 2:.4g} .. {foot_x.max() + dx / 2:.4g} m): no moment balance"
        )
    width = float(inside.sum(axis=1).max() * dy)
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
            True,
            0,
            0.0,
            "zero load: no contact",
            t0,
        )
    p_warm = None
    if initial_pressure_pa is not None:
        p_warm = np.asarray(initial_pressure_pa, dtype=float)
        if p_warm.shape != h.shape:
            raise InputError(
                f"initial_pressure_pa has shape {p_warm.shape}, expected the gap map's {h.shape}"
            )
        p_warm = np.where(inside & np.isfinite(p_warm), p_warm, 0.0)
    if initial_rigid_body is not None:
        delta0, theta0 = (float(v) for v in initial_rigid_body)
        if not (np.isfinite(delta0) and np.isfinite(theta0)):
            raise InputError(f"initial_rigid_body must be finite, got {initial_rigid_body!r}")
        guess = None
    else:
        guess = _coarse_guess(h, inside, x, dx, width, f, xf, e_eff, tilt)
    if initial_rigid_body is not None:
        margin = float(window_gap_m) if window_gap_m is not None else 50.0 * f / (e_eff * width)
    elif guess is None:  # short grid: start from a generous window on H* alone
        delta0, theta0 = float(np.nanmin(h)), 0.0
        margin = float(window_gap_m) if window_gap_m is not None else 50.0 * f / (e_eff * width)
    else:
        delta0, theta0, u_scale, xc, pc = guess
        margin = float(window_gap_m) if window_gap_m is not None else 0.25 * u_scale
        if p_warm is None:
            p_warm = np.where(inside, np.interp(x, xc, pc)[:, None], 0.0)
    sol = _solve_windowed(
        h,
        inside,
        x,
        dx,
        dy,
        f,
        xf,
        e_eff,
        tilt,
        tol,
        max_iterations,
        delta0,
        theta0,
        margin,
        p_warm,
    )
    p, delta, theta = sol.pressure, sol.delta, sol.theta
    i0, i1 = sol.rows
    # clearance everywhere on the footprint from the full displacement field
    u_full = _halfspace(h.shape, dx, dy, e_eff).displacement(p)
    clear = np.where(inside, h + u_full - delta - theta * xs_full, np.nan)
    clear[p > 0] = 0.0
    clear = np.where(inside, np.maximum(clear, 0.0), np.nan)
    its, res, conv = sol.iterations, sol.residual, sol.converged
    msg = (
        f"converged in {its} iterations (residual {res:.3g} < tol {tol:.3g})"
        if conv
        else f"not converged: {its} iterations, residual {res:.3g} (tol {tol:.3g})"
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
        sol.margin,
        sol.n_window,
        conv,
        its,
        res,
        msg,
        t0,
        window_length=float((i1 - i0) * dx),
    )


@numba.njit(cache=True, error_model="numpy")
def _edge(h1: float, h2: float, x1: float, x0: float) -> float:
    """Sub-pixel contact edge between the last contact pixel (centre x0) and the first free
    pixel beyond it (centre x1, clearance h1 [m]), with h2 the clearance of the next free pixel
    (centre 2 x1 − x0): zero crossing of H^{2/3}, linear in X, clipped to [x0, x1]."""
    if not (np.isfinite(h1) and np.isfinite(h2)) or not (h2 > h1 and h1 >= 0):
        return 0.5 * (x0 + x1)
    a1, a2 = h1 ** (2.0 / 3.0), h2 ** (2.0 / 3.0)
    e = x1 + (x0 - x1) * a1 / (a2 - a1)
    return min(max(e, min(x0, x1)), max(x0, x1))


@numba.njit(cache=True, error_model="numpy")
def _edge_lengths(
    contact: np.ndarray, clearance: np.ndarray, x: np.ndarray, a: int, b: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sub-pixel contact edges and contact length of the rows a..b−1, per pixel column [m].

    Outside a smooth contact edge the clearance grows as d^{3/2} (d: distance from the edge),
    so H^{2/3} is linear in X; its zero crossing through the first two free pixels beyond each
    run of contact pixels (along X, in each column) is that run's edge, clipped to lie between
    the last contact and the first free pixel centres. Pixel counting puts the edge midway,
    which is the fallback when the two clearances are not available (footprint end) and for
    runs of a single pixel (a contact narrower than a pixel cannot be located by two edges).
    Compiled (numba): the runs are few, but a Python loop over them cost about half of
    :func:`_finish` (0.7 ms per solve at the default grid); the arithmetic is the same.

    Returns
    -------
    rear, front : ndarray (ny,)
        Rearmost and frontmost edge per column [m]; NaN in columns without contact.
    length : ndarray (ny,)
        Contact length per column, summed over its runs [m].
    """
    nx, ny = contact.shape
    dx = x[1] - x[0]
    rear = np.full(ny, np.nan)
    front = np.full(ny, np.nan)
    length = np.zeros(ny)
    for j in range(ny):
        r = a
        while r < b:
            if not contact[r, j]:
                r += 1
                continue
            r0 = r
            while r + 1 < b and contact[r + 1, j]:
                r += 1
            r1 = r
            r += 1
            if r1 == r0:  # one contact pixel cannot place two edges: count it
                e_r, e_f = x[r0] - dx / 2, x[r0] + dx / 2
                length[j] += dx
            else:
                h1 = clearance[r0 - 1, j] if r0 >= 1 else np.nan
                h2 = clearance[r0 - 2, j] if r0 >= 2 else np.nan
                e_r = _edge(h1, h2, x[r0] - dx, x[r0])
                h1 = clearance[r1 + 1, j] if r1 + 1 < nx else np.nan
                h2 = clearance[r1 + 2, j] if r1 + 2 < nx else np.nan
                e_f = _edge(h1, h2, x[r1] + dx, x[r1])
                length[j] += e_f - e_r
            rear[j] = e_r if np.isnan(rear[j]) else min(rear[j], e_r)
            front[j] = e_f if np.isnan(front[j]) else max(front[j], e_f)
    return rear, front, length


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
    force = float(p0.sum() * dx * dy)
    moment = float(np.sum(p0 * (x - xf)[:, None]) * dx * dy)
    zones: list[ContactZone] = []
    row = contact.any(axis=1).astype(np.int8)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], row, [0]])))
    area = 0.0
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        load = float(p0[a:b].sum() * dx * dy)
        rear, front, length = _edge_lengths(contact, clearance, x, a, b)
        zone_area = float(length.sum() * dy)
        area += zone_area
        e0, e1 = float(np.nanmin(rear)), float(np.nanmax(front))
        zones.append(
            ContactZone(
                start_m=float(x[a] - dx / 2),
                end_m=float(x[b - 1] + dx / 2),
                length_m=float((b - a) * dx),
                load_n=load,
                load_share=load / force if force > 0 else 0.0,
                edge_start_m=e0,
                edge_end_m=e1,
                apparent_area_m2=zone_area,
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
