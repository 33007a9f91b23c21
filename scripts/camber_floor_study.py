"""What limits the camber network's apparent-area accuracy: measurement noise or the network?

Issue #3 asks for the apparent contact area from the predicted loaded profile within 3 % of
that from the true profile. The shipped demo networks meet it in the median but not at light
loads (docs/camber-network.md). This study separates the two candidate causes on the demo
skis, whose beam model gives the noise-free truth at any load:

``measured``
    the network trained on the ski file's measurements (3 µm device noise), as shipped;
``noise-free``
    the same network, settings and load cases, trained on the beam model's exact profiles.

If ``noise-free`` misses the target too, more or better measurements cannot close the gap:
the network's own approximation error (about 1 µm) is what the area reacts to. ``--grid
LxP`` adds both variants on a denser measuring grid (L loads 10–90 kg × P positions
−300…+100 mm, the virtual device of ``solvers.beam.measure_camber``, seed 7).

Every variant is one ensemble member (``--ensemble``), seed 0, the command's other defaults
(relu 2 × 64, 5 mm nodes, 10 mm output smoothing), checked by
:func:`app.training.check.truth_check` on the network's held-out test cases, 32 loads drawn
uniformly from the trained range (seed 0) and the papers' case 40 kg at −160 mm, through the
macro BEM at E_snow = 200 MPa. Results: ``docs/studies/camber-floor.json`` and ``.png``
(atomic writes, provenance inside).

Usage::

    python scripts/camber_floor_study.py [--ski ski-a] [--grid 49x33] [--ensemble 1]
                                         [--residual-stage] [--jobs 2]

``--residual-stage`` adds, for every variant, the same network plus a second one trained on
what the first leaves (:func:`residual_stage`, a prototype that is not part of
``skisnow train-camber``).

Needs PyTorch (``pip install 'skisnow[train]'``); about 1–2 min per variant on a quiet 2-core
machine at the shipped grid (425 load cases), about 4× that at 49 × 33.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app.storage import common, skis  # noqa: E402
from skisnow.app.training.check import beam_truth_profiles, truth_check  # noqa: E402
from skisnow.app.training.data import camber_training_arrays, split_load_cases  # noqa: E402
from skisnow.app.training.fit import _fit_member, train_camber_network  # noqa: E402
from skisnow.app.training.model import smoothing_matrix, sum_networks, torch_threads  # noqa: E402
from skisnow.solvers import beam, elastic  # noqa: E402

log = logging.getLogger("camber_floor_study")

SNOW_MODULUS_PA = 200e6
PAPERS_CASE = (40.0 * beam.G_STANDARD, -0.160)
TARGET = 0.03
NOISE_M = 3e-6
GRID_SEED = 7


def variants(record, grid: tuple[int, int] | None):
    """(name, loads [N], positions [m], profiles [m]) of every training set to compare."""
    _, x, f, xf, h, _ = camber_training_arrays(record.measurements)
    out = [
        ("measured", f, xf, h),
        ("noise-free", f, xf, beam_truth_profiles(record.beam, x, f, xf)),
    ]
    if grid is not None:
        loads = np.linspace(10.0, 90.0, grid[0]) * beam.G_STANDARD
        pos = np.linspace(-0.300, 0.100, grid[1])
        for name, noise in (
            (f"measured {grid[0]}x{grid[1]}", NOISE_M),
            (f"noise-free {grid[0]}x{grid[1]}", 0.0),
        ):
            gf, gxf, gh = beam.measure_camber(
                record.beam, loads, pos, noise_m=noise, rng=np.random.default_rng(GRID_SEED)
            )
            gh = np.array([np.interp(x, record.beam.positions_m, row) for row in gh])
            out.append((name, gf, gxf, gh))
    return x, out


def residual_stage(
    network: dict,
    f: np.ndarray,
    xf: np.ndarray,
    h: np.ndarray,
    *,
    scale_m: float = 2e-6,
    smoothing_m: float = 3e-3,
    epochs: int = 4000,
    lbfgs_epochs: int = 1500,
    patience: int = 400,
    seed: int = 100,
) -> dict:
    """Second network fitted to what the first one leaves, folded into one MLP (prototype).

    The first network (frozen) gives S1 at the nodes; a second MLP of the same width and
    activation, with its output scaled to ``scale_m`` per node and smoothed by
    ``smoothing_m``, minimises the training loss of S1 + S2 (``app.training.fit._fit_member``
    with ``base = S1``: same loss, split, Adam then L-BFGS and early stopping as the first).
    :func:`app.training.model.sum_networks` adds the two into one MLP of the stored schema
    (stacked first layer, block-diagonal hidden layers, concatenated
    last layer), exactly like the ensemble fold.
    """
    import torch
    from skisnow.solvers import camber

    x = np.asarray(network["positions_m"])
    node_idx = camber.select_nodes(x, float(network["attrs"]["node_spacing_m"]))
    nodes = x[node_idx]
    split = split_load_cases(f, xf, seed=int(network["attrs"]["seed"]))
    band = float(network["attrs"]["contact_band_m"])
    hidden = [int(v) for v in str(network["attrs"]["hidden_layers"]).split(",")]
    if not np.allclose(network["output_scale"], 1.0):
        raise ValueError("residual_stage needs a folded network (output_scale 1)")
    activation = str(network["attrs"]["activation"])
    g = smoothing_matrix(nodes, smoothing_m)
    f_in = (np.stack([f, xf], axis=1) - network["input_offset"]) / network["input_scale"]
    with torch_threads(torch, 1):
        member = _fit_member(
            torch,
            seed=seed,
            sizes=[2, *hidden, int(nodes.size)],
            inputs=f_in,
            targets=h[:, node_idx],
            rows=(split["train"], split["validation"]),
            out_offset=np.zeros(nodes.size),
            out_scale=np.full(nodes.size, scale_m),
            smoother=g,
            activation=activation,
            contact_band_m=band,
            epochs=epochs,
            lbfgs_epochs=lbfgs_epochs,
            learning_rate=1e-2,
            patience=patience,
            progress=None,
            base=camber.signed_node_gaps(network, np.stack([f, xf], axis=1)),
        )
    w2, b2 = list(member["weights"]), list(member["biases"])
    w2[-1] = g @ (scale_m * w2[-1])
    b2[-1] = g @ (scale_m * b2[-1])
    n = int(network["attrs"]["n_layers"])
    first = (
        [np.asarray(network[f"layer{i}_weight"]) for i in range(n)],
        [np.asarray(network[f"layer{i}_bias"]) for i in range(n)],
    )
    weights, biases = sum_networks([first, (w2, b2)])
    out = dict(network)
    out["attrs"] = dict(network["attrs"])
    for i in range(n):
        out[f"layer{i}_weight"], out[f"layer{i}_bias"] = weights[i], biases[i]
    out["attrs"]["residual_stage"] = f"scale {scale_m:g} m, smoothing {smoothing_m:g} m"
    return out


def evaluate(record, network, name: str, n_cases: int, train_s: float) -> dict:
    """Truth check of one trained network (module docstring) as a JSON-ready row."""
    t = truth_check(
        network,
        record.beam,
        n_random=32,
        seed=0,
        width_m=record.outline.width_m,
        width_positions_m=record.outline.positions_m,
        effective_modulus_pa=elastic.effective_modulus(SNOW_MODULUS_PA),
        extra_cases=[PAPERS_CASE],
    )
    err = t["truth_cases_area_pred_m2"] / t["truth_cases_area_true_m2"] - 1.0
    return {
        "variant": name,
        "load_cases": int(n_cases),
        "training_time_s": round(train_s, 1),
        "rmse_band_test_um": round(t["truth_rmse_band_test_m"] * 1e6, 3),
        "rmse_band_random_um": round(t["truth_rmse_band_random_m"] * 1e6, 3),
        "area_error_rms_pct": round(float(np.sqrt(np.mean(err**2))) * 100, 2),
        "area_error_max_pct": round(float(np.abs(err).max()) * 100, 2),
        "area_error_median_pct": round(float(np.median(np.abs(err))) * 100, 2),
        "cases_within_target_pct": round(float(np.mean(np.abs(err) <= TARGET)) * 100, 1),
        "papers_case_error_pct": round(float(err[-1]) * 100, 2),
        "bem_converged": bool(t["truth_bem_converged"]),
        "cases_load_n": np.round(t["truth_cases_loads_n"], 2).tolist(),
        "cases_load_position_m": np.round(t["truth_cases_load_positions_m"], 4).tolist(),
        "cases_area_error_pct": np.round(err * 100, 3).tolist(),
    }


def train_variant(x, f, xf, h, name: str, ensemble: int = 1, **kwargs) -> tuple[dict, float]:
    """The network of one training set: ``skisnow train-camber``'s defaults except
    ``ensemble`` members, seed 0 (``kwargs`` override other settings, e.g. ``epochs``).
    Returns the network dict and the training time [s]."""
    t0 = time.perf_counter()
    res = train_camber_network(x, f, xf, h, ensemble=ensemble, seed=0, ski_id=name, **kwargs)
    return res.network, time.perf_counter() - t0


def run_variant(record, x, name, f, xf, h, ensemble: int, residual: bool) -> list[dict]:
    """Train on one training set and check against the truth; with ``residual`` also the
    network plus a residual stage (:func:`residual_stage`)."""
    network, train_s = train_variant(x, f, xf, h, name, ensemble)
    rows = [evaluate(record, network, name, f.size, train_s)]
    if residual:
        t0 = time.perf_counter()
        both = residual_stage(network, f, xf, h)
        extra_s = time.perf_counter() - t0
        rows.append(
            evaluate(
                record, both, f"{name} + residual", f.size, rows[0]["training_time_s"] + extra_s
            )
        )
    return rows


def study_ski(ski: str, grid, ensemble: int, residual: bool) -> list[dict]:
    """All variants of one demo ski (runs in a worker process)."""
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    record = skis.read_ski(REPO / "tables" / "skis" / f"{ski}.h5")
    x, sets = variants(record, grid)
    out: list[dict] = []
    for i, (name, f, xf, h) in enumerate(sets, 1):
        log.info("%s: variant %d/%d %s (%d load cases)", ski, i, len(sets), name, f.size)
        for row in run_variant(record, x, name, f, xf, h, ensemble, residual):
            log.info(
                "%s %-28s RMSE(H*<0.2 mm) %.2f µm  area error rms %.1f %%, max %.1f %%, "
                "%.0f %% of cases within 3 %%",
                ski,
                row["variant"],
                row["rmse_band_random_um"],
                row["area_error_rms_pct"],
                row["area_error_max_pct"],
                row["cases_within_target_pct"],
            )
            out.append(row)
    return out


def plot(results: dict, path: Path) -> None:
    from matplotlib.figure import Figure

    names = list(results)
    fig = Figure(figsize=(5.0 * len(names), 3.8), layout="constrained")
    axes = fig.subplots(1, len(names), squeeze=False)[0]
    for ax, ski in zip(axes, names, strict=True):
        for row, marker in zip(results[ski], "os^vDP<>", strict=False):
            ax.scatter(
                row["cases_load_n"],
                np.maximum(np.abs(row["cases_area_error_pct"]), 0.01),
                s=14,
                marker=marker,
                alpha=0.7,
                label=f"{row['variant']} (max {row['area_error_max_pct']:.1f} %)",
            )
        ax.axhline(TARGET * 100, color="k", lw=0.8, ls="--", label="target 3 %")
        ax.set_yscale("log")
        ax.set_ylim(0.01, 100)
        ax.set_xlabel("load F [N]")
        ax.set_ylabel("|area error| vs beam truth [%]")
        ax.set_title(f"{ski}: trained on measured vs noise-free profiles", fontsize=9)
        ax.legend(fontsize=7)
    with common.atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ski", action="append", choices=("ski-a", "ski-b"))
    ap.add_argument("--grid", help="also train on a denser measuring grid, e.g. 49x33")
    ap.add_argument("--ensemble", type=int, default=1, help="members per network (default 1)")
    ap.add_argument(
        "--residual-stage",
        action="store_true",
        help="also train a second network on what the first leaves (prototype, not shipped)",
    )
    ap.add_argument("--jobs", type=int, default=2, help="skis studied in parallel (default 2)")
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "studies" / "camber-floor.json")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    grid = None
    if args.grid:
        try:
            grid = tuple(int(v) for v in args.grid.lower().split("x"))
        except ValueError:
            ap.error(f"--grid must look like 49x33, got {args.grid!r}")
        if len(grid) != 2 or min(grid) < 3:
            ap.error(f"--grid needs two counts >= 3, got {args.grid!r}")
    names = args.ski or ["ski-a", "ski-b"]
    # one process per ski (each trains with one torch thread)
    with ProcessPoolExecutor(max_workers=min(len(names), args.jobs)) as pool:
        futures = [
            pool.submit(study_ski, ski, grid, args.ensemble, args.residual_stage) for ski in names
        ]
        results = dict(zip(names, (fut.result() for fut in futures), strict=True))
    doc = {
        "schema": "skisnow.camber-floor/1",
        "provenance": common.provenance(
            {
                "ensemble": args.ensemble,
                "grid": args.grid,
                "residual_stage": args.residual_stage,
                "snow_modulus_pa": SNOW_MODULUS_PA,
            }
        ),
        "units": {"rmse": "µm", "area errors": "% of the area from the true profile"},
        "results": results,
    }
    with common.atomic_path(args.out) as tmp:
        tmp.write_text(json.dumps(doc, indent=1), encoding="utf-8")
    plot(results, args.out.with_suffix(".png"))
    print(
        f"{'ski':6s} {'variant':30s} {'cases':>5s} {'RMSE µm':>8s} {'rms %':>6s} "
        f"{'max %':>6s} {'≤3 %':>5s}"
    )
    for ski, rows in results.items():
        for r in rows:
            print(
                f"{ski:6s} {r['variant']:30s} {r['load_cases']:5d} {r['rmse_band_random_um']:8.2f} "
                f"{r['area_error_rms_pct']:6.1f} {r['area_error_max_pct']:6.1f} "
                f"{r['cases_within_target_pct']:5.0f}"
            )
    print(f"written {args.out} and {args.out.with_suffix('.png')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
