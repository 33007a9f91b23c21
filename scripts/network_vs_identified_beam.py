"""Profile model of a ski: its identified beam, or a network retrained on that beam's profiles?

Issue #12 point 2. The loaded profile H*(X) for any (F, x_F) can come from the beam identified
from the ski's camber measurements (:class:`app.service.profiles.ProfileModel`, flexibility
cached) or from the camber network retrained on that identified beam's **noise-free** profiles.
This study measures both on the demo skis, against their true beam (``record.beam``), on the 85
cases the identification held out (``tests/service/test_demo_identification.py``:
``held_out_index`` of the
ski file's ``identified`` group, 20 %, seed 0):

- loaded profile: RMS of H* − H*_true where H*_true < 0.2 mm, pooled over the cases (the
  acceptance test's figure), and the worst single case;
- apparent area: rigid model, default macro grid, E_snow = 200 MPa
  (:func:`solvers.macro.solve_macro` on :func:`solvers.macro.extrude_profile`, as the
  acceptance test), error against the true profile's area: max, median, count within 3 %;
- time per profile as the service calls it (:class:`app.service.profiles.ProfileModel`): the
  identified beam (:func:`solvers.beam.solve_beam_contact`, cold start, cached flexibility) and
  the network (:func:`solvers.camber.predict_profile`), interleaved in the same process, medians
  over ``--repeats`` rounds of the held-out cases; the flexibility's one-off build apart.

Models compared (the network: :func:`camber_floor_study.train_variant`, i.e. ``skisnow
train-camber``'s settings, relu 2 × 64, 5 mm nodes, 10 mm output smoothing, 4000 Adam + 1500
L-BFGS epochs, patience 400, one ensemble member, seed 0):

``identified beam``
    what the service serves today;
``network on identified beam (identification cases)``
    trained on the identified beam's profiles at the 340 measured cases the identification
    used, so the 85 held-out cases are unseen by both models (the fair comparison);
``network on identified beam (all measured cases)``
    trained at all 425 measured cases, held-out ones included (``--all-cases``; what a
    retrain of a stored ski would use, favourable to the network);
``shipped network (measurements)``
    the ski file's 3-member network, trained on the 3 µm-noise measurements (reference).

Results: ``docs/studies/network-vs-identified-beam.json`` and ``.png`` (atomic writes,
provenance inside).

Usage::

    python scripts/network_vs_identified_beam.py [--ski ski-a] [--all-cases] [--epochs 4000]
                                                 [--lbfgs-epochs 1500] [--repeats 3]
                                                 [--skip-training]
                                                 [--jobs 2]

Needs PyTorch (``pip install 'skisnow[train]'``); one training takes about 1–2 min on a quiet
core.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "scripts"))

import camber_floor_study as cfs  # noqa: E402
from skisnow.app.service.profiles import ProfileModel  # noqa: E402
from skisnow.app.storage import common, skis  # noqa: E402
from skisnow.app.training.check import beam_truth_profiles  # noqa: E402
from skisnow.solvers import elastic  # noqa: E402
from skisnow.solvers.macro import extrude_profile, solve_macro  # noqa: E402

log = logging.getLogger("network_vs_identified_beam")

#: where the acceptance test measures the profile error: true H* below this [m]
NEAR_CONTACT_M = 2e-4
#: targets of issue #12: profile RMS [m], area error [-], time per beam profile [s]
PROFILE_TARGET_M = 0.3e-6
AREA_TARGET = cfs.TARGET
TIME_TARGET_S = 10e-3

BEAM = "identified beam"
NET_ID = "network on identified beam (identification cases)"
NET_ALL = "network on identified beam (all measured cases)"
SHIPPED = "shipped network (measurements)"


def read_record(ski: str) -> skis.SkiRecord:
    return skis.read_ski(REPO / "tables" / "skis" / f"{ski}.h5")


def held_out(record) -> np.ndarray:
    """Indices of the measured cases the identification held out (as the acceptance test)."""
    ident = record.identified
    if ident is None or not ident["attrs"]["ok"]:
        raise SystemExit(f"{record.ski_id}: no identified beam in the ski file")
    return np.asarray(ident["held_out_index"], dtype=int)


def network_model(record, network: dict) -> ProfileModel:
    """The service's profile model of ``record`` answering with ``network`` (no beam)."""
    rec = dataclasses.replace(record, identified=None, network=network, cache={})
    model = ProfileModel(rec)
    assert model.source == "network", model.source
    return model


