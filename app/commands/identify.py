"""``skisnow identify-ski``: identify a ski's beam (EI(X), c(X)) from its camber measurements.

Runs :func:`solvers.identify.identify_beam` on the measured cases of a stored ski (or a neutral
camber CSV), holding out a seeded fraction of the cases, and reports the misfit per case (it
should come down to the device noise), EI(X) with its 90 % band, and the held-out errors: against
the held-out measurements, and, for a ski that stores its design beam (the demo skis), against
that beam's noise-free profiles where H* < 0.2 mm. ``--out`` writes the report as JSON
(atomically, with provenance). ``--store`` stores the identification in the ski file, with each
held-out case's error (what ``GET /v1/skis/{name}`` and the ski's page show);
``--add-held-out-errors`` adds those errors to an identification stored before they were
(predicted from the stored beam, no re-identification, said in their provenance).

Left/right profiles of one case are averaged into one profile (said in the report); the
measurements themselves are never changed.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from skisnow.app.service.identification import identify_report
from skisnow.app.service.profiles import HELD_OUT_ERRORS, add_held_out_errors, identification_group
from skisnow.app.storage.common import atomic_path, provenance
from skisnow.app.storage.skis import (
    SHIPPED_SKI_DIR,
    SKI_MANIFEST,
    read_camber_csv,
    read_ski,
    replace_ski_group,
    write_ski_manifest,
)
from skisnow.solvers.errors import InputError
from tqdm import tqdm


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "identify-ski",
        help="identify a ski's beam (EI, camber) from its camber measurements",
        description=__doc__.splitlines()[0],
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--ski", metavar="NAME", help="stored ski (tables/skis/NAME.h5) or a path")
    src.add_argument("--csv", metavar="CSV", help="neutral camber CSV (docs/macro.md)")
    p.add_argument(
        "--holdout", type=float, default=0.2, help="fraction of cases held out [-] (0: none)"
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the held-out draw")
    p.add_argument("--out", type=Path, help="write the report as JSON here")
    p.add_argument(
        "--store",
        action="store_true",
        help="with --ski: store the identification (with its held-out check and the loaded "
        "profile's spread) in the ski file; a passed identification becomes the ski's profile "
        "model and beam (docs/camber-identification.md)",
    )
    p.add_argument(
        "--add-held-out-errors",
        action="store_true",
        help="with --ski: do not identify; add each held-out case's error, predicted from the "
        "stored beam, to the identification stored in the ski file (files stored before these "
        "errors were; the service otherwise computes them on reading)",
    )
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=run)


def _say_reading_notes(data) -> None:
    """On stderr: how the CSV was read where not the neutral format's way, if at all (a
    device's lines before the header, columns named another way, positions written rounded,
    samples unmeasured: :func:`app.storage.skis.reading_notes`)."""
    from skisnow.app.storage.skis import reading_notes

    for note in reading_notes(data):
        print(f"note: {note}", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    if args.ski:
        path = Path(args.ski)
        if not path.suffix:
            path = SHIPPED_SKI_DIR / f"{args.ski}.h5"
        record = read_ski(path)
        data, design = record.measurements, record.beam
    else:
        data, design = read_camber_csv(args.csv), None
        _say_reading_notes(data)
    if args.store and not args.ski:
        raise InputError("--store needs --ski (a stored ski file)")
    if args.add_held_out_errors:
        if not args.ski or args.store:
            raise InputError("--add-held-out-errors needs --ski and does not identify (no --store)")
        return run_add_held_out_errors(path, record, vars_of(args), as_json=args.json)
    keep: dict = {}
    # a progress bar on stderr (the identification takes minutes; shown on a terminal only)
    with tqdm(total=100, desc="identify", unit="%", disable=None, leave=False) as bar:

        def progress(fraction: float, message: str) -> None:
            bar.n = round(100 * min(max(fraction, 0.0), 1.0))
            bar.set_postfix_str(message[:60], refresh=True)

        rep = identify_report(data, design, args.holdout, args.seed, keep=keep, callback=progress)
    if args.store:
        store_identification(path, record, keep, vars_of(args))
        rep["stored_in"] = str(path)
    if args.out:
        with atomic_path(args.out) as tmp:
            Path(tmp).write_text(
                json.dumps({"report": rep, "provenance": provenance(vars_of(args))}, indent=1)
            )
    if args.json:
        print(json.dumps(rep))
        return 0 if rep["identified"] else 1
    print(
        f"ski {rep['ski_id']}: {rep['cases']} cases ({rep['sides']}), "
        f"{rep['held_out_cases']} held out"
    )
    print(f"  identified        {rep['identified']} {rep['reason']}")
    print(f"  device noise      {rep['noise_um']:.2f} µm (from the data)")
    print(
        f"  misfit            {rep['misfit_um']:.2f} µm RMS; per case median "
        f"{rep['case_misfit_um']['median']:.2f}, max {rep['case_misfit_um']['max']:.2f} µm"
    )
    for key, label in (
        ("held_out_vs_measured_rms_um", "held-out vs measured"),
        ("held_out_vs_design_beam_rms_um", "held-out vs design beam (H* < 0.2 mm)"),
    ):
        if key in rep:
            print(f"  {label:38s} {rep[key]:.2f} µm RMS")
    print("  EI(X) [N·m²] with 90 % band:")
    for s in rep["stiffness"][::2]:
        lo, hi = s["band_90_nm2"]
        print(f"    {s['position_mm']:7.0f} mm  {s['ei_nm2']:8.1f}  [{lo:8.1f} … {hi:8.1f}]")
    print(f"  time {rep['time_s']:.1f} s, {rep['iterations']} Gauss–Newton steps")
    return 0 if rep["identified"] else 1


def store_identification(path: Path, record, keep: dict, params: dict) -> None:
    """Write the identification into the ski file at ``path`` (atomic; the folder's manifest,
    when there is one, gets the new sha256)."""
    group = identification_group(
        keep["ident"],
        keep["check"],
        keep["sides"],
        keep["loads_n"],
        keep["positions_m"],
        params,
        keep["profiles_m"],
        nodes_m=record.measurements.positions_m,
    )
    replace_ski_group(path, "identified", group)
    record.identified = group
    if (path.parent / SKI_MANIFEST).is_file():
        write_ski_manifest(path.parent)


def run_add_held_out_errors(path: Path, record, params: dict, *, as_json: bool) -> int:
    """Add each held-out case's error to the identification stored in the ski file at ``path``
    (atomic; the manifest, when there is one, gets the new sha256); prints what was added."""
    t0 = time.perf_counter()
    group = add_held_out_errors(record.identified, record.measurements, params)
    elapsed = time.perf_counter() - t0
    replace_ski_group(path, "identified", group)
    record.identified = group
    if (path.parent / SKI_MANIFEST).is_file():
        write_ski_manifest(path.parent)
    error = np.asarray(group[HELD_OUT_ERRORS]["rms_error_m"])
    rep = {
        "ski_id": record.measurements.ski_id,
        "stored_in": str(path),
        "held_out_cases": int(error.size),
        "held_out_rms_um": float(np.sqrt(np.mean(error**2))) * 1e6,
        "held_out_max_um": float(error.max()) * 1e6,
        "time_s": elapsed,
    }
    if as_json:
        print(json.dumps(rep))
    else:
        print(
            f"ski {rep['ski_id']}: {rep['held_out_cases']} held-out errors added to the stored "
            f"identification in {path} (RMS {rep['held_out_rms_um']:.3f} µm, max "
            f"{rep['held_out_max_um']:.3f} µm; {elapsed:.1f} s)"
        )
    return 0


def vars_of(args: argparse.Namespace) -> dict:
    return {k: str(v) for k, v in vars(args).items() if k != "func"}
