"""How well the flex sheet's band covers the identified beam's actual error (docs/flex.md).

A ski answered by the beam identified from its noisy camber data is compared with the sheet of
its true beam: for body weights over the ski's range, the sheet of the identified beam (with its
band, :mod:`app.service.flex`) against the sheet of the true beam; per quantity the share of
cases where |identified − true| ≤ band is the band's coverage (target 90 %), and the mean
half-width ÷ the RMS error its width.

Two populations:

- the demo skis (``--skis``): their true (design) beam is stored with them;
- with ``--own-ski-work``: the skis of ``scripts/own_ski_study.py`` (its work folder's kept ski
  files ``skis/<design>-<grid>-d<draw>.h5``), their true beam the design's
  (:func:`solvers.ski_designs.get_design`: the study and validation designs and the seeded
  random designs ``random-<seed>``, built on 1 mm).

``--scales`` recomputes every band with the beam draws' deviations × each factor
(:data:`app.service.band_sampling.BEAM_SCALE`, the sheet's; default: the served one only).

Usage::

    PYTHONPATH=. python scripts/flex_band_check.py [--weights 30 50 70 90 110 130]
    PYTHONPATH=. python scripts/flex_band_check.py --own-ski-work <study work> \\
        --scales 2 4 8 16 --out docs/studies/flex-band.json
"""

from __future__ import annotations

import argparse
import json
import math
import re
from pathlib import Path

import numpy as np
from skisnow.app.service import flex, load_catalogue
from skisnow.app.service.catalogue import Catalogue, Ski
from skisnow.app.service.flex import sheet as sheet_module
from skisnow.app.storage import common
from skisnow.app.storage.common import tables_dir
from skisnow.app.storage.skis import read_ski
from skisnow.solvers.beam import G_STANDARD
from skisnow.solvers.errors import SkisnowError
from skisnow.solvers.flex import beam_profile, flex_sheet
from skisnow.solvers.ski_designs import get_design

SCHEMA = "skisnow.flex-band-check/1"
OWN_SKI_FILE = re.compile(r"^(?P<design>.+)-(?P<grid>dense|coarse)-d(?P<draw>\d+)$")


def own_skis(work: Path) -> list[tuple[str, Ski, object]]:
    """The own-ski study's kept ski files: (population, ski, true beam)."""
    out = []
    for path in sorted((work / "skis").glob("*.h5")):
        m = OWN_SKI_FILE.match(path.stem)
        if m is None:
            continue
        try:  # study, validation or seeded random designs
            design = get_design(m["design"])
        except SkisnowError:
            continue
        rec = read_ski(path)
        if rec.identified is None:
            continue
        ski = Ski(path.stem, path, "", rec)
        out.append((f"own-ski {m['grid']}", ski, design.build(1e-3)))
    return out


def case_errors(cat: Catalogue, ski: Ski, true_beam, weights) -> list[dict]:
    """Per body weight inside the ski's range and per sheet quantity: the identified beam's
    value, the true beam's and the band (NaNs and exact zeros left out)."""
    rows = []
    true_fn = beam_profile(true_beam)
    lo, hi = (v / G_STANDARD for v in ski.load_range_n)
    for w in weights:
        if not lo <= w <= hi:
            continue
        try:
            out = flex.compute_sheet(cat, flex.FlexRequest(ski.name, w))
            true = flex_sheet(
                true_fn, w * G_STANDARD, max_closing_load_n=ski.load_range_n[1]
            ).scalars()
        except SkisnowError:
            continue
        for k, v in out["nominal"].items():
            b, t = out["widths"].get(k, math.nan), true[k]
            if not (math.isfinite(v) and math.isfinite(t) and math.isfinite(b)):
                continue
            if v == t == 0:
                continue
            rows.append({"ski": ski.name, "weight_kg": w, "q": k, "value": v, "true": t, "band": b})
    return rows


def summarise(rows: list[dict]) -> dict:
    """Per quantity: cases, covered, coverage, mean half-width ÷ RMS error, largest error ÷
    band."""
    out = {}
    for q in sorted({r["q"] for r in rows}):
        sel = [r for r in rows if r["q"] == q]
        err = np.array([abs(r["value"] - r["true"]) for r in sel])
        band = np.array([r["band"] for r in sel])
        rms = float(np.sqrt(np.mean(err**2)))
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.where(band > 0, err / band, np.where(err > 0, np.inf, 0.0))
        out[q] = {
            "cases": len(sel),
            "covered": int(np.sum(err <= band)),
            "coverage": round(float(np.mean(err <= band)), 3),
            "half_width_over_rms": round(float(band.mean() / rms), 2) if rms > 0 else None,
            "max_error_over_band": round(float(np.max(ratio)), 2),
        }
    return out


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--weights", type=float, nargs="+", default=[30, 50, 70, 90, 110, 130])
    ap.add_argument("--skis", nargs="+", default=["ski-a", "ski-b"])
    ap.add_argument("--own-ski-work", type=Path, help="scripts/own_ski_study.py work folder")
    ap.add_argument("--scales", type=float, nargs="+", help="beam-draw factors to compare")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    cat = load_catalogue(tables_dir())
    skis = [("demo", cat.ski(n), cat.ski(n).record.beam) for n in args.skis]
    if args.own_ski_work:
        for pop, ski, beam in own_skis(args.own_ski_work):
            cat.skis[ski.name] = ski
            skis.append((pop, ski, beam))
    served = sheet_module.BEAM_SCALE
    scales = args.scales or [None]  # None: each ski's own (band_sampling.sheet_beam_scale)
    report: dict = {}
    try:
        for scale in scales:
            sheet_module.BEAM_SCALE = scale
            rows: dict[str, list[dict]] = {}
            for pop, ski, beam in skis:
                ski.record.cache.pop("flex_draws", None)  # drawn again at this scale
                rows.setdefault(pop, []).extend(case_errors(cat, ski, beam, args.weights))
            key = "served" if scale is None else f"{scale:g}"
            report[key] = {pop: summarise(r) for pop, r in rows.items()}
    finally:
        sheet_module.BEAM_SCALE = served
    doc = {
        "schema": SCHEMA,
        "weights_kg": args.weights,
        "skis": [s.name for _, s, _ in skis],
        "served_scale": "each ski's own (band_sampling.sheet_beam_scale)"
        if served is None
        else served,
        "per_scale": report,
    }
    print(json.dumps(doc, indent=1))
    if args.out:
        body = {k: v for k, v in doc.items() if k != "schema"}
        common.write_study_json(args.out, SCHEMA, vars(args), body)
    return report


if __name__ == "__main__":
    main()
