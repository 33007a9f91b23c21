"""Beam camber device: closed form, equilibrium, complementarity, measuring noise."""

import numpy as np
import pytest
from skisnow.solvers.beam import BeamSki, ClassicSkiDesign, measure_camber, solve_beam_contact
from skisnow.solvers.errors import InputError


@pytest.mark.parametrize("n", [1001, 1000])
def test_simply_supported_central_load(n):
    """Arched uniform beam touching only at its ends: w = F x (3L² − 4x²) / (48 EI)."""
    length, ei, load = 1.0, 100.0, 100.0
    x = np.linspace(0.0, length, n)
    camber = 0.05 * 4 * x * (length - x) / length**2  # deep arch: only the end nodes touch
    res = solve_beam_contact(BeamSki(x, np.full(n, ei), camber), load, length / 2)
    assert res.converged, res.message
    xf = x[np.argmin(np.abs(x - length / 2))] if n % 2 else length / 2
    s = np.minimum(x, 2 * xf - x) if n % 2 else np.minimum(x, length - x)
    expected = load * s * (3 * length**2 - 4 * s**2) / (48 * ei)
    deflection = camber - res.gap_m
    # exact for the discrete model when the load sits on a node; linear load split otherwise
    rel = np.abs(deflection - expected).max() / expected.max()
    assert rel < (1e-10 if n % 2 else 1e-5)
    assert res.reaction_n[0] == pytest.approx(load / 2, rel=1e-9)
    assert res.reaction_n[-1] == pytest.approx(load / 2, rel=1e-9)


def test_classic_ski_equilibrium_and_complementarity():
    ski = ClassicSkiDesign().build()
    for kg, xf in [(10, -0.3), (40, -0.16), (90, 0.1)]:
        res = solve_beam_contact(ski, kg * 9.82, xf)
        assert res.converged, res.message
        assert res.force_residual < 1e-10 and res.moment_residual < 1e-10
        assert res.gap_m.min() >= 0 and res.reaction_n.min() >= 0
        assert np.all(res.gap_m[res.reaction_n > 0] == 0)
        assert res.residual < 1e-8


def test_measure_camber_is_seeded():
    ski = ClassicSkiDesign().build(spacing_m=4e-3)
    a = measure_camber(ski, [100.0, 400.0], [-0.2, 0.0], noise_m=3e-6, rng=7)
    b = measure_camber(ski, [100.0, 400.0], [-0.2, 0.0], noise_m=3e-6, rng=7)
    assert a[2].shape == (4, ski.positions_m.size)
    np.testing.assert_array_equal(a[2], b[2])
    clean = measure_camber(ski, [100.0, 400.0], [-0.2, 0.0], noise_m=0.0)
    assert np.std(a[2] - clean[2]) == pytest.approx(3e-6, rel=0.1)


def test_invalid_inputs_name_the_parameter():
    ski = ClassicSkiDesign().build(spacing_m=5e-3)
    with pytest.raises(InputError, match="load_n"):
        solve_beam_contact(ski, -1.0, 0.0)
    with pytest.raises(InputError, match="load_position_m"):
        solve_beam_contact(ski, 100.0, 5.0)
    with pytest.raises(InputError, match="camber_height_m"):
        ClassicSkiDesign(camber_height_m=-1.0)
    with pytest.raises(InputError, match="rng"):
        measure_camber(ski, [100.0], [0.0], noise_m=1e-6)


def test_measure_unloaded_is_the_camber_plus_seeded_noise():
    """The unloaded case of the virtual device (#26): the gap with no load is c(X) (zero at the
    two contacts), the noise is seeded and has the asked standard deviation."""
    from skisnow.solvers.beam import ClassicSkiDesign, measure_unloaded
    from skisnow.solvers.beam_fit import camber_on_flat
    from skisnow.solvers.identify import predict_gaps

    fine = ClassicSkiDesign().build(1e-3)  # c is zero at both contacts: the gap is c itself
    np.testing.assert_allclose(measure_unloaded(fine, noise_m=0.0), fine.unloaded_gap_m, atol=1e-15)
    # a coarse sampling leaves c above zero at a contact: the ski rests on its lower hull
    ski = ClassicSkiDesign().build(4e-3)
    clean = measure_unloaded(ski, noise_m=0.0)
    assert (clean <= 1e-15).sum() >= 2 and clean.min() >= 0.0
    np.testing.assert_array_equal(clean, camber_on_flat(ski.positions_m, ski.unloaded_gap_m))
    np.testing.assert_allclose(clean, predict_gaps(ski, [0.0], [0.0])[0], atol=1e-15)
    a = measure_unloaded(ski, noise_m=3e-6, rng=7)
    b = measure_unloaded(ski, noise_m=3e-6, rng=7)
    np.testing.assert_array_equal(a, b)
    assert abs(np.std(a - clean) - 3e-6) < 0.3e-6
    with pytest.raises(InputError):
        measure_unloaded(ski, noise_m=3e-6)
