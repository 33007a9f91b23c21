"""The 90 % error band (issue #12 point 4): its kernels against closed forms, its place in the
answer, and its calibration on held-out camber cases of the demo skis."""

from __future__ import annotations

import functools
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from skisnow.app import service
from skisnow.app.presets import PRESETS
from skisnow.app.service import band, band_sampling
from skisnow.app.service.band_calibration import beam_scale_at, loaded_cases
from skisnow.app.storage.skis import read_ski
from skisnow.app.storage.tables import read_table
from skisnow.solvers.band import (
    combine,
    end_pixel_share,
    model_error_sigma,
    position_error_sigma,
    profile_perturbations,
    table_interpolation_error,
    unit_perturbations,
)
from skisnow.solvers.beam import solve_beam_contact
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.errors import InputError
from skisnow.solvers.macro import extrude_profile, solve_macro
from skisnow.solvers.multiscale import multiscale

ROOT = Path(__file__).resolve().parents[2]
TABLES = ROOT / "tables"


# ----------------------------------------------------------------------------- kernels


def test_model_error_sigma_removes_noise_in_quadrature():
    assert model_error_sigma(5e-6, 3e-6) == pytest.approx(4e-6)
    assert model_error_sigma(2e-6, 3e-6) == 0.0
    assert model_error_sigma(2e-6, 3e-6, floor_m=1e-6) == pytest.approx(1e-6)
    with pytest.raises(InputError):
        model_error_sigma(-1.0, 0.0)


def test_perturbations_have_the_asked_spread_and_correlation():
    x = np.linspace(-1.0, 1.0, 801)
    sigma, ell = 2e-6, 0.05
    d = profile_perturbations(x, sigma, ell, 2000, seed=3)
    assert d.shape == (2000, x.size)
    np.testing.assert_allclose(d[:1000], -d[1000:])  # antithetic pairs
    inner = slice(100, 700)
    assert np.std(d[:, inner]) == pytest.approx(sigma, rel=0.05)
    lag = 20  # 50 mm at 2.5 mm spacing: exp(-1/2)
    c = np.mean(d[:, 300] * d[:, 300 + lag]) / np.mean(d[:, 300] ** 2)
    assert c == pytest.approx(math.exp(-0.5), abs=0.05)
    again = profile_perturbations(x, sigma, ell, 2000, seed=3)
    np.testing.assert_array_equal(d, again)  # explicit seed: the same band every time
    varying = profile_perturbations(x, np.where(x < 0, 1e-6, 3e-6), ell, 2000, seed=4)
    assert np.std(varying[:, 100]) == pytest.approx(1e-6, rel=0.08)
    assert np.std(varying[:, 700]) == pytest.approx(3e-6, rel=0.08)
    with pytest.raises(InputError):
        profile_perturbations(x, sigma, ell, 3, seed=0)


def test_unit_fields_times_sigma_are_the_perturbations_and_are_kept_per_grid():
    """The service keeps the unit fields per profile grid; × σ they are the perturbations of
    profile_perturbations bit for bit, so the band does not depend on what was cached."""
    from skisnow.app.service import band, band_sampling

    x = np.linspace(-0.9, 1.0, 2001)
    sigma = np.where(x < 0, 1e-6, 2.5e-6)
    expected = profile_perturbations(x, sigma, band.PROFILE_CORRELATION_M, 8, seed=12)
    assert np.array_equal(
        unit_perturbations(x, band.PROFILE_CORRELATION_M, 8, 12) * sigma, expected
    )
    first = band_sampling._unit_fields(x, 8, 12)
    assert band_sampling._unit_fields(x.copy(), 8, 12) is first  # same grid, another array: kept
    assert np.array_equal(first * sigma, expected)
    assert not np.array_equal(band_sampling._unit_fields(x, 8, 13), first)  # the seed is in the key
    with pytest.raises(InputError):
        band_sampling._nonnegative(-1e-6, x)


def test_table_interpolation_error_is_zero_for_a_power_law_and_positive_for_a_bend():
    r = np.logspace(-6, -2, 24)
    np.testing.assert_allclose(table_interpolation_error(r, 3.0 * r**0.7), 0.0, atol=1e-12)
    bent = r**0.7 * np.exp(0.3 * np.sin(3 * np.log(r)))
    e = table_interpolation_error(r, bent)
    assert np.all(e[1:-1] > 0) and np.max(e) < 0.05


def test_combine_is_a_quadrature_sum_ignoring_missing():
    out = combine({"a": {"x": 0.03, "y": float("nan")}, "b": {"x": 0.04, "y": 0.01}})
    assert out == {"x": pytest.approx(0.05), "y": pytest.approx(0.01)}


def test_position_error_sigma_recovers_a_model_error_that_varies_along_the_ski():
    rng = np.random.default_rng(5)
    x = np.linspace(-1, 1, 401)
    truth = np.where(np.abs(x) > 0.6, 2e-6, 0.5e-6)
    noise = 3e-6
    res = truth * rng.standard_normal((300, x.size)) + noise * rng.standard_normal((300, x.size))
    res[:, 190:210] = np.nan  # points outside the contact band do not count
    s = position_error_sigma(x, res, noise, window_m=0.1)
    assert np.median(s[np.abs(x) > 0.75]) == pytest.approx(2e-6, rel=0.2)
    assert np.median(s[np.abs(x) < 0.4]) < 1e-6
    assert np.all(np.isfinite(s))


# ----------------------------------------------------------------------------- the answer


@pytest.fixture(scope="module")
def shipped():
    return service.load_catalogue(TABLES)


PAPER = service.ContactInputs("ski-a", "grind-1", 40, -160, 200, 0.5, ski_model="rigid")


