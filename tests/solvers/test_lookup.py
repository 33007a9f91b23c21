"""Lookup of micro-scale tables (solvers/lookup.py): accuracy against direct solves, monotonicity,
exact limits (zero load, full contact) and out-of-range handling."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import make_table
from skisnow.solvers import lookup as L
from skisnow.solvers.errors import InputError, OutOfRangeError
from skisnow.solvers.micro import solve_micro
from skisnow.solvers.texture import self_affine_surface

E_EFF = 1e8  # [Pa]
PIXEL = 1e-6  # [m]
TOL = 1e-6


def _table(heights, ratios, *, tol=TOL, floor=10e-9) -> L.MicroTable:
    return make_table(heights, ratios, pixel_m=PIXEL, e_eff=E_EFF, floor=floor, tol=tol)


@pytest.fixture(scope="module")
def surface_128():
    # roughness resolved by >= 8 pixels, so that a_r(P_n) is not dominated by single pixels
    rng = np.random.default_rng(20230427)
    return self_affine_surface(
        (128, 128), PIXEL, hurst=0.8, rms_height_m=1e-6, rng=rng, short_cutoff_m=8 * PIXEL
    )


@pytest.fixture(scope="module")
def table_128(surface_128):
    # a step of 1.23x between points (the shipped tables: 72 points over 7 decades, 1.25x)
    return _table(surface_128, L.pressure_ratio_grid(3e-3, 6e-2, 15))


@pytest.fixture(scope="module")
def table_full():
    """A small table whose grid reaches full contact."""
    rng = np.random.default_rng(7)
    h = self_affine_surface((32, 32), PIXEL, hurst=0.8, rms_height_m=1e-6, rng=rng)
    return _table(h, L.pressure_ratio_grid(1e-4, 1.0, 10))


def test_midpoints_match_direct_solves(table_128, surface_128):
    """Half-way (in ln r) between table points, the lookup is within 1 % of a direct solve.

    Measured on this surface: a_r within 0.7 %, mean gap within 0.4 % for a_r in [0.1, 0.92];
    the floored reciprocal gap scatters by up to ~5 % (it is carried by the pixels next to
    contact spots, docs/physics.md §5), hence its looser bound.
    """
    r = table_128.pressure_ratio
    mids = np.sqrt(r[:-1] * r[1:])[::2]
    ar = L.real_contact_area_fraction(table_128, mids * E_EFF, E_EFF)
    gap = L.mean_gap_m(table_128, mids * E_EFF, E_EFF)
    rec = L.mean_reciprocal_gap_per_m(table_128, mids * E_EFF, E_EFF)
    checked = 0
    for i, ratio in enumerate(mids):
        res = solve_micro(surface_128, PIXEL, ratio * E_EFF, E_EFF, tol=TOL)
        assert res.converged
        if not 0.1 <= res.real_contact_area_fraction <= 0.92:
            continue
        checked += 1
        assert ar[i] == pytest.approx(res.real_contact_area_fraction, rel=0.01)
        assert gap[i] == pytest.approx(res.mean_gap_m, rel=0.01)
        assert rec[i] == pytest.approx(res.mean_reciprocal_gap_per_m, rel=0.06)
    assert checked >= 5


def test_nodes_are_reproduced(table_128):
    r = table_128.pressure_ratio
    partial = ~table_128.full_contact
    ar = L.real_contact_area_fraction(table_128, r[partial] * 2e8, 2e8)
    np.testing.assert_allclose(ar, table_128.real_contact_area_fraction[partial], rtol=1e-12)
    gap = L.mean_gap_m(table_128, r[partial] * 3e7, 3e7)
    np.testing.assert_allclose(gap, table_128.mean_gap_m[partial], rtol=1e-12)


def test_interpolants_are_monotone(table_128, table_full):
    for table in (table_128, table_full):
        lo = table.pressure_ratio[0]
        ratio = np.geomspace(lo, table.pressure_ratio[-1], 2000)
        ar = L.real_contact_area_fraction(table, ratio, 1.0)
        gap = L.mean_gap_m(table, ratio, 1.0)
        assert np.all(np.diff(ar) >= 0)
        assert np.all(np.diff(gap) <= 0)
        assert np.all((ar > 0) & (ar <= 1))
        assert np.all(gap >= 0)
    clearance = np.geomspace(1e-8, 1e-2, 2000)
    sep = L.separated_reciprocal_gap_per_m(table_128, clearance)
    assert np.all(np.diff(sep) < 0)


def test_separated_curve_matches_direct_mean(table_128, surface_128):
    h0 = surface_128.max() - surface_128
    c = np.sqrt(table_128.clearance_m[:-1] * table_128.clearance_m[1:])[::7]
    direct = np.array([np.mean(1.0 / (h0 + x)) for x in c])
    np.testing.assert_allclose(L.separated_reciprocal_gap_per_m(table_128, c), direct, rtol=2e-3)
    assert L.separated_mean_gap_m(table_128, 2e-6) == pytest.approx(h0.mean() + 2e-6, rel=1e-12)


def test_zero_load_is_exact_unloaded_state(table_128, surface_128):
    h0 = surface_128.max() - surface_128
    assert L.real_contact_area_fraction(table_128, 0.0, E_EFF) == 0.0
    assert L.mean_gap_m(table_128, 0.0, E_EFF) == pytest.approx(h0.mean(), rel=1e-12)
    rec = L.mean_reciprocal_gap_per_m(table_128, 0.0, E_EFF)
    assert rec == pytest.approx(np.mean(1 / np.maximum(h0, 10e-9)), rel=1e-12)


def test_full_contact_is_exact_above_r_fc(table_full):
    assert table_full.full_contact_reached
    fc = table_full.full_contact_pressure_ratio
    ratio = np.array([fc, 1.5 * fc, 10.0, 1e6])
    assert np.all(L.real_contact_area_fraction(table_full, ratio, 1.0) == 1.0)
    assert np.all(L.mean_gap_m(table_full, ratio, 1.0) == 0.0)
    rec = L.mean_reciprocal_gap_per_m(table_full, ratio, 1.0)
    np.testing.assert_allclose(rec, 1 / table_full.gap_floor_m)
    # continuous approach to full contact from below
    just_below = L.real_contact_area_fraction(table_full, fc * (1 - 1e-6), 1.0)
    assert 0.99 < just_below < 1.0


def test_out_of_range_raises_or_flags(table_128):
    lo, hi = table_128.pressure_ratio[0], table_128.pressure_ratio[-1]
    assert not table_128.full_contact_reached
    for ratio in (0.5 * lo, 2 * hi):
        with pytest.raises(OutOfRangeError, match="not extrapolated"):
            L.real_contact_area_fraction(table_128, ratio * E_EFF, E_EFF)
        with pytest.raises(OutOfRangeError):
            L.mean_gap_m(table_128, ratio, 1.0)
    values, flagged = L.mean_gap_m(
        table_128, np.array([0.0, 0.5 * lo, lo, hi, 2 * hi]), 1.0, out_of_range="flag"
    )
    np.testing.assert_array_equal(flagged, [False, True, False, False, True])
    assert np.isnan(values[flagged]).all() and np.isfinite(values[~flagged]).all()
    # table ends are inside, with round-off of P(1 - n)/E' snapped onto them
    assert np.isfinite(L.real_contact_area_fraction(table_128, lo * (1 - 1e-12), 1.0))
    with pytest.raises(OutOfRangeError):
        L.separated_reciprocal_gap_per_m(table_128, 0.0)
    with pytest.raises(OutOfRangeError):
        L.separated_reciprocal_gap_per_m(table_128, [1e-6, 1.0])
    _, f = L.separated_reciprocal_gap_per_m(table_128, [1e-9, 1e-6], out_of_range="flag")
    np.testing.assert_array_equal(f, [True, False])


def test_bad_inputs_raise_input_error(table_128):
    with pytest.raises(InputError, match="nominal_pressure_pa"):
        L.real_contact_area_fraction(table_128, -1.0, E_EFF)
    with pytest.raises(InputError, match="nominal_pressure_pa"):
        L.mean_gap_m(table_128, np.nan, E_EFF)
    with pytest.raises(InputError, match="effective_modulus_pa"):
        L.mean_gap_m(table_128, 1e3, 0.0)
    with pytest.raises(InputError, match="out_of_range"):
        L.mean_gap_m(table_128, 1e3, E_EFF, out_of_range="clip")


def test_nominal_pressure_ratio_applies_porosity():
    assert L.nominal_pressure_ratio(60e3, 0.5, 3e8) == pytest.approx(1e-4)
    np.testing.assert_allclose(
        L.nominal_pressure_ratio(np.array([0.0, 1e5]), 0.0, 1e8), [0.0, 1e-3]
    )
    for bad in (1.0, -0.1):
        with pytest.raises(InputError, match="porosity"):
            L.nominal_pressure_ratio(1e4, bad, 1e8)
    with pytest.raises(InputError, match="pressure_pa"):
        L.nominal_pressure_ratio(-1.0, 0.5, 1e8)


def test_grid_and_chunks_depend_on_grid_only():
    assert L.chunk_bounds(10, 4) == [(0, 4), (4, 8), (8, 10)]
    assert L.chunk_bounds(3, 5) == [(0, 3)]
    r = L.pressure_ratio_grid(1e-8, 1e-2, 40)
    assert r[0] == pytest.approx(1e-8) and r[-1] == pytest.approx(1e-2) and r.size == 40
    with pytest.raises(InputError):
        L.pressure_ratio_grid(1e-2, 1e-8, 40)
    with pytest.raises(InputError):
        L.chunk_bounds(10, 0)
