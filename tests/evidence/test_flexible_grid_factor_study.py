"""The bending ski's apparent-area grid factor rule (``scripts/flexible_grid_factor_study.py``):
its band recombination, the smallest factor with ≥ 90 % inside, and which populations calibrate
which node, on cases written here with known answers."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import flexible_grid_factor_study as fgs  # noqa: E402


def _case(err, other, part_at_1, e=200.0, source="own-ski dense", grid_error=0.0):
    return {
        "source": source,
        "e_snow_mpa": e,
        "error": err,
        "other": other,
        "part_at_1": part_at_1,
        "grid_error": grid_error,
    }


def test_band_recombines_the_rescaled_grid_part_in_quadrature():
    cases = [_case(0.05, 0.03, 0.02), _case(0.01, 0.0, 0.02)]
    at2 = fgs.band_stats(cases, 2.0)
    # widths hypot(0.03, 0.04) = 0.05 (holds 0.05) and 0.04
    assert at2["coverage"] == 1.0
    assert at2["mean_half_width"] == pytest.approx(0.045)
    assert at2["rms_error"] == pytest.approx(np.sqrt((0.05**2 + 0.01**2) / 2))
    assert fgs.band_stats(cases, 1.0)["coverage"] == 0.5
    # a callable gives the factor per snow modulus
    assert fgs.band_stats(cases, lambda e: 2.0)["coverage"] == 1.0


def test_fit_picks_the_smallest_factor_with_ninety_percent_inside():
    # 10 cases: error = k_i × grid part for k_i = 0.25, 0.5, …, 2.5; nothing else in the band
    cases = [_case(0.01 * k, 0.0, 0.01) for k in np.arange(1, 11) * 0.25]
    assert fgs.fit_factor(cases) == pytest.approx(2.25)  # 9 of 10 inside
    assert fgs.fit_factor(cases, target=0.5) == pytest.approx(1.25)
    # none reachable: the largest candidate
    assert fgs.fit_factor([_case(1.0, 0.0, 0.01)]) == fgs.GRID_FACTORS[-1]


def test_grid_only_floor_covers_the_grids_own_errors():
    # grid errors 0.1…1.0 × the grid part at factor 1: 90 % covered from 0.9 on
    cases = [_case(0.5, 0.5, 0.01, grid_error=0.001 * k) for k in range(1, 11)]
    assert fgs.grid_only_stats(cases, 0.9)["coverage"] == pytest.approx(0.9)
    assert fgs.fit_grid_only(cases) == pytest.approx(0.9)
    # the whole band's other parts do not count toward the floor
    assert fgs.grid_only_stats(cases, 0.5)["coverage"] == pytest.approx(0.5)


def test_own_ski_cases_undo_the_served_factor_and_judge_against_the_reference_truth():
    study = {
        "skis": [
            {
                "draw": 0,
                "grid": "dense",
                "answers": [
                    {
                        "snow_modulus_mpa": 20.0,
                        "truth_ref_cm2": {"flexible": 95.0},
                        "truth_cm2": {"flexible": 98.0},
                        "flexible": {
                            "status": 200,
                            "area_cm2": 100.0,
                            "area_grid_factor": 2.0,
                            "area_components": {"macro_grid": 0.04, "camber_model": 0.03},
                        },
                    }
                ],
            },
            {"draw": 1, "grid": "coarse", "answers": []},
        ]
    }
    (c,) = fgs.own_ski_cases(study)
    assert c["error"] == pytest.approx(0.05)  # relative to the answer, as its band
    assert c["part_at_1"] == pytest.approx(0.02)
    assert c["other"] == pytest.approx(0.03)
    assert c["source"] == "own-ski dense"
    assert c["grid_error"] == pytest.approx(3.0 / 98.0)  # true beam: own grid vs reference
    assert fgs.own_ski_cases(study, lambda d: d == 1) == []


def test_each_node_is_calibrated_by_the_populations_nearest_to_it():
    nodes = (2.0, 20.0, 200.0, 2000.0)
    assert fgs.nearest_node(10.0, nodes) == 20.0
    assert fgs.nearest_node(2.0, nodes) == 2.0
    own = [_case(0.01, 0.0, 0.01, e=20.0), _case(0.01, 0.0, 0.01, e=20.0, source="own-ski coarse")]
    demo = [
        _case(0.01, 0.0, 0.01, e=10.0, source="demo calib"),
        _case(0.01, 0.0, 0.01, e=2.0, source="demo calib"),
        _case(0.01, 0.0, 0.01, e=20.0, source="demo test"),
    ]
    pops = fgs.node_populations(own, demo, 20.0, nodes)
    assert sorted(pops) == ["demo calib 10 MPa", "own-ski coarse 20 MPa", "own-ski dense 20 MPa"]
    assert list(fgs.node_populations(own, demo, 2.0, nodes)) == ["demo calib 2 MPa"]


def _beam_case(err, camber, part, e=20.0, source="own-ski dense", warned=False):
    return {
        "source": source,
        "e_snow_mpa": e,
        "error": err,
        "fixed": 0.0,
        "camber_at_1": camber,
        "part_at_1": part,
        "warned": warned,
    }


def test_random_designs_are_a_population_of_their_own_and_the_draws_part_is_undone():
    answer = {
        "snow_modulus_mpa": 20.0,
        "truth_ref_cm2": {"flexible": 95.0},
        "truth_cm2": {"flexible": 98.0},
        "flexible": {
            "status": 200,
            "area_cm2": 100.0,
            "area_grid_factor": 2.0,
            "camber_scale": 4.0,
            "warnings": ["wide_error_band"],
            "area_components": {"macro_grid": 0.04, "camber_model": 0.08, "table": 0.01},
        },
    }
    study = {
        "skis": [
            {"design": "random-3", "draw": 0, "grid": "coarse", "answers": [answer]},
            {"design": "skate", "draw": 0, "grid": "coarse", "answers": [answer]},
        ]
    }
    rnd, hand = fgs.own_ski_cases(study)
    assert rnd["source"] == "own-ski random coarse" and hand["source"] == "own-ski coarse"
    assert rnd["camber_at_1"] == pytest.approx(0.02)  # 0.08 served at × 4
    assert rnd["fixed"] == pytest.approx(0.01)  # neither the draws' part nor the grid's
    assert rnd["warned"] is True


def test_beam_scale_stats_recombine_the_scaled_draws_and_count_unwarned_misses():
    cases = [_beam_case(0.05, 0.01, 0.0), _beam_case(0.05, 0.01, 0.0, warned=True)]
    at4 = fgs.beam_scale_stats(cases, 4.0, 0.9)
    assert at4["coverage"] == 0.0 and at4["unwarned_misses"] == 1  # 4 % wide, 5 % off
    at6 = fgs.beam_scale_stats(cases, 6.0, 0.9)
    assert at6["coverage"] == 1.0 and at6["half_width_over_rms"] == pytest.approx(0.06 / 0.05)


def test_beam_scale_fit_takes_the_smallest_meeting_both_targets_else_the_coverage():
    # 200 MPa: errors 2.5 % with draws 1 % per unit: × 3 covers, and keeps the width
    ok = [_beam_case(0.025, 0.01, 0.0, e=200.0, source=s) for s in ("own-ski dense", "x")]
    # 20 MPa: one population needs × 10 but another's width passes 2.5 × its RMS from × 6
    hard = [_beam_case(0.09, 0.01, 0.0, source="own-ski random coarse")] * 4
    easy = [_beam_case(0.02, 0.01, 0.0, source="own-ski dense")] * 4
    e2000 = [_beam_case(0.035, 0.01, 0.0, e=2000.0)]
    got = fgs.fit_beam_scales(ok + hard + easy + e2000, 0.9)
    assert got["nodes_e_snow_mpa"] == [20.0, 200.0, 2000.0]
    # 20 MPa: no factor meets both; coverage first: × 10, the smallest that covers the hard one
    assert got["fitted"] == [10.0, 3.0, 4.0]
    assert got["per_node"]["20 MPa"]["met"] is False
    assert got["per_node"]["200 MPa"]["met"] is True
    at = got["per_node"]["20 MPa"]["per_scale"]
    assert at["8"]["own-ski random coarse"]["coverage"] == 0.0  # 8 % wide, 9 % off
    assert at["10"]["own-ski random coarse"]["coverage"] == 1.0
    # the price: the easy population's width passes 2.5 × (0.1 / 0.02 = 5 ×)
    assert at["10"]["own-ski dense"]["half_width_over_rms"] == pytest.approx(5.0)
    # nothing covers: the largest candidate
    worst = [_beam_case(0.5, 0.01, 0.0, source="own-ski random coarse")]
    assert fgs.fit_beam_scales(worst + ok + e2000, 0.9)["fitted"][0] == fgs.BEAM_SCALES[-1]


def test_the_service_serves_what_the_committed_study_fitted():
    import json

    from skisnow.app.service import band_calibration

    doc = json.loads((REPO / "docs/studies/flexible-grid-factor.json").read_text(encoding="utf-8"))
    # the beam-draw factor was refitted after the covariance's cut-off was fixed
    # (scripts/covariance_refit_study.py, tests/evidence/test_covariance_refit_study.py)
    assert doc["beam_scale"]["fitted"] == [2.0, 4.0, 8.0]
    assert doc["grid_nodes_with_beam_scales"] == list(band_calibration.FLEXIBLE_AREA_GRID_NODES)
    # random designs among the populations that set the beam scales
    assert any(
        "random" in name for name in doc["beam_scale"]["per_node"]["20 MPa"]["per_scale"]["4"]
    )
