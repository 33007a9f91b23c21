"""What ``auto`` leaves out when a ski has no beam (issue #26 point 4): the rigid shape
against the bending ski on the design catalogue, per snow modulus.

For every beam of the catalogue (``solvers.ski_designs.STUDY_DESIGNS``, ``solvers.beam.
OTHER_DESIGNS``, on the demo ski-a's outline and measured range) and the demo skis' own
beams, at each load of ``LOADS`` and each modulus of ``E_SNOW_MPA``, the service answers
with ``ski_model`` rigid and flexible (design beam, default preset, grind-1, porosity 0.5, no
band). Recorded per case and quantity: the bending ski's value over the rigid one minus 1
(what an answer of the rigid shape misses). The summary per modulus and quantity is the 90th
percentile of its magnitude over the catalogue designs (``calib``: the eight designs) and the
coverage of that width on the demo skis (``test``), which the calibration did not use; beside
them, the coverage of the served width (:data:`app.service.band_calibration.
BENDING_IGNORED_WIDTH`) on each set. ``--randoms N`` adds ``random-<seed>`` designs (seeds
``--random-start`` …, :func:`solvers.ski_designs.random_design`) as a third set (``random``),
used by no calibration: designs nobody wrote by hand; ``--calib-randoms N`` adds random designs
(seeds ``--calib-random-start`` …) to the calibration. ``fitted_width``: the served width's rule
(the largest over the calibration, rounded up to 0.01).

Usage::

    python scripts/auto_without_beam_study.py --out docs/studies/auto-without-beam.json \
        --calib-randoms 24 --randoms 24

About 1 min on a loaded 2-core machine (44 s measured) without random designs, ~5 s each.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app import service  # noqa: E402
from skisnow.app.service.band import ANSWER_KEYS  # noqa: E402
from skisnow.app.service.band_calibration import (  # noqa: E402
    BENDING_IGNORED_E_SNOW_MPA,
    BENDING_IGNORED_WIDTH,
)
from skisnow.app.storage import common  # noqa: E402
from skisnow.solvers.beam import OTHER_DESIGNS  # noqa: E402
from skisnow.solvers.ski_designs import STUDY_DESIGNS, random_design  # noqa: E402

SCHEMA = "skisnow.auto-without-beam-study/1"
SETS = ("calib", "test", "random")

E_SNOW_MPA = BENDING_IGNORED_E_SNOW_MPA
#: (kg, mm): light to heavy, behind and at the balance point
LOADS = ((15.0, -100.0), (25.0, -200.0), (40.0, -160.0), (40.0, 0.0), (60.0, -150.0), (85.0, -50.0))


def cases_of(cat, name: str, ski) -> list[dict]:
    rows = []
    for kg, mm in LOADS:
        for e in E_SNOW_MPA:
            vals = {}
            try:
                for model in ("rigid", "flexible"):
                    a = service.contact(
                        cat,
                        service.ContactInputs(name, "grind-1", kg, mm, e, 0.5, ski_model=model),
                        error_band=False,
                    )
                    vals[model] = {q: a[s][k] for q, (s, k) in ANSWER_KEYS.items()}
            except Exception as exc:  # a failing case is recorded, the study goes on
                rows.append(
                    {"ski": name, "load_kg": kg, "position_mm": mm, "e_mpa": e, "error": repr(exc)}
                )
                continue
            miss = {q: vals["flexible"][q] / vals["rigid"][q] - 1 for q in ANSWER_KEYS}
            rows.append(
                {
                    "ski": name,
                    "load_kg": kg,
                    "position_mm": mm,
                    "e_mpa": e,
                    "values": vals,
                    "flexible_over_rigid_minus_1": miss,
                }
            )
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--randoms", type=int, default=0, help="random designs, a third set")
    ap.add_argument("--random-start", type=int, default=800, help="their first seed")
    ap.add_argument(
        "--calib-randoms", type=int, default=0, help="random designs added to the calibration"
    )
    ap.add_argument("--calib-random-start", type=int, default=700, help="their first seed")
    args = ap.parse_args(argv)
    t0 = time.time()
    cat = service.load_catalogue(REPO / "tables")
    base = cat.ski("ski-a")
    rows = []
    designs = {name: (d, "calib") for name, d in {**STUDY_DESIGNS, **OTHER_DESIGNS}.items()}
    for seed in range(args.calib_random_start, args.calib_random_start + args.calib_randoms):
        designs[f"random-{seed}"] = (random_design(seed)[1], "calib")
    for seed in range(args.random_start, args.random_start + args.randoms):
        if f"random-{seed}" in designs:
            ap.error(f"random-{seed} is in the calibration and the random set")
        designs[f"random-{seed}"] = (random_design(seed)[1], "random")
    for name, (design, set_name) in designs.items():
        rec = replace(base.record, beam=design.build(1e-3), network=None, identified=None, cache={})
        ski = service.Ski(name, base.path, "", rec)
        c = replace(cat, skis={**cat.skis, name: ski})
        rows += [dict(r, set=set_name) for r in cases_of(c, name, ski)]
        print(name, f"{time.time() - t0:.0f} s", file=sys.stderr)
    for name in ("ski-a", "ski-b"):
        ski = cat.ski(name)
        rec = replace(ski.record, identified=None, cache={})  # its design beam answers
        c = replace(cat, skis={**cat.skis, name: replace(ski, record=rec, _flexible={})})
        rows += [dict(r, set="test") for r in cases_of(c, name, c.skis[name])]
        print(name, f"{time.time() - t0:.0f} s", file=sys.stderr)
    summary = {}
    for q in ANSWER_KEYS:
        per = {}
        for e, served in zip(E_SNOW_MPA, BENDING_IGNORED_WIDTH[q], strict=True):
            miss = {
                name: np.array(
                    [
                        abs(r["flexible_over_rigid_minus_1"][q])
                        for r in rows
                        if r.get("set") == name and r["e_mpa"] == e and "error" not in r
                    ]
                )
                for name in SETS
            }
            cal, tst = miss["calib"], miss["test"]
            w = float(np.percentile(cal, 90))
            per[str(e)] = {
                "p90_calib": w,
                "median_calib": float(np.median(cal)),
                "max_calib": float(np.max(cal)),
                # the served width's rule: the largest over the calibration, rounded up
                "fitted_width": float(np.ceil(np.max(cal) * 100 - 1e-9) / 100),
                "n_calib": len(cal),
                "test_inside": float(np.mean(tst <= w)),
                "n_test": len(tst),
                "median_test": float(np.median(tst)),
                "served_width": served,
                # the served width's coverage per set (None: no case in the set)
                "served_inside": {
                    name: float(np.mean(m <= served)) if m.size else None
                    for name, m in miss.items()
                },
                "max_per_set": {
                    name: float(m.max()) if m.size else None for name, m in miss.items()
                },
            }
        summary[q] = per
    body = {"seconds": time.time() - t0, "summary": summary, "rows": rows}
    params = {
        "randoms": args.randoms,
        "random_start": args.random_start,
        "calib_randoms": args.calib_randoms,
        "calib_random_start": args.calib_random_start,
        "loads": LOADS,
    }
    common.write_study_json(args.out, SCHEMA, params, body)
    print(json.dumps(summary["apparent_contact_area"], indent=1))


if __name__ == "__main__":
    main()
