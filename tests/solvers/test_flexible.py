"""Flexible ski on snow (docs/physics.md §4b): device limit, dense reference, balance, stiff limit,
mesh convergence, input errors."""

import numpy as np
import pytest
import scipy.linalg
import scipy.optimize
from skisnow.app.storage.skis import read_ski
from skisnow.solvers import flexible, macro
from skisnow.solvers.beam import G_STANDARD, BeamSki, ClassicSkiDesign, solve_beam_contact
from skisnow.solvers.elastic import (
    NonPeriodicHalfSpace,
    effective_modulus,
    love_rectangle_influence,
)
from skisnow.solvers.errors import InputError
from skisnow.solvers.flexible import FlexibleModel, prepare_flexible, solve_flexible

#: the papers' case (docs/physics.md §4): 40 kg at −160 mm, E_snow = 200 MPa
PAPER_LOAD_N = 40 * G_STANDARD
PAPER_POSITION_M = -0.160
PAPER_E_EFF = effective_modulus(200e6, 0.7e9, 0.3)


@pytest.fixture(scope="module")
def demo_models():
    out = {}
    for name in ("ski-a", "ski-b"):
        rec = read_ski(f"tables/skis/{name}.h5")
        out[name] = (
            rec,
            prepare_flexible(
                rec.beam, rec.outline.width_m, width_positions_m=rec.outline.positions_m
            ),
        )
    return out


# --------------------------------------------------------------------------------------------
# 1. rigid snow, beam grid = pixel rows: the measuring device
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("load_n", "load_position_m"), [(PAPER_LOAD_N, PAPER_POSITION_M), (700.0, 0.05), (150.0, -0.4)]
)
def test_rigid_snow_is_the_measuring_device(load_n, load_position_m):
    spacing = 4e-3
    design = ClassicSkiDesign()
    # ski nodes every spacing/2 so that the pixel-row centres (tail + spacing (i + ½)) are nodes
    fine = design.build(spacing_m=spacing / 2)
    model = prepare_flexible(fine, 0.044, pixel_along_m=spacing, pixels_across=1)
    rows = model.positions_m
    np.testing.assert_allclose(rows, fine.positions_m[1::2][: rows.size], rtol=0, atol=1e-12)
    # the device's beam on exactly those nodes, built from the design independently
    device_ski = BeamSki(rows, design.stiffness(rows), design.camber(rows))
    dev = solve_beam_contact(device_ski, load_n, load_position_m)
    assert dev.converged
    res = solve_flexible(model, load_n, load_position_m, np.inf)
    assert res.converged, res.message
    r = res.extra["beam_reaction_row_n"]
    np.testing.assert_allclose(r, dev.reaction_n, rtol=0, atol=1e-8 * load_n)
    np.testing.assert_array_equal(r > 1e-8 * load_n, dev.reaction_n > 1e-8 * load_n)
    gap_scale = float(np.ptp(device_ski.unloaded_gap_m))
    np.testing.assert_allclose(res.extra["beam_gap_m"], dev.gap_m, rtol=0, atol=1e-8 * gap_scale)
    np.testing.assert_allclose(res.clearance_m, dev.gap_m, rtol=0, atol=1e-8 * gap_scale)
    dx, dy = res.pixel_size_m
    np.testing.assert_allclose(res.pressure_pa[:, 0] * dx * dy, dev.reaction_n, atol=1e-8 * load_n)


def test_rigid_snow_spreads_rows_across_the_width(demo_models):
    _, model = demo_models["ski-b"]
    res = solve_flexible(model, PAPER_LOAD_N, PAPER_POSITION_M, np.inf)
    dev = solve_beam_contact(
        model.row_beam, PAPER_LOAD_N, PAPER_POSITION_M, flexibility=model.row_flexibility
    )
    np.testing.assert_allclose(
        res.extra["beam_reaction_row_n"], dev.reaction_n, atol=1e-8 * PAPER_LOAD_N
    )
    p = res.pressure_pa
    touching = np.nanmax(p, axis=1) > 0
    assert np.all(np.nanmin(p[touching], axis=1) == np.nanmax(p[touching], axis=1))


# --------------------------------------------------------------------------------------------
# 2. an independent dense solve
# --------------------------------------------------------------------------------------------


