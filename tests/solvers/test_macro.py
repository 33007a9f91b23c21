"""Macro BEM: Hertz, flat punch, force/moment balance, window check, demo-ski calibration."""

import numpy as np
import pytest
from skisnow.app.commands.macro import loaded_profile
from skisnow.app.storage.skis import SHIPPED_SKI_DIR as SKI_DIR
from skisnow.app.storage.skis import read_ski
from skisnow.solvers import reference
from skisnow.solvers.beam import G_STANDARD, solve_beam_contact
from skisnow.solvers.elastic import NonPeriodicHalfSpace, effective_modulus
from skisnow.solvers.errors import InputError
from skisnow.solvers.macro import (
    DEFAULT_PIXEL_ACROSS,
    DEFAULT_PIXEL_ALONG_M,
    GapMap,
    _couple_across,
    _LineOperator,
    _solve_windowed,
    extrude_profile,
    interpolate_sides,
    solve_macro,
)

E_EFF = effective_modulus(200e6, 0.7e9, 0.3)


def _square(n, size):
    dx = size / n
    x = (np.arange(n) + 0.5) * dx - size / 2
    return x, dx


@pytest.mark.parametrize("n", [96, 97])
def test_hertz(n):
    x, dx = _square(n, 0.016)
    radius, load = 0.5, 50.0
    h = (x[:, None] ** 2 + x[None, :] ** 2) / (2 * radius)
    res = solve_macro(GapMap(h, x, (dx, dx)), load, 0.0, E_EFF, tol=1e-9)
    assert res.converged, res.message
    a = reference.hertz_contact_radius(load, radius, E_EFF)
    p0 = reference.hertz_peak_pressure(load, radius, E_EFF)
    assert np.sqrt(res.apparent_contact_area_m2 / np.pi) == pytest.approx(a, rel=0.01)
    assert res.peak_pressure_pa == pytest.approx(p0, rel=0.01)
    assert res.force_residual < 1e-10


@pytest.mark.parametrize("n", [60, 61])
def test_flat_punch_boussinesq(n):
    x, dx = _square(n, 0.012)
    a = 0.005
    r = np.hypot(x[:, None], x[None, :])
    h = np.where(r <= a, 0.0, np.nan)  # footprint = the punch face, flat
    load = 100.0
    res = solve_macro(GapMap(h, x, (dx, dx)), load, 0.0, E_EFF, tol=1e-10)
    assert res.converged, res.message
    area_a = np.sqrt(np.count_nonzero(np.isfinite(h)) * dx * dx / np.pi)
    expected = load / reference.flat_punch_stiffness(area_a, E_EFF)
    assert res.approach_m == pytest.approx(expected, rel=0.02)


@pytest.mark.parametrize("shape", [(40, 1), (37, 4), (33, 8)])
def test_line_operator_is_the_2d_operator(shape):
    """FFT along X + dense coupling across = zero-padded 2-D Love convolution (to rounding)."""
    dx, dy = 4e-3, 5.5e-3
    p = np.random.default_rng(7).random(shape)
    line = _LineOperator(*shape, dx, dy, E_EFF).displacement(p)
    full = NonPeriodicHalfSpace(shape, (dx, dy), E_EFF).displacement(p)
    assert np.max(np.abs(line - full)) < 1e-12 * np.max(np.abs(full))


@pytest.mark.parametrize("shape", [(40, 1), (37, 4), (33, 8), (2, 3)])
def test_line_operator_is_bit_for_bit_the_scipy_fft_convolution(shape):
    """The operator calls SciPy's pocketfft directly (no per-call dispatch); the numbers are
    those of the public scipy.fft.rfft/irfft path, not merely close to them."""
    import scipy.fft

    n = shape[0]
    op = _LineOperator(*shape, 4e-3, 5.5e-3, E_EFF)
    p = np.random.default_rng(8).random(shape)
    ph = scipy.fft.rfft(p, n=2 * n, axis=0)
    uh = ph * op.coupling[:, 0, :] if shape[1] == 1 else _couple_across(op.coupling, ph)
    expected = scipy.fft.irfft(uh, n=2 * n, axis=0)[:n]
    got = op.displacement(p)
    assert got.shape == shape
    assert np.array_equal(got, expected)


