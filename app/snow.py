"""Snow by type and temperature: named snow presets (issue #28).

A technician thinks in snow types, not in moduli. Each preset is a snow a classic track has,
with a density from the snow-science literature and a Young's modulus from a published
density–modulus relation, each with its reference and its range. The answer uses the preset's
nominal numbers (``snow_modulus_mpa``, ``porosity``); the range says how far a real track of
that type can be from them. Every route and page takes the preset by name (``snow``) and the
raw numbers still override it (an answer's inputs say which number came from where).

How the numbers were chosen (no new measurement; ranges rather than precision)
-----------------------------------------------------------------------------
Density ρ [kg/m³]
    Typical ranges of seasonal snow by type: Cuffey & Paterson, *The Physics of Glaciers*,
    4th ed. (2010), Table 2.1 (new snow 50–200, settled 200–300, wind-packed 350–400, firn
    400–830, ice 830–917); Fierz et al., *The International Classification for Seasonal Snow on
    the Ground*, UNESCO-IHP (2009) for the grain-shape classes (fine rounded RG, melt forms
    MF). A machine-groomed track is compacted well above the fresh snowfall's density; the
    track densities below are our reading of those ranges for a prepared track, stated as
    ranges.
Porosity n [-]
    ``n = 1 − ρ/ρ_ice`` with ρ_ice = 917 kg/m³ (docs/physics.md §5).
Young's modulus E_snow [MPa]
    Sigrist (2006), PhD thesis, ETH Zürich, cantilever-beam tests at fast loading:
    ``E = 968 MPa · (ρ/ρ_ice)^2.94``. The range's low end is the lower of Sigrist's relation and
    Scapozza (2004), PhD thesis, ETH Zürich, ``E = 0.1873 MPa · exp(0.0149 ρ)``, at the
    low density (Scapozza's only up to 500 kg/m³, beyond which its exponential was not fitted),
    and its high end Sigrist's relation at the high density. Published moduli at one density
    scatter by a factor of ~3–10 with the loading rate and the microstructure (Gerling, Löwe
    and van Herwijnen 2017, "Measuring the elastic modulus of snow", *Geophys. Res. Lett.*;
    Reuter et al. 2019, "Comparing measurements of snow mechanical properties relevant for slab
    avalanche release", *J. Glaciol.*): the
    nominal value is a starting point, not a measurement of the track.
Temperature
    The air/snow temperature band in which the type is found on a track; the modulus relations
    above were measured on dry snow well below 0 °C, and wet snow near 0 °C is softer than they
    say (not quantified here: use the raw numbers).
``study``
    The papers' study value (Holmberg & Almqvist, docs/physics.md §3 and §5): 200 MPa, n = 0.5
    (groomed track ≈ 460 kg/m³). It is the default everywhere, so that a request naming no
    snow answers as before; at 460 kg/m³ Sigrist's relation gives 130 MPa, inside the papers'
    range 20–400 MPa.

Pure data and arithmetic: no I/O, no settings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

__all__ = [
    "DEFAULT_SNOW",
    "ICE_DENSITY_KG_M3",
    "SNOW_PRESETS",
    "SnowName",
    "SnowPreset",
    "modulus_scapozza_mpa",
    "modulus_sigrist_mpa",
    "resolve_snow",
    "snow_choices",
    "snow_record",
]

#: density of ice [kg/m³] (n = 1 − ρ/ρ_ice; docs/physics.md §5)
ICE_DENSITY_KG_M3 = 917.0

SIGRIST_2006 = (
    "Sigrist C. (2006) Measurement of fracture mechanical properties of snow and application "
    "to dry snow slab avalanche release, PhD thesis, ETH Zürich: "
    "E = 968 MPa (ρ/917)^2.94"
)
SCAPOZZA_2004 = (
    "Scapozza C. (2004) Entwicklung eines dichte- und temperaturabhängigen Stoffgesetzes zur "
    "Beschreibung des visko-elastischen Verhaltens von Schnee, PhD thesis, ETH Zürich: "
    "E = 0.1873 MPa exp(0.0149 ρ)"
)
PATERSON_2010 = (
    "Cuffey K. M. & Paterson W. S. B. (2010) The Physics of Glaciers, 4th ed., Table 2.1 "
    "(densities of snow types); Fierz C. et al. (2009) The International Classification for "
    "Seasonal Snow on the Ground, UNESCO-IHP (grain shapes)"
)
HOLMBERG = "Holmberg & Almqvist (the papers of docs/physics.md): study value 200 MPa, n = 0.5"


def modulus_sigrist_mpa(density_kg_m3: float) -> float:
    """Young's modulus of dry snow [MPa] from its density [kg/m³] (Sigrist 2006)."""
    return 968.0 * (density_kg_m3 / ICE_DENSITY_KG_M3) ** 2.94