def _small_ski(stiffness_nm2: float = 40.0) -> BeamSki:
    """A 24 cm uniform beam: shallow parabolic camber, steep ends."""
    x = np.linspace(-0.12, 0.12, 241)
    arch = 3e-4 * (1 - (x / 0.1) ** 2)
    c = np.where(np.abs(x) <= 0.1, arch, 2e-3 * ((np.abs(x) - 0.1) / 0.02) ** 2)
    return BeamSki(x, np.full(x.size, stiffness_nm2), c - c.min())


def _virtual_work_flexibility(x: np.ndarray, ei: np.ndarray) -> np.ndarray:
    """W[i, j]: upward deflection at node i (up to a rigid motion) per unit upward force at j,
    valid for self-equilibrated force sets, by virtual work: ∫ m_i M_j / EI dX with the moments
    at the nodes and M/EI, m linear between them (element-wise exact product integral).

    M_j(X) = (X − X_j)⁺ (moment of the forces behind X, equal to minus those ahead for an
    equilibrated set); m_i: a unit downward load at i on a beam simply supported at the end
    nodes, so ∫ m_i κ = −(w_i − chord of w through the end nodes).
    """
    n = x.size
    dx = float(x[1] - x[0])
    kappa = np.maximum(x[:, None] - x[None, :], 0.0) / ei[:, None]  # (node, load)
    span = x[-1] - x[0]
    a = x[None, :] - x[0]
    s = x[:, None] - x[0]
    m_virtual = np.where(s <= a, s * (span - a) / span, a * (span - s) / span)  # (node, i)
    mass = np.zeros((n, n))
    k = np.arange(n - 1)
    mass[k, k] += dx / 3
    mass[k + 1, k + 1] += dx / 3
    mass[k, k + 1] += dx / 6
    mass[k + 1, k] += dx / 6
    return -(m_virtual.T @ mass @ kappa)


def test_beam_operator_matches_virtual_work():
    """B of the model equals an independently integrated flexibility (varying EI) up to a rigid
    motion, on self-equilibrated row forces."""
    ski = ClassicSkiDesign().build(spacing_m=2e-3)
    model = prepare_flexible(ski, 0.044, pixel_along_m=8e-3, pixels_across=1)
    x = model.positions_m
    w = _virtual_work_flexibility(x, model.row_beam.bending_stiffness_nm2)
    q, _ = np.linalg.qr(np.stack([np.ones_like(x), x], axis=1))
    f = np.random.default_rng(7).standard_normal((x.size, 5))
    f -= q @ (q.T @ f)  # self-equilibrated
    diff = model.compliance_m_per_n @ f - w @ f
    diff -= q @ (q.T @ diff)  # up to a rigid motion
    assert np.abs(diff).max() <= 1e-12 * np.abs(w @ f).max()