def _demo_gap_map(name, dx=DEFAULT_PIXEL_ALONG_M, ny=DEFAULT_PIXEL_ACROSS):
    """The demo ski's true loaded profile (its beam model, the calibration target; the
    network's own accuracy is tested in test_camber.py)."""
    ski = read_ski(SKI_DIR / f"{name}.h5")
    beam = solve_beam_contact(ski.beam, 40 * G_STANDARD, -0.160)
    assert beam.converged, beam.message
    x, gap = beam.positions_m, beam.gap_m
    return extrude_profile(x, gap, 0.044, pixel_along_m=dx, pixels_across=ny)


@pytest.mark.parametrize("tilt", [True, False])
def test_balance(tilt):
    gm = _demo_gap_map("ski-a")
    load, xf = 40 * G_STANDARD, -0.160
    res = solve_macro(gm, load, xf, E_EFF, tilt=tilt)
    assert res.converged, res.message
    p = np.nan_to_num(res.pressure_pa)
    dx, dy = res.pixel_size_m
    assert abs(p.sum() * dx * dy - load) / load < 1e-8
    moment = np.sum(p * (res.positions_m - xf)[:, None]) * dx * dy
    if tilt:
        assert abs(moment) / (load * 1.0) < 1e-8
    else:
        assert res.tilt_rad == 0.0 and abs(moment) / load > 1e-3
    # complementarity and the window check
    assert np.nanmin(res.clearance_map_m) >= 0
    assert np.all(res.clearance_map_m[p > 0] == 0)
    assert sum(z.load_share for z in res.zones) == pytest.approx(1.0, rel=1e-12)


PAPER = {"ski-a": (63.98e-4, 61.40e3), "ski-b": (121.84e-4, 32.24e3)}


@pytest.mark.parametrize("name", ["ski-a", "ski-b"])
def test_demo_skis_meet_papers(name):
    res = solve_macro(_demo_gap_map(name), 40 * G_STANDARD, -0.160, E_EFF)
    area, pressure = PAPER[name]
    assert res.apparent_contact_area_m2 == pytest.approx(area, rel=0.02)
    assert res.mean_apparent_pressure_pa == pytest.approx(pressure, rel=0.02)
    p = np.nan_to_num(res.pressure_pa)
    rear = p[res.positions_m < -0.160].sum() / p.sum()
    assert 0.635 <= rear <= 0.93
    assert len(res.zones) == 2 and res.zones[0].end_m < 0 < res.zones[1].start_m


def test_area_matches_fine_reference():
    """Default grid within 1 % of the 0.5 mm × 16 reference (docs/macro.md); sub-pixel edges."""
    load, xf = 40 * G_STANDARD, -0.160
    coarse = solve_macro(_demo_gap_map("ski-a"), load, xf, E_EFF)
    fine = solve_macro(_demo_gap_map("ski-a", 0.5e-3, 16), load, xf, E_EFF)
    assert coarse.apparent_contact_area_m2 == pytest.approx(fine.apparent_contact_area_m2, rel=0.01)
    for res in (coarse, fine):
        dx = res.pixel_size_m[0]
        assert res.mean_apparent_pressure_pa * res.apparent_contact_area_m2 == pytest.approx(load)
        assert sum(z.apparent_area_m2 for z in res.zones) == pytest.approx(
            res.apparent_contact_area_m2, rel=1e-12
        )
        for z in res.zones:  # sub-pixel edges lie within half a pixel of the pixel edges
            assert abs(z.edge_start_m - z.start_m) <= dx / 2 + 1e-12
            assert abs(z.edge_end_m - z.end_m) <= dx / 2 + 1e-12
    # the zone edges agree across grids to well below the coarse pixel
    for zc, zf in zip(coarse.zones, fine.zones, strict=True):
        assert abs(zc.edge_start_m - zf.edge_start_m) < 0.5 * coarse.pixel_size_m[0]
        assert abs(zc.edge_end_m - zf.edge_end_m) < 0.5 * coarse.pixel_size_m[0]


