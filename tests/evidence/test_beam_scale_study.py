"""The beam-draw factor's calibration rule (``scripts/beam_scale_study.py``): its statistics
against the reference truth and the choice of the smallest factor with ≥ 90 % inside on the
calibration draws, on rows written here with known answers."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import beam_scale_study as bss  # noqa: E402


def _row(scale, draw, err, half, warned=False, e=200.0, model="flexible"):
    """An answer ``err`` (relative) off its reference truth 100 cm², band half-width ``half``."""
    return {
        "model": model,
        "scale": scale,
        "e_snow_mpa": e,
        "draw": draw,
        "area_cm2": 100.0 * (1 + err),
        "truth_cm2": 100.0,
        "truth_ref_cm2": 100.0,
        "half_width": half,
        "components": {"camber_model": half},
        "warnings": ["wide_error_band"] if warned else [],
    }


def test_stats_judge_the_band_against_the_reference_truth():
    rows = [_row(1.0, 0, 0.02, 0.03), _row(1.0, 0, -0.05, 0.03), _row(1.0, 0, 0.05, 0.03, True)]
    st = bss.stats(rows)
    assert st["answers"] == 3
    # inside: truth in the served band [A(1 − h), A / (1 − h)]
    assert st["coverage"] == pytest.approx(1 / 3)
    # 2.9 % under against ± 3 %: inside (the log band reaches 3.09 % above the answer); 3.2 %
    # under: outside; 3 % over: inside (the truth is 2.9 % below the answer)
    near = [_row(1.0, 0, -0.029, 0.03), _row(1.0, 0, -0.032, 0.03), _row(1.0, 0, 0.030, 0.03)]
    assert bss.stats(near)["coverage"] == pytest.approx(2 / 3)
    err = np.array([0.02, -0.05, 0.05])
    assert st["rms_error"] == pytest.approx(np.sqrt(np.mean(err**2)))
    assert st["half_width_over_rms"] == pytest.approx(0.03 / st["rms_error"])
    # more than 3 % off, outside and unwarned: only the second (the third carries a warning)
    assert st["off_3pct_outside_unwarned"] == 1
    assert bss.stats([{"model": "flexible", "error": "refused"}]) == {"answers": 0}


def test_the_chosen_factor_is_the_smallest_with_90_percent_of_the_calibration_draws_inside():
    rows = []
    for s in bss.FLEX_SCALES:
        # calibration draw 0: 10 answers 4 % off; the band holds them from factor 4 on
        half = 0.05 if s >= 4 else 0.01
        rows += [_row(s, 0, 0.04, half) for _ in range(10)]
        # another draw, left out of the choice: never inside
        rows += [_row(s, 1, 0.2, half) for _ in range(10)]
    for s in bss.RIGID_SCALES:
        rows += [_row(s, 0, 0.01, 0.02, model="rigid") for _ in range(10)]
    out = bss.summarise(rows, {0})
    assert out["flexible"]["200 MPa"]["chosen"] == 4.0
    per = out["flexible"]["200 MPa"]["per_scale"]
    assert per["2"]["calib"]["coverage"] == 0.0 and per["4"]["calib"]["coverage"] == 1.0
    assert per["4"]["other"]["coverage"] == 0.0
    assert per["4"]["all"]["answers"] == 20
    assert out["rigid"]["200 MPa"]["chosen"] == bss.RIGID_SCALES[0]


def test_the_per_ski_cache_is_keyed_by_the_ski_file_and_its_truths(tmp_path):
    """A ski re-identified (or rescored) at the same commit is answered again: the cache's
    name changes with the kept ski file's bytes and with its rescored truths, not only with the
    factor lists and the commit."""
    (tmp_path / "skis").mkdir()
    (tmp_path / "rescored").mkdir()
    ski, truths = tmp_path / "skis" / "s.h5", tmp_path / "rescored" / "s.json"
    ski.write_bytes(b"beam 1")
    truths.write_text("{}", encoding="utf-8")
    first = bss.cache_file(tmp_path, "s", (1.0, 2.0), (1.0,))
    assert first.parent == tmp_path / "beam-scale" and first.name.startswith("s-")
    assert bss.cache_file(tmp_path, "s", (1.0, 2.0), (1.0,)) == first
    assert bss.cache_file(tmp_path, "s", (1.0, 4.0), (1.0,)) != first
    ski.write_bytes(b"beam 2")
    second = bss.cache_file(tmp_path, "s", (1.0, 2.0), (1.0,))
    assert second != first
    truths.write_text('{"fields": 1}', encoding="utf-8")
    assert bss.cache_file(tmp_path, "s", (1.0, 2.0), (1.0,)) not in (first, second)
    third = bss.cache_file(tmp_path, "s", (1.0, 2.0), (1.0,))
    # the snow moduli asked are part of the key; asking every modulus keeps the old key
    only = bss.cache_file(tmp_path, "s", (1.0, 2.0), (1.0,), (2000.0,))
    assert only != third
    assert bss.cache_file(tmp_path, "s", (1.0, 2.0), (1.0,), (2000.0,)) == only
    assert bss.cache_file(tmp_path, "s", (1.0, 2.0), (1.0,), None) == third
