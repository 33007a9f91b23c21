"""Property-based tests of the micro and macro solvers (issue 6 §3, "where methods fail").

Random but seeded inputs (hypothesis with ``derandomize=True``; every surface comes from an
explicit ``numpy.random.Generator`` seed) over the range the service may meet and beyond it:

- micro: self-affine surfaces on odd and even grids of 8–48 pixels, Hurst 0.3–1, loads
  ``P/E'`` over nine decades (1e-9 … 1) and moduli ``E'`` over 1e5 … 1e11 Pa;
- macro: smooth random camber profiles (two contact zones, a single bump, random Fourier
  modes), loads over four decades and moduli over six.

Every solve must either converge with the invariants below, or say that it did not
(``converged=False`` with a message; never NaN/inf, never a hang: iterations are capped).

Invariants (tolerances follow the error source, style.md §10): force balance is imposed, so
to rounding; complementarity holds exactly by construction of the returned fields, and the
*independent* re-evaluation of the gap from the returned pressure (one extra FFT) is held to
the solver tolerance; monotonicity and scale invariance are exact in the pixel counts.

Known failures are listed by name (strict xfail), not hidden by looser tolerances; none at
present (``test_micro_rigid_approach_is_continuous_at_full_contact``, once MICRO-FC-APPROACH,
passes).

The macro solver on the service's own grid (200 examples) runs with the rest: once gated
behind ``SKISNOW_SLOW_TESTS=1`` (which CI never set) as a long run, it takes 12 s (200
examples of 29–82 ms each, measured on a loaded 2-core machine), so it is not gated.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from skisnow.solvers.elastic import NonPeriodicHalfSpace, PeriodicHalfSpace
from skisnow.solvers.macro import extrude_profile, solve_macro
from skisnow.solvers.micro import full_contact_pressure, solve_micro
from skisnow.solvers.texture import self_affine_surface

settings.register_profile(
    "solver-properties",
    derandomize=True,
    deadline=None,
    max_examples=20,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    database=None,
    print_blob=True,
)
PROFILE = settings.get_profile("solver-properties")

PIXEL_M = 1e-6  # texture pixel [m]
RMS_M = 1e-6  # texture Sq [m]
TOL = 1e-6  # micro solver tolerance [-]
MAX_IT = 400  # bounded: a hang is a failure, running out is a flagged result

grid_sizes = st.integers(min_value=8, max_value=48)
hursts = st.floats(min_value=0.3, max_value=1.0)
log_ratios = st.floats(min_value=-9.0, max_value=0.0)  # log10(P/E')
log_moduli = st.floats(min_value=5.0, max_value=11.0)  # log10(E' / Pa)
seeds = st.integers(min_value=0, max_value=2**32 - 1)


def _surface(nx: int, ny: int, hurst: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return self_affine_surface((nx, ny), PIXEL_M, hurst=hurst, rms_height_m=RMS_M, rng=rng)


def _assert_micro_result_sound(res, h: np.ndarray, p_nom: float, e_eff: float) -> None:
    """Invariants every micro result must satisfy, converged or flagged."""
    p, g = res.pressure_pa, res.gap_m
    assert p.shape == h.shape and g.shape == h.shape
    assert np.all(np.isfinite(p)) and np.all(np.isfinite(g)), res.message
    for name in (
        "real_contact_area_fraction",
        "mean_gap_m",
        "mean_reciprocal_gap_per_m",
        "mean_reciprocal_gap_raw_per_m",
        "rigid_approach_m",
        "residual",
    ):
        assert np.isfinite(getattr(res, name)), (name, res.message)
    assert res.message
    if not res.converged:
        assert "not converged" in res.message
        assert res.iterations >= MAX_IT
        return
    # force balance: the mean pressure is imposed [rounding]
    assert abs(p.mean() - p_nom) <= 1e-10 * p_nom, (p.mean(), p_nom)
    # complementarity (exact)
    assert np.all(p >= 0) and np.all(g >= 0)
    assert np.all(g[p > 0] == 0)
    assert np.all(p[g > 0] == 0)
    a_r = np.count_nonzero(p > 0) / p.size
    assert res.real_contact_area_fraction == a_r
    assert 0 < a_r <= 1
    assert res.mean_gap_m == pytest.approx(g.mean(), rel=1e-12, abs=0)
    if res.full_contact:
        assert p_nom >= full_contact_pressure(h, PIXEL_M, e_eff)[0]
        assert np.all(g == 0) and res.mean_gap_m == 0
        u = PeriodicHalfSpace(h.shape, PIXEL_M, e_eff, workers=1).displacement(p)
        closed = h.max() - h + u - res.rigid_approach_m  # h0 + u − δ = 0 everywhere
        assert np.max(np.abs(closed)) <= 1e-9 * np.ptp(h)
        return
    assert res.residual < TOL
    # the returned gap agrees with an independent evaluation g = h0 + u(p) - δ
    hs = PeriodicHalfSpace(h.shape, PIXEL_M, e_eff, workers=1)
    g_check = h.max() - h + hs.displacement(p) - res.rigid_approach_m
    scale = float(np.std(h))
    free = p == 0
    # on the contact set the gap closes to the solver tolerance (RMS) ...
    assert np.sqrt(np.mean(g_check[~free] ** 2)) <= 10 * TOL * scale
    # ... and off it nothing penetrates beyond a few tolerances, and the returned gap is it
    if free.any():
        assert g_check[free].min() >= -10 * TOL * scale * np.sqrt(p.size)
        np.testing.assert_allclose(g[free], np.maximum(g_check[free], 0), rtol=0, atol=1e-9 * scale)


@settings(PROFILE, max_examples=40)
@given(
    nx=grid_sizes,
    ny=grid_sizes,
    hurst=hursts,
    log_ratio=log_ratios,
    log_modulus=log_moduli,
    seed=seeds,
)
def test_micro_solve_is_balanced_complementary_or_flagged(
    nx, ny, hurst, log_ratio, log_modulus, seed
):
    h = _surface(nx, ny, hurst, seed)
    e_eff = 10.0**log_modulus
    p_nom = 10.0**log_ratio * e_eff
    res = solve_micro(h, PIXEL_M, p_nom, e_eff, tol=TOL, max_iterations=MAX_IT, workers=1)
    event("converged" if res.converged else "flagged: not converged")
    event("full contact" if res.full_contact else "partial contact")
    _assert_micro_result_sound(res, h, p_nom, e_eff)


@settings(PROFILE, max_examples=12)
@given(
    n=grid_sizes,
    hurst=hursts,
    log_start=st.floats(min_value=-9.0, max_value=-3.0),
    decades=st.floats(min_value=1.0, max_value=6.0),
    log_modulus=log_moduli,
    seed=seeds,
    warm=st.booleans(),
)
def test_micro_rising_load_closes_the_gap(n, hurst, log_start, decades, log_modulus, seed, warm):
    """a_r non-decreasing and mean gap non-increasing along a rising load sequence, solved
    cold or warm-started from the previous point (as the table build does)."""
    h = _surface(n, n + 1, hurst, seed)  # one odd, one even side
    e_eff = 10.0**log_modulus
    ratios = np.logspace(log_start, log_start + decades, 6)
    previous = None
    a_r, mean_gap = [], []
    for ratio in ratios:
        res = solve_micro(
            h,
            PIXEL_M,
            ratio * e_eff,
            e_eff,
            tol=TOL,
            max_iterations=MAX_IT,
            initial_pressure_pa=previous if warm else None,
            workers=1,
        )
        _assert_micro_result_sound(res, h, ratio * e_eff, e_eff)
        if not res.converged:
            return  # flagged: nothing to compare along the sequence
        previous = res.pressure_pa if res.real_contact_area_fraction < 1 else None
        a_r.append(res.real_contact_area_fraction)
        mean_gap.append(res.mean_gap_m)
    assert np.all(np.diff(a_r) >= 0), a_r
    # mean gap: a stiffer-than-tolerance decrease (tolerance-sized wiggles allowed)
    assert np.all(np.diff(mean_gap) <= 10 * TOL * RMS_M), mean_gap


@settings(PROFILE, max_examples=12)
@given(
    nx=grid_sizes,
    ny=grid_sizes,
    hurst=hursts,
    log_ratio=st.floats(min_value=-7.0, max_value=-1.0),
    log_e1=log_moduli,
    log_e2=log_moduli,
    seed=seeds,
)
def test_micro_depends_on_pressure_over_modulus_only(
    nx, ny, hurst, log_ratio, log_e1, log_e2, seed
):
    """Same P/E' with two moduli: the same contact set and gap field (docs/physics.md §5)."""
    h = _surface(nx, ny, hurst, seed)
    ratio = 10.0**log_ratio
    out = []
    for log_e in (log_e1, log_e2):
        e_eff = 10.0**log_e
        # pressures are compared pointwise to 1e-6 below, so both solves are converged well
        # below that (the float32 preconditioner rounds differently at the two moduli and
        # the two iterations part at the level of the tolerance)
        res = solve_micro(h, PIXEL_M, ratio * e_eff, e_eff, tol=1e-3 * TOL, max_iterations=MAX_IT)
        _assert_micro_result_sound(res, h, ratio * e_eff, e_eff)
        out.append(res)
    a, b = out
    assert a.converged == b.converged
    if not a.converged:
        return
    assert a.full_contact == b.full_contact
    assert a.real_contact_area_fraction == b.real_contact_area_fraction
    np.testing.assert_allclose(a.gap_m, b.gap_m, rtol=0, atol=1e-6 * RMS_M)
    # pointwise to 1e-6, and absolutely to 1e-6 of the pressure scale: points with a tiny
    # pressure carry the solvers' absolute error (~1e-9 of the scale here), which is no
    # longer bit-identical between the moduli now that the preconditioner is float32
    pa = a.pressure_pa / a.effective_modulus_pa
    np.testing.assert_allclose(
        pa,
        b.pressure_pa / b.effective_modulus_pa,
        rtol=1e-6,
        atol=1e-6 * float(pa.max()),
    )


