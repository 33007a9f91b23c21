"""The residual-structure check of an identified beam (``scripts/residual_structure.py``): white
device noise reads as white, a smooth shape the model missed does not."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import residual_structure as rs  # noqa: E402


def test_white_noise_reads_white_and_a_missed_shape_does_not():
    rng = np.random.default_rng(5)
    x = np.linspace(-0.5, 0.5, 1001)
    measured = np.full((40, x.size), 50e-6)  # all within the contact band
    noise = rng.normal(0.0, 3e-6, measured.shape)
    white = rs.residual_structure(measured + noise, measured)
    assert white["rms_m"] == pytest.approx(3e-6, rel=0.02)
    assert abs(white["lag1"]) < 0.01
    assert white["smoothed_over_white"] == pytest.approx(1.0, abs=0.1)
    # a 2 µm bump (σ 50 mm) that the model does not have: lag-1 about 0.35 / 9.35 µm²
    bump = 2e-6 * np.exp(-0.5 * (x / 0.05) ** 2)
    missed = rs.residual_structure(measured + noise + bump, measured)
    assert missed["lag1"] > 0.02
    assert missed["smoothed_over_white"] > 1.5
    # points outside the contact band do not count
    far = measured.copy()
    far[:, :500] = 1e-3
    assert rs.residual_structure(far + noise, far)["rms_m"] == pytest.approx(3e-6, rel=0.03)
