"""One cell of the bending ski's beam-draw factor checked and refitted with this code (issue #26
point 4; :data:`app.service.band_calibration.BEAM_SCALE_GRID_NODES`, docs/limits.md "The bands
across eleven populations").

The per-grid factors were fitted by ``scripts/per_grid_band_study.py`` on re-solves of four
populations at an older commit; the band has changed since (alternative beams, the grid
factor), and eleven populations have been run since (``scripts/population_band_study.py``).
This checks one cell (measurement grid, snow modulus) on two kinds of evidence, both with this
code's band:

- **re-solves** (``--scans``): ``scripts/beam_scale_study.py --rows --moduli E`` on the work
  folders of fresh own-ski study runs; every held-out case answered again with the beam draws
  at each candidate factor (its ``--flex-scales``);
- **the committed populations** (``--studies``, default
  :data:`population_band_study.DEFAULT_POPULATIONS`): the linear estimate of each at the
  candidate factors (the draws' part rescaled, the other parts kept; an estimate: the draws'
  spread is not exactly linear in the factor, which is why the re-solves decide with it).

The refit is the smallest candidate at which every re-solved population and every committed
population's estimate holds ≥ 90 % of the reference truths inside the served band, symmetric in
log (area × (1 − hw) … area ÷ (1 − hw), :func:`app.service.band.interval_90`): the per-grid
study's rule, applied to more populations (``None`` when no candidate does). Beside it, what the
same rule chooses for the band served until 2026-11-29 (area × (1 ± hw)), the width ratios and
the unwarned misses.

Nothing is solved here: seconds. Usage::

    python scripts/beam_scale_study.py --work W1 --rows --moduli 2000 --flex-scales 4 6 8 12 \\
        --rigid-scales 2 --out scan1.json   # per fresh population
    python scripts/beam_scale_refit_study.py --grid coarse --e-snow-mpa 2000 \\
        --scans 'random 37-42=scan1.json' 'validation=scan2.json'

Writes docs/studies/beam-scale-refit.json and .md.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "scripts"))

import beam_scale_study as bss  # noqa: E402
import per_grid_band_study as pgs  # noqa: E402  (the grids' names and order)
import population_band_study as pbs  # noqa: E402
from skisnow.app.storage import common  # noqa: E402

SCHEMA = "skisnow.beam-scale-refit-study/1"
COVERAGE_TARGET = 0.90
WIDTH_TARGET = 2.5
OUT = REPO / "docs" / "studies" / "beam-scale-refit.json"


def scan_rows(scan: dict, grid: str, e_snow_mpa: float) -> list[dict]:
    """The bending-ski rows of a ``beam_scale_study.py --rows`` output on ``grid`` at
    ``e_snow_mpa`` [MPa]."""
    return [
        r
        for r in scan.get("rows", [])
        if r["model"] == "flexible" and r["grid"] == grid and r["e_snow_mpa"] == e_snow_mpa
    ]


def resolved_stats(rows: list[dict]) -> dict:
    """:func:`population_band_study.stats` of re-solved answers (the coverage of the band
    symmetric in log and of area × (1 ± hw), the width ratio, unwarned misses), with the
    refused ones counted."""
    ok = [r for r in rows if "area_cm2" in r]
    st = pbs.stats(
        [r["area_cm2"] / r["truth_ref_cm2"] - 1.0 for r in ok],
        [r["half_width"] for r in ok],
        [bool(r["warnings"]) for r in ok],
        [bss.served_sides(r) for r in ok],
    )
    return {**st, "refused": len(rows) - len(ok)}


def refit(scans: dict[str, dict], studies: dict[str, dict], grid: str, e_snow_mpa: float) -> dict:
    """Per candidate factor (the factors every scan was re-solved at): each re-solved
    population's stats (:func:`per_grid_band_study.stats`) and each committed population's
    linear estimate (:func:`population_band_study.stats` of
    :func:`population_band_study.rescaled_half_widths`); the smallest factor meeting
    :data:`COVERAGE_TARGET` everywhere (``None`` when none does)."""
    per_scan = {label: scan_rows(s, grid, e_snow_mpa) for label, s in scans.items()}
    factors = sorted(
        set.intersection(*({r["scale"] for r in rows} for rows in per_scan.values()))
        if per_scan
        else set()
    )
    per_study = {
        label: pbs.answers(s, "flexible", grid, e_snow_mpa) for label, s in studies.items()
    }
    candidates = []
    for k in factors:
        resolved = {
            label: resolved_stats([r for r in rows if r["scale"] == k])
            for label, rows in per_scan.items()
        }
        estimated = {
            label: pbs.stats(
                [r["error"] for r in rows],
                pbs.rescaled_half_widths(rows, k),
                [r["warned"] for r in rows],
                [pbs.served_sides(r, k) for r in rows],
            )
            for label, rows in per_study.items()
            if rows
        }
        every = [s for s in (*resolved.values(), *estimated.values()) if s.get("answers")]
        covs = [s["coverage"] for s in every]
        # as served now (the grid part one-sided on soft snow; symmetric in log from 200 MPa)
        covs_log = [s["coverage_now"] for s in every]
        widths = [s["half_width_over_rms_now"] for s in every]
        pooled = [r for rows in per_study.values() for r in rows]
        candidates.append(
            {
                "factor": k,
                "resolved": resolved,
                "estimated": estimated,
                "estimated_pooled": pbs.stats(
                    [r["error"] for r in pooled],
                    pbs.rescaled_half_widths(pooled, k),
                    [r["warned"] for r in pooled],
                    [pbs.served_sides(r, k) for r in pooled],
                )
                if pooled
                else {"answers": 0},
                "lowest_coverage": min(covs_log) if covs_log else None,
                "lowest_coverage_symmetric_band": min(covs) if covs else None,
                "widest": max(widths) if widths else None,
                "meets_coverage": bool(covs_log) and min(covs_log) >= COVERAGE_TARGET,
                "meets_coverage_symmetric_band": bool(covs) and min(covs) >= COVERAGE_TARGET,
            }
        )
    return {
        "grid": grid,
        "e_snow_mpa": e_snow_mpa,
        "candidates": candidates,
        "chosen": next((c["factor"] for c in candidates if c["meets_coverage"]), None),
        # what the same rule chooses for the band served until 2026-11-29, area × (1 ± hw)
        "chosen_symmetric_band": next(
            (c["factor"] for c in candidates if c["meets_coverage_symmetric_band"]), None
        ),
    }


def markdown(doc: dict) -> str:
    """The candidates as one table: per population, coverage / width ratio / unwarned misses."""
    fit = doc["refit"]
    cands = fit["candidates"]
    if not cands:
        return "no candidate factor: the scans have no common factor in this cell\n"
    labels_r = list(cands[0]["resolved"])
    labels_e = list(cands[0]["estimated"])
    lines = [
        f"# The bending ski's beam-draw factor refitted: {fit['grid']}, {fit['e_snow_mpa']:g} MPa",
        "",
        f"_{doc['provenance']['created_utc']}, commit {doc['provenance']['git_commit'][:12]}, "
        "`scripts/beam_scale_refit_study.py`. Per population: share of reference truths inside "
        "the band / mean half-width ÷ RMS error / answers more than 3 % off, outside and "
        "unwarned. Re-solved: answered again at each factor with this code; estimated: the "
        "committed study's answers with the draws' part rescaled linearly. Coverage in the "
        "cells: of the band symmetric in log (served since 2026-11-29)._",
        "",
        "| factor | "
        + " | ".join([f"{x} (re-solved)" for x in labels_r] + [f"{x} (est.)" for x in labels_e])
        + " | estimated pooled | lowest coverage (as served now / area × (1 ± hw)) | widest |",
        "|---" * (len(labels_r) + len(labels_e) + 4) + "|",
    ]

    def cell(s: dict) -> str:
        if not s.get("answers"):
            return "–"
        return (
            f"{s['coverage_now']:.2f} / {s['half_width_over_rms_now']:.2f} / "
            f"{s['unwarned_misses_now']}"
        )

    for c in cands:
        row = [f"× {c['factor']:g}"]
        row += [cell(c["resolved"][x]) for x in labels_r]
        row += [cell(c["estimated"][x]) for x in labels_e]
        row += [
            cell(c["estimated_pooled"]),
            f"{c['lowest_coverage']:.3f} / {c['lowest_coverage_symmetric_band']:.3f}",
            f"{c['widest']:.2f}",
        ]
        lines.append("| " + " | ".join(row) + " |")

    def named(k: float | None) -> str:
        return "none of the candidates" if k is None else f"× {k:g}"

    lines += [
        "",
        f"Smallest factor with ≥ {COVERAGE_TARGET:.0%} of the truths inside the served band "
        f"as served now (area × (1 − hw) … area ÷ (1 − hw_above): symmetric in log, the grid "
        f"part one-sided on soft snow) in every population: "
        f"{named(fit['chosen'])}. For the band served until 2026-11-29 (area × (1 ± hw)): "
        f"{named(fit['chosen_symmetric_band'])}.",
        "",
    ]
    return "\n".join(lines)


def _pairs(items: list[str] | None, default: dict[str, str]) -> list[tuple[str, str]]:
    if not items:
        return list(default.items())
    return [tuple(s.split("=", 1)) for s in items]  # type: ignore[misc]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--grid", choices=pgs.GRIDS, required=True)
    ap.add_argument("--e-snow-mpa", type=float, required=True)
    ap.add_argument("--scans", nargs="+", required=True, help="label=beam_scale_study.json ...")
    ap.add_argument(
        "--studies",
        nargs="+",
        help="label=own_ski_study.json ... (default: population_band_study's eleven)",
    )
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    scan_pairs = _pairs(args.scans, {})
    study_pairs = _pairs(
        args.studies, {k: str(pbs.STUDIES / v) for k, v in pbs.DEFAULT_POPULATIONS.items()}
    )
    scans = {k: json.loads(Path(v).read_text("utf-8")) for k, v in scan_pairs}
    studies = {k: json.loads(Path(v).read_text("utf-8")) for k, v in study_pairs}
    doc = {
        "schema": SCHEMA,
        "provenance": common.provenance(
            {"scans": dict(scan_pairs), "studies": dict(study_pairs), "grid": args.grid}
        ),
        "scans": {
            k: {
                "commit": scans[k]["provenance"]["git_commit"],
                "skis": json.loads(scans[k]["provenance"].get("parameters_json") or "{}").get(
                    "skis"
                ),
            }
            for k, _ in scan_pairs
        },
        "targets": {"coverage": COVERAGE_TARGET, "half_width_over_rms": WIDTH_TARGET},
        "refit": refit(scans, studies, args.grid, args.e_snow_mpa),
    }
    pbs.write_outputs(doc, args.out, markdown(doc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
