"""``skisnow report paper-case``: the published 2 skis × 2 grinds study in one command.

Reproduces the case of Kalliorinne et al. (Lubricants 2023, 11, 427; ``shared/method.md``):
skis ``ski-a`` and ``ski-b`` with grinds ``grind-1`` and ``grind-2``, 40 kg at 160 mm behind the
balance point, E_snow = 200 MPa and the porosity the docs state (n = 0.5, method.md §5, a choice
of ours). It writes ``<out-dir>/paper-case.md`` with tables, figures (SVG) in
``<out-dir>/paper-case/`` and the numbers behind them in ``<out-dir>/paper-case/paper-case.json``.

Every contact result comes from :func:`app.service.contact` — the same computation as
``POST /v1/contact`` — so the report's 2 × 2 tables are the service's answers. The along-the-ski
figures are those of the web form (:mod:`app.web.plots`). Our choices where the papers are silent
are stated in the report; the findings of method.md §8 are checked by measurement, with the
thresholds written next to each verdict.
"""

from __future__ import annotations

import argparse
import io
import json
import logging
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from matplotlib import rc_context
from matplotlib.figure import Figure
from skisnow.app import units
from skisnow.app.profiles import profile_model
from skisnow.app.service import Catalogue, ContactInputs, contact, load_catalogue
from skisnow.app.storage.common import atomic_path, docs_dir, provenance
from skisnow.app.web import plots
from skisnow.solvers import lookup
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.errors import InputError, NotConvergedError, OutOfRangeError, SkisnowError

log = logging.getLogger(__name__)

#: words for :attr:`app.profiles.ProfileModel.source` in the report
PROFILE_MODEL_NAMES = {
    "identified_beam": "identified-beam",
    "network": "network",
    "design_beam": "design-beam",
}

__all__ = [
    "PaperCase",
    "compute_paper_case",
    "fmt",
    "measure_findings",
    "register",
    "render_markdown",
    "run",
    "write_paper_case",
    "zone_pressures",
]

# ------------------------------------------------------------------ the published case

SKIS = ("ski-a", "ski-b")
GRINDS = ("grind-1", "grind-2")
#: the finer of the two grinds (method.md §7: "Grind 1 (fine linear)")
FINE_GRIND = "grind-1"
PAPER_LOAD_KG = 40.0
PAPER_POSITION_MM = -160.0
PAPER_SNOW_MODULUS_MPA = 200.0
#: the porosity the docs state (method.md §5, README): a choice of ours, the papers give none
DOC_POROSITY = 0.5
BASE_MODULUS_MPA = 700.0
POISSON_RATIO = 0.3

#: method.md §4: published apparent contact at the paper case
PUBLISHED_APPARENT = {
    "ski-a": {"mean_pressure_kpa": 61.40, "contact_area_cm2": 63.98},
    "ski-b": {"mean_pressure_kpa": 32.24, "contact_area_cm2": 121.84},
}
#: method.md §4: rear-zone load share in a related study (range over ski types and poses) [-]
PUBLISHED_REAR_SHARE = (0.635, 0.930)
#: method.md §7: published ISO 25178 parameters (heights in µm, Sdq in µm/mm)
PUBLISHED_ISO = {
    "grind-1": {"Sa": 1.77, "Sq": 2.16, "Ssk": -0.16, "Sku": 2.58, "Sdq": 65.79,
                "Spk": 1.44, "Sk": 6.01, "Svk": 1.92},
    "grind-2": {"Sa": 8.77, "Sq": 9.62, "Ssk": -0.43, "Sku": 1.63, "Sdq": 185.77,
                "Spk": 2.16, "Sk": 11.65, "Svk": 20.02},
}  # fmt: skip

#: E_snow sweep of the zone-pressure figure, 20 … 400 MPa (method.md §3 range) [MPa]
SWEEP_MODULI_MPA = (20, 30, 40, 50, 60, 80, 100, 125, 150, 200, 250, 300, 350, 400)
#: porosities of the real-area curve: the documented 0.5 and, our choice, 0.3 and 0.7 [-]
CURVE_POROSITIES = (0.3, 0.5, 0.7)
#: apparent pressures of the real-area curve [kPa]
CURVE_PRESSURES_KPA = tuple(float(v) for v in np.geomspace(1.0, 1000.0, 121))
#: loads of the load-dependence checks of method.md §8 (paper load, and half and 1.5×) [kg]
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
        (``ski_model: flexible``, method.md §4b), or ``{"error": message}``.
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
    """Our textures' ISO 25178 parameters in the units of method.md §7 (µm, µm/mm)."""
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
        Loads of the load-dependence checks of method.md §8 [kg], at least two distinct.
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


