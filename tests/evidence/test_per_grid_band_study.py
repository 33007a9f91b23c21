"""The identified beam's band factors per measurement grid (scripts/per_grid_band_study.py,
docs/limits.md "Factors per measurement grid")."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from skisnow.app.service import band_calibration

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import per_grid_band_study as pgs  # noqa: E402


def _row(model, grid, e, scale, error, half_width, warned=False):
    """A re-solved answer of ``beam_scale_study.py --rows``: ``error`` relative off the
    reference truth, band ± ``half_width``."""
    return {
        "model": model,
        "grid": grid,
        "e_snow_mpa": e,
        "scale": scale,
        "area_cm2": 100.0 * (1 + error),
        "truth_ref_cm2": 100.0,
        "half_width": half_width,
        "components": {},
        "warnings": ["x"] if warned else [],
    }


def _population(errors, half_width_at_1, scales, model="flexible", grid="coarse", e=20.0):
    """Answers whose half-width grows linearly with the factor."""
    return [_row(model, grid, e, s, err, half_width_at_1 * s) for s in scales for err in errors]


def test_stats_count_coverage_width_and_unwarned_misses():
    rows = [
        _row("flexible", "dense", 20.0, 1.0, 0.01, 0.02),  # inside
        _row("flexible", "dense", 20.0, 1.0, 0.05, 0.02),  # out, > 3 %, unwarned
        _row("flexible", "dense", 20.0, 1.0, 0.05, 0.02, warned=True),  # out, warned
        _row("flexible", "dense", 20.0, 1.0, -0.02, 0.01),  # out, < 3 %
    ]
    st = pgs.stats(rows)
    assert st["answers"] == 4 and st["coverage"] == pytest.approx(0.25)
    assert st["unwarned_misses"] == 1
    rms = (sum(e * e for e in (0.01, 0.05, 0.05, -0.02)) / 4) ** 0.5
    assert st["half_width_over_rms"] == pytest.approx(0.0175 / rms, rel=1e-3)
    assert pgs.stats([{"model": "flexible", "error": "refused"}]) == {"answers": 0, "refused": 1}


def test_pick_takes_the_fewest_unwarned_misses_within_the_width_target():
    """Errors 1 … 10 % (RMS ≈ 6.2 %): a half-width of 1 % × the factor covers 90 % from × 9 on
    and stays within 2.5 × the RMS error up to × 15; × 9 leaves the 10 % answer outside
    without a warning, × 12 covers it."""
    errors = [0.01 * k for k in range(1, 11)]
    scales = (1.0, 4.0, 8.0, 9.0, 12.0, 16.0)
    pops = {"a": _population(errors, 0.01, scales)}
    per = pgs.table(pops, "flexible", "coarse", 20.0)
    assert per["8"]["a"]["coverage"] == pytest.approx(0.8)
    assert per["9"]["a"]["unwarned_misses"] == 1 and per["12"]["a"]["unwarned_misses"] == 0
    assert per["16"]["a"]["half_width_over_rms"] > pgs.WIDTH_TARGET
    assert pgs.pick(per) == (12.0, "coverage and width, no unwarned miss")
    # the same answer with a warning: × 9 already meets every target
    for r in pops["a"]:
        if r["area_cm2"] > 109.9:
            r["warnings"] = ["x"]
    assert pgs.pick(pgs.table(pops, "flexible", "coarse", 20.0)) == (
        9.0,
        "coverage and width, no unwarned miss",
    )


def test_pick_puts_coverage_first_when_no_factor_meets_the_width():
    """A second population whose band is far wider than its error at every factor: the width
    target cannot be met, and the smallest factor that covers every population is taken."""
    errors = [0.01 * k for k in range(1, 11)]
    scales = (1.0, 4.0, 8.0, 9.0, 12.0, 16.0)
    wide = [
        _row("flexible", "coarse", 20.0, s, err, hw * s)
        for s in scales
        for err, hw in [(0.0, 0.5)] * 9 + [(0.01, 0.001)]
    ]
    pops = {"a": _population(errors, 0.01, scales), "wide": wide}
    per = pgs.table(pops, "flexible", "coarse", 20.0)
    assert all(per[k]["wide"]["half_width_over_rms"] > pgs.WIDTH_TARGET for k in per)
    assert pgs.pick(per) == (9.0, "coverage")


def test_a_population_that_no_factor_covers_gets_the_largest():
    pops = {"a": _population([0.5], 0.001, (1.0, 2.0))}
    assert pgs.pick(pgs.table(pops, "flexible", "coarse", 20.0)) == (2.0, "none")


def test_pooling_joins_populations_of_the_same_label_and_serves_the_larger():
    scales = (1.0, 2.0, 4.0, 8.0)
    calib = {"hand": _population([0.01] * 9 + [0.02], 0.01, scales)}  # × 1 covers 90 %
    val = {"hand": _population([0.07] * 10, 0.01, scales)}  # needs × 8
    res = pgs.study(calib, val, pool=True)
    assert res["calibration_factors"]["flexible"][0][0] == 1.0
    checks = res["validation_checks"]["flexible"]
    assert checks["coarse | 20 MPa | × 1"]["hand (validation)"]["coverage"] == 0.0
    # pooled, 20 answers: × 4 leaves out the 10 validation answers (50 %); × 8 covers them
    assert res["pooled_factors"]["flexible"][0][0] == 8.0
    assert res["served"]["flexible"][0][0] == 8.0
    assert pgs.merged(calib, val)["hand"] == calib["hand"] + val["hand"]


def test_the_service_serves_what_the_committed_study_fitted():
    doc = json.loads((REPO / "docs/studies/per-grid-band.json").read_text(encoding="utf-8"))
    assert doc["grids"]["cases"] == list(band_calibration.GRID_CASES)
    # the flexible table: this study's, but for the cells refitted since
    # (tests/evidence/test_beam_scale_refit_study.py)
    refitted = {
        (pgs.GRIDS.index(g), list(band_calibration.BEAM_SCALE_E_SNOW_MPA).index(e))
        for g, e in band_calibration.BEAM_SCALE_REFITS
    }
    for i, row in enumerate(band_calibration.BEAM_SCALE_GRID_NODES):
        for j, k in enumerate(row):
            if (i, j) not in refitted:
                assert k == doc["served"]["flexible"][i][j], (i, j)
    assert doc["served"]["rigid"] == [list(r) for r in band_calibration.IDENTIFIED_SIGMA_GRID_NODES]
    # the larger per node of the calibration-only fit and the pooled one
    for model in pgs.MODELS:
        alone, pooled = doc["calibration_factors"][model], doc["pooled_factors"][model]
        want = [
            [max(a, b) for a, b in zip(ra, rb, strict=True)]
            for ra, rb in zip(alone, pooled, strict=True)
        ]
        assert doc["served"][model] == want
    # calibrated on hand-written and random designs; at the served factors every population,
    # the validation's included, holds ≥ 90 % of its re-solved answers
    labels = {label for per in doc["served_checks"]["flexible"].values() for label in per}
    assert any("random" in x for x in labels) and any("validation" in x for x in labels)
    for model in pgs.MODELS:
        for key, per in doc["served_checks"][model].items():
            for label, st in per.items():
                assert st["answers"] > 0 and st["coverage"] >= 0.9, (model, key, label)