def _dense_reference(model: FlexibleModel, load_n: float, xf: float, e_eff: float):
    """Dense complementarity problem solved by NNLS at fixed (δ, θ) plus nested Brent root
    finding on force and moment, then an exact KKT polish on the identified contact set."""
    gm = model.unloaded_map
    inside = np.isfinite(gm.gap_m)
    x = gm.positions_m
    dx, dy = gm.pixel_size_m
    nx, ny = gm.gap_m.shape
    ii, jj = np.nonzero(inside)
    xp, yp = x[ii], (jj - (ny - 1) / 2) * dy
    area = dx * dy
    snow = (2 / (np.pi * e_eff)) * love_rectangle_influence(
        xp[:, None] - xp[None, :], yp[:, None] - yp[None, :], dx / 2, dy / 2
    )
    rb = model.row_beam
    q, _ = np.linalg.qr(np.stack([np.ones_like(x), x], axis=1))
    proj = np.eye(nx) - q @ q.T
    w = proj @ _virtual_work_flexibility(x, rb.bending_stiffness_nm2) @ proj
    s = (xf - x[0]) / dx
    i0 = int(np.floor(s))
    e_load = np.zeros(nx)
    e_load[[i0, i0 + 1]] = [1 - (s - i0), s - i0]
    h = rb.unloaded_gap_m[ii] - load_n * (w @ e_load)[ii]
    mat = snow + area * w[np.ix_(ii, ii)]
    assert np.abs(mat - mat.T).max() <= 1e-12 * np.abs(mat).max()  # uniform EI: symmetric
    mat = 0.5 * (mat + mat.T)
    chol = np.linalg.cholesky(mat)
    xs = xp - xf

    def pressure(delta, theta):
        rhs = -scipy.linalg.solve_triangular(chol, h - delta - theta * xs, lower=True)
        return scipy.optimize.nnls(chol.T, rhs, maxiter=5000)[0]

    def delta_of(theta):
        lo = float((h - theta * xs).min())
        return scipy.optimize.brentq(
            lambda d: pressure(d, theta).sum() * area - load_n, lo, lo + 1e-2, xtol=1e-18
        )

    theta = scipy.optimize.brentq(lambda t: pressure(delta_of(t), t) @ xs, -0.05, 0.05, xtol=1e-18)
    contact = pressure(delta_of(theta), theta) > 0
    m = int(contact.sum())
    kkt = np.zeros((m + 2, m + 2))
    kkt[:m, :m] = mat[np.ix_(contact, contact)]
    kkt[:m, m] = -1.0
    kkt[:m, m + 1] = -xs[contact]
    kkt[m, :m] = area
    kkt[m + 1, :m] = area * xs[contact]
    sol = np.linalg.solve(kkt, np.concatenate([-h[contact], [load_n, 0.0]]))
    p = np.zeros(xs.size)
    p[contact] = sol[:m]
    gap = h + mat @ p - sol[m] - sol[m + 1] * xs
    scale = float(np.abs(mat @ p).max())
    assert p.min() >= 0 and gap[~contact].min() >= -1e-12 * scale  # a complementarity solution
    return p, float(sol[m]), float(sol[m + 1]), (ii, jj)


@pytest.mark.parametrize(
    ("pixels_across", "e_eff", "xf"), [(3, 2e7, -0.02), (2, 5e7, 0.015), (3, 2e8, 0.0)]
)
def test_dense_reference(pixels_across, e_eff, xf):
    model = prepare_flexible(_small_ski(), 0.03, pixel_along_m=10e-3, pixels_across=pixels_across)
    load = 60.0
    p_ref, delta, theta, (ii, jj) = _dense_reference(model, load, xf, e_eff)
    res = solve_flexible(model, load, xf, e_eff, tol=1e-11)
    assert res.converged, res.message
    p = res.pressure_pa[ii, jj]
    assert np.abs(p - p_ref).max() <= 1e-6 * p_ref.max()
    np.testing.assert_array_equal(p > 0, p_ref > 0)
    # δ, θ: both sides carry the beam's rigid motion the same way (orthogonal to 1, X on rows)
    u_scale = float(np.abs(res.extra["beam_deflection_m"]).max())
    assert abs(res.approach_m - delta) <= 1e-6 * u_scale
    assert abs(res.tilt_rad - theta) * 0.24 <= 1e-6 * u_scale


# --------------------------------------------------------------------------------------------
# 3. balance, warm start, zero load
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["ski-a", "ski-b"])
def test_force_and_moment_balance(demo_models, name):
    _, model = demo_models[name]
    res = solve_flexible(model, PAPER_LOAD_N, PAPER_POSITION_M, PAPER_E_EFF)
    assert res.converged, res.message
    dx, dy = res.pixel_size_m
    p = np.nan_to_num(res.pressure_pa)
    length = res.window_m[1] - res.window_m[0]
    assert abs(p.sum() * dx * dy - PAPER_LOAD_N) <= 1e-10 * PAPER_LOAD_N
    moment = np.sum(p * (res.positions_m - PAPER_POSITION_M)[:, None]) * dx * dy
    assert abs(moment) <= 1e-10 * PAPER_LOAD_N * length
    assert res.force_residual <= 1e-10 and res.moment_residual <= 1e-10
    r = res.extra["beam_reaction_row_n"]
    assert abs(r.sum() - PAPER_LOAD_N) <= 1e-10 * PAPER_LOAD_N
    # the clearance is the beam's loaded profile plus the snow's displacement, ≥ 0
    assert np.nanmin(res.clearance_map_m) >= 0
    assert np.all(res.clearance_map_m[p > 0] == 0)