def train_networks(
    ski: str, all_cases: bool, epochs: int, lbfgs_epochs: int
) -> dict[str, tuple[dict, float, int]]:
    """Networks trained on the identified beam's noise-free profiles (runs in a worker):
    name -> (network, training time [s], training load cases)."""
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    record = read_record(ski)
    beam = skis.identified_beam(record.identified)
    m = record.measurements
    x = np.asarray(m.positions_m, dtype=float)
    held = np.zeros(m.loads_n.size, dtype=bool)
    held[held_out(record)] = True
    sets = [(NET_ID, ~held)]
    if all_cases:
        sets.append((NET_ALL, np.ones_like(held)))
    out = {}
    for name, rows in sets:
        f, xf = m.loads_n[rows], m.load_positions_m[rows]
        h = beam_truth_profiles(beam, x, f, xf)
        log.info("%s: training %s on %d cases, %d epochs", ski, name, f.size, epochs)
        net, train_s = cfs.train_variant(
            x, f, xf, h, f"{ski} {name}", epochs=epochs, lbfgs_epochs=lbfgs_epochs
        )
        log.info("%s: %s trained in %.0f s", ski, name, train_s)
        out[name] = (net, train_s, int(f.size))
    return out


def area(record, gap_m: np.ndarray, load_n: float, position_m: float) -> float:
    """Apparent contact area [m²] of one loaded profile: rigid model, default grid, 200 MPa."""
    gm = extrude_profile(
        record.measurements.positions_m,
        gap_m,
        record.outline.width_m,
        width_positions_m=record.outline.positions_m,
    )
    res = solve_macro(gm, load_n, position_m, elastic.effective_modulus(cfs.SNOW_MODULUS_PA))
    if not res.converged:
        raise RuntimeError(f"macro BEM did not converge at {load_n:.1f} N, {position_m:.3f} m")
    return float(res.apparent_contact_area_m2)


def timings(models: dict[str, ProfileModel], f: np.ndarray, xf: np.ndarray, repeats: int):
    """Time per profile of every model, calls interleaved case by case: name -> median wall
    time, 90th-percentile wall time and median CPU time of this process [s]."""
    wall: dict[str, list[float]] = {name: [] for name in models}
    cpu: dict[str, list[float]] = {name: [] for name in models}
    for _ in range(repeats):
        for load, pos in zip(f, xf, strict=True):
            for name, model in models.items():
                c0, t0 = time.process_time(), time.perf_counter()
                model(load, pos)
                wall[name].append(time.perf_counter() - t0)
                cpu[name].append(time.process_time() - c0)
    return {
        name: (
            float(np.median(wall[name])),
            float(np.percentile(wall[name], 90)),
            float(np.median(cpu[name])),
        )
        for name in models
    }


def papers_case_timing(record, beam_model: ProfileModel, repeats: int) -> dict[str, float]:
    """Yardstick against the quiet-machine benchmark (``skisnow bench macro``, papers' case):
    median wall times [ms] of the beam profile and of the rigid macro solve of that profile at
    40 kg / −160 mm, interleaved, in this run."""
    load, pos = cfs.PAPERS_CASE
    x, gap = beam_model(load, pos)
    gm = extrude_profile(
        x, gap, record.outline.width_m, width_positions_m=record.outline.positions_m
    )
    e_eff = elastic.effective_modulus(cfs.SNOW_MODULUS_PA)
    solve_macro(gm, load, pos, e_eff)  # warm-up
    t_beam, t_macro = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        beam_model(load, pos)
        t_beam.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        solve_macro(gm, load, pos, e_eff)
        t_macro.append(time.perf_counter() - t0)
    return {
        "beam_profile_ms": round(float(np.median(t_beam)) * 1e3, 3),
        "rigid_macro_solve_ms": round(float(np.median(t_macro)) * 1e3, 3),
    }