# ------------------------------------------------------------------ method.md §8, measured


def _spread(values: Sequence[float]) -> float:
    """max / min of positive values [-]."""
    return max(values) / min(values)


def measure_findings(case: PaperCase) -> list[dict]:
    """Check each finding of method.md §8 on our results.

    Returns
    -------
    list of dict
        ``{"finding", "holds" (bool), "evidence" (text with the measured numbers), "test"}``.
    """
    m = {k: v["metrics"] for k, v in case.results.items()}
    coarse = next(g for g in GRINDS if g != FINE_GRIND)
    out = []

    def effects(key: str) -> tuple[list[float], list[float]]:
        by_grind = [_spread([m[(s, g)][key] for g in GRINDS]) for s in SKIS]  # per ski
        by_ski = [_spread([m[(s, g)][key] for s in SKIS]) for g in GRINDS]  # per grind
        return by_grind, by_ski

    # 1. grind sets A_tot and the real pressure; finer grind → more real area
    ga, sa = effects("total_real_contact_area_mm2")
    finer_more = all(
        m[(s, FINE_GRIND)]["total_real_contact_area_mm2"]
        > m[(s, coarse)]["total_real_contact_area_mm2"]
        for s in SKIS
    )
    out.append(
        {
            "finding": "The grind, more than the camber profile, sets the real contact area and "
            "the average real contact pressure; the finer grind gives more real contact area.",
            "test": "smallest grind factor (max/min over the grinds, per ski) > largest ski "
            f"factor (max/min over the skis, per grind), and {FINE_GRIND} (finer) has the "
            "larger A_tot on both skis. F / A_tot has the same factors (same F).",
            "holds": bool(min(ga) > max(sa) and finer_more),
            "evidence": "A_tot grind factor "
            + ", ".join(f"{s}: {fmt(v, 3)}×" for s, v in zip(SKIS, ga, strict=True))
            + "; ski factor "
            + ", ".join(f"{g}: {fmt(v, 3)}×" for g, v in zip(GRINDS, sa, strict=True))
            + f"; {FINE_GRIND} larger on both skis: {'yes' if finer_more else 'no'}.",
        }
    )

    # 2a. grind sets the minimum separation
    gs, ss = effects("min_average_separation_um")
    out.append(
        {
            "finding": "The grind sets the minimum average separation.",
            "test": "smallest grind factor > largest ski factor (as above).",
            "holds": bool(min(gs) > max(ss)),
            "evidence": "min h̄_n grind factor "
            + ", ".join(f"{s}: {fmt(v, 3)}×" for s, v in zip(SKIS, gs, strict=True))
            + "; ski factor "
            + ", ".join(f"{g}: {fmt(v, 3)}×" for g, v in zip(GRINDS, ss, strict=True))
            + ".",
        }
    )

    # 2b. ... and it hardly changes with load
    loads = sorted(next(iter(case.load_checks.values())))
    changes = {}
    for k, by_load in case.load_checks.items():
        v = [by_load[kg]["min_average_separation_um"] for kg in loads]
        changes[k] = (max(v) - min(v)) / min(v)
    worst = max(changes.values())
    out.append(
        {
            "finding": "The minimum average separation hardly changes with load (above ~10 kPa).",
            "test": f"over loads {', '.join(fmt(kg, 3) for kg in loads)} kg (at −160 mm), "
            f"(max − min)/min of min h̄_n < {HARDLY_CHANGES:.0%} for every ski × grind.",
            "holds": bool(worst < HARDLY_CHANGES),
            "evidence": "; ".join(
                f"{s} × {g}: {100 * changes[(s, g)]:.1f} %" for s, g in case.load_checks
            )
            + ".",
        }
    )

    # 3. both ski and grind set the reciprocal separation; longer zones → larger total
    gr, sr = effects("total_reciprocal_separation_m")
    lengths = {
        s: sum(z["length_mm"] for z in case.results[(s, GRINDS[0])]["apparent"]["zones"])
        for s in SKIS
    }
    longer = max(SKIS, key=lengths.get)
    larger = all(
        m[(longer, g)]["total_reciprocal_separation_m"]
        == max(m[(s, g)]["total_reciprocal_separation_m"] for s in SKIS)
        for g in GRINDS
    )
    out.append(
        {
            "finding": "Both the ski and the grind set the reciprocal separation; the ski with "
            "the longer contact zones gives the larger total.",
            "test": f"smallest grind factor and smallest ski factor both ≥ {SETS_IT:g}×, and "
            "the ski with the longer summed contact-zone length has the larger total with both "
            "grinds.",
            "holds": bool(min(gr) >= SETS_IT and min(sr) >= SETS_IT and larger),
            "evidence": "grind factor "
            + ", ".join(f"{s}: {fmt(v, 3)}×" for s, v in zip(SKIS, gr, strict=True))
            + "; ski factor "
            + ", ".join(f"{g}: {fmt(v, 3)}×" for g, v in zip(GRINDS, sr, strict=True))
            + "; summed zone length "
            + ", ".join(f"{s}: {fmt(lengths[s], 4)} mm" for s in SKIS)
            + f"; {longer} larger with both grinds: {'yes' if larger else 'no'}.",
        }
    )

    # 4. real area grows almost linearly with load; a_r(X) follows P(X)
    exps = {}
    for k, by_load in case.load_checks.items():
        a = [by_load[kg]["total_real_contact_area_mm2"] for kg in (loads[0], loads[-1])]
        exps[k] = math.log(a[1] / a[0]) / math.log(loads[-1] / loads[0])
    r2 = {}
    for k, r in case.results.items():
        d = r["distributions"]
        p = np.array([np.nan if v is None else v for v in d["pressure_kpa"]], dtype=float)
        ar = np.array([np.nan if v is None else v for v in d["real_area_fraction"]], dtype=float)
        ok = np.isfinite(p) & np.isfinite(ar) & (p > 0)
        kfit = float(np.sum(ar[ok] * p[ok]) / np.sum(p[ok] ** 2))
        resid = ar[ok] - kfit * p[ok]
        r2[k] = 1.0 - float(np.sum(resid**2) / np.sum((ar[ok] - ar[ok].mean()) ** 2))
    lo, hi = LINEAR_EXPONENT
    out.append(
        {
            "finding": "Real contact area grows almost linearly with load, so a_r(X) follows "
            "the shape of P(X).",
            "test": f"exponent b of A_tot ∝ F^b between {fmt(loads[0], 3)} and "
            f"{fmt(loads[-1], 3)} kg in [{lo:g}, {hi:g}], and R² of the fit a_r(X) = k·P(X) "
            f"over the loaded stations ≥ {FOLLOWS_SHAPE_R2:g}, for every ski × grind.",
            "holds": bool(
                all(lo <= b <= hi for b in exps.values())
                and all(v >= FOLLOWS_SHAPE_R2 for v in r2.values())
            ),
            "evidence": "; ".join(
                f"{s} × {g}: b = {fmt(exps[(s, g)], 3)}, R² = {fmt(r2[(s, g)], 3)}"
                for s, g in case.results
            )
            + ".",
        }
    )
    return out