def test_warm_start_gives_the_same_answer(demo_models):
    _, model = demo_models["ski-a"]
    # pressures are asked to 1e-6 of their peak: the clearance tolerance is set 1e-10
    cold = solve_flexible(model, PAPER_LOAD_N, PAPER_POSITION_M, PAPER_E_EFF, tol=1e-10)
    warm = solve_flexible(
        model,
        PAPER_LOAD_N * 1.02,
        PAPER_POSITION_M,
        PAPER_E_EFF,
        tol=1e-10,
        initial_pressure_pa=cold.pressure_pa,
    )
    again = solve_flexible(model, PAPER_LOAD_N * 1.02, PAPER_POSITION_M, PAPER_E_EFF, tol=1e-10)
    assert warm.converged and again.converged
    assert warm.extra["warm_start"] == "initial_pressure_pa"
    scale = np.nanmax(again.pressure_pa)
    assert np.nanmax(np.abs(warm.pressure_pa - again.pressure_pa)) <= 1e-6 * scale


def test_zero_load(demo_models):
    _, model = demo_models["ski-a"]
    res = solve_flexible(model, 0.0, PAPER_POSITION_M, PAPER_E_EFF)
    assert res.converged and res.apparent_contact_area_m2 == 0.0
    assert np.nanmax(res.pressure_pa) == 0.0


# --------------------------------------------------------------------------------------------
# 4. stiff limit: the device's reactions
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["ski-a", "ski-b"])
def test_stiff_snow_tends_to_the_device(demo_models, name):
    """E_snow and E_base → ∞ together (E_base alone caps E' at 1.5 GPa): the row reactions tend
    to the device's, measured by the Wasserstein-1 distance of the two force distributions
    along the ski [m]; the beam's loaded profile tends to the device's gap."""
    _, model = demo_models[name]
    dev = solve_beam_contact(
        model.row_beam, PAPER_LOAD_N, PAPER_POSITION_M, flexibility=model.row_flexibility
    )
    dx = float(model.positions_m[1] - model.positions_m[0])
    gap_err, w1 = [], []
    for modulus in (2e9, 2e10, 2e11):  # E_snow = E_base: 2e3, 2e4, 2e5 MPa
        res = solve_flexible(
            model, PAPER_LOAD_N, PAPER_POSITION_M, effective_modulus(modulus, modulus, 0.3)
        )
        assert res.converged, res.message
        gap_err.append(np.abs(res.extra["beam_gap_m"] - dev.gap_m).max())
        cum = np.cumsum(res.extra["beam_reaction_row_n"] - dev.reaction_n)
        w1.append(np.abs(cum).sum() * dx / PAPER_LOAD_N)
    assert w1[0] > w1[1] > w1[2]
    assert w1[2] < 0.25 * w1[0]
    assert gap_err[0] > gap_err[1] > gap_err[2]


# --------------------------------------------------------------------------------------------
# 5. mesh convergence at the papers' case
# --------------------------------------------------------------------------------------------


def test_mesh_convergence(demo_models):
    rec, _ = demo_models["ski-b"]
    area, rear = [], []
    for pixel in (8e-3, 4e-3, 2e-3):
        model = prepare_flexible(
            rec.beam,
            rec.outline.width_m,
            pixel_along_m=pixel,
            width_positions_m=rec.outline.positions_m,
        )
        res = solve_flexible(model, PAPER_LOAD_N, PAPER_POSITION_M, PAPER_E_EFF)
        assert res.converged, res.message
        area.append(res.apparent_contact_area_m2)
        rear.append(sum(z.load_n for z in res.zones if z.start_m + z.end_m < 0))
    assert abs(area[2] - area[1]) < abs(area[1] - area[0])
    assert abs(rear[2] - rear[1]) < abs(rear[1] - rear[0])
    assert abs(area[2] - area[1]) < 0.02 * area[2]
    assert abs(rear[2] - rear[1]) < 0.01 * PAPER_LOAD_N


