"""The camber network's band across snow moduli (issue #26 point 4): coverage per modulus of
rigid answers of skis served by their camber network, against their true beams.

The demo skis are served by their identified beams; here each is served by its camber network
instead (its record without the identification: the service's network fallback), and its
design beam is the truth. Cases: the network's held-out (test split) loads, ``calib`` 10 per ski
(seed 5) and ``test`` 10 others per ski (seed 6), each at 20, 200 and 2000 MPa. Per case the
band (:func:`app.service.band.answer_band`, default preset, grind-1, porosity 0.5) is built for
every candidate of ``--scales`` (``band_calibration.NETWORK_SIGMA_SCALE``), and the truth is
the design beam's loaded profile solved on the fine preset (1 mm × 16); the same truth on the
answer's own grid (``error_same_grid``) isolates the camber model's error. Reported per set,
scale, modulus and quantity: the share of truths inside the band, the mean half-width and the
RMS error; and whether every case more than 3 % off in apparent area is inside its band or
carries a warning (the flat-base and wide-band warnings of the answer).

Usage::

    python scripts/network_band_study.py --out docs/studies/network-band.json

About 3–5 min on a loaded 2-core machine (3 min 24 s – 4 min 48 s measured). With
``--own-ski`` the rows' set is ``own``, the ski's measurement grid and ``refused`` where its
network failed the job's accuracy check (the service never serves it).
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
from skisnow.app.service import band, band_calibration, band_sampling  # noqa: E402
from skisnow.solvers.beam import solve_beam_contact  # noqa: E402
from skisnow.solvers.elastic import effective_modulus  # noqa: E402
from skisnow.solvers.macro import extrude_profile, solve_macro  # noqa: E402
from skisnow.solvers.multiscale import multiscale  # noqa: E402

E_SNOW_MPA = (20.0, 200.0, 2000.0)
SEEDS = {"calib": 5, "test": 6}
PER_SKI = 10


def _solve(rec, table, x, g, pre, f, xf, e):
    gm = extrude_profile(
        x,
        g,
        rec.outline.width_m,
        width_positions_m=rec.outline.positions_m,
        pixel_along_m=pre.pixel_along_m,
        pixels_across=pre.pixels_across,
    )
    m = solve_macro(gm, f, xf, e)
    return gm, m, multiscale(m, table, 0.5, e)


def network_record(rec):
    """The record as the service serves a ski whose beam was not identified."""
    return replace(rec, identified=None, cache={})


def pick_cases(rec):
    """Disjoint held-out cases per set: {set: [(F [N], x_F [m])]}."""
    f = np.asarray(rec.network["split_test_loads_n"], dtype=float)
    x = np.asarray(rec.network["split_test_load_positions_m"], dtype=float)
    order = np.random.default_rng(SEEDS["calib"]).permutation(f.size)
    rest = np.random.default_rng(SEEDS["test"]).permutation(order[PER_SKI:])
    return {
        "calib": [(float(f[i]), float(x[i])) for i in order[:PER_SKI]],
        "test": [(float(f[i]), float(x[i])) for i in rest[:PER_SKI]],
    }


def case_rows(name, rec, table, f, xf, e_mpa, scales, truth_beam=None):
    """One case's rows (one per scale); the truth is ``truth_beam`` (default: the record's
    design beam)."""
    pre = PRESETS["default"]
    e = effective_modulus(e_mpa * 1e6, 700e6, 0.3)
    ski = service.Ski(name, REPO, "", rec)
    x, g = service.loaded_profile(ski, f, xf)
    gm, m, ms = _solve(rec, table, x, g, pre, f, xf, e)
    truth = solve_beam_contact(rec.beam if truth_beam is None else truth_beam, f, xf)
    _, _, mst = _solve(rec, table, truth.positions_m, truth.gap_m, PRESETS["fine"], f, xf, e)
    got, want = band_sampling._quantities(m, ms), band_sampling._quantities(None, mst)
    # the same truth on the answer's own grid: the camber model's error alone
    _, _, mss = _solve(rec, table, truth.positions_m, truth.gap_m, pre, f, xf, e)
    same = band_sampling._quantities(None, mss)
    rows = []
    for s in scales:
        band_calibration.NETWORK_SIGMA_SCALE = s
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
        warned = b.flat_base is not None or any(
            w > band.WIDE_BAND for w in b.widths.values() if np.isfinite(w)
        )
        rows.append(
            {
                "ski": name,
                "load_n": f,
                "load_position_m": xf,
                "e_snow_mpa": e_mpa,
                "scale": s,
                "error": {q: got[q] / want[q] - 1 for q in got},
                "error_same_grid": {q: got[q] / same[q] - 1 for q in got},
                "width": b.widths,
                "width_above": {q: b.width_above(q) for q in b.widths},
                "components": b.components,
                "flat_base": b.flat_base,
                "warned": warned,
            }
        )
    return rows


def own_ski_cases(study: Path, limit: int | None = None):
    """The skis of an own-ski study (``scripts/own_ski_study.py`` output) whose kept ski file
    exists, each served by its network: [(name, network record, true beam, [(F [N], x_F [m])])],
    the cases the study's held-out cases (never seen by the network's training nor by the
    identification); read by ``metric_band_study.study_skis``."""
    from skisnow.solvers.beam import G_STANDARD

    sys.path.insert(0, str(REPO / "scripts"))
    from metric_band_study import study_skis

    return [
        (
            name,
            served.record,
            truth.record.beam,
            [(float(kg) * G_STANDARD, float(mm) * 1e-3) for kg, mm in cases],
        )
        for name, served, truth, cases in study_skis(study, limit, network=True)
    ]


def own_set(name: str, record) -> str:
    """The set of an own ski's rows: ``own``, its measurement grid when the name gives it, and
    whether its network failed the job's accuracy check (then the service never serves it:
    its rows say what a refused network would have answered)."""
    from skisnow.app.settings import Settings

    grid = next((g for g in ("dense", "coarse") if f"-{g}-" in name), "")
    rmse_m = (record.network or {}).get("attrs", {}).get("metric_test_rmse_band_m", 0.0)
    refused = " refused" if rmse_m * 1e6 > Settings().ski_max_test_rmse_um else ""
    return " ".join(p for p in ("own", grid) if p) + refused


def _above(row, q):
    """A row's half-width above its answer (rows written before the grid part was one-sided:
    the one width)."""
    return row.get("width_above", row["width"]).get(q, row["width"][q])


def summarise(rows, scales):
    out = {}
    for st in sorted({r["set"] for r in rows}):
        for s in scales:
            for e in E_SNOW_MPA:
                sel = [
                    r for r in rows if r["set"] == st and r["scale"] == s and r["e_snow_mpa"] == e
                ]
                per = {}
                for q in band.QUANTITIES:
                    sel_q = [r for r in sel if np.isfinite(r["width"].get(q, np.nan))]
                    if not sel_q:
                        continue
                    err, same, below, above = (
                        np.array([r["error"][q] for r in sel_q]),
                        np.array([r["error_same_grid"][q] for r in sel_q]),
                        np.array([r["width"][q] for r in sel_q]),
                        np.array([_above(r, q) for r in sel_q]),
                    )
                    reach = band.reach_over_side(err, below, above)
                    per[q] = {
                        "inside": float(np.mean(band.inside_interval(err, below, above))),
                        "n": len(sel_q),
                        "mean_half_width": float(np.mean((below + above) / 2)),
                        "rms_error": float(np.sqrt(np.mean(err**2))),
                        "inside_same_grid_truth": float(
                            np.mean(band.inside_interval(same, below, above))
                        ),
                        "farthest_over_side": float(reach.max()),
                        "q99_over_side": float(np.quantile(reach, 0.99)),
                    }
                off = [
                    r
                    for r in sel
                    if abs(r["error"]["apparent_contact_area"]) > 0.03
                    and not band.inside_interval(
                        r["error"]["apparent_contact_area"],
                        r["width"]["apparent_contact_area"],
                        _above(r, "apparent_contact_area"),
                    )
                    and not r["warned"]
                ]
                per["off_3pct_outside_without_warning"] = len(off)
                out[f"{st} scale {s:g} {e:g} MPa"] = per
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--scales", type=float, nargs="+", default=[1.0, 1.5, 2.0, 3.0])
    ap.add_argument(
        "--own-ski",
        type=Path,
        help="instead of the demo skis: the skis of this own-ski study output (its kept ski "
        "files, served by their networks; truth their designs' beams; cases the study's "
        "held-out cases, set 'own')",
    )
    ap.add_argument("--cases", type=int, help="at most this many cases per own ski")
    ap.add_argument(
        "--no-rows", action="store_true", help="write the summary only (no per-case rows)"
    )
    args = ap.parse_args(argv)
    t0 = time.time()
    cat = service.load_catalogue(REPO / "tables")
    table = cat.grind("grind-1").table
    rows = []
    if args.own_ski is not None:
        for name, rec, truth, cases in own_ski_cases(args.own_ski, args.cases):
            for f, xf in cases:
                for e in E_SNOW_MPA:
                    for r in case_rows(name, rec, table, f, xf, e, args.scales, truth):
                        rows.append(dict(r, set=own_set(name, rec)))
            print(name, f"{time.time() - t0:.0f} s", file=sys.stderr)
    for name in () if args.own_ski is not None else ("ski-a", "ski-b"):
        rec = network_record(cat.ski(name).record)
        for st, cases in pick_cases(rec).items():
            for f, xf in cases:
                for e in E_SNOW_MPA:
                    for r in case_rows(name, rec, table, f, xf, e, args.scales):
                        rows.append(dict(r, set=st))
        print(name, f"{time.time() - t0:.0f} s", file=sys.stderr)
    summary = summarise(rows, args.scales)
    out = {
        "command": "python scripts/network_band_study.py " + " ".join(sys.argv[1:] or argv or []),
        "seconds": time.time() - t0,
        "summary": summary,
        "rows": [] if args.no_rows else rows,
    }
    args.out.write_text(json.dumps(out, indent=1, default=float))
    for k, v in summary.items():
        a = v.get("apparent_contact_area", {})
        print(
            k,
            f"area inside {a.get('inside', float('nan')):.2f} "
            f"w/rms {a.get('mean_half_width', 0) / max(a.get('rms_error', 1e-12), 1e-12):.2f}",
            "all q inside",
            " ".join(f"{q[:8]} {v[q]['inside']:.2f}" for q in band.QUANTITIES if q in v),
            "off-unwarned",
            v["off_3pct_outside_without_warning"],
        )


if __name__ == "__main__":
    main()
