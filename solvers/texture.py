"""Textures: height maps, ISO 25178 areal parameters and synthetic linear grinds.

A texture is the ski-base height map h*(x, y) of a patch ω (docs/physics.md §2, §5), stored as a 2-D
float64 array in metres. **Axis 0 runs along the ski** (the x direction, the direction of the
grinding grooves of a linear grind); axis 1 runs across the ski (y). ``heights_m[i, j]`` is the
height at ``x = i·Δ``, ``y = j·Δ`` with one square pixel size Δ [m].

ISO 25178-2 parameters (our own small implementation, :func:`iso25178_parameters`):

- the reference plane is the mean (heights are taken as already levelled, see
  :func:`level_heights`); ``Sa``, ``Sq``, ``Ssk``, ``Sku`` are the moments of the heights;
- gradients use second-order central differences, ``(h[i+1] − h[i−1]) / 2Δ``; on a periodic
  grid (``periodic=True``, the synthetic grinds, which feed a periodic FFT solver) the neighbours
  wrap around, on an open grid (``periodic=False``, measured maps) the edge rows and columns use
  one-sided first-order differences (``numpy.gradient``). ``Sdq`` is the RMS gradient
  [dimensionless, m/m]; docs/physics.md quotes it in µm/mm, so 65.79 µm/mm is 0.06579. ``Sdr``
  is the mean of ``sqrt(1 + |∇h|²) − 1`` in per cent;
- the functional ``Sk`` family comes from the areal material ratio curve as in ISO 13565-2,
  adapted to areal data: the 40 % window of the curve whose secant has the least slope is the
  core; the equivalent straight line is the least-squares line through the curve inside that
  window; its heights at 0 % and 100 % bound the core (``Sk``); ``Smr1`` and ``Smr2`` are the
  material ratios where the curve crosses those two heights; ``Spk`` and ``Svk`` are the heights
  of the triangles with the areas of the peak and valley regions beyond the core.

Measured maps are not periodic, but the micro solver is (periodic FFT half-space);
:func:`make_periodic` makes a measured map fit it (mirror tiling, a cosine-tapered window, or
nothing), see ``docs/topography.md`` for the choice and its measured effect.

Synthetic linear grinds (:func:`linear_grind`) are periodic in both directions: an integer
number of grooves across the cell (axis 1), every groove straight along axis 0, plus seeded
self-affine roughness (:func:`self_affine_surface`, periodic by construction).
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass, field

import numpy as np

from .errors import InputError

__all__ = [
    "DETREND_METHODS",
    "GRIND_TARGETS",
    "GRIND_TOLERANCES",
    "PERIODISATION_METHODS",
    "GrindFit",
    "GrindParameters",
    "Texture",
    "check_detrend",
    "combined_detrend",
    "fit_linear_grind",
    "fourier_upsample",
    "iso25178_parameters",
    "level_heights",
    "linear_grind",
    "make_periodic",
    "periodic_shape",
    "self_affine_surface",
    "target_errors",
]

log = logging.getLogger(__name__)


@dataclass
class Texture:
    """A levelled ski-base height map.

    Attributes
    ----------
    heights_m : numpy.ndarray
        Heights h* [m], 2-D float64, axis 0 along the ski (groove direction), axis 1 across.
    pixel_size_m : float
        Pixel size Δ, the same along both axes [m].
    name : str
        Short name (e.g. "grind-1").
    missing_fraction : float
        Fraction of the points that were missing in the source and filled [-].
    source : str
        Where the heights came from (file path, "synthetic: ...").
    detrend : str
        What was removed from the source heights to give ``heights_m`` (one of
        :data:`DETREND_METHODS`): ``"plane"`` the least-squares plane, ``"mean"`` the mean
        height, ``"none"`` nothing (the heights as given; the default for a texture built
        from an array in code).
    """

    heights_m: np.ndarray
    pixel_size_m: float
    name: str
    missing_fraction: float = 0.0
    source: str = ""
    detrend: str = "none"

    @property
    def shape(self) -> tuple[int, int]:
        """Grid size (along, across) [-]."""
        return self.heights_m.shape

    @property
    def size_m(self) -> tuple[float, float]:
        """Cell size (along, across) [m]."""
        n0, n1 = self.heights_m.shape
        return n0 * self.pixel_size_m, n1 * self.pixel_size_m

    def parameters(self, *, periodic: bool = False) -> dict[str, float]:
        """ISO 25178 parameters of the heights, see :func:`iso25178_parameters`."""
        return iso25178_parameters(self.heights_m, self.pixel_size_m, periodic=periodic)


# --------------------------------------------------------------------------- validation


def _check_pixel_size(pixel_size_m: float) -> float:
    try:
        value = float(pixel_size_m)
    except (TypeError, ValueError):
        raise InputError(f"pixel_size_m must be a number, got {pixel_size_m!r}") from None
    if not (np.isfinite(value) and value > 0):
        raise InputError(f"pixel_size_m must be finite and > 0, got {pixel_size_m!r}")
    return value


def _check_grid(heights_m, name: str = "heights_m") -> np.ndarray:
    h = np.asarray(heights_m, dtype=np.float64)
    if h.ndim != 2:
        raise InputError(f"{name} must be a 2-D array, got {h.ndim} dimension(s)")
    if min(h.shape) < 2:
        raise InputError(f"{name} needs at least 2 points along each axis, got shape {h.shape}")
    return h


# --------------------------------------------------------------------------- levelling


def _plane_basis(shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    n0, n1 = shape
    i = (np.arange(n0, dtype=np.float64) - (n0 - 1) / 2)[:, None] * np.ones((1, n1))
    j = np.ones((n0, 1)) * (np.arange(n1, dtype=np.float64) - (n1 - 1) / 2)[None, :]
    return i, j


def _plane_fit(h: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Least-squares plane a + b·i + c·j over the valid points, evaluated on the whole grid."""
    i, j = _plane_basis(h.shape)
    a = np.stack([np.ones(int(valid.sum())), i[valid], j[valid]], axis=1)
    coef, _, rank, _ = np.linalg.lstsq(a, h[valid], rcond=None)
    if rank < 3:
        raise InputError(
            "heights_m: the valid points lie on one line; a mean plane cannot be fitted"
        )
    return coef[0] + coef[1] * i + coef[2] * j


