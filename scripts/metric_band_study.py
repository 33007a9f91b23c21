"""The functional parameters' bands on a technician's own ski (issue #26 point 4): coverage
per quantity, ski model and snow modulus of the bands of the four metrics (and the apparent
area, for comparison) against the ski's true beam.

The own-ski study (``scripts/own_ski_study.py``) judges the apparent area only. Here the
skis it kept (its work folder's ski files, each served as the job left it: identified beam or
camber network) answer the study's held-out cases again through ``app.service.contact`` (the
service's band, default preset, the study's grind and porosity), rigid and flexible, at 20,
200 and 2000 MPa. The truth is the true beam's answer on the reference grid of the study
(1 mm × 32 across, the same as its band columns); the same truth on the answer's own grid
isolates the camber model's error (``error_same_grid``). ``--network`` serves every ski by
its camber network instead (its record without the identification: the service's fallback).

Reported per model, modulus and quantity: the share of truths inside the served interval
(``app.service.band.inside_interval``), the mean half-width (mean of the two sides) over the
RMS error, the farthest truth in half-widths of its side (``reach_over_side``), and how many
answers had no band for the quantity (the minimum separation's, where a zone is unresolved).

Usage::

    python scripts/metric_band_study.py --own-ski docs/studies/own-ski-random-101-104.json \\
        --out docs/studies/metric-bands.json --md docs/studies/metric-bands.md

About 4 min for 8 skis × 12 cases × 3 moduli × 2 models on 2 cores.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "scripts"))

import own_ski_study  # noqa: E402
from skisnow.app import service  # noqa: E402
from skisnow.app.presets import DEFAULT_PRESET, PRESETS  # noqa: E402
from skisnow.app.service import band  # noqa: E402
from skisnow.app.storage import common  # noqa: E402
from skisnow.app.storage.skis import read_ski  # noqa: E402
from skisnow.solvers.errors import SkisnowError  # noqa: E402
from skisnow.solvers.ski_designs import get_design  # noqa: E402

E_SNOW_MPA = (20.0, 200.0, 2000.0)
MODELS = ("rigid", "flexible")
#: quantity → (where its value is in an answer, its key there): the service's own map
VALUES = band.ANSWER_KEYS


def _value(answer: dict, q: str) -> float:
    group, key = VALUES[q]
    return float(answer[group][key])


def study_skis(study: Path, limit: int | None, network: bool):
    """[(name, served ski, truth ski, cases [(kg, mm)])] of an own-ski study's kept skis."""
    doc = json.loads(study.read_text())
    out = []
    for s in doc["skis"]:
        path = Path(s.get("ski_file") or "")
        if s.get("outcome") != "done" or not path.is_file():
            continue
        name = f"{s['design']}-{s['grid']}-d{s['draw']}"
        rec = read_ski(path)
        if network:
            if rec.network is None:
                continue
            rec = dataclasses.replace(rec, identified=None, cache={})
        served = service.Ski(name, path, "", rec)
        truth = own_ski_study.truth_ski(
            served, get_design(s["design"]).build(own_ski_study.SPACING_M), name + "-truth"
        )
        held = s["held_out"]
        cases = list(zip(held["load_kg"], held["load_position_mm"], strict=True))[:limit]
        out.append((name, served, truth, cases))
    return out


def reference_presets() -> dict:
    """The presets with the study's reference grid added (``own_ski_study.REFERENCE_PRESET``)."""
    ref = dataclasses.replace(
        PRESETS[DEFAULT_PRESET],
        name=own_ski_study.REFERENCE_PRESET,
        pixel_along_m=own_ski_study.REFERENCE_GRID[0],
        pixels_across=own_ski_study.REFERENCE_GRID[1],
    )
    return {**PRESETS, own_ski_study.REFERENCE_PRESET: ref}


def case_rows(cat, presets, name, truth_name, kg, mm, e_mpa, grind, models) -> list[dict]:
    """One case's rows, one per ski model: each quantity's error against both truths and its
    band's two relative half-widths (None: no band)."""
    rows = []
    for model in models:
        inp = service.ContactInputs(
            name, grind, kg, mm, e_mpa, own_ski_study.POROSITY, ski_model=model
        )
        try:
            a = service.contact(cat, inp)
        except SkisnowError as exc:  # e.g. flexible on a network-served ski
            rows.append({"ski": name, "model": model, "refused": str(exc)[:200]})
            continue
        t_ref, t_same = (
            service.contact(
                cat,
                dataclasses.replace(inp, ski=truth_name, preset=p),
                presets=presets,
                error_band=False,
            )
            for p in (own_ski_study.REFERENCE_PRESET, DEFAULT_PRESET)
        )
        b = a["band"]
        below, above = b["relative_half_width"], b.get("relative_half_width_above") or {}
        per = {}
        for q in VALUES:
            v = _value(a, q)
            w = below.get(q)
            per[q] = {
                "error": v / _value(t_ref, q) - 1.0,
                "error_same_grid": v / _value(t_same, q) - 1.0,
                "below": w,
                "above": above.get(q, w),
            }
        rows.append(
            {
                "ski": name,
                "model": model,
                "used": a["provenance"]["ski_model"].get("used"),
                "profile_model": a["provenance"]["ski"]["profile_model"],
                "load_kg": kg,
                "load_position_mm": mm,
                "e_snow_mpa": e_mpa,
                "quantities": per,
                # the band's parts (relative half-widths per quantity) and the zone holding
                # the minimum separation: what a refit of a part is made from
                "components": {
                    k: dict(v)
                    for k, v in (b.get("components") or {}).items()
                    if isinstance(v, dict)
                },
                "min_zone_length_mm": min(
                    a["apparent"]["zones"], key=lambda z: z["min_average_separation_um"]
                )["length_mm"]
                if a["apparent"]["zones"]
                else None,
                "warnings": sorted({w["code"] for w in a.get("warnings", [])}),
            }
        )
    return rows


