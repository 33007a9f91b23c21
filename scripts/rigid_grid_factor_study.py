"""Rigid answers' apparent-area grid factor and identified-profile factor per snow modulus
(issue #26 point 4; :data:`app.service.band_calibration.RIGID_AREA_GRID_NODES` and
:data:`app.service.band_calibration.IDENTIFIED_SIGMA_NODES`, docs/limits.md "Rigid answers'
grid part per snow modulus").

A rigid answer's apparent-area band has a grid part (``K_END_PIXELS`` × its end-pixel share,
:func:`app.service.band.grid_component`, times the factor fitted here) and, for a ski served by
its identified beam, a camber part (the identified profile's spread × the factor fitted here).
``K_END_PIXELS`` (0.45) was pooled over the demo skis' ``calib`` cases at 10–1000 MPa, mostly
set by soft snow: on stiff snow the grid part alone was 2–5 × the grid's own error, and the
held-out validation designs' bands 3–6 × their RMS error.

The rule, in two steps:

1. **The grid factor** per node of :data:`app.service.band_calibration.RIGID_AREA_GRID_E_SNOW_MPA`
   (one node per calibration modulus): the largest over the node's populations of
   - the grid-only need: the smallest of :data:`GRID_FACTORS` whose grid part alone covers
     ≥ 90 % of the grid's own errors. Populations: the own-ski study's rigid answers per grid
     (the true beam on the answer's grid against it on the reference grid), the demo skis'
     ``calib`` cases (the served profile on the default grid against the fine grid, times the
     true beam on the fine grid against the reference grid) and the two design-beam skis'
     ``calib`` cases (exact beams: their whole error is the grid's);
   - the whole-band need of the demo and design-beam ``calib`` cases (their other parts as
     served: their camber part is not the identified-profile factor's).
2. **The identified-profile factor** per node of
   :data:`app.service.band_calibration.IDENTIFIED_SIGMA_E_SNOW_MPA`: with the grid factor of
   step 1 in place, the smallest of :data:`SIGMA_SCALES` that puts ≥ 90 % of the own-ski
   study's rigid answers inside the whole band on each measurement grid (the largest over the
   grids).

3. **The camber network's factor** (``NETWORK_SIGMA_SCALE``): with the grid factor in place,
   the smallest scale ``network_band_study.py`` recorded with ≥ 90 % of its ``calib`` cases
   inside at every modulus (its rule).

So the grid part estimates the grid's error, and the camber part carries what the identified
profile's spread misses. Each answer's recorded band parts are recombined in quadrature with
its grid part and camber part rescaled from the factors it was served with. Checks, with the
factors interpolated as the service does: the calibration test's cases (the demo skis'
``test`` set, tests/service/test_band.py), the held-out validation designs
(``own_ski_study.py --designs`` with ``solvers.ski_designs.VALIDATION_DESIGNS``), and the skis
served by their camber networks (``scripts/network_band_study.py``, at ``NETWORK_SIGMA_SCALE``).

Usage::

    python scripts/band_calibration_study.py --reference-every 1 \\
        --out docs/studies/band-calibration-rows.json  # about 45 min
    python scripts/rigid_grid_factor_study.py \\
        --calibration docs/studies/band-calibration-rows.json \\
        --own-ski docs/studies/own-ski-study.json docs/studies/own-ski-random.json \\
        --validation docs/studies/own-ski-validation.json docs/studies/own-ski-random-check.json \\
        --network docs/studies/network-band.json --out docs/studies/rigid-grid-factor.json

Seconds: it reads the answers those studies recorded and solves nothing.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "scripts"))

from band_calibration_study import read_rows  # noqa: E402
from flexible_grid_factor_study import (  # noqa: E402
    COVERAGE_TARGET,
    GRID_FACTORS,
    OWN_SKI_FILES,
    fit_grid_only,
    grid_only_stats,
    interpolated,
    random_suffix,
    read_own_ski,
)
from skisnow.app.service import band_calibration  # noqa: E402
from skisnow.app.storage import common  # noqa: E402

SCHEMA = "skisnow.rigid-grid-factor-study/1"
QUANTITY = "apparent_contact_area"
#: candidate factors on the identified profile's spread
SIGMA_SCALES = (0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0)
#: the identified-profile factors served before this study (its grid factor was 1; a check
#: column)
BEFORE_SIGMA_NODES = (1.5, 2.0, 2.5)
#: sources whose cases calibrate (the others are checks)
CALIBRATION_SOURCES = (
    "demo calib",
    "design calib",
    "own-ski dense",
    "own-ski coarse",
    "own-ski random dense",
    "own-ski random coarse",
)


def _q(values: dict) -> float:
    return float(values[QUANTITY])


def _other_parts(components: dict) -> float:
    """The apparent area's band parts other than the grid part, in quadrature (a study row's
    recorded ``components``)."""
    return math.sqrt(
        sum((p.get(QUANTITY) or 0.0) ** 2 for name, p in components.items() if name != "macro_grid")
    )


def calibration_cases(rows: list[dict]) -> list[dict]:
    """The ``band_calibration_study.py`` rows with a reference truth: per case its modulus, its
    error against the truth (relative to the truth, as tests/service/test_band.py judges it),
    its fixed band parts (``other``: everything but the grid part), its grid part at factor 1
    (``part_at_1``) and the grid's own error (``grid_error``)."""
    out = []
    for r in rows:
        v = r.get("values") or {}
        if "reference" not in v or "components" not in r:
            continue
        comps = r["components"]
        ref, ans = _q(v["reference"]), _q(v["default"])
        design = r["ski"] not in ("ski-a", "ski-b")
        # an exact beam: the whole error is the grid's; a served profile: its own grid error
        # (default against fine) and the fine grid's (the true beam, fine against reference)
        grid_error = (
            abs(ans / ref - 1) if design else abs(ans / _q(v["fine"]) * _q(v["truth"]) / ref - 1)
        )
        out.append(
            {
                "source": f"{'design' if design else 'demo'} {r['set']}",
                "e_snow_mpa": float(r["e_snow_mpa"]),
                "error": abs(ans / ref - 1),
                "other": _other_parts(comps),
                "camber_at_1": 0.0,
                # undone from the factor it was served with (rows written before the factor
                # was per snow modulus record none: 1)
                "part_at_1": comps["macro_grid"][QUANTITY]
                / ((r.get("grid_factors") or {}).get(QUANTITY) or 1.0),
                "grid_error": grid_error,
                "warned": None,
            }
        )
    return out


