"""The identified beam's two band factors refitted after the covariance fix of 2026-11-27
(issue #26 point 4; docs/limits.md, "The covariance's cut-off").

The forward fit's covariance used to drop, through a pseudo-inverse cut-off, every direction
only the smoothing prior held, and reported zero variance there (the tip and tail beyond the
device's contact points, part of the fore- and afterbody). The factors on the beam draws
(:data:`app.service.band_calibration.BEAM_SCALE_NODES`, bending-ski answers) and on the
identified profile's spread (:data:`app.service.band_calibration.IDENTIFIED_SIGMA_NODES`,
rigid answers) were calibrated on that covariance and stood in for the missing variance. With
the fixed covariance both are fitted again, by their own rules, on own-ski studies run with
the fixed identification:

- the beam-draw factor per node: :func:`flexible_grid_factor_study.fit_beam_scales` (the
  smallest candidate with ≥ 90 % inside in every population, hand-written and random designs
  per grid, and every population's mean half-width ≤ 2.5 × its RMS error; else the smallest
  that covers), with the bending ski's grid part at its grid-only floor
  (:data:`app.service.band_calibration.FLEXIBLE_AREA_GRID_NODES` from 20 MPa up);
- the identified-profile factor per node: :func:`rigid_grid_factor_study.fit_sigma_nodes`
  (the smallest with ≥ 90 % of each population's rigid answers inside), with the rigid grid
  factors as served (:data:`app.service.band_calibration.RIGID_AREA_GRID_NODES`).

The grid factors are not refitted: they estimate the grid's own error, which the covariance
does not touch. Each answer's recorded band parts are recombined with the factor's part
rescaled linearly from the factor it was served with. Checks: the held-out studies
(``--validation``) at the fitted factors: coverage, mean half-width ÷ RMS error and unwarned
misses per population and snow modulus.

Usage::

    python scripts/covariance_refit_study.py \\
        --own-ski docs/studies/own-ski-cov.json docs/studies/own-ski-cov-random.json \\
        --validation docs/studies/own-ski-cov-validation.json --pool \\
        --out docs/studies/covariance-refit.json

``--pool`` also fits on calibration and validation together and serves the larger factor per
node (what the service serves; the validation is then no longer held out).

Seconds: it reads the answers those studies recorded and solves nothing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "scripts"))

import flexible_grid_factor_study as fgs  # noqa: E402
import rigid_grid_factor_study as rgs  # noqa: E402
from skisnow.app.service import band_calibration  # noqa: E402
from skisnow.app.storage import common  # noqa: E402

SCHEMA = "skisnow.covariance-refit-study/1"
#: the bending ski's grid factor from 20 MPa up (its grid-only floor)
FLEXIBLE_GRID_FLOOR = band_calibration.FLEXIBLE_AREA_GRID_NODES[1]


def flexible_checks(cases: list[dict], scales) -> dict:
    """Per population and node modulus: :func:`flexible_grid_factor_study.beam_scale_stats` at
    the node's factor."""
    out = {}
    for e, s in zip(band_calibration.BEAM_SCALE_E_SNOW_MPA, scales, strict=True):
        pops: dict[str, list[dict]] = {}
        for c in cases:
            if c["e_snow_mpa"] == e:
                pops.setdefault(c["source"], []).append(c)
        for name, sel in sorted(pops.items()):
            out[f"{name} | {e:g} MPa"] = fgs.beam_scale_stats(sel, s, FLEXIBLE_GRID_FLOOR)
    return out


def _rigid_grid():
    """The rigid grid factor as served (a callable of the snow modulus [MPa])."""
    return rgs.interpolated(
        band_calibration.RIGID_AREA_GRID_E_SNOW_MPA, band_calibration.RIGID_AREA_GRID_NODES
    )


def rigid_checks(cases: list[dict], sigma_nodes) -> dict:
    """Per population and modulus: :func:`rigid_grid_factor_study.band_stats` with the served
    grid factors and the identified-profile factor ``sigma_nodes``."""
    grid = _rigid_grid()
    sigma = rgs.interpolated(band_calibration.IDENTIFIED_SIGMA_E_SNOW_MPA, sigma_nodes)
    return {
        f"{src} | {e:g} MPa": rgs.band_stats(sel, grid, sigma)
        for (src, e), sel in sorted(rgs.populations(cases).items())
    }