#: What :func:`level_heights` can remove from a height map before it is solved:
#: ``"plane"`` the least-squares plane (tilt and mean; the default for measured, non-periodic
#: maps), ``"mean"`` only the mean height (the default for maps declared periodic: a plane
#: fit of a periodic map removes a tilt it does not have and puts a step at the wrap),
#: ``"none"`` nothing. The micro solver is invariant to the mean height (the gap is measured
#: from the highest point), so ``"mean"`` and ``"none"`` give the same contact.
DETREND_METHODS = ("plane", "mean", "none")


def check_detrend(detrend) -> str:
    """``detrend`` if it is one of :data:`DETREND_METHODS`, else :class:`InputError`."""
    if not isinstance(detrend, str) or detrend not in DETREND_METHODS:
        raise InputError(f"detrend must be one of {', '.join(DETREND_METHODS)}, got {detrend!r}")
    return detrend


def combined_detrend(first: str, then: str) -> str:
    """The detrending equal to ``first`` followed by ``then`` [one of :data:`DETREND_METHODS`].

    Removing the least-squares plane also removes the mean, and removing the mean of a map
    without plane leaves it without plane, so the composition is the stronger of the two
    (none < mean < plane).
    """
    order = {m: i for i, m in enumerate(reversed(DETREND_METHODS))}
    return max(check_detrend(first), check_detrend(then), key=order.__getitem__)


def level_heights(
    heights_m,
    pixel_size_m: float,
    *,
    detrend: str = "plane",
    max_missing_fraction: float = 0.5,
) -> tuple[np.ndarray, float]:
    """Fill missing points and remove the least-squares plane, the mean, or nothing.

    Steps for ``detrend="plane"``: (1) fit the mean plane to the valid (finite) points and
    subtract it; (2) give every missing (NaN) point the levelled value of its nearest valid
    point (Euclidean distance on the grid); (3) remove the least-squares plane of the filled
    map, so the result has zero mean and no tilt over the full grid. ``"mean"``: the same with
    the mean height in place of the plane (the tilt is kept). ``"none"``: only step (2); the
    valid heights are returned unchanged.

    Parameters
    ----------
    heights_m : array_like
        Raw heights [m], 2-D, NaN where the instrument did not measure.
    pixel_size_m : float
        Pixel size Δ [m] (validated; the plane is fitted in pixel coordinates).
    detrend : str
        ``"plane"`` (default), ``"mean"`` or ``"none"``, see :data:`DETREND_METHODS`.
    max_missing_fraction : float
        Largest accepted fraction of missing points [-], in [0, 1).

    Returns
    -------
    heights_m : numpy.ndarray
        Detrended, filled heights [m], float64, same shape.
    missing_fraction : float
        Fraction of the points that were missing and have been filled [-].

    Raises
    ------
    InputError
        Unknown ``detrend``, not 2-D, fewer than 2 points along an axis, ±inf values, all or
        too many points missing, or a flat map (constant; with ``"plane"``, any plane: nothing
        left after levelling).
    """
    from scipy import ndimage

    _check_pixel_size(pixel_size_m)
    detrend = check_detrend(detrend)
    if not (0 <= max_missing_fraction < 1):
        raise InputError(f"max_missing_fraction must be in [0, 1), got {max_missing_fraction!r}")
    h = _check_grid(heights_m).copy()
    if np.isinf(h).any():
        raise InputError(
            f"heights_m contains {int(np.isinf(h).sum())} infinite value(s); "
            "mark missing points with NaN"
        )
    valid = np.isfinite(h)
    n_missing = int(h.size - valid.sum())
    missing_fraction = n_missing / h.size
    if n_missing == h.size:
        raise InputError("heights_m has no valid point (all NaN)")
    if missing_fraction > max_missing_fraction:
        raise InputError(
            f"heights_m is mostly missing: {missing_fraction:.1%} of the points are NaN, "
            f"more than max_missing_fraction={max_missing_fraction:.1%}"
        )
    if detrend == "plane" and valid.sum() < 3:
        raise InputError(f"heights_m has only {int(valid.sum())} valid point(s); need >= 3")
    raw_range = float(np.ptp(h[valid]))
    if detrend == "plane":
        h = h - _plane_fit(h, valid)
    elif detrend == "mean":
        h = h - h[valid].mean()
    if n_missing:
        idx = ndimage.distance_transform_edt(~valid, return_distances=False, return_indices=True)
        h = h[tuple(idx)]
        if detrend == "plane":
            h = h - _plane_fit(h, np.ones_like(valid))
    if detrend != "none":
        h -= h.mean()
    if raw_range == 0 or np.ptp(h) <= 1e-9 * raw_range:
        what = "a plane" if detrend == "plane" else "constant"
        raise InputError(
            f"heights_m is flat ({what}, peak-to-valley 0 after detrend={detrend!r}): no texture"
        )
    return h, missing_fraction


# --------------------------------------------------------------------------- periodisation

#: Ways :func:`make_periodic` can make an open (measured) map fit the periodic solver
PERIODISATION_METHODS = ("none", "mirror", "window")