@pytest.mark.parametrize("shape", [(16, 16), (17, 23)])
def test_micro_zero_load_and_far_beyond_full_contact(shape):
    h = _surface(*shape, 0.7, 11)
    zero = solve_micro(h, PIXEL_M, 0.0, 1e8)
    assert zero.converged and zero.real_contact_area_fraction == 0
    np.testing.assert_array_equal(zero.gap_m, h.max() - h)
    huge = solve_micro(h, PIXEL_M, 1e8, 1e8)  # P/E' = 1
    assert huge.full_contact and huge.converged and huge.real_contact_area_fraction == 1
    assert abs(huge.pressure_pa.mean() - 1e8) <= 1e-10 * 1e8


def test_micro_rigid_approach_is_continuous_at_full_contact():
    """Once MICRO-FC-APPROACH: the full-contact branch reported δ = max(h0), not the partial
    branch's zero-mean-displacement δ; fixed, δ is continuous and h0 + u − δ = 0 in full
    contact."""
    h = _surface(32, 32, 0.8, 1)
    e_eff = 1e8
    p_fc, _ = full_contact_pressure(h, PIXEL_M, e_eff)
    below = solve_micro(h, PIXEL_M, 0.999 * p_fc, e_eff, tol=1e-8)
    above = solve_micro(h, PIXEL_M, 1.001 * p_fc, e_eff)
    assert not below.full_contact and above.full_contact
    assert above.rigid_approach_m == pytest.approx(below.rigid_approach_m, abs=0.01 * RMS_M)
    hs = PeriodicHalfSpace(h.shape, PIXEL_M, e_eff, workers=1)
    closed = h.max() - h + hs.displacement(above.pressure_pa) - above.rigid_approach_m
    assert np.max(np.abs(closed)) <= 1e-9 * np.ptp(h)


