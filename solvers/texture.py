"""Textures: height maps, ISO 25178 areal parameters and synthetic linear grinds."""

from __future__ import annotations

import numpy as np

from .errors import InputError

__all__ = ["self_affine_surface"]


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
