"""Error bands: the pieces that turn measured error sources into a 90 % band on an answer.

An answer of skisnow carries three kinds of error (docs/physics.md §4, docs/limits.md):

- the **camber model** (the loaded profile H*(X) from the network or a beam identified from
  noisy camber data) — propagated here by solving again with perturbed profiles;
- the **macro grid** — measured per preset by ``skisnow bench accuracy``;
- the **texture table** (interpolation between table points, and the texture's pixel size where
  it was estimated).

Each source gives a relative 90 % half-width per reported quantity; independent sources are
combined in quadrature (:func:`combine`). The profile perturbations are smooth random fields
(:func:`profile_perturbations`): a Gaussian-correlated field of standard deviation
``sigma_m`` and correlation length ``correlation_m``, drawn from an explicit seed so that the
same request always gets the same band.

Pure kernels: arrays and SI floats in, arrays and dicts out.
"""

from __future__ import annotations

import math

import numpy as np
from skisnow.solvers.errors import InputError

__all__ = [
    "Z90",
    "combine",
    "end_pixel_share",
    "flat_stretch",
    "model_error_sigma",
    "one_sided_part",
    "position_error_sigma",
    "profile_perturbations",
    "sampled_half_width",
    "table_interpolation_error",
    "unit_perturbations",
]

#: two-sided 90 % quantile of the standard normal distribution
Z90 = 1.6448536269514722


def model_error_sigma(held_out_rms_m: float, noise_m: float, floor_m: float = 0.0) -> float:
    """Standard deviation of a profile model's own error [m], from its held-out RMS residual
    against *noisy* measurements and the device noise: ``sqrt(max(rms² − noise², floor²))``.

    The held-out residual mixes the model's error with the measurement noise, which is
    independent of it, so the variances subtract. On the demo skis this recovers the model's
    error against the noise-free truth: 1.12 vs 1.13 µm (ski-a), 0.47 vs 0.51 µm (ski-b)."""
    if not (held_out_rms_m >= 0 and noise_m >= 0 and floor_m >= 0):
        raise InputError("held_out_rms_m, noise_m and floor_m must be ≥ 0")
    return math.sqrt(max(held_out_rms_m**2 - noise_m**2, floor_m**2))


def profile_perturbations(
    positions_m: np.ndarray,
    sigma_m: float | np.ndarray,
    correlation_m: float,
    samples: int,
    seed: int,
) -> np.ndarray:
    """``samples`` smooth random fields δH(X) [m], shape (samples, M), each with pointwise
    standard deviation ``sigma_m`` (a constant, or one value per position) and Gaussian
    correlation exp(−Δ²/(2 ℓ²)), ℓ = ``correlation_m``. Drawn in antithetic pairs (δ, −δ)
    so that the mean perturbation is zero and a linear response has no sampling bias.
    ``unit_perturbations(...) · sigma_m`` (:func:`unit_perturbations`, which a caller may
    keep for a grid it perturbs often)."""
    x = np.asarray(positions_m, dtype=float)
    unit = unit_perturbations(x, correlation_m, samples, seed)
    sigma = np.broadcast_to(np.asarray(sigma_m, dtype=float), x.shape)
    if not np.all(sigma >= 0):
        raise InputError("correlation_m must be > 0 and sigma_m ≥ 0")
    return unit * sigma


def unit_perturbations(
    positions_m: np.ndarray, correlation_m: float, samples: int, seed: int
) -> np.ndarray:
    """The fields of :func:`profile_perturbations` with unit standard deviation [-], shape
    (samples, M): they depend on the grid, ℓ, the count and the seed only."""
    x = np.asarray(positions_m, dtype=float)
    if x.ndim != 1 or x.size < 2:
        raise InputError("positions_m must be a 1-D grid of at least 2 points")
    if samples < 2 or samples % 2:
        raise InputError(f"samples must be an even number ≥ 2, got {samples}")
    if not correlation_m > 0:
        raise InputError("correlation_m must be > 0 and sigma_m ≥ 0")
    rng = np.random.default_rng(seed)
    # white noise on a padded uniform grid, smoothed by a Gaussian kernel of std ℓ/√2 (the
    # convolution of two such kernels gives the correlation exp(−Δ²/(2ℓ²))), then sampled at X
    dx = min(float(np.min(np.diff(x))), correlation_m / 4)
    pad = 4 * correlation_m
    grid = np.arange(x[0] - pad, x[-1] + pad + dx, dx)
    s = correlation_m / math.sqrt(2)
    half = math.ceil(4 * s / dx)
    k = np.exp(-0.5 * (np.arange(-half, half + 1) * dx / s) ** 2)
    k /= math.sqrt(np.sum(k**2))
    n_pairs = samples // 2
    white = rng.standard_normal((n_pairs, grid.size))
    smooth = np.array([np.convolve(w, k, mode="same") for w in white])
    fields = np.array([np.interp(x, grid, f) for f in smooth])
    return np.concatenate([fields, -fields])