def study_ski(ski: str, networks: dict, repeats: int) -> dict:
    """Errors and timings of every model on one ski's held-out cases (main process)."""
    record = read_record(ski)
    idx = held_out(record)
    m = record.measurements
    f, xf = m.loads_n[idx], m.load_positions_m[idx]

    beam_model = ProfileModel(record)
    assert beam_model.source == "identified_beam", beam_model.source
    t0 = time.perf_counter()
    beam_model(f[0], xf[0])  # first call: builds the cached flexibility
    first_call_s = time.perf_counter() - t0
    models = {BEAM: beam_model}
    for name, (net, _, _) in networks.items():
        models[name] = network_model(record, net)
    models[SHIPPED] = network_model(record, record.network)
    times = timings(models, f, xf, repeats)
    yardstick = papers_case_timing(record, beam_model, 10 * repeats)

    truth = beam_truth_profiles(record.beam, m.positions_m, f, xf)
    truth_area = np.array([area(record, truth[k], f[k], xf[k]) for k in range(f.size)])
    rows = []
    for name, model in models.items():
        pred = np.array([model(f[k], xf[k])[1] for k in range(f.size)])
        near = truth < NEAR_CONTACT_M
        diff = np.where(near, pred - truth, 0.0)
        per_case = np.sqrt((diff**2).sum(axis=1) / np.maximum(near.sum(axis=1), 1))
        rms = float(np.sqrt(np.mean((pred - truth)[near] ** 2)))
        err = np.array([area(record, pred[k], f[k], xf[k]) for k in range(f.size)]) / truth_area
        err -= 1.0
        worst = int(np.argmax(np.abs(err)))
        row = {
            "model": name,
            "training_load_cases": networks[name][2] if name in networks else None,
            "training_time_s": round(networks[name][1], 1) if name in networks else None,
            "profile_rms_near_contact_um": round(rms * 1e6, 4),
            "profile_rms_worst_case_um": round(float(per_case.max()) * 1e6, 3),
            "area_error_max_pct": round(float(np.abs(err).max()) * 100, 2),
            "area_error_median_pct": round(float(np.median(np.abs(err))) * 100, 3),
            "area_error_rms_pct": round(float(np.sqrt(np.mean(err**2))) * 100, 2),
            "cases_within_3pct": int(np.sum(np.abs(err) <= AREA_TARGET)),
            "worst_case": {
                "load_n": round(float(f[worst]), 2),
                "load_position_m": round(float(xf[worst]), 4),
                "area_error_pct": round(float(err[worst]) * 100, 2),
            },
            "time_per_profile_median_ms": round(times[name][0] * 1e3, 3),
            "time_per_profile_p90_ms": round(times[name][1] * 1e3, 3),
            "cpu_time_per_profile_median_ms": round(times[name][2] * 1e3, 3),
            "cases_area_error_pct": np.round(err * 100, 3).tolist(),
            "cases_profile_rms_um": np.round(per_case * 1e6, 4).tolist(),
        }
        row["meets_targets"] = bool(
            rms <= PROFILE_TARGET_M
            and row["cases_within_3pct"] == f.size
            and times[name][0] <= TIME_TARGET_S
        )
        rows.append(row)
        log.info(
            "%s %-52s RMS %.3f µm  area max %.2f %% median %.3f %% (%d/%d within 3 %%)  "
            "%.3f ms/profile (CPU %.3f ms)",
            ski,
            name,
            rms * 1e6,
            row["area_error_max_pct"],
            row["area_error_median_pct"],
            row["cases_within_3pct"],
            f.size,
            row["time_per_profile_median_ms"],
            row["cpu_time_per_profile_median_ms"],
        )
    return {
        "held_out_cases": int(f.size),
        "cases_load_n": np.round(f, 2).tolist(),
        "cases_load_position_m": np.round(xf, 4).tolist(),
        "cases_true_area_cm2": np.round(truth_area * 1e4, 3).tolist(),
        "beam_first_call_ms": round(first_call_s * 1e3, 1),
        "papers_case_ms": yardstick,
        "models": rows,
    }