def modulus_scapozza_mpa(density_kg_m3: float) -> float:
    """Young's modulus of dry snow [MPa] from its density [kg/m³] (Scapozza 2004)."""
    return 0.1873 * math.exp(0.0149 * density_kg_m3)


#: largest density at which Scapozza's relation is used [kg/m³]
SCAPOZZA_MAX_DENSITY_KG_M3 = 500.0


def _low_modulus_mpa(density_kg_m3: float) -> float:
    """The lower of the two relations at ``density_kg_m3`` [kg/m³] (Scapozza's only where
    fitted) [MPa]."""
    e = modulus_sigrist_mpa(density_kg_m3)
    if density_kg_m3 <= SCAPOZZA_MAX_DENSITY_KG_M3:
        e = min(e, modulus_scapozza_mpa(density_kg_m3))
    return e


def _sig(v: float, digits: int = 2) -> float:
    return float(f"{v:.{digits}g}")


@dataclass(frozen=True)
class SnowPreset:
    """One snow type at one temperature band, in technician units.

    Attributes
    ----------
    name : str
        Name in requests (``snow``).
    label : str
        What a technician reads.
    temperature_c : tuple of float
        Temperature band where the type is found on a track [°C].
    density_kg_m3 : float
        Nominal density [kg/m³].
    density_range_kg_m3 : tuple of float
        Range of density [kg/m³].
    snow_modulus_mpa : float
        Nominal Young's modulus [MPa] (2 significant digits).
    modulus_range_mpa : tuple of float
        Range of the modulus [MPa] (module docstring).
    reference : str
        Where the numbers come from.
    """

    name: str
    label: str
    temperature_c: tuple[float, float]
    density_kg_m3: float
    density_range_kg_m3: tuple[float, float]
    snow_modulus_mpa: float
    modulus_range_mpa: tuple[float, float]
    reference: str

    @property
    def porosity(self) -> float:
        """Porosity n = 1 − ρ/ρ_ice [-] of the nominal density (3 decimals)."""
        return round(1.0 - self.density_kg_m3 / ICE_DENSITY_KG_M3, 3)

    def as_json(self) -> dict:
        """The preset in technician units (API, pages)."""
        return {
            "name": self.name,
            "label": self.label,
            "temperature_c": list(self.temperature_c),
            "density_kg_m3": self.density_kg_m3,
            "density_range_kg_m3": list(self.density_range_kg_m3),
            "snow_modulus_mpa": self.snow_modulus_mpa,
            "modulus_range_mpa": list(self.modulus_range_mpa),
            "porosity": self.porosity,
            "reference": self.reference,
        }


def _from_density(
    name: str, label: str, temperature_c, density: float, low: float, high: float
) -> SnowPreset:
    return SnowPreset(
        name,
        label,
        temperature_c,
        density,
        (low, high),
        _sig(modulus_sigrist_mpa(density)),
        (_sig(_low_modulus_mpa(low)), _sig(modulus_sigrist_mpa(high))),
        f"density: {PATERSON_2010}; modulus: {SIGRIST_2006} (range low end: {SCAPOZZA_2004})",
    )