def own_ski_cases(study: dict, source: str = "own-ski") -> list[dict]:
    """The rigid answers of an own-ski study: the fields of :func:`calibration_cases` (the error
    relative to the answer, as its band), the camber part at factor 1 (``camber_at_1``, undone
    from the factor it was served with) and whether the answer warned."""
    out = []
    for ski in study["skis"]:
        for case in ski.get("answers", []):
            a = case.get("rigid") or {}
            ref = (case.get("truth_ref_cm2") or {}).get("rigid")
            comps = a.get("area_components")
            if a.get("status") != 200 or ref is None or not comps or not a.get("camber_scale"):
                continue
            truth = case["truth_cm2"]["rigid"]
            out.append(
                {
                    # random designs: a population of their own (a node takes the largest need)
                    "source": f"{source}{random_suffix(ski)} {ski['grid']}",
                    "draw": ski["draw"],
                    "design": ski["design"],
                    "e_snow_mpa": float(case["snow_modulus_mpa"]),
                    "error": abs(a["area_cm2"] - ref) / a["area_cm2"],
                    "other": math.sqrt(
                        sum(
                            v * v
                            for p, v in comps.items()
                            if p not in ("camber_model", "macro_grid") and v is not None
                        )
                    ),
                    "camber_at_1": (comps.get("camber_model") or 0.0) / a["camber_scale"],
                    "part_at_1": comps.get("macro_grid", 0.0) / (a.get("area_grid_factor") or 1.0),
                    "grid_error": abs(truth - ref) / truth,
                    "warned": bool(a.get("warnings")),
                }
            )
    return out


def network_cases(doc: dict, scale: float) -> list[dict]:
    """The ``network_band_study.py`` rows at the served ``NETWORK_SIGMA_SCALE`` (their truth: the
    design beam on the fine preset; a check, not a calibration)."""
    out = []
    for r in doc["rows"]:
        if r.get("scale") != scale or "components" not in r:
            continue
        comps = r["components"]
        out.append(
            {
                "source": f"network {r['set']}",
                "e_snow_mpa": float(r["e_snow_mpa"]),
                "error": abs(r["error"][QUANTITY]),
                "other": _other_parts(comps),
                "camber_at_1": 0.0,
                "part_at_1": comps["macro_grid"][QUANTITY],
                "grid_error": None,
                "warned": bool(r.get("warned")),
            }
        )
    return out


def _at(f, e: float) -> float:
    return float(f(e)) if callable(f) else float(f)