# --------------------------------------------------------------------------------- macro

SKI_LENGTH_M = 1.9
WIDTH_M = 0.044
MACRO_PIXEL_M = 5e-3  # coarse along the ski to keep the property run short


@st.composite
def camber_profiles(draw):
    """(kind, positions [m], loaded gap H* [m]) of a smooth random camber profile."""
    kind = draw(st.sampled_from(["two-zone", "single-bump", "fourier"]))
    seed = draw(seeds)
    rng = np.random.default_rng(seed)
    x = np.linspace(-SKI_LENGTH_M / 2, SKI_LENGTH_M / 2, 381)
    tip = (np.maximum(x - 0.75, 0) / 0.2) ** 2 * 5e-3  # shovel rise [m]
    tail = (np.maximum(-0.8 - x, 0) / 0.15) ** 2 * 3e-3
    if kind == "two-zone":
        # camber pocket between a rear and a front zone, as a loaded classic ski
        centre = rng.uniform(-0.15, 0.15)
        half = rng.uniform(0.15, 0.4)
        depth = 10.0 ** rng.uniform(-5, -3)  # 10 µm … 1 mm
        pocket = depth * np.clip(1 - ((x - centre) / half) ** 2, 0, None) ** 2
        base = rng.uniform(0, 50e-6) * ((x - centre) / SKI_LENGTH_M) ** 2
        gap = pocket + base + tip + tail
    elif kind == "single-bump":
        # one convex contact zone (a skating ski pressed flat, or a stiff-waxed ski)
        lowest = rng.uniform(-0.4, 0.4)
        curvature = 10.0 ** rng.uniform(-4, -1)  # [1/m]
        gap = 0.5 * curvature * (x - lowest) ** 2 + tip + tail
    else:
        k = np.arange(1, 6)
        amp = rng.normal(size=k.size) * 10.0 ** rng.uniform(-5, -3.5) / k**2
        phase = rng.uniform(0, 2 * np.pi, size=k.size)
        wave = (amp[:, None] * np.sin(np.pi * k[:, None] * x / SKI_LENGTH_M + phase[:, None])).sum(
            0
        )
        gap = wave - wave.min() + tip + tail
    gap = gap - gap.min()
    return kind, x, gap