# --------------------------------------------------------------------------------------------
# 6. bad input
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"load_n": -1.0}, "load_n"),
        ({"load_n": np.nan}, "load_n"),
        ({"load_position_m": 5.0}, "load_position_m"),
        ({"load_position_m": np.inf}, "load_position_m"),
        ({"effective_modulus_pa": 0.0}, "effective_modulus_pa"),
        ({"effective_modulus_pa": np.nan}, "effective_modulus_pa"),
        ({"effective_modulus_pa": "soft"}, "effective_modulus_pa"),
        ({"tol": 0.0}, "tol"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"initial_pressure_pa": np.zeros((3, 3))}, "initial_pressure_pa"),
    ],
)
def test_bad_input(demo_models, kwargs, name):
    _, model = demo_models["ski-a"]
    args = {
        "load_n": PAPER_LOAD_N,
        "load_position_m": PAPER_POSITION_M,
        "effective_modulus_pa": PAPER_E_EFF,
    }
    args.update(kwargs)
    with pytest.raises(InputError, match=name):
        solve_flexible(model, **args)


def test_bad_model_input():
    ski = ClassicSkiDesign().build(spacing_m=4e-3)
    with pytest.raises(InputError, match="model"):
        solve_flexible(ski, PAPER_LOAD_N, PAPER_POSITION_M, PAPER_E_EFF)
    with pytest.raises(InputError, match="ski"):
        prepare_flexible("ski-a", 0.044)
    with pytest.raises(InputError, match="width_m"):
        prepare_flexible(ski, -0.044)
    with pytest.raises(InputError, match="pixel_along_m"):
        prepare_flexible(ski, 0.044, pixel_along_m=0.5)
    with pytest.raises(InputError, match="pixels_across"):
        prepare_flexible(ski, 0.044, pixels_across=0)


def test_same_pixels_as_the_rigid_solve(demo_models):
    rec, model = demo_models["ski-a"]
    rigid = macro.extrude_profile(
        rec.beam.positions_m,
        rec.beam.unloaded_gap_m,
        rec.outline.width_m,
        width_positions_m=rec.outline.positions_m,
    )
    np.testing.assert_array_equal(model.unloaded_map.positions_m, rigid.positions_m)
    np.testing.assert_array_equal(np.isfinite(model.unloaded_map.gap_m), np.isfinite(rigid.gap_m))
    assert model.unloaded_map.pixel_size_m == rigid.pixel_size_m


# --------------------------------------------------------------------------------------------
# 7. the row-level start and row preconditioner across moduli and loads (issue #12)
# --------------------------------------------------------------------------------------------


def _complementarity_violation(model, res, load_n, xf, e_eff):
    """(max |H| on contact, max penetration off it) over the largest elastic displacement,
    with operators independent of the solver's: the 2-D FFT half-space of solvers.elastic and
    the virtual-work beam of this file; δ, θ are the result's."""
    gm = model.unloaded_map
    inside = np.isfinite(gm.gap_m)
    x = gm.positions_m
    dx, dy = gm.pixel_size_m
    p = np.nan_to_num(res.pressure_pa)
    u = NonPeriodicHalfSpace(p.shape, (dx, dy), e_eff, workers=1).displacement(p)
    q, _ = np.linalg.qr(np.stack([np.ones_like(x), x], axis=1))
    proj = np.eye(x.size) - q @ q.T
    flex = proj @ _virtual_work_flexibility(x, model.row_beam.bending_stiffness_nm2) @ proj
    s = (xf - x[0]) / dx
    i0 = int(np.floor(s))
    forces = p.sum(axis=1) * dx * dy
    forces[[i0, i0 + 1]] -= load_n * np.array([1 - (s - i0), s - i0])
    w = flex @ forces
    h = model.row_beam.unloaded_gap_m[:, None] + w[:, None] + u
    h -= res.approach_m + res.tilt_rad * (x - xf)[:, None]
    scale = float(np.abs(u + w[:, None])[inside].max())
    on = p > 0
    return float(np.abs(h[on]).max() / scale), float(max(-h[inside & ~on].min(), 0.0) / scale)