def test_every_answer_carries_a_band_with_intervals_around_it(shipped):
    ans = service.contact(shipped, PAPER)
    b = ans["band"]
    assert b["level"] == 0.9
    assert set(b["relative_half_width"]) == set(band.QUANTITIES)
    assert {"camber_model", "macro_grid", "table_interpolation"} <= set(b["components"])
    for (section, key), q in zip(band.ANSWER_KEYS.values(), band.ANSWER_KEYS, strict=True):
        lo, hi = b["intervals"][key]
        v = ans[section][key]
        w = b["relative_half_width"][q]
        assert lo < v < hi
        # symmetric in log: v (1 − w) … v / (1 − w)
        assert lo == pytest.approx(v * (1 - w), rel=1e-3)
        assert hi == pytest.approx(v / (1 - w), rel=1e-3)
        # each source adds: the total is at least the largest component
        comp = max(c.get(q) or 0.0 for c in b["components"].values())
        assert w >= comp * (1 - 1e-3)
    # the mean apparent pressure F / A: the area's band inverted, the same band in log
    p, w_a = ans["apparent"]["mean_pressure_kpa"], b["relative_half_width"]["apparent_contact_area"]
    lo, hi = b["intervals"]["mean_pressure_kpa"]
    a_lo, a_hi = b["intervals"]["contact_area_cm2"]
    a = ans["apparent"]["contact_area_cm2"]
    assert lo == pytest.approx(p * a / a_hi, rel=1e-3) and hi == pytest.approx(
        p * a / a_lo, rel=1e-3
    )
    assert lo == pytest.approx(p * (1 - w_a), rel=1e-3)
    for z in ans["apparent"]["zones"]:  # zone loads share the load: value × (1 ± w)
        lo, hi = z["load_band_90_n"]
        assert lo < z["load_n"] < hi
        assert hi - z["load_n"] == pytest.approx(z["load_n"] - lo, rel=1e-3, abs=1e-6)
    lo = ans["distributions"]["pressure_band_low_kpa"]
    hi = ans["distributions"]["pressure_band_high_kpa"]
    p = ans["distributions"]["pressure_kpa"]
    assert len(lo) == len(p) == len(hi)
    assert all(a <= c + 1e-9 and c <= b_ + 1e-9 for a, c, b_ in zip(lo, p, hi, strict=True))
    assert b["camber_model"]["perturbed_solves"] == band.PROFILE_SAMPLES
    assert b["not_covered"]  # honest about what it leaves out
    # the same request gets the same band (explicit seed)
    assert service.contact(shipped, PAPER)["band"] == b
    assert "max_rel_error" not in ans["provenance"]["preset"]


def test_band_follows_the_preset_grid(shipped):
    """Coarser grids get wider grid parts: the apparent area's from the answer's own end-pixel
    share on its grid, the real-area-type quantities' from the preset's measured width."""
    ans = {p: service.contact(shipped, replace(PAPER, preset=p)) for p in ("fast", "fine")}
    fast, fine = ans["fast"]["band"], ans["fine"]["band"]
    for q in ("apparent_contact_area", "total_reciprocal_separation"):
        assert fast["components"]["macro_grid"][q] > fine["components"]["macro_grid"][q]
    for p, a in ans.items():
        grid = a["band"]["components"]["macro_grid"]
        assert grid["total_reciprocal_separation"] == pytest.approx(
            band.GRID_BAND_FACTOR["total_reciprocal_separation"]
            * PRESETS[p].grid_band["total_reciprocal_separation"],
            rel=1e-3,
        )
        lengths = [z["length_mm"] * 1e-3 for z in a["apparent"]["zones"]]
        share = end_pixel_share(lengths, PRESETS[p].pixel_along_m)
        k = a["band"]["macro_grid_factor"]["apparent_contact_area"]  # the rigid factor
        assert grid["apparent_contact_area"] == pytest.approx(
            k * band.K_END_PIXELS * share, rel=1e-3
        )


def test_end_pixel_share_counts_two_end_pixels_per_zone():
    assert end_pixel_share([0.1, 0.3], 0.004) == pytest.approx(4 * 0.004 / 0.4)
    assert end_pixel_share([0.002], 0.004) == 2.0  # a zone below one pixel: both ends in it
    assert math.isnan(end_pixel_share([], 0.004))
    # halving the pixel halves the share (the apparent area's grid error is first order)
    assert end_pixel_share([0.2], 0.002) == pytest.approx(0.5 * end_pixel_share([0.2], 0.004))
    with pytest.raises(InputError):
        end_pixel_share([0.1], 0.0)
    with pytest.raises(InputError):
        end_pixel_share([-0.1], 0.004)


def test_flexible_answers_carry_the_identified_beams_uncertainty(shipped):
    """An answer of the bending ski from an identified beam (the demo skis) is solved again
    with plausible beams drawn from the identification's covariance: a camber part, the same
    band for the same request, the grid part's minimum separation from its coarse nominal.
    A design beam is the truth (no camber part); an identification without a stored
    covariance leaves the beam's uncertainty out and says so."""
    req = replace(PAPER, ski_model="flexible", snow_modulus_mpa=20)
    ans = service.contact(shipped, req)
    b = ans["band"]
    assert ans["provenance"]["ski_model"]["used"] == "flexible"
    assert "camber_model" in b["components"]
    assert "identified beam" in b["camber_model"]["source"]
    assert "plausible beams" in b["camber_model"]["source"]
    assert b["camber_model"]["perturbed_solves"] == band.BEAM_SAMPLES
    # the draws' factor is the calibrated one at this answer's snow modulus
    e_eff = ans["inputs"]["effective_modulus_mpa"] * 1e6
    cases = loaded_cases(shipped.skis["ski-a"].record)
    assert b["camber_model"]["beam_deviation_scale"] == pytest.approx(beam_scale_at(e_eff, cases))
    assert not any("identified beam" in n for n in b["not_covered"])
    for q in band.QUANTITIES:
        if b["relative_half_width"][q] is None:  # here the minimum separation (a short zone)
            assert all(q not in parts for parts in b["components"].values()), q
            continue
        w = b["components"]["camber_model"][q]
        assert w is not None and 0 < w < 0.5, q
    assert b["relative_half_width"]["apparent_contact_area"] is not None
    assert service.contact(shipped, req)["band"] == b  # seeded draws: the same band
    # the per-answer grid estimate: the minimum separation from the coarse nominal (rigid
    # answers alike), not the preset's constant; at 70 kg, −80 mm every zone resolves it
    resolved = service.contact(shipped, replace(req, load_kg=70, load_position_mm=-80))
    assert resolved["band"]["relative_half_width"]["min_average_separation"] is not None
    grid = resolved["band"]["components"]["macro_grid"]["min_average_separation"]
    assert grid != pytest.approx(PRESETS["default"].grid_band["min_average_separation"])
    assert grid >= band.MIN_SEPARATION_FLOOR * (1 - 1e-3)
    ski = shipped.skis["ski-a"]
    design_only = replace(ski, record=replace(ski.record, identified=None, cache={}))
    cat = replace(shipped, skis={**shipped.skis, "ski-a": design_only})
    ans = service.contact(cat, replace(PAPER, ski_model="flexible"))
    assert "camber_model" not in ans["band"]["components"]
    assert "design beam" in ans["band"]["camber_model"]["source"]
    assert ans["band"]["camber_model"]["perturbed_solves"] == 0
    ident = {k: v for k, v in ski.record.identified.items() if k != "parameter_covariance"}
    no_cov = replace(ski, record=replace(ski.record, identified=ident, cache={}))
    cat = replace(shipped, skis={**shipped.skis, "ski-a": no_cov})
    ans = service.contact(cat, replace(PAPER, ski_model="flexible"))
    assert "camber_model" not in ans["band"]["components"]
    assert any("identified beam" in n for n in ans["band"]["not_covered"])


