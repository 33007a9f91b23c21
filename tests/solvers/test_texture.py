"""Textures: ISO 25178 parameters against closed forms, levelling, linear-grind generator."""

from __future__ import annotations

import numpy as np
import pytest
from skisnow.solvers.errors import InputError
from skisnow.solvers.texture import (
    GRIND_TARGETS,
    GrindParameters,
    iso25178_parameters,
    level_heights,
    linear_grind,
    self_affine_surface,
    target_errors,
)

DX = 1e-6


def sinusoid(shape, amplitude, wavelength_px):
    _n0, n1 = shape
    y = np.arange(n1)
    return np.broadcast_to(amplitude * np.sin(2 * np.pi * y / wavelength_px), shape).copy()


# ----------------------------------------------------------------------------- ISO closed forms


@pytest.mark.parametrize("shape", [(16, 256), (17, 255)])
def test_sinusoid_closed_forms(shape):
    a, lam = 3e-6, 64 if shape[1] == 256 else 51  # integer periods: exact moments
    h = sinusoid(shape, a, lam)
    p = iso25178_parameters(h, DX, periodic=True)
    # moments of a sampled sinusoid over whole periods are exact (up to rounding)
    assert p["Sq_m"] == pytest.approx(a / np.sqrt(2), rel=1e-12)
    assert p["Ssk"] == pytest.approx(0.0, abs=1e-10)
    assert p["Sku"] == pytest.approx(1.5, rel=1e-12)
    # Sa of the sampled sine is a Riemann sum of |sin|: pixel-sized error, O((π/λ)²)
    assert p["Sa_m"] == pytest.approx(2 * a / np.pi, rel=(np.pi / lam) ** 2)
    # central differences: exact discrete derivative amplitude A·sin(kΔ)/Δ
    k = 2 * np.pi / (lam * DX)
    assert p["Sdq"] == pytest.approx(a * np.sin(k * DX) / DX / np.sqrt(2), rel=1e-12)
    assert p["Sdq"] == pytest.approx(a * k / np.sqrt(2), rel=(k * DX) ** 2 / 6 * 1.01)
    # Sdr = mean(sqrt(1 + g²) − 1), g = G cos: close to G²/4 for small slopes
    g = a * np.sin(k * DX) / DX
    assert p["Sdr_percent"] == pytest.approx(100 * g**2 / 4, rel=g**2)


def test_sinusoid_material_ratio_closed_form():
    # material ratio curve of A·sin: z(mr) = A cos(π mr), steepest in the middle, so the
    # least-slope 40 % secant lies at an end ([0, 0.4] or, by symmetry, [0.6, 1]); Sk is minus
    # the slope of the least-squares line through z on that window
    a = 1e-6
    h = sinusoid((4, 20000), a, 200)
    p = iso25178_parameters(h, DX, periodic=True)
    mr = np.linspace(0.0, 0.4, 200001)
    slope = np.polyfit(mr, a * np.cos(np.pi * mr), 1)[0]
    assert p["Sk_m"] == pytest.approx(-slope, rel=1e-3)
    # the peak (or valley) region beyond an end window is a thin sliver
    assert min(p["Smr1_percent"], 100 - p["Smr2_percent"]) < 1


def test_two_level_surface_material_ratio():
    # 70 % at +1 µm, 30 % at −2 µm (a square wave): the core is the flat top level; Sk = 0,
    # no peaks, valleys: triangle of the 30 % valley area below the core
    h = np.ones((8, 1000)) * 1e-6
    h[:, 700:] = -2e-6
    p = iso25178_parameters(h, DX, periodic=True)
    hm = h - h.mean()
    assert p["Sk_m"] == pytest.approx(0.0, abs=1e-15)
    assert p["Spk_m"] == pytest.approx(0.0, abs=1e-18)
    assert p["Smr2_percent"] == pytest.approx(70.0)
    assert p["Svk_m"] == pytest.approx(2 * 3e-6, rel=1e-9)
    assert p["Ssk"] == pytest.approx(np.mean(hm**3) / np.mean(hm**2) ** 1.5, rel=1e-12)


def test_gaussian_surface_moments():
    rng = np.random.default_rng(42)
    h = rng.standard_normal((512, 512)) * 1e-6
    p = iso25178_parameters(h, DX)
    n = h.size
    # sampling standard errors of skewness and kurtosis: sqrt(6/n), sqrt(24/n); 4 sigma
    assert abs(p["Ssk"]) < 4 * np.sqrt(6 / n)
    assert abs(p["Sku"] - 3) < 4 * np.sqrt(24 / n)
    assert p["Sa_m"] / p["Sq_m"] == pytest.approx(np.sqrt(2 / np.pi), rel=0.01)
    # Gaussian material ratio curve z = σ Φ⁻¹(1 − mr): the least-slope window is centred and
    # Sk is minus the slope of the least-squares line through it on [0.3, 0.7]
    from scipy.stats import norm

    mr = np.linspace(0.3, 0.7, 100001)
    sk = -np.polyfit(mr, norm.ppf(1 - mr), 1)[0]
    assert p["Sk_m"] / p["Sq_m"] == pytest.approx(sk, rel=0.01)
    assert p["Spk_m"] / p["Sq_m"] == pytest.approx(p["Svk_m"] / p["Sq_m"], rel=0.05)