@pytest.mark.parametrize("name", ["ski-a", "ski-b"])
@pytest.mark.parametrize("snow_mpa", [2.0, 20.0, 200.0, 2000.0])
@pytest.mark.parametrize("load_kg", [10.0, 40.0, 90.0])
def test_row_start_gives_the_rigid_start_answer(demo_models, name, snow_mpa, load_kg):
    """The default start (row-level problem) and the previous one (rigid-shape solve of the
    device profile, passed as initial_pressure_pa) take different set sequences to the same
    discrete answer; both satisfy complementarity with independent operators."""
    _, model = demo_models[name]
    e_eff = effective_modulus(snow_mpa * 1e6, 0.7e9, 0.3)
    load_n = load_kg * G_STANDARD
    xf = PAPER_POSITION_M
    res = solve_flexible(model, load_n, xf, e_eff, tol=1e-10)
    assert res.converged, res.message
    assert res.extra["warm_start"] == "row-level problem"
    dev = solve_beam_contact(model.row_beam, load_n, xf, flexibility=model.row_flexibility)
    gm = model.unloaded_map
    inside = np.isfinite(gm.gap_m)
    device_map = macro.GapMap(
        np.where(inside, dev.gap_m[:, None], np.nan), gm.positions_m, gm.pixel_size_m
    )
    rigid = macro.solve_macro(device_map, load_n, xf, e_eff)
    other = solve_flexible(
        model, load_n, xf, e_eff, tol=1e-10, initial_pressure_pa=rigid.pressure_pa
    )
    assert other.converged, other.message
    # pressures to 1e-6 of their peak at tol 1e-10 (as test_warm_start_gives_the_same_answer)
    scale = np.nanmax(other.pressure_pa)
    assert np.nanmax(np.abs(res.pressure_pa - other.pressure_pa)) <= 1e-6 * scale
    np.testing.assert_array_equal(res.pressure_pa > 0, other.pressure_pa > 0)
    on_contact, penetration = _complementarity_violation(model, res, load_n, xf, e_eff)
    # max |H| on contact: the RMS asked is 1e-10, the maximum at most √(contact pixels) times
    # that; measured ≤ 1.2e-10 over this sweep
    assert on_contact <= 1e-9
    # off contact the solver admits H ≥ −0.5 tol (largest displacement) before adding a pixel
    assert penetration <= 1e-10


# --------------------------------------------------------------------------------------------
# 8. compiled kernels and per-model caches (issue #12 benchmark): same answers as the routes
#    they replace
# --------------------------------------------------------------------------------------------


def _narrowed_model() -> FlexibleModel:
    """The small ski on a footprint whose middle rows lose their outer pixels (width 15 mm of
    30 mm there, 3 pixels across): rows of 3 and of 1 pixel."""
    width = np.array([0.03, 0.03, 0.015, 0.015, 0.03, 0.03])
    at = np.array([-0.13, -0.06, -0.04, 0.04, 0.06, 0.13])
    return prepare_flexible(
        _small_ski(), width, width_positions_m=at, pixel_along_m=10e-3, pixels_across=3
    )


def test_row_preconditioner_is_the_galerkin_row_operator_on_a_narrowed_footprint():
    """A_c of the row preconditioner equals Eᵀ A E built densely from Love's influence and B
    (χ_i: the row's pixels of C by their grid column, on a footprint with missing pixels)."""
    model = _narrowed_model()
    gm = model.unloaded_map
    inside = np.isfinite(gm.gap_m)
    counts = inside.sum(axis=1)
    assert set(counts[counts > 0]) == {1, 3}  # the case this test is about
    e_eff = 5e7
    pix = flexible._Pixels(model, inside, 60.0, 0.0, e_eff)
    contact = np.random.default_rng(3).random(pix.idx.size) < 0.6
    cidx = np.flatnonzero(contact)
    prec = flexible._Preconditioner(pix, cidx)
    assert prec.m == np.unique(pix.rows[cidx]).size  # no row grouping at this size
    u = np.triu(prec.factor)
    got = u.T @ u
    # dense: pixels of C at their grid positions
    x = gm.positions_m
    dx, dy = gm.pixel_size_m
    ny = gm.gap_m.shape[1]
    ii, jj = np.divmod(pix.idx[cidx], ny)
    snow = (2 / (np.pi * e_eff)) * love_rectangle_influence(
        x[ii][:, None] - x[ii][None, :], (jj[:, None] - jj[None, :]) * dy, dx / 2, dy / 2
    )
    a_cc = snow + dx * dy * model.compliance_m_per_n[np.ix_(ii, ii)]
    rows = np.unique(ii)
    e = (ii[:, None] == rows[None, :]).astype(float)
    want = e.T @ a_cc @ e
    want = 0.5 * (want + want.T)
    assert np.abs(got - want).max() <= 1e-12 * np.abs(want).max()