def test_beam_draws_are_antithetic_scaled_and_kept_per_ski():
    """The beams of a bending-ski band: pairs (d, −d) of parameter deviations, × the scale
    (× 0 is the identified beam itself), seeded; their models prepared once per record."""
    from skisnow.app.storage.skis import identification_for_sampling
    from skisnow.solvers.identify import draw_beam_deviations, sample_beams

    rec = read_ski(TABLES / "skis" / "ski-b.h5")
    ident = identification_for_sampling(rec.identified)
    log_ei = np.log(ident.beam.bending_stiffness_nm2)
    one = sample_beams(ident, 4, 7, antithetic=True)
    two = sample_beams(ident, 4, 7, antithetic=True, scale=2.0)
    d1 = np.array([np.log(b.bending_stiffness_nm2) - log_ei for b in one])
    d2 = np.array([np.log(b.bending_stiffness_nm2) - log_ei for b in two])
    assert np.max(np.abs(d1)) > 1e-3
    # log EI = −log(Σ φ_m exp(γ_m)): odd in Δγ to first order, so pairs cancel to second order
    np.testing.assert_allclose(d1[:2] + d1[2:], 0.0, atol=20 * np.max(np.abs(d1)) ** 2)
    # twice the scale, twice the deviation, up to the same second-order term (of order d²)
    np.testing.assert_allclose(d2, 2 * d1, rtol=0.05, atol=2 * np.max(np.abs(d1)) ** 2)
    zero = sample_beams(ident, 2, 7, antithetic=True, scale=0.0)
    np.testing.assert_allclose(zero[0].bending_stiffness_nm2, ident.beam.bending_stiffness_nm2)
    with pytest.raises(InputError):
        sample_beams(ident, 3, 7, antithetic=True)
    with pytest.raises(InputError):
        sample_beams(ident, 2, 7, scale=-1.0)
    pre = PRESETS["default"]
    first = band.beam_models(rec, pre, samples=4, seed=3, scale=2.0)
    assert band.beam_models(rec, pre, samples=4, seed=3, scale=2.0) is first
    assert len(first[1]) == 4
    other = band.beam_models(rec, pre, samples=4, seed=4, scale=2.0)
    assert not np.array_equal(
        other[1][0].unloaded_map.gap_m, first[1][0].unloaded_map.gap_m, equal_nan=True
    )
    assert first[0].unloaded_map.pixel_size_m[0] == pytest.approx(band_sampling.coarse_grid(pre)[0])
    # another scale (the factor moves with the snow modulus): the nominal model and the unit
    # draws are the cached ones, only the drawn beams are prepared again, and they are the
    # models a record without any cache builds, bit for bit
    third = band.beam_models(rec, pre, samples=4, seed=3, scale=3.1)
    assert third[0] is first[0]
    assert rec.cache["band_beam_draws"][1][(4, 3)].deviations is not None
    fresh = band.beam_models(replace(rec, cache={}), pre, samples=4, seed=3, scale=3.1)
    assert fresh[0] is not third[0]
    for a, b in zip(third[1], fresh[1], strict=True):
        np.testing.assert_array_equal(a.ski.bending_stiffness_nm2, b.ski.bending_stiffness_nm2)
        np.testing.assert_array_equal(a.compliance_m_per_n, b.compliance_m_per_n)
    # the unit draws scaled are sample_beams' beams at that scale, bit for bit
    draws = draw_beam_deviations(ident, 4, 7, antithetic=True)
    for a, b in zip(draws.beams(2.0), two, strict=True):
        np.testing.assert_array_equal(a.bending_stiffness_nm2, b.bending_stiffness_nm2)
        np.testing.assert_array_equal(a.unloaded_gap_m, b.unloaded_gap_m)


def test_unit_draws_scaled_are_the_draws_at_that_scale():
    """draw_beam_deviations(...).beams(scale): per draw, the parameter deviation of one set of
    standard normals (antithetic: the first half mirrored) times the scale, written out here
    from sample_beams' definition for both covariances it draws from (the forward fit's joint
    one, and log-compliance with the camber's sensitivity and scatter), bit for bit."""
    from scipy.interpolate import BSpline
    from skisnow.app.storage.skis import identification_for_sampling
    from skisnow.solvers.beam_fit import camber_on_flat, hats
    from skisnow.solvers.identify import _covariance_root, draw_beam_deviations

    ident = identification_for_sampling(read_ski(TABLES / "skis" / "ski-b.h5").identified)
    x = ident.beam.positions_m
    phi = hats(x, ident.knots_m)

    def normals(n, seed):
        gen = np.random.default_rng(seed)
        half = [gen.standard_normal(n) for _ in range(2)]
        return half + [-z for z in half]

    joint = draw_beam_deviations(ident, 4, 9, antithetic=True).beams(2.5)
    basis = BSpline.design_matrix(x, ident.camber_knots_m, 3).toarray()
    root = _covariance_root(ident.parameter_covariance)
    nc = ident.camber_coefficients.size
    for b, z in zip(joint, normals(root.shape[1], 9), strict=True):
        d = 2.5 * (root @ z)
        gamma = ident.log_compliance + d[nc:]
        np.testing.assert_array_equal(b.bending_stiffness_nm2, 1.0 / (phi @ np.exp(gamma)))
        c = camber_on_flat(x, basis @ (ident.camber_coefficients + d[:nc]))
        np.testing.assert_array_equal(b.unloaded_gap_m, c)
    # an identification without the forward fit's covariance (its camber sensitivity and
    # scatter, not stored with the demo file, set to plausible values)
    rng = np.random.default_rng(3)
    older = replace(
        ident,
        parameter_covariance=None,
        camber_sensitivity=1e-5 * rng.standard_normal(ident.camber_sensitivity.shape),
        camber_sd_m=np.full(x.size, 0.5e-6),
    )
    split = draw_beam_deviations(older, 4, 9, antithetic=True).beams(2.5)
    m = ident.knots_m.size
    chol = np.linalg.cholesky(ident.log_compliance_covariance + 1e-15 * np.eye(m))
    for b, z in zip(split, normals(m + x.size, 9), strict=True):
        dg = 2.5 * (chol @ z[:m])
        c = ident.beam.unloaded_gap_m - older.camber_sensitivity @ dg
        c = c + 2.5 * older.camber_sd_m * z[m:]
        gamma = ident.log_compliance + dg
        np.testing.assert_array_equal(b.bending_stiffness_nm2, 1.0 / (phi @ np.exp(gamma)))
        np.testing.assert_array_equal(b.unloaded_gap_m, camber_on_flat(x, c))
    with pytest.raises(InputError):
        draw_beam_deviations(ident, 4, 9).beams(-1.0)


