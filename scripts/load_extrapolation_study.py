"""How far beyond its measured loads each profile model may answer (issue #26, point 3).

For each ski (the demo skis' true beams and the designs of ``solvers.ski_designs.STUDY_DESIGNS``)
the virtual device (``solvers.beam.measure_camber``, ``measure_unloaded``; 3 µm noise) measures
the unloaded profile and 9 loads × 9 positions up to ``--fit-max-kg``. The camber network (the
job's settings, ``--ensemble`` members) is trained and the beam identified on these cases only;
both are then compared with the true beam's noise-free profile at ``factor`` × the heaviest
measured load (1.0 … 1.5, above the measured range) and × the lightest (0.25 … 1.0, between the
unloaded profile and the lightest loaded case), at 5 load positions: RMS of H* − H*_true where
H*_true < 0.2 mm and over the whole profile.

    python scripts/load_extrapolation_study.py --out docs/studies/load-extrapolation.json

Writes the JSON after every ski (a partial run keeps what it finished).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from skisnow.app.storage.skis import read_ski
from skisnow.app.training.fit import train_camber_network
from skisnow.solvers import camber
from skisnow.solvers.beam import G_STANDARD, measure_camber, measure_unloaded, solve_beam_contact
from skisnow.solvers.identify import identify_beam, predict_gaps
from skisnow.solvers.ski_designs import STUDY_DESIGNS

REPO = Path(__file__).resolve().parents[1]
HEAVY_FACTORS = (1.0, 1.1, 1.2, 1.3, 1.4, 1.5)
LIGHT_FACTORS = (0.25, 0.5, 0.75, 1.0)
EVAL_POSITIONS_M = np.linspace(-0.25, 0.05, 5)
BAND_M = 0.2e-3


def truth_beams(names: list[str]):
    for name in names:
        if name in ("ski-a", "ski-b"):
            yield name, read_ski(REPO / "tables" / "skis" / f"{name}.h5").beam
        else:
            yield name, STUDY_DESIGNS[name].build()


def rms(pred: np.ndarray, true: np.ndarray) -> tuple[float, float]:
    band = true < BAND_M
    d = pred - true
    return float(np.sqrt(np.mean(d[band] ** 2))), float(np.sqrt(np.mean(d**2)))


def study(name, beam, args) -> dict:
    step = args.sample_step
    nodes = beam.positions_m[::step]
    loads = np.linspace(args.fit_min_kg, args.fit_max_kg, args.loads) * G_STANDARD
    positions = np.linspace(-0.30, 0.10, args.positions)
    f, xf, y = measure_camber(beam, loads, positions, noise_m=3e-6, rng=args.seed)
    y0 = measure_unloaded(beam, noise_m=3e-6, rng=args.seed + 1000)
    y = y[:, ::step]
    y0 = y0[::step]
    out: dict = {"ski": name, "fit_loads_kg": [float(v) for v in loads / G_STANDARD]}
    t0 = time.perf_counter()
    net = train_camber_network(
        nodes,
        np.concatenate([f, [0.0]]),
        np.concatenate([xf, [0.0]]),
        np.vstack([y, y0]),
        epochs=args.epochs,
        lbfgs_epochs=args.lbfgs_epochs,
        ensemble=args.ensemble,
        seed=0,
    ).network
    out["network_training_s"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    ident = identify_beam(nodes, f, xf, y)
    out["identification_s"] = time.perf_counter() - t0
    out["identification_ok"] = bool(ident.ok)
    out["identification_reason"] = str(ident.reason)
    out["misfit_um"] = float(ident.misfit_m * 1e6)
    out["noise_um"] = float(ident.noise_m * 1e6)
    rows = []
    for kind, base, factors in (
        ("heavy", loads.max(), HEAVY_FACTORS),
        ("light", loads.min(), LIGHT_FACTORS),
    ):
        for fac in factors:
            fe = np.full(EVAL_POSITIONS_M.size, base * fac)
            true = np.stack(
                [
                    solve_beam_contact(beam, a, b).gap_m[::step]
                    for a, b in zip(fe, EVAL_POSITIONS_M, strict=True)
                ]
            )
            pn = camber._forward(net, np.stack([fe, EVAL_POSITIONS_M], axis=1))
            row = {"side": kind, "factor": fac, "load_kg": float(base * fac / G_STANDARD)}
            row["network_band_um"], row["network_all_um"] = (v * 1e6 for v in rms(pn, true))
            if ident.ok:
                pb = predict_gaps(ident.beam, fe, EVAL_POSITIONS_M)
                row["beam_band_um"], row["beam_all_um"] = (v * 1e6 for v in rms(pb, true))
            rows.append(row)
            print(name, row, flush=True)
    # the network at F = 0 against the true camber
    p0 = camber._forward(net, np.stack([np.zeros(5), EVAL_POSITIONS_M], axis=1))
    c0 = np.repeat(beam.unloaded_gap_m[::step][None], 5, 0)
    out["network_unloaded_um"] = rms(p0, c0)[1] * 1e6
    out["rows"] = rows
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--skis", default="ski-a,ski-b," + ",".join(STUDY_DESIGNS))
    ap.add_argument("--fit-min-kg", type=float, default=10.0)
    ap.add_argument("--fit-max-kg", type=float, default=60.0)
    ap.add_argument("--loads", type=int, default=9)
    ap.add_argument("--positions", type=int, default=9)
    ap.add_argument("--sample-step", type=int, default=5, help="every n-th 1 mm node (5: 5 mm)")
    ap.add_argument("--epochs", type=int, default=4000)
    ap.add_argument("--lbfgs-epochs", type=int, default=1500)
    ap.add_argument("--ensemble", type=int, default=1)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--out", type=Path, default=REPO / "docs/studies/load-extrapolation.json")
    args = ap.parse_args(argv)
    results = {"settings": {k: str(v) for k, v in vars(args).items()}, "skis": []}
    for name, beam in truth_beams(args.skis.split(",")):
        results["skis"].append(study(name, beam, args))
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
