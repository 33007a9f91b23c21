"""The functional parameters' bands on own skis (scripts/metric_band_study.py,
docs/studies/metric-bands.md; docs/limits.md, the minimum separation's edge-peak rule)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import metric_band_study as mbs  # noqa: E402

QS = tuple(mbs.VALUES)


def _row(model, e_mpa, error, below, above=None):
    """One answer whose every quantity is ``error`` off with half-widths ``below``/``above``."""
    part = {
        "error": error,
        "error_same_grid": error / 2,
        "below": below,
        "above": below if above is None else above,
    }
    return {"model": model, "e_snow_mpa": e_mpa, "quantities": {q: dict(part) for q in QS}}


def test_summarise_counts_the_served_interval_and_the_reach():
    """Coverage by the served interval (value × (1 − below) … value ÷ (1 − above)), the mean of
    the two sides as the width, the farthest truth in half-widths of its side, and answers
    without a band counted apart."""
    rows = [
        _row("rigid", 20.0, 0.01, 0.02),  # inside
        _row("rigid", 20.0, -0.03, 0.05, 0.01),  # 3 % low against 1 % above: outside, 3 ×
        _row("rigid", 20.0, 0.04, 0.05, 0.0),  # 4 % high, 5 % below: inside
        _row("rigid", 20.0, 0.5, None),  # no band
        {"model": "flexible", "refused": "422"},
    ]
    s = mbs.summarise(rows)["rigid 20 MPa"]["min_average_separation"]
    assert s["n"] == 3 and s["no_band"] == 1
    assert s["inside"] == pytest.approx(2 / 3)
    assert s["mean_half_width"] == pytest.approx(np.mean([0.02, 0.03, 0.025]))
    assert s["rms_error"] == pytest.approx(np.sqrt(np.mean([0.01**2, 0.03**2, 0.04**2])))
    assert s["farthest_over_side"] == pytest.approx(3.0)
    assert s["mean_error"] == pytest.approx(np.mean([0.01, -0.03, 0.04]))
    assert "flexible 20 MPa" not in mbs.summarise(rows)


def test_the_committed_study_covers_every_quantity_of_four_unseen_designs():
    """docs/studies/metric-bands.json (four seeded random designs, both grids, 12 held-out
    cases, rigid and flexible, against the true beam on 1 mm × 32): every quantity's truth inside
    its band in ≥ 85 % of the answers with one at each snow modulus, the minimum separation's in
    ≥ 90 % (72.8 % at 20 MPa rigid before the edge-peak rule,
    docs/studies/metric-bands-before-edge-rule.json, the farthest 6.2 × its half-width away)."""
    doc = json.loads((REPO / "docs" / "studies" / "metric-bands.json").read_text())
    before = json.loads(
        (REPO / "docs" / "studies" / "metric-bands-before-edge-rule.json").read_text()
    )
    assert before["summary"]["rigid 20 MPa"]["min_average_separation"]["inside"] < 0.8
    assert len(doc["skis"]) == 8
    for cell, per in doc["summary"].items():
        for q, s in per.items():
            assert s["inside"] >= 0.85, (cell, q, s["inside"])
        assert per["min_average_separation"]["inside"] >= 0.9, cell
        assert per["min_average_separation"]["farthest_over_side"] < 2.0, cell
    # the summary is the rows' (not edited by hand)
    assert mbs.summarise(doc["rows"]) == doc["summary"]