def test_wide_band_warns_and_a_short_zone_has_no_min_separation_band(shipped):
    ans = service.contact(
        shipped,
        service.ContactInputs(
            "ski-a", "grind-1", 13, -25, 500, 0.5, preset="fast", ski_model="rigid"
        ),
    )
    codes = {w["code"] for w in ans["warnings"]}
    assert "wide_error_band" in codes
    assert ans["band"]["relative_half_width"]["min_average_separation"] is None
    assert ans["band"]["intervals"]["min_average_separation_um"] is None
    assert any("minimum average separation" in t for t in ans["band"]["not_covered"])


def _peak_and_edge(gap_m, x, pixel_m):
    """The macro solve of a 1-D profile (44 mm wide, 200 N at −20 mm, 20 MPa snow): its
    largest row pressure [Pa] and :func:`band.edge_peak_m` of each zone."""
    gm = extrude_profile(x, gap_m, 0.044, pixel_along_m=pixel_m, pixels_across=8)
    m = solve_macro(gm, 200.0, -0.02, effective_modulus(20e6, 0.7e9, 0.3))
    assert len(m.zones) == 1
    return np.nanmax(m.pressure_line_pa), band.edge_peak_m(
        m.positions_m, m.pressure_line_pa, m.zones[0]
    )


def test_a_zone_peaking_at_its_edge_has_a_pressure_that_does_not_converge():
    """The rule behind the edge-peak reason: a profile with a corner (a gentle slope meeting a
    steep rise, like the start of a tip's rise) concentrates the pressure at the zone's edge,
    and the peak grows without limit as the grid is refined (≥ 10 % per halving here: the
    minimum separation, which follows it, has no grid-converged value); a smooth profile peaks
    inside and converges. :func:`band.edge_peak_m` tells the two apart on 4, 2 and 1 mm pixels
    (on 1 mm the contact climbs a few pixels up the steep side: the rule's distance in mm)."""
    x = np.linspace(-0.5, 0.5, 100_001)
    smooth = x**2 / (2 * 20.0)  # radius 20 m
    corner = np.where(x < 0, -0.002 * x, 0.02 * x)  # slopes 2 and 20 µm/mm meeting at 0
    peaks = {}
    for name, g in (("smooth", smooth), ("corner", corner)):
        peaks[name] = []
        for pixel_m in (0.004, 0.002, 0.001):
            peak, at = _peak_and_edge(g, x, pixel_m)
            peaks[name].append(peak)
            if name == "smooth":
                assert at is None
            else:
                assert at is not None and abs(at) < band.MIN_SEPARATION_EDGE_M, (pixel_m, at)
    assert np.all(np.abs(np.diff(peaks["smooth"])) < 0.01 * peaks["smooth"][0])
    assert np.all(np.diff(peaks["corner"]) / peaks["corner"][:-1] > 0.1)


def test_a_zone_peaking_at_its_edge_has_no_min_separation_band(shipped):
    """ski-b at 80 kg, −100 mm on 20 MPa snow: its tail zone's pressure peaks in its end row
    (the tail's rise begins there), and its minimum separation falls 2.93 → 2.80 → 2.75 → 2.69 µm
    from 4 to 0.5 mm pixels: the answer promises no band for it and says why, per zone too."""
    ans = service.contact(
        shipped, service.ContactInputs("ski-b", "grind-1", 80, -100, 20, 0.5, ski_model="rigid")
    )
    assert ans["band"]["relative_half_width"]["min_average_separation"] is None
    assert any("peak pressure at its edge" in t for t in ans["band"]["not_covered"])
    why = [z["unresolved"] for z in ans["apparent"]["zones"]]
    assert any(w and "peaks at its edge" in w for w in why)
    assert why[1] is None  # the long middle zone's minimum is grid-converged
    # no part of a band that is not given is listed (the page showed a ±6 % grid part for it)
    parts = ans["band"]["components"]
    assert parts["macro_grid"] and all("min_average_separation" not in w for w in parts.values())


def test_an_edge_peak_on_the_fine_grid_is_found_a_few_pixels_inside_its_zone(shipped):
    """On the `fine` preset (1 mm) ski-b's tail and tip zones (80 kg, −100 mm, 20 MPa) peak 5
    and 2 mm inside their ends, more than 3 rows: the rule's distance in mm finds them, while a
    smooth answer's zones (ski-a 40 kg at −160 mm, 200 MPa) peak 21–51 mm inside and stay
    resolved."""
    cornered = service.contact(
        shipped,
        service.ContactInputs(
            "ski-b", "grind-1", 80, -100, 20, 0.5, ski_model="rigid", preset="fine"
        ),
    )
    assert cornered["band"]["relative_half_width"]["min_average_separation"] is None
    why = [z["unresolved"] for z in cornered["apparent"]["zones"]]
    assert why[0] and "peaks at its edge" in why[0] and why[1] is None
    assert why[2] and "peaks at its edge" in why[2]
    smooth = service.contact(
        shipped,
        service.ContactInputs(
            "ski-a", "grind-1", 40, -160, 200, 0.5, ski_model="rigid", preset="fine"
        ),
    )
    assert all(z["unresolved"] is None for z in smooth["apparent"]["zones"])
    assert smooth["band"]["relative_half_width"]["min_average_separation"] is not None


