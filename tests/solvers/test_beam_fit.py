"""Forward-model beam fit (solvers.beam_fit): kink detection, the camber basis, and the
implicit-differentiation gradient of the exact device model against finite differences."""

import numpy as np
import pytest
from skisnow.solvers import beam_fit
from skisnow.solvers.beam import BeamSki, ClassicSkiDesign, measure_camber

LOADS_N = np.linspace(10, 90, 7) * 9.82
POSITIONS_M = np.linspace(-0.30, 0.10, 6)
DESIGN = ClassicSkiDesign(
    camber_height_m=0.0025,
    pocket_m=(-0.30, 0.35),
    pocket_height_m=6e-4,
    stiffness_nm2=2200.0,
    end_stiffness_ratio=0.2,
)


def test_kinks_found_where_the_design_has_them():
    """The design's camber has slope kinks where the shovels start (tail and tip contact
    points); 42 cases with 3 µm noise place them within one node."""
    ski = DESIGN.build(1e-3)
    _, _, y = measure_camber(ski, LOADS_N, POSITIONS_M, noise_m=3e-6, rng=4)
    kinks = beam_fit.detect_camber_kinks(ski.positions_m, y, 3e-6)
    assert kinks.size == 2
    np.testing.assert_allclose(kinks, [DESIGN.tail_contact_m, DESIGN.tip_contact_m], atol=1e-3)


def test_no_kink_on_a_smooth_camber():
    """A smooth camber (no kink anywhere) measured with noise: nothing is detected."""
    x = np.linspace(-0.97, 1.03, 2001)
    c = 1.5e-3 * np.cos(np.pi * x / 2.2) ** 2 + 2e-3 * ((x - 0.03) / 1.0) ** 4
    ski = BeamSki(x, np.full(x.size, 1500.0), c - c.min())
    _, _, y = measure_camber(ski, LOADS_N, POSITIONS_M, noise_m=3e-6, rng=5)
    assert beam_fit.detect_camber_kinks(x, y, 3e-6).size == 0


def test_camber_basis_holds_a_kinked_quadratic():
    """With the kink as a triple knot, a piecewise quadratic with a slope jump there is in the
    basis (least-squares residual at rounding); without it, it is not."""
    x = np.linspace(-1.0, 1.0, 801)
    f = 1e-3 * (np.abs(x - 0.2137) + 3.0 * x**2)
    with_kink, _ = beam_fit.camber_basis(x, 0.05, np.array([0.2137]))
    coef = np.linalg.lstsq(with_kink, f, rcond=None)[0]
    assert np.abs(with_kink @ coef - f).max() < 1e-12
    without, _ = beam_fit.camber_basis(x, 0.05, None)
    coef = np.linalg.lstsq(without, f, rcond=None)[0]
    assert np.abs(without @ coef - f).max() > 1e-6


def test_gradient_matches_finite_differences():
    """Jᵀρ of the implicit differentiation (contact sets fixed) equals ½ ∇ of the residual sum
    of squares by central differences, for camber coefficients and log-compliances alike."""
    ski = DESIGN.build(4e-3)
    x = ski.positions_m
    f, xf, y = measure_camber(ski, LOADS_N[::3], POSITIONS_M[::2], noise_m=3e-6, rng=6)
    bc, _ = beam_fit.camber_basis(x, 0.02, np.array([DESIGN.tail_contact_m, DESIGN.tip_contact_m]))
    knots = np.linspace(x[0], x[-1], 21)
    model = beam_fit._Model(x, f, xf, y, 3e-6, bc, knots, 10.0)
    cc = np.linalg.lstsq(bc, ski.unloaded_gap_m, rcond=None)[0]
    gamma = np.log(1.0 / np.interp(knots, x, ski.bending_stiffness_nm2))
    theta = np.concatenate([cc, gamma + 0.05 * np.sin(np.arange(knots.size))])
    _, _, _, jtr, ok = model.evaluate(theta, jacobian=True)
    assert ok
    rng = np.random.default_rng(0)
    picks = list(rng.choice(bc.shape[1], 6, replace=False)) + [bc.shape[1] + i for i in (3, 10, 16)]
    for i in picks:
        h = 1e-9 if i < bc.shape[1] else 1e-5  # [m] for c's coefficients, [-] for γ
        up, down = theta.copy(), theta.copy()
        up[i] += h
        down[i] -= h
        fd = (model.evaluate(up, False)[0] - model.evaluate(down, False)[0]) / (2 * h)
        assert 0.5 * fd == pytest.approx(jtr[i], rel=2e-3, abs=1e-6 * np.abs(jtr).max())


