"""Profile models of a stored ski (app.service.profiles): which model answers, and that the
identified beam's answer is the device model's exact contact solve whatever the warm start."""

import dataclasses

import numpy as np
import pytest
from conftest import REPO
from skisnow.app.service.profiles import ProfileModel, profile_model, served_beam, served_beam_note
from skisnow.app.storage.skis import read_ski
from skisnow.solvers.beam import solve_beam_contact
from skisnow.solvers.errors import DataFileError

SKI = REPO / "tables" / "skis" / "ski-a.h5"


def _identified_group(beam, ok=True):
    return {
        "attrs": {
            "ok": ok,
            "reason": "" if ok else "misfit too large",
            "misfit_m": 3.0e-6,
            "noise_m": 3.0e-6,
        },
        "positions_m": beam.positions_m,
        "bending_stiffness_nm2": beam.bending_stiffness_nm2 * 1.01,
        "unloaded_gap_m": beam.unloaded_gap_m,
    }


def test_source_order():
    rec = read_ski(SKI)
    ident = _identified_group(rec.beam)
    assert ProfileModel(dataclasses.replace(rec, identified=ident, cache={})).source == (
        "identified_beam"
    )
    failed = _identified_group(rec.beam, ok=False)
    with_net = dataclasses.replace(rec, identified=failed, cache={})
    assert ProfileModel(with_net).source == (
        "network" if rec.network is not None else "design_beam"
    )
    bare = dataclasses.replace(rec, identified=None, network=None, cache={})
    assert ProfileModel(bare).source == "design_beam"
    nothing = dataclasses.replace(rec, identified=None, network=None, beam=None, cache={})
    with pytest.raises(DataFileError, match="no profile model"):
        ProfileModel(nothing)


def test_identified_beam_profile_is_the_exact_contact_solve():
    """The profile model answers the device's contact solve of the identified beam, whatever
    was solved before in the process (no history-dependent warm start)."""
    rec = read_ski(SKI)
    rec = dataclasses.replace(rec, identified=_identified_group(rec.beam), cache={})
    model = profile_model(rec)
    assert profile_model(rec) is model  # built once per record
    beam = model.beam
    rng = np.random.default_rng(3)
    for load_n, xf in zip(rng.uniform(100, 880, 12), rng.uniform(-0.3, 0.1, 12), strict=True):
        x, gap = model(load_n, xf)
        cold = solve_beam_contact(beam, load_n, xf)
        np.testing.assert_allclose(gap, cold.gap_m, atol=1e-12)
        np.testing.assert_array_equal(x, cold.positions_m)


def test_a_beam_fitted_above_the_noise_is_not_served():
    """An identification that passed but whose forward fit stopped above the noise (a local
    minimum) is not the profile model; the ski says why."""
    rec = read_ski(SKI)
    ident = _identified_group(rec.beam)
    ident["attrs"]["misfit_m"] = 3.3e-6  # 1.10 × the noise
    assert served_beam(ident) is None
    assert "local minimum" in served_beam_note(ident)
    assert ProfileModel(dataclasses.replace(rec, identified=ident, cache={})).source != (
        "identified_beam"
    )