def test_dense_reference_on_a_narrowed_footprint():
    model = _narrowed_model()
    p_ref, _, _, (ii, jj) = _dense_reference(model, 60.0, 0.005, 3e7)
    res = solve_flexible(model, 60.0, 0.005, 3e7, tol=1e-11)
    assert res.converged, res.message
    p = res.pressure_pa[ii, jj]
    assert np.abs(p - p_ref).max() <= 1e-6 * p_ref.max()
    np.testing.assert_array_equal(p > 0, p_ref > 0)


def test_lu_solve_matches_lapack():
    rng = np.random.default_rng(11)
    for k in (1, 2, 7, 40):
        a = rng.standard_normal((k, k))
        if k > 1:
            a[0, 0] = 0.0  # a zero leading pivot: needs the row exchange
        b = rng.standard_normal(k)
        want = np.linalg.solve(a, b)
        x = b.copy()
        assert flexible._lu_solve(a.copy(), x)
        assert np.abs(x - want).max() <= 1e-10 * np.abs(want).max()
    singular = np.ones((3, 3))
    assert not flexible._lu_solve(singular, np.ones(3))


@pytest.mark.parametrize(("name", "snow_mpa"), [("ski-a", 200.0), ("ski-b", 2.0)])
def test_row_problem_compiled_and_lapack_routes_agree(demo_models, monkeypatch, name, snow_mpa):
    """The compiled row-level PDAS (one LU per set) and the Python route with
    ``_kkt_solve``'s Cholesky route (forced by a tiny _MAX_DENSE) visit the same sets; the
    compiled levels solve the final set's KKT system as numpy's LU does."""
    _, model = demo_models[name]
    e_eff = effective_modulus(snow_mpa * 1e6, 0.7e9, 0.3)
    inside = np.isfinite(model.unloaded_map.gap_m)
    pix = flexible._Pixels(model, inside, PAPER_LOAD_N, PAPER_POSITION_M, e_eff)
    row_in = model.footprint_rows
    n = model.row_pixels
    mx, h = n * pix.xr[row_in], n * pix.h0_rows[row_in]
    act = np.zeros(n.size, dtype=bool)
    for side in (mx <= 0, mx > 0):
        act[np.flatnonzero(side)[np.argmin(h[side] / n[side])]] = True
    op = (model.row_snow_unit, model.row_beam_nn, e_eff, pix.area, 2)
    n2, mx2, h2, act2 = (flexible._block_sum(v, 2) for v in (n, mx, h, act.astype(float)))
    compiled = flexible._row_pdas(op, n2, mx2, h2, pix.total, act2 > 0)
    with monkeypatch.context() as mp:
        mp.setattr(flexible, "_MAX_DENSE", 3)
        python = flexible._row_pdas(op, n2, mx2, h2, pix.total, act2 > 0)
    assert compiled is not None and python is not None
    np.testing.assert_array_equal(compiled[1], python[1])
    assert compiled[2] == python[2]
    idx = np.flatnonzero(compiled[1])
    c = np.stack([n2[idx], mx2[idx]])
    kkt = np.block([[flexible._group_block(*op, idx), -c.T], [c, np.zeros((2, 2))]])
    want = np.linalg.solve(kkt, np.concatenate([-h2[idx], [pix.total, 0.0]]))[: idx.size]
    scale = np.abs(want).max()
    if idx.size + 2 <= flexible._MAX_DENSE:  # the final set was solved compiled
        assert np.abs(compiled[0][idx] - want).max() <= 1e-10 * scale
    # the Cholesky route of large sets is less accurate (augmented system): measured 1.4e-5
    # (ski-a, 200 MPa) and 4.8e-6 (ski-b, 2 MPa) of the largest level against numpy's LU
    assert np.abs(python[0][idx] - want).max() <= 1e-4 * scale