#: the presets, by name (order: softest to hardest, then the papers' value)
SNOW_PRESETS: dict[str, SnowPreset] = {
    p.name: p
    for p in (
        _from_density(
            "new-cold",
            "New snow on the track, cold (below −5 °C)",
            (-25.0, -5.0),
            300.0,
            200.0,
            350.0,
        ),
        _from_density(
            "new-mild",
            "New snow on the track, mild (−5 … 0 °C)",
            (-5.0, 0.0),
            350.0,
            250.0,
            400.0,
        ),
        _from_density(
            "fine-grained",
            "Fine-grained groomed track (rounded grains), cold",
            (-20.0, -3.0),
            450.0,
            400.0,
            500.0,
        ),
        _from_density(
            "coarse-old",
            "Coarse transformed / old snow (melt-freeze grains)",
            (-10.0, 0.0),
            500.0,
            450.0,
            550.0,
        ),
        _from_density(
            "artificial",
            "Artificial (machine-made) snow",
            (-20.0, 0.0),
            550.0,
            450.0,
            600.0,
        ),
        _from_density(
            "icy",
            "Icy track (refrozen, glazed)",
            (-20.0, -2.0),
            700.0,
            600.0,
            830.0,
        ),
        SnowPreset(
            "study",
            "Groomed track, the papers' study value",
            (-20.0, 0.0),
            458.5,
            (400.0, 500.0),
            200.0,
            (20.0, 400.0),
            HOLMBERG,
        ),
    )
}

#: the snow every page, route and command uses when none is named: the papers' study value
DEFAULT_SNOW = "study"

#: names of :data:`SNOW_PRESETS` as a type (checked equal in tests/service/test_snow.py)
SnowName = Literal[
    "new-cold", "new-mild", "fine-grained", "coarse-old", "artificial", "icy", "study"
]


def snow_choices() -> list[tuple[str, str]]:
    """(name, label with its numbers) of every preset, for a select box."""
    return [
        (
            p.name,
            f"{p.label}: {p.snow_modulus_mpa:g} MPa, n = {p.porosity:g} "
            f"(ρ ≈ {p.density_kg_m3:g} kg/m³)",
        )
        for p in SNOW_PRESETS.values()
    ]


def resolve_snow(
    name: str | None, snow_modulus_mpa: float | None, porosity: float | None
) -> tuple[float | None, float | None]:
    """The snow numbers of a request: those given, else the named preset's (None without one).

    Raises
    ------
    KeyError
        Unknown preset name (the routes' schemas check names first).
    """
    if name is None:
        return snow_modulus_mpa, porosity
    p = SNOW_PRESETS[name]
    return (
        p.snow_modulus_mpa if snow_modulus_mpa is None else snow_modulus_mpa,
        p.porosity if porosity is None else porosity,
    )


def snow_record(name: str | None, snow_modulus_mpa: float, porosity: float) -> dict | None:
    """What an answer says about its snow: the preset, and for each number whether it is the
    preset's or was given instead (None when no preset is named)."""
    if name is None:
        return None
    p = SNOW_PRESETS[name]
    given = {
        k: v
        for k, v, pv in (
            ("snow_modulus_mpa", snow_modulus_mpa, p.snow_modulus_mpa),
            ("porosity", porosity, p.porosity),
        )
        if v is not None and not math.isclose(v, pv, rel_tol=0, abs_tol=1e-12)
    }
    return {
        "name": p.name,
        "label": p.label,
        "numbers_given_instead_of_the_preset": given,
        "preset_snow_modulus_mpa": p.snow_modulus_mpa,
        "preset_porosity": p.porosity,
        "modulus_range_mpa": list(p.modulus_range_mpa),
        "reference": p.reference,
    }
