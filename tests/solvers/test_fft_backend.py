"""FFT backends of the periodic half-space: pyFFTW (bound plans, float32 pairs) against scipy."""

import numpy as np
import pytest
from skisnow.solvers.elastic import FFTBackend, PeriodicHalfSpace, pyfftw_available, resolve_backend
from skisnow.solvers.errors import InputError
from skisnow.solvers.micro import solve_micro
from skisnow.solvers.texture import self_affine_surface

needs_pyfftw = pytest.mark.skipif(not pyfftw_available(), reason="pyFFTW not installed")

SHAPES = [(64, 64), (48, 30), (33, 17)]


def _kernel(shape: tuple[int, int]) -> np.ndarray:
    hs = PeriodicHalfSpace(shape, 1e-6, 4e8, backend="scipy")
    return hs.compliance


@needs_pyfftw
@pytest.mark.parametrize("shape", SHAPES)
def test_pyfftw_convolve_matches_scipy_for_workspace_and_foreign_arrays(shape):
    rng = np.random.default_rng(3)
    kernel = _kernel(shape)
    src = rng.normal(size=shape)
    ref = FFTBackend(shape, backend="scipy").convolve(kernel, src)
    fft = FFTBackend(shape, backend="pyfftw", workers=2)
    a, b = fft.workspace(2)
    a[...] = src
    bound = fft.convolve(kernel, a, b)  # plans bound to the workspace arrays
    assert bound is b
    scale = np.abs(ref).max()
    np.testing.assert_allclose(bound, ref, rtol=0, atol=1e-12 * scale)
    # the same call again reuses the plan and gives the same numbers
    np.testing.assert_array_equal(fft.convolve(kernel, a, b), bound)
    # foreign arrays go through internal buffers; out=None returns a fresh array
    np.testing.assert_allclose(fft.convolve(kernel, src), ref, rtol=0, atol=1e-12 * scale)
    out = np.empty(shape)
    fft.convolve(kernel, src, out)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12 * scale)
    assert np.array_equal(src, a)  # the input is not destroyed


@pytest.mark.parametrize("backend", ["scipy", "auto"])
@pytest.mark.parametrize("shape", SHAPES)
def test_single_precision_pair_is_float32_accurate(shape, backend):
    rng = np.random.default_rng(5)
    kernel = _kernel(shape)
    src = rng.normal(size=shape)
    ref = FFTBackend(shape, backend="scipy").convolve(kernel, src)
    fft = FFTBackend(shape, backend=backend)
    a, b = fft.workspace(2, np.float32)
    a[...] = src
    fft.convolve(kernel, a, b)
    assert b.dtype == np.float32
    err = np.abs(b - ref).max() / np.abs(ref).max()
    assert 0 < err < 1e-5  # float32 rounding: present, and ~1e-7 of the scale


@needs_pyfftw
def test_bound_plans_refuse_arrays_the_backend_does_not_own():
    fft = FFTBackend((16, 16), backend="pyfftw")
    a = fft.workspace(1, np.float32)[0]
    with pytest.raises(InputError):
        fft.bound_plans(a, np.zeros((16, 16), dtype=np.float32))
    with pytest.raises(InputError):
        fft.bound_plans(a, a)
    with pytest.raises(InputError):
        fft.bound_plans(a, fft.workspace(1)[0])  # float32 into float64


@needs_pyfftw
def test_foreign_arrays_do_not_touch_the_workspace():
    shape = (32, 32)
    kernel = _kernel(shape)
    fft = FFTBackend(shape, backend="pyfftw")
    work = fft.workspace(2)
    for w in work:
        w[...] = 7.0
    src = np.random.default_rng(1).normal(size=shape).astype(np.float32)
    ref = FFTBackend(shape, backend="scipy").convolve(kernel, src.astype(float))
    res = fft.convolve(kernel, src)
    np.testing.assert_allclose(res, ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    assert all(np.all(w == 7.0) for w in work)


def test_backend_names():
    assert resolve_backend("scipy") == "scipy"
    assert resolve_backend("auto") in ("scipy", "pyfftw")
    with pytest.raises(InputError):
        resolve_backend("numpy")


@needs_pyfftw
@pytest.mark.parametrize("pressure_over_modulus", [1e-4, 3e-3])
def test_micro_solve_is_the_same_on_both_backends(pressure_over_modulus):
    e_eff = 4e8
    h = self_affine_surface(
        (128, 128), 1e-6, hurst=0.8, rms_height_m=1e-6, rng=np.random.default_rng(11)
    )
    res = {
        b: solve_micro(h, 1e-6, pressure_over_modulus * e_eff, e_eff, tol=1e-8, backend=b)
        for b in ("scipy", "pyfftw")
    }
    a, b = res["scipy"], res["pyfftw"]
    assert a.converged and b.converged
    # both are converged to 1e-8; the contact sets may differ by a boundary pixel or two
    assert abs(a.real_contact_area_fraction - b.real_contact_area_fraction) <= 2 / h.size
    assert b.mean_gap_m == pytest.approx(a.mean_gap_m, rel=1e-6)
    scale = a.pressure_pa.max()
    assert np.abs(a.pressure_pa - b.pressure_pa).max() < 1e-4 * scale


def test_coarsened_halfspace_is_cached_and_consistent():
    hs = PeriodicHalfSpace((32, 16), (1e-6, 2e-6), 4e8, backend="scipy")
    c = hs.coarsened()
    assert c is hs.coarsened()
    assert c.shape == (16, 8)
    assert c.pixel_size_m == (2e-6, 4e-6)
    assert c.effective_modulus_pa == hs.effective_modulus_pa
    with pytest.raises(InputError):
        PeriodicHalfSpace((15, 16), 1e-6, 4e8).coarsened()