# ------------------------------------------------------------------ figures


def _figure(title: str, xlabel: str, ylabel: str) -> tuple[Figure, object]:
    fig = Figure(figsize=(7.2, 3.6), layout="constrained")
    ax = fig.add_subplot()
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3, which="both")
    return fig, ax


def _fig_svg(fig: Figure) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight", metadata={"Date": None})
    return buf.getvalue()


def zone_pressure_svg(case: PaperCase) -> str:
    """Mean apparent pressure of the rear and front zones against E_snow [kPa vs MPa]."""
    fig, ax = _figure(
        f"Zone mean apparent pressure, {fmt(PAPER_LOAD_KG)} kg at {fmt(PAPER_POSITION_MM)} mm",
        "snow modulus E_snow [MPa]",
        "mean apparent pressure [kPa]",
    )
    for i, s in enumerate(SKIS):
        rows = [r for r in case.sweep if r["ski"] == s and r["error"] is None]
        e = [r["snow_modulus_mpa"] for r in rows]
        colour = plots._COLOURS[i % len(plots._COLOURS)]
        for side, style in (("rear", "-"), ("front", "--")):
            ax.plot(
                e,
                [r[side]["mean_pressure_kpa"] for r in rows],
                ls=style,
                marker="o",
                ms=3,
                color=colour,
                label=f"{s} {side} zone",
            )
        ax.plot(
            e,
            [r["mean_pressure_kpa"] for r in rows],
            ls=":",
            color=colour,
            lw=1,
            label=f"{s} whole ski F / A_app",
        )
        pub = PUBLISHED_APPARENT.get(s)
        if pub:
            ax.plot(
                [PAPER_SNOW_MODULUS_MPA],
                [pub["mean_pressure_kpa"]],
                marker="*",
                ms=10,
                ls="none",
                color=colour,
                label=f"{s} published F / A_app",
            )
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    return _fig_svg(fig)