@pytest.mark.xfail(
    strict=True,
    reason="PRESET-GRID-BAND-STALE: the end-to-end stage of docs/bench/accuracy.json, rerun on "
    "2026-11-26 for the first time since 2026-11-23 (before the identified beam became the demo "
    "skis' profile model), measures 90th percentiles the presets' grid_band no longer matches "
    "(fast apparent area 0.183 vs 0.108, min. separation 0.109 vs 0.068; default reciprocal "
    "separation 0.016 vs 0.018; fine apparent area 0.014 vs 0.008, from one short tip contact, "
    "ski-a 20 kg at -250 mm). Setting them to the new p90 drops the held-out coverage of the "
    "default band for the reciprocal separation to 75 % (test_band_covers_held_out_cases_of_the_"
    "demo_skis needs 80 %): recalibrate grid_band together with GRID_BAND_FACTOR "
    "(scripts/band_calibration_study.py)",
)
def test_grid_band_of_the_presets_covers_the_accuracy_benchmark():
    """The presets' grid widths are the 90th percentile of the measured errors (not tuned)."""
    import json

    data = json.loads((ROOT / "docs" / "bench" / "accuracy.json").read_text())["end_to_end"]
    names = {s["preset"]: s["name"] for s in data["settings"] if s.get("preset")}
    for preset in ("fast", "default", "fine"):
        for q, w in PRESETS[preset].grid_band.items():
            errs = [abs(c["settings"][names[preset]]["rel_error"][q]) for c in data["cases"]]
            p90 = float(np.percentile(errs, 90))
            assert p90 <= w <= p90 + 0.002, (preset, q, p90, w)


# ----------------------------------------------------------------------------- calibration

CAL_MODULI_MPA = (20.0, 100.0, 500.0)
CAL_CASES_PER_SKI = 8


#: the truth's grid: the reference of ``skisnow bench accuracy`` (0.5 mm × 64 across). The
#: fine preset (1 mm × 16) is not converged enough to judge the default grid: its own error has
#: the same sign and about half the size (real area +0.45 % where the default is +0.73 %), so
#: against it the RMS error of the default answers is 0.84 % instead of 1.24 %.
TRUTH_GRID = (0.5e-3, 64)


def _calibration_rows() -> list[dict]:
    """Held-out cases (the camber network's test split) of both demo skis at three snow moduli:
    the answer (served profile, default preset) with its band, against the truth (the ski's
    own beam, no device noise, on the benchmark's reference grid)."""
    table = read_table(TABLES / "grind-1.h5")
    pre = PRESETS["default"]
    fine = replace(pre, pixel_along_m=TRUTH_GRID[0], pixels_across=TRUTH_GRID[1])
    rows = []
    for name in ("ski-a", "ski-b"):
        rec = read_ski(TABLES / "skis" / f"{name}.h5")
        f_all = np.asarray(rec.network["split_test_loads_n"])
        x_all = np.asarray(rec.network["split_test_load_positions_m"])
        pick = np.random.default_rng(0).choice(f_all.size, CAL_CASES_PER_SKI, replace=False)
        ski = service.Ski(name, TABLES / "skis" / f"{name}.h5", "", rec)
        for i in pick:
            f, xf = float(f_all[i]), float(x_all[i])
            for e_mpa in CAL_MODULI_MPA:
                e = effective_modulus(e_mpa * 1e6, 700e6, 0.3)

                def solve(x, g, p, f=f, xf=xf, e=e, rec=rec):
                    gm = extrude_profile(
                        x,
                        g,
                        rec.outline.width_m,
                        width_positions_m=rec.outline.positions_m,
                        pixel_along_m=p.pixel_along_m,
                        pixels_across=p.pixels_across,
                    )
                    m = solve_macro(gm, f, xf, e)
                    return gm, m, multiscale(m, table, 0.5, e)

                x, g = service.loaded_profile(ski, f, xf)
                gm, m, ms = solve(x, g, pre)
                b = band.answer_band(
                    record=rec,
                    positions_m=x,
                    gap_m=g,
                    preset=pre,
                    macro=m,
                    ms=ms,
                    table=table,
                    porosity=0.5,
                    e_eff=e,
                    ski_model_used="rigid",
                    beam_is_design=False,
                    min_separation_unresolved=band.min_separation_unresolved(gm, m, ms),
                )
                truth = solve_beam_contact(rec.beam, f, xf)
                _, _, mst = solve(truth.positions_m, truth.gap_m, fine)
                got, want = band_sampling._quantities(m, ms), band_sampling._quantities(None, mst)
                for q in band.QUANTITIES:
                    if math.isfinite(b.widths[q]):
                        rows.append(
                            {
                                "q": q,
                                "err": got[q] / want[q] - 1,
                                "below": b.widths[q],
                                "above": b.width_above(q),
                            }
                        )
    return rows


def test_inside_interval_is_the_served_interval():
    """band.inside_interval (the studies' vectorised test) agrees with interval_90's ends, and
    reach_over_side is the factor on both half-widths that just holds the truth."""
    for err, below, above in (
        (0.1, 0.05, 0.2),
        (-0.1, 0.3, 0.05),
        (0.02, 0.03, 0.0),
        (-0.5, 0.1, 1.2),
        (0.0, 0.0, 0.0),
    ):
        lo, hi = band.interval_90(1.0 + err, below, above)
        truth = 1.0
        want = lo <= truth and (hi is None or truth <= hi)
        assert bool(band.inside_interval(err, below, above)) == want, (err, below, above)
        k = float(band.reach_over_side(err, below, above))
        if 0 < k < math.inf:
            assert bool(band.inside_interval(err, k * below * 1.0001, k * above * 1.0001))
            assert not bool(band.inside_interval(err, k * below * 0.999, k * above * 0.999))