def test_against_surfacetopography_oracle():
    st = pytest.importorskip("SurfaceTopography")
    rng = np.random.default_rng(7)
    h = self_affine_surface((128, 96), DX, hurst=0.8, rms_height_m=1e-6, rng=rng)
    t = st.Topography(h, physical_sizes=(128 * DX, 96 * DX), periodic=True)
    p = iso25178_parameters(h, DX, periodic=True)
    assert p["Sq_m"] == pytest.approx(t.rms_height_from_area(), rel=1e-10)
    assert p["Sa_m"] == pytest.approx(np.mean(np.abs(t.heights() - t.heights().mean())), rel=1e-12)
    # oracle slope uses its own (Fourier/forward) derivative: agreement to discretisation
    assert p["Sdq"] == pytest.approx(t.rms_gradient(), rel=0.25)


def test_open_grid_gradients_of_a_plane_are_exact():
    i, j = np.mgrid[0:20, 0:30]
    h = (2e-3 * i + 5e-3 * j) * DX + 1e-15 * np.sin(j)  # tilt + a tiny texture
    p = iso25178_parameters(h, DX, periodic=False)
    assert p["Sdq"] == pytest.approx(np.hypot(2e-3, 5e-3), rel=1e-3)


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        (np.zeros((4, 4)), "flat"),
        (np.ones((1, 10)), "at least 2"),
        (np.array([[0.0, np.nan], [1.0, 2.0]]), "NaN"),
    ],
)
def test_iso_refuses(bad, match):
    with pytest.raises(InputError, match=match):
        iso25178_parameters(bad, DX)


def test_iso_refuses_bad_pixel_size():
    with pytest.raises(InputError, match="pixel_size_m"):
        iso25178_parameters(np.eye(4), -1.0)


# ----------------------------------------------------------------------------- levelling


def test_level_removes_plane_exactly():
    rng = np.random.default_rng(1)
    tex = rng.standard_normal((40, 33)) * 1e-7
    i, j = np.mgrid[0:40, 0:33]
    plane = 3e-6 + 2e-7 * i - 5e-8 * j
    lev_tex, _ = level_heights(tex, DX)
    lev, missing = level_heights(tex + plane, DX)
    assert missing == 0
    np.testing.assert_allclose(lev, lev_tex, atol=1e-18)
    assert abs(lev.mean()) < 1e-20
    # no tilt left: orthogonal to both coordinates
    assert abs(np.sum(lev * (i - i.mean()))) < 1e-16
    assert abs(np.sum(lev * (j - j.mean()))) < 1e-16


def test_level_fills_missing_points():
    rng = np.random.default_rng(2)
    h = self_affine_surface((64, 64), DX, hurst=0.8, rms_height_m=1e-6, rng=rng)
    holes = h.copy()
    holes[10:14, 20:25] = np.nan
    holes[40, :] = np.nan
    lev, missing = level_heights(holes, DX)
    assert missing == pytest.approx((20 + 64) / 64**2)
    assert np.isfinite(lev).all()
    # the filled values are local: within the range of the surface, and close to the truth
    ref, _ = level_heights(h, DX)
    assert np.max(np.abs(lev - ref)) < 0.5 * np.ptp(ref)
    assert np.sqrt(np.mean((lev - ref) ** 2)) < 0.1 * ref.std()


def test_level_refuses_mostly_missing():
    h = np.random.default_rng(3).standard_normal((20, 20))
    h[:, :11] = np.nan
    with pytest.raises(InputError, match="mostly missing"):
        level_heights(h, DX)
    _lev, missing = level_heights(h, DX, max_missing_fraction=0.6)
    assert missing == pytest.approx(0.55)


@pytest.mark.parametrize(
    ("bad", "match"),
    [
        (np.full((5, 5), np.nan), "all NaN"),
        (np.array([[1.0, np.inf], [0.0, 2.0]]), "infinite"),
        (np.array([[1.0, -np.inf], [0.0, 2.0]]), "infinite"),
        (np.ones((1, 7)), "at least 2"),
        (np.ones(7), "2-D"),
        (np.add.outer(np.arange(5.0), np.arange(6.0)), "flat"),
        (np.zeros((5, 6)), "flat"),
    ],
)
def test_level_refuses_degenerate(bad, match):
    with pytest.raises(InputError, match=match):
        level_heights(bad, DX)


