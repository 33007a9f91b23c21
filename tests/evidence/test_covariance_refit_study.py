"""The band factors refitted after the covariance's cut-off was fixed
(scripts/covariance_refit_study.py, docs/limits.md "The covariance's cut-off")."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from skisnow.app.service import band_calibration

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import covariance_refit_study as crs  # noqa: E402


def _answer(e, error, camber, scale, grid=0.01, warned=False):
    """An own-ski study answer (rigid and flexible alike) at ``e`` MPa: ``error`` off the
    reference truth, its camber part ``camber`` served at factor ``scale``."""
    part = {
        "status": 200,
        "area_cm2": 100.0,
        "area_components": {"camber_model": camber, "macro_grid": grid},
        "area_grid_factor": 1.0,
        "camber_scale": scale,
        "warnings": ["x"] if warned else [],
    }
    return {
        "snow_modulus_mpa": e,
        "truth_cm2": {"rigid": 100.0, "flexible": 100.0},
        "truth_ref_cm2": {"rigid": 100.0 * (1 - error), "flexible": 100.0 * (1 - error)},
        "rigid": part,
        "flexible": part,
    }


def test_refit_takes_each_rule_on_the_recorded_parts():
    # camber parts 1 % per unit factor (served at × 2: 2 %), errors 2.5 %: the beam draws need
    # × 3 with the grid part at its floor; the rigid rule the smallest of its candidates
    answers = [_answer(e, 0.025, 0.02, 2.0) for e in (20.0, 200.0, 2000.0) for _ in range(5)]
    ski = {"design": "race-classic", "grid": "dense", "draw": 0, "answers": answers}
    res = crs.study({"skis": [ski]}, {"skis": [ski]})
    assert res["beam_scale"]["fitted"] == [3.0, 3.0, 3.0]
    assert res["served"]["beam_scale"] == [3.0, 3.0, 3.0] and not res["validation_pooled"]
    # a validation that needs more: pooled, the larger fit is served
    hard = [_answer(e, 0.05, 0.02, 2.0) for e in (20.0, 200.0, 2000.0) for _ in range(30)]
    val = {"skis": [{**ski, "design": "mid-classic", "answers": hard}]}
    pooled = crs.study({"skis": [ski]}, val, pool=True)
    assert pooled["validation_pooled"]
    assert pooled["served"]["beam_scale"] == pooled["pooled"]["beam_scale"]["fitted"]
    assert all(a > 3.0 for a in pooled["served"]["beam_scale"])
    grid = crs.rgs.interpolated(
        band_calibration.RIGID_AREA_GRID_E_SNOW_MPA, band_calibration.RIGID_AREA_GRID_NODES
    )
    for e, s in zip((20.0, 200.0, 2000.0), res["identified_sigma"]["fitted"], strict=True):
        # the smallest candidate whose camber part (× s, 1 % each) with the grid's covers 2.5 %
        k = grid(e)
        assert (s * 0.01) ** 2 + (k * 0.01) ** 2 >= 0.025**2 - 1e-12
        smaller = [c for c in crs.rgs.SIGMA_SCALES if c < s]
        assert all((c * 0.01) ** 2 + (k * 0.01) ** 2 < 0.025**2 for c in smaller)
    checks = res["validation"]["flexible"]
    assert all(v["coverage"] == pytest.approx(1.0) for v in checks.values())


def test_the_service_serves_what_the_committed_refit_fitted():
    doc = json.loads((REPO / "docs/studies/covariance-refit.json").read_text(encoding="utf-8"))
    # what it served until the factors went per measurement grid
    # (docs/studies/per-grid-band.json, tests/evidence/test_per_grid_band_study.py)
    assert doc["served"]["beam_scale"] == [1.25, 6.0, 8.0]
    assert doc["served"]["identified_sigma"] == [3.0, 1.5, 2.5]
    # the larger per node of the calibration-only fit and the fit pooled with the validation
    for key in ("beam_scale", "identified_sigma"):
        alone, pooled = doc[key]["fitted"], doc["pooled"][key]["fitted"]
        assert doc["served"][key] == [max(a, b) for a, b in zip(alone, pooled, strict=True)]
    # calibrated on random designs too, ≥ 90 % of every calibration population inside
    assert any("random" in name for name in doc["calibration"]["flexible"])
    for kind in ("flexible", "rigid"):
        for name, stats in doc["calibration"][kind].items():
            assert stats["coverage"] >= 0.9, (kind, name)


def test_the_fixed_covariance_describes_eis_error_better_than_the_cut_one():
    """On every ski of the refit's studies the fixed covariance puts at least as many stiffness
    knots within 2 σ of the truth as the cut one did, and no knot has zero variance."""
    doc = json.loads((REPO / "docs/studies/covariance-z-scores.json").read_text(encoding="utf-8"))
    assert len(doc["skis"]) >= 12
    for r in doc["skis"]:
        assert r["scaled"]["share_within_2_sd"] >= r["plain"]["share_within_2_sd"] - 0.05, r
        assert r["scaled"]["zero_sd_knots"] == 0, r
    worse = [r for r in doc["skis"] if r["plain"]["max_z"] > 10 * r["scaled"]["max_z"]]
    assert len(worse) >= len(doc["skis"]) // 2