def test_model_caches_give_the_answers_of_a_fresh_model(demo_models):
    """Window transforms kept on the model (filled by earlier solves at other moduli, loads
    and positions) give bit-identical answers to a model that has never solved."""
    rec, used = demo_models["ski-b"]
    for mpa, kg, mm in ((2.0, 90.0, -300.0), (2000.0, 10.0, 100.0), (200.0, 40.0, -160.0)):
        solve_flexible(used, kg * G_STANDARD, mm / 1e3, effective_modulus(mpa * 1e6, 0.7e9, 0.3))
    assert used.window_couplings  # filled
    fresh = prepare_flexible(
        rec.beam, rec.outline.width_m, width_positions_m=rec.outline.positions_m
    )
    assert not fresh.window_couplings
    for mpa, kg, mm in ((20.0, 60.0, -200.0), (200.0, 40.0, -160.0)):
        e_eff = effective_modulus(mpa * 1e6, 0.7e9, 0.3)
        a = solve_flexible(used, kg * G_STANDARD, mm / 1e3, e_eff)
        b = solve_flexible(fresh, kg * G_STANDARD, mm / 1e3, e_eff)
        np.testing.assert_array_equal(a.pressure_pa, b.pressure_pa)
        assert a.iterations == b.iterations
        assert a.apparent_contact_area_m2 == b.apparent_contact_area_m2


def test_a_model_like_another_shares_its_snow_parts_and_answers_the_same(demo_models):
    """``prepare_flexible(..., like=)``: a beam of the same outline and grid (a stiffer, less
    cambered ski-b) takes the other model's snow parts (the same objects) and answers bit for
    bit as the model prepared on its own; a model of another footprint is not used."""
    rec, nominal = demo_models["ski-b"]
    beam = BeamSki(
        rec.beam.positions_m, 1.3 * rec.beam.bending_stiffness_nm2, 0.8 * rec.beam.unloaded_gap_m
    )
    kw = {"width_positions_m": rec.outline.positions_m}
    alone = prepare_flexible(beam, rec.outline.width_m, **kw)
    solve_flexible(nominal, 40 * G_STANDARD, -0.16, PAPER_E_EFF)  # fill the shared cache
    shared = prepare_flexible(beam, rec.outline.width_m, like=nominal, **kw)
    assert shared.snow_kernel_rows is nominal.snow_kernel_rows
    assert shared.row_snow_unit is nominal.row_snow_unit
    assert shared.window_couplings is nominal.window_couplings
    for name in ("snow_kernel_rows", "row_snow_unit", "block_snow_unit", "block_beam_nn"):
        np.testing.assert_array_equal(getattr(shared, name), getattr(alone, name))
    for mpa, kg, mm in ((20.0, 60.0, -200.0), (200.0, 40.0, -160.0), (2000.0, 80.0, 50.0)):
        e_eff = effective_modulus(mpa * 1e6, 0.7e9, 0.3)
        a = solve_flexible(shared, kg * G_STANDARD, mm / 1e3, e_eff)
        b = solve_flexible(alone, kg * G_STANDARD, mm / 1e3, e_eff)
        np.testing.assert_array_equal(a.pressure_pa, b.pressure_pa)
        assert a.apparent_contact_area_m2 == b.apparent_contact_area_m2
    # another footprint (a narrower ski; another grid): computed afresh, not taken
    narrow = prepare_flexible(beam, 0.9 * rec.outline.width_m, like=nominal, **kw)
    assert narrow.snow_kernel_rows is not nominal.snow_kernel_rows
    assert narrow.window_couplings is not nominal.window_couplings
    fine = prepare_flexible(beam, rec.outline.width_m, pixel_along_m=2e-3, like=nominal, **kw)
    assert fine.snow_kernel_rows.shape != nominal.snow_kernel_rows.shape
    with pytest.raises(InputError, match="like must be a FlexibleModel"):
        prepare_flexible(beam, rec.outline.width_m, like="ski-b", **kw)


def test_window_cache_is_bounded():
    model = prepare_flexible(_small_ski(), 0.03, pixel_along_m=2e-3, pixels_across=2)
    for n in range(2, 2 + flexible._WINDOW_CACHE + 5):
        flexible._window_coupling(model, n)
    assert len(model.window_couplings) == flexible._WINDOW_CACHE
    assert 2 not in model.window_couplings  # the oldest went first