def plot(results: dict, path: Path) -> None:
    from matplotlib.figure import Figure

    names = list(results)
    fig = Figure(figsize=(5.0 * len(names), 3.8), layout="constrained")
    axes = fig.subplots(1, len(names), squeeze=False)[0]
    for ax, ski in zip(axes, names, strict=True):
        res = results[ski]
        for row, marker in zip(res["models"], "os^v", strict=False):
            ax.scatter(
                res["cases_load_n"],
                np.maximum(np.abs(row["cases_area_error_pct"]), 0.001),
                s=14,
                marker=marker,
                alpha=0.7,
                label=f"{row['model']} (max {row['area_error_max_pct']:.1f} %)",
            )
        ax.axhline(AREA_TARGET * 100, color="k", lw=0.8, ls="--", label="target 3 %")
        ax.set_yscale("log")
        ax.set_ylim(0.001, 100)
        ax.set_xlabel("load F [N]")
        ax.set_ylabel("|area error| vs beam truth [%]")
        ax.set_title(f"{ski}: {res['held_out_cases']} held-out cases, 200 MPa", fontsize=9)
        ax.legend(fontsize=6)
    with common.atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ski", action="append", choices=("ski-a", "ski-b"))
    ap.add_argument(
        "--all-cases",
        action="store_true",
        help="also train on all 425 measured cases (held-out ones included)",
    )
    ap.add_argument(
        "--skip-training",
        action="store_true",
        help="only the identified beam and the shipped network (errors and timings)",
    )
    ap.add_argument("--epochs", type=int, default=4000, help="Adam epochs (default 4000)")
    ap.add_argument("--lbfgs-epochs", type=int, default=1500, help="L-BFGS (default 1500)")
    ap.add_argument("--repeats", type=int, default=3, help="timing rounds (default 3)")
    ap.add_argument("--jobs", type=int, default=2, help="skis trained in parallel (default 2)")
    ap.add_argument(
        "--out", type=Path, default=REPO / "docs" / "studies" / "network-vs-identified-beam.json"
    )
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    names = args.ski or ["ski-a", "ski-b"]
    t0 = time.perf_counter()
    # one process per ski (each trains with one torch thread)
    if args.skip_training:
        networks = {ski: {} for ski in names}
    else:
        with ProcessPoolExecutor(max_workers=min(len(names), args.jobs)) as pool:
            futures = [
                pool.submit(train_networks, s, args.all_cases, args.epochs, args.lbfgs_epochs)
                for s in names
            ]
            networks = dict(zip(names, (fut.result() for fut in futures), strict=True))
    train_wall_s = time.perf_counter() - t0
    # errors and timings in this process, one ski after the other (no training running)
    results = {ski: study_ski(ski, networks[ski], args.repeats) for ski in names}
    doc = {
        "schema": "skisnow.network-vs-identified-beam/1",
        "provenance": common.provenance(
            {
                "all_cases": args.all_cases,
                "skip_training": args.skip_training,
                "epochs": args.epochs,
                "lbfgs_epochs": args.lbfgs_epochs,
                "ensemble": 1,
                "seed": 0,
                "repeats": args.repeats,
                "snow_modulus_pa": cfs.SNOW_MODULUS_PA,
                "near_contact_m": NEAR_CONTACT_M,
                "training_wall_s": round(train_wall_s, 1),
            }
        ),
        "units": {
            "profile rms": "µm, where the true H* < 0.2 mm",
            "area errors": "% of the area from the true profile",
            "times": "ms per profile, median (and 90th percentile) wall time of interleaved "
            "calls; CPU: median process CPU time of the same calls",
        },
        "targets": {
            "profile_rms_um": PROFILE_TARGET_M * 1e6,
            "area_error_pct_every_case": AREA_TARGET * 100,
            "beam_profile_ms": TIME_TARGET_S * 1e3,
        },
        "results": results,
    }
    with common.atomic_path(args.out) as tmp:
        tmp.write_text(json.dumps(doc, indent=1), encoding="utf-8")
    plot(results, args.out.with_suffix(".png"))
    print(
        f"{'ski':6s} {'model':52s} {'RMS µm':>7s} {'max %':>6s} {'med %':>6s} {'≤3 %':>6s} "
        f"{'ms':>6s} {'CPU ms':>6s}"
    )
    for ski, res in results.items():
        for r in res["models"]:
            print(
                f"{ski:6s} {r['model']:52s} {r['profile_rms_near_contact_um']:7.3f} "
                f"{r['area_error_max_pct']:6.2f} {r['area_error_median_pct']:6.3f} "
                f"{r['cases_within_3pct']:3d}/{res['held_out_cases']:<2d} "
                f"{r['time_per_profile_median_ms']:6.3f} {r['cpu_time_per_profile_median_ms']:6.3f}"
            )
    print(f"written {args.out} and {args.out.with_suffix('.png')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