def test_window_grows_when_margin_too_small():
    """Start from a one-pixel window (δ0 = min H*, θ0 = 0, 0.1 µm): the check must grow it."""
    gm = _demo_gap_map("ski-a")
    load, xf = 40 * G_STANDARD, -0.160
    ref = solve_macro(gm, load, xf, E_EFF)
    h = gm.gap_m
    dx, dy = gm.pixel_size_m
    sol = _solve_windowed(
        h, np.isfinite(h), gm.positions_m, dx, dy, load, xf, E_EFF, True, 1e-8, 3000,
        float(np.nanmin(h)), 0.0, 1e-7, None,
    )  # fmt: skip
    assert sol.converged and sol.margin > 1e-7
    p_ref = np.nan_to_num(ref.pressure_pa)
    assert np.max(np.abs(sol.pressure - p_ref)) < 1e-5 * p_ref.max()


def test_warm_start():
    gm = _demo_gap_map("ski-b")
    load, xf = 40 * G_STANDARD, -0.160
    ref = solve_macro(gm, load, xf, E_EFF)
    warm = solve_macro(gm, load, xf, E_EFF, initial_pressure_pa=ref.pressure_pa)
    assert warm.converged and warm.iterations < ref.iterations
    assert warm.apparent_contact_area_m2 == pytest.approx(ref.apparent_contact_area_m2, rel=1e-6)
    with pytest.raises(InputError, match="initial_pressure_pa"):
        solve_macro(gm, load, xf, E_EFF, initial_pressure_pa=np.zeros((3, 3)))


def test_stiff_tilt_onto_a_second_row():
    """Load beside a sharp bump on a stiff half-space: the tilt must bring a row behind x_F into
    contact (the CG step is shortened when the projection empties one side of x_F)."""
    x = np.linspace(-0.95, 0.95, 381)  # pixel centres at ±2.5 mm, ±7.5 mm, …
    gm = extrude_profile(x, 50.0 * (x - 0.007) ** 2, 0.044, pixel_along_m=5e-3, pixels_across=4)
    for xf in (0.0, 1e-3):
        res = solve_macro(gm, 1.0, xf, 1e9)
        assert res.converged, res.message
        p = np.nan_to_num(res.pressure_pa)
        assert res.force_residual < 1e-10 and res.moment_residual < 1e-10
        rows = res.positions_m[p.sum(axis=1) > 0]
        assert rows.min() < xf < rows.max()


@pytest.mark.parametrize("lift_m", [10e-6, 50e-6])
def test_sides_differ(lift_m):
    """Left edge lifted: partial-width contact; balance holds and every loaded zone has area."""
    ski = read_ski(SKI_DIR / "ski-a.h5")
    load, xf = 40 * G_STANDARD, -0.160
    x, gap = loaded_profile(ski, load, xf)
    res = solve_macro(interpolate_sides(x, gap + lift_m, gap, 0.044), load, xf, E_EFF)
    assert res.converged, res.message
    assert res.force_residual < 1e-10 and res.moment_residual < 1e-10
    assert res.mean_apparent_pressure_pa * res.apparent_contact_area_m2 == pytest.approx(load)
    p = np.nan_to_num(res.pressure_pa)
    assert np.count_nonzero(p[:, 0] > 0) < np.count_nonzero(p[:, -1] > 0)
    for z in res.zones:
        assert z.load_n > 0 and z.apparent_area_m2 > 0


