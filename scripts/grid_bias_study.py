"""Which way the macro grid errs on the apparent contact area, read from the committed studies
(issue #26 point 4; docs/limits.md "The grid part is a bias").

The band's macro-grid part of the apparent area (:func:`app.service.band.grid_component`) was
calibrated as a two-sided half-width. This measures its sign, without solving anything:

- the own-ski populations (``scripts/own_ski_study.py`` output, the eleven of
  :data:`population_band_study.DEFAULT_POPULATIONS`): every held-out case's true-beam answer on
  the default grid (``truth_cm2``) against the same beam on the 1 mm × 32 reference grid
  (``truth_ref_cm2``), rigid and bending, per snow modulus, and per population the share
  above;
- the rest of the served answers' error, on the same grid: the served (identified-beam)
  answer against the true beam's default-grid answer, per model, measurement grid and modulus
  (the identification's bias, which the grid's adds to or offsets);
- the demo skis' and design-beam skis' calibration cases
  (docs/studies/band-calibration-rows.json): the camber model's answer on the default grid
  against the same profile on the fine preset, per ski and modulus.

Seconds. Usage::

    python scripts/grid_bias_study.py [--out docs/studies/grid-bias.json]

Writes the JSON and its markdown (``.md``) beside it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "scripts"))

import population_band_study as pbs  # noqa: E402
from skisnow.app.storage import common  # noqa: E402

SCHEMA = "skisnow.grid-bias-study/1"
STUDIES = REPO / "docs" / "studies"
CALIBRATION_ROWS = STUDIES / "band-calibration-rows.json"


def summary(values) -> dict:
    """Count, share above 0, mean, median, 5th and 95th percentile of relative differences
    (as fractions)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if not v.size:
        return {"n": 0}
    return {
        "n": int(v.size),
        "share_above": float(np.mean(v > 0)),
        "mean": float(v.mean()),
        "median": float(np.median(v)),
        "p5": float(np.percentile(v, 5)),
        "p95": float(np.percentile(v, 95)),
    }


def grid_differences(study: dict) -> dict[tuple[str, float], list[float]]:
    """Per (model, modulus): the true beam's default-grid answer over its reference-grid one,
    minus 1, once per held-out case (the dense and coarse measurement grids share the truths:
    each case is counted on the dense grid's skis only, or on the coarse one's where a study
    has no dense grid)."""
    grids = {ski.get("grid") for ski in study["skis"]}
    keep = "dense" if "dense" in grids else "coarse"
    out: dict[tuple[str, float], list[float]] = {}
    for ski in study["skis"]:
        if ski.get("grid") != keep:
            continue
        for case in ski.get("answers", []):
            same, ref = case.get("truth_cm2") or {}, case.get("truth_ref_cm2") or {}
            for model in pbs.MODELS:
                if same.get(model) and ref.get(model):
                    key = (model, float(case["snow_modulus_mpa"]))
                    out.setdefault(key, []).append(same[model] / ref[model] - 1.0)
    return out


def served_differences(study: dict) -> dict[tuple[str, str, float], list[float]]:
    """Per (model, measurement grid, modulus): the served identified-beam answer over the true
    beam's answer on the same (default) grid, minus 1."""
    out: dict[tuple[str, str, float], list[float]] = {}
    for ski in study["skis"]:
        if ski.get("outcome") != "done":
            continue
        if ski.get("served", {}).get("profile_model") != "identified_beam":
            continue
        for case in ski.get("answers", []):
            for model in pbs.MODELS:
                a = case.get(model, {})
                truth = (case.get("truth_cm2") or {}).get(model)
                if a.get("status") == 200 and truth:
                    key = (model, ski["grid"], float(case["snow_modulus_mpa"]))
                    out.setdefault(key, []).append(a["area_cm2"] / truth - 1.0)
    return out


def calibration_differences(rows: list[dict]) -> dict[tuple[str, float], list[float]]:
    """Per (ski, modulus): the default grid's apparent area over the fine preset's, same
    profile, minus 1."""
    out: dict[tuple[str, float], list[float]] = {}
    for r in rows:
        v = r["values"]
        if "default" in v and "fine" in v:
            d = v["default"]["apparent_contact_area"] / v["fine"]["apparent_contact_area"] - 1
            out.setdefault((r["ski"], float(r["e_snow_mpa"])), []).append(d)
    return out


