"""Build the shipped skis ``ski-a``, ``ski-b`` (calibrated demos), ``ski-c`` (tables/skis/*.h5).

The papers' camber data are not public (docs/physics.md §4), so each demo ski is a classic beam ski
(:class:`solvers.beam.ClassicSkiDesign`) whose pocket (kick-zone camber) height is calibrated by a
1-D root-find so that the macro BEM — true beam profile at 40 kg (g = 9.82) 160 mm behind the
balance point, E_snow = 200 MPa, E_base = 0.7 GPa, ν = 0.3, default grid of
:mod:`solvers.macro` (4 mm × 8 pixels across, sub-pixel zone edges) — gives the papers'
apparent contact area (ski A 63.98 cm², ski B 121.84 cm²). The virtual measuring device then
records 25 loads (10–90 kg) × 17 load positions (−300…+100 mm) at 1 mm sampling with 3 µm
noise (fixed seed).

``ski-c`` (#28) is not calibrated to the papers: it is a classic ski for a 60–80 kg skier, the
design :data:`SKI_C_DESIGN` chosen so that its wax pocket stands open at half weight and closes
near full weight (residual camber under the foot 8 cm behind the balance point ≈ 0.15 mm at
45 kg, 0.10 mm at ≈ 57 kg on the rigid flat; docs/flex.md). It is measured like the others
(same grid, 3 µm noise, its own seeds, the unloaded profile included) and its beam identified
from those measurements (``skisnow identify-ski --ski ski-c --store``); it ships no camber
network (its identified beam answers).

Usage::

    python scripts/make_demo_skis.py [--out tables/skis] [--ski ski-a]
    python scripts/make_demo_skis.py --remeasure [--ski ski-a]   # keep the calibrated beam
    python scripts/make_demo_skis.py --add-unloaded [--ski ski-a]   # + the 0 kg profile

``--remeasure`` keeps the ski in the existing file (beam model, design, outline, calibration
record) bit for bit and only measures it again on the current grid (MEASURE_LOADS_KG ×
MEASURE_POSITIONS_M); the camber network is dropped (retrain: ``skisnow train-camber``). Use it
when only the sampling changes: a fresh calibration depends on the macro solver's version and
would move the pocket height slightly.

``--add-unloaded`` keeps everything in the existing file (the loaded measurements bit for bit,
the network, the calibration) and appends the unloaded profile (load 0, docs/physics.md §4c), which
real devices record first: the virtual device's ``measure_unloaded`` of the true beam with the
same noise model (3 µm) and its own seed (UNLOADED_SEEDS). The stored identification is dropped
(its held-out indices refer to the old cases): identify again with ``skisnow identify-ski --ski
NAME --store``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import sys
from pathlib import Path

import h5py
import numpy as np
import scipy.optimize

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from skisnow.app.storage.skis import CamberData, SkiOutline, SkiRecord, read_ski, write_ski
from skisnow.solvers.beam import (
    G_STANDARD,
    ClassicSkiDesign,
    measure_camber,
    measure_unloaded,
    solve_beam_contact,
)
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.macro import extrude_profile, solve_macro

log = logging.getLogger("make_demo_skis")

WIDTH_M = 0.044
LOAD_N = 40.0 * G_STANDARD
LOAD_POSITION_M = -0.160
E_EFF_PA = effective_modulus(200e6, 0.7e9, 0.3)
#: papers' targets (docs/physics.md §4): apparent contact area [m²]
TARGETS = {"ski-a": 63.98e-4, "ski-b": 121.84e-4}
#: base designs and the bracket of the calibrated pocket height [m]
DESIGNS = {
    "ski-a": (
        ClassicSkiDesign(
            camber_height_m=0.002,
            tail_contact_m=-0.80,
            tip_contact_m=0.70,
            stiffness_nm2=1500.0,
            end_stiffness_ratio=0.15,
            pocket_height_m=1e-3,
        ),
        (0.0006, 0.0012),
    ),
    "ski-b": (
        ClassicSkiDesign(
            camber_height_m=0.001,
            tail_contact_m=-0.85,
            tip_contact_m=0.75,
            stiffness_nm2=600.0,
            end_stiffness_ratio=0.3,
            pocket_m=(-0.40, 0.45),
            pocket_height_m=3.5e-4,
        ),
        (0.0003, 0.0005),
    ),
}
#: ski-c (#28): the ski-a outline with a softer kick zone (EI 1150 N·m²) and a higher pocket
#: (1.5 mm), not calibrated (no papers' target)
SKI_C_DESIGN = ClassicSkiDesign(
    camber_height_m=0.002,
    tail_contact_m=-0.80,
    tip_contact_m=0.70,
    stiffness_nm2=1150.0,
    end_stiffness_ratio=0.15,
    pocket_height_m=1.5e-3,
)
#: skis built from their design as is (no calibration)
UNCALIBRATED = {"ski-c": SKI_C_DESIGN}
#: measuring grid: the loaded profile is kinked in (F, x_F) where contacts appear or lift off,
#: and the apparent contact area from the network is sensitive to µm errors near contact, so
#: the grid is dense (docs/camber-network.md): 25 loads 10..90 kg (3.33 kg apart) × 17 load
#: positions −300..+100 mm (25 mm apart) = 425 cases
MEASURE_LOADS_KG = np.linspace(10.0, 90.0, 25)
MEASURE_POSITIONS_M = np.linspace(-0.300, 0.100, 17)
NOISE_M = 3e-6
SEEDS = {"ski-a": 20231001, "ski-b": 20231002, "ski-c": 20261128}
#: seeds of the unloaded profile's noise (#26): its own stream, so the loaded cases stay bit for bit
UNLOADED_SEEDS = {"ski-a": 20261126, "ski-b": 20261127, "ski-c": 20261129}


def bem_for(design: ClassicSkiDesign):
    """Macro result of a design at the papers' load case (true beam profile)."""
    ski = design.build()
    beam = solve_beam_contact(ski, LOAD_N, LOAD_POSITION_M)
    gm = extrude_profile(ski.positions_m, beam.gap_m, WIDTH_M)
    return solve_macro(gm, LOAD_N, LOAD_POSITION_M, E_EFF_PA)