def test_zero_load_and_bad_inputs():
    gm = _demo_gap_map("ski-a", 8e-3, 2)
    res = solve_macro(gm, 0.0, -0.16, E_EFF)
    assert res.apparent_contact_area_m2 == 0 and res.converged
    with pytest.raises(InputError, match="load_n"):
        solve_macro(gm, -1.0, -0.16, E_EFF)
    with pytest.raises(InputError, match="outside the footprint"):
        solve_macro(gm, 100.0, 3.0, E_EFF)
    with pytest.raises(InputError, match="gap_m"):
        GapMap(np.full((4, 2), -1.0), np.arange(4) * 1e-3, (1e-3, 1e-3))


def test_a_nearby_rigid_body_start_gives_the_same_answer():
    """``initial_rigid_body`` skips the coarse line problem; the window check keeps the answer
    the same for a nearby profile (the error band's perturbed solves) and for a far one."""
    x = np.linspace(-0.9, 0.9, 451)
    base = 2e-4 * (x / 0.9) ** 2 + 2e-5 * np.sin(7 * x)
    base -= base.min()
    gm = extrude_profile(x, base, 0.044, pixel_along_m=4e-3, pixels_across=8)
    load, xf, e = 300.0, -0.1, 3e8
    ref = solve_macro(gm, load, xf, e)
    for bump in (1e-6 * np.cos(20 * x), 3e-5 * x):  # nearby, then a tilt that moves the zone
        g2 = extrude_profile(
            x,
            base + bump - min(0.0, float(np.min(base + bump))),
            0.044,
            pixel_along_m=4e-3,
            pixels_across=8,
        )
        plain = solve_macro(g2, load, xf, e)
        near = solve_macro(
            g2,
            load,
            xf,
            e,
            initial_pressure_pa=ref.pressure_pa,
            initial_rigid_body=(ref.approach_m, ref.tilt_rad),
            window_gap_m=ref.window_gap_m,
        )
        assert near.converged and plain.converged
        assert near.apparent_contact_area_m2 == pytest.approx(
            plain.apparent_contact_area_m2, rel=1e-6
        )
        np.testing.assert_allclose(
            np.nan_to_num(near.pressure_pa),
            np.nan_to_num(plain.pressure_pa),
            rtol=0,
            atol=1e-4 * np.nanmax(plain.pressure_pa),
        )
        assert near.approach_m == pytest.approx(plain.approach_m, rel=1e-5, abs=1e-10)
    with pytest.raises(InputError):
        solve_macro(gm, load, xf, e, initial_rigid_body=(float("nan"), 0.0))


def _edge_lengths_python(contact, clearance, x, a, b):
    """The former pure-Python loop of solvers.macro._edge_lengths (the compiled one must give
    the same numbers bit for bit)."""

    def edge(h1, h2, x1, x0):
        if not (np.isfinite(h1) and np.isfinite(h2)) or not h2 > h1 >= 0:
            return 0.5 * (x0 + x1)
        a1, a2 = h1 ** (2.0 / 3.0), h2 ** (2.0 / 3.0)
        e = x1 + (x0 - x1) * a1 / (a2 - a1)
        return float(min(max(e, min(x0, x1)), max(x0, x1)))

    nx, ny = contact.shape
    dx = float(x[1] - x[0])
    rear, front, length = np.full(ny, np.nan), np.full(ny, np.nan), np.zeros(ny)
    for j in range(ny):
        col = contact[a:b, j].astype(np.int8)
        ed = np.flatnonzero(np.diff(np.concatenate([[0], col, [0]])))
        for r0, r1 in zip(ed[::2] + a, ed[1::2] + a - 1, strict=True):
            if r1 == r0:
                e_r, e_f = x[r0] - dx / 2, x[r0] + dx / 2
                length[j] += dx
            else:
                h1 = clearance[r0 - 1, j] if r0 >= 1 else np.nan
                h2 = clearance[r0 - 2, j] if r0 >= 2 else np.nan
                e_r = edge(h1, h2, x[r0] - dx, x[r0])
                h1 = clearance[r1 + 1, j] if r1 + 1 < nx else np.nan
                h2 = clearance[r1 + 2, j] if r1 + 2 < nx else np.nan
                e_f = edge(h1, h2, x[r1] + dx, x[r1])
                length[j] += e_f - e_r
            rear[j] = e_r if np.isnan(rear[j]) else min(rear[j], e_r)
            front[j] = e_f if np.isnan(front[j]) else max(front[j], e_f)
    return rear, front, length