def test_level_refuses_bad_arguments():
    with pytest.raises(InputError, match="max_missing_fraction"):
        level_heights(np.eye(3), DX, max_missing_fraction=1.0)
    with pytest.raises(InputError, match="pixel_size_m"):
        level_heights(np.eye(3), float("nan"))


# ----------------------------------------------------------------------------- linear grind

GRIND = GrindParameters(
    pitch_m=100e-6,
    depth_m=5e-6,
    land_fraction=0.3,
    groove_exponent=2.0,
    asymmetry=0.2,
    lip_height_m=0.5e-6,
    lip_width_m=3e-6,
    roughness_rms_m=0.3e-6,
    roughness_long_cutoff_m=30e-6,
    roughness_short_cutoff_m=4e-6,
)


def test_grind_deterministic_for_seed():
    a = linear_grind((32, 200), DX, GRIND, 5)
    b = linear_grind((32, 200), DX, GRIND, np.random.default_rng(5))
    c = linear_grind((32, 200), DX, GRIND, 6)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_grind_is_periodic():
    # periodic: the spectrum has no edge discontinuity, so periodic and open-grid slopes agree
    # in the interior, and the wrap-around step is as small as an interior step
    h = linear_grind((64, 300), DX, GRIND, 1)
    steps1 = np.abs(np.diff(h, axis=1, append=h[:, :1]))
    steps0 = np.abs(np.diff(h, axis=0, append=h[:1, :]))
    assert steps1[:, -1].max() <= steps1[:, :-1].max()
    assert steps0[-1, :].max() <= steps0[:-1, :].max()
    # integer number of grooves: the groove pattern repeats exactly on a doubled grid
    smooth = GrindParameters(
        **{**GRIND.to_dict(), "roughness_rms_m": 0.0, "pitch_jitter": 0.0, "depth_jitter": 0.0}
    )
    g = linear_grind((4, 300), DX, smooth, 1)
    np.testing.assert_allclose(g[:, :100], g[:, 100:200], atol=1e-18)
    assert np.ptp(g, axis=0).max() == 0  # straight grooves along axis 0


def test_grind_groove_depth_and_lands():
    smooth = GrindParameters(
        **{
            **GRIND.to_dict(),
            "roughness_rms_m": 0.0,
            "lip_height_m": 0.0,
            "pitch_jitter": 0.0,
            "depth_jitter": 0.0,
        }
    )
    g = linear_grind((2, 1000), DX, smooth, 1)[0]
    top = g.max()
    assert top - g.min() == pytest.approx(5e-6, rel=1e-3)  # depth (pixel-averaged bottom)
    assert np.mean(np.isclose(g, top, atol=1e-15)) == pytest.approx(0.3, abs=0.02)  # lands


def test_grind_parameters_validate():
    with pytest.raises(InputError, match="land_fraction"):
        GrindParameters(pitch_m=1e-4, depth_m=1e-6, land_fraction=1.2)
    with pytest.raises(InputError, match="pitch_m"):
        GrindParameters(pitch_m=-1e-4, depth_m=1e-6)
    with pytest.raises(InputError, match="depth_m"):
        GrindParameters(pitch_m=1e-4, depth_m=float("nan"))
    with pytest.raises(InputError, match="shape"):
        linear_grind((1, 10), DX, GRIND, 0)


def test_target_errors_units_of_tolerance():
    t = GRIND_TARGETS["grind-1"]
    achieved = dict(t)
    achieved["Sa_m"] = t["Sa_m"] * 1.05  # exactly at the 5 % tolerance
    achieved["Sku"] = t["Sku"] - 0.1  # half the 0.2 absolute tolerance
    e = target_errors(achieved, t)
    assert e["Sa_m"] == pytest.approx(1.0)
    assert e["Sku"] == pytest.approx(-0.5)
    assert e["Sq_m"] == 0
    with pytest.raises(InputError, match="unknown ISO parameter"):
        target_errors(achieved, {"Sz_m": 1.0})


def test_fit_recovers_a_known_grind():
    """Fit targets taken from a grind of the model itself: all within tolerance, quickly."""
    from skisnow.solvers.texture import fit_linear_grind

    shape = (32, 300)
    truth = linear_grind(shape, DX, GRIND, 3)
    targets = {
        k: v
        for k, v in iso25178_parameters(truth, DX, periodic=True).items()
        if k in GRIND_TARGETS["grind-1"]
    }
    start = GrindParameters(**{**GRIND.to_dict(), "depth_m": 4.5e-6, "land_fraction": 0.35})
    fit = fit_linear_grind(
        targets, shape, DX, 3, initial=start, fit_rows=32, max_evaluations=600, polish_evaluations=0
    )
    _params, heights, achieved = fit
    assert heights.shape == shape
    assert fit.converged, fit.message
    assert all(abs(v) <= 1 for v in target_errors(achieved, targets).values())