def rear_share(result) -> float:
    """Fraction of the load carried by contact behind the load point [-]."""
    p = np.nan_to_num(result.pressure_pa)
    behind = result.positions_m < result.load_position_m
    return float(p[behind].sum() / p.sum())


def calibrate(name: str) -> ClassicSkiDesign:
    """Root-find the pocket height so that the apparent area hits the target."""
    base, (lo, hi) = DESIGNS[name]
    target = TARGETS[name]

    def misfit(height: float) -> float:
        res = bem_for(dataclasses.replace(base, pocket_height_m=height))
        log.info(
            "%s pocket %.4g mm -> %.2f cm²", name, height * 1e3, res.apparent_contact_area_m2 * 1e4
        )
        return res.apparent_contact_area_m2 / target - 1.0

    height = scipy.optimize.brentq(misfit, lo, hi, xtol=1e-7, rtol=1e-6)
    return dataclasses.replace(base, pocket_height_m=height)


def measure(name: str, ski) -> CamberData:
    """The virtual device's readings of a beam ski on the measuring grid (seeded noise)."""
    loads_n = MEASURE_LOADS_KG * G_STANDARD
    cases_n, cases_m, gaps = measure_camber(
        ski, loads_n, MEASURE_POSITIONS_M, noise_m=NOISE_M, rng=np.random.default_rng(SEEDS[name])
    )
    return CamberData(
        ski_id=name,
        positions_m=ski.positions_m,
        loads_n=cases_n,
        load_positions_m=cases_m,
        sides=["mean"] * cases_n.size,
        profiles_m=gaps,
    )


def remeasure(name: str, out_dir: Path) -> dict:
    """Measure the ski of an existing file again on the current grid; the ski is unchanged."""
    path = out_dir / f"{name}.h5"
    old = read_ski(path)
    if old.beam is None or old.beam_design is None:
        raise SystemExit(f"{path} holds no beam model to measure")
    with h5py.File(path, "r") as fh:
        parameters = json.loads(fh.attrs["parameters_json"])
    record = SkiRecord(
        measure(name, old.beam), old.outline, old.metadata, old.beam, old.beam_design
    )
    write_ski(path, record, parameters=parameters)
    return {"cases": int(record.measurements.loads_n.size), "beam": "unchanged"}