def _tukey(n: int, taper_fraction: float) -> np.ndarray:
    """Periodic Tukey window: cosine ramps over ``taper_fraction`` of ``n`` at each end.

    ``w[0] = 0`` and the ramp up at the start mirrors the ramp down at the end, so the periodic
    continuation ``w[n] = w[0]`` is smooth.
    """
    m = max(1, round(taper_fraction * n))
    w = np.ones(n)
    ramp = 0.5 * (1 - np.cos(np.pi * np.arange(m) / m))  # 0 ... just below 1
    w[:m] = ramp
    w[n - m + 1 :] = ramp[1:][::-1]
    return w


def periodic_shape(shape: tuple[int, ...], method: str = "mirror") -> tuple[int, ...]:
    """Shape of :func:`make_periodic` ``(h, method)`` for a map of ``shape``, without building it.

    The grid the periodic solver works on: ``(2·n0, 2·n1)`` for ``"mirror"``, else ``shape``.
    Lets a caller check the solve size of a map before it allocates the periodised heights.

    Raises
    ------
    InputError
        Unknown method.
    """
    if method not in PERIODISATION_METHODS:
        raise InputError(
            f"method must be one of {', '.join(PERIODISATION_METHODS)}, got {method!r}"
        )
    shape = tuple(int(n) for n in shape)
    return tuple(2 * n for n in shape) if method == "mirror" else shape


def make_periodic(heights_m, method: str = "mirror", *, taper_fraction: float = 0.1) -> np.ndarray:
    """Make an open (non-periodic) height map fit the periodic FFT solver.

    The periodic solver sees the map as one cell of an infinite tiling. A measured map's
    opposite edges do not match, so the plain tiling has steps (and a cut through every groove)
    at the cell edges. The methods:

    ``"none"``
        The map unchanged (a copy): the tiling keeps its edge steps. Right only for periodic
        maps (synthetic grinds).
    ``"mirror"``
        Even reflection across both axes: the result has shape ``(2·n0, 2·n1)``, blocks
        ``[[h, h[:, ::-1]], [h[::-1, :], h[::-1, ::-1]]]``. The tiling is continuous (no steps,
        slope kinks at the edges only) and every measured point is used with weight one. A
        solve on it equals the solve of the measured patch alone with symmetry (frictionless
        wall) conditions on its four edges, so area fraction and mean gaps of the doubled grid
        are those of the patch. Costs 4× the points.
    ``"window"``
        Heights (about their mean) multiplied by a separable periodic Tukey window whose cosine
        ramps span ``taper_fraction`` of each side at each end: the edges go smoothly to the
        mean plane, the shape is kept, the mean is removed again. The tapered border is lowered
        towards the mean, so fewer peaks touch there (see ``docs/topography.md``).

    Parameters
    ----------
    heights_m : array_like
        Levelled heights [m], 2-D, finite, axis 0 along the ski.
    method : str
        One of :data:`PERIODISATION_METHODS`.
    taper_fraction : float
        Fraction of each side covered by each cosine ramp of ``"window"`` [-], in (0, 0.5].

    Returns
    -------
    numpy.ndarray
        Heights [m], float64; shape ``(2·n0, 2·n1)`` for ``"mirror"``, else unchanged. The
        pixel size is unchanged.

    Raises
    ------
    InputError
        Unknown method, bad ``taper_fraction``, non-finite or non-2-D heights.
    """
    if method not in PERIODISATION_METHODS:
        raise InputError(
            f"method must be one of {', '.join(PERIODISATION_METHODS)}, got {method!r}"
        )
    h = _check_grid(heights_m)
    if not np.isfinite(h).all():
        raise InputError("heights_m contains NaN or inf; level and fill the map first")
    if method == "none":
        return h.copy()
    if method == "mirror":
        top = np.concatenate([h, h[:, ::-1]], axis=1)
        return np.concatenate([top, top[::-1, :]], axis=0)
    try:
        tf = float(taper_fraction)
    except (TypeError, ValueError):
        raise InputError(f"taper_fraction must be a number, got {taper_fraction!r}") from None
    if not (0 < tf <= 0.5):
        raise InputError(f"taper_fraction must be in (0, 0.5], got {taper_fraction!r}")
    w = _tukey(h.shape[0], tf)[:, None] * _tukey(h.shape[1], tf)[None, :]
    out = (h - h.mean()) * w
    return out - out.mean()


# --------------------------------------------------------------------------- ISO 25178


def _gradients(h: np.ndarray, dx: float, periodic: bool) -> tuple[np.ndarray, np.ndarray]:
    if periodic:
        g0 = (np.roll(h, -1, axis=0) - np.roll(h, 1, axis=0)) / (2 * dx)
        g1 = (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1)) / (2 * dx)
        return g0, g1
    g0, g1 = np.gradient(h, dx, dx, edge_order=1)
    return g0, g1


def _material_ratio_parameters(h: np.ndarray) -> dict[str, float]:
    """Sk, Spk, Svk, Smr1, Smr2 from the areal material ratio curve (ISO 13565-2 on areas)."""
    z = np.sort(h.ravel())[::-1]  # heights at material ratio mr_k = (k + 0.5)/n, descending
    n = z.size
    mr = (np.arange(n) + 0.5) / n
    w = max(round(0.4 * n), 2)
    drop = z[: n - w] - z[w:]  # height drop of each 40 % secant
    k = int(np.argmin(drop))
    seg = slice(k, k + w + 1)
    slope, intercept = np.polyfit(mr[seg], z[seg], 1)  # equivalent straight line
    top = intercept  # line at mr = 0
    bottom = intercept + slope  # line at mr = 1
    sk = top - bottom
    # material ratios where the curve crosses the core limits (z is descending)
    eps = 1e-12 * (z[0] - z[-1])  # rounding of the fitted line (flat cores)
    smr1 = np.count_nonzero(z > top + eps) / n
    smr2 = np.count_nonzero(z >= bottom - eps) / n
    peaks = z[z > top + eps] - top
    valleys = bottom - z[z < bottom - eps]
    a1 = peaks.sum() / n  # peak area [m · ratio]
    a2 = valleys.sum() / n
    spk = 2 * a1 / smr1 if smr1 > 0 else 0.0
    svk = 2 * a2 / (1 - smr2) if smr2 < 1 else 0.0
    return {
        "Sk_m": float(sk),
        "Spk_m": float(spk),
        "Svk_m": float(svk),
        "Smr1_percent": float(100 * smr1),
        "Smr2_percent": float(100 * smr2),
    }


