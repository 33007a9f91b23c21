"""What every stage of ``skisnow bench accuracy`` shares: metrics, the run's configuration,
the refinement classifier and Richardson extrapolation, the Pareto front."""

from __future__ import annotations

import logging
import statistics
import time
from dataclasses import dataclass, field

import numpy as np
from skisnow.app.storage.common import tables_dir
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.micro import DEFAULT_GAP_FLOOR_M

TABLES = tables_dir()
log = logging.getLogger(__name__)


#: metrics of one micro solve (MicroResult attribute, label with unit)
MICRO_METRICS = {
    "real_contact_area_fraction": "real contact area fraction a_r",
    "mean_gap_m": "mean gap h̄_n",
    "mean_reciprocal_gap_per_m": "reciprocal gap (1/h)‾, floored at "
    f"{DEFAULT_GAP_FLOOR_M * 1e9:g} nm",
    "mean_reciprocal_gap_raw_per_m": "reciprocal gap (1/h)‾, raw (no floor)",
}
#: metrics a table interpolates (MicroTable array, lookup function name)
TABLE_METRICS = {
    "real_contact_area_fraction": "real_contact_area_fraction",
    "mean_gap_m": "mean_gap_m",
    "mean_reciprocal_gap_per_m": "mean_reciprocal_gap_per_m",
}
#: metrics of an answer of /v1/contact compared between settings (path in the answer)
ANSWER_METRICS = {
    "apparent_contact_area": ("apparent", "contact_area_cm2"),
    "total_real_contact_area": ("metrics", "total_real_contact_area_mm2"),
    "average_real_contact_pressure": ("metrics", "average_real_contact_pressure_mpa"),
    "min_average_separation": ("metrics", "min_average_separation_um"),
    "total_reciprocal_separation": ("metrics", "total_reciprocal_separation_m"),
}
#: the minimum average separation is a minimum over X of a pointwise quantity: where it sits
#: at a short contact (tip or tail point) it follows the edge-singular peak pressure and does
#: not converge with the macro grid (like the peak pressure, docs/macro.md); presets are
#: chosen on the other metrics and it is reported beside them
CONVERGING_METRICS = tuple(m for m in ANSWER_METRICS if m != "min_average_separation")
#: largest error of the converging metrics each preset may have against the reference [-]:
#: `default` stays at the size of the micro-scale error the shipped tables carry at 1.5 µm
#: pixels (a_r +2 … +21 %, floored reciprocal gap 1 … 3 %, micro stage), so the macro grid is
#: not the dominant error; `fine` for comparisons closer than 1 %; `fast` for previews: the
#: grids between it and the default save no time measurable on a loaded machine (1–2 ms)
PRESET_TOLERANCES = {"fast": 0.15, "default": 0.025, "fine": 0.01}


#: (load_kg, load_position_mm, snow_modulus_mpa, porosity) of the end-to-end cases
LOAD_CASES = ((40.0, -160.0, 200.0, 0.5), (70.0, -80.0, 100.0, 0.4), (20.0, -250.0, 400.0, 0.6))


@dataclass(frozen=True)
class AccuracyConfig:
    """Sizes of one accuracy run (``--quick`` shrinks every stage to a smoke test)."""

    micro_sizes: tuple[int, ...] = (256, 512, 1024, 2048, 4096)
    micro_grinds: tuple[str, ...] = ("grind-1", "grind-2")
    #: nominal pressures P_n of the micro study [Pa] (at E' of 200 MPa snow on 0.7 GPa base)
    micro_pressures_pa: tuple[float, ...] = (15e3, 60e3)
    micro_repeats: int = 3
    table_grinds: tuple[str, ...] = ("grind-1", "grind-2")
    table_points: tuple[int, ...] = (9, 18, 36, 72)
    #: off-grid pressure ratios solved directly (0: held-out nodes only)
    table_direct_points: int = 8
    table_ratio_range: tuple[float, float] = (1e-6, 1e-2)
    #: candidate macro grids (pixel along [mm], pixels across); the presets are added
    grids: tuple[tuple[float, int], ...] = (
        (8.0, 4),
        (8.0, 8),
        (6.0, 8),
        (4.0, 4),
        (4.0, 8),
        (2.0, 8),
        (2.0, 16),
        (1.0, 8),
        (1.0, 16),
        (0.5, 16),
        (0.5, 32),
        (0.25, 16),
    )
    reference_grid: tuple[float, int] = (0.5, 64)
    #: end-to-end cases: (ski, grind, load_kg, load_position_mm, snow_modulus_mpa, porosity)
    cases: tuple[tuple, ...] = tuple(
        (ski, grind, *load)
        for ski in ("ski-a", "ski-b")
        for grind in ("grind-1", "grind-2")
        for load in LOAD_CASES
    )
    e2e_repeats: int = 5
    reference_repeats: int = 2
    network_skis: tuple[str, ...] = ("ski-a", "ski-b")
    network_loads_kg: tuple[float, ...] = (15.0, 30.0, 45.0, 60.0, 75.0)
    network_positions_mm: tuple[float, ...] = (-275.0, -175.0, -125.0, -25.0, 75.0)
    network_grind: str = "grind-1"
    network_repeats: int = 5
    stages: tuple[str, ...] = ("micro", "table", "end-to-end", "network")
    extra: dict = field(default_factory=dict)


