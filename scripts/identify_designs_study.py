"""Beam identification on designs the tests have not seen (#26 points 1-2): every design of
``solvers.ski_designs.STUDY_DESIGNS`` (and ``solvers.beam.OTHER_DESIGNS``) measured with the
virtual device (13 × 9 or 9 × 5 cases, loads linspace(10, 90, n) kg × positions
linspace(−0.30, 0.10, m) m, 1 mm nodes, 3 µm noise, seeded) plus the unloaded profile, identified
with ``identify_beam_checked`` (20 % held out, seed 0) as the ski job runs it
(``app.path_pool.identify_with_pool``); for comparison the forward fit started from the true
beam on the same kept cases.

    python scripts/identify_designs_study.py [--grid 13x9] [--designs a,b] [--no-unloaded]
        [--out docs/studies/identify-designs.jsonl]

One JSON line per design (appended): served or not and why, misfit/noise, held-out profile RMS
against the noise-free truth where H* < 0.2 mm, the starts and candidates, times.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from skisnow.app.path_pool import fixed_blas_threads, identify_with_pool
from skisnow.solvers.beam import (
    G_STANDARD,
    OTHER_DESIGNS,
    measure_camber,
    measure_unloaded,
)
from skisnow.solvers.beam_fit import fit_forward
from skisnow.solvers.identify import identify_beam_checked, predict_gaps
from skisnow.solvers.ski_designs import STUDY_DESIGNS

NOISE_M = 3e-6
NEAR_CONTACT_M = 2e-4
DESIGNS = {**STUDY_DESIGNS, **OTHER_DESIGNS}


def run(name: str, n_loads: int, n_pos: int, seed: int, unloaded: bool) -> dict:
    ski = DESIGNS[name].build(1e-3)
    x = ski.positions_m
    f, xf, y = measure_camber(
        ski,
        np.linspace(10.0, 90.0, n_loads) * G_STANDARD,
        np.linspace(-0.30, 0.10, n_pos),
        noise_m=NOISE_M,
        rng=seed,
    )
    if unloaded:
        y0 = measure_unloaded(ski, noise_m=NOISE_M, rng=seed + 500)
        f, xf, y = np.r_[0.0, f], np.r_[0.0, xf], np.vstack([y0, y])
    t0 = time.perf_counter()
    ident, check = identify_with_pool(identify_beam_checked, x, f, xf, y, holdout=0.2, seed=0)
    wall = time.perf_counter() - t0
    held = np.asarray(check["held_out_index"], dtype=int)
    truth = predict_gaps(ski, f[held], xf[held])
    pred = predict_gaps(ident.beam, f[held], xf[held])
    near = truth < NEAR_CONTACT_M
    held_rms = float(np.sqrt(np.mean((pred - truth)[near] ** 2)))
    kept = np.setdiff1d(np.arange(f.size), held)
    t1 = time.perf_counter()
    with fixed_blas_threads():
        from_truth = fit_forward(
            x,
            f[kept],
            xf[kept],
            y[kept],
            ski,
            noise_m=ident.noise_m,
            stiffness_knots_m=ident.knots_m,
            smoothing=10.0,
            coarse_spacing_m=0.0,
            foundation_length_m=0.0,
        )
    pred_t = predict_gaps(from_truth.beam, f[held], xf[held])
    return {
        "design": name,
        "grid": f"{n_loads}x{n_pos}",
        "seed": seed,
        "unloaded": unloaded,
        "ok": bool(ident.ok),
        "reason": ident.reason,
        "misfit_over_noise": ident.misfit_m / ident.noise_m,
        "noise_um": ident.noise_m * 1e6,
        "held_out_vs_truth_um": held_rms * 1e6,
        "held_out_vs_measured_um": (check["held_out_rms_m"] or float("nan")) * 1e6,
        "time_s": wall,
        "start": ident.extra.get("start"),
        "restarted": ident.extra.get("restarted"),
        "starts": ident.extra.get("starts"),
        "candidates": ident.extra.get("forward_candidates"),
        "spread": ident.extra.get("candidate_spread"),
        "from_truth": {
            "misfit_over_noise": from_truth.misfit_m / ident.noise_m,
            "objective": from_truth.objective,
            "held_out_vs_truth_um": float(np.sqrt(np.mean((pred_t - truth)[near] ** 2))) * 1e6,
            "time_s": time.perf_counter() - t1,
        },
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--grid", default="13x9")
    ap.add_argument("--designs", default=",".join(DESIGNS))
    ap.add_argument("--no-unloaded", action="store_true")
    ap.add_argument("--out", default="docs/studies/identify-designs.jsonl")
    a = ap.parse_args()
    n_loads, n_pos = (int(v) for v in a.grid.split("x"))
    for name in a.designs.split(","):
        seed = 2600 + list(DESIGNS).index(name)
        row = run(name, n_loads, n_pos, seed, not a.no_unloaded)
        print(
            f"{name} {a.grid}: ok={row['ok']} {row['misfit_over_noise']:.4f}x "
            f"held-out {row['held_out_vs_truth_um']:.3f} um, from truth "
            f"{row['from_truth']['misfit_over_noise']:.4f}x "
            f"{row['from_truth']['held_out_vs_truth_um']:.3f} um, {row['time_s']:.0f} s "
            f"{row['reason']}",
            flush=True,
        )
        with open(a.out, "a") as fh:
            fh.write(json.dumps(row, default=float) + "\n")


if __name__ == "__main__":
    main()