@functools.cache
def _calibration() -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(inside the served band, mean of the two half-widths, |error| ..., quantity) per row."""
    rows = _calibration_rows()
    err = np.array([r["err"] for r in rows])
    below = np.array([r["below"] for r in rows])
    above = np.array([r["above"] for r in rows])
    inside = band.inside_interval(err, below, above)
    return inside, 0.5 * (below + above), np.abs(err), [r["q"] for r in rows]


@pytest.mark.slow
def test_band_covers_held_out_cases_of_the_demo_skis():
    """≥ 85 % of the truths inside the band, ≥ 80 % per quantity (measured with the identified
    beams as profile model: 93.9 % inside, 89.6 % for the reciprocal separation)."""
    inside, _, _, qs = _calibration()
    assert np.mean(inside) >= 0.85, np.mean(inside)
    for q in band.QUANTITIES:
        sel = np.array([x == q for x in qs])
        assert sel.sum() >= 10, q  # enough cases kept per quantity
        assert np.mean(inside[sel]) >= 0.8, (q, np.mean(inside[sel]))


@pytest.mark.slow
def test_band_is_not_uselessly_wide():
    """Mean half-width ≤ 2× the RMS actual error (measured: 1.87×). The band's factors were
    calibrated on other cases (scripts/band_calibration_study.py, set ``calib``: other loads,
    moduli and ski designs), so this checks them on cases they were not fitted to."""
    _, width, err, _ = _calibration()
    assert width.mean() <= 2 * np.sqrt(np.mean(err**2)), width.mean() / np.sqrt(np.mean(err**2))


def test_not_covered_says_where_the_pixel_size_estimate_is(small_table):
    """A table on several pixel sizes stores its own estimate (the answer reports it beside the
    band); one on one pixel size stores none, and the band's list says which."""
    from skisnow.app.service.band import pixel_size_not_covered
    from skisnow.app.storage.common import tables_dir
    from skisnow.app.storage.tables import read_table

    shipped = read_table(tables_dir() / "grind-2.h5")
    assert shipped.real_contact_area_fraction_error is not None
    assert "provenance.table.pixel_error_estimate" in pixel_size_not_covered(shipped)
    assert small_table.real_contact_area_fraction_error is None
    assert "stores no estimate" in pixel_size_not_covered(small_table)


def test_intervals_of_non_negative_quantities_stop_at_zero():
    """A band wider than the value (a flat-base zone load, ±120 %) ends at 0, not below: areas,
    pressures, separations and zone loads are never negative. A zone load's band is value ×
    (1 ± w); the metrics' and the apparent area's are symmetric in log, value × (1 − w) …
    value ÷ (1 − w), with no upper end from w = 1 on."""
    assert band._interval(10.0, 0.25) == [7.5, 12.5]
    assert band._interval(0.19, 2.2) == [0.0, pytest.approx(0.608)]
    assert band.interval_90(10.0, 0.25) == [7.5, pytest.approx(40.0 / 3.0, rel=1e-5)]
    assert band.interval_90(10.0, 0.0) == [10.0, 10.0]
    assert band.interval_90(0.19, 2.2) == [0.0, None]
    assert band.interval_90(0.19, 1.0) == [0.0, None]
    # an underestimate by u is inside from w = u on, as an overestimate by u / (1 − u) is
    lo, hi = band.interval_90(60.0, 0.4)
    assert hi == pytest.approx(100.0) and lo == pytest.approx(36.0)
    # a band wider below than above (the apparent area's grid part, a bias): each end its own
    assert band.interval_90(10.0, 0.25, 0.5) == [7.5, pytest.approx(20.0)]
    assert band.interval_90(10.0, 1.2, 0.1) == [0.0, pytest.approx(100 / 9, rel=1e-5)]
    assert band.interval_90(10.0, 0.3, 1.0) == [7.0, None]


def test_one_sided_part_adds_a_bias_below_and_keeps_a_share_above():
    """A bias adds to the other errors (linearly) on its side and not at all on the other; a
    share of 1 is the quadrature band, unchanged."""
    from skisnow.solvers.band import one_sided_part

    w = math.hypot(0.03, 0.04)  # rest 0.03, grid part 0.04
    assert one_sided_part(w, 0.04, 1.0) == (pytest.approx(w), pytest.approx(w))
    assert one_sided_part(w, 0.04, 0.0) == (pytest.approx(0.07), pytest.approx(0.03))
    below, above = one_sided_part(w, 0.04, 0.5)
    assert below == pytest.approx(0.5 * 0.07 + 0.5 * w)
    assert above == pytest.approx(math.hypot(0.03, 0.02))
    # the band only moves: below never shrinks, above never grows, both monotone in the share
    prev = (math.inf, 0.0)
    for s in np.linspace(0, 1, 11):
        b, a = one_sided_part(w, 0.04, float(s))
        assert w - 1e-12 <= b <= prev[0] + 1e-12 and prev[1] - 1e-12 <= a <= w + 1e-12
        prev = (b, a)
    # a part as large as the width: nothing else above
    assert one_sided_part(0.05, 0.05, 0.0) == (pytest.approx(0.05), pytest.approx(0.0))
    assert all(math.isnan(v) for v in one_sided_part(float("nan"), 0.01, 0.0))
    with pytest.raises(InputError):
        one_sided_part(0.05, 0.01, 1.5)
    with pytest.raises(InputError):
        one_sided_part(-0.05, 0.01, 0.5)


def test_one_sided_widths_combine_the_parts_and_move_the_grid_below():
    """The parts in quadrature (missing ones ignored), the grid part below the answer at the
    snow's share: what answer_band serves and the studies rebuild recorded answers with."""
    parts = {"camber_model": 0.03, "macro_grid": 0.04, "ski_model": None}
    soft, hard = (effective_modulus(e * 1e6, 700e6, 0.3) for e in (20.0, 2000.0))
    assert band.one_sided_widths(parts, soft) == (pytest.approx(0.07), pytest.approx(0.03))
    assert band.one_sided_widths(parts, hard) == (pytest.approx(0.05), pytest.approx(0.05))
    assert band.one_sided_widths(parts, hard, share_above=0.0) == (
        pytest.approx(0.07),
        pytest.approx(0.03),
    )
    # no grid part: nothing to move
    assert band.one_sided_widths({"camber_model": 0.03}, soft) == (
        pytest.approx(0.03),
        pytest.approx(0.03),
    )


def test_grid_above_share_is_zero_on_soft_snow_and_one_on_hard():
    from skisnow.app.service.band_calibration import grid_above_share_at

    def at(e_mpa):
        return grid_above_share_at(effective_modulus(e_mpa * 1e6, 700e6, 0.3))

    assert at(5.0) == 0.0 and at(20.0) == pytest.approx(0.0, abs=1e-12)
    assert at(200.0) == pytest.approx(1.0) and at(2000.0) == 1.0
    assert 0.4 < at(63.0) < 0.6  # linear in log E' between the nodes