def real_area_curve_svg(case: PaperCase) -> str:
    """Real contact area fraction a_r [%] against apparent pressure P [kPa], per grind and
    porosity, at E_snow 200 MPa."""
    fig, ax = _figure(
        f"Real contact area against apparent pressure, E_snow = {fmt(PAPER_SNOW_MODULUS_MPA)} MPa"
        " (P_n = P (1 − n))",
        "apparent (nominal macro-scale) pressure P [kPa]",
        "real contact area a_r [% of apparent area]",
    )
    p = np.asarray(case.curves["pressure_kpa"])
    styles = ("--", "-", ":", "-.")
    for i, g in enumerate(GRINDS):
        colour = plots._COLOURS[i % len(plots._COLOURS)]
        for j, (n, ar) in enumerate(case.curves[g].items()):
            y = np.asarray(ar, dtype=float)
            ax.plot(p, np.where(y > 0, y, np.nan), color=colour, ls=styles[j % 4], lw=1.3,
                    label=f"{g}, n = {n}")  # fmt: skip
    for s in SKIS:
        r = case.results[(s, GRINDS[0])]
        x = r["apparent"]["mean_pressure_kpa"]
        ax.axvline(x, color="0.4", lw=0.8, ls=":")
        ax.annotate(f"{s} F/A_app", xy=(x, 0.02), xycoords=("data", "axes fraction"),
                    rotation=90, fontsize=7, color="0.3", ha="right", va="bottom")  # fmt: skip
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.legend(fontsize=7, loc="upper left")
    return _fig_svg(fig)


def _figures(case: PaperCase) -> list[tuple[str, str, str]]:
    """``[(file name, caption, svg text)]`` of every figure."""
    results = [case.results[(s, g)] for s in SKIS for g in GRINDS]
    head = '<?xml version="1.0" encoding="utf-8" standalone="no"?>\n'
    figs = [
        (f"{key.replace('_', '-')}.svg", caption, head + fn(results))
        for key, caption, fn in plots.PLOTS
    ]
    figs.append(
        (
            "zone-pressure-vs-modulus.svg",
            "Mean apparent pressure of the rear and front contact zones against E_snow",
            zone_pressure_svg(case),
        )
    )
    figs.append(
        (
            "real-area-vs-pressure.svg",
            "Real contact area fraction a_r against apparent pressure P for both grinds at "
            "three porosities",
            real_area_curve_svg(case),
        )
    )
    return figs


# ------------------------------------------------------------------ markdown


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return lines


