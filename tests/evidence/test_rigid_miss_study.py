"""The rigid answers' unwarned misses (scripts/rigid_miss_study.py, docs/limits.md "The rigid
answers' unwarned misses"): the summary's rules on synthetic rows, where each can fail."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import rigid_miss_study as rms  # noqa: E402


def _row(error, half_width, camber, draw_sd=1e-7, stored_sd=1e-7, warned=False, **kw):
    inside = abs(error) <= half_width
    return {
        "population": kw.get("population", "p"),
        "design": "d",
        "grid": kw.get("grid", "dense"),
        "e_snow_mpa": kw.get("e", 200.0),
        "load_kg": 50.0,
        "load_position_mm": 0.0,
        "error": error,
        "half_width": half_width,
        "camber_part": camber,
        "inside": inside,
        "warned": warned,
        "true_error_m": kw.get("true", 1e-7),
        "stored_sd_m": stored_sd,
        "draw_sd_m": draw_sd,
        "draws_solved": 8,
        "flat_length_m": [0.1, 0.2, 0.3, 0.4],
    }


def test_a_miss_is_off_outside_and_unwarned():
    assert rms.is_miss(_row(0.05, 0.02, 0.01))
    assert not rms.is_miss(_row(0.05, 0.06, 0.01))  # inside
    assert not rms.is_miss(_row(0.05, 0.02, 0.01, warned=True))
    assert not rms.is_miss(_row(0.02, 0.01, 0.01))  # within 3 %


def test_warning_rule_counts_warned_off_and_caught_misses():
    rows = [
        _row(0.05, 0.02, 0.01),  # miss
        _row(0.05, 0.02, 0.01),  # miss
        _row(0.04, 0.05, 0.01),  # off, inside
        _row(0.0, 0.02, 0.01),
    ]
    got = rms.warning_rule(rows, np.array([3.0, 0.0, 3.0, 0.0]), 2.0)
    assert got["warned_share"] == pytest.approx(0.5)
    assert got["off_warned_share"] == pytest.approx(2 / 3)
    assert (got["misses"], got["misses_caught"]) == (2, 1)


def test_rescaled_band_scales_the_camber_part_only():
    row = _row(0.0, 0.05, 0.03, draw_sd=2e-7, stored_sd=1e-7)  # other parts: 0.04
    assert rms.rescaled_band(row, "stored", 1.0) == pytest.approx(0.05)
    assert rms.rescaled_band(row, "ratio", 1.0) == pytest.approx(math.hypot(0.04, 0.06))
    narrow = _row(0.0, 0.05, 0.03, draw_sd=0.5e-7, stored_sd=1e-7)
    assert rms.rescaled_band(narrow, "ratio", 1.0) == pytest.approx(math.hypot(0.04, 0.015))
    assert rms.rescaled_band(narrow, "widen", 1.0) == pytest.approx(0.05)
    assert rms.rescaled_band(narrow, "widen", 2.0) == pytest.approx(math.hypot(0.04, 0.06))


def test_cell_stats_and_totals():
    rows = [_row(0.05, 0.02, 0.01), _row(0.01, 0.02, 0.01), _row(-0.01, 0.02, 0.01)]
    got = rms.cell_stats(rows, [0.02, 0.02, 0.02])
    rms_err = math.sqrt((0.05**2 + 0.01**2 + 0.01**2) / 3)
    assert got["coverage"] == pytest.approx(2 / 3)
    assert got["width_over_rms"] == pytest.approx(0.02 / rms_err)
    assert got["misses"] == 1
    wide = rms.cell_stats(rows, [0.06, 0.02, 0.02])
    assert (wide["coverage"], wide["misses"]) == (1.0, 0)
    cells = rms.screen(rows)
    tot = {(t["mode"], t["multiplier"]): t for t in rms.totals(cells)}
    assert tot[("stored", 1.0)]["misses"] == 1
    assert tot[("stored", 1.0)]["cells_below_90"] == 1
    # draw spread = stored: ratio × 2 doubles the camber part, 0.02 → √(0.02² + 0.01²·3)
    assert tot[("ratio", 2.0)]["misses"] == 1


def test_summary_lists_the_misses_and_a_markdown_table():
    rows = [_row(0.05, 0.02, 0.01, draw_sd=3e-7), _row(0.0, 0.02, 0.01), _row(0.01, 0.02, 0.01)]
    s = rms.summarise(rows)
    assert s["off_answers"] == 1 and len(s["misses"]) == 1
    caught = {r["threshold"]: r["misses_caught"] for r in s["warning_rules"]["draw_over_stored"]}
    assert caught[2.5] == 1 and caught[1.25] == 1
    md = rms.markdown(s, {"git_commit": "abc"})
    assert "| p | d | dense | 200 |" in md
