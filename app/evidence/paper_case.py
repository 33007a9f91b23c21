"""``skisnow report paper-case``: the published 2 skis × 2 grinds study in one command.

Reproduces the case of Kalliorinne et al. (Lubricants 2023, 11, 427; ``docs/physics.md``):
skis ``ski-a`` and ``ski-b`` with grinds ``grind-1`` and ``grind-2``, 40 kg at 160 mm behind the
balance point, E_snow = 200 MPa and the porosity the docs state (n = 0.5, docs/physics.md §5,
a choice of ours). It writes ``<out-dir>/paper-case.md`` with tables, figures (SVG) in
``<out-dir>/paper-case/`` and the numbers behind them in ``<out-dir>/paper-case/paper-case.json``.

Every contact result comes from :func:`app.service.contact` — the same computation as
``POST /v1/contact`` — so the report's 2 × 2 tables are the service's answers. The along-the-ski
figures are those of the web form (:mod:`app.plots`). Our choices where the papers are silent
are stated in the report; the findings of docs/physics.md §8 are checked by measurement, with the
thresholds written next to each verdict.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from skisnow.app import units
from skisnow.app.service import Catalogue, ContactInputs, contact
from skisnow.app.service.profiles import profile_model
from skisnow.app.storage.common import provenance
from skisnow.solvers import lookup
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.errors import InputError, NotConvergedError, OutOfRangeError, SkisnowError

log = logging.getLogger(__name__)

#: words for :attr:`app.service.profiles.ProfileModel.source` in the report
PROFILE_MODEL_NAMES = {
    "identified_beam": "identified-beam",
    "network": "network",
    "design_beam": "design-beam",
}

__all__ = ["PaperCase", "compute_paper_case", "fmt", "zone_pressures"]

# ------------------------------------------------------------------ the published case

SKIS = ("ski-a", "ski-b")
GRINDS = ("grind-1", "grind-2")
#: the finer of the two grinds (docs/physics.md §7: "Grind 1 (fine linear)")
FINE_GRIND = "grind-1"
PAPER_LOAD_KG = 40.0
PAPER_POSITION_MM = -160.0
PAPER_SNOW_MODULUS_MPA = 200.0
#: the porosity the docs state (docs/physics.md §5, README): a choice of ours, the papers give none
DOC_POROSITY = 0.5
BASE_MODULUS_MPA = 700.0
POISSON_RATIO = 0.3

#: docs/physics.md §4: published apparent contact at the paper case
PUBLISHED_APPARENT = {
    "ski-a": {"mean_pressure_kpa": 61.40, "contact_area_cm2": 63.98},
    "ski-b": {"mean_pressure_kpa": 32.24, "contact_area_cm2": 121.84},
}
#: docs/physics.md §4: rear-zone load share in a related study (range over ski types and poses) [-]
PUBLISHED_REAR_SHARE = (0.635, 0.930)
#: docs/physics.md §7: published ISO 25178 parameters (heights in µm, Sdq in µm/mm)
PUBLISHED_ISO = {
    "grind-1": {"Sa": 1.77, "Sq": 2.16, "Ssk": -0.16, "Sku": 2.58, "Sdq": 65.79,
                "Spk": 1.44, "Sk": 6.01, "Svk": 1.92},
    "grind-2": {"Sa": 8.77, "Sq": 9.62, "Ssk": -0.43, "Sku": 1.63, "Sdq": 185.77,
                "Spk": 2.16, "Sk": 11.65, "Svk": 20.02},
}  # fmt: skip

#: E_snow sweep of the zone-pressure figure, 20 … 400 MPa (docs/physics.md §3 range) [MPa]
SWEEP_MODULI_MPA = (20, 30, 40, 50, 60, 80, 100, 125, 150, 200, 250, 300, 350, 400)
#: porosities of the real-area curve: the documented 0.5 and, our choice, 0.3 and 0.7 [-]
CURVE_POROSITIES = (0.3, 0.5, 0.7)
#: apparent pressures of the real-area curve [kPa]
CURVE_PRESSURES_KPA = tuple(float(v) for v in np.geomspace(1.0, 1000.0, 121))
#: loads of the load-dependence checks of docs/physics.md §8 (paper load, and half and 1.5×) [kg]
LOAD_CHECK_KG = (20.0, 40.0, 60.0)

#: thresholds of the §8 verdicts (ours; the papers state the findings only in words)
HARDLY_CHANGES = 0.20  # "hardly changes": < 20 % change when the load triples
SETS_IT = 1.20  # a factor "sets" a metric: it changes it by ≥ 20 % (max/min over its levels)
LINEAR_EXPONENT = (0.85, 1.15)  # "almost linear": power-law exponent in this band
FOLLOWS_SHAPE_R2 = 0.95  # "follows the shape": R² of a_r(X) = k·P(X) over loaded stations

METRICS = (
    ("total_real_contact_area_mm2", "Total real contact area A_tot", "mm²"),
    ("average_real_contact_pressure_mpa", "Average real contact pressure F / A_tot", "MPa"),
    ("min_average_separation_um", "Minimum average interfacial separation min h̄_n", "µm"),
    ("total_reciprocal_separation_m", "Total average reciprocal separation ∬(1/h)‾_n dA", "m"),
)

FIG_DIR = "paper-case"
MD_NAME = "paper-case.md"
JSON_NAME = "paper-case.json"
#: fixed SVG id salt, so regenerating the figures from the same numbers gives the same files
_SVG_SALT = "skisnow-paper-case"


def fmt(value: float | None, digits: int = 4) -> str:
    """A number as the report prints it: ``digits`` significant digits, "—" if missing."""
    if value is None or not math.isfinite(value):
        return "—"
    return f"{value:.{digits}g}"


# ------------------------------------------------------------------ computation


@dataclass
class PaperCase:
    """Everything the report shows, in technician units (names carry the unit).

    Attributes
    ----------
    porosity : float
        Snow porosity n of the case [-].
    results : dict
        ``{(ski, grind): contact() answer}`` at the paper case.
    load_checks : dict
        ``{(ski, grind): {load_kg: metrics}}`` at the paper position, modulus and porosity.
    sweep : list of dict
        Zone pressures per ski and E_snow (rows of :func:`zone_pressures` plus ``ski``,
        ``snow_modulus_mpa`` and ``error`` for a failed solve).
    curves : dict
        ``{"pressure_kpa": [...], grind: {porosity: a_r [%] list}}`` at E_snow 200 MPa.
    flexible : dict
        ``{(ski, grind): contact() answer}`` at the paper case with the bending ski
        (``ski_model: flexible``, docs/physics.md §4b), or ``{"error": message}``.
    tables, skis : dict
        Per file: name, sha256 and profile model (skis) / pixel size and gap floor (tables).
    provenance : dict
        Code version, git commit, command line, creation time.
    elapsed_s : float
        Wall time of the computation [s] (:func:`write_paper_case` adds the figures).
    """

    porosity: float
    results: dict = field(default_factory=dict)
    load_checks: dict = field(default_factory=dict)
    sweep: list = field(default_factory=list)
    curves: dict = field(default_factory=dict)
    flexible: dict = field(default_factory=dict)
    iso: dict = field(default_factory=dict)
    tables: dict = field(default_factory=dict)
    skis: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    elapsed_s: float = 0.0


def _inputs(ski: str, grind: str, porosity: float, **over) -> ContactInputs:
    kw = {
        "load_kg": PAPER_LOAD_KG,
        "load_position_mm": PAPER_POSITION_MM,
        "snow_modulus_mpa": PAPER_SNOW_MODULUS_MPA,
        "porosity": porosity,
        "base_modulus_mpa": BASE_MODULUS_MPA,
        "poisson_ratio": POISSON_RATIO,
        "ski_model": "rigid",  # the papers' model: the ski keeps its device shape
    }
    kw.update(over)
    return ContactInputs(ski=ski, grind=grind, **kw)


def zone_pressures(result: dict) -> dict:
    """Rear and front contact of one answer of :func:`app.service.contact`.

    **(choice)** The apparent contact behind the balance point (zone midpoint X < 0) is the
    rear zone, ahead of it (X ≥ 0) the front zone; at soft snow a ski touches in more than two
    places (tail and tip ends), and those pieces are counted with their side. Mean apparent
    pressure of a side = its load / its apparent area.

    Returns
    -------
    dict
        ``{"rear": {...}, "front": {...}}`` with ``load_n`` [N], ``load_share`` [-],
        ``apparent_area_cm2`` [cm²], ``mean_pressure_kpa`` [kPa] (NaN without contact),
        ``length_mm`` [mm] and ``pieces`` (number of zones) for each side.
    """
    out = {}
    for side in ("rear", "front"):
        zones = [
            z
            for z in result["apparent"]["zones"]
            if (0.5 * (z["start_mm"] + z["end_mm"]) < 0) == (side == "rear")
        ]
        load = sum(z["load_n"] for z in zones)
        area = sum(z["apparent_area_cm2"] for z in zones)
        out[side] = {
            "load_n": load,
            "load_share": sum(z["load_share"] for z in zones),
            "apparent_area_cm2": area,
            "mean_pressure_kpa": load / (area * 1e-4) / 1e3 if area > 0 else float("nan"),
            "length_mm": sum(z["length_mm"] for z in zones),
            "pieces": len(zones),
        }
    return out


def _file_info(cat: Catalogue) -> tuple[dict, dict]:
    tables = {
        g: {
            "file": cat.grind(g).path.name,
            "sha256": cat.grind(g).sha256,
            "pixel_size_um": cat.grind(g).table.pixel_size_m * 1e6,
            "grid_shape": list(cat.grind(g).table.grid_shape),
            "gap_floor_nm": cat.grind(g).table.gap_floor_m * 1e9,
        }
        for g in GRINDS
    }
    skis = {
        s: {
            "file": cat.ski(s).path.name,
            "sha256": cat.ski(s).sha256,
            "profile_model": profile_model(cat.ski(s).record).source,
        }
        for s in SKIS
    }
    return tables, skis


def _iso(cat: Catalogue) -> dict:
    """Our textures' ISO 25178 parameters in the units of docs/physics.md §7 (µm, µm/mm)."""
    out = {}
    for g in GRINDS:
        p = cat.grind(g).table.iso_parameters
        out[g] = {
            key: (p[src] * scale if src in p else None)
            for key, src, scale in (
                ("Sa", "Sa_m", 1e6),
                ("Sq", "Sq_m", 1e6),
                ("Ssk", "Ssk", 1.0),
                ("Sku", "Sku", 1.0),
                ("Sdq", "Sdq", 1e3),
                ("Spk", "Spk_m", 1e6),
                ("Sk", "Sk_m", 1e6),
                ("Svk", "Svk_m", 1e6),
            )
        }
    return out