def test_soft_snow_band_reaches_further_below_than_above(shipped):
    """At 20 MPa the apparent area's grid part is served below the answer only: its interval
    is value × (1 − w) … value ÷ (1 − w_above) with w_above < w, the mean apparent pressure's
    the same sides swapped; the other quantities stay symmetric in log."""
    ans = service.contact(shipped, replace(PAPER, snow_modulus_mpa=20.0))
    b = ans["band"]
    assert b["grid_above_share"] == 0.0
    w = b["relative_half_width"]["apparent_contact_area"]
    wa = b["relative_half_width_above"]["apparent_contact_area"]
    g = b["components"]["macro_grid"]["apparent_contact_area"]
    assert wa < w and g > 0
    # nothing of the grid part above, all of it added below (the rounded parts: 2e-3)
    assert w == pytest.approx(wa + g, rel=2e-3)
    a = ans["apparent"]["contact_area_cm2"]
    lo, hi = b["intervals"]["contact_area_cm2"]
    assert lo == pytest.approx(a * (1 - w), rel=1e-3) and hi == pytest.approx(
        a / (1 - wa), rel=1e-3
    )
    p = ans["apparent"]["mean_pressure_kpa"]
    lo, hi = b["intervals"]["mean_pressure_kpa"]
    assert lo == pytest.approx(p * (1 - wa), rel=1e-3) and hi == pytest.approx(
        p / (1 - w), rel=1e-3
    )
    assert set(b["relative_half_width_above"]) == {"apparent_contact_area"}
    hard = service.contact(shipped, PAPER)["band"]
    assert hard["grid_above_share"] == 1.0
    assert hard["relative_half_width_above"]["apparent_contact_area"] == pytest.approx(
        hard["relative_half_width"]["apparent_contact_area"]
    )


def _with_alternatives(ski, beams):
    """``ski`` (an identified demo ski) with ``beams`` stored as its identification's
    alternative beams, as a ski file written by the job holds them."""
    from skisnow.app.storage.skis import alternatives_to_dict

    ident = {**ski.record.identified, "alternatives": alternatives_to_dict(beams)}
    return replace(ski, record=replace(ski.record, identified=ident, cache={}))


def test_alternative_beams_enter_the_bending_skis_band(shipped):
    """The identification's alternative beams (fits the data do not tell from the served one)
    are solved on the band's coarse grid; their largest deviation from the coarse nominal is
    the component ``beam_alternatives``. Checked against the same answers asked directly with
    each beam as the served one on a preset of that coarse grid, for the bending ski and for a
    rigid answer (the alternatives' loaded profiles). Skis without alternatives, or answering
    with their design beam, do not get the component."""
    from skisnow.app.storage.skis import identified_beam

    ski = shipped.skis["ski-a"]
    served = identified_beam(ski.record.identified)
    stiffer = replace(served, bending_stiffness_nm2=1.25 * served.bending_stiffness_nm2)
    softer = replace(served, bending_stiffness_nm2=0.9 * served.bending_stiffness_nm2)
    alt_ski = _with_alternatives(ski, [softer, stiffer])
    cat = replace(shipped, skis={**shipped.skis, "ski-a": alt_ski})
    req = replace(PAPER, ski_model="flexible", snow_modulus_mpa=20)
    ans = service.contact(cat, req)
    b = ans["band"]
    assert b["camber_model"]["alternative_beams"] == 2
    assert b["camber_model"]["alternative_beams_not_converged"] == 0
    got = b["components"]["beam_alternatives"]["apparent_contact_area"]

    # the same answers asked directly on the coarse grid, each beam served in turn
    dx, ny = band_sampling.coarse_grid(PRESETS["default"])
    coarse = replace(PRESETS["default"], name="coarse-check", pixel_along_m=dx, pixels_across=ny)
    presets = {**PRESETS, "coarse-check": coarse}

    def area(beam) -> float:
        ident = {**ski.record.identified, "bending_stiffness_nm2": beam.bending_stiffness_nm2}
        one = replace(ski, record=replace(ski.record, identified=ident, cache={}), _flexible={})
        c = replace(shipped, skis={**shipped.skis, "ski-a": one})
        a = service.contact(
            c, replace(req, preset="coarse-check"), presets=presets, error_band=False
        )
        return a["apparent"]["contact_area_cm2"]

    a0 = area(served)
    want = max(abs(area(b_) / a0 - 1) for b_ in (softer, stiffer))
    assert want > 0.02  # the stiffer beam moves the soft-snow footprint
    assert got == pytest.approx(want, rel=0.02, abs=2e-3)
    # it widens the apparent area's band in quadrature with the other parts (the grid part,
    # a bias, then moved below the answer at this snow's share)
    from skisnow.solvers.band import one_sided_part

    parts = [w.get("apparent_contact_area") for w in b["components"].values()]
    below, above = one_sided_part(
        math.sqrt(sum(p * p for p in parts if p is not None)),
        b["components"]["macro_grid"]["apparent_contact_area"],
        b["grid_above_share"],
    )
    assert b["relative_half_width"]["apparent_contact_area"] == pytest.approx(below, rel=1e-3)
    assert b["relative_half_width_above"]["apparent_contact_area"] == pytest.approx(above, rel=1e-3)
    # a rigid answer: the alternatives' loaded profiles on the flat, solved rigid
    rig = replace(req, ski_model="rigid", snow_modulus_mpa=200)
    rb = service.contact(cat, rig)["band"]
    got = rb["components"]["beam_alternatives"]["apparent_contact_area"]
    req = rig
    a0 = area(served)
    want = max(abs(area(b_) / a0 - 1) for b_ in (softer, stiffer))
    assert want > 0.005
    assert got == pytest.approx(want, rel=0.05, abs=2e-3)
    # without alternatives (or a design beam): no such component
    bare = {k: v for k, v in ski.record.identified.items() if k != "alternatives"}
    bare_ski = replace(ski, record=replace(ski.record, identified=bare, cache={}))
    none = replace(shipped, skis={**shipped.skis, "ski-a": bare_ski})
    plain = service.contact(none, replace(req, ski_model="flexible"))["band"]
    assert "beam_alternatives" not in plain["components"]
    assert plain["camber_model"]["alternative_beams"] == 0
    assert "beam_alternatives" not in service.contact(none, rig)["band"]["components"]
    design = replace(
        alt_ski,
        record=replace(alt_ski.record, identified={**alt_ski.record.identified, "attrs": {}}),
    )
    cat = replace(shipped, skis={**shipped.skis, "ski-a": design})
    assert "beam_alternatives" not in service.contact(cat, rig)["band"]["components"]