@pytest.mark.parametrize("seed", range(6))
def test_compiled_edge_lengths_are_the_python_loop_bit_for_bit(seed):
    from skisnow.solvers.macro import _edge_lengths

    rng = np.random.default_rng(seed)
    nx, ny = 60, 1 + seed
    x = -0.1 + 4e-3 * (np.arange(nx) + 0.5)
    contact = rng.random((nx, ny)) < 0.3
    contact[:2, 0] = True  # runs at the footprint ends and single pixels
    contact[-1, -1] = True
    clearance = np.where(contact, 0.0, rng.lognormal(-12, 1, (nx, ny)))
    clearance[rng.random((nx, ny)) < 0.05] = np.nan  # outside the footprint
    clearance[5, 0] = clearance[6, 0] = 1e-6  # h2 == h1: fallback to the midpoint
    for a, b in ((0, nx), (3, 41), (10, 11)):
        got = _edge_lengths(contact, clearance, x, a, b)
        expected = _edge_lengths_python(contact, clearance, x, a, b)
        for g, e in zip(got, expected, strict=True):
            assert np.array_equal(g, e, equal_nan=True)


@pytest.mark.parametrize("ny", [2, 5, 8])
def test_coupling_across_the_width_is_the_complex_product_sum(ny):
    """The compiled coupling sums real and imaginary parts apart; the numbers are those of
    the complex sum Σ_k K̂[f, j, k] · P̂[f, k] in k order, bit for bit."""
    rng = np.random.default_rng(ny)
    nf = 9
    coupling = rng.normal(size=(nf, ny, ny))
    ph = rng.normal(size=(nf, ny)) + 1j * rng.normal(size=(nf, ny))
    expected = np.empty_like(ph)
    for f in range(nf):
        for j in range(ny):
            s = 0j
            for k in range(ny):
                s += complex(coupling[f, j, k]) * complex(ph[f, k])
            expected[f, j] = s
    assert np.array_equal(_couple_across(coupling, ph), expected)


def test_profile_extruder_gives_the_maps_of_extrude_profile_and_interpolate_sides():
    from skisnow.solvers.macro import ProfileExtruder

    rng = np.random.default_rng(11)
    x = np.linspace(-0.9, 1.0, 401)
    width_x, width = np.array([-0.9, 0.0, 1.0]), np.array([0.044, 0.047, 0.043])
    ext = ProfileExtruder(x, width, width_positions_m=width_x, pixel_along_m=8e-3, pixels_across=5)
    for _ in range(3):
        g, g2 = rng.uniform(-1e-6, 1e-3, x.size), rng.uniform(0, 1e-3, x.size)
        a = ext(g)
        b = extrude_profile(
            x, g, width, width_positions_m=width_x, pixel_along_m=8e-3, pixels_across=5
        )
        assert np.array_equal(a.gap_m, b.gap_m, equal_nan=True)
        assert np.array_equal(a.positions_m, b.positions_m)
        assert a.pixel_size_m == b.pixel_size_m
        s = ext.sides(g, g2)
        t = interpolate_sides(
            x, g, g2, width, width_positions_m=width_x, pixel_along_m=8e-3, pixels_across=5
        )
        assert np.array_equal(s.gap_m, t.gap_m, equal_nan=True)
    with pytest.raises(InputError, match="equal length"):
        ext(np.zeros(x.size - 1))
    with pytest.raises(InputError, match="finite"):
        ext(np.full(x.size, np.nan))
    with pytest.raises(InputError, match="increasing"):
        ProfileExtruder(x[::-1], 0.044)
