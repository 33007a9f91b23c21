"""The knot-variant lead of the rigid misses (scripts/knot_variant_study.py): its summary on
synthetic cases, where each number can fail."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import knot_variant_study as kvs  # noqa: E402


def _case(shift_um, true_um, sd_um, miss):
    return {
        "variant_shift_m": shift_um * 1e-6,
        "true_error_m": true_um * 1e-6,
        "stored_sd_m": sd_um * 1e-6,
        "miss": miss,
    }


def test_summary_separates_misses_from_the_other_cases():
    skis = [
        {"cases": [_case(1.0, 1.6, 0.1, True), _case(0.1, 0.6, 0.2, True)]},
        {"cases": [_case(0.02, 0.1, 0.1, False), _case(0.06, 0.1, 0.2, False)]},
        {"cases": [_case(0.3, 0.2, 0.1, False)]},
    ]
    s = kvs.summarise(skis)
    assert s["misses"]["cases"] == 2 and s["others"]["cases"] == 3
    assert s["misses"]["shift_over_true_median"] == pytest.approx((1.0 / 1.6 + 0.1 / 0.6) / 2)
    assert s["misses"]["share_shift_at_least_half_true"] == pytest.approx(0.5)
    assert s["others"]["shift_over_band_sd_median"] == pytest.approx(0.3)
    assert s["others"]["share_shift_at_least_half_true"] == pytest.approx(2 / 3)


def test_summary_without_cases_of_a_kind():
    s = kvs.summarise([{"cases": [_case(1.0, 1.0, 1.0, False)]}])
    assert s["misses"] == {"cases": 0}