def add_unloaded(name: str, out_dir: Path) -> dict:
    """Append the unloaded profile (load 0 N, x_F 0) to the measurements of an existing file;
    the loaded cases, the network and the ski are kept bit for bit, the identification dropped."""
    path = out_dir / f"{name}.h5"
    old = read_ski(path)
    if old.beam is None:
        raise SystemExit(f"{path} holds no beam model to measure")
    m = old.measurements
    if np.any(m.loads_n == 0):
        return {"cases": int(m.loads_n.size), "unloaded": "already measured"}
    with h5py.File(path, "r") as fh:
        parameters = json.loads(fh.attrs["parameters_json"])
    gaps = measure_unloaded(
        old.beam, noise_m=NOISE_M, rng=np.random.default_rng(UNLOADED_SEEDS[name])
    )
    data = CamberData(
        ski_id=m.ski_id,
        positions_m=m.positions_m,
        loads_n=np.append(m.loads_n, 0.0),
        load_positions_m=np.append(m.load_positions_m, 0.0),
        sides=[*m.sides, "mean"],
        profiles_m=np.vstack([m.profiles_m, gaps[None, :]]),
    )
    metadata = {**old.metadata, "unloaded_seed": UNLOADED_SEEDS[name]}
    record = SkiRecord(data, old.outline, metadata, old.beam, old.beam_design, network=old.network)
    write_ski(path, record, parameters={**parameters, "unloaded_profile_added": True})
    return {"cases": int(data.loads_n.size), "unloaded": "added (identification dropped)"}


def build(name: str, out_dir: Path) -> dict:
    design = UNCALIBRATED[name] if name in UNCALIBRATED else calibrate(name)
    res = bem_for(design)
    ski = design.build()
    data = measure(name, ski)
    if name in UNCALIBRATED:  # shipped with its unloaded profile from the start (#26)
        unloaded = measure_unloaded(
            ski, noise_m=NOISE_M, rng=np.random.default_rng(UNLOADED_SEEDS[name])
        )
        data = CamberData(
            ski_id=data.ski_id,
            positions_m=data.positions_m,
            loads_n=np.append(data.loads_n, 0.0),
            load_positions_m=np.append(data.load_positions_m, 0.0),
            sides=[*data.sides, "mean"],
            profiles_m=np.vstack([data.profiles_m, unloaded[None, :]]),
        )
    outline = SkiOutline(
        length_m=design.tip_m - design.tail_m,
        balance_point_from_tail_m=-design.tail_m,
        positions_m=np.array([design.tail_m, design.tip_m]),
        width_m=np.array([WIDTH_M, WIDTH_M]),
    )
    summary = {
        "apparent_contact_area_cm2": res.apparent_contact_area_m2 * 1e4,
        "target_area_cm2": TARGETS[name] * 1e4 if name in TARGETS else None,
        "mean_apparent_pressure_kpa": res.mean_apparent_pressure_pa / 1e3,
        "rear_load_share": rear_share(res),
        "pixel_size_m": list(res.pixel_size_m),
        "zones": [(z.edge_start_m, z.edge_end_m, z.load_share) for z in res.zones],
    }
    design_dict = dataclasses.asdict(design)
    description = (
        f"synthetic classic ski {name} for a 60–80 kg skier (design beam, not calibrated)"
        if name in UNCALIBRATED
        else f"synthetic classic ski {name} (beam model calibrated to the papers)"
    )
    metadata = {
        "description": description,
        "calibration_json": json.dumps(summary),
        "noise_m": NOISE_M,
        "seed": SEEDS[name],
        **({"unloaded_seed": UNLOADED_SEEDS[name]} if name in UNCALIBRATED else {}),
    }
    record = SkiRecord(data, outline, metadata, ski, design_dict)
    write_ski(out_dir / f"{name}.h5", record, parameters={"design": design_dict, **summary})
    return summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out", type=Path, default=Path(__file__).resolve().parents[1] / "tables/skis"
    )
    parser.add_argument("--ski", choices=sorted({*DESIGNS, *UNCALIBRATED}), action="append")
    parser.add_argument(
        "--remeasure",
        action="store_true",
        help="keep the calibrated ski of the existing file, only measure it again",
    )
    parser.add_argument(
        "--add-unloaded",
        action="store_true",
        help="keep the existing file, append the unloaded (0 kg) profile to its measurements",
    )
    parser.add_argument("-v", "--verbose", action="store_true")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING)
    for name in args.ski or sorted({*DESIGNS, *UNCALIBRATED}):
        if args.add_unloaded:
            summary = add_unloaded(name, args.out)
        elif args.remeasure:
            summary = remeasure(name, args.out)
        else:
            summary = build(name, args.out)
        print(name, summary)
    return 0


if __name__ == "__main__":
    sys.exit(main())
