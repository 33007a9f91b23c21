"""The rigid answers' band-factor rules (``scripts/rigid_grid_factor_study.py``): the cases read
from each study, the band recombined with both factors, which populations set each node, and
that the service serves what the committed study fitted."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import rigid_grid_factor_study as rgs  # noqa: E402
from skisnow.app.service import band_calibration  # noqa: E402


def _case(err, part, camber=0.0, other=0.0, e=200.0, source="own-ski dense", grid_error=0.0):
    return {
        "source": source,
        "e_snow_mpa": e,
        "error": err,
        "other": other,
        "camber_at_1": camber,
        "part_at_1": part,
        "grid_error": grid_error,
        "warned": False,
    }


def _row(ski, default, fine, truth, reference, grid=0.02, camber=0.01, e=50.0):
    q = rgs.QUANTITY
    return {
        "ski": ski,
        "set": "calib",
        "e_snow_mpa": e,
        "values": {
            "default": {q: default},
            "fine": {q: fine},
            "truth": {q: truth},
            "reference": {q: reference},
        },
        "components": {"macro_grid": {q: grid}, "camber_model": {q: camber}},
    }


def test_calibration_cases_take_the_grids_own_error_per_kind_of_ski():
    demo, design = rgs.calibration_cases(
        [
            _row("ski-a", 1.10, 1.05, 1.02, 1.00),
            _row("stiff", 1.10, 1.05, 1.02, 1.00),
            {"ski": "ski-b", "set": "calib", "values": {"default": {}}},  # no reference: left out
        ]
    )
    assert demo["source"] == "demo calib" and design["source"] == "design calib"
    for c in (demo, design):
        assert c["error"] == pytest.approx(0.10)  # relative to the truth, as the test judges
        assert c["other"] == pytest.approx(0.01)  # the camber part, as served
        assert c["part_at_1"] == pytest.approx(0.02)
        assert c["camber_at_1"] == 0.0  # the demo's camber part is not the factor's
    # an exact design beam: its whole error is the grid's; a served profile: its own grid
    # error (default against fine) times the fine grid's (the true beam against reference)
    assert design["grid_error"] == pytest.approx(0.10)
    assert demo["grid_error"] == pytest.approx(1.10 / 1.05 * 1.02 - 1)


def test_own_ski_cases_undo_both_served_factors():
    study = {
        "skis": [
            {
                "design": "skate",
                "draw": 1,
                "grid": "coarse",
                "answers": [
                    {
                        "snow_modulus_mpa": 2000.0,
                        "truth_cm2": {"rigid": 104.0},
                        "truth_ref_cm2": {"rigid": 110.0},
                        "rigid": {
                            "status": 200,
                            "area_cm2": 100.0,
                            "camber_scale": 2.5,
                            "area_grid_factor": 0.5,
                            "warnings": ["flat_base"],
                            "area_components": {
                                "camber_model": 0.05,
                                "macro_grid": 0.03,
                                "flat_base": 0.04,
                            },
                        },
                    },
                    {"snow_modulus_mpa": 20.0, "rigid": {"status": 422}},  # refused: left out
                ],
            }
        ]
    }
    (c,) = rgs.own_ski_cases(study, "validation")
    assert c["source"] == "validation coarse"
    assert c["error"] == pytest.approx(0.10)  # relative to the answer, as its band
    assert c["camber_at_1"] == pytest.approx(0.02)
    assert c["part_at_1"] == pytest.approx(0.06)
    assert c["other"] == pytest.approx(0.04)  # the flat-base part stays as served
    assert c["grid_error"] == pytest.approx(6.0 / 104.0)  # true beam: own grid vs reference
    assert c["warned"] is True


def test_band_recombines_both_factors_and_counts_unwarned_misses():
    cases = [_case(0.05, 0.02, camber=0.015, other=0.0), _case(0.04, 0.01)]
    s = rgs.band_stats(cases, 2.0, 2.0)
    # widths hypot(0.04, 0.03) = 0.05 (holds 0.05) and 0.02 (misses 0.04, unwarned)
    assert s["coverage"] == 0.5
    assert s["mean_half_width"] == pytest.approx(0.035)
    assert s["unwarned_misses"] == 1
    cases[1]["warned"] = True
    assert rgs.band_stats(cases, 2.0, 2.0)["unwarned_misses"] == 0
    # callables give the factors per snow modulus
    assert rgs.band_stats(cases, lambda e: 4.0, lambda e: 2.0)["coverage"] == 1.0


def test_a_grid_node_is_the_largest_need_of_the_populations_at_its_modulus():
    # own-ski: grid errors 0.1…1.0 × the part → the grid alone needs 0.9; its whole band is
    # not asked of the grid factor (the camber factor carries it)
    own = [_case(0.5, 0.01, grid_error=0.001 * k, e=20.0) for k in range(1, 11)]
    # demo calib at 50 MPa: grid errors need 0.5, but the whole band needs 1.5 (errors up to
    # 1.5 × the part, nothing else in the band)
    demo = [
        _case(
            0.0015 if k == 10 else 0.001, 0.001, source="demo calib", e=50.0, grid_error=0.00005 * k
        )
        for k in range(1, 11)
    ]
    got = rgs.fit_grid_nodes(own + demo, (20.0, 50.0))
    assert got["fitted"] == pytest.approx([0.9, 1.0])
    assert got["per_node"]["50 MPa"]["needs"]["demo calib"]["whole_band"] == pytest.approx(1.0)
    # a check population (the demo test set) never sets a node
    test = [_case(1.0, 0.001, source="demo test", e=20.0, grid_error=1.0)]
    assert rgs.fit_grid_nodes(own + demo + test, (20.0, 50.0))["fitted"][0] == 0.9
    with pytest.raises(ValueError, match="no calibration population"):
        rgs.fit_grid_nodes(own, (20.0, 2000.0))


def test_identified_factor_is_the_largest_any_measurement_grid_needs():
    # dense: errors 0.1…1.0 %, camber part 0.3 % at 1, no grid part: 9 of 10 inside first at 3
    dense = [_case(0.001 * k, 0.0, camber=0.003) for k in range(1, 11)]
    coarse = [_case(0.001, 0.0, camber=0.003, source="own-ski coarse") for _ in range(10)]
    got = rgs.fit_sigma_nodes(dense + coarse, 1.0, (200.0,))
    # the coarse errors (0.1 %) are inside from the smallest candidate on (0.5: 0.15 %)
    assert got["per_node"]["200 MPa"]["per_grid"]["own-ski coarse"]["factor"] == 0.5
    assert got["fitted"] == [3.0]
    # a grid part takes some of it: with the grid part 0.6 %, 0.9 % needs hypot ≥ 0.9 %
    dense = [_case(0.001 * k, 0.006, camber=0.003) for k in range(1, 11)]
    assert rgs.fit_sigma_nodes(dense, 1.0, (200.0,))["fitted"] == [2.5]


def test_network_scale_is_the_smallest_with_every_calibration_modulus_covered():
    q = rgs.QUANTITY

    def row(scale, e, err, camber):
        return {
            "scale": scale,
            "set": "calib",
            "e_snow_mpa": e,
            "error": {q: err},
            "components": {"macro_grid": {q: 0.0}, "camber_model": {q: camber * scale}},
        }

    # 20 MPa covered from × 1, 200 MPa (error 0.035 against 0.02 per unit scale) from × 2
    rows = [row(s, 20.0, 0.01, 0.02) for s in (1.0, 1.5, 2.0)]
    rows += [row(s, 200.0, 0.035, 0.02) for s in (1.0, 1.5, 2.0)]
    got = rgs.fit_network_scale({"rows": rows}, 1.0)
    assert got["fitted"] == 2.0
    assert got["per_scale"]["1.5"]["network calib | 200 MPa"]["coverage"] == 0.0


def test_the_service_serves_what_the_committed_study_fitted():
    doc = json.loads((REPO / "docs/studies/rigid-grid-factor.json").read_text(encoding="utf-8"))
    assert doc["grid_factor"]["nodes_e_snow_mpa"] == list(
        band_calibration.RIGID_AREA_GRID_E_SNOW_MPA
    )
    assert doc["grid_factor"]["fitted"] == list(band_calibration.RIGID_AREA_GRID_NODES)
    # the identified-profile factor was refitted after the covariance's cut-off was fixed
    # (scripts/covariance_refit_study.py, tests/evidence/test_covariance_refit_study.py)
    assert doc["identified_sigma"]["fitted"] == [2.0, 1.5, 2.5]
    assert doc["network_sigma_scale"]["fitted"] == band_calibration.NETWORK_SIGMA_SCALE
    # and it calibrated on every modulus of its nodes, ≥ 90 % of each population inside
    for name, r in doc["checks"].items():
        if r["calibrates"]:
            assert r["fitted"]["coverage"] >= 0.9, name
    assert np.all(np.diff(doc["grid_factor"]["nodes_e_snow_mpa"]) > 0)


def test_random_designs_are_a_population_of_their_own_and_can_set_a_node():
    answer = {
        "snow_modulus_mpa": 20.0,
        "truth_ref_cm2": {"rigid": 100.0},
        "truth_cm2": {"rigid": 100.0},
        "rigid": {
            "status": 200,
            "area_cm2": 100.0,
            "camber_scale": 1.5,
            "area_grid_factor": 0.9,
            "warnings": [],
            "area_components": {"camber_model": 0.015, "macro_grid": 0.009},
        },
    }
    study = {
        "skis": [
            {"design": "random-7", "draw": 0, "grid": "dense", "answers": [answer]},
            {"design": "race-classic", "draw": 0, "grid": "dense", "answers": [answer]},
        ]
    }
    rnd, hand = rgs.own_ski_cases(study)
    assert rnd["source"] == "own-ski random dense" and hand["source"] == "own-ski dense"
    assert rnd["camber_at_1"] == pytest.approx(0.01) and rnd["part_at_1"] == pytest.approx(0.01)
    assert "own-ski random dense" in rgs.CALIBRATION_SOURCES
    # the hand-written designs are covered at × 0.5, the random ones need × 3: the node takes 3
    own = [_case(0.005, 0.0, camber=0.01, e=e) for e in (20.0, 200.0, 2000.0)]
    own += [
        _case(0.029, 0.0, camber=0.01, e=e, source="own-ski random dense")
        for e in (20.0, 200.0, 2000.0)
    ]
    got = rgs.fit_sigma_nodes(own, 1.0, (20.0, 200.0, 2000.0))
    assert got["fitted"] == [3.0, 3.0, 3.0]
    assert got["per_node"]["20 MPa"]["per_grid"]["own-ski dense"]["factor"] == 0.5
