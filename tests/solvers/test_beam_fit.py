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
    _assert_gradient_by_central_differences(model, theta, jtr, bc.shape[1])


def _assert_gradient_by_central_differences(model, theta, jtr, nc):
    """Jᵀρ equals ½ ∇ of the residual sum of squares by central differences, at six camber
    coefficients and three log-compliances (of ``nc`` camber coefficients)."""
    rng = np.random.default_rng(0)
    picks = list(rng.choice(nc, 6, replace=False)) + [nc + i for i in (3, 10, 16)]
    for i in picks:
        h = 1e-9 if i < nc else 1e-5  # [m] for c's coefficients, [-] for γ
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


def test_model_grid_holds_the_measured_nodes_bit_for_bit():
    """The finer model grid divides each measured interval evenly and keeps the measured
    positions exactly; samples within MODEL_REFINE_RATIO × the spacing keep their nodes."""
    x = np.linspace(-0.8, 0.8, 321)  # 5 mm
    x_f, obs = beam_fit.model_grid(x, 1e-3)
    assert x_f.size == 320 * 5 + 1
    assert np.array_equal(x_f[obs], x)
    assert np.allclose(np.diff(x_f), 1e-3, rtol=1e-9)
    assert beam_fit.model_grid(x, 0.0) is None
    assert beam_fit.model_grid(np.linspace(-0.8, 0.8, 1281), 1e-3) is None  # 1.25 mm
    x_f, obs = beam_fit.model_grid(np.linspace(-0.8, 0.8, 801), 1e-3)  # 2 mm
    assert obs[1] == 2 and x_f.size == 1601


def test_gradient_on_a_finer_model_grid_matches_finite_differences():
    """Residuals at the measured nodes only, the device model on nodes 4× finer: Jᵀρ of the
    implicit differentiation (contact rows the model's, residual rows the measured ones) equals
    ½ ∇ of the residual sum of squares, for the loaded cases and the unloaded profile."""
    fine = DESIGN.build(2e-3)
    x_f, obs = beam_fit.model_grid(fine.positions_m[::4], 2e-3)
    assert np.allclose(x_f, fine.positions_m, rtol=0.0, atol=1e-12)
    f, xf, y = measure_camber(fine, LOADS_N[::3], POSITIONS_M[::2], noise_m=3e-6, rng=6)
    y0 = fine.unloaded_gap_m + np.random.default_rng(1).normal(0.0, 3e-6, x_f.size)
    f, xf, y = np.r_[0.0, f], np.r_[0.0, xf], np.vstack([y0, y])[:, obs]
    bc, _ = beam_fit.camber_basis(
        x_f, 0.02, np.array([DESIGN.tail_contact_m, DESIGN.tip_contact_m])
    )
    knots = np.linspace(x_f[0], x_f[-1], 21)
    model = beam_fit._Model(x_f, f, xf, y, 3e-6, bc, knots, 10.0, obs=obs)
    cc = np.linalg.lstsq(bc, fine.unloaded_gap_m, rcond=None)[0]
    gamma = np.log(1.0 / np.interp(knots, x_f, fine.bending_stiffness_nm2))
    theta = np.concatenate(
        [cc + 2e-6 * np.cos(np.arange(cc.size)), gamma + 0.05 * np.sin(np.arange(knots.size))]
    )
    _, per, _, jtr, ok = model.evaluate(theta, jacobian=True)
    assert ok and per.size == f.size
    _assert_gradient_by_central_differences(model, theta, jtr, bc.shape[1])


def test_every_node_observed_is_the_plain_model_bit_for_bit():
    """obs naming every node gives the same sums and normal equations as no obs at all."""
    ski = DESIGN.build(4e-3)
    x = ski.positions_m
    f, xf, y = measure_camber(ski, LOADS_N[::3], POSITIONS_M[::2], noise_m=3e-6, rng=6)
    bc, _ = beam_fit.camber_basis(x, 0.02)
    knots = np.linspace(x[0], x[-1], 21)
    cc = np.linalg.lstsq(bc, ski.unloaded_gap_m, rcond=None)[0]
    theta = np.concatenate([cc, np.log(1.0 / np.interp(knots, x, ski.bending_stiffness_nm2))])
    a = beam_fit._Model(x, f, xf, y, 3e-6, bc, knots, 10.0).evaluate(theta, True)
    b = beam_fit._Model(x, f, xf, y, 3e-6, bc, knots, 10.0, obs=np.arange(x.size)).evaluate(
        theta, True
    )
    assert a[0] == pytest.approx(b[0], rel=1e-12)
    assert np.allclose(a[2], b[2], rtol=1e-10, atol=1e-12 * np.abs(a[2]).max())
    assert np.allclose(a[3], b[3], rtol=1e-10, atol=1e-12 * np.abs(a[3]).max())


def test_samples_every_5_mm_fitted_on_1_mm_nodes_predict_the_device_better():
    """A device that measures the ski continuously (here on 1 mm nodes), sampled every 5 mm:
    fitted from its true beam, the model on the samples' nodes misses held-out loaded profiles
    near contact by far more than the model on 1 mm nodes (residuals at the samples only).
    Measured: 0.98 µm on the samples' nodes, 0.36 µm on 1 mm nodes (random-601 of the sample-
    spacing study: 0.78 and 0.37 µm, docs/camber-identification.md)."""
    truth = DESIGN.build(1e-3)
    loads, positions = np.linspace(10, 90, 9) * 9.82, np.linspace(-0.30, 0.10, 7)
    f, xf, y = measure_camber(truth, loads, positions, noise_m=3e-6, rng=9)
    x = truth.positions_m[::5]
    y = y[:, ::5]
    knots = np.linspace(x[0], x[-1], 33)
    start = BeamSki(x, truth.bending_stiffness_nm2[::5], truth.unloaded_gap_m[::5])
    rng = np.random.default_rng(3)
    hf, hx = rng.uniform(15, 85, 8) * 9.82, rng.uniform(-0.28, 0.08, 8)
    from skisnow.solvers.identify import predict_gaps

    exact = predict_gaps(truth, hf, hx)
    near = exact < 2e-4
    out = {}
    for spacing in (0.0, 1e-3):
        fit = beam_fit.fit_forward(
            x,
            f,
            xf,
            y,
            start,
            noise_m=3e-6,
            stiffness_knots_m=knots,
            smoothing=10.0,
            model_spacing_m=spacing,
        )
        assert fit.converged, fit.message
        assert fit.case_misfit_m.size == f.size
        pred = predict_gaps(fit.beam, hf, hx, truth.positions_m)
        out[spacing] = float(np.sqrt(np.mean((pred - exact)[near] ** 2)))
    assert np.array_equal(fit.beam.positions_m[::5], x)
    assert out[1e-3] < 0.6e-6
    assert out[1e-3] < 0.6 * out[0.0]
