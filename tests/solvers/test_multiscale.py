"""Multi-scale step: metrics and distributions from a macro solve and a texture table."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import make_table
from skisnow.solvers import lookup as L
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.errors import InputError, OutOfRangeError
from skisnow.solvers.macro import extrude_profile, solve_macro
from skisnow.solvers.multiscale import multiscale
from skisnow.solvers.texture import self_affine_surface

PIXEL = 1e-6
E_TABLE = 1e8
FLOOR = 10e-9


def _table(heights: np.ndarray, ratios: np.ndarray) -> L.MicroTable:
    return make_table(heights, ratios, pixel_m=PIXEL, e_eff=E_TABLE, floor=FLOOR)


@pytest.fixture(scope="module")
def table():
    h = self_affine_surface(
        (64, 64), PIXEL, hurst=0.8, rms_height_m=1e-6, rng=np.random.default_rng(4)
    )
    return _table(h, np.geomspace(1e-8, 1e-2, 25))


@pytest.fixture(scope="module")
def macro_case():
    """A two-zone ski-like profile: parabolic camber with flat contact regions."""
    x = np.arange(-0.9, 0.9, 1e-3)
    gap = 0.8e-3 * np.clip(1 - ((x + 0.05) / 0.45) ** 2, 0, None)
    gap += np.where(np.abs(x) > 0.75, 5e-3 * (np.abs(x) - 0.75) ** 2 / 0.15**2, 0.0)
    gmap = extrude_profile(x, gap, 0.044, pixel_along_m=2e-3, pixels_across=4)
    e_eff = effective_modulus(200e6)
    res = solve_macro(gmap, 392.8, -0.16, e_eff)
    assert res.converged, res.message
    return res, e_eff


def test_force_and_apparent_pressure_consistent(table, macro_case):
    macro, e_eff = macro_case
    res = multiscale(macro, table, 0.5, e_eff)
    # F / A_app equals the mean apparent pressure
    assert macro.load_n / res.apparent_contact_area_m2 == pytest.approx(
        res.mean_apparent_pressure_pa, rel=1e-12
    )
    # integrating the width-averaged pressure line gives back the load
    dx, _ = macro.pixel_size_m
    line_force = np.nansum(res.pressure_pa * 0.044) * dx
    assert line_force == pytest.approx(macro.load_n, rel=1e-6)
    # the average real contact pressure uses the full load
    assert res.average_real_contact_pressure_pa == pytest.approx(
        macro.load_n / res.total_real_contact_area_m2
    )
    assert 0 < res.total_real_contact_area_m2 < res.apparent_contact_area_m2
    # the zones' apparent areas (sub-pixel edges) add up to the apparent area
    assert sum(z.apparent_area_m2 for z in res.zones) == pytest.approx(
        res.apparent_contact_area_m2, rel=1e-12
    )


def test_real_area_follows_pressure(table, macro_case):
    macro, e_eff = macro_case
    res = multiscale(macro, table, 0.5, e_eff)
    loaded = res.pressure_pa > 0
    # a_r is zero exactly where the ski does not touch, positive where it does
    assert np.all(res.real_area_fraction[~loaded & np.isfinite(res.real_area_fraction)] == 0)
    assert np.all(res.real_area_fraction[loaded] > 0)
    # per pixel, a_r is a monotone function of P: sorting by P sorts a_r
    p = macro.pressure_pa[macro.pressure_pa > 0]
    ar = res.real_area_fraction_map[macro.pressure_pa > 0]
    assert np.all(np.diff(ar[np.argsort(p)]) >= -1e-15)
    # and along the ski, the real area follows the pressure's shape: strongly correlated
    assert np.corrcoef(res.pressure_pa[loaded], res.real_area_fraction[loaded])[0, 1] > 0.95
    # zone sums equal the total
    assert sum(z.real_area_m2 for z in res.zones) == pytest.approx(
        res.total_real_contact_area_m2, rel=1e-9
    )


def test_separations_and_porosity(table, macro_case):
    macro, e_eff = macro_case
    dense = multiscale(macro, table, 0.0, e_eff)
    porous = multiscale(macro, table, 0.6, e_eff)
    # porosity lowers the nominal pressure: less real area, larger separation
    assert porous.total_real_contact_area_m2 < dense.total_real_contact_area_m2
    assert porous.min_average_separation_m > dense.min_average_separation_m
    # the minimum average separation lies in a contact zone and is below the unloaded mean gap
    assert dense.min_average_separation_m < table.unloaded_mean_gap_m
    # separated region: exact mean separation <h0> + H
    free = (dense.pressure_pa == 0) & np.isfinite(dense.clearance_m)
    np.testing.assert_allclose(
        dense.average_separation_m[free],
        table.unloaded_mean_gap_m + dense.clearance_m[free],
        rtol=1e-9,
    )
    # reciprocal separation: (1 - n) prefactor, positive and finite everywhere on the ski
    assert np.all(np.isfinite(dense.reciprocal_separation_per_m[np.isfinite(dense.clearance_m)]))
    assert dense.total_reciprocal_separation_m > 0


def test_bad_inputs(table, macro_case):
    macro, e_eff = macro_case
    with pytest.raises(InputError):
        multiscale(macro, table, 1.0, e_eff)
    with pytest.raises(InputError):
        multiscale(macro, table, -0.1, e_eff)
    # a table that stops well below the pressures of the ski: refused, not extrapolated
    short = _table(
        self_affine_surface(
            (32, 32), PIXEL, hurst=0.8, rms_height_m=1e-6, rng=np.random.default_rng(1)
        ),
        np.geomspace(1e-8, 1e-6, 5),
    )
    with pytest.raises(OutOfRangeError):
        multiscale(macro, short, 0.0, e_eff)