def band_stats(cases: list[dict], grid, sigma) -> dict:
    """Coverage, mean half-width ÷ RMS error and unwarned misses (> 3 % off, outside, no
    warning) of ``cases`` with the grid part × ``grid`` and the camber part × ``sigma`` (numbers
    or callables of the snow modulus [MPa])."""
    if not cases:
        return {"cases": 0}
    err = np.array([c["error"] for c in cases])
    g = np.array([_at(grid, c["e_snow_mpa"]) for c in cases])
    s = np.array([_at(sigma, c["e_snow_mpa"]) for c in cases])
    width = np.sqrt(
        np.array([c["other"] for c in cases]) ** 2
        + (s * np.array([c["camber_at_1"] for c in cases])) ** 2
        + (g * np.array([c["part_at_1"] for c in cases])) ** 2
    )
    rms = float(np.sqrt(np.mean(err**2)))
    warned = np.array([bool(c["warned"]) for c in cases])
    return {
        "cases": len(cases),
        "coverage": float(np.mean(err <= width)),
        "mean_half_width": float(width.mean()),
        "rms_error": rms,
        "half_width_over_rms": float(width.mean() / rms) if rms > 0 else None,
        "unwarned_misses": int(np.sum((err > 0.03) & (err > width) & ~warned)),
    }


def populations(cases: list[dict]) -> dict[tuple[str, float], list[dict]]:
    out: dict[tuple[str, float], list[dict]] = {}
    for c in cases:
        out.setdefault((c["source"], c["e_snow_mpa"]), []).append(c)
    return out


def fit_whole_band(cases: list[dict], sigma: float = 1.0) -> float:
    """The smallest of :data:`GRID_FACTORS` that puts ≥ 90 % of ``cases`` inside their whole
    band (the largest when none does)."""
    for k in GRID_FACTORS:
        if band_stats(cases, k, sigma)["coverage"] >= COVERAGE_TARGET:
            return k
    return GRID_FACTORS[-1]


def fit_grid_nodes(cases: list[dict], nodes_mpa) -> dict:
    """Step 1 of the module docstring: the grid factor per node and what set it."""
    pops = populations([c for c in cases if c["source"] in CALIBRATION_SOURCES])
    values, per_node = [], {}
    for e in nodes_mpa:
        needs = {}
        for (src, pe), sel in pops.items():
            if pe != e:
                continue
            need = {"grid_only": fit_grid_only(sel), "cases": len(sel)}
            if not src.startswith("own-ski"):
                need["whole_band"] = fit_whole_band(sel)
            needs[src] = need
        if not needs:
            raise ValueError(f"no calibration population at the node {e:g} MPa")
        k = max(max(n["grid_only"], n.get("whole_band", 0.0)) for n in needs.values())
        values.append(k)
        per_node[f"{e:g} MPa"] = {"factor": k, "needs": needs}
    return {"nodes_e_snow_mpa": list(nodes_mpa), "fitted": values, "per_node": per_node}


def fit_sigma_nodes(own: list[dict], grid, nodes_mpa) -> dict:
    """Step 2: per node, the smallest of :data:`SIGMA_SCALES` with ≥ 90 % of each measurement
    grid's own-ski answers at that modulus inside, with the grid factor ``grid`` in place."""
    values, per_node = [], {}
    for e in nodes_mpa:
        per = {}
        for src in sorted({c["source"] for c in own}):
            sel = [c for c in own if c["source"] == src and c["e_snow_mpa"] == e]
            if not sel:
                continue
            s = next(
                (
                    s
                    for s in SIGMA_SCALES
                    if band_stats(sel, grid, s)["coverage"] >= COVERAGE_TARGET
                ),
                SIGMA_SCALES[-1],
            )
            per[src] = {"factor": s, "at_factor": band_stats(sel, grid, s)}
        if not per:
            raise ValueError(f"no own-ski answers at the node {e:g} MPa")
        values.append(max(p["factor"] for p in per.values()))
        per_node[f"{e:g} MPa"] = {"factor": values[-1], "per_grid": per}
    return {"nodes_e_snow_mpa": list(nodes_mpa), "fitted": values, "per_node": per_node}


def fit_network_scale(doc: dict, grid) -> dict:
    """Step 3: ``NETWORK_SIGMA_SCALE`` with the grid factor ``grid`` in place, by its rule (the
    smallest scale the network study recorded with ≥ 90 % of ``calib`` inside at every
    modulus); ``test`` is the check."""
    scales = sorted({float(r["scale"]) for r in doc["rows"] if "scale" in r})
    per_scale, pick = {}, None
    for scale in scales:
        cases = network_cases(doc, scale)
        stats = {
            f"{src} | {e:g} MPa": band_stats(sel, grid, 1.0)
            for (src, e), sel in sorted(populations(cases).items())
        }
        per_scale[f"{scale:g}"] = stats
        calib = [v for k, v in stats.items() if k.startswith("network calib")]
        if pick is None and calib and all(v["coverage"] >= COVERAGE_TARGET for v in calib):
            pick = scale
    return {"fitted": pick if pick is not None else scales[-1], "per_scale": per_scale}