def summarise(rows: list[dict]) -> dict:
    """Per model, modulus and quantity: coverage, width over RMS, farthest reach."""
    out = {}
    answered = [r for r in rows if "quantities" in r]
    for model in sorted({r["model"] for r in answered}):
        for e in E_SNOW_MPA:
            sel = [r for r in answered if r["model"] == model and r["e_snow_mpa"] == e]
            if not sel:
                continue
            cell = {}
            for q in VALUES:
                banded = [r["quantities"][q] for r in sel if r["quantities"][q]["below"]]
                if not banded:
                    continue
                err, same, below, above = (
                    np.array([p[k] for p in banded], dtype=float)
                    for k in ("error", "error_same_grid", "below", "above")
                )
                reach = band.reach_over_side(err, below, above)
                rms = float(np.sqrt(np.mean(err**2)))
                width = float(np.mean((below + above) / 2))
                cell[q] = {
                    "n": len(banded),
                    "no_band": len(sel) - len(banded),
                    "inside": float(np.mean(band.inside_interval(err, below, above))),
                    "inside_same_grid_truth": float(
                        np.mean(band.inside_interval(same, below, above))
                    ),
                    "mean_half_width": width,
                    "rms_error": rms,
                    "rms_error_same_grid": float(np.sqrt(np.mean(same**2))),
                    "mean_error": float(np.mean(err)),
                    "half_width_over_rms": width / rms if rms > 0 else float("inf"),
                    "farthest_over_side": float(reach.max()),
                    "q90_over_side": float(np.quantile(reach, 0.9)),
                }
            out[f"{model} {e:g} MPa"] = cell
    return out


def markdown(doc: dict) -> str:
    prov = doc["provenance"]
    lines = [
        "# The functional parameters' bands on own skis",
        "",
        f"Written by `scripts/metric_band_study.py` (commit `{str(prov['git_commit'])[:12]}`, "
        f"{prov['created_utc']}; command `{prov['command_line']}`); do not edit by hand.",
        "",
        f"Skis: {', '.join(doc['skis'])} ({doc['served']}); {doc['cases_per_ski']} held-out "
        "cases each at 20, 200 and 2000 MPa. Truth: the true beam's answer on the reference "
        "grid (1 mm × 32 across); in brackets against the same truth on the answer's own grid.",
        "*Inside*: share of truths inside the served 90 % interval; *width / RMS*: mean relative "
        "half-width (mean of the two sides) over the RMS error against the reference truth; "
        "*farthest*: the farthest truth in half-widths of the band's side towards it; *mean "
        "error*: the answers' mean signed error (a bias the band would have to hold).",
        "",
        "| model | snow | quantity | answers (no band) | inside | mean error | RMS error | "
        "mean half-width | width / RMS | farthest |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for cell, per in doc["summary"].items():
        model, e = cell.split(" ", 1)
        for q, s in per.items():
            lines.append(
                f"| {model} | {e} | {q.replace('_', ' ')} | {s['n']} ({s['no_band']}) | "
                f"{100 * s['inside']:.1f} % ({100 * s['inside_same_grid_truth']:.1f} %) | "
                f"{100 * s['mean_error']:+.2f} % | {100 * s['rms_error']:.2f} % "
                f"({100 * s['rms_error_same_grid']:.2f} %) | {100 * s['mean_half_width']:.2f} % | "
                f"{s['half_width_over_rms']:.2f} | {s['farthest_over_side']:.2f} |"
            )
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--own-ski", type=Path, required=True, help="an own_ski_study.py output")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--md", type=Path)
    ap.add_argument("--cases", type=int, default=12, help="held-out cases per ski (12)")
    ap.add_argument("--models", nargs="+", default=list(MODELS), choices=MODELS)
    ap.add_argument("--network", action="store_true", help="serve every ski by its network")
    ap.add_argument("--grind", default="grind-1")
    args = ap.parse_args(argv)
    t0 = time.time()
    base = service.load_catalogue(REPO / "tables")
    presets = reference_presets()
    rows, names = [], []
    for name, served, truth, cases in study_skis(args.own_ski, args.cases, args.network):
        cat = service.Catalogue(
            tables_dir=base.tables_dir,
            skis={**base.skis, name: served, truth.name: truth},
            grinds=dict(base.grinds),
        )
        for kg, mm in cases:
            for e in E_SNOW_MPA:
                rows += case_rows(
                    cat, presets, name, truth.name, kg, mm, e, args.grind, args.models
                )
        names.append(name)
        print(f"{name}: {time.time() - t0:.0f} s", file=sys.stderr)
    doc = {
        "schema": "skisnow.metric-band-study/1",
        "provenance": common.provenance(
            parameters={"own_ski": str(args.own_ski), "cases": args.cases, "models": args.models}
        ),
        "served": "every ski by its camber network" if args.network else "as the job served it",
        "skis": names,
        "cases_per_ski": args.cases,
        "seconds": time.time() - t0,
        "summary": summarise(rows),
        "rows": rows,
    }
    with common.atomic_path(args.out) as tmp:
        tmp.write_text(json.dumps(doc, indent=1, default=float), encoding="utf-8")
    if args.md:
        args.md.write_text(markdown(doc), encoding="utf-8")
    print(markdown(doc))


if __name__ == "__main__":
    main()