def _real_area_curves(
    cat: Catalogue, porosities: Sequence[float], pressures_kpa: Sequence[float]
) -> dict:
    """a_r [%] against the apparent pressure P at E_snow 200 MPa, P_n = P (1 − n) (eq. 2)."""
    e_eff = effective_modulus(
        units.mpa_to_pa(PAPER_SNOW_MODULUS_MPA), units.mpa_to_pa(BASE_MODULUS_MPA), POISSON_RATIO
    )
    p_pa = np.asarray(pressures_kpa, dtype=float) * 1e3
    curves: dict = {"pressure_kpa": [float(v) for v in pressures_kpa]}
    for g in GRINDS:
        curves[g] = {}
        for n in porosities:
            ar, _flag = lookup.real_contact_area_fraction(
                cat.grind(g).table, p_pa * (1 - n), e_eff, out_of_range="flag"
            )
            curves[g][f"{n:g}"] = [float(v) * 100 for v in np.atleast_1d(ar)]
    return curves


def compute_paper_case(
    cat: Catalogue,
    *,
    porosity: float = DOC_POROSITY,
    snow_moduli_mpa: Sequence[float] = SWEEP_MODULI_MPA,
    curve_porosities: Sequence[float] = CURVE_POROSITIES,
    load_check_kg: Sequence[float] = LOAD_CHECK_KG,
    progress: bool = True,
) -> PaperCase:
    """Run every contact computation the report needs.

    Parameters
    ----------
    cat : Catalogue
        Skis and grinds (must hold ``ski-a``, ``ski-b``, ``grind-1``, ``grind-2``).
    porosity : float
        Snow porosity n [-] of the case.
    snow_moduli_mpa : sequence of float
        E_snow values of the zone-pressure sweep [MPa].
    curve_porosities : sequence of float
        Porosities of the real-area-against-pressure curves [-].
    load_check_kg : sequence of float
        Loads of the load-dependence checks of docs/physics.md §8 [kg], at least two distinct.
    progress : bool
        Show a tqdm bar over the sweep (stderr).
    """
    from tqdm import tqdm

    if len(set(load_check_kg)) < 2:
        raise InputError(f"load_check_kg needs at least 2 distinct loads, got {load_check_kg!r}")
    t0 = time.perf_counter()
    case = PaperCase(porosity=porosity)
    case.tables, case.skis = _file_info(cat)
    case.iso = _iso(cat)
    for s in SKIS:
        for g in GRINDS:
            case.results[(s, g)] = contact(cat, _inputs(s, g, porosity))
            try:
                case.flexible[(s, g)] = contact(cat, _inputs(s, g, porosity, ski_model="flexible"))
            except SkisnowError as exc:  # no beam, or not converged: said in the report
                case.flexible[(s, g)] = {"error": str(exc)}
            case.load_checks[(s, g)] = {
                float(kg): (
                    case.results[(s, g)]["metrics"]
                    if kg == PAPER_LOAD_KG
                    else contact(cat, _inputs(s, g, porosity, load_kg=float(kg)))["metrics"]
                )
                for kg in load_check_kg
            }
    jobs = [(s, float(e)) for s in SKIS for e in snow_moduli_mpa]
    for s, e in tqdm(jobs, desc="E_snow sweep", unit="solve", disable=not progress):
        row: dict = {"ski": s, "snow_modulus_mpa": e, "error": None}
        try:
            # the apparent contact does not depend on the grind; any grind's answer serves
            r = contact(cat, _inputs(s, GRINDS[0], porosity, snow_modulus_mpa=e))
        except (NotConvergedError, OutOfRangeError) as exc:
            log.warning("sweep %s at %g MPa: %s", s, e, exc)
            row["error"] = str(exc)
        else:
            row.update(zone_pressures(r))
            row["mean_pressure_kpa"] = r["apparent"]["mean_pressure_kpa"]
            row["contact_area_cm2"] = r["apparent"]["contact_area_cm2"]
        case.sweep.append(row)
    case.curves = _real_area_curves(cat, curve_porosities, CURVE_PRESSURES_KPA)
    case.provenance = provenance(
        {
            "porosity": porosity,
            "snow_moduli_mpa": list(snow_moduli_mpa),
            "curve_porosities": list(curve_porosities),
            "load_check_kg": list(load_check_kg),
        }
    )
    case.elapsed_s = time.perf_counter() - t0
    return case
