"""Where the error band's width comes from, case by case (issue #12 point 4, docs/limits.md
"Error band").

For each case (ski, load F at x_F, snow modulus) the answer is solved as the service does
(rigid model, profile from the ski's profile model, default preset) and again

- on the grid twice as coarse (``c2``: the per-answer grid estimate of the band) and four
  times as coarse (``c4``: a third level for an observed order of convergence);
- on the fine grid (1 mm × 16) with the *served* profile (``fine``): its difference to the
  answer is the answer's own grid error;
- on the fine grid with the *true* profile (``truth``: the ski's design beam, no noise);
- on the reference grid of ``skisnow bench accuracy`` (0.5 mm × 64) with the true profile
  (``reference``), for every case of ``test`` and every third of ``calib``
  (``--reference-every``). The fine grid's own error has the same sign as the default grid's
  and about half its size, so ``reference`` is the truth the band is calibrated against.

Per quantity it records the five values, the band's components (camber model, table
interpolation) and whether the minimum separation is unresolved. Two sets of cases:

``test``
    the calibration test's own cases (tests/service/test_band.py): the camber network's test-split
    loads
    of both demo skis (8 per ski, seed 0) at 20, 100 and 500 MPa;
``calib``
    cases the test does not use: other held-out loads of the demo skis (the identification's
    held-out cases, 8 per ski not in the test's, seed 1) at 10, 50, 200 and 1000 MPa, and two
    beam skis of other designs (``tests/solvers/test_identify.py``'s 'stiff' and 'soft', answered by
    their design beam, which is exact: their error is the grid's alone) at 12 loads each
    (seed 2) and the same four moduli.

Usage::

    python scripts/band_calibration_study.py --out /tmp/band_study.json

It writes ``{"schema", "provenance", "rows"}`` (docs/studies/band-calibration-rows.json is a
run with ``--reference-every 1``).

About 10 min (45 min with the reference grid) on a loaded 2-core machine.
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
from skisnow.app.presets import PRESETS  # noqa: E402
from skisnow.app.service import (  # noqa: E402
    band,
    band_sampling,
)
from skisnow.app.storage import common  # noqa: E402
from skisnow.app.storage.skis import read_ski  # noqa: E402
from skisnow.app.storage.tables import read_table  # noqa: E402
from skisnow.solvers.beam import OTHER_DESIGNS, solve_beam_contact  # noqa: E402
from skisnow.solvers.elastic import effective_modulus  # noqa: E402
from skisnow.solvers.macro import extrude_profile, solve_macro  # noqa: E402
from skisnow.solvers.multiscale import multiscale  # noqa: E402

TABLES = REPO / "tables"
#: the two designs unlike the demo skis (also used by tests/solvers/test_identify.py)
DESIGNS = OTHER_DESIGNS


def _grid(pixel_along_m, pixels_across):
    return replace(PRESETS["default"], pixel_along_m=pixel_along_m, pixels_across=pixels_across)


def _solve(rec, table, x, g, p, f, xf, e):
    gm = extrude_profile(
        x,
        g,
        rec.outline.width_m,
        width_positions_m=rec.outline.positions_m,
        pixel_along_m=p.pixel_along_m,
        pixels_across=p.pixels_across,
    )
    m = solve_macro(gm, f, xf, e)
    return gm, m, multiscale(m, table, 0.5, e)


REFERENCE_GRID = (0.5e-3, 64)


def case_row(name, rec, table, f, xf, e_mpa, truth_beam, reference=False):
    """Everything about one answer (see the module docstring)."""
    pre, fine = PRESETS["default"], PRESETS["fine"]
    c2 = _grid(*band_sampling.coarse_grid(pre))
    c4 = _grid(4 * pre.pixel_along_m, max(pre.pixels_across // 4, 2))
    e = effective_modulus(e_mpa * 1e6, 700e6, 0.3)
    ski = service.Ski(name, TABLES, "", rec)
    x, g = service.loaded_profile(ski, f, xf)
    gm, m, ms = _solve(rec, table, x, g, pre, f, xf, e)
    t0 = time.perf_counter()
    b = band.answer_band(
        record=rec,
        positions_m=x,
        gap_m=g,
        preset=pre,
        macro=m,
        ms=ms,
        table=table,
        porosity=0.5,
        e_eff=e,
        ski_model_used="rigid",
        beam_is_design=False,
        min_separation_unresolved=band.min_separation_unresolved(gm, m, ms),
    )
    t_band = time.perf_counter() - t0
    vals = {"default": band_sampling._quantities(m, ms)}
    for key, p in (("c2", c2), ("c4", c4), ("fine", fine)):
        vals[key] = band_sampling._quantities(*_solve(rec, table, x, g, p, f, xf, e)[1:])
    truth = solve_beam_contact(truth_beam, f, xf)
    vals["truth"] = band_sampling._quantities(
        *_solve(rec, table, truth.positions_m, truth.gap_m, fine, f, xf, e)[1:]
    )
    if reference:
        ref = _grid(*REFERENCE_GRID)
        vals["reference"] = band_sampling._quantities(
            *_solve(rec, table, truth.positions_m, truth.gap_m, ref, f, xf, e)[1:]
        )
    return {
        "ski": name,
        "load_n": f,
        "load_position_m": xf,
        "e_snow_mpa": e_mpa,
        "values": vals,
        "components": b.components,
        # the factors the grid part was served with (per quantity; one not named: 1)
        "grid_factors": b.grid_factors,
        "widths": b.widths,
        "band_time_s": t_band,
        "zones": len(ms.zones),
        "zone_lengths_mm": [1e3 * (z.end_m - z.start_m) for z in m.zones],
    }


#: snow moduli of the ``calib`` set's cases [MPa] (``--calib-moduli``)
CALIB_MODULI_MPA = (10.0, 50.0, 200.0, 1000.0)


def demo_cases(set_name, calib_moduli=CALIB_MODULI_MPA):
    out = []
    for name in ("ski-a", "ski-b"):
        rec = read_ski(TABLES / "skis" / f"{name}.h5")
        f_t = np.asarray(rec.network["split_test_loads_n"])
        x_t = np.asarray(rec.network["split_test_load_positions_m"])
        pick = np.random.default_rng(0).choice(f_t.size, 8, replace=False)
        if set_name == "test":
            for i in pick:
                for e in (20.0, 100.0, 500.0):
                    out.append((name, rec, float(f_t[i]), float(x_t[i]), e, rec.beam))
            continue
        idx = np.asarray(rec.identified["held_out_index"], dtype=int)
        mf, mx = rec.measurements.loads_n[idx], rec.measurements.load_positions_m[idx]
        used = {(round(float(f_t[i]), 6), round(float(x_t[i]), 6)) for i in pick}
        keep = [k for k in range(idx.size) if (round(mf[k], 6), round(mx[k], 6)) not in used]
        for k in np.random.default_rng(1).choice(keep, 8, replace=False):
            for e in calib_moduli:
                out.append((name, rec, float(mf[k]), float(mx[k]), e, rec.beam))
    return out


def design_cases(calib_moduli=CALIB_MODULI_MPA):
    base = read_ski(TABLES / "skis" / "ski-a.h5")
    out = []
    rng = np.random.default_rng(2)
    for name, design in DESIGNS.items():
        beam = design.build(1e-3)
        rec = replace(base, beam=beam, network=None, identified=None, cache={})
        f = rng.uniform(15, 85, 12) * 9.82
        xf = rng.uniform(-0.28, 0.08, 12)
        for k in range(12):
            for e in calib_moduli:
                out.append((name, rec, float(f[k]), float(xf[k]), e, beam))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--sets", nargs="+", default=["test", "calib"])
    ap.add_argument("--reference-every", type=int, default=3, help="calib cases per reference")
    ap.add_argument(
        "--calib-moduli",
        type=float,
        nargs="+",
        default=list(CALIB_MODULI_MPA),
        help="snow moduli of the calib set [MPa]",
    )
    args = ap.parse_args(argv)
    table = read_table(TABLES / "grind-1.h5")
    rows = []
    for s in args.sets:
        cases = (
            demo_cases("test")
            if s == "test"
            else demo_cases("calib", args.calib_moduli) + design_cases(args.calib_moduli)
        )
        for i, (name, rec, f, xf, e, truth) in enumerate(cases):
            reference = s == "test" or i % args.reference_every == 0
            try:
                r = case_row(name, rec, table, f, xf, e, truth, reference)
            except Exception as exc:  # a failing case is recorded, the study goes on
                r = {"ski": name, "load_n": f, "load_position_m": xf, "e_snow_mpa": e}
                r["error"] = repr(exc)
            r["set"] = s
            rows.append(r)
            print(s, name, f"{f:.0f} N {xf * 1e3:.0f} mm {e:g} MPa", file=sys.stderr)
    params = {
        "sets": args.sets,
        "reference_every": args.reference_every,
        "calib_moduli": args.calib_moduli,
    }
    common.write_study_json(
        args.out, "skisnow.band-calibration-rows/1", params, {"rows": rows}, indent=None
    )


def read_rows(path: Path) -> list[dict]:
    """The rows of a study file (a bare list, as the script wrote before it recorded
    provenance, or ``{"provenance": ..., "rows": [...]}``)."""
    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    return doc if isinstance(doc, list) else doc["rows"]


if __name__ == "__main__":
    main()
