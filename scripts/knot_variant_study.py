"""Would the identification find the rigid misses' beams with other stiffness knots? (issue #26;
docs/limits.md, "The rigid answers' unwarned misses"; the lead of
``scripts/rigid_miss_study.py``).

The rigid answers' unwarned misses come from identified profiles off by up to 1.8 µm where the
fit's covariance says 0.1–0.6 µm. This study identifies each ski again as its job did
(:func:`app.path_pool.identify_with_pool` of :func:`solvers.identify.identify_beam_checked`, the
same held-out cases) but with stiffness knots every ``--knot-spacing-m`` instead of
:data:`solvers.identify.DEFAULT_KNOT_SPACING_M`, from scratch, and asks per held-out case how far
that variant's loaded profile lies from the served one (``variant_shift_m``, RMS where the
served profile is within ``CONTACT_BAND_M`` of the flat) against the true error there
(``true_error_m``, from ``rigid-miss.json``) and their correlation along the ski. A variant
that fits as well and moves the misses towards the truth, but not the other cases, is an
alternative beam the band could carry (``beam_alternatives``).

Usage::

    python scripts/knot_variant_study.py --rigid-miss docs/studies/rigid-miss.json \\
        --study docs/studies/own-ski-pergrid.json docs/studies/own-ski-pergrid-random.json \\
        docs/studies/own-ski-pergrid-validation.json --only-misses \\
        --out docs/studies/knot-variant.json

About 1–3 min per ski on 2 cores (a full identification).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "scripts"))

from reidentify_study import identify_as_its_job  # noqa: E402
from skisnow.app.service.band_sampling import CONTACT_BAND_M  # noqa: E402
from skisnow.app.service.profiles import served_beam  # noqa: E402
from skisnow.app.storage import common  # noqa: E402
from skisnow.app.storage.skis import read_ski  # noqa: E402
from skisnow.solvers.beam import G_STANDARD, solve_beam_contact  # noqa: E402

SCHEMA = "skisnow.knot-variant-study/1"
KNOT_SPACING_M = 0.033


def shift(served, variant, load_n: float, load_position_m: float) -> tuple[float, np.ndarray]:
    """RMS [m] of the variant's loaded profile minus the served one where the served one is
    within ``CONTACT_BAND_M`` of the flat, and that difference (for a correlation)."""
    n = solve_beam_contact(served, load_n, load_position_m)
    v = solve_beam_contact(variant, load_n, load_position_m)
    near = n.gap_m < CONTACT_BAND_M
    d = np.interp(n.positions_m[near], v.positions_m, v.gap_m) - n.gap_m[near]
    return float(np.sqrt(np.mean(d**2))), d


def ski_rows(ski_file: str, cases: list[dict], misses: list[dict], knot_spacing_m: float) -> dict:
    """The variant of one ski and its shift at each of ``cases`` (rows of rigid-miss.json);
    ``misses``: the ski's unwarned misses (rigid-miss.json's summary), flagged per case."""
    record = read_ski(ski_file)
    served = served_beam(record.identified)
    t0 = time.perf_counter()
    ident, check = identify_as_its_job(record, knot_spacing_m=knot_spacing_m)
    out = {
        "ski_file": ski_file,
        "knot_spacing_m": knot_spacing_m,
        "identified": bool(ident.ok),
        "misfit_m": float(ident.misfit_m),
        "served_misfit_m": float(record.identified["attrs"]["misfit_m"]),
        "held_out_rms_m": float(check.get("held_out_rms_m", np.nan)),
        "time_s": round(time.perf_counter() - t0, 1),
        "cases": [],
    }
    if not ident.ok:
        return out
    missed = {(m["load_kg"], m["load_position_mm"]) for m in misses}
    seen = set()
    for c in cases:
        key = (c["load_kg"], c["load_position_mm"])
        if key in seen:
            continue
        seen.add(key)
        s, _ = shift(served, ident.beam, c["load_kg"] * G_STANDARD, c["load_position_mm"] * 1e-3)
        out["cases"].append(
            {
                "load_kg": c["load_kg"],
                "load_position_mm": c["load_position_mm"],
                "variant_shift_m": s,
                "true_error_m": c["true_error_m"],
                "stored_sd_m": c["stored_sd_m"],
                "miss": key in missed,
            }
        )
    return out


def summarise(skis: list[dict]) -> dict:
    """Over the cases of the misses and of the other cases: the variant's shift over the true
    error (median) and over the band's σ (median), and the share of cases the shift reaches
    half the true error."""
    out = {}
    for label, want in (("misses", True), ("others", False)):
        rows = [c for s in skis for c in s["cases"] if c["miss"] == want]
        if not rows:
            out[label] = {"cases": 0}
            continue
        r_true = np.array([c["variant_shift_m"] / c["true_error_m"] for c in rows])
        r_sd = np.array([c["variant_shift_m"] / c["stored_sd_m"] for c in rows])
        out[label] = {
            "cases": len(rows),
            "shift_over_true_median": float(np.median(r_true)),
            "shift_over_band_sd_median": float(np.median(r_sd)),
            "share_shift_at_least_half_true": float(np.mean(r_true >= 0.5)),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rigid-miss", type=Path, required=True, help="rigid_miss_study.py output")
    ap.add_argument("--study", nargs="+", required=True, help="own-ski study JSON (ski files)")
    ap.add_argument("--knot-spacing-m", type=float, default=KNOT_SPACING_M)
    ap.add_argument("--only-misses", action="store_true", help="only skis with a miss")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    doc = json.loads(args.rigid_miss.read_text(encoding="utf-8"))
    misses = doc["summary"]["misses"]
    files = {}
    for path in args.study:
        for ski in json.loads(Path(path).read_text(encoding="utf-8"))["skis"]:
            files[(ski["design"], ski["grid"])] = ski["ski_file"]
    by_ski: dict = {}
    for r in doc["rows"]:
        by_ski.setdefault((r["design"], r["grid"]), []).append(r)
    skis = []
    for key, rows in sorted(by_ski.items()):
        mine = [m for m in misses if (m["design"], m["grid"]) == key]
        if args.only_misses and not mine:
            continue
        got = ski_rows(files[key], rows, mine, args.knot_spacing_m)
        skis.append({"design": key[0], "grid": key[1], **got})
        print(
            f"{key[0]} {key[1]}: misfit {got['misfit_m'] * 1e6:.3f} µm (served "
            f"{got['served_misfit_m'] * 1e6:.3f}) in {got['time_s']} s",
            flush=True,
        )
    result = {
        "schema": SCHEMA,
        "provenance": common.provenance(
            {"rigid_miss": str(args.rigid_miss), "knot_spacing_m": args.knot_spacing_m}
        ),
        "summary": summarise(skis),
        "skis": skis,
    }
    with common.atomic_path(args.out) as tmp:
        tmp.write_text(json.dumps(result, indent=1), encoding="utf-8")
    print(json.dumps(result["summary"], indent=1))
    print(f"written {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
