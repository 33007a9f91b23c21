"""The identified beam's two band factors per measurement grid, fitted on actual re-solves
(issue #26 point 4; :data:`app.service.band_calibration.BEAM_SCALE_GRID_NODES` and
:data:`app.service.band_calibration.IDENTIFIED_SIGMA_GRID_NODES`; docs/limits.md, "Factors per
measurement grid").

One factor per snow modulus for both measurement grids had to serve the 9 × 5 skis, whose
covariance understates their error more, and made the 13 × 9 skis' bands wider than 2.5 × their
error. Here each grid gets its own. The input is ``scripts/beam_scale_study.py --rows`` run on
the work folders of own-ski studies: every held-out case answered again, through the service,
at each candidate factor (no linear rescaling of recorded band parts: the spread of the beam
draws is not linear in their factor). Per model (``flexible``: the beam draws' factor;
``rigid``: the identified profile's factor), measurement grid and snow modulus, the rule:

- of the candidates with ≥ 90 % of the reference truths inside the band and a mean half-width
  ≤ 2.5 × the RMS error in every calibration population, the one with the fewest answers more
  than 3 % off, outside the band and without a warning (summed over the populations), the
  smallest of those;
- else the smallest with the coverage alone (coverage first: a band that holds less than it
  says is wrong, a wider one only less sharp); else the largest.

An unwarned miss that no candidate within the width target removes needs a warning, not a wider
band for every answer: the output counts what is left.

The validation populations (``--validation``) are checked at the fitted factors. ``--pool``
also fits on calibration and validation together, and serves the larger factor per node (what
the service serves; the validation is then no longer held out where the pooled fit is larger).

Usage::

    python scripts/beam_scale_study.py --work <own-ski work> --rows --out scan.json \\
        --flex-scales 0.5 1 1.5 2 3 4 6 8 12 --rigid-scales 1 1.5 2 2.5 3 4
    python scripts/per_grid_band_study.py --calibration hand-written=scan-s6.json \\
        random=scan-rnd.json --validation validation=scan-val2.json --pool \\
        --out docs/studies/per-grid-band.json

Seconds: it reads the re-solved answers and solves nothing.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "scripts"))

import beam_scale_study  # noqa: E402
from skisnow.app.service import band_calibration  # noqa: E402
from skisnow.app.storage import common  # noqa: E402

SCHEMA = "skisnow.per-grid-band-study/1"
COVERAGE_TARGET = 0.90
WIDTH_TARGET = 2.5
#: answers this far off (relative) and outside the band must carry a warning
AREA_OFF = beam_scale_study.AREA_OFF
#: the own-ski study's grids, in the order of :data:`band_calibration.GRID_CASES`
GRIDS = ("coarse", "dense")
MODELS = ("flexible", "rigid")


def stats(rows: list[dict]) -> dict:
    """:func:`beam_scale_study.stats` of re-solved answers (share of reference truths inside
    the band, mean half-width ÷ RMS error, answers more than 3 % off, outside the band and
    unwarned: ``unwarned_misses``), with the refused ones counted."""
    st = beam_scale_study.stats(rows)
    refused = len(rows) - st["answers"]
    if not st["answers"]:
        return {"answers": 0, "refused": refused}
    keys = ("coverage", "mean_half_width", "rms_error", "half_width_over_rms")
    return {
        "answers": st["answers"],
        "refused": refused,
        **{k: st[k] for k in keys},
        "unwarned_misses": st["off_3pct_outside_unwarned"],
    }


def read_rows(specs: list[str]) -> dict[str, list[dict]]:
    """``label=path`` of ``beam_scale_study.py --rows`` outputs → rows per label."""
    out: dict[str, list[dict]] = {}
    for spec in specs:
        label, _, path = spec.partition("=")
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
        if "rows" not in doc:
            raise SystemExit(f"{path}: no rows (run beam_scale_study.py with --rows)")
        out.setdefault(label, []).extend(doc["rows"])
    return out


def table(pops: dict[str, list[dict]], model: str, grid: str, e_mpa: float) -> dict:
    """Per candidate factor and population: :func:`stats`."""
    scales = sorted(
        {r["scale"] for rows in pops.values() for r in rows if r["model"] == model},
    )
    out = {}
    for s in scales:
        out[f"{s:g}"] = {
            label: stats(
                [
                    r
                    for r in rows
                    if r["model"] == model
                    and r["grid"] == grid
                    and r["e_snow_mpa"] == e_mpa
                    and r["scale"] == s
                ]
            )
            for label, rows in sorted(pops.items())
        }
    return out


def pick(per_scale: dict) -> tuple[float, str]:
    """The factor by the module's rule, and which of its targets it meets."""

    def ok(st: dict, what: str) -> bool:
        if not st.get("answers"):
            return True
        if what == "coverage":
            return st["coverage"] >= COVERAGE_TARGET
        return (st["half_width_over_rms"] or 0.0) <= WIDTH_TARGET

    def misses(s: str) -> int:
        return sum(st.get("unwarned_misses", 0) for st in per_scale[s].values())

    scales = sorted(per_scale, key=float)
    if not scales:
        return float("nan"), "no answers"
    both = [s for s in scales if all(ok(st, w) for st in per_scale[s].values() for w in WHAT)]
    if both:
        # the fewest unwarned misses the width allows; of those the smallest factor
        best = min(both, key=lambda s: (misses(s), float(s)))
        return float(best), "coverage and width" + (
            ", no unwarned miss" if not misses(best) else ""
        )
    covers = [s for s in scales if all(ok(st, "coverage") for st in per_scale[s].values())]
    if covers:
        return float(covers[0]), "coverage"
    return float(scales[-1]), "none"