def test_unloaded_case_is_the_camber_on_the_flat_with_its_exact_jacobian():
    """A 0 N case is the unloaded profile (#26): its device model is c resting on its two end
    contacts (no deflection, no contact solve), its residual enters the sum, and its Jᵀρ and
    JᵀJ (c's block only; γ does not move it) match central differences."""
    ski = DESIGN.build(4e-3)
    x = ski.positions_m
    f, xf, y = measure_camber(ski, LOADS_N[::3], POSITIONS_M[::2], noise_m=3e-6, rng=6)
    y0 = ski.unloaded_gap_m + np.random.default_rng(1).normal(0.0, 3e-6, x.size)
    bc, _ = beam_fit.camber_basis(x, 0.02, np.array([DESIGN.tail_contact_m, DESIGN.tip_contact_m]))
    knots = np.linspace(x[0], x[-1], 21)
    cc = np.linalg.lstsq(bc, ski.unloaded_gap_m, rcond=None)[0]
    gamma = np.log(1.0 / np.interp(knots, x, ski.bending_stiffness_nm2))
    theta = np.concatenate([cc + 2e-6 * np.cos(np.arange(cc.size)), gamma])
    one = beam_fit._Model(x, np.zeros(1), np.zeros(1), y0[None, :], 3e-6, bc, knots, 10.0)
    ssr, _per, jtj, jtr, ok = one.evaluate(theta, jacobian=True)
    assert ok
    gap = beam_fit.camber_on_flat(x, bc @ theta[: bc.shape[1]])
    assert ssr == pytest.approx(float(np.sum((gap - y0) ** 2)), rel=1e-12)
    nc = bc.shape[1]
    assert np.all(jtr[nc:] == 0) and np.all(jtj[nc:] == 0)
    # the Jacobian by differences (the supports do not move for these small steps)
    h = 1e-10
    jac = np.empty((x.size, nc))
    for i in range(nc):
        up, down = theta.copy(), theta.copy()
        up[i] += h
        down[i] -= h
        jac[:, i] = (
            beam_fit.camber_on_flat(x, bc @ up[:nc]) - beam_fit.camber_on_flat(x, bc @ down[:nc])
        ) / (2 * h)
    np.testing.assert_allclose(jtr[:nc], jac.T @ (gap - y0), atol=1e-6 * np.abs(jtr).max())
    np.testing.assert_allclose(jtj[:nc, :nc], jac.T @ jac, atol=1e-6 * np.abs(jtj).max())
    # with the loaded cases: the sum of both parts
    both = beam_fit._Model(
        x, np.r_[0.0, f], np.r_[0.0, xf], np.vstack([y0, y]), 3e-6, bc, knots, 10.0
    )
    loaded = beam_fit._Model(x, f, xf, y, 3e-6, bc, knots, 10.0)
    s2, _, jtj2, jtr2, _ = both.evaluate(theta, jacobian=True)
    s3, _, jtj3, jtr3, _ = loaded.evaluate(theta, jacobian=True)
    assert s2 == pytest.approx(ssr + s3, rel=1e-12)
    np.testing.assert_allclose(jtr2, jtr + jtr3, atol=1e-9 * np.abs(jtr2).max())
    np.testing.assert_allclose(jtj2, jtj + jtj3, atol=1e-9 * np.abs(jtj2).max())


def test_scaled_inverse_keeps_the_directions_only_a_prior_holds():
    """Normal matrices of the forward fit mix camber coefficients [m] (data information
    ~1e15) with log-compliances held only by the prior (~1): a plain pseudo-inverse cut at
    1e-15 of the largest singular value drops the latter and gives them zero variance; the
    Jacobi-scaled inverse is the true inverse."""
    rng = np.random.default_rng(3)
    a = rng.standard_normal((6, 6))
    h = a @ a.T + 6 * np.eye(6)
    scale = np.array([1e8, 1e8, 1e8, 1.0, 1.0, 1e-1])
    h = h * np.outer(scale, scale)
    want = np.linalg.inv(h)
    got = beam_fit._scaled_inverse(h)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=0)
    plain = np.linalg.pinv(h, hermitian=True)
    assert plain[5, 5] < 1e-3 * want[5, 5]  # the failure this guards against


def test_covariance_is_wide_where_no_case_bends_the_ski():
    """Fitted from its true beam on 7 loads × 6 positions between −300 and +100 mm, the
    device bends the ski only between its contact points: there the cases set EI (model
    resolution near 1) and the standard deviation of log EI is small; beyond the contact
    points no case bends the ski (resolution near 0), the smoothing prior extrapolates EI and
    the covariance says so: the standard deviation grows towards the ends to many times the
    middle's. The truth lies within 3 standard deviations at every knot."""
    ski = DESIGN.build(4e-3)
    x = ski.positions_m
    f, xf, y = measure_camber(ski, LOADS_N, POSITIONS_M, noise_m=3e-6, rng=8)
    knots = np.linspace(x[0], x[-1], 41)
    fit = beam_fit.fit_forward(
        x, f, xf, y, ski, noise_m=3e-6, stiffness_knots_m=knots, smoothing=10.0, max_steps=20
    )
    nc = fit.camber_coefficients.size
    sd = np.sqrt(np.diag(fit.covariance)[nc:])
    r = fit.stiffness_resolution
    mid = np.abs(knots - (-0.1)) < 0.2
    ends = (knots < DESIGN.tail_contact_m - 0.05) | (knots > DESIGN.tip_contact_m + 0.1)
    assert r[mid].min() > 0.6, r[mid]
    assert r[ends].max() < 0.1, r[ends]
    assert sd[ends].min() > 5 * sd[mid].max(), (sd[ends], sd[mid])
    truth = np.log(np.interp(knots, x, ski.bending_stiffness_nm2))
    z = np.abs(-fit.log_compliance - truth) / sd
    assert z.max() < 3.0, z
