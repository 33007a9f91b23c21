"""Micro solver against closed forms (Westergaard, JGH full contact) and its edge cases."""

import numpy as np
import pytest
from skisnow.solvers import reference
from skisnow.solvers.errors import InputError
from skisnow.solvers.micro import full_contact_pressure, solve_micro

E_EFF = 2.0e8  # E' [Pa]


@pytest.mark.parametrize("ratio", [0.01, 0.1, 0.5])
def test_westergaard_contact_fraction(ratio):
    n, lam, amp = 2048, 1e-3, 1e-6
    dx = lam / n
    x = (np.arange(n) + 0.5) * dx
    h = amp * np.cos(2 * np.pi * x / lam)[:, None] * np.ones((1, 3))
    p_star = reference.westergaard_full_contact_pressure(amp, lam, E_EFF)
    res = solve_micro(h, dx, ratio * p_star, E_EFF, tol=1e-9)
    assert res.converged, res.message
    expected = reference.westergaard_contact_fraction(ratio * p_star, amp, lam, E_EFF)
    assert res.real_contact_area_fraction == pytest.approx(expected, rel=0.01)
    # force balance is imposed exactly
    assert res.pressure_pa.mean() == pytest.approx(ratio * p_star, rel=1e-10)


def test_westergaard_pressure_field():
    n, lam, amp = 512, 1e-3, 1e-6
    dx = lam / n
    x = (np.arange(n) + 0.5) * dx - lam / 2
    h = amp * np.cos(2 * np.pi * x / lam)[:, None] * np.ones((1, 2))
    p_star = reference.westergaard_full_contact_pressure(amp, lam, E_EFF)
    res = solve_micro(h, dx, 0.2 * p_star, E_EFF, tol=1e-10)
    expected = reference.westergaard_pressure(x, 0.2 * p_star, amp, lam, E_EFF)
    peak = expected.max()
    err = np.abs(res.pressure_pa[:, 0] - expected).max() / peak
    assert err < 0.03  # pixel-sized error at the contact edge (sqrt singularity of dp/dx)


@pytest.mark.parametrize("n", [128, 129])
def test_jgh_full_contact_pressure(n):
    """One Fourier mode: the FFT half-space is exact for it, so the only error is where the
    grid samples the deepest valley. On an even grid it samples the valley (−Δ) itself: the
    closed form to rounding (measured 1e-14 on 128²). On an odd grid the nearest sample is
    −Δ cos(π/n), and p_fc is the closed form times cos(π/n) (−3.0e-4 on 129², measured; the
    product agrees to 1e-14). Bounds: rounding 1e-12, plus the valley's sampling on odd grids.
    """
    lam, amp = 1e-3, 1e-6
    dx = lam / n
    x = np.arange(n) * dx
    h = amp * np.cos(2 * np.pi * x / lam)[:, None] * np.cos(2 * np.pi * x / lam)[None, :]
    expected = reference.jgh_full_contact_pressure(amp, lam, E_EFF)
    p_fc, _ = full_contact_pressure(h, dx, E_EFF)
    valley_sampling = 0.0 if n % 2 == 0 else 1.0 - np.cos(np.pi / n)
    assert p_fc == pytest.approx(expected * (1.0 - valley_sampling), rel=1e-12)
    assert abs(p_fc / expected - 1.0) <= valley_sampling + 1e-12
    res = solve_micro(h, dx, 1.01 * expected, E_EFF)
    assert res.full_contact and res.real_contact_area_fraction > 0.999
    below = solve_micro(h, dx, 0.9 * expected, E_EFF, tol=1e-8)
    assert not below.full_contact and below.real_contact_area_fraction < 1.0


def test_zero_load_is_unloaded_state():
    rng = np.random.default_rng(1)
    h = rng.normal(size=(32, 33)) * 1e-6
    res = solve_micro(h, 1e-6, 0.0, E_EFF)
    assert res.converged and res.real_contact_area_fraction == 0.0
    np.testing.assert_array_equal(res.gap_m, h.max() - h)
    assert res.mean_gap_m == pytest.approx(h.max() - h.mean())


@pytest.mark.parametrize(
    "bad",
    [
        {"heights_m": np.array([[0.0, np.nan], [1.0, 2.0]])},
        {"heights_m": np.array([[0.0, np.inf], [1.0, 2.0]])},
        {"nominal_pressure_pa": -1.0},
        {"nominal_pressure_pa": np.nan},
        {"effective_modulus_pa": 0.0},
        {"heights_m": np.zeros((4, 4))},
        {"heights_m": np.zeros(4)},
    ],
)
def test_bad_input_raises(bad):
    kwargs = {
        "heights_m": np.arange(16.0).reshape(4, 4) * 1e-6,
        "pixel_size_m": 1e-6,
        "nominal_pressure_pa": 1e3,
        "effective_modulus_pa": E_EFF,
    }
    kwargs.update(bad)
    with pytest.raises(InputError):
        solve_micro(**kwargs)


def test_iteration_cap_is_reported_not_hidden():
    rng = np.random.default_rng(2)
    h = rng.normal(size=(64, 64)) * 1e-6
    res = solve_micro(h, 1e-6, 1e5, E_EFF, max_iterations=2, nested=False, tol=1e-12)
    assert not res.converged
    assert "not converged" in res.message


@pytest.mark.parametrize("shape", [(64, 64), (63, 65)])
def test_nine_decades_monotone(shape):
    rng = np.random.default_rng(3)
    from skisnow.solvers.texture import self_affine_surface

    h = self_affine_surface(shape, 1e-6, hurst=0.8, rms_height_m=1e-6, rng=rng)
    fractions, gaps = [], []
    p_prev = None
    for ratio in np.logspace(-9, 0, 10):
        res = solve_micro(h, 1e-6, ratio * E_EFF, E_EFF, tol=1e-8, initial_pressure_pa=p_prev)
        assert res.converged or res.full_contact, res.message
        assert np.isfinite(res.mean_gap_m) and np.isfinite(res.mean_reciprocal_gap_per_m)
        fractions.append(res.real_contact_area_fraction)
        gaps.append(res.mean_gap_m)
        p_prev = None if res.full_contact else res.pressure_pa
    assert np.all(np.diff(fractions) >= 0)
    assert np.all(np.diff(gaps) <= 1e-15)
    assert fractions[-1] == 1.0
