"""The design catalogue of the identification studies (solvers.ski_designs), random designs
included: each builds a valid beam, the same seed the same design."""

from __future__ import annotations

import numpy as np
import pytest
from skisnow.solvers.beam import ClassicSkiDesign
from skisnow.solvers.errors import InputError
from skisnow.solvers.ski_designs import (
    STUDY_DESIGNS,
    VALIDATION_DESIGNS,
    FunctionalSkiDesign,
    design_family,
    get_design,
    random_design,
)


def _check_beam(design) -> None:
    beam = design.build(2e-3)
    x, ei, c = beam.positions_m, beam.bending_stiffness_nm2, beam.unloaded_gap_m
    assert 1.6 < x[-1] - x[0] < 2.2  # a cross-country ski's length [m]
    assert np.all(np.isfinite(ei)) and ei.min() > 100.0 and ei.max() < 5000.0
    assert np.all(np.isfinite(c)) and c.min() >= 0.0
    mid = np.abs(x) < 0.5
    # a camber under the foot of 0.5-3 mm that rests on the flat at both ends of the arch
    assert 0.5e-3 < c[mid].max() < 3e-3
    assert c[x < -0.5].min() < 1e-5 and c[x > 0.5].min() < 1e-5  # within a node


@pytest.mark.parametrize("name", [*STUDY_DESIGNS, *VALIDATION_DESIGNS])
def test_named_designs_build_valid_beams(name):
    assert get_design(name) is {**STUDY_DESIGNS, **VALIDATION_DESIGNS}[name]
    assert design_family(name) in ("classic", "functional", "skate")
    _check_beam(get_design(name))


def test_random_designs_are_seeded_valid_and_varied():
    families, plates, pockets = set(), 0, 0
    for seed in range(40):
        family, design = random_design(seed)
        assert random_design(seed) == (family, design)  # the same seed, the same design
        assert get_design(f"random-{seed}") == design
        assert design_family(f"random-{seed}") == family
        _check_beam(design)
        families.add(family)
        if family == "classic":
            assert isinstance(design, ClassicSkiDesign)
        else:
            assert isinstance(design, FunctionalSkiDesign)
            plates += design.plate_gain > 0
            pockets += design.bump_height_m > 0
    assert families == {"classic", "functional", "skate"}
    assert plates >= 5 and pockets >= 5  # both features drawn in and left out
    assert random_design(1) != random_design(2)


@pytest.mark.parametrize("name", ["nope", "random-", "random-x", "random--1"])
def test_unknown_design_names_are_refused_with_the_known_ones(name):
    with pytest.raises(InputError, match="random-<seed>"):
        get_design(name)
    with pytest.raises(InputError, match="unknown design"):
        design_family(name)


@pytest.mark.parametrize("seed", [-1, 1.5, True, "3"])
def test_random_design_refuses_a_bad_seed(seed):
    with pytest.raises(InputError, match="seed"):
        random_design(seed)