def iso25178_parameters(
    heights_m, pixel_size_m: float, *, periodic: bool = False
) -> dict[str, float]:
    """ISO 25178-2 areal parameters of a height map.

    Parameters
    ----------
    heights_m : array_like
        Heights [m], 2-D, finite. The mean is removed; a tilt is *not* (level first).
    pixel_size_m : float
        Pixel size Δ [m].
    periodic : bool
        Whether the map is periodic (gradients wrap around) or open (one-sided at the edges).

    Returns
    -------
    dict
        ``Sa_m``, ``Sq_m`` [m]; ``Ssk``, ``Sku`` [-]; ``Sdq`` [m/m]; ``Sdr_percent`` [%];
        ``Sk_m``, ``Spk_m``, ``Svk_m`` [m]; ``Smr1_percent``, ``Smr2_percent`` [%].
        All plain floats.
    """
    dx = _check_pixel_size(pixel_size_m)
    h = _check_grid(heights_m)
    if not np.isfinite(h).all():
        raise InputError("heights_m contains NaN or inf; fill missing points first")
    h = h - h.mean()
    sq = float(np.sqrt(np.mean(h**2)))
    if sq == 0:
        raise InputError("heights_m is flat (Sq = 0): ISO parameters are undefined")
    g0, g1 = _gradients(h, dx, periodic)
    grad2 = g0**2 + g1**2
    out = {
        "Sa_m": float(np.mean(np.abs(h))),
        "Sq_m": sq,
        "Ssk": float(np.mean(h**3) / sq**3),
        "Sku": float(np.mean(h**4) / sq**4),
        "Sdq": float(np.sqrt(np.mean(grad2))),
        "Sdr_percent": float(100 * np.mean(np.sqrt(1 + grad2) - 1)),
    }
    out.update(_material_ratio_parameters(h))
    return out


# --------------------------------------------------------------------------- self-affine


def self_affine_surface(
    shape: tuple[int, int],
    pixel_size_m: float,
    *,
    hurst: float,
    rms_height_m: float,
    rng: np.random.Generator,
    long_cutoff_m: float | None = None,
    short_cutoff_m: float | None = None,
) -> np.ndarray:
    """Seeded periodic self-affine random surface by Fourier filtering [m].

    PSD ``C(q) ∝ q^(−2(1+H))`` between the roll-off wavevector ``2π/long_cutoff`` (flat below)
    and ``2π/short_cutoff`` (zero above); the result is rescaled to ``rms_height_m``.

    Parameters
    ----------
    shape : (int, int)
        Grid size [-].
    pixel_size_m : float
        Pixel size [m].
    hurst : float
        Hurst exponent H in (0, 1] [-].
    rms_height_m : float
        Target RMS height Sq [m].
    rng : numpy.random.Generator
        Source of randomness (explicit seed).
    long_cutoff_m, short_cutoff_m : float, optional
        Roll-off and short-wavelength cut-off [m]; default the cell size and 2 pixels.
    """
    if not (0 < hurst <= 1):
        raise InputError(f"hurst must be in (0, 1], got {hurst!r}")
    if not (np.isfinite(rms_height_m) and rms_height_m > 0):
        raise InputError(f"rms_height_m must be finite and > 0, got {rms_height_m!r}")
    nx, ny = shape
    qx = 2 * np.pi * np.fft.fftfreq(nx, d=pixel_size_m)[:, None]
    qy = 2 * np.pi * np.fft.rfftfreq(ny, d=pixel_size_m)[None, :]
    q = np.sqrt(qx**2 + qy**2)
    q_r = 2 * np.pi / (long_cutoff_m or max(nx, ny) * pixel_size_m)
    q_s = 2 * np.pi / (short_cutoff_m or 2 * pixel_size_m)
    amp = np.where(q > 0, np.maximum(q, q_r) ** (-(1 + hurst)), 0.0)
    amp[q > q_s] = 0.0
    noise = rng.normal(size=q.shape) + 1j * rng.normal(size=q.shape)
    h = np.fft.irfft2(amp * noise, s=(nx, ny))
    h -= h.mean()
    sq = np.sqrt(np.mean(h**2))
    if sq == 0:
        raise InputError("surface parameters leave no roughness on this grid")
    return h * (rms_height_m / sq)


# --------------------------------------------------------------------------- linear grinds