def _assert_macro_result_sound(res, gmap, load_n, xf, e_eff, tilt):
    inside = np.isfinite(gmap.gap_m)
    p, c = res.pressure_pa, res.clearance_map_m
    assert np.all(np.isfinite(p[inside])) and np.all(np.isfinite(c[inside])), res.message
    assert np.all(np.isnan(p[~inside])) and np.all(np.isnan(c[~inside]))
    for name in ("force_residual", "moment_residual", "approach_m", "tilt_rad", "residual"):
        assert np.isfinite(getattr(res, name)), (name, res.message)
    assert res.message
    if not res.converged:
        assert "not converged" in res.message
        return
    dx, dy = gmap.pixel_size_m
    p0 = np.where(inside, p, 0.0)
    force = p0.sum() * dx * dy
    assert abs(force - load_n) <= 1e-8 * load_n, (force, load_n)
    assert res.force_residual <= 1e-8
    moment = np.sum(p0 * (gmap.positions_m - xf)[:, None]) * dx * dy
    if tilt:
        assert abs(moment) <= 1e-8 * load_n * SKI_LENGTH_M, moment
        assert res.moment_residual <= 1e-8
    else:
        assert res.tilt_rad == 0.0
    # complementarity (exact in the returned fields)
    assert np.all(p0 >= 0) and np.nanmin(c) >= 0
    assert np.all(c[p0 > 0] == 0)
    # apparent area: the sum of the zones' sub-pixel areas (edges between the last contact and
    # the first free pixel centres), so within half a pixel of the pixel count at each end of
    # every run of contact pixels along X
    area = res.apparent_contact_area_m2
    assert area > 0
    assert area == pytest.approx(sum(z.apparent_area_m2 for z in res.zones), rel=1e-12)
    assert all(z.apparent_area_m2 > 0 for z in res.zones)
    touching = (p0 > 0).astype(np.int8)
    runs = int(np.count_nonzero(np.diff(touching, axis=0, prepend=0) == 1))  # runs along X
    assert abs(area - np.count_nonzero(p0 > 0) * dx * dy) <= runs * dx * dy * (1 + 1e-9)
    assert res.mean_apparent_pressure_pa == pytest.approx(load_n / area, rel=1e-12)
    assert sum(z.load_n for z in res.zones) == pytest.approx(load_n, rel=1e-10)
    # independent check of the contact conditions with the library half-space (2-D FFT)
    hs = NonPeriodicHalfSpace(gmap.gap_m.shape, (dx, dy), e_eff, workers=1)
    u = hs.displacement(p0)
    xs = (gmap.positions_m - xf)[:, None]
    raw = np.where(inside, gmap.gap_m, 0.0) + u - res.approach_m - res.tilt_rad * xs
    scale = float(np.max(np.abs(u[inside]))) or 1.0
    on = p0 > 0
    assert np.max(np.abs(raw[on])) <= 1e-4 * scale + 1e-12, np.max(np.abs(raw[on])) / scale
    free = inside & ~on
    if free.any():  # very soft snow can put the whole footprint in contact
        assert raw[free].min() >= -1e-4 * scale - 1e-12
        np.testing.assert_allclose(
            c[free], np.maximum(raw[free], 0), rtol=0, atol=1e-4 * scale + 1e-12
        )