def render_markdown(case: PaperCase, figures: Sequence[tuple[str, str]], fig_dir: str) -> str:
    """The report text; ``figures`` is ``[(file name, caption)]`` inside ``fig_dir``."""
    n = case.porosity
    r0 = case.results[(SKIS[0], GRINDS[0])]
    inp = r0["inputs"]
    L: list[str] = []
    add = L.append
    add("# The paper case: 2 skis × 2 grinds")
    add("")
    add(
        "Generated by `skisnow report paper-case` — do not edit by hand; rerun the command. "
        "It reproduces, with this project's code and shipped data, the study of Kalliorinne et "
        "al., *Characterisation of the Contact between Cross-Country Skis and Snow* (Lubricants "
        "2023, 11(10), 427), as specified in `shared/method.md`. Every contact number below is "
        "the answer of `POST /v1/contact` (`app.service.contact`) for the same inputs."
    )
    add("")
    add("## Inputs")
    add("")
    L += _table(
        ["input", "value", "source"],
        [
            ["skis", ", ".join(SKIS), "demo skis (synthetic, see below)"],
            ["grinds", ", ".join(GRINDS), "demo grinds (synthetic, see below)"],
            ["equivalent load", f"{fmt(inp['load_kg'])} kg (F = {fmt(inp['load_n'])} N, "
             f"g = {inp['load_n'] / inp['load_kg']:.4g} m/s²)", "papers"],
            ["load position x_F", f"{fmt(inp['load_position_mm'])} mm (behind the balance "
             "point)", "papers"],
            ["snow modulus E_snow", f"{fmt(inp['snow_modulus_mpa'])} MPa", "papers"],
            ["snow porosity n", f"{fmt(n)} (−)", "**our choice** (method.md §5, the docs' "
             "default; the papers state none)"],
            ["base modulus E_base", f"{fmt(inp['base_modulus_mpa'])} MPa",
             "**our choice** (method.md §3)"],
            ["Poisson's ratio ν", f"{fmt(inp['poisson_ratio'])} (−)",
             "**our choice** (method.md §3)"],
            ["effective modulus E'", f"{fmt(inp['effective_modulus_mpa'])} MPa",
             "eq. (1) from the above"],
        ]
        + ([["discretisation preset", f"`{inp['preset']}`", "service default"]]
           if "preset" in inp else []),
    )  # fmt: skip
    add("")
    add("## What is synthetic and what is ours")
    add("")
    add("Synthetic stand-ins (the papers' measurements are not public):")
    add("")
    for g in GRINDS:
        t = case.tables[g]
        add(
            f"- **{g}**: a synthetic linear grind fitted to the published ISO 25178 parameters "
            f"(method.md §7; comparison below), {t['grid_shape'][0]} × {t['grid_shape'][1]} "
            f"pixels of {fmt(t['pixel_size_um'])} µm, tabulated over P_n / E' "
            f"(`tables/{t['file']}`)."
        )
    for s in SKIS:
        add(
            f"- **{s}**: a synthetic beam-model ski (loaded profile from its "
            f"{PROFILE_MODEL_NAMES.get(case.skis[s]['profile_model'], 'camber')} model) "
            "calibrated to the published apparent "
            "contact at 40 kg, −160 mm, 200 MPa (method.md §4; the next section shows how close "
            "the shipped file comes); its camber is not the papers' ski's."
        )
    add("")
    floor_nm = case.tables[GRINDS[0]]["gap_floor_nm"]
    moduli = ", ".join(fmt(e) for e in sorted({r["snow_modulus_mpa"] for r in case.sweep}))
    loads = ", ".join(fmt(kg) for kg in sorted(next(iter(case.load_checks.values()))))
    add("Our choices (method.md marks them **(choice)**; the last four are this report's):")
    add("")
    for line in (
        f"porosity n = {fmt(n)} (groomed track ≈ 460 kg/m³), E_base = 700 MPa, ν = 0.3;",
        "X from the balance point, positive towards the tip; the macro BEM balances force and "
        "moment with a tilt;",
        f"reciprocal separation with a gap floor h_c = {fmt(floor_nm)} nm; one table per "
        "texture over P_n / E'; contact-zone fringes below the table's lowest ratio "
        "interpolated linearly to the unloaded state;",
        "rear zone = apparent contact behind the balance point (zone midpoint X < 0), front zone ="
        " ahead of it; at soft snow the tail and tip ends touch too and count with their side;",
        f"the E_snow sweep grid ({moduli} MPa) and the porosities of the real-area curve "
        f"({', '.join(case.curves[GRINDS[0]])});",
        f"the load-dependence checks at {loads} kg;",
        "the numerical thresholds that turn the worded findings of method.md §8 into verdicts "
        "(stated with each verdict).",
    ):
        add(f"- {line}")
    add("")

    add("## Apparent contact: published and ours")
    add("")
    add(
        "Published values: method.md §4 (E_snow 200 MPa, 40 kg at −160 mm); the rear-zone share "
        "range comes from a related study over ski types and poses."
    )
    add("")
    rows = []
    for s in SKIS:
        a = case.results[(s, GRINDS[0])]["apparent"]
        zp = zone_pressures(case.results[(s, GRINDS[0])])
        pub = PUBLISHED_APPARENT[s]
        rows.append(
            [
                s,
                fmt(pub["contact_area_cm2"], 6),
                fmt(a["contact_area_cm2"]),
                f"{100 * (a['contact_area_cm2'] / pub['contact_area_cm2'] - 1):+.1f} %",
                fmt(pub["mean_pressure_kpa"], 6),
                fmt(a["mean_pressure_kpa"]),
                f"{100 * (a['mean_pressure_kpa'] / pub['mean_pressure_kpa'] - 1):+.1f} %",
                f"{100 * PUBLISHED_REAR_SHARE[0]:.1f}–{100 * PUBLISHED_REAR_SHARE[1]:.1f} %",
                f"{100 * zp['rear']['load_share']:.1f} %",
            ]
        )
    L += _table(
        [
            "ski",
            "A_app published [cm²]",
            "A_app ours [cm²]",
            "Δ",
            "F/A_app published [kPa]",
            "F/A_app ours [kPa]",
            "Δ",
            "rear share published",
            "rear share ours",
        ],
        rows,
    )
    add("")
    add(
        "The bending ski (our extension, method.md §4b; `ski_model: flexible`) beside the "
        f"papers' rigid model, same skis, no recalibration; porosity {fmt(case.porosity)}:"
    )
    add("")
    rows = []
    for s in SKIS:
        for g in GRINDS:
            rig = case.results[(s, g)]
            flx = case.flexible.get((s, g), {"error": "not computed"})
            if "error" in flx:
                rows.append([s, g, fmt(rig["apparent"]["contact_area_cm2"]), "—", "—", "—", "—"])
                continue
            pub = PUBLISHED_APPARENT[s]["contact_area_cm2"]
            a_r, a_f = rig["apparent"]["contact_area_cm2"], flx["apparent"]["contact_area_cm2"]
            rows.append(
                [
                    s,
                    g,
                    fmt(a_r),
                    fmt(a_f),
                    f"{100 * (a_f / pub - 1):+.1f} %",
                    f"{100 * zone_pressures(rig)['rear']['load_share']:.1f} % → "
                    f"{100 * zone_pressures(flx)['rear']['load_share']:.1f} %",
                    " · ".join(
                        f"{100 * (flx['metrics'][k] / rig['metrics'][k] - 1):+.1f} %"
                        for k in rig["metrics"]
                    ),
                ]
            )
    L += _table(
        [
            "ski",
            "grind",
            "A_app rigid [cm²]",
            "A_app flexible [cm²]",
            "flexible vs published",
            "rear share rigid → flexible",
            "four metrics, flexible vs rigid (A_tot · p_real · min h̄ · Σ1/h)",
        ],
        rows,
    )
    add("")
    add("Contact zones of our skis (rear to front):")
    add("")
    rows = []
    for s in SKIS:
        for z in case.results[(s, GRINDS[0])]["apparent"]["zones"]:
            p_kpa = z["load_n"] / (z["apparent_area_cm2"] * 1e-4) / 1e3
            rows.append(
                [
                    s,
                    z["name"],
                    fmt(z["start_mm"]),
                    fmt(z["end_mm"]),
                    fmt(z["length_mm"]),
                    fmt(z["load_n"]),
                    f"{100 * z['load_share']:.1f} %",
                    fmt(z["apparent_area_cm2"]),
                    fmt(p_kpa),
                ]
            )
    L += _table(
        [
            "ski",
            "zone",
            "start [mm]",
            "end [mm]",
            "length [mm]",
            "load [N]",
            "load share",
            "apparent area [cm²]",
            "mean P [kPa]",
        ],
        rows,
    )
    add("")
    add(
        '("mid" marks a zone that spans the load position; in the E_snow sweep below it '
        "counts as rear because it lies behind the balance point.)"
    )
    add("")

    add(f"## The four metrics (40 kg at −160 mm, E_snow 200 MPa, n = {fmt(n)})")
    add("")
    for key, title, unit in METRICS:
        add(f"**{title} [{unit}]**")
        add("")
        L += _table(
            [f"ski \\ grind [{unit}]", *GRINDS],
            [
                [s, *(f"{fmt(case.results[(s, g)]['metrics'][key])} {unit}" for g in GRINDS)]
                for s in SKIS
            ],
        )
        add("")

    add("## Along the ski")
    add("")
    add(
        "P(X) and H(X) come from the macro scale and do not depend on the grind; a_r(X), "
        "h̄_n(X) and (1/h)‾_n(X) are shown for each ski × grind. Width averages over the "
        "footprint."
    )
    add("")
    by_name = dict(figures)
    for name, caption in figures:
        if name in ("zone-pressure-vs-modulus.svg", "real-area-vs-pressure.svg"):
            continue
        add(f"![{caption}]({fig_dir}/{name})")
        add("")
        add(f"*{caption}.*")
        add("")

    add("## Zone pressures against snow modulus")
    add("")
    name = "zone-pressure-vs-modulus.svg"
    add(f"![{by_name[name]}]({fig_dir}/{name})")
    add("")
    add(
        f"*{by_name[name]}: {fmt(PAPER_LOAD_KG)} kg at {fmt(PAPER_POSITION_MM)} mm, "
        "zone load / zone apparent area; stars: published F / A_app at 200 MPa.*"
    )
    add("")
    header = ["E_snow [MPa]"]
    for s in SKIS:
        header += [f"{s} rear [kPa]", f"{s} front [kPa]", f"{s} F/A_app [kPa]"]
    rows = []
    errors = []
    for e in sorted({r["snow_modulus_mpa"] for r in case.sweep}):
        row = [fmt(e)]
        for s in SKIS:
            r = next(x for x in case.sweep if x["ski"] == s and x["snow_modulus_mpa"] == e)
            if r["error"] is not None:
                errors.append(f"{s} at {fmt(e)} MPa: {r['error']}")
                row += ["—", "—", "—"]
                continue
            pieces = r["rear"]["pieces"] + r["front"]["pieces"]
            mark = " ¹" if pieces > 2 else ""
            row += [
                fmt(r["rear"]["mean_pressure_kpa"]) + mark,
                fmt(r["front"]["mean_pressure_kpa"]) + mark,
                fmt(r["mean_pressure_kpa"]),
            ]
        rows.append(row)
    L += _table(header, rows)
    add("")
    add("¹ more than two contact zones (the tail or tip end touches too), summed per side.")
    if errors:
        add("")
        add("Failed solves (left out of the figure):")
        add("")
        for err in errors:
            add(f"- {err}")
    add("")

    add("## Real contact area against pressure")
    add("")
    name = "real-area-vs-pressure.svg"
    add(f"![{by_name[name]}]({fig_dir}/{name})")
    add("")
    add(
        f"*{by_name[name]}: table lookups at E_snow {fmt(PAPER_SNOW_MODULUS_MPA)} MPa "
        f"(E' = {fmt(inp['effective_modulus_mpa'])} MPa); porosity lowers the load the texture "
        "carries, P_n = P (1 − n) (eq. 2); dotted verticals: our skis' F / A_app.*"
    )
    add("")
    p = np.asarray(case.curves["pressure_kpa"])
    picks = [int(np.argmin(np.abs(p - v))) for v in (10.0, 30.0, 100.0, 300.0)]
    header = ["grind", "n [−]", *(f"a_r at {fmt(p[i], 3)} kPa [%]" for i in picks)]
    rows = [
        [g, nn, *(fmt(case.curves[g][nn][i], 3) for i in picks)]
        for g in GRINDS
        for nn in case.curves[g]
    ]
    L += _table(header, rows)
    add("")

    add("## Findings of method.md §8, measured")
    add("")
    add(
        "Each finding is stated in words in the papers; the “Test” line says which measurement "
        "and threshold (ours) decides the verdict here."
    )
    add("")
    for i, f in enumerate(measure_findings(case), 1):
        verdict = "**holds**" if f["holds"] else "**does not hold**"
        add(f"{i}. *{f['finding']}* — {verdict} in our results.")
        add(f"   Test: {f['test']}")
        add(f"   Measured: {f['evidence']}")
    add("")
    add("Minimum average separation and total real contact area at the load checks:")
    add("")
    loads = sorted(next(iter(case.load_checks.values())))
    header = ["ski × grind"]
    header += [f"min h̄_n at {fmt(kg)} kg [µm]" for kg in loads]
    header += [f"A_tot at {fmt(kg)} kg [mm²]" for kg in loads]
    L += _table(
        header,
        [
            [f"{s} × {g}"]
            + [fmt(by[kg]["min_average_separation_um"]) for kg in loads]
            + [fmt(by[kg]["total_real_contact_area_mm2"]) for kg in loads]
            for (s, g), by in case.load_checks.items()
        ],
    )
    add("")

    add("## Textures: published ISO 25178 parameters and ours")
    add("")
    keys = list(PUBLISHED_ISO[GRINDS[0]])
    unit = {"Ssk": "−", "Sku": "−", "Sdq": "µm/mm"}
    L += _table(
        ["grind", "", *(f"{k} [{unit.get(k, 'µm')}]" for k in keys)],
        [
            row
            for g in GRINDS
            for row in (
                [g, "published", *(fmt(PUBLISHED_ISO[g][k], 4) for k in keys)],
                [g, "ours", *(fmt(case.iso[g][k], 4) for k in keys)],
            )
        ],
    )
    add("")

    add("## Provenance")
    add("")
    pv = case.provenance
    L += _table(
        ["item", "value"],
        [
            ["code version", f"`{pv['code_version']}`"],
            ["git commit", f"`{pv['git_commit']}`"],
            ["command", f"`{pv['command_line']}`"],
            ["created (UTC)", pv["created_utc"]],
            ["Python", pv["python"]],
            ["computation and figures", f"{case.elapsed_s:.1f} s (wall time)"],
        ]
        + [
            [f"table {g}", f"`{case.tables[g]['file']}` sha256 `{case.tables[g]['sha256']}`"]
            for g in GRINDS
        ]
        + [
            [
                f"ski {s}",
                f"`{case.skis[s]['file']}` sha256 `{case.skis[s]['sha256']}` "
                f"({PROFILE_MODEL_NAMES.get(case.skis[s]['profile_model'], 'camber')} profile)",
            ]
            for s in SKIS
        ],
    )
    add("")
    add(f"The numbers behind this page: [`{fig_dir}/{JSON_NAME}`]({fig_dir}/{JSON_NAME}).")
    add("")
    return "\n".join(L)


