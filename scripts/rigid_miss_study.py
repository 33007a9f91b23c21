"""What the rigid answers' unwarned misses have in common, and whether the identification itself
could have flagged them (issue #26 point 4: every answer more than 3 % off inside its band or
warned; docs/limits.md, "The rigid answers' unwarned misses").

The input is own-ski studies (``scripts/own_ski_study.py`` output JSON with their work folders'
ski files). For every rigid answer of an identified beam it takes the answer's case (load,
position) and measures, on the served beam, its true beam and the identification:

- ``true_error_m``: the served loaded profile minus the true beam's (built as the own-ski study
  builds it), RMS where the served one is below ``CONTACT_BAND_M`` (what the band's camber part
  stands for);
- ``stored_sd_m``: the band's σ(X) (the stored ``profile_sd_m``, × 1) RMS on the same nodes;
- ``draw_sd_m``: the spread of :data:`DRAWS` beams drawn from the fit's covariance (antithetic,
  × 1) at this very case, RMS on the same nodes (a per-case σ);
- ``flat_length_m``: how much of the served loaded base lies within each of
  :data:`FLAT_GAPS_M` of the flat (the answer's sensitivity to a smooth profile error).

Then, per predictor, how well it separates the answers more than 3 % off from the others: the
correlation of log true error with log σ, warning rules (warn above a threshold: the share of all
answers warned, of the > 3 %-off answers warned, and of the unwarned misses caught), and the band
re-scaled with a per-case σ (the camber part × ``draw_sd/stored_sd``, or × max(1, ratio); the
other parts kept): coverage, width over RMS error and unwarned misses per grid, modulus and
population. That re-scale is linear in σ (a screen, not a re-solve).

Usage::

    python scripts/rigid_miss_study.py --study hand-written=docs/studies/own-ski-pergrid.json \\
        random=docs/studies/own-ski-pergrid-random.json \\
        validation=docs/studies/own-ski-pergrid-validation.json \\
        --out docs/studies/rigid-miss.json --md docs/studies/rigid-miss.md

About 2 min per population of 8 skis (one beam solve per case and draw).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "scripts"))

import beam_scale_study  # noqa: E402
from own_ski_study import SPACING_M  # noqa: E402
from skisnow.app.service.band_sampling import CONTACT_BAND_M  # noqa: E402
from skisnow.app.service.profiles import served_beam  # noqa: E402
from skisnow.app.storage import common  # noqa: E402
from skisnow.app.storage.skis import identification_for_sampling, read_ski  # noqa: E402
from skisnow.solvers.beam import G_STANDARD, solve_beam_contact  # noqa: E402
from skisnow.solvers.identify import sample_beams  # noqa: E402
from skisnow.solvers.ski_designs import get_design  # noqa: E402

SCHEMA = "skisnow.rigid-miss-study/1"
#: beams drawn per case (as the band's) and their seed
DRAWS = 8
DRAW_SEED = 0
#: gaps below which the loaded base counts as flat [m]
FLAT_GAPS_M = (2e-6, 5e-6, 10e-6, 20e-6)
#: warning thresholds on draw_sd / stored_sd [-]
RATIO_THRESHOLDS = (1.25, 1.5, 2.0, 2.5)
#: warning thresholds on the flat length, as quantiles over all answers [-]
FLAT_QUANTILES = (0.5, 0.75, 0.9)
#: multipliers of the per-case σ in the re-scale screen [-]
MULTIPLIERS = (0.5, 0.75, 1.0, 1.5, 2.0)
#: answers this far off (relative) and outside the band must carry a warning
AREA_OFF = beam_scale_study.AREA_OFF


def case_features(record, truth, load_n: float, load_position_m: float, draws) -> dict:
    """The predictors of one case (module docstring) for a ski ``record`` with a served beam,
    its ``truth`` (BeamSki) and ``draws`` (BeamSki drawn from the fit's covariance)."""
    beam = served_beam(record.identified)
    nom = solve_beam_contact(beam, load_n, load_position_m)
    tru = solve_beam_contact(truth, load_n, load_position_m)
    near = nom.gap_m < CONTACT_BAND_M
    x = nom.positions_m[near]
    true_err = np.interp(x, tru.positions_m, tru.gap_m) - nom.gap_m[near]
    ident = record.identified
    stored = np.interp(
        x,
        np.asarray(ident["positions_m"], dtype=float),
        np.asarray(ident["profile_sd_m"], dtype=float),
    )
    sq, n = np.zeros(x.size), 0
    for b in draws:
        r = solve_beam_contact(b, load_n, load_position_m)
        if r.converged:
            sq += (np.interp(x, r.positions_m, r.gap_m) - nom.gap_m[near]) ** 2
            n += 1
    dx = float(np.mean(np.diff(nom.positions_m)))
    return {
        "true_error_m": float(np.sqrt(np.mean(true_err**2))),
        "stored_sd_m": float(np.sqrt(np.mean(stored**2))),
        "draw_sd_m": float(np.sqrt(np.mean(sq / max(n, 1)))),
        "draws_solved": n,
        "flat_length_m": [float(np.sum(nom.gap_m < g) * dx) for g in FLAT_GAPS_M],
    }


def answer_rows(study: dict, population: str) -> list[dict]:
    """One row per rigid answer of an identified beam in an own-ski study's output."""
    rows = []
    for ski in study["skis"]:
        if ski.get("outcome") != "done":
            continue
        record = read_ski(ski["ski_file"])
        if served_beam(record.identified) is None:
            continue
        ib = identification_for_sampling(record.identified)
        if ib is None or record.identified.get("profile_sd_m") is None:
            continue
        draws = sample_beams(ib, DRAWS, DRAW_SEED, scale=1.0, antithetic=True)
        truth = get_design(ski["design"]).build(SPACING_M)
        seen: dict = {}
        for a in ski["answers"]:
            m = a.get("rigid", {})
            if m.get("status") != 200 or m.get("profile_model") != "identified_beam":
                continue
            key = (a["load_kg"], a["load_position_mm"])
            if key not in seen:
                seen[key] = case_features(
                    record, truth, a["load_kg"] * G_STANDARD, a["load_position_mm"] * 1e-3, draws
                )
            rows.append(
                {
                    "population": population,
                    "design": ski["design"],
                    "grid": ski["grid"],
                    "e_snow_mpa": a["snow_modulus_mpa"],
                    "load_kg": a["load_kg"],
                    "load_position_mm": a["load_position_mm"],
                    "error": m["error_ref_pct"] / 100,
                    "half_width": m["band_half_width"],
                    "camber_part": m.get("area_components", {}).get("camber_model", 0.0),
                    "inside": bool(m["inside_band"]),
                    "warned": bool(m["warnings"]),
                    **seen[key],
                }
            )
    return rows


def is_miss(row: dict) -> bool:
    """More than :data:`AREA_OFF` off, outside the band and without a warning."""
    return abs(row["error"]) > AREA_OFF and not row["inside"] and not row["warned"]


def ratio(row: dict) -> float:
    """The per-case draw spread over the stored σ at the case [-]."""
    return row["draw_sd_m"] / row["stored_sd_m"] if row["stored_sd_m"] > 0 else math.inf


def warning_rule(rows: list[dict], values: np.ndarray, threshold: float) -> dict:
    """Warn where ``values`` ≥ ``threshold``: the share of all answers warned, of the answers
    more than 3 % off warned, and the unwarned misses that the warning would catch."""
    warn = np.asarray(values) >= threshold
    off = np.array([abs(r["error"]) > AREA_OFF for r in rows])
    miss = np.array([is_miss(r) for r in rows])
    return {
        "threshold": float(threshold),
        "warned_share": float(warn.mean()) if warn.size else math.nan,
        "off_warned_share": float(warn[off].mean()) if off.any() else math.nan,
        "misses": int(miss.sum()),
        "misses_caught": int(warn[miss].sum()),
    }


def rescaled_band(row: dict, mode: str, multiplier: float) -> float:
    """The row's half-width with its camber part × the per-case ratio (``ratio``) or × max(1,
    ratio) (``widen``), × ``multiplier``; ``stored`` keeps the ratio at 1 (the other parts kept,
    quadrature sum)."""
    r = {"stored": 1.0, "ratio": ratio(row), "widen": max(1.0, ratio(row))}[mode]
    rest = max(row["half_width"] ** 2 - row["camber_part"] ** 2, 0.0)
    return math.sqrt(rest + (row["camber_part"] * r * multiplier) ** 2)


def cell_stats(rows: list[dict], widths: list[float]) -> dict:
    """Coverage, mean half-width over the RMS error and unwarned misses of ``rows`` with the
    half-widths ``widths``: :func:`beam_scale_study.stats` (the band is the answer ± its
    relative half-width) of each row's answer relative to its reference truth."""
    st = beam_scale_study.stats(
        [
            {
                "area_cm2": 1.0 + r["error"],
                "truth_ref_cm2": 1.0,
                "half_width": float(w),
                "warnings": ["warned"] if r["warned"] else [],
                "components": {},
            }
            for r, w in zip(rows, widths, strict=True)
        ]
    )
    if not st["answers"]:
        return {"answers": 0, "coverage": math.nan, "width_over_rms": math.nan, "misses": 0}
    ratio = st["half_width_over_rms"]
    return {
        "answers": st["answers"],
        "coverage": st["coverage"],
        "width_over_rms": math.nan if ratio is None else ratio,
        "misses": st["off_3pct_outside_unwarned"],
    }


def screen(rows: list[dict]) -> list[dict]:
    """:func:`cell_stats` per grid, modulus, population, mode and multiplier."""
    out = []
    keys = sorted({(r["grid"], r["e_snow_mpa"], r["population"]) for r in rows})
    for grid, e, pop in keys:
        cell = [r for r in rows if (r["grid"], r["e_snow_mpa"], r["population"]) == (grid, e, pop)]
        out.append(
            {
                "grid": grid,
                "e_snow_mpa": e,
                "population": pop,
                "mode": "stored",
                "multiplier": 1.0,
                **cell_stats(cell, [r["half_width"] for r in cell]),
            }
        )
        for mode in ("ratio", "widen"):
            for k in MULTIPLIERS:
                out.append(
                    {
                        "grid": grid,
                        "e_snow_mpa": e,
                        "population": pop,
                        "mode": mode,
                        "multiplier": k,
                        **cell_stats(cell, [rescaled_band(r, mode, k) for r in cell]),
                    }
                )
    return out


def totals(cells: list[dict]) -> list[dict]:
    """Per mode and multiplier over all cells: the misses, the cells below 90 % and above
    2.5 × (the #26 targets)."""
    out = []
    for mode, k in sorted({(c["mode"], c["multiplier"]) for c in cells}):
        sel = [c for c in cells if (c["mode"], c["multiplier"]) == (mode, k)]
        out.append(
            {
                "mode": mode,
                "multiplier": k,
                "misses": sum(c["misses"] for c in sel),
                "cells_below_90": sum(1 for c in sel if c["coverage"] < 0.9),
                "cells_above_2_5": sum(1 for c in sel if c["width_over_rms"] > 2.5),
                "cells": len(sel),
            }
        )
    return out


def correlations(rows: list[dict]) -> dict:
    """Correlation of log true profile error with log stored σ and log per-case draw spread."""
    t = np.log([max(r["true_error_m"], 1e-12) for r in rows])
    out = {}
    for key in ("stored_sd_m", "draw_sd_m"):
        v = np.log([max(r[key], 1e-12) for r in rows])
        out[key] = float(np.corrcoef(t, v)[0, 1]) if len(rows) > 2 else math.nan
    return out


def summarise(rows: list[dict]) -> dict:
    ratios = np.array([ratio(r) for r in rows])
    rules = {"draw_over_stored": [warning_rule(rows, ratios, t) for t in RATIO_THRESHOLDS]}
    for j, g in enumerate(FLAT_GAPS_M):
        lengths = np.array([r["flat_length_m"][j] for r in rows])
        rules[f"flat_length_below_{g * 1e6:g}um"] = [
            {**warning_rule(rows, lengths, float(np.quantile(lengths, q))), "quantile": q}
            for q in FLAT_QUANTILES
        ]
    misses = [r for r in rows if is_miss(r)]
    cells = screen(rows)
    return {
        "answers": len(rows),
        "off_answers": sum(1 for r in rows if abs(r["error"]) > AREA_OFF),
        "misses": [
            {
                k: r[k]
                for k in (
                    "population",
                    "design",
                    "grid",
                    "e_snow_mpa",
                    "load_kg",
                    "load_position_mm",
                    "error",
                    "half_width",
                    "true_error_m",
                    "stored_sd_m",
                    "draw_sd_m",
                )
            }
            for r in misses
        ],
        "true_over_stored_median": float(
            np.median([r["true_error_m"] / r["stored_sd_m"] for r in rows])
        ),
        "correlation_log_true_error": correlations(rows),
        "warning_rules": rules,
        "rescaled": cells,
        "rescaled_totals": totals(cells),
    }


def markdown(summary: dict, meta: dict) -> str:
    um = 1e6
    lines = [
        "# The rigid answers' unwarned misses (issue #26)",
        "",
        f"Commit `{meta['git_commit']}`; {summary['answers']} rigid answers of identified beams, "
        f"{summary['off_answers']} of them more than 3 % off, {len(summary['misses'])} of those "
        "outside their band and unwarned. Generated by `scripts/rigid_miss_study.py`.",
        "",
        "## The misses",
        "",
        "| population | design | grid | E [MPa] | load [kg] | x_F [mm] | error | half-width "
        "| true profile error [µm] | band σ [µm] | per-case draw spread [µm] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for m in summary["misses"]:
        lines.append(
            f"| {m['population']} | {m['design']} | {m['grid']} | {m['e_snow_mpa']:g} | "
            f"{m['load_kg']:g} | {m['load_position_mm']:g} | {m['error'] * 100:+.2f} % | "
            f"{m['half_width'] * 100:.2f} % | {m['true_error_m'] * um:.2f} | "
            f"{m['stored_sd_m'] * um:.2f} | {m['draw_sd_m'] * um:.2f} |"
        )
    c = summary["correlation_log_true_error"]
    lines += [
        "",
        f"Correlation of log true profile error with log band σ: {c['stored_sd_m']:.2f}; with "
        f"log per-case draw spread: {c['draw_sd_m']:.2f}. Median true error over band σ: "
        f"{summary['true_over_stored_median']:.2f}.",
        "",
        "## Warning rules",
        "",
        "| rule | threshold | answers warned | > 3 % off warned | misses caught |",
        "|---|---|---|---|---|",
    ]
    for name, rules in summary["warning_rules"].items():
        for r in rules:
            thr = (
                f"{r['threshold']:g}"
                if name == "draw_over_stored"
                else f"{r['threshold'] * 1e3:.0f} mm (q {r['quantile']:g})"
            )
            lines.append(
                f"| {name} | {thr} | {r['warned_share'] * 100:.0f} % | "
                f"{r['off_warned_share'] * 100:.0f} % | {r['misses_caught']} of {r['misses']} |"
            )
    lines += [
        "",
        "## The band with a per-case σ (linear re-scale screen)",
        "",
        "| mode | × | unwarned misses | cells < 90 % | cells > 2.5 × |",
        "|---|---|---|---|---|",
    ]
    for t in summary["rescaled_totals"]:
        lines.append(
            f"| {t['mode']} | {t['multiplier']:g} | {t['misses']} | {t['cells_below_90']} of "
            f"{t['cells']} | {t['cells_above_2_5']} of {t['cells']} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--study", nargs="+", required=True, help="label=own-ski study JSON")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--md", type=Path)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows = []
    for spec in args.study:
        label, _, path = spec.partition("=")
        if not path:
            ap.error(f"--study takes label=path, got {spec!r}")
        rows += answer_rows(json.loads(Path(path).read_text(encoding="utf-8")), label)
        print(f"{label}: {len(rows)} rigid answers so far", flush=True)
    summary = summarise(rows)
    meta = {
        "schema": SCHEMA,
        "git_commit": common.git_commit(),
        "studies": args.study,
        "constants": {
            "contact_band_m": CONTACT_BAND_M,
            "draws": DRAWS,
            "draw_seed": DRAW_SEED,
            "flat_gaps_m": list(FLAT_GAPS_M),
            "area_off": AREA_OFF,
        },
        "wall_s": round(time.perf_counter() - t0, 1),
    }
    with common.atomic_path(args.out) as tmp:
        tmp.write_text(json.dumps({**meta, "summary": summary, "rows": rows}, indent=1), "utf-8")
    if args.md:
        with common.atomic_path(args.md) as tmp:
            tmp.write_text(markdown(summary, meta), encoding="utf-8")
    print(f"written {args.out}" + (f", {args.md}" if args.md else ""))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
