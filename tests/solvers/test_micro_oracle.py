"""Micro solver against an independent implementation (ContactMechanics) and against the
small-load proportionality of self-affine surfaces."""

import numpy as np
import pytest
from skisnow.solvers.micro import solve_micro
from skisnow.solvers.texture import self_affine_surface

E_EFF = 4.0e8  # E' [Pa], E* = 200 MPa


@pytest.fixture(scope="module")
def surface():
    rng = np.random.default_rng(5)
    return self_affine_surface((128, 128), 1e-6, hurst=0.8, rms_height_m=1e-6, rng=rng)


@pytest.mark.parametrize("pressure_pa", [1e5, 1e6, 5e6])
def test_against_contactmechanics(surface, pressure_pa):
    pytest.importorskip("ContactMechanics")
    from ContactMechanics.Factory import make_system
    from SurfaceTopography import Topography

    n, dx = surface.shape[0], 1e-6
    topo = Topography(surface, physical_sizes=(n * dx, n * dx), periodic=True)
    system = make_system(substrate="periodic", surface=topo, young=E_EFF / 2)
    ref = system.minimize_proxy(
        external_force=pressure_pa * (n * dx) ** 2, pentol=1e-12, maxiter=10000
    )
    assert ref.success
    ref_fraction = np.mean(ref.jac > 0)
    ref_gap = system.compute_gap(ref.x, ref.offset).mean()
    ours = solve_micro(surface, dx, pressure_pa, E_EFF, tol=1e-8)
    assert ours.converged
    assert ours.real_contact_area_fraction == pytest.approx(ref_fraction, rel=5e-3)
    assert ours.mean_gap_m == pytest.approx(ref_gap, rel=5e-3)


def test_self_affine_small_load_kappa():
    """Persson / Hyun-Robbins: a_r = κ P / (E* ∇h_rms) with κ ≈ 2 at small load."""
    rng = np.random.default_rng(11)
    n, dx = 512, 1e-6
    h = self_affine_surface(
        (n, n),
        dx,
        hurst=0.8,
        rms_height_m=1e-6,
        rng=rng,
        long_cutoff_m=n * dx / 4,
        short_cutoff_m=8 * dx,
    )
    gx = (np.roll(h, -1, 0) - np.roll(h, 1, 0)) / (2 * dx)
    gy = (np.roll(h, -1, 1) - np.roll(h, 1, 1)) / (2 * dx)
    slope_rms = np.sqrt(np.mean(gx**2 + gy**2))
    e_star = E_EFF / 2
    pressure = 0.01 * e_star * slope_rms  # a_r of about 2 %
    res = solve_micro(h, dx, pressure, E_EFF, tol=1e-7)
    assert res.converged
    kappa = res.real_contact_area_fraction * e_star * slope_rms / pressure
    assert 1.5 < kappa < 2.5
