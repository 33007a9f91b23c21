"""A ski's beam identification with its held-out check, as a JSON-ready report
(:func:`identify_report`): what ``skisnow identify-ski`` prints and the bench's identification
stage records. Imports ``storage``, ``solvers`` and the shared top-level modules.
"""

from __future__ import annotations

import time

import numpy as np
from skisnow.app.path_pool import identify_with_pool
from skisnow.app.storage.skis import CamberData, mean_profiles
from skisnow.solvers.errors import InputError
from skisnow.solvers.identify import identify_beam_checked, predict_gaps

__all__ = ["NEAR_CONTACT_M", "identify_report"]

#: where held-out profiles are compared with a design beam: near contact [m]
NEAR_CONTACT_M = 2e-4


def identify_report(
    data: CamberData,
    design_beam,
    holdout: float,
    seed: int,
    *,
    keep: dict | None = None,
    callback=None,
    held_out_index=None,
) -> dict:
    """Identify on the kept cases and measure on the held-out ones; a JSON-ready report.
    ``keep``: a dict that receives the identification and its check (for ``--store``);
    ``callback(fraction, message)``: progress of the identification; ``held_out_index``
    (indices into the cases of :func:`app.storage.skis.mean_profiles`), if given, the held-out
    cases instead of the seeded draw (a ski job's choice, or the one stored with a ski)."""
    if not (0.0 <= holdout < 0.9):
        raise InputError(f"--holdout must be in [0, 0.9), got {holdout}")
    f, xf, y, sides_note = mean_profiles(data)
    t0 = time.perf_counter()
    # thread counts fixed as in the ski job: the same data and seed give the same beam
    ident, check = identify_with_pool(
        identify_beam_checked,
        data.positions_m,
        f,
        xf,
        y,
        holdout=holdout,
        seed=seed,
        held_out_index=held_out_index,
        callback=callback,
    )
    elapsed = time.perf_counter() - t0
    if keep is not None:
        keep.update(
            ident=ident, check=check, sides=sides_note, loads_n=f, positions_m=xf, profiles_m=y
        )
    held = np.zeros(f.size, dtype=bool)
    held[check["held_out_index"]] = True
    x = ident.beam.positions_m  # the beam's nodes (finer than the samples' when they are far)
    report: dict = {
        "ski_id": data.ski_id,
        "cases": int(f.size),
        "held_out_cases": int(held.sum()),
        "sides": sides_note,
        "identified": bool(ident.ok),
        "reason": ident.reason,
        "noise_um": ident.noise_m * 1e6,
        "misfit_um": ident.misfit_m * 1e6,
        "case_misfit_um": {
            "median": float(np.median(ident.case_misfit_m)) * 1e6,
            "max": float(np.max(ident.case_misfit_m)) * 1e6,
        },
        "iterations": ident.iterations,
        "contact_passes": ident.contact_passes,
        "time_s": elapsed,
        "start_time_s": ident.extra.get("start_time_s"),
        "forward_time_s": ident.extra.get("forward_time_s"),
        **_starts_and_fits(ident.extra),
        "kinks_mm": [k * 1e3 for k in ident.extra.get("kinks_m", [])],
        "stiffness": [
            {
                "position_mm": float(x[i] * 1e3),
                "ei_nm2": float(ident.beam.bending_stiffness_nm2[i]),
                "band_90_nm2": [float(v) for v in ident.stiffness_band_nm2[:, i]],
            }
            for i in np.linspace(0, x.size - 1, 21).astype(int)
        ],
    }
    if held.any():
        pred = predict_gaps(ident.beam, f[held], xf[held], data.positions_m)
        res = pred - y[held]
        report["held_out_vs_measured_rms_um"] = float(np.sqrt(np.mean(res**2))) * 1e6
        if design_beam is not None:
            truth = predict_gaps(design_beam, f[held], xf[held], data.positions_m)
            near = truth < NEAR_CONTACT_M
            err = (pred - truth)[near]
            report["held_out_vs_design_beam_rms_um"] = float(np.sqrt(np.mean(err**2))) * 1e6
    return report


def _starts_and_fits(extra: dict) -> dict:
    """What the several starts cost and how far apart their fits ended (from
    :func:`solvers.identify.identify_beam`'s ``extra``): wall times [s] of the starts and of the
    forward fits, the starts run and the forward fits run, the converged candidates' objectives
    (lowest, range [-]) and misfits [µm], and their largest beam distance in the middle of the
    ski (max |Δc| [µm], max |Δ ln EI| [-]), the misfits [µm] of those kept as alternative
    beams (from the main and the variant starts), and the variant starts' fits."""
    spread = extra.get("candidate_spread") or {}
    cands = extra.get("forward_candidates") or []
    variants = extra.get("variant_candidates") or []
    um = 1e6
    return {
        "starts_wall_s": extra.get("wall_starts_s"),
        "forward_wall_s": extra.get("wall_forward_s"),
        "starts_run": extra.get("starts_run"),
        "starts_checked": len(extra.get("starts") or []),
        "forward_fits": extra.get("forward_fits", len(cands)),
        "forward_fits_time_s": float(sum(c["time_s"] for c in cands)),
        "restarted": extra.get("restarted"),
        "tried_rejected_starts": extra.get("tried_rejected_starts"),
        "chosen_start": extra.get("start"),
        "candidates_converged": spread.get("converged", 0),
        "candidates_objective_min": spread.get("objective_min"),
        "candidates_objective_range": spread.get("objective_range"),
        "candidates_misfit_um": [
            spread["misfit_min_m"] * um if "misfit_min_m" in spread else None,
            spread["misfit_max_m"] * um if "misfit_max_m" in spread else None,
        ],
        "candidates_max_dc_middle_um": (
            spread["max_dc_middle_m"] * um if "max_dc_middle_m" in spread else None
        ),
        "candidates_max_dlog_ei_middle": spread.get("max_dlog_ei_middle"),
        # the candidates kept as alternative beams (solvers.identify.alternative_fits): their
        # misfits [µm]; the error band answers with them too
        "alternative_beams_misfit_um": [
            cands[i]["misfit_m"] * um for i in extra.get("alternatives") or [] if i < len(cands)
        ]
        + [
            variants[i]["misfit_m"] * um
            for i in extra.get("variant_alternatives") or []
            if i < len(variants)
        ],
        # the variant starts (other stiffness knots): their forward fits are alternatives, or
        # the chosen beam when every main fit stays above the noise and one of them reaches it
        # (solvers.identify.variant_choice): its index, and the best main fit's misfit [µm]
        "variant_chosen": extra.get("variant_chosen"),
        "main_misfit_um": (
            extra["main_misfit_m"] * um if extra.get("main_misfit_m") is not None else None
        ),
        "variant_fits": len(variants),
        "variant_fits_time_s": float(sum(c["time_s"] for c in variants)),
        "variant_misfit_um": [c["misfit_m"] * um for c in variants],
    }