@dataclass(frozen=True)
class GrindParameters:
    """Parameters of the synthetic linear-grind model of :func:`linear_grind`.

    One period across the ski (axis 1) is a groove followed by a flat land. In the local
    coordinate ``t ∈ [−1, 1]`` of a groove (``t = 0`` at its deepest point) the groove profile
    is ``−D·(1 − |t|^p)``: ``p = 1`` a V, ``p = 2`` a parabola, large ``p`` a flat-bottomed
    groove with steep walls, ``p < 1`` cusped walls. Raised lips (burrs) of Gaussian shape sit
    on the land at both edges of every groove. Random roughness is added on top.

    Attributes
    ----------
    pitch_m : float
        Mean groove pitch across the ski [m]; the number of grooves in the cell is the nearest
        integer to ``width / pitch_m`` (at least 1), so the map stays periodic.
    depth_m : float
        Mean groove depth D below the land [m].
    land_fraction : float
        Fraction of each pitch that is flat land [-], in [0, 0.95].
    groove_exponent : float
        Shape exponent p of the groove profile [-], in [0.2, 50].
    asymmetry : float
        Position of the deepest point inside the groove, −1 (at the leading edge) … 0 (centre)
        … 1 (trailing edge) [-], in (−0.95, 0.95): one wall steeper than the other.
    lip_height_m : float
        Height of the raised lips at the groove edges [m], >= 0.
    lip_width_m : float
        Standard deviation (half-width) of the Gaussian lips [m], > 0.
    pitch_jitter, depth_jitter : float
        Relative standard deviations of the pitch and depth of each groove [-], in [0, 0.3].
    roughness_rms_m : float
        RMS height of the self-affine roughness [m], >= 0 (0: none).
    roughness_hurst : float
        Hurst exponent of the roughness [-], in (0, 1].
    roughness_long_cutoff_m, roughness_short_cutoff_m : float
        Roll-off and short cut-off wavelengths of the roughness [m]; the short cut-off is
        raised to 2 pixels and the long one to the short one if needed.
    """

    pitch_m: float
    depth_m: float
    land_fraction: float = 0.3
    groove_exponent: float = 2.0
    asymmetry: float = 0.0
    lip_height_m: float = 0.0
    lip_width_m: float = 5e-6
    pitch_jitter: float = 0.05
    depth_jitter: float = 0.05
    roughness_rms_m: float = 0.0
    roughness_hurst: float = 0.8
    roughness_long_cutoff_m: float = 100e-6
    roughness_short_cutoff_m: float = 4e-6

    def __post_init__(self) -> None:
        def need(name: str, ok: bool, rule: str) -> None:
            if not ok:
                raise InputError(f"{name} must be {rule}, got {getattr(self, name)!r}")

        for name in self.__dataclass_fields__:
            value = getattr(self, name)
            need(name, isinstance(value, int | float) and np.isfinite(value), "a finite number")
        need("pitch_m", self.pitch_m > 0, "> 0")
        need("depth_m", self.depth_m >= 0, ">= 0")
        need("land_fraction", 0 <= self.land_fraction <= 0.95, "in [0, 0.95]")
        need("groove_exponent", 0.2 <= self.groove_exponent <= 50, "in [0.2, 50]")
        need("asymmetry", -0.95 < self.asymmetry < 0.95, "in (-0.95, 0.95)")
        need("lip_height_m", self.lip_height_m >= 0, ">= 0")
        need("lip_width_m", self.lip_width_m > 0, "> 0")
        need("pitch_jitter", 0 <= self.pitch_jitter <= 0.3, "in [0, 0.3]")
        need("depth_jitter", 0 <= self.depth_jitter <= 0.3, "in [0, 0.3]")
        need("roughness_rms_m", self.roughness_rms_m >= 0, ">= 0")
        need("roughness_hurst", 0 < self.roughness_hurst <= 1, "in (0, 1]")
        need("roughness_long_cutoff_m", self.roughness_long_cutoff_m > 0, "> 0")
        need("roughness_short_cutoff_m", self.roughness_short_cutoff_m > 0, "> 0")

    def to_dict(self) -> dict[str, float]:
        """Plain-float dictionary (units in the names)."""
        return {k: float(v) for k, v in asdict(self).items()}


#: Oversampling of the groove profile inside one pixel (area-averaged, like an instrument)
_PROFILE_OVERSAMPLING = 8