def _json_ready(case: PaperCase) -> dict:
    return {
        "schema": "skisnow.paper-case/1",
        "porosity": case.porosity,
        "results": [
            {k: v for k, v in case.results[(s, g)].items() if k not in ("timing_ms",)}
            for s in SKIS
            for g in GRINDS
        ],
        "load_checks": [
            {"ski": s, "grind": g, "by_load_kg": {f"{kg:g}": m for kg, m in by.items()}}
            for (s, g), by in case.load_checks.items()
        ],
        "flexible": [
            {
                "ski": s,
                "grind": g,
                **{k: v for k, v in r.items() if k not in ("timing_ms", "distributions")},
            }
            for (s, g), r in case.flexible.items()
        ],
        "zone_pressure_sweep": case.sweep,
        "real_area_curves_percent": case.curves,
        "findings": measure_findings(case),
        "published": {
            "apparent": PUBLISHED_APPARENT,
            "rear_share": PUBLISHED_REAR_SHARE,
            "iso": PUBLISHED_ISO,
        },
        "iso_ours": case.iso,
        "tables": case.tables,
        "skis": case.skis,
        "provenance": case.provenance,
        "elapsed_s": case.elapsed_s,
    }


def write_paper_case(
    cat: Catalogue, out_dir: str | Path, *, progress: bool = True, **kwargs
) -> Path:
    """Compute the paper case and write ``out_dir/paper-case.md``, its figures and JSON.

    Every file is written atomically. ``kwargs`` go to :func:`compute_paper_case`.

    Returns
    -------
    Path
        The markdown file.
    """
    out_dir = Path(out_dir)
    t0 = time.perf_counter()
    case = compute_paper_case(cat, progress=progress, **kwargs)
    fig_dir = out_dir / FIG_DIR
    with rc_context({"svg.hashsalt": _SVG_SALT}):
        figs = _figures(case)
    case.elapsed_s = time.perf_counter() - t0  # computation and figures
    for name, _caption, svg in figs:
        _write_text(fig_dir / name, svg)
    _write_text(
        fig_dir / JSON_NAME,
        json.dumps(_finite_json(_json_ready(case)), indent=1, allow_nan=False) + "\n",
    )
    md = out_dir / MD_NAME
    text = render_markdown(case, [(n, c) for n, c, _ in figs], FIG_DIR)
    _write_text(md, text)
    return md