QUICK = AccuracyConfig(
    micro_sizes=(64, 128, 256),
    micro_grinds=("grind-1",),
    micro_pressures_pa=(60e3,),
    micro_repeats=1,
    table_grinds=("grind-1",),
    table_direct_points=0,
    grids=((8.0, 4), (4.0, 8)),
    reference_grid=(2.0, 8),
    cases=(("ski-a", "grind-1", 40.0, -160.0, 200.0, 0.5),),
    e2e_repeats=1,
    reference_repeats=1,
    network_skis=("ski-a",),
    network_loads_kg=(45.0,),
    network_positions_mm=(-175.0,),
    network_repeats=1,
)

#: snow modulus of the micro and network studies [Pa]
SNOW_MODULUS_PA = 200e6
#: E' of the micro study: 200 MPa snow on a 0.7 GPa base, ν = 0.3 [Pa]
MICRO_E_EFF_PA = effective_modulus(SNOW_MODULUS_PA, 0.7e9, 0.3)
#: relative pressure step of the micro study's well-posedness check, d ln f / d ln P_n [-]
PRESSURE_STEP = 1e-3
#: porosity n of the network stage's computations [-]
NETWORK_POROSITY = 0.5
#: a refinement sequence converges when each change is this many times smaller than the last
CONVERGENCE_RATIO_MIN = 1.4
#: physical size of the micro patch: the shipped textures' 1024 × 1.5 µm [m]
MICRO_PATCH_M = 1024 * 1.5e-6


def median_time(fn, repeats: int) -> tuple[float, list[float], object]:
    times, out = [], None
    for _ in range(max(repeats, 1)):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times, out


def rel_diff(value: float, ref: float) -> float:
    return float(value / ref - 1) if ref != 0 else float("nan")


def convergence(
    values: list[float], ratio_min: float = CONVERGENCE_RATIO_MIN, bound: float = 0.05
) -> dict:
    """Classify a refinement sequence (coarse → fine) by its successive differences.

    ``converges``: every successive difference is smaller than the previous one by at least
    ``ratio_min`` (halving the pixel should shrink the change); the observed order is ``log2``
    of the last ratio. Otherwise ``converges slowly`` if the sequence is monotone and its last
    change is at most half its first, ``bounded`` if every change relative to the finest value
    stays within ``bound`` (no clear order, but small), else ``does not converge``.
    """
    v = np.asarray(values, dtype=float)
    steps = np.diff(v)
    d = np.abs(steps)
    ratios = d[:-1] / np.maximum(d[1:], 1e-300)
    ok = bool(len(ratios) > 0 and np.all(ratios >= ratio_min))
    rel = d / abs(v[-1]) if v[-1] != 0 else d * np.inf
    monotone = bool(np.all(steps >= 0) or np.all(steps <= 0))
    if ok:
        verdict = "converges"
    elif monotone and len(d) > 1 and d[-1] <= d[0] / 2:
        verdict = "converges slowly"
    elif np.all(rel <= bound):
        verdict = "bounded"
    else:
        verdict = "does not converge"
    return {
        "converges": ok,
        "verdict": verdict,
        "max_relative_change": float(rel.max()) if rel.size else 0.0,
        "successive_differences": d.tolist(),
        "difference_ratios": ratios.tolist(),
        "observed_order": float(np.log2(ratios[-1])) if len(ratios) and ratios[-1] > 0 else None,
    }


def richardson(values: list[float], order: float) -> float:
    """Zero-pixel limit from the two finest values of a halving sequence with ``order``."""
    p = min(max(order, 0.5), 4.0)
    return values[-1] + (values[-1] - values[-2]) / (2**p - 1)


def zero_pixel_limit(values: list[float], conv: dict) -> float:
    """The bench's estimate of the zero-pixel limit: Richardson from the two finest values
    with the observed order where the sequence converges, else the finest value."""
    if conv["verdict"] == "converges" and conv["observed_order"] is not None:
        return float(richardson(values, conv["observed_order"]))
    return float(values[-1])


#: grid of the shipped textures [-]; levels of the two-level tables (this and twice as fine)
SHIPPED_N = 1024


def grid_name(dx_mm: float, ny: int) -> str:
    return f"{dx_mm:g} mm × {ny}"


def pareto_front(points: list[tuple[float, float, str]]) -> list[str]:
    """Names of the points no other point beats in both time and error (time, error, name)."""
    front, best = [], float("inf")
    for _t, e, name in sorted(points):
        if e < best:
            front.append(name)
            best = e
    return front
