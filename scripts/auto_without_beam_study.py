"""What ``auto`` leaves out when a ski has no beam (issue #26 point 4): the rigid shape
against the bending ski on the design catalogue, per snow modulus.

For every beam of the catalogue (``solvers.ski_designs.STUDY_DESIGNS``, ``solvers.beam.
OTHER_DESIGNS``, on the demo ski-a's outline and measured range) and the demo skis' own
beams, at each load of ``LOADS`` and each modulus of ``E_SNOW_MPA``, the service answers
with ``ski_model`` rigid and flexible (design beam, default preset, grind-1, porosity 0.5, no
band). Recorded per case and quantity: the bending ski's value over the rigid one minus 1
(what an answer of the rigid shape misses). The summary per modulus and quantity is the 90th
percentile of its magnitude over the catalogue designs (``calib``: the eight designs) and the
coverage of that width on the demo skis (``test``), which the calibration did not use.

Usage::

    python scripts/auto_without_beam_study.py --out docs/studies/auto-without-beam.json

About 1 min on a loaded 2-core machine (44 s measured).
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
from skisnow.solvers.beam import OTHER_DESIGNS  # noqa: E402
from skisnow.solvers.ski_designs import STUDY_DESIGNS  # noqa: E402

E_SNOW_MPA = (2.0, 5.0, 20.0, 50.0, 200.0, 500.0, 2000.0)
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
    args = ap.parse_args(argv)
    t0 = time.time()
    cat = service.load_catalogue(REPO / "tables")
    base = cat.ski("ski-a")
    rows = []
    designs = {**STUDY_DESIGNS, **OTHER_DESIGNS}
    for name, design in designs.items():
        rec = replace(base.record, beam=design.build(1e-3), network=None, identified=None, cache={})
        ski = service.Ski(name, base.path, "", rec)
        c = replace(cat, skis={**cat.skis, name: ski})
        rows += [dict(r, set="calib") for r in cases_of(c, name, ski)]
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
        for e in E_SNOW_MPA:
            cal = [
                abs(r["flexible_over_rigid_minus_1"][q])
                for r in rows
                if r.get("set") == "calib" and r["e_mpa"] == e and "error" not in r
            ]
            tst = [
                abs(r["flexible_over_rigid_minus_1"][q])
                for r in rows
                if r.get("set") == "test" and r["e_mpa"] == e and "error" not in r
            ]
            w = float(np.percentile(cal, 90))
            per[str(e)] = {
                "p90_calib": w,
                "median_calib": float(np.median(cal)),
                "max_calib": float(np.max(cal)),
                "n_calib": len(cal),
                "test_inside": float(np.mean(np.array(tst) <= w)),
                "n_test": len(tst),
                "median_test": float(np.median(tst)),
            }
        summary[q] = per
    out = {
        "command": "python scripts/auto_without_beam_study.py --out " + str(args.out),
        "seconds": time.time() - t0,
        "summary": summary,
        "rows": rows,
    }
    args.out.write_text(json.dumps(out, indent=1, default=float))
    print(json.dumps(summary["apparent_contact_area"], indent=1))


if __name__ == "__main__":
    main()
