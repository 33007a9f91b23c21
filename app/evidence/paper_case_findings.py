"""The findings of docs/physics.md §8, measured on the paper case (thresholds in
:mod:`app.evidence.paper_case`)."""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence

import numpy as np
from skisnow.app.evidence.paper_case import (
    FINE_GRIND,
    FOLLOWS_SHAPE_R2,
    GRINDS,
    HARDLY_CHANGES,
    LINEAR_EXPONENT,
    SETS_IT,
    SKIS,
    PaperCase,
    fmt,
)

log = logging.getLogger(__name__)


def _spread(values: Sequence[float]) -> float:
    """max / min of positive values [-]."""
    return max(values) / min(values)


def measure_findings(case: PaperCase) -> list[dict]:
    """Check each finding of docs/physics.md §8 on our results.

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
