"""``bench accuracy`` stage ``network``: each ski's camber network against the beam model it
learned, through the whole computation (see :mod:`app.evidence.accuracy`)."""

from __future__ import annotations

import logging
import statistics

import numpy as np
from skisnow.app.evidence.accuracy_common import (
    ANSWER_METRICS,
    MICRO_E_EFF_PA,
    NETWORK_POROSITY,
    AccuracyConfig,
    median_time,
    rel_diff,
)
from skisnow.app.evidence.accuracy_e2e import shipped_catalogue
from skisnow.solvers.beam import G_STANDARD, BeamFlexibility, solve_beam_contact
from tqdm import tqdm

log = logging.getLogger(__name__)


def bench_network(cfg: AccuracyConfig, bar: tqdm) -> dict:
    from skisnow.solvers import camber
    from skisnow.solvers.macro import extrude_profile, solve_macro
    from skisnow.solvers.multiscale import multiscale

    cat, verified = shipped_catalogue()
    grind = cat.grind(cfg.network_grind)
    e_eff = MICRO_E_EFF_PA
    porosity = NETWORK_POROSITY
    out = {"grind": cfg.network_grind, "skis": [], "catalogue": verified}
    for name in cfg.network_skis:
        ski = cat.ski(name)
        rec = ski.record
        if rec.network is None or rec.beam is None:
            out["skis"].append({"ski": name, "skipped": "needs both a network and a beam"})
            continue
        flex = BeamFlexibility(rec.beam)
        outline = rec.outline
        rows, t_net, t_beam, t_beam_cached = [], [], [], []
        for kg in cfg.network_loads_kg:
            for pos in cfg.network_positions_mm:
                f, xf = kg * G_STANDARD, pos * 1e-3
                net, beam_ski = rec.network, rec.beam
                tn, _, (xn, gn) = median_time(
                    lambda f=f, xf=xf, net=net: camber.predict_profile(net, f, xf),
                    cfg.network_repeats,
                )
                tb, _, beam = median_time(
                    lambda f=f, xf=xf, b=beam_ski: solve_beam_contact(b, f, xf), 1
                )
                tbc, _, _ = median_time(
                    lambda f=f, xf=xf, b=beam_ski, fl=flex: solve_beam_contact(
                        b, f, xf, flexibility=fl
                    ),
                    cfg.network_repeats,
                )
                t_net.append(tn)
                t_beam.append(tb)
                t_beam_cached.append(tbc)
                gb = np.interp(xn, beam.positions_m, beam.gap_m)
                row = {
                    "load_kg": kg,
                    "load_position_mm": pos,
                    "contact_band_rmse_um": camber.contact_band_rmse_m(gn, gb) * 1e6,
                    "max_abs_profile_error_um": float(np.max(np.abs(gn - gb))) * 1e6,
                }
                vals = {}
                for label, g in (("network", gn), ("beam", gb)):
                    gm = extrude_profile(
                        xn, g, outline.width_m, width_positions_m=outline.positions_m
                    )
                    mac = solve_macro(gm, f, xf, e_eff)
                    ms = multiscale(mac, grind.table, porosity, e_eff)
                    vals[label] = {
                        "apparent_contact_area": mac.apparent_contact_area_m2,
                        "total_real_contact_area": ms.total_real_contact_area_m2,
                        "average_real_contact_pressure": ms.average_real_contact_pressure_pa,
                        "min_average_separation": ms.min_average_separation_m,
                        "total_reciprocal_separation": ms.total_reciprocal_separation_m,
                        "converged": bool(mac.converged),
                    }
                row["rel_error"] = {
                    m: rel_diff(vals["network"][m], vals["beam"][m]) for m in ANSWER_METRICS
                }
                row["converged"] = vals["network"]["converged"] and vals["beam"]["converged"]
                rows.append(row)
                bar.update(1)
        attrs = rec.network.get("attrs", {})
        out["skis"].append(
            {
                "ski": name,
                "sha256": ski.sha256,
                "network_metrics": attrs.get("metrics_json"),
                "median_network_s": statistics.median(t_net),
                "median_beam_s": statistics.median(t_beam),
                "median_beam_cached_flexibility_s": statistics.median(t_beam_cached),
                "max_rel_error": {
                    m: max(abs(r["rel_error"][m]) for r in rows) for m in ANSWER_METRICS
                },
                "median_abs_rel_error": {
                    m: statistics.median(abs(r["rel_error"][m]) for r in rows)
                    for m in ANSWER_METRICS
                },
                "max_contact_band_rmse_um": max(r["contact_band_rmse_um"] for r in rows),
                "rows": rows,
            }
        )
    return out