WHAT = ("coverage", "width")


def fit(pops: dict[str, list[dict]]) -> dict:
    """Per model, grid and node: the picked factor, what it meets, and the whole table."""
    nodes = {"flexible": band_calibration.BEAM_SCALE_E_SNOW_MPA}
    nodes["rigid"] = band_calibration.IDENTIFIED_SIGMA_E_SNOW_MPA
    out: dict = {}
    for model in MODELS:
        out[model] = {}
        for grid in GRIDS:
            rows = []
            for e in nodes[model]:
                per = table(pops, model, grid, e)
                s, met = pick(per)
                rows.append({"e_snow_mpa": e, "factor": s, "meets": met, "per_scale": per})
            out[model][grid] = rows
    return out


def factors(fitted: dict, model: str) -> list[list[float]]:
    """The fitted factors as the service's table (rows: :data:`GRIDS`)."""
    return [[n["factor"] for n in fitted[model][g]] for g in GRIDS]


def check(pops: dict[str, list[dict]], model: str, table_: list[list[float]]) -> dict:
    """Every population at the given per-grid factors, per grid and node."""
    nodes = (
        band_calibration.BEAM_SCALE_E_SNOW_MPA
        if model == "flexible"
        else band_calibration.IDENTIFIED_SIGMA_E_SNOW_MPA
    )
    out = {}
    for gi, grid in enumerate(GRIDS):
        for e, s in zip(nodes, table_[gi], strict=True):
            per = table(pops, model, grid, e)
            out[f"{grid} | {e:g} MPa | × {s:g}"] = per.get(f"{s:g}", {})
    return out


def merged(a: dict[str, list[dict]], b: dict[str, list[dict]]) -> dict[str, list[dict]]:
    """Populations of ``a`` and ``b``, those of the same label pooled."""
    out = {k: list(v) for k, v in a.items()}
    for k, v in b.items():
        out.setdefault(k, []).extend(v)
    return out


def study(calib: dict, validation: dict, pool: bool) -> dict:
    """Fit on ``calib``; check ``validation`` at the fit; with ``pool`` also fit on both (the
    validation's populations joined to the calibration's of the same label) and serve the
    larger factor per node."""
    fitted = fit(calib)
    res: dict = {"calibration": fitted, "calibration_factors": {}, "validation_checks": {}}
    served = {}
    held_out = {f"{k} (validation)": v for k, v in validation.items()}
    for model in MODELS:
        f = factors(fitted, model)
        res["calibration_factors"][model] = f
        if validation:
            res["validation_checks"][model] = check(held_out, model, f)
        served[model] = f
    if pool and validation:
        pooled = fit(merged(calib, validation))
        res["pooled"] = pooled
        res["pooled_factors"] = {m: factors(pooled, m) for m in MODELS}
        served = {
            m: [
                [max(a, b) for a, b in zip(ra, rb, strict=True)]
                for ra, rb in zip(served[m], res["pooled_factors"][m], strict=True)
            ]
            for m in MODELS
        }
    res["served"] = served
    res["served_checks"] = {m: check({**calib, **held_out}, m, served[m]) for m in MODELS}
    return res


def _print(res: dict) -> None:
    for model in MODELS:
        print(f"{model}:")
        for grid in GRIDS:
            for node in res["calibration"][model][grid]:
                print(
                    f"  {grid:6s} {node['e_snow_mpa']:6g} MPa: × {node['factor']:g} "
                    f"(meets {node['meets']})"
                )
        print(f"  served (rows {', '.join(GRIDS)}): {res['served'][model]}")
        for key, per in res["served_checks"][model].items():
            line = " | ".join(
                f"{label} {st['coverage']:.1%} w {st['half_width_over_rms']:.2f} "
                f"b {st['unwarned_misses']}"
                for label, st in per.items()
                if st.get("answers")
            )
            print(f"    {key}: {line}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--calibration", nargs="+", required=True, help="label=scan.json ...")
    ap.add_argument(
        "--validation",
        nargs="*",
        default=[],
        help="label=scan.json ... (a label of --calibration: pooled into it by --pool)",
    )
    ap.add_argument("--pool", action="store_true")
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "studies" / "per-grid-band.json")
    args = ap.parse_args(argv)
    calib = read_rows(args.calibration)
    validation = read_rows(args.validation)
    res = study(calib, validation, args.pool)
    doc = {
        "schema": SCHEMA,
        "provenance": common.provenance(
            {
                "calibration": args.calibration,
                "validation": args.validation,
                "pool": args.pool,
            }
        ),
        "grids": {"rows": list(GRIDS), "cases": list(band_calibration.GRID_CASES)},
        "targets": {
            "coverage": COVERAGE_TARGET,
            "half_width_over_rms": WIDTH_TARGET,
            "unwarned_misses_above": AREA_OFF,
        },
        **res,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with common.atomic_path(args.out) as tmp:
        tmp.write_text(json.dumps(doc, indent=1), encoding="utf-8")
    _print(res)
    print(f"written {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