def sampled_half_width(nominal: float, samples: np.ndarray) -> float:
    """Relative 90 % half-width [-] of a quantity from its values under the perturbations:
    ``Z90 · rms(sample − nominal) / |nominal|`` (RMS about the nominal answer, not the sample
    mean, so that a shift of the answer under perturbation counts as error). Non-finite samples
    are dropped; with fewer than two left the width is ``nan``."""
    v = np.asarray(samples, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 2 or not math.isfinite(nominal) or nominal == 0:
        return float("nan")
    return float(Z90 * np.sqrt(np.mean((v - nominal) ** 2)) / abs(nominal))


def end_pixel_share(zone_lengths_m: np.ndarray, pixel_along_m: float) -> float:
    """Share [-] of an answer's contact length that lies in the end pixels of its contact zones:
    ``2 · n_zones · Δx / Σ L_z``. Each zone end is located only to within a pixel, so this is
    the scale of the apparent area's grid error (the pixels counted in or out at the ends).
    Zones shorter than a pixel count as one pixel; no zone gives ``nan``.

    Parameters
    ----------
    zone_lengths_m : array_like
        Lengths of the contact zones along the ski [m].
    pixel_along_m : float
        Pixel size along the ski [m], > 0.
    """
    lengths = np.asarray(zone_lengths_m, dtype=float).ravel()
    if not (math.isfinite(pixel_along_m) and pixel_along_m > 0):
        raise InputError(f"pixel_along_m must be finite and > 0, got {pixel_along_m!r}")
    if np.any(~np.isfinite(lengths)) or np.any(lengths < 0):
        raise InputError("zone_lengths_m must be finite and >= 0")
    if lengths.size == 0:
        return float("nan")
    total = float(np.sum(np.maximum(lengths, pixel_along_m)))
    return min(2.0 * lengths.size * pixel_along_m / total, 2.0)


def table_interpolation_error(ratios: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Interpolation error estimate of a table column [-] at each node: leave node i out, fit
    the same log-log PCHIP the lookup uses (:mod:`solvers.lookup`) through the others, and take
    the relative miss at node i, divided by 4. Leaving a node out doubles the local spacing, and
    PCHIP's error grows at least with the square of the spacing, so the quarter still bounds the
    error between the table's own nodes from above. End nodes (which cannot be left out) copy
    their neighbour's estimate. Non-positive values give ``nan``."""
    from scipy.interpolate import PchipInterpolator

    r = np.asarray(ratios, dtype=float)
    v = np.asarray(values, dtype=float)
    if r.ndim != 1 or r.shape != v.shape or r.size < 4:
        raise InputError("ratios and values must be 1-D of the same size ≥ 4")
    if np.any(np.diff(r) <= 0) or np.any(r <= 0):
        raise InputError("ratios must be positive and strictly increasing")
    out = np.full(r.shape, np.nan)
    ok = v > 0
    lr = np.log(r)
    with np.errstate(divide="ignore", invalid="ignore"):
        lv = np.log(np.where(ok, v, np.nan))
    for i in range(1, r.size - 1):
        keep = ok.copy()
        keep[i] = False
        if not ok[i] or keep.sum() < 2:
            continue
        f = PchipInterpolator(lr[keep], lv[keep], extrapolate=False)
        out[i] = abs(math.expm1(float(f(lr[i])) - lv[i])) / 4.0
    out[0], out[-1] = out[1], out[-2]
    return out


def combine(components: dict[str, dict[str, float]]) -> dict[str, float]:
    """Quadrature sum of independent relative half-widths: ``{source: {quantity: w}}`` →
    ``{quantity: sqrt(Σ w²)}`` over the sources that give the quantity (``nan`` ignored)."""
    out: dict[str, float] = {}
    for widths in components.values():
        for q, w in widths.items():
            if w is None or not math.isfinite(w):
                continue
            out[q] = math.hypot(out.get(q, 0.0), float(w))
    return out


def one_sided_part(width: float, part: float, share_above: float) -> tuple[float, float]:
    """Relative 90 % half-widths (below, above) [-] of an answer whose combined half-width
    ``width`` (:func:`combine`) holds a ``part`` that is a one-sided bias: an error that makes
    the answer too large, so that the truth lies below it (the macro grid's apparent area,
    docs/limits.md "The grid part is a bias").

    ``share_above`` in [0, 1] is how much of ``part`` may still lie above the answer: 1 gives
    the symmetric band (``width``, ``width``); 0 gives the rest ``R = sqrt(width² − part²)``
    above and ``R + part`` below (a bias adds to the other errors, it does not average with
    them). Between: below ``(1 − s)(R + part) + s·width``, above ``sqrt(R² + (s·part)²)``.
    ``nan`` in gives ``nan`` out."""
    if not (math.isfinite(width) and math.isfinite(part)):
        return float("nan"), float("nan")
    if not 0.0 <= share_above <= 1.0:
        raise InputError(f"share_above must lie in [0, 1], got {share_above!r}")
    if width < 0 or part < 0:
        raise InputError("width and part must be ≥ 0")
    part = min(part, width)
    rest = math.sqrt(max(width * width - part * part, 0.0))
    s = share_above
    below = (1.0 - s) * (rest + part) + s * width
    above = math.hypot(rest, s * part)
    return below, above


def position_error_sigma(
    positions_m: np.ndarray,
    residuals_m: np.ndarray,
    noise_m: float,
    window_m: float,
    floor_m: float = 0.0,
) -> np.ndarray:
    """A profile model's error standard deviation along the ski, σ(X) [m], from its held-out
    residuals against noisy measurements: the RMS of ``residuals_m`` (cases × positions, ``nan``
    where a point does not count, e.g. outside the contact band) over a moving window of width
    ``window_m`` around each position, with the device noise removed in quadrature
    (:func:`model_error_sigma`). Positions whose window holds no residual get the overall value.

    On the demo skis this tracks the error against the noise-free truth bin by bin (ski-a:
    2.09 µm near the tail vs 0.43 µm behind the binding, truth 2.09 / 0.62 µm)."""
    x = np.asarray(positions_m, dtype=float)
    r = np.asarray(residuals_m, dtype=float)
    if x.ndim != 1 or r.ndim != 2 or r.shape[1] != x.size:
        raise InputError("residuals_m must be (cases, positions) on positions_m")
    if not window_m > 0:
        raise InputError("window_m must be > 0")
    sq = np.nansum(r**2, axis=0)
    n = np.sum(np.isfinite(r), axis=0).astype(float)
    cs, cn = np.concatenate([[0.0], np.cumsum(sq)]), np.concatenate([[0.0], np.cumsum(n)])
    lo = np.searchsorted(x, x - window_m / 2, side="left")
    hi = np.searchsorted(x, x + window_m / 2, side="right")
    tot_n = cn[hi] - cn[lo]
    overall = math.sqrt(float(cs[-1] / cn[-1])) if cn[-1] > 0 else float("nan")
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.where(tot_n > 0, np.sqrt((cs[hi] - cs[lo]) / np.maximum(tot_n, 1)), overall)
    return np.sqrt(np.maximum(rms**2 - noise_m**2, floor_m**2))


def flat_stretch(
    positions_m: np.ndarray, gap_m: np.ndarray, flat_gap_m: float, taper_m: float
) -> tuple[float, float, np.ndarray]:
    """Where a loaded profile lies near the flat (docs/physics.md §4c, the flat-base regime).

    Returns the length [m] and midpoint [m] of the longest run of positions with
    ``gap_m < flat_gap_m`` (contact points, gap 0, included), and a weight in [0, 1] per
    position: 1 where the gap is below ``flat_gap_m``, tapered to 0 over ``taper_m`` on either
    side (a moving average), so that a perturbation weighted by it has no step. Positions are
    sorted ascending; non-finite gaps count as far from the flat."""
    x = np.asarray(positions_m, dtype=float)
    g = np.asarray(gap_m, dtype=float)
    if x.ndim != 1 or g.shape != x.shape or x.size < 2:
        raise InputError("positions_m and gap_m must be 1-D of the same size ≥ 2")
    if not (flat_gap_m > 0 and taper_m >= 0):
        raise InputError("flat_gap_m must be > 0 and taper_m ≥ 0")
    near = np.isfinite(g) & (g < flat_gap_m)
    best, mid = 0.0, float("nan")
    edges = np.diff(np.concatenate([[0], near.astype(np.int8), [0]]))
    for a, b in zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1, strict=True):
        # a run of k points stands for k pixels of the profile's spacing
        length = float(x[b] - x[a]) + float(np.median(np.diff(x)))
        if length > best:
            best, mid = length, 0.5 * float(x[a] + x[b])
    weight = near.astype(float)
    dx = float(np.median(np.diff(x)))
    n = round(taper_m / dx) if dx > 0 else 0
    if n >= 1 and near.any():
        k = np.ones(2 * n + 1) / (2 * n + 1)
        weight = np.maximum(weight, np.clip(np.convolve(weight, k, mode="same"), 0.0, 1.0))
    return (best if near.any() else 0.0), mid, weight
