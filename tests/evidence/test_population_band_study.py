"""The served bands across the own-ski populations (scripts/population_band_study.py,
docs/limits.md "The bands across eleven populations")."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import population_band_study as pbs  # noqa: E402


def _answer(error, half_width, camber, factor, warned=False, grid_part=0.0):
    return {
        "status": 200,
        "error_ref_pct": 100.0 * error,
        "band_half_width": half_width,
        "area_components": {"camber_model": camber, "macro_grid": grid_part},
        "camber_scale": factor,
        "warnings": ["wide"] if warned else [],
    }


def _study(skis):
    """A study file of skis ``(design, errors, camber part at × 4, grid part)`` on the coarse
    grid at 2000 MPa, the band the camber and grid parts in quadrature."""
    out = []
    for design, errors, camber, grid_part in skis:
        hw = math.hypot(camber, grid_part)
        answers = [
            {
                "snow_modulus_mpa": 2000.0,
                "flexible": _answer(e, hw, camber, 4.0, grid_part=grid_part),
                "rigid": {"status": 422},
            }
            for e in errors
        ]
        out.append(
            {
                "design": design,
                "draw": 0,
                "grid": "coarse",
                "outcome": "done",
                "served": {"profile_model": "identified_beam"},
                "identification": {"misfit_over_noise": 1.0},
                "answers": answers,
            }
        )
    # a ski served by its network is not one of the identified beam's answers
    out.append({**out[0], "design": "net", "served": {"profile_model": "network"}})
    return {"provenance": {"git_commit": "abc"}, "skis": out}


def test_stats_count_coverage_width_and_unwarned_misses():
    st = pbs.stats([0.01, -0.05, 0.05, 0.02], [0.02, 0.02, 0.02, 0.01], [False, False, True, False])
    assert st["answers"] == 4 and st["coverage"] == pytest.approx(0.25)
    assert st["unwarned_misses"] == 1  # -5 % outside, unwarned; +5 % warned; +2 % below 3 %
    rms = math.sqrt((0.01**2 + 2 * 0.05**2 + 0.02**2) / 4)
    assert st["half_width_over_rms"] == pytest.approx(0.0175 / rms)
    assert pbs.stats([], [], []) == {"answers": 0}


def test_inside_is_the_served_band_area_times_one_plus_or_minus_the_half_width():
    # 9 % under: the truth is 9.9 % above the answer, outside ± 9.5 %; 10 % over: the truth is
    # 9.1 % below the answer, inside
    st = pbs.stats([-0.09, 0.10], [0.095, 0.095], [False, False])
    assert st["coverage"] == pytest.approx(0.5)
    assert st["unwarned_misses"] == 1
    # on a committed study, every answer's recorded inside_band (its served band_cm2 against
    # the reference truth) is what stats counts
    doc = json.loads((REPO / "docs/studies/own-ski-random-33-36.json").read_text("utf-8"))
    checked = 0
    for ski in doc["skis"]:
        for case in ski.get("answers", []):
            for model in pbs.MODELS:
                a = case.get(model, {})
                if a.get("status") != 200 or "inside_band" not in a:
                    continue
                st = pbs.stats([a["error_ref_pct"] / 100.0], [a["band_half_width"]], [True])
                assert (st["coverage"] == 1.0) == a["inside_band"], (ski["design"], case)
                checked += 1
    assert checked > 1000


def test_rescaling_changes_only_the_beam_draws_part_linearly():
    rows = [{"half_width": 0.05, "factor": 4.0, "parts": {"camber_model": 0.04}}]
    # the other parts: sqrt(0.05² − 0.04²) = 0.03
    assert pbs.rescaled_half_widths(rows, 4.0) == pytest.approx([0.05])
    assert pbs.rescaled_half_widths(rows, 8.0) == pytest.approx([math.hypot(0.08, 0.03)])
    assert pbs.rescaled_half_widths(rows, 0.0) == pytest.approx([0.03])


def test_study_reads_served_beam_answers_and_ranks_the_predictors(tmp_path):
    """Skis whose error grows with their grid part and not with their camber part: the grid
    part predicts, the camber part does not; the network-served ski is left out."""
    rng = np.random.default_rng(0)
    skis = []
    for k in range(6):
        scale = 0.01 * 2**k
        errors = list(scale * rng.choice([-1.0, 1.0], 8))
        skis.append((f"d{k}", errors, 0.02 * (1 + (k % 2)), 1.6 * scale))
    doc = pbs.study({"a": _study(skis[:3]), "b": _study(skis[3:])})
    (cell,) = [c for c in doc["cells"] if c["model"] == "flexible"]
    assert cell["grid"] == "coarse" and cell["e_snow_mpa"] == 2000.0
    assert cell["served"]["a"]["answers"] == 24 and cell["served"]["pooled"]["answers"] == 48
    assert (
        cell["served"]["pooled"]["coverage"] == 1.0
    )  # bands ≥ 1.6 × the error: 32 % under is inside
    pred = cell["predictors"]
    assert pred["skis"] == 6
    assert pred["macro_grid"] > 0.99 and abs(pred["camber_model"]) < 0.5
    assert math.isnan(pred["misfit_over_noise"])  # the same misfit on every ski
    # at × 1 (a quarter of the served draws part) the grid part alone still covers
    assert cell["linear_estimate"]["1"]["pooled"]["coverage"] == 1.0
    assert not [c for c in doc["cells"] if c["model"] == "rigid"]  # no rigid answer given


def test_main_writes_json_and_markdown_with_provenance(tmp_path):
    skis = [(f"d{k}", [0.01 * (k + 1), -0.01], 0.02, 0.01) for k in range(4)]
    path = tmp_path / "s.json"
    path.write_text(json.dumps(_study(skis)), encoding="utf-8")
    out = tmp_path / "pb.json"
    assert pbs.main(["--studies", f"pop={path}", "--out", str(out)]) == 0
    doc = json.loads(out.read_text("utf-8"))
    assert doc["schema"] == pbs.SCHEMA and doc["provenance"]["git_commit"]
    assert doc["populations"]["pop"]["commit"] == "abc"
    md = out.with_suffix(".md").read_text("utf-8")
    assert "| flexible | coarse | 2000 |" in md and "× 12" in md


def test_served_sides_split_the_recorded_parts_as_the_service_does():
    """The recorded parts in quadrature, the grid part moved below the answer at the snow's
    share (0 at 20 MPa, 1 at 200 MPa and above): the service's own split
    (solvers.band.one_sided_part)."""
    from skisnow.solvers.band import one_sided_part

    parts = {"camber_model": 0.03, "macro_grid": 0.04}
    soft = {"parts": parts, "factor": 2.0, "e_snow_mpa": 20.0, "half_width": 0.05}
    assert pbs.served_sides(soft) == pytest.approx((0.07, 0.03))
    assert pbs.served_sides({**soft, "e_snow_mpa": 2000.0}) == pytest.approx((0.05, 0.05))
    # the camber part rescaled first: × 4 where the study served × 2
    assert pbs.served_sides(soft, 4.0) == pytest.approx(
        one_sided_part(math.hypot(0.06, 0.04), 0.04, 0.0)
    )
    assert pbs.served_sides({**soft, "e_snow_mpa": 2000.0}, share=0.0) == pytest.approx(
        (0.07, 0.03)
    )


def test_stats_now_judge_each_side_of_the_served_band():
    """An answer 6 % over (truth 5.7 % below) is inside (1 − 0.07, 1 / (1 − 0.03)); one 4 %
    under (truth 4.2 % above) is outside it (4 % > 3 % above), and unwarned."""
    st = pbs.stats([0.06, -0.04], [0.05, 0.05], [False, False], [(0.07, 0.03), (0.07, 0.03)])
    assert st["coverage_now"] == pytest.approx(0.5)
    assert st["unwarned_misses_now"] == 1
    assert st["mean_half_width_now"] == pytest.approx(0.05)
    # the recorded symmetric band (± 5 %) had it the other way round: the overestimate out,
    # the underestimate in
    assert st["coverage"] == 0.5 and st["unwarned_misses"] == 1


def test_the_served_tail_is_the_committed_studys_rounded_up():
    """band_calibration.STUDIED_TAIL is docs/studies/population-bands.json's pooled share
    outside and farthest reach per model, grid and modulus, rounded up (never below the
    study, at most one rounding step above); the answers per cell the same."""
    from skisnow.app.service import band_calibration as bc

    doc = json.loads((REPO / "docs" / "studies" / "population-bands.json").read_text("utf-8"))
    seen = 0
    for c in doc["cells"]:
        s = c["served"]["pooled"]
        g = pbs.GRIDS.index(c["grid"])
        n = bc.STUDIED_TAIL_E_SNOW_MPA.index(c["e_snow_mpa"])
        share, far = bc.STUDIED_TAIL[c["model"]][g][n]
        assert 0 <= share - (1 - s["coverage_now"]) < 1e-3 + 1e-12
        assert 0 <= far - s["farthest_over_side_now"] < 1e-2 + 1e-12
        assert bc.STUDIED_TAIL_ANSWERS[g] == s["answers"]
        seen += 1
    assert seen == 12


def test_stats_measure_the_tail_and_the_factor_the_3pct_rule_needs():
    """A truth 6 % below an answer whose band reaches 3 % below (the side towards it) lies
    2 × the side away; an unwarned one needs the band × 2, and the width ratio doubles."""
    errors = [0.06 / 0.94, 0.0, 0.01, -0.01]  # the first: truth = answer × 0.94
    sides = [(0.03, 0.05), (0.03, 0.05), (0.03, 0.05), (0.03, 0.05)]
    s = pbs.stats(errors, [0.04] * 4, [False] * 4, sides)
    assert s["farthest_over_side_now"] == pytest.approx(2.0)
    assert s["misses_over_3pct_now"] == 1 and s["unwarned_misses_now"] == 1
    assert s["narrow_unwarned_misses_now"] == 0  # its side was 3 %, not under
    assert s["scale_for_no_unwarned_miss_now"] == pytest.approx(2.0)
    assert s["half_width_over_rms_at_that_scale"] == pytest.approx(
        2.0 * s["half_width_over_rms_now"]
    )
    warned = pbs.stats(errors, [0.04] * 4, [True, False, False, False], sides)
    assert warned["scale_for_no_unwarned_miss_now"] == 1.0