def study(calib: list[dict], own: list[dict], checks: list[dict], network: dict | None) -> dict:
    grid_nodes = band_calibration.RIGID_AREA_GRID_E_SNOW_MPA
    sigma_nodes = band_calibration.IDENTIFIED_SIGMA_E_SNOW_MPA
    g = fit_grid_nodes(calib + own, grid_nodes)
    grid_fit = interpolated(grid_nodes, g["fitted"])
    s = fit_sigma_nodes(own, grid_fit, sigma_nodes)
    sigma_fit = interpolated(sigma_nodes, s["fitted"])
    served = (
        interpolated(grid_nodes, band_calibration.RIGID_AREA_GRID_NODES),
        interpolated(sigma_nodes, band_calibration.IDENTIFIED_SIGMA_NODES),
    )
    before = (1.0, interpolated(sigma_nodes, BEFORE_SIGMA_NODES))
    table = {}
    for (src, e), sel in sorted(populations(calib + own + checks).items()):
        table[f"{src} | {e:g} MPa"] = {
            "calibrates": src in CALIBRATION_SOURCES,
            "fitted": band_stats(sel, grid_fit, sigma_fit),
            "served": band_stats(sel, *served),
            "before": band_stats(sel, *before),
            "grid_only_at_fitted": (
                grid_only_stats(sel, grid_fit(e)) if sel[0]["grid_error"] is not None else None
            ),
        }
    out = {"grid_factor": g, "identified_sigma": s, "checks": table}
    if network is not None:
        out["network_sigma_scale"] = fit_network_scale(network, grid_fit)
    return out


def _fmt(s: dict) -> str:
    if not s.get("cases"):
        return "– | –"
    r = s["half_width_over_rms"]
    return f"{s['coverage']:.1%} | {r:.2f}" if r is not None else f"{s['coverage']:.1%} | –"


def _print(res: dict) -> None:
    g = res["grid_factor"]
    print("grid factor nodes [MPa]:", g["nodes_e_snow_mpa"], "fitted:", g["fitted"])
    for node, r in g["per_node"].items():
        print(f"  {node}: {r['factor']:g}  ", r["needs"])
    s = res["identified_sigma"]
    print("identified-profile factor nodes [MPa]:", s["nodes_e_snow_mpa"], "fitted:", s["fitted"])
    for node, r in s["per_node"].items():
        print(f"  {node}: {r['factor']:g}  ", {k: v["factor"] for k, v in r["per_grid"].items()})
    if "network_sigma_scale" in res:
        n = res["network_sigma_scale"]
        print("NETWORK_SIGMA_SCALE fitted:", n["fitted"])
        for scale, stats in n["per_scale"].items():
            print(f"  × {scale}: " + ", ".join(f"{k} {_fmt(v)}" for k, v in stats.items()))
    print(
        "| population | fitted inside | ratio | misses | served inside | ratio "
        "| before inside | ratio | misses |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for name, r in res["checks"].items():
        mark = "" if r["calibrates"] else " (check)"
        print(
            f"| {name}{mark} ({r['fitted']['cases']}) | {_fmt(r['fitted'])} | "
            f"{r['fitted']['unwarned_misses']} | {_fmt(r['served'])} | {_fmt(r['before'])} | "
            f"{r['before']['unwarned_misses']} |"
        )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--calibration",
        type=Path,
        default=REPO / "docs" / "studies" / "band-calibration-rows.json",
        help="band_calibration_study.py --reference-every 1 rows",
    )
    ap.add_argument(
        "--own-ski",
        type=Path,
        nargs="+",
        default=list(OWN_SKI_FILES),
        help="own_ski_study.py results that calibrate, pooled (the study's designs, random ones)",
    )
    ap.add_argument(
        "--validation",
        type=Path,
        nargs="+",
        default=[
            REPO / "docs" / "studies" / "own-ski-validation.json",
            REPO / "docs" / "studies" / "own-ski-random-check.json",
        ],
        help="own_ski_study.py results held out (checks)",
    )
    ap.add_argument("--network", type=Path, default=REPO / "docs" / "studies" / "network-band.json")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)

    def load(path: Path):
        return json.loads(path.read_text(encoding="utf-8"))

    own_study = read_own_ski(args.own_ski)
    calib = calibration_cases(read_rows(args.calibration))
    own = own_ski_cases(own_study)
    network = load(args.network)
    checks = own_ski_cases(read_own_ski(args.validation), "validation") + network_cases(
        network, band_calibration.NETWORK_SIGMA_SCALE
    )
    res = study(calib, own, checks, network)
    _print(res)
    if args.out:
        params = {
            "calibration": str(args.calibration),
            "own_ski": [str(p) for p in args.own_ski],
            "own_ski_commit": own_study.get("provenance", {}).get("git_commit"),
            "validation": [str(p) for p in args.validation],
            "network": str(args.network),
            "coverage_target": COVERAGE_TARGET,
        }
        common.write_study_json(args.out, SCHEMA, params, res)
        print("written", args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
