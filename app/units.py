"""Technician units at the edge: the only place kg, mm, µm, kPa and MPa become SI.

Every function names its input unit; unknown unit strings raise :class:`InputError`.
"""

from __future__ import annotations

from skisnow.solvers.beam import G_STANDARD
from skisnow.solvers.errors import InputError

#: density of ice [kg/m³]: snow density ρ = (1 − n) ρ_ice, porosity n = 1 − ρ/ρ_ice (the web
#: form converts a density to a porosity with it; app/static/web.js repeats the number)
ICE_DENSITY_KG_M3 = 917.0

_LENGTH_TO_M = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "μm": 1e-6, "nm": 1e-9}


def length_to_m(value: float, unit: str) -> float:
    """Convert a length in ``unit`` (m, mm, um/µm, nm) to metres."""
    try:
        return float(value) * _LENGTH_TO_M[unit]
    except KeyError:
        raise InputError(
            f"unknown length unit {unit!r}; use one of {sorted(set(_LENGTH_TO_M) - {'μm'})}"
        ) from None


def kg_to_n(load_kg: float) -> float:
    """Load in kg-force (g = 9.82 m/s², the papers' value) to newtons."""
    return float(load_kg) * G_STANDARD


def n_to_kg(load_n: float) -> float:
    """Load [N] → the equivalent mass [kg] (g = 9.82 m/s², docs/physics.md §2), for messages."""
    return load_n / G_STANDARD


def mm_to_m(value_mm: float) -> float:
    return float(value_mm) * 1e-3


def um_to_m(value_um: float) -> float:
    return float(value_um) * 1e-6


def kpa_to_pa(value_kpa: float) -> float:
    return float(value_kpa) * 1e3


def mpa_to_pa(value_mpa: float) -> float:
    return float(value_mpa) * 1e6
