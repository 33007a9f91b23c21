"""Closed-form contact solutions used as references by the tests and benchmarks.

All use the modulus convention of docs/physics.md §3: E' with ``û = 4 p̂ / (E'|q|)``, i.e. Johnson's
composite modulus ``E* = E'/2``.

References
----------
- H. M. Westergaard, "Bearing pressures and cracks", J. Appl. Mech. 6 (1939) A49-A53; Johnson,
  Contact Mechanics (1985) §13.2: a 1-D wave ``h = Δ cos(2πx/λ)`` on a half-space.
- K. L. Johnson, J. A. Greenwood, J. G. Higginson, "The contact of elastic regular wavy
  surfaces", Int. J. Mech. Sci. 27 (1985) 383-396: full contact of ``Δ cos x cos y`` at
  ``p = √2 π E* Δ / λ``.
- H. Hertz (1882); Johnson (1985) §4.2: sphere of radius R under load F.
- J. Boussinesq (1885); Johnson (1985) §3.8: rigid flat circular punch of radius a,
  ``F = 2 a E* d``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "flat_punch_stiffness",
    "hertz_contact_radius",
    "hertz_peak_pressure",
    "hertz_pressure",
    "jgh_full_contact_pressure",
    "westergaard_contact_fraction",
    "westergaard_full_contact_pressure",
    "westergaard_pressure",
]


def westergaard_full_contact_pressure(
    amplitude_m: float, wavelength_m: float, effective_modulus_pa: float
) -> float:
    """p* = π E* Δ / λ [Pa], the mean pressure that closes a 1-D wave of amplitude Δ."""
    return np.pi * (effective_modulus_pa / 2) * amplitude_m / wavelength_m


def westergaard_contact_fraction(
    mean_pressure_pa: float, amplitude_m: float, wavelength_m: float, effective_modulus_pa: float
) -> float:
    """Contact fraction 2a/λ = (2/π) arcsin √(P/p*) [-] of a 1-D wave."""
    p_star = westergaard_full_contact_pressure(amplitude_m, wavelength_m, effective_modulus_pa)
    ratio = min(mean_pressure_pa / p_star, 1.0)
    return float(2 / np.pi * np.arcsin(np.sqrt(ratio)))


def westergaard_pressure(
    x_m: np.ndarray,
    mean_pressure_pa: float,
    amplitude_m: float,
    wavelength_m: float,
    effective_modulus_pa: float,
) -> np.ndarray:
    """Pressure [Pa] of a 1-D wave with contact centred on x = 0.

    ``p(x) = 2 P cos(πx/λ) / sin²(πa/λ) · √(sin²(πa/λ) − sin²(πx/λ))`` for |x| < a.
    """
    p_star = westergaard_full_contact_pressure(amplitude_m, wavelength_m, effective_modulus_pa)
    ratio = mean_pressure_pa / p_star
    if ratio >= 1:
        return mean_pressure_pa + p_star * np.cos(2 * np.pi * np.asarray(x_m) / wavelength_m)
    s2 = ratio  # sin²(πa/λ) = P/p*
    xs = np.asarray(x_m, dtype=float)
    xs = (xs + wavelength_m / 2) % wavelength_m - wavelength_m / 2
    sx2 = np.sin(np.pi * xs / wavelength_m) ** 2
    inside = sx2 < s2
    out = np.zeros_like(xs)
    out[inside] = (
        2
        * mean_pressure_pa
        * np.cos(np.pi * xs[inside] / wavelength_m)
        / s2
        * np.sqrt(s2 - sx2[inside])
    )
    return out


def jgh_full_contact_pressure(
    amplitude_m: float, wavelength_m: float, effective_modulus_pa: float
) -> float:
    """√2 π E* Δ / λ [Pa]: full contact of ``Δ cos(2πx/λ) cos(2πy/λ)``."""
    return np.sqrt(2) * np.pi * (effective_modulus_pa / 2) * amplitude_m / wavelength_m


def hertz_contact_radius(load_n: float, radius_m: float, effective_modulus_pa: float) -> float:
    """Hertz contact radius a = (3 F R / (4 E*))^(1/3) [m]."""
    return float((3 * load_n * radius_m / (4 * effective_modulus_pa / 2)) ** (1 / 3))


def hertz_peak_pressure(load_n: float, radius_m: float, effective_modulus_pa: float) -> float:
    """Hertz peak pressure p0 = 3F / (2πa²) [Pa]."""
    a = hertz_contact_radius(load_n, radius_m, effective_modulus_pa)
    return float(3 * load_n / (2 * np.pi * a * a))


def hertz_pressure(
    r_m: np.ndarray, load_n: float, radius_m: float, effective_modulus_pa: float
) -> np.ndarray:
    """Hertz pressure p0 √(1 − r²/a²) [Pa]."""
    a = hertz_contact_radius(load_n, radius_m, effective_modulus_pa)
    p0 = hertz_peak_pressure(load_n, radius_m, effective_modulus_pa)
    r = np.asarray(r_m, dtype=float)
    return p0 * np.sqrt(np.clip(1 - (r / a) ** 2, 0.0, None))


def flat_punch_stiffness(radius_m: float, effective_modulus_pa: float) -> float:
    """Boussinesq: load per unit indentation of a rigid flat circular punch, 2 a E* [N/m]."""
    return 2 * radius_m * effective_modulus_pa / 2