def test_an_identified_beams_answer_states_its_studied_tail(shipped):
    """band.studied_tail: the own-ski studies' share outside and farthest reach for the
    answer's ski model, grid and snow (band_calibration.studied_tail_at), and the apparent
    area's band stretched that far: value × (1 − k w) … value ÷ (1 − k w_above)."""
    from skisnow.app.service.band_calibration import studied_tail_at

    for case in (
        PAPER,
        replace(PAPER, snow_modulus_mpa=20.0),
        replace(PAPER, ski_model="flexible"),
    ):
        ans = service.contact(shipped, case)
        b = ans["band"]
        tail = b["studied_tail"]
        e_eff = effective_modulus(case.snow_modulus_mpa * 1e6, 700e6, 0.3)
        share, k, n = studied_tail_at(
            case.ski_model, e_eff, loaded_cases(shipped.skis["ski-a"].record)
        )
        assert (tail["outside_share"], tail["farthest_over_half_width"], tail["answers"]) == (
            share,
            k,
            n,
        )
        w = b["relative_half_width"]["apparent_contact_area"]
        wa = b["relative_half_width_above"]["apparent_contact_area"]
        a = ans["apparent"]["contact_area_cm2"]
        lo, hi = tail["contact_area_cm2_at_farthest"]
        assert lo == pytest.approx(a * (1 - k * w), rel=1e-3)
        assert hi == pytest.approx(a / (1 - k * wa), rel=1e-3)
        lo90, hi90 = b["intervals"]["contact_area_cm2"]
        assert lo < lo90 < a < hi90 < hi


def test_a_network_served_answer_states_the_networks_studied_tail(shipped):
    """A rigid answer of a ski served by its camber network (the demo ski's identification
    removed) states the tail of the networks' studies (band.studied_tail, of "network"); a
    bending answer of the same ski has none (it bends its design beam, exact)."""
    from skisnow.app.service.band_calibration import network_studied_tail_at

    ski = shipped.skis["ski-b"]
    rec = replace(ski.record, identified=None, beam=None, cache={})
    cat = service.Catalogue(
        tables_dir=shipped.tables_dir,
        skis={"ski-b-net": replace(ski, name="ski-b-net", record=rec)},
        grinds=shipped.grinds,
    )
    for e_mpa in (20.0, 200.0, 2000.0):
        ans = service.contact(cat, replace(PAPER, ski="ski-b-net", snow_modulus_mpa=e_mpa))
        assert ans["provenance"]["ski"]["profile_model"] == "network"
        tail = ans["band"]["studied_tail"]
        share, k, n = network_studied_tail_at(effective_modulus(e_mpa * 1e6, 700e6, 0.3))
        assert tail["of"] == "network" and "network" in tail["source"]
        assert (tail["outside_share"], tail["farthest_over_half_width"], tail["answers"]) == (
            share,
            k,
            n,
        )
        w = ans["band"]["relative_half_width"]["apparent_contact_area"]
        lo, _ = tail["contact_area_cm2_at_farthest"]
        assert lo == pytest.approx(ans["apparent"]["contact_area_cm2"] * (1 - k * w), rel=1e-3)
    assert service.contact(shipped, PAPER)["band"]["studied_tail"]["of"] == "identified_beam"


def test_the_network_tail_is_its_committed_studies_pooled_and_rounded_up():
    """band_calibration.NETWORK_STUDIED_TAIL: per snow modulus, the committed network band
    studies' sets of NETWORK_STUDIED_TAIL_STUDIES at the served factor, pooled (share outside
    weighted by answers, the farthest reach the largest), rounded up by at most one step."""
    import json

    from skisnow.app.service import band_calibration as bc

    for n, e_mpa in enumerate(bc.STUDIED_TAIL_E_SNOW_MPA):
        answers, outside, far = 0, 0.0, 0.0
        for path, sets in bc.NETWORK_STUDIED_TAIL_STUDIES.items():
            summary = json.loads((TABLES.parent / path).read_text("utf-8"))["summary"]
            for st in sets:
                cell = summary[f"{st} scale {bc.NETWORK_SIGMA_SCALE:g} {e_mpa:g} MPa"]
                area = cell["apparent_contact_area"]
                answers += area["n"]
                outside += area["n"] * (1 - area["inside"])
                far = max(far, area["farthest_over_side"])
        share, k = bc.NETWORK_STUDIED_TAIL[n]
        assert answers == bc.NETWORK_STUDIED_TAIL_ANSWERS
        assert 0 <= share - outside / answers < 1e-3 + 1e-12
        assert 0 <= k - far < 1e-2 + 1e-12


def test_studied_tail_takes_the_worse_node_and_grid():
    """Between two moduli or two measurement grids the tail is the worse of the cells around
    (a worst case is not interpolated); a model the studies did not judge gets none."""
    from skisnow.app.service.band_calibration import (
        STUDIED_TAIL,
        STUDIED_TAIL_ANSWERS,
        studied_tail_at,
    )

    def at(model, e_mpa, cases):
        return studied_tail_at(model, effective_modulus(e_mpa * 1e6, 700e6, 0.3), cases)

    rigid = STUDIED_TAIL["rigid"]
    assert at("rigid", 200.0, 45) == (rigid[0][1][0], rigid[0][1][1], STUDIED_TAIL_ANSWERS[0])
    assert at("rigid", 200.0, 117) == (rigid[1][1][0], rigid[1][1][1], STUDIED_TAIL_ANSWERS[1])
    assert at("rigid", 2.0, 425) == (
        rigid[1][0][0],
        rigid[1][0][1],
        STUDIED_TAIL_ANSWERS[1],
    )  # held at the ends
    mid = at("rigid", 630.0, 45)
    assert mid[:2] == (
        max(rigid[0][1][0], rigid[0][2][0]),
        max(rigid[0][1][1], rigid[0][2][1]),
    )
    both = at("flexible", 20.0, 80)
    flex = STUDIED_TAIL["flexible"]
    assert both == (
        max(flex[0][0][0], flex[1][0][0]),
        max(flex[0][0][1], flex[1][0][1]),
        min(STUDIED_TAIL_ANSWERS),
    )
    assert at("flexible", 20.0, None) == both
    assert at("auto", 200.0, 45) is None