def _groove_profile(
    n1: int, pixel_size_m: float, p: GrindParameters, rng, refine: int = 1
) -> np.ndarray:
    """Periodic profile across the ski [m], pixel-averaged, length ``n1 · refine``.

    The profile is sampled at ``_PROFILE_OVERSAMPLING`` points per pixel of the ``n1`` grid; with
    ``refine > 1`` each of the ``refine`` finer pixels averages its share of the same sample
    points, so the block average of the refined profile is the unrefined profile. Beyond
    that (``refine`` 16) the profile is sampled ``refine`` times per pixel, one point per fine
    pixel, at the fine pixels' centres: the same groove shapes, their block average the
    unrefined profile up to the difference between 8- and 16-point pixel averages.
    """
    width = n1 * pixel_size_m
    n_grooves = max(1, round(width / p.pitch_m))
    z = rng.standard_normal((2, n_grooves))  # fixed draw order: pitch, then depth
    pitches = p.pitch_m * np.clip(1 + p.pitch_jitter * z[0], 0.5, 1.5)
    pitches *= width / pitches.sum()
    depths = p.depth_m * np.clip(1 + p.depth_jitter * z[1], 0.2, 1.8)
    starts = np.concatenate([[0.0], np.cumsum(pitches)[:-1]])
    m = max(_PROFILE_OVERSAMPLING, refine)
    y = (np.arange(n1 * m) + 0.5) * (pixel_size_m / m)
    prof = np.zeros_like(y)
    v0 = 0.5 * (1 + p.asymmetry)  # deepest point, fraction of the groove width
    for start, pitch, depth in zip(starts, pitches, depths, strict=True):
        g = (1 - p.land_fraction) * pitch  # groove width
        if g > 0:
            v = (y - start) / g
            inside = (v >= 0) & (v < 1)
            vi = v[inside]
            t = np.where(vi < v0, (v0 - vi) / v0, (vi - v0) / (1 - v0))
            prof[inside] -= depth * (1 - t**p.groove_exponent)
        if p.lip_height_m > 0:
            for edge in (start, start + g):
                d = (y - edge + width / 2) % width - width / 2
                prof += p.lip_height_m * np.exp(-0.5 * (d / p.lip_width_m) ** 2)
    return prof.reshape(n1 * refine, m // refine).mean(axis=1)


def fourier_upsample(heights_m: np.ndarray, refine: int, *, shift_px: float = 0.0) -> np.ndarray:
    """Trigonometric interpolation of a periodic, band-limited map onto a ``refine``× finer grid.

    The rfft2 spectrum is zero-padded (1/N normalisation of numpy's inverse, so the result is
    multiplied by ``refine²``). Fine sample ``j`` (each axis) lies at ``(j + shift_px)`` fine
    pixels from the first input sample: with ``shift_px = 0`` every ``refine``-th sample of the
    result is the input. Exact for maps without content at the Nyquist rows and columns
    (checked: that content must be below 1e-12 of the total, else ``InputError``).

    Parameters
    ----------
    heights_m : numpy.ndarray
        Periodic map (even sizes) [m].
    refine : int
        Refinement factor >= 1 [-].
    shift_px : float, optional
        Offset of the fine samples, in fine pixels [-].
    """
    h = np.asarray(heights_m, dtype=float)
    if refine == 1 and shift_px == 0:
        return h.copy()
    n0, n1 = h.shape
    if n0 % 2 or n1 % 2:
        raise InputError(f"fourier_upsample needs even grid sizes, got {h.shape}")
    spec = np.fft.rfft2(h)
    nyq = np.abs(spec[n0 // 2, :]).sum() + np.abs(spec[:, -1]).sum()
    if nyq > 1e-12 * max(np.abs(spec).sum(), 1e-300):
        raise InputError("fourier_upsample: the map has content at the Nyquist frequency")
    f0, f1 = refine * n0, refine * n1
    out = np.zeros((f0, f1 // 2 + 1), dtype=complex)
    half = n0 // 2
    out[:half, : n1 // 2] = spec[:half, : n1 // 2]
    out[f0 - half + 1 :, : n1 // 2] = spec[half + 1 :, : n1 // 2]
    if shift_px:
        m0 = np.fft.fftfreq(f0, d=1.0 / f0)[:, None]
        m1 = np.arange(f1 // 2 + 1)[None, :]
        out *= np.exp(2j * np.pi * shift_px * (m0 / f0 + m1 / f1))
    return np.fft.irfft2(out, s=(f0, f1)) * refine**2


def linear_grind(
    shape: tuple[int, int],
    pixel_size_m: float,
    params: GrindParameters,
    rng: np.random.Generator | int,
    *,
    refine: int = 1,
) -> np.ndarray:
    """Seeded synthetic linear stone grind [m], periodic in both directions.

    Grooves run along axis 0 (along the ski); the groove pattern of :class:`GrindParameters`
    repeats across axis 1 with an integer number of grooves; self-affine roughness
    (:func:`self_affine_surface`) is added. The random draws happen in a fixed order (groove
    pitches, groove depths, roughness), so for a given seed and grid the result is a smooth
    function of the continuous parameters (used by :func:`fit_linear_grind`).

    Parameters
    ----------
    shape : (int, int)
        Grid size (along, across) [-], each >= 2.
    pixel_size_m : float
        Pixel size Δ [m].
    params : GrindParameters
        Groove and roughness parameters.
    rng : numpy.random.Generator or int
        Source of randomness, or a seed for ``numpy.random.default_rng``.
    refine : int, optional
        1 (default), 2, 4, 8 or 16: the **same** surface on a ``refine``× finer grid
        (``shape · refine`` pixels of ``pixel_size_m / refine``, the same patch). The random
        draws are those of ``shape``; the groove profile is averaged over the finer pixels from
        the same sub-samples (its block average is the unrefined profile), the band-limited
        roughness is trigonometrically interpolated (:func:`fourier_upsample`, exact: its
        short cut-off lies far below the Nyquist frequency) at the points that keep its
        position against the grooves (on the unrefined grid pixel ``i`` holds the roughness
        at ``i·Δ`` and the profile averaged over ``[i·Δ, (i + 1)·Δ]``; refined pixels hold the
        roughness half a coarse pixel before their centres), so the block average of a refined
        map is the unrefined map up to the second-order difference between a point value and
        a pixel average of the roughness. Used for pixel-refinement studies and the two-level
        tables (docs/tables.md). With 16 the profile is sampled at the fine pixels' centres
        (16 points per pixel instead of the 8 the other levels share; see
        :func:`_groove_profile`): the block average of a 16× map is the unrefined map to
        6e-4 of its RMS on the shipped grinds (1e-3 is what
        :func:`app.storage.textures.refined_texture` accepts).

    Returns
    -------
    numpy.ndarray
        Heights [m], float64, zero mean; shape ``shape · refine``.
    """
    if refine not in (1, 2, 4, 8, 16):
        raise InputError(f"refine must be 1, 2, 4, 8 or 16, got {refine!r}")
    dx = _check_pixel_size(pixel_size_m)
    try:
        n0, n1 = (int(s) for s in shape)
    except (TypeError, ValueError):
        raise InputError(f"shape must be two integers, got {shape!r}") from None
    if min(n0, n1) < 2:
        raise InputError(f"shape needs at least 2 points along each axis, got {shape!r}")
    if not isinstance(params, GrindParameters):
        raise InputError(f"params must be GrindParameters, got {type(params).__name__}")
    if not isinstance(rng, np.random.Generator):
        rng = np.random.default_rng(rng)
    prof = _groove_profile(n1, dx, params, rng, refine)
    h = np.broadcast_to(prof[None, :], (n0 * refine, n1 * refine)).copy()
    if params.roughness_rms_m > 0:
        short = max(params.roughness_short_cutoff_m, 2 * dx)
        long = max(params.roughness_long_cutoff_m, short)
        rough = self_affine_surface(
            (n0, n1),
            dx,
            hurst=params.roughness_hurst,
            rms_height_m=params.roughness_rms_m,
            rng=rng,
            long_cutoff_m=long,
            short_cutoff_m=short,
        )
        h += fourier_upsample(rough, refine, shift_px=(1 - refine) / 2) if refine > 1 else rough
    h -= h.mean()
    return h


# --------------------------------------------------------------------------- fitting

_UM = 1e-6

#: ISO 25178 parameters of the two linear grinds of docs/physics.md §7, SI (Sdq: 65.79 µm/mm → m/m)
GRIND_TARGETS: dict[str, dict[str, float]] = {
    "grind-1": {
        "Sa_m": 1.77 * _UM,
        "Sq_m": 2.16 * _UM,
        "Ssk": -0.16,
        "Sku": 2.58,
        "Sdq": 65.79e-3,
        "Spk_m": 1.44 * _UM,
        "Sk_m": 6.01 * _UM,
        "Svk_m": 1.92 * _UM,
    },
    "grind-2": {
        "Sa_m": 8.77 * _UM,
        "Sq_m": 9.62 * _UM,
        "Ssk": -0.43,
        "Sku": 1.63,
        "Sdq": 185.77e-3,
        "Spk_m": 2.16 * _UM,
        "Sk_m": 11.65 * _UM,
        "Svk_m": 20.02 * _UM,
    },
}

#: Accepted deviation of a synthetic grind from its target: ("rel", r) or ("abs", a)
GRIND_TOLERANCES: dict[str, tuple[str, float]] = {
    "Sa_m": ("rel", 0.05),
    "Sq_m": ("rel", 0.05),
    "Sdq": ("rel", 0.05),
    "Ssk": ("abs", 0.2),
    "Sku": ("abs", 0.2),
    "Sk_m": ("rel", 0.2),
    "Spk_m": ("rel", 0.2),
    "Svk_m": ("rel", 0.2),
}


def target_errors(achieved: dict[str, float], targets: dict[str, float]) -> dict[str, float]:
    """Deviation of each targeted parameter in units of its tolerance (|e| <= 1 passes) [-].

    Relative tolerances of :data:`GRIND_TOLERANCES` divide ``(achieved − target)/|target|``,
    absolute ones ``achieved − target``; a key without a listed tolerance uses 5 % relative.
    """
    out = {}
    for key, target in targets.items():
        if key not in achieved:
            raise InputError(f"targets: unknown ISO parameter {key!r}; known: {sorted(achieved)}")
        kind, tol = GRIND_TOLERANCES.get(key, ("rel", 0.05))
        diff = achieved[key] - target
        out[key] = diff / tol if kind == "abs" else diff / (abs(target) * tol)
    return out


@dataclass
class GrindFit:
    """Result of :func:`fit_linear_grind`; unpacks as ``(parameters, heights_m, achieved)``.

    Attributes
    ----------
    parameters : GrindParameters
        Fitted generator parameters.
    heights_m : numpy.ndarray
        The grind at the requested shape [m].
    achieved : dict
        ISO parameters of ``heights_m`` (periodic gradients), SI.
    errors : dict
        Deviation of each target in units of its tolerance (:func:`target_errors`) [-].
    seed : int
        Seed of the generator.
    converged : bool
        Whether every target is within its tolerance at the requested shape.
    iterations : int
        Objective evaluations spent.
    objective : float
        Final sum of squared normalised errors [-].
    message : str
        Human-readable summary.
    """

    parameters: GrindParameters
    heights_m: np.ndarray
    achieved: dict[str, float]
    errors: dict[str, float]
    seed: int
    converged: bool
    iterations: int
    objective: float
    message: str = ""
    history: list[float] = field(default_factory=list, repr=False)

    def __iter__(self):
        return iter((self.parameters, self.heights_m, self.achieved))


# fitted parameters and their unconstrained coordinates
_FIT_NAMES = (
    "depth_m",
    "land_fraction",
    "groove_exponent",
    "depth_jitter",
    "lip_height_m",
    "lip_width_m",
    "roughness_rms_m",
    "roughness_short_cutoff_m",
)


def _to_x(p: GrindParameters) -> np.ndarray:
    lf = min(max(p.land_fraction, 1e-3), 0.949) / 0.95
    dj = min(max(p.depth_jitter, 1e-4), 0.299) / 0.3
    return np.array(
        [
            np.log(max(p.depth_m, 1e-9) / _UM),
            np.log(lf / (1 - lf)),
            np.log(p.groove_exponent),
            np.log(dj / (1 - dj)),
            np.log(max(p.lip_height_m, 1e-9) / _UM),
            np.log(p.lip_width_m / _UM),
            np.log(max(p.roughness_rms_m, 1e-9) / _UM),
            np.log(p.roughness_short_cutoff_m / _UM),
        ]
    )


def _from_x(x: np.ndarray, base: GrindParameters) -> GrindParameters:
    x = np.clip(x, -30, 30)
    values = {
        "depth_m": np.exp(x[0]) * _UM,
        "land_fraction": 0.95 / (1 + np.exp(-x[1])),
        "groove_exponent": float(np.clip(np.exp(x[2]), 0.2, 50)),
        "depth_jitter": 0.3 / (1 + np.exp(-x[3])),
        "lip_height_m": np.exp(x[4]) * _UM,
        "lip_width_m": np.exp(x[5]) * _UM,
        "roughness_rms_m": np.exp(x[6]) * _UM,
        "roughness_short_cutoff_m": np.exp(x[7]) * _UM,
    }
    d = base.to_dict()
    d.update({k: float(v) for k, v in values.items()})
    return GrindParameters(**d)


def fit_linear_grind(
    targets: dict[str, float],
    shape: tuple[int, int],
    pixel_size_m: float,
    seed: int,
    *,
    initial: GrindParameters | None = None,
    pitch_m: float | None = None,
    fit_rows: int = 128,
    max_evaluations: int = 3000,
    polish_evaluations: int = 150,
    callback=None,
) -> GrindFit:
    """Tune the linear-grind generator to match target ISO 25178 parameters.

    Nelder-Mead (scipy) on eight unconstrained coordinates (log depth, logit land fraction,
    log groove exponent, logit depth jitter, log lip height and width, log roughness RMS and short
    cut-off) minimises ``Σ e_k²`` with ``e_k`` the deviation of target ``k`` in units of its
    tolerance (:func:`target_errors`). The random draws are fixed by ``seed``, so the objective
    is deterministic. The search runs on a reduced grid of ``fit_rows`` rows (grooves run along
    the rows, so the groove pattern is identical and only the roughness realisation is
    shorter), restarting the simplex until it stops improving; a short polish then runs at the
    requested ``shape``. Pitch, pitch jitter, asymmetry, Hurst exponent and roughness roll-off
    are held at ``initial``'s values.

    Parameters
    ----------
    targets : dict
        Target ISO parameters, keys as returned by :func:`iso25178_parameters`, SI.
    shape : (int, int)
        Grid size of the result (along, across) [-].
    pixel_size_m : float
        Pixel size Δ [m].
    seed : int
        Seed of every random draw.
    initial : GrindParameters, optional
        Starting point (and fixed parameters); default a generic grind scaled on Sq.
    pitch_m : float, optional
        Groove pitch [m] replacing ``initial.pitch_m``; default a fifth of the cell width.
    fit_rows : int
        Rows of the reduced search grid [-].
    max_evaluations : int
        Objective evaluations of the reduced search [-].
    polish_evaluations : int
        Objective evaluations of the full-size polish [-] (0: none).
    callback : callable, optional
        Called as ``callback(stage, evaluations, objective)`` after each simplex run.

    Returns
    -------
    GrindFit
        Typed result; unpacks as ``(parameters, heights_m, achieved)``.
    """
    from scipy.optimize import minimize

    dx = _check_pixel_size(pixel_size_m)
    if not targets:
        raise InputError("targets must name at least one ISO parameter")
    for key, value in targets.items():
        if not np.isfinite(value):
            raise InputError(f"targets[{key!r}] must be finite, got {value!r}")
    n0, n1 = (int(s) for s in shape)
    if min(n0, n1) < 2:
        raise InputError(f"shape needs at least 2 points along each axis, got {shape!r}")
    if initial is None:
        sq = targets.get("Sq_m", targets.get("Sa_m", 1 * _UM) * 1.25)
        initial = GrindParameters(
            pitch_m=pitch_m or n1 * dx / 5,
            depth_m=3 * sq,
            land_fraction=0.3,
            groove_exponent=2.0,
            asymmetry=0.1,
            lip_height_m=0.2 * sq,
            lip_width_m=5 * dx,
            roughness_rms_m=0.5 * sq,
            roughness_short_cutoff_m=10 * dx,
        )
    elif pitch_m is not None:
        initial = GrindParameters(**{**initial.to_dict(), "pitch_m": pitch_m})

    evaluations = 0
    history: list[float] = []

    def objective(x, rows):
        nonlocal evaluations
        evaluations += 1
        try:
            p = _from_x(x, initial)
            h = linear_grind((rows, n1), dx, p, seed)
            e = target_errors(iso25178_parameters(h, dx, periodic=True), targets)
        except InputError:
            return 1e12
        return float(sum(v * v for v in e.values()))

    x = _to_x(initial)
    rows_fit = min(fit_rows, n0)
    best = objective(x, rows_fit)
    # restart the simplex from its best point until a restart no longer helps
    while evaluations < max_evaluations:
        res = minimize(
            objective,
            x,
            args=(rows_fit,),
            method="Nelder-Mead",
            options={
                "maxfev": min(1500, max_evaluations - evaluations),
                "xatol": 1e-4,
                "fatol": 1e-6,
                "adaptive": True,
            },
        )
        history.append(float(res.fun))
        if callback is not None:
            callback("search", evaluations, float(res.fun))
        improved = res.fun < best - 1e-3 * max(best, 1e-3)
        if res.fun < best:
            x, best = res.x, float(res.fun)
        if not improved:
            break
    if polish_evaluations > 0 and rows_fit < n0:
        res = minimize(
            objective,
            x,
            args=(n0,),
            method="Nelder-Mead",
            options={
                "maxfev": polish_evaluations,
                "adaptive": True,
                "initial_simplex": x + np.vstack([np.zeros(len(x)), 0.05 * np.eye(len(x))]),
            },
        )
        history.append(float(res.fun))
        if callback is not None:
            callback("polish", evaluations, float(res.fun))
        full_start = objective(x, n0)
        if res.fun < full_start:
            x = res.x
    params = _from_x(x, initial)
    heights = linear_grind((n0, n1), dx, params, seed)
    achieved = iso25178_parameters(heights, dx, periodic=True)
    errors = target_errors(achieved, targets)
    worst = max(errors, key=lambda k: abs(errors[k]))
    ok = all(abs(v) <= 1 for v in errors.values())
    objective_value = float(sum(v * v for v in errors.values()))
    message = (
        f"{'all targets met' if ok else 'targets missed'}; worst {worst}: "
        f"{errors[worst]:+.2f} tolerances; {evaluations} evaluations"
    )
    log.info("fit_linear_grind: %s", message)
    return GrindFit(
        params,
        heights,
        achieved,
        errors,
        int(seed),
        ok,
        evaluations,
        objective_value,
        message,
        history,
    )