def fit(own: dict) -> tuple[dict, dict]:
    """Both rules on the own-ski study ``own``: (beam-draw fit, identified-profile fit)."""
    beam = fgs.fit_beam_scales(fgs.own_ski_cases(own, None), FLEXIBLE_GRID_FLOOR)
    grid = _rigid_grid()
    sigma = rgs.fit_sigma_nodes(
        rgs.own_ski_cases(own), grid, band_calibration.IDENTIFIED_SIGMA_E_SNOW_MPA
    )
    return beam, sigma


def study(own: dict, validation: dict | None, pool: bool = False) -> dict:
    """The fits on ``own`` and their checks. ``pool``: also fit on ``own`` and ``validation``
    together, and serve per node the larger of the two fits (coverage first); the validation
    is then no longer held out, and its checks say so (``validation_pooled``)."""
    beam, sigma = fit(own)
    served = {"beam_scale": list(beam["fitted"]), "identified_sigma": list(sigma["fitted"])}
    out = {"beam_scale": beam, "identified_sigma": sigma}
    if pool and validation is not None:
        both = {"skis": own["skis"] + validation["skis"]}
        p_beam, p_sigma = fit(both)
        out["pooled"] = {"beam_scale": p_beam, "identified_sigma": p_sigma}
        served = {
            "beam_scale": [
                max(a, b) for a, b in zip(beam["fitted"], p_beam["fitted"], strict=True)
            ],
            "identified_sigma": [
                max(a, b) for a, b in zip(sigma["fitted"], p_sigma["fitted"], strict=True)
            ],
        }
    out["served"] = served
    out["validation_pooled"] = bool(pool and validation is not None)
    out["calibration"] = {
        "flexible": flexible_checks(fgs.own_ski_cases(own, None), served["beam_scale"]),
        "rigid": rigid_checks(rgs.own_ski_cases(own), served["identified_sigma"]),
    }
    if validation is not None:
        out["validation"] = {
            "flexible": flexible_checks(fgs.own_ski_cases(validation, None), served["beam_scale"]),
            "rigid": rigid_checks(
                rgs.own_ski_cases(validation, "validation"), served["identified_sigma"]
            ),
        }
    return out


def _print(res: dict) -> None:
    print("beam-draw factor per node:", res["beam_scale"]["fitted"])
    for node, v in res["beam_scale"]["per_node"].items():
        print(f"  {node}: × {v['factor']:g} (both targets met: {v['met']})")
    print("identified-profile factor per node:", res["identified_sigma"]["fitted"])
    if "pooled" in res:
        print(
            "pooled with the validation:",
            res["pooled"]["beam_scale"]["fitted"],
            "and",
            res["pooled"]["identified_sigma"]["fitted"],
        )
    print("served (beam draws, identified profile):", res["served"])
    for part in ("calibration", "validation"):
        if part not in res:
            continue
        for kind, table in res[part].items():
            print(
                f"\n{part}, {kind}: | population | cases | inside | half-width / RMS | unwarned |"
            )
            for name, s in table.items():
                ratio = s.get("half_width_over_rms")
                print(
                    f"| {name} | {s['cases']} | {s['coverage']:.1%} | "
                    f"{'–' if ratio is None else f'{ratio:.2f}'} | "
                    f"{s.get('unwarned_misses', '–')} |"
                )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--own-ski", type=Path, nargs="+", required=True, help="calibration studies")
    ap.add_argument("--validation", type=Path, nargs="*", default=[], help="held-out studies")
    ap.add_argument(
        "--pool",
        action="store_true",
        help="also fit with the validation pooled in; serve the larger of the two per node",
    )
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    own = fgs.read_own_ski(args.own_ski)
    validation = fgs.read_own_ski(args.validation) if args.validation else None
    res = study(own, validation, pool=args.pool)
    _print(res)
    if args.out:
        params = {
            "own_ski": [str(p) for p in args.own_ski],
            "own_ski_commit": own.get("provenance", {}).get("git_commit"),
            "validation": [str(p) for p in args.validation],
            "flexible_grid_floor": FLEXIBLE_GRID_FLOOR,
            "rigid_grid_nodes": list(band_calibration.RIGID_AREA_GRID_NODES),
            "coverage_target": fgs.COVERAGE_TARGET,
            "pool": bool(args.pool),
        }
        common.write_study_json(args.out, SCHEMA, params, res)
        print("written", args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