def _write_text(path: Path, text: str) -> None:
    """Atomic write, readable by everyone like any other docs file (mkstemp makes 0600)."""
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
        tmp.chmod(0o644)


def _finite_json(obj):
    """``obj`` with NumPy scalars as Python numbers and NaN/inf as ``None`` (strict JSON)."""
    if isinstance(obj, dict):
        return {str(k): _finite_json(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite_json(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


# ------------------------------------------------------------------ command line


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``report`` command with its ``paper-case`` subcommand."""
    p = subparsers.add_parser(
        "report",
        help="generated reports in docs/",
        description="Write reports that reproduce published studies with this project's code.",
    )
    sub = p.add_subparsers(dest="report", required=True, metavar="REPORT")
    pc = sub.add_parser(
        "paper-case",
        help="the published 2 skis × 2 grinds study (writes docs/paper-case.md)",
        description="Reproduce the 2 skis × 2 grinds study (40 kg at -160 mm, E_snow 200 MPa, "
        f"porosity {DOC_POROSITY:g}) and write OUT_DIR/{MD_NAME} with figures in "
        f"OUT_DIR/{FIG_DIR}/.",
    )
    pc.add_argument("--out-dir", type=Path, default=docs_dir(), help="output folder (default docs)")
    pc.add_argument(
        "--tables-dir",
        type=Path,
        default=None,
        help="texture tables and skis (default: the service setting, tables/)",
    )
    pc.add_argument("--no-progress", action="store_true", help="no progress bar")
    pc.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    tables_dir = args.tables_dir
    if tables_dir is None:
        from skisnow.app.settings import Settings

        tables_dir = Settings().tables_dir
    t0 = time.perf_counter()
    cat = load_catalogue(tables_dir)
    md = write_paper_case(cat, args.out_dir, progress=not args.no_progress)
    print(f"wrote {md} and {md.parent / FIG_DIR}/ in {time.perf_counter() - t0:.1f} s")
    return 0