@settings(PROFILE, max_examples=50)
@given(
    profile=camber_profiles(),
    log_load=st.floats(min_value=0.0, max_value=3.5),  # 1 N … 3 kN
    log_modulus=st.floats(min_value=5.0, max_value=11.0),
    xf=st.floats(min_value=-0.35, max_value=0.25),
    tilt=st.booleans(),
)
def test_macro_solve_is_balanced_complementary_or_flagged(profile, log_load, log_modulus, xf, tilt):
    _, x, gap = profile
    gmap = extrude_profile(x, gap, WIDTH_M, pixel_along_m=MACRO_PIXEL_M, pixels_across=4)
    load_n, e_eff = 10.0**log_load, 10.0**log_modulus
    res = solve_macro(gmap, load_n, xf, e_eff, tilt=tilt, max_iterations=1500)
    event("converged" if res.converged else "flagged: not converged")
    event(f"{len(res.zones)} contact zone(s)")
    _assert_macro_result_sound(res, gmap, load_n, xf, e_eff, tilt)


@settings(PROFILE, max_examples=200)
@given(
    profile=camber_profiles(),
    log_load=st.floats(min_value=0.0, max_value=3.5),
    log_modulus=st.floats(min_value=5.0, max_value=11.0),
    xf=st.floats(min_value=-0.35, max_value=0.25),
    tilt=st.booleans(),
)
def test_macro_at_service_resolution(profile, log_load, log_modulus, xf, tilt):
    """The same invariants on the service's grid (4 mm × 8 pixels across), more examples."""
    _, x, gap = profile
    gmap = extrude_profile(x, gap, WIDTH_M)
    load_n, e_eff = 10.0**log_load, 10.0**log_modulus
    res = solve_macro(gmap, load_n, xf, e_eff, tilt=tilt)
    _assert_macro_result_sound(res, gmap, load_n, xf, e_eff, tilt)
