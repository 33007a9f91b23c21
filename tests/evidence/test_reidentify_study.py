"""scripts/reidentify_study.py: the alternatives it writes into a ski file are read back by the
service's reader; the rest of the file stays as it was; a different beam is told apart."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "scripts"))

import reidentify_study as rs  # noqa: E402
from skisnow.app.storage.skis import identified_alternatives, identified_beam, read_ski  # noqa: E402


def test_alternatives_replaced_and_read_back(tmp_path):
    path = tmp_path / "ski.h5"
    shutil.copyfile(REPO / "tables" / "skis" / "ski-a.h5", path)
    before = read_ski(path)
    beam = identified_beam(before.identified)
    assert beam is not None
    alts = [
        type(beam)(beam.positions_m, k * beam.bending_stiffness_nm2, beam.unloaded_gap_m)
        for k in (1.1, 0.9)
    ]
    rs.write_alternatives(path, alts, "abc123")
    after = read_ski(path)
    got = identified_alternatives(after.identified)
    assert len(got) == 2
    for a, g in zip(alts, got, strict=True):
        np.testing.assert_array_equal(a.bending_stiffness_nm2, g.bending_stiffness_nm2)
        np.testing.assert_array_equal(a.unloaded_gap_m, g.unloaded_gap_m)
    assert after.identified["attrs"]["alternatives_reidentified_git_commit"] == "abc123"
    # the served beam and the measurements are untouched
    assert rs.same_beam(identified_beam(after.identified), beam)
    np.testing.assert_array_equal(after.measurements.profiles_m, before.measurements.profiles_m)
    # none left
    rs.write_alternatives(path, [], "abc124")
    assert identified_alternatives(read_ski(path).identified) == []


def test_same_beam_is_bitwise():
    beam = identified_beam(read_ski(REPO / "tables" / "skis" / "ski-a.h5").identified)
    assert rs.same_beam(beam, beam)
    ei = beam.bending_stiffness_nm2.copy()
    ei[100] = np.nextafter(ei[100], np.inf)
    assert not rs.same_beam(type(beam)(beam.positions_m, ei, beam.unloaded_gap_m), beam)
