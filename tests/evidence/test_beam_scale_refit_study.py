"""One cell of the bending ski's beam-draw factor refitted on re-solves and on the committed
populations' estimate (scripts/beam_scale_refit_study.py)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from skisnow.app.service import band_calibration

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import beam_scale_refit_study as brs  # noqa: E402
import per_grid_band_study as pgs  # noqa: E402
from test_population_band_study import _study  # noqa: E402


def _scan(errors_by_factor: dict[float, list[float]], half_width: float = 0.05) -> dict:
    """A ``beam_scale_study.py --rows`` output: at each factor, answers ``errors`` (relative,
    against the reference truth) on the coarse grid at 2000 MPa with bands of ``half_width``
    times the factor ÷ 4."""
    rows = []
    for k, errors in errors_by_factor.items():
        for e in errors:
            rows.append(
                {
                    "model": "flexible",
                    "grid": "coarse",
                    "e_snow_mpa": 2000.0,
                    "scale": k,
                    "area_cm2": 100.0 * (1 + e),
                    "truth_ref_cm2": 100.0,
                    "half_width": half_width * k / 4,
                    "components": {},
                    "warnings": [],
                }
            )
        rows.append({**rows[-1], "grid": "dense", "area_cm2": 500.0})  # another cell: ignored
    return {"provenance": {"git_commit": "abc", "parameters_json": "{}"}, "rows": rows}


def test_the_chosen_factor_is_the_smallest_that_holds_90_percent_in_every_population():
    # re-solved: × 4 holds 5 of 10 (bands ± 5 %), × 8 every one (± 10 %)
    errs = [0.02] * 5 + [0.07] * 5
    scans = {"fresh": _scan({4.0: errs, 8.0: errs, 12.0: errs})}
    # committed, served at × 4 with a draws' part of 0.02: errors of 1 % are inside at any
    # factor ≥ 2, so the estimate never binds here
    studies = {"old": _study([("a", [0.01] * 10, 0.02, 0.0)])}
    fit = brs.refit(scans, studies, "coarse", 2000.0)
    assert [c["factor"] for c in fit["candidates"]] == [4.0, 8.0, 12.0]
    first = fit["candidates"][0]
    assert first["resolved"]["fresh"]["coverage"] == pytest.approx(0.5)
    assert first["resolved"]["fresh"]["answers"] == 10  # the dense row is not in this cell
    assert first["estimated"]["old"]["coverage"] == 1.0
    assert fit["chosen"] == 8.0
    # a committed population that the estimate holds only from × 12 decides instead: its
    # errors of 5.5 % against a draws' part of 0.02 at × 4 (± 2 % → ± 6 % at × 12)
    studies["hard"] = _study([("b", [0.055] * 10, 0.02, 0.0)])
    fit = brs.refit(scans, studies, "coarse", 2000.0)
    assert [c["meets_coverage"] for c in fit["candidates"]] == [False, False, True]
    assert fit["chosen"] == 12.0
    assert fit["chosen_symmetric_band"] == 12.0  # overestimates: both band shapes alike
    # nothing meets: None, never the largest by default
    scans["never"] = _scan({4.0: [0.5] * 10, 8.0: [0.5] * 10, 12.0: [0.5] * 10})
    assert brs.refit(scans, studies, "coarse", 2000.0)["chosen"] is None


def test_only_the_factors_every_scan_was_re_solved_at_are_candidates():
    scans = {
        "a": _scan({4.0: [0.01], 8.0: [0.01], 12.0: [0.01]}),
        "b": _scan({8.0: [0.01], 12.0: [0.01]}),
    }
    fit = brs.refit(scans, {}, "coarse", 2000.0)
    assert [c["factor"] for c in fit["candidates"]] == [8.0, 12.0]
    assert fit["chosen"] == 8.0


def test_the_markdown_names_every_population_and_the_choice():
    doc = {
        "provenance": {"created_utc": "2026-11-29T00:00:00", "git_commit": "0123456789abcdef"},
        "refit": brs.refit(
            {"fresh": _scan({4.0: [0.02] * 10, 8.0: [0.02] * 10})},
            {"old": _study([("a", [0.01] * 10, 0.02, 0.0)])},
            "coarse",
            2000.0,
        ),
    }
    md = brs.markdown(doc)
    assert "fresh (re-solved)" in md and "old (est.)" in md
    assert "in every population: × 4. For the band served until 2026-11-29" in md
    assert md.rstrip().endswith("(area × (1 ± hw)): × 4.")


def test_the_log_band_counts_an_underestimate_inside_up_to_the_half_width():
    # answers 9.5 % under their truths with half-widths of 10 % (× 4) and 20 % (× 8): area ×
    # (1 ± hw) reaches 10.5 % above the answer only from × 8 on; the log band (served) from × 4
    scans = {"under": _scan({4.0: [-0.095] * 10, 8.0: [-0.095] * 10}, half_width=0.10)}
    fit = brs.refit(scans, {}, "coarse", 2000.0)
    first = fit["candidates"][0]["resolved"]["under"]
    assert first["coverage"] == 0.0 and first["coverage_log_band"] == 1.0
    assert first["outside_above"] == 10
    assert (fit["chosen"], fit["chosen_symmetric_band"]) == (4.0, 8.0)


def test_the_service_serves_the_committed_refits_over_the_per_grid_study():
    """Every refitted cell is served at its committed refit study's choice, every other cell at
    the per-grid study's (docs/studies/per-grid-band.json); the refit chose from re-solves of
    at least one fresh population and the eleven committed populations' estimate."""
    per_grid = json.loads((REPO / "docs/studies/per-grid-band.json").read_text("utf-8"))
    want = [list(r) for r in per_grid["served"]["flexible"]]
    assert band_calibration.BEAM_SCALE_REFITS
    for (grid, e_mpa), path in band_calibration.BEAM_SCALE_REFITS.items():
        doc = json.loads((REPO / path).read_text("utf-8"))
        fit = doc["refit"]
        assert (fit["grid"], fit["e_snow_mpa"]) == (grid, e_mpa)
        assert fit["chosen"] is not None
        chosen = next(c for c in fit["candidates"] if c["factor"] == fit["chosen"])
        assert chosen["resolved"] and len(chosen["estimated"]) >= 11
        assert chosen["lowest_coverage"] >= brs.COVERAGE_TARGET
        want[pgs.GRIDS.index(grid)][list(band_calibration.BEAM_SCALE_E_SNOW_MPA).index(e_mpa)] = (
            fit["chosen"]
        )
    assert [list(r) for r in band_calibration.BEAM_SCALE_GRID_NODES] == want