def study(populations: dict[str, dict], calibration_rows: list[dict]) -> dict:
    """The three measurements of the module docstring."""
    grid_cells = []
    per_pop = {p: grid_differences(s) for p, s in populations.items()}
    for model in pbs.MODELS:
        for e in pbs.MODULI_MPA:
            pooled = [d for diffs in per_pop.values() for d in diffs.get((model, e), [])]
            grid_cells.append(
                {
                    "model": model,
                    "e_snow_mpa": e,
                    "pooled": summary(pooled),
                    "populations": {p: summary(d.get((model, e), [])) for p, d in per_pop.items()},
                }
            )
    served_cells = []
    served = [served_differences(s) for s in populations.values()]
    for model in pbs.MODELS:
        for grid in pbs.GRIDS:
            for e in pbs.MODULI_MPA:
                pooled = [d for diffs in served for d in diffs.get((model, grid, e), [])]
                served_cells.append(
                    {"model": model, "grid": grid, "e_snow_mpa": e, **summary(pooled)}
                )
    calib = calibration_differences(calibration_rows)
    calib_cells = [
        {"ski": ski, "e_snow_mpa": e, **summary(v)} for (ski, e), v in sorted(calib.items())
    ]
    return {"grid": grid_cells, "served_vs_truth": served_cells, "calibration": calib_cells}


def markdown(doc: dict) -> str:
    prov = doc["provenance"]
    lines = [
        "# Which way the macro grid errs on the apparent contact area",
        "",
        f"_{prov['created_utc']}, commit {prov['git_commit'][:12]}, `{prov['command_line']}`._",
        "",
        "True beams' answers, default grid against the 1 mm × 32 reference, every held-out case "
        "of the eleven own-ski populations: share of answers above the reference (pooled, and "
        "the lowest population), mean, median, 5th / 95th percentile [%].",
        "",
        "| model | E [MPa] | answers | above (pooled) | above (lowest population) | mean | "
        "median | p5 / p95 |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for c in doc["grid"]:
        p = c["pooled"]
        if not p.get("n"):
            continue
        low = min(s["share_above"] for s in c["populations"].values() if s.get("n"))
        lines.append(
            f"| {c['model']} | {c['e_snow_mpa']:g} | {p['n']} | {p['share_above']:.3f} | "
            f"{low:.3f} | {p['mean'] * 100:+.2f} | {p['median'] * 100:+.2f} | "
            f"{p['p5'] * 100:+.2f} / {p['p95'] * 100:+.2f} |"
        )
    lines += [
        "",
        "The rest of the served answers' error: identified beam's answer against the true "
        "beam's, both on the default grid [%].",
        "",
        "| model | grid | E [MPa] | answers | above | mean | median | p5 / p95 |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for c in doc["served_vs_truth"]:
        if not c.get("n"):
            continue
        lines.append(
            f"| {c['model']} | {c['grid']} | {c['e_snow_mpa']:g} | {c['n']} | "
            f"{c['share_above']:.3f} | {c['mean'] * 100:+.2f} | {c['median'] * 100:+.2f} | "
            f"{c['p5'] * 100:+.2f} / {c['p95'] * 100:+.2f} |"
        )
    lines += [
        "",
        "Calibration cases (docs/studies/band-calibration-rows.json): the camber model's "
        "answer, default grid against the fine preset, same profile [%].",
        "",
        "| ski | E [MPa] | cases | above | mean |",
        "|---|---|---|---|---|",
    ]
    for c in doc["calibration"]:
        lines.append(
            f"| {c['ski']} | {c['e_snow_mpa']:g} | {c['n']} | {c['share_above']:.2f} | "
            f"{c['mean'] * 100:+.2f} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--studies", nargs="+", help="label=study.json ... (default: the eleven)")
    ap.add_argument("--calibration", type=Path, default=CALIBRATION_ROWS)
    ap.add_argument("--out", type=Path, default=STUDIES / "grid-bias.json")
    args = ap.parse_args(argv)
    pairs = (
        [s.split("=", 1) for s in args.studies]
        if args.studies
        else [(k, str(STUDIES / v)) for k, v in pbs.DEFAULT_POPULATIONS.items()]
    )
    populations = {label: json.loads(Path(path).read_text("utf-8")) for label, path in pairs}
    rows = json.loads(args.calibration.read_text("utf-8"))["rows"]
    doc = {
        "schema": SCHEMA,
        "provenance": common.provenance(
            {"studies": dict(pairs), "calibration": args.calibration.name}
        ),
        "units": {"differences": "relative (fraction), answer / reference − 1"},
        **study(populations, rows),
    }
    pbs.write_outputs(doc, args.out, markdown(doc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
