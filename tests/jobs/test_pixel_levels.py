"""Tables converged in the pixel size (issue #13 point 3): the refined generator is the same
surface, Richardson extrapolation, two-level tables whose stored error estimate covers an
independent finer solve, the shipped tables' estimate, one-level (older) tables still load."""

from __future__ import annotations

import json
import os

import h5py
import numpy as np
import pytest
from skisnow.app.jobs.table_build import build_tables
from skisnow.app.jobs.table_settings import BuildSettings
from skisnow.app.service import pixel_error_estimate
from skisnow.app.storage.common import tables_dir
from skisnow.app.storage.tables import read_table, table_data_sha256
from skisnow.solvers import lookup as L
from skisnow.solvers.errors import InputError
from skisnow.solvers.micro import solve_micro
from skisnow.solvers.texture import GrindParameters, Texture, fourier_upsample, linear_grind

SLOW = os.environ.get("SKISNOW_SLOW_TESTS") == "1"
PIXEL = 1.5e-6  # [m]
#: a strip of the shipped grind-1 generator: one groove across, 64 rows along [-]
SHAPE = (64, 256)
SEED = 7
#: shipped-table points whose error estimate must stay within 3 % (issue #13 point 3 from
#: 1e-3; issue #29 from 1e-4, met with the light-load levels)
AR_RANGE = (1e-4, 0.9)
AR_TOLERANCE = 0.03


def _grind_params(name: str = "grind-1") -> GrindParameters:
    with h5py.File(tables_dir() / "textures" / f"{name}.h5", "r") as f:
        return GrindParameters(**json.loads(f.attrs["generator_parameters_json"]))


# ------------------------------------------------------------------- the same surface refined


def test_fourier_upsample_is_trigonometric_interpolation():
    n = 32
    x = np.arange(n) / n
    h = np.sin(2 * np.pi * 3 * x)[:, None] * np.cos(2 * np.pi * 5 * x)[None, :]
    fine = fourier_upsample(h, 4, shift_px=0.5)
    xf = (np.arange(4 * n) + 0.5) / (4 * n)
    exact = np.sin(2 * np.pi * 3 * xf)[:, None] * np.cos(2 * np.pi * 5 * xf)[None, :]
    np.testing.assert_allclose(fine, exact, atol=1e-12)
    np.testing.assert_allclose(fourier_upsample(h, 2)[::2, ::2], h, atol=1e-14)
    with pytest.raises(InputError, match="Nyquist"):
        fourier_upsample(np.cos(np.pi * np.arange(n))[:, None] * np.ones((1, n)), 2)


@pytest.mark.parametrize("refine", [2, 4])
def test_refined_grind_block_averages_to_the_unrefined_grind(refine):
    params = _grind_params()
    coarse = linear_grind(SHAPE, PIXEL, params, SEED)
    fine = linear_grind(SHAPE, PIXEL, params, SEED, refine=refine)
    assert fine.shape == (SHAPE[0] * refine, SHAPE[1] * refine)
    back = fine.reshape(SHAPE[0], refine, SHAPE[1], refine).mean(axis=(1, 3))
    # the groove profile nests exactly; the roughness differs by point value vs pixel mean,
    # second order in the pixel (its short cut-off is 77 µm against 1.5 µm pixels)
    rms = np.sqrt(np.mean(coarse**2))
    assert np.max(np.abs(back - coarse)) < 2e-3 * rms
    # a different seed is a different surface (the check above can fail)
    other = linear_grind(SHAPE, PIXEL, params, SEED + 1)
    assert np.max(np.abs(other - coarse)) > 0.1 * rms


def test_shipped_texture_is_reproduced_by_its_generator():
    from skisnow.app.storage.textures import read_texture, refined_texture

    base = read_texture(tables_dir() / "textures" / "grind-2.h5")
    fine = refined_texture("grind-2", 2)
    assert fine.pixel_size_m == base.pixel_size_m / 2
    n0, n1 = base.heights_m.shape
    back = fine.heights_m.reshape(n0, 2, n1, 2).mean(axis=(1, 3))
    assert np.max(np.abs(back - base.heights_m)) < 1e-3 * np.sqrt(np.mean(base.heights_m**2))


# ----------------------------------------------------------------------------- extrapolation


def test_richardson_recovers_the_limit_of_a_first_order_sequence():
    f0, c, d = 0.02, 0.5, 3.0
    dx = np.array([2e-3, 1e-3])
    f = f0 + c * dx + d * dx**2  # leading first order, a second-order remainder
    value, err = L.richardson(f[0], f[1], 1.0)
    # the remainder of the extrapolation is -2 d dx_fine^2 (exactly, for this sequence)
    assert value == pytest.approx(f0 - 2 * d * dx[1] ** 2, rel=1e-12)
    assert abs(value - f0) < err  # the estimate covers the true error
    kept, last = L.richardson(f[0], f[1], None)
    assert kept == f[1] and last == pytest.approx(f[0] - f[1])
    with pytest.raises(InputError):
        L.richardson(f[0], f[1], 0.0)


def test_combine_keeps_exact_full_contact_and_the_fine_level_where_extrapolation_fails():
    keys = ("real_contact_area_fraction", "mean_gap_m", "mean_reciprocal_gap_per_m")
    coarse = {k: np.array([3e-5, 0.5, 1.0]) for k in keys}
    fine = {k: np.array([1e-5, 0.4, 1.0]) for k in keys}
    for d in (coarse, fine):
        d["full_contact"] = np.array([False, False, True])
        d["converged"] = np.array([True, True, True])
        d["mean_reciprocal_gap_raw_per_m"] = np.ones(3)
    out = L.combine_pixel_levels(coarse, fine)
    # 2·1e-5 − 3e-5 < 0: a few contact pixels, no extrapolation, the change is the estimate
    assert out["real_contact_area_fraction"][0] == 1e-5
    assert out["real_contact_area_fraction_error"][0] == pytest.approx(2e-5)
    assert out["real_contact_area_fraction"][1] == pytest.approx(0.3)
    assert out["mean_gap_m"][1] == pytest.approx(0.4 - 0.1 / 3)
    assert out["mean_reciprocal_gap_per_m"][1] == 0.4  # no order: the finest level
    assert out["real_contact_area_fraction_error"][2] == 0.0  # exact full contact


# ---------------------------------------------------------------------------- three levels


def _sequence(limit, c1, p, c2, q, pixels):
    """f(Δ) = limit + c1·Δ^p + c2·Δ^q at each pixel size: known order and limit."""
    return [limit + c1 * d**p + c2 * d**q for d in pixels]


def test_observed_order_recovers_a_known_order():
    pixels = [4.0, 2.0, 1.0]
    for p in (1.0, 2.0, 1.5):
        f = _sequence(0.3, 0.01, p, 0.0, 1.0, pixels)
        assert L.observed_order(*f) == pytest.approx(p, rel=1e-12)
    # non-monotone or stagnant sequences have no order
    assert np.isnan(L.observed_order(1.0, 2.0, 1.5))
    assert np.isnan(L.observed_order(1.0, 1.0, 1.0))
    with pytest.raises(InputError, match="refinement"):
        L.observed_order(1.0, 2.0, 3.0, refinement=1.0)


def _levels3(values_by_quantity, full_contact=None):
    n = len(next(iter(values_by_quantity.values()))[0])
    out = []
    for i in range(3):
        d = {q: np.asarray(v[i], dtype=float) for q, v in values_by_quantity.items()}
        d["full_contact"] = np.zeros(n, bool) if full_contact is None else full_contact[i]
        d["converged"] = np.ones(n, bool)
        d["mean_reciprocal_gap_raw_per_m"] = np.ones(n)
        d["iterations"] = np.full(n, 10)
        out.append(d)
    return out


def test_three_levels_estimate_is_the_difference_of_successive_extrapolants():
    """Closed form: f = A + c1·Δ + c2·Δ² (a_r, order 1 assumed) and g = B + d1·Δ² + d2·Δ³ (mean
    gap, order 2). R(2Δ, Δ) removes the leading term exactly; its remaining error and the
    estimate |R(2Δ, Δ) − R(4Δ, 2Δ)| are known in closed form, and the estimate bounds the
    error (factor k^q − 1 = 3 for a_r, 7 for the gap)."""
    pixels = [4.0, 2.0, 1.0]  # [arbitrary unit]
    a_lim, g_lim = 0.02, 5e-6
    a = _sequence(a_lim, 1e-3, 1.0, 1e-5, 2.0, pixels)
    g = _sequence(g_lim, 1e-8, 2.0, 1e-11, 3.0, pixels)
    rec = [np.full(1, v) for v in (3.0, 2.0, 1.5)]
    levels = _levels3(
        {
            "real_contact_area_fraction": [np.full(1, v) for v in a],
            "mean_gap_m": [np.full(1, v) for v in g],
            "mean_reciprocal_gap_per_m": rec,
        }
    )
    out, info = L.combine_three_pixel_levels(*levels)
    # order-1 extrapolants of the two finest and the two coarsest levels
    r21 = a[2] + (a[2] - a[1])
    r42 = a[1] + (a[1] - a[0])
    assert out["real_contact_area_fraction"][0] == pytest.approx(r21, rel=1e-13)
    assert r21 - a_lim == pytest.approx(-2e-5, rel=1e-9)  # −c2·Δ²·k (k=2, Δ=1)
    err = out["real_contact_area_fraction_error"][0]
    assert err == pytest.approx(abs(r21 - r42), rel=1e-13)
    assert err == pytest.approx(3 * abs(r21 - a_lim), rel=1e-9)  # (k^q − 1)·|error|, q = 2
    assert info["observed_order_real_contact_area_fraction"][0] == pytest.approx(
        np.log2((a[1] - a[0]) / (a[2] - a[1]))
    )
    assert info["three_level_estimate_real_contact_area_fraction"][0] == 1
    g21 = g[2] + (g[2] - g[1]) / 3
    assert out["mean_gap_m"][0] == pytest.approx(g21, rel=1e-13)
    assert out["mean_gap_error_m"][0] == pytest.approx(7 * abs(g21 - g_lim), rel=1e-9)
    # no order: the finest level and its last change, whatever the observed order
    assert out["mean_reciprocal_gap_per_m"][0] == 1.5
    assert out["mean_reciprocal_gap_error_per_m"][0] == pytest.approx(0.5)
    assert info["three_level_estimate_mean_reciprocal_gap_per_m"][0] == -1


def test_three_levels_fall_back_where_the_order_is_not_stable():
    """Observed order 2 (assumed 1), a non-monotone point and a point in full contact at the
    finest level: the conservative estimates, flagged."""
    pixels = [4.0, 2.0, 1.0]
    quad = _sequence(0.1, 1e-3, 2.0, 0.0, 1.0, pixels)  # observed order 2 ≠ 1
    wiggle = [0.1, 0.12, 0.11]
    full = [0.9, 0.95, 1.0]
    ar = [np.array([quad[i], wiggle[i], full[i]]) for i in range(3)]
    gap = [np.array([2e-6, 2e-6, 1e-6]) * (1 + 0.1 * 2.0 ** (2 - i)) for i in range(3)]
    rec = [np.ones(3) * (1 + i) for i in range(3)]
    fc = [np.array([False, False, False])] * 2 + [np.array([False, False, True])]
    levels = _levels3(
        {"real_contact_area_fraction": ar, "mean_gap_m": gap, "mean_reciprocal_gap_per_m": rec},
        fc,
    )
    two = L.combine_pixel_levels(levels[1], levels[2])
    out, info = L.combine_three_pixel_levels(*levels)
    method = info["three_level_estimate_real_contact_area_fraction"]
    np.testing.assert_array_equal(method, [0, 0, -1])
    err = out["real_contact_area_fraction_error"]
    r21, r42 = 2 * quad[2] - quad[1], 2 * quad[1] - quad[0]
    assert err[0] == pytest.approx(max(abs(r21 - r42), abs(r21 - quad[2])))
    assert err[0] >= two["real_contact_area_fraction_error"][0]
    assert err[1] >= two["real_contact_area_fraction_error"][1]
    assert np.isnan(info["observed_order_real_contact_area_fraction"][1])
    # full contact at a level: the two-level result of the finest levels, unchanged
    assert err[2] == two["real_contact_area_fraction_error"][2]
    for key in ("real_contact_area_fraction", "mean_gap_m"):
        np.testing.assert_array_equal(out[key], two[key])
    with pytest.raises(InputError, match="order_tolerance"):
        L.combine_three_pixel_levels(*levels, order_tolerance=0.0)


@pytest.fixture(scope="module")
def three_level(tmp_path_factory):
    from dask.distributed import Client, LocalCluster

    params = _grind_params()
    texture = Texture(linear_grind(SHAPE, PIXEL, params, SEED), PIXEL, "strip", source="test")
    finer = [
        Texture(
            linear_grind(SHAPE, PIXEL, params, SEED, refine=k), PIXEL / k, "strip", source="test"
        )
        for k in (2, 4)
    ]
    settings = BuildSettings(
        points=4, ratio_min=1e-3, ratio_max=1e-2, chunk_size=2, pixel_levels="refine3"
    )
    out = tmp_path_factory.mktemp("three-level")
    done = []
    cluster = LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    )

    def stop_after_two(level, index):
        done.append((level, index))
        if len(done) == 2:
            raise KeyboardInterrupt

    with Client(cluster) as client:
        with pytest.raises(KeyboardInterrupt):
            build_tables(
                [texture],
                out,
                settings,
                client=client,
                progress=False,
                refined={"strip": finer},
                on_chunk_done=stop_after_two,
            )
        resumed = build_tables(
            [texture], out, settings, client=client, progress=False, refined={"strip": finer}
        )["strip"]
        fresh = build_tables(
            [texture],
            tmp_path_factory.mktemp("fresh"),
            settings,
            client=client,
            progress=False,
            refined={"strip": finer},
        )["strip"]
        with pytest.raises(InputError, match="refined"):
            build_tables(
                [texture], out, settings, client=client, progress=False, refined={"strip": finer[0]}
            )
    cluster.close()
    return read_table(resumed), read_table(fresh), done


def test_three_level_build_resumes_reproducibly_and_records_its_method(three_level):
    table, fresh, done = three_level
    assert {level for level, _ in done} <= {f"strip.level{i}" for i in range(3)}
    assert table.attrs["chunks_resumed"] == 2
    assert table_data_sha256(table) == table_data_sha256(fresh)
    info = json.loads(table.attrs["pixel_extrapolation_json"])
    assert info["levels"] == 3 and info["level_pixel_size_m"] == [PIXEL, PIXEL / 2, PIXEL / 4]
    assert info["order_tolerance"] == L.ORDER_TOLERANCE
    assert table.levels["real_contact_area_fraction"].shape == (3, 4)
    p_obs = table.levels["observed_order_real_contact_area_fraction"]
    method = table.levels["three_level_estimate_real_contact_area_fraction"]
    assert p_obs.shape == method.shape == (4,)
    # the stored value is the extrapolant of the two finest levels, the estimate follows its rule
    a = table.levels["real_contact_area_fraction"]
    r21, r42 = 2 * a[2] - a[1], 2 * a[1] - a[0]
    np.testing.assert_allclose(table.real_contact_area_fraction, r21, rtol=1e-12)
    stable = method == 1
    np.testing.assert_allclose(
        table.real_contact_area_fraction_error[stable], np.abs(r21 - r42)[stable], rtol=1e-12
    )
    assert np.all(table.real_contact_area_fraction_error[~stable] >= np.abs(r21 - a[2])[~stable])
    e = table.effective_modulus_pa
    p = table.pressure_ratio[1] * e
    info = pixel_error_estimate(table, np.array([[p]]), np.array([[0.1]]), 0.0, e)
    assert info["level_pixel_size_um"] == pytest.approx([1.5, 0.75, 0.375])
    assert info["estimate_rule"] == "successive_extrapolants"


# ------------------------------------------------------------------------ two-level tables


@pytest.fixture(scope="module")
def two_level(tmp_path_factory):
    from dask.distributed import Client, LocalCluster

    params = _grind_params()
    texture = Texture(linear_grind(SHAPE, PIXEL, params, SEED), PIXEL, "strip", source="test")
    fine = Texture(
        linear_grind(SHAPE, PIXEL, params, SEED, refine=2), PIXEL / 2, "strip", source="test"
    )
    settings = BuildSettings(
        points=6, ratio_min=3e-4, ratio_max=1e-2, chunk_size=3, pixel_levels="refine"
    )
    out = tmp_path_factory.mktemp("two-level")
    cluster = LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    )
    with Client(cluster) as client:
        path = build_tables(
            [texture], out, settings, client=client, progress=False, refined={"strip": fine}
        )["strip"]
        again = build_tables(
            [texture],
            tmp_path_factory.mktemp("again"),
            settings,
            client=client,
            progress=False,
            refined={"strip": fine},
        )["strip"]
    cluster.close()
    return read_table(path), read_table(again), params


def test_two_level_table_is_reproducible_and_records_its_levels(two_level):
    table, again, _ = two_level
    assert table.has_error_estimates
    assert table_data_sha256(table) == table_data_sha256(again)
    info = json.loads(table.attrs["pixel_extrapolation_json"])
    assert info["level_pixel_size_m"] == [PIXEL, PIXEL / 2]
    assert info["orders"]["real_contact_area_fraction"] == 1.0
    assert table.levels["real_contact_area_fraction"].shape == (2, 6)


def test_stored_error_estimate_covers_an_independent_finer_solve(two_level):
    """At three table points: the limit from two finer levels (Δ/4, Δ/8; solved here, not by
    the build) lies within the stored estimate of the stored value, and the stored value is
    closer to it than the finest level of the table."""
    table, _, params = two_level
    e = table.effective_modulus_pa
    for i in (0, 2, 5):
        ratio = table.pressure_ratio[i]
        a = [
            solve_micro(
                linear_grind(SHAPE, PIXEL, params, SEED, refine=k), PIXEL / k, ratio * e, e
            ).real_contact_area_fraction
            for k in (4, 8)
        ]
        limit, _ = L.richardson(a[0], a[1], 1.0)
        stored = table.real_contact_area_fraction[i]
        claim = table.real_contact_area_fraction_error[i]
        finest = table.levels["real_contact_area_fraction"][1, i]
        assert abs(stored - limit) <= claim, (i, stored, limit, claim)
        assert abs(stored - limit) < abs(finest - limit), (i, stored, finest, limit)


def test_lookup_reports_the_error_estimate_at_interpolated_points(two_level):
    table, _, _ = two_level
    e = table.effective_modulus_pa
    r = table.pressure_ratio
    rel_nodes = table.real_contact_area_fraction_error / table.real_contact_area_fraction
    mid = np.sqrt(r[1] * r[2])
    got = L.relative_error_estimate(
        table, [r[1] * e, mid * e, 0.0], e, "real_contact_area_fraction"
    )
    assert got[0] == pytest.approx(rel_nodes[1])
    assert min(rel_nodes[1:3]) <= got[1] <= max(rel_nodes[1:3])
    assert got[2] == 0.0  # zero load is exact
    pressure = np.array([[r[1] * e, 0.0], [mid * e, np.nan]])
    ar_map = np.array([[0.1, 0.0], [0.2, np.nan]])
    info = pixel_error_estimate(table, pressure, ar_map, 0.0, e)
    assert info["estimated"] and info["level_pixel_size_um"] == [1.5, 0.75]
    assert info["estimate_rule"] == "richardson_correction"
    assert info["real_contact_area_fraction_rel_max"] == pytest.approx(max(got[:2]))
    assert info["total_real_contact_area_rel"] == pytest.approx((0.1 * got[0] + 0.2 * got[1]) / 0.3)


def test_one_level_table_still_loads_without_estimates(tmp_path, small_table):
    """Tables built before the estimates (one pixel size, uploads) read as before."""
    from skisnow.app.storage.tables import write_table

    path = write_table(tmp_path / "old.h5", small_table, heights_m=np.zeros((4, 4)))
    with h5py.File(path, "r") as f:
        assert "real_contact_area_fraction_error" not in f["loaded"] and "levels" not in f
    table = read_table(path)
    assert not table.has_error_estimates and table.levels is None
    e = table.effective_modulus_pa
    p = table.pressure_ratio[1] * e
    assert L.relative_error_estimate(table, p, e, "real_contact_area_fraction") is None
    assert pixel_error_estimate(table, np.array([[p]]), np.array([[0.1]]), 0.0, e) == {
        "estimated": False,
        "pixel_levels": "none",
    }


# ----------------------------------------------------------------------------- shipped tables


def _shipped(name: str):
    return read_table(tables_dir() / f"{name}.h5")


@pytest.mark.parametrize("name", ["grind-1", "grind-2"])
def test_shipped_table_area_error_estimate_within_3_percent(name):
    table = _shipped(name)
    assert table.has_error_estimates
    a = table.real_contact_area_fraction
    sel = ~table.full_contact & (a >= AR_RANGE[0]) & (a <= AR_RANGE[1])
    assert np.count_nonzero(sel) >= 20
    rel = table.real_contact_area_fraction_error[sel] / a[sel]
    assert rel.max() <= AR_TOLERANCE, f"{name}: largest a_r estimate {rel.max():.3%}"


@pytest.mark.parametrize("name", ["grind-1", "grind-2"])
def test_shipped_light_load_levels_follow_their_rule(name):
    """The shipped grinds have the light-load levels exactly at the nodes their rule selects
    from the table before the pass, every level half the pixel of the one before down to
    16384², every solve converged, and each node recombined from its three finest levels."""
    table = _shipped(name)
    nodes = table.light_load_nodes
    lv = table.levels
    a_before = table.real_contact_area_fraction.copy()
    a_before[nodes] = lv["light_previous_real_contact_area_fraction"]
    expect = L.select_light_load_nodes(
        a_before, table.full_contact, exclude=table.fourth_level_nodes
    )
    assert nodes.size >= 10 and np.array_equal(nodes, expect)
    pixels = np.r_[lv["pixel_size_m"], lv["light_pixel_size_m"]]
    np.testing.assert_allclose(pixels[1:] / pixels[:-1], 0.5, rtol=1e-12)
    assert round(table.pixel_size_m / pixels[-1]) * table.grid_shape[0] == 16384
    assert np.all(lv["light_converged"])
    out, _ = L.combine_with_light_load_levels(
        lv,
        nodes,
        [
            {k: lv[f"light_{k}"][j] for k in L._LEVEL_KEYS}
            for j in range(pixels.size - lv["pixel_size_m"].size)
        ],
    )
    for q, err in L.ERROR_FIELDS.items():
        np.testing.assert_allclose(getattr(table, q)[nodes], out[q], rtol=1e-14)
        np.testing.assert_allclose(getattr(table, err)[nodes], out[err], rtol=1e-14)
    info = json.loads(table.attrs["light_load_levels_json"])
    assert info["device"] == "cuda" and info["nodes"] == nodes.tolist()


def test_shipped_grind2_fourth_level_follows_its_rule():
    """The shipped grind-2 table has the fourth level exactly at the nodes its rule selects
    from the three-level table (its a_r before the pass and its three-level flags)."""
    table = _shipped("grind-2")
    nodes = table.fourth_level_nodes
    a_before = table.real_contact_area_fraction.copy()
    a_before[nodes] = table.levels["adaptive_previous_real_contact_area_fraction"]
    expect, _ = L.select_fourth_level_nodes(
        a_before, {q: table.levels[f"three_level_estimate_{q}"] for q in L.ERROR_FIELDS}
    )
    assert nodes.size and np.array_equal(nodes, expect)
    assert float(table.levels["adaptive_pixel_size_m"]) == pytest.approx(
        table.levels["pixel_size_m"][-1] / 2, rel=1e-12
    )
    assert np.all(table.levels["adaptive_converged"])


@pytest.mark.slow
@pytest.mark.skipif(
    not SLOW,
    reason="4096² (two-level) or 8192² (three-level, ~6 GB) solves: set SKISNOW_SLOW_TESTS=1",
)
@pytest.mark.parametrize(("name", "node"), [("grind-2", 38), ("grind-2", 60), ("grind-1", 39)])
def test_shipped_estimate_covers_a_finer_solve(name, node):
    """The shipped table's stored a_r against the limit from its finest level and one solve
    on half its pixel (0.75/0.375 µm for two-level tables, 0.375/0.1875 µm for three)."""
    from skisnow.app.storage.textures import refined_texture

    table = _shipped(name)
    e = table.effective_modulus_pa
    ratio = table.pressure_ratio[node]
    finest = table.levels["real_contact_area_fraction"][-1, node]
    k = 2 * round(table.pixel_size_m / table.levels["pixel_size_m"][-1])
    fine = refined_texture(name, k)
    a_k = solve_micro(fine.heights_m, fine.pixel_size_m, ratio * e, e, workers=1)
    limit, _ = L.richardson(finest, a_k.real_contact_area_fraction, 1.0)
    stored = table.real_contact_area_fraction[node]
    assert abs(stored - limit) <= table.real_contact_area_fraction_error[node]


def test_two_level_build_resumes_to_the_same_table(tmp_path):
    """A killed two-level build (``coarsen``, any texture) reruns only the missing chunks of
    each level and writes the table an uninterrupted build writes."""
    from dask.distributed import Client, LocalCluster

    texture = Texture(linear_grind(SHAPE, PIXEL, _grind_params(), SEED), PIXEL, "strip")
    settings = BuildSettings(
        points=6, ratio_min=3e-4, ratio_max=1e-2, chunk_size=3, pixel_levels="coarsen"
    )
    done = []

    def interrupt(name, index):
        done.append((name, index))
        if len(done) == 2:
            raise KeyboardInterrupt("simulated kill")

    cluster = LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    )
    with Client(cluster) as client:
        whole = build_tables([texture], tmp_path / "whole", settings, client=client, progress=False)
        with pytest.raises(KeyboardInterrupt):
            build_tables(
                [texture],
                tmp_path / "cut",
                settings,
                client=client,
                progress=False,
                on_chunk_done=interrupt,
            )
        rerun = []
        again = build_tables(
            [texture],
            tmp_path / "cut",
            settings,
            client=client,
            progress=False,
            on_chunk_done=lambda n, i: rerun.append((n, i)),
        )
    cluster.close()
    assert {n for n, _ in done + rerun} == {"strip.level0", "strip.level1"}
    assert len(rerun) == 4 - 2 and not set(rerun) & set(done)
    a, b = read_table(whole["strip"]), read_table(again["strip"])
    assert b.has_error_estimates and table_data_sha256(a) == table_data_sha256(b)
    assert b.attrs["chunks_resumed"] == 2
    assert json.loads(b.attrs["pixel_extrapolation_json"])["level_pixel_size_m"] == [
        2 * PIXEL,
        PIXEL,
    ]


# ---------------------------------------------------------------- adaptive fourth level


def test_fourth_level_selects_fall_backs_in_the_estimate_range_only():
    """Selected: a fall-back of a_r or of the mean gap with a_r in [1e-3, 0.9] (ends included).
    Not selected: stable nodes, fall-backs outside the range, the reciprocal gap (no order)."""
    a_r = np.array([5e-4, 1e-3, 0.01, 0.5, 0.9, 0.95, 0.2])
    estimate = {
        "real_contact_area_fraction": np.array([0, 1, 0, 1, 1, 0, -1]),
        "mean_gap_m": np.array([0, 1, 1, 1, 0, 0, 1]),
        "mean_reciprocal_gap_per_m": np.array([0, 0, 0, 0, 0, 0, 0]),
    }
    nodes, selected_by = L.select_fourth_level_nodes(a_r, estimate)
    np.testing.assert_array_equal(nodes, [2, 4])
    np.testing.assert_array_equal(selected_by["real_contact_area_fraction"], [True, False])
    np.testing.assert_array_equal(selected_by["mean_gap_m"], [False, True])
    assert set(selected_by) == {"real_contact_area_fraction", "mean_gap_m"}
    # the acceptance test checks both ranges together: light loads, then the estimate range
    assert (L.LIGHT_LOAD_RANGE_A_R[0], L.ESTIMATE_RANGE_A_R[1]) == AR_RANGE
    assert L.LIGHT_LOAD_RANGE_A_R[1] == L.ESTIMATE_RANGE_A_R[0]
    stable = {q: np.ones(a_r.size) for q in estimate}
    assert L.select_fourth_level_nodes(a_r, stable)[0].size == 0
    with pytest.raises(InputError, match="a_r_range"):
        L.select_fourth_level_nodes(a_r, estimate, a_r_range=(0.5, 0.1))
    with pytest.raises(InputError, match="shape"):
        L.select_fourth_level_nodes(a_r[:3], estimate)


def test_fourth_level_recombines_from_the_three_finest_levels():
    """Four levels Δ = 8, 4, 2, 1 of sequences with a known limit. Node 0: a_r = A + c1·Δ +
    c2·Δ², gap = B + d1·Δ² + d2·Δ³: the recombined value is the extrapolant R(2, 1) of the
    two finest levels, its estimate |R(2, 1) − R(4, 2)| = (k^q − 1)·|R(2, 1) − limit|.
    Node 1: a_r of order 1.6 (observed 1.6 ≠ 1): the conservative fall-back."""
    pixels = [8.0, 4.0, 2.0, 1.0]
    a0 = _sequence(0.02, 1e-3, 1.0, 1e-5, 2.0, pixels)
    a1 = _sequence(0.05, 1e-3, 1.6, 0.0, 1.0, pixels)
    g = _sequence(5e-6, 1e-8, 2.0, 1e-11, 3.0, pixels)
    rec = [3.0, 2.0, 1.5, 1.25]
    n = 3  # node 2 is not recombined
    levels = {
        "real_contact_area_fraction": np.array([[a0[i], a1[i], 0.3] for i in range(3)]),
        "mean_gap_m": np.array([[g[i]] * n for i in range(3)]),
        "mean_reciprocal_gap_per_m": np.array([[rec[i]] * n for i in range(3)]),
        "mean_reciprocal_gap_raw_per_m": np.ones((3, n)),
        "iterations": np.full((3, n), 10),
        "converged": np.ones((3, n), bool),
        "full_contact": np.zeros((3, n), bool),
    }
    fourth = {
        "real_contact_area_fraction": np.array([a0[3], a1[3]]),
        "mean_gap_m": np.full(2, g[3]),
        "mean_reciprocal_gap_per_m": np.full(2, rec[3]),
        "mean_reciprocal_gap_raw_per_m": np.ones(2),
        "iterations": np.full(2, 12),
        "residual": np.full(2, 1e-7),
        "converged": np.ones(2, bool),
        "full_contact": np.zeros(2, bool),
    }
    out, info = L.combine_with_fourth_level(levels, [0, 1], fourth)
    r21, r42 = 2 * a0[3] - a0[2], 2 * a0[2] - a0[1]
    assert out["real_contact_area_fraction"][0] == pytest.approx(r21, rel=1e-13)
    assert out["real_contact_area_fraction_error"][0] == pytest.approx(abs(r21 - r42), rel=1e-12)
    assert out["real_contact_area_fraction_error"][0] == pytest.approx(
        3 * abs(r21 - 0.02), rel=1e-9
    )
    g21 = g[3] + (g[3] - g[2]) / 3
    assert out["mean_gap_m"][0] == pytest.approx(g21, rel=1e-13)
    assert out["mean_gap_error_m"][0] == pytest.approx(7 * abs(g21 - 5e-6), rel=1e-9)
    np.testing.assert_array_equal(info["three_level_estimate_real_contact_area_fraction"], [1, 0])
    assert info["observed_order_real_contact_area_fraction"][1] == pytest.approx(1.6, rel=1e-12)
    s21, s42 = 2 * a1[3] - a1[2], 2 * a1[2] - a1[1]
    assert out["real_contact_area_fraction_error"][1] == pytest.approx(
        max(abs(s21 - s42), abs(s21 - a1[3])), rel=1e-12
    )
    assert out["mean_reciprocal_gap_per_m"][0] == 1.25  # no order: the fourth level
    assert out["mean_reciprocal_gap_error_per_m"][0] == pytest.approx(0.25)
    with pytest.raises(InputError, match="three-level"):
        L.combine_with_fourth_level({k: v[:2] for k, v in levels.items()}, [0], fourth)


#: a narrower strip for the fourth-level build (its finest level is 8× the strip) [-]
SHAPE4 = (32, 256)
FOURTH_SETTINGS = dict(points=6, ratio_min=3e-4, ratio_max=3e-2, chunk_size=3)


def _strip_levels(shape):
    params = _grind_params()

    def surface(k: int) -> Texture:
        h = linear_grind(shape, PIXEL, params, SEED, refine=k)
        return Texture(h, PIXEL / k, "strip", source=f"test strip refined {k}x")

    return surface(1), [surface(2), surface(4)], surface


@pytest.fixture(scope="module")
def fourth_level(tmp_path_factory):
    """Build then pass, and a from-scratch build with the pass killed after its first node and
    rerun."""
    from dask.distributed import Client, LocalCluster
    from skisnow.app.jobs.table_fourth_level import fourth_level_pass

    texture, finer, surface = _strip_levels(SHAPE4)
    settings = BuildSettings(**FOURTH_SETTINGS, pixel_levels="refine3")
    cluster = LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0"
    )
    calls = []

    def counted(k):
        calls.append(k)
        return surface(k)

    solved, resolved = [], []

    def kill_after_first(node):
        solved.append(node)
        raise KeyboardInterrupt("simulated kill")

    scratch = tmp_path_factory.mktemp("scratch")
    with Client(cluster) as client:
        kw = dict(client=client, progress=False, refined={"strip": finer})
        three = build_tables([texture], tmp_path_factory.mktemp("three"), settings, **kw)["strip"]
        with pytest.raises(KeyboardInterrupt):
            build_tables(
                [texture],
                scratch,
                settings,
                fourth_level={"strip": counted},
                on_node_done=kill_after_first,
                **kw,
            )
        assert not (scratch / "strip.h5").exists()  # the table appears only when complete
        resumed = build_tables(
            [texture],
            scratch,
            settings,
            fourth_level={"strip": counted},
            on_node_done=resolved.append,
            **kw,
        )["strip"]
    cluster.close()
    passed = fourth_level_pass(three, tmp_path_factory.mktemp("pass"), surface, progress=False)
    assert not (scratch / ".checkpoints").exists()
    tables = (read_table(three), read_table(passed), read_table(resumed))
    return (*tables, solved, resolved, calls, resumed)


def test_fourth_level_pass_refines_only_the_selected_nodes(fourth_level):
    three, table, *_ = fourth_level
    nodes, selected_by = L.select_fourth_level_nodes(
        three.real_contact_area_fraction,
        {q: three.levels[f"three_level_estimate_{q}"] for q in L.ERROR_FIELDS},
    )
    assert nodes.size >= 2  # the strip has fall-backs in range (else the test proves nothing)
    np.testing.assert_array_equal(table.fourth_level_nodes, nodes)
    lv = table.levels
    assert float(lv["adaptive_pixel_size_m"]) == PIXEL / 8
    for q, mask in selected_by.items():
        np.testing.assert_array_equal(lv[f"adaptive_selected_by_{q}"], mask)
    # the three stored levels are unchanged, so are the nodes not selected
    for key, value in three.levels.items():
        np.testing.assert_array_equal(lv[key], value)
    other = np.setdiff1d(np.arange(three.pressure_ratio.size), nodes)
    for q, err in L.ERROR_FIELDS.items():
        np.testing.assert_array_equal(getattr(table, q)[other], getattr(three, q)[other])
        np.testing.assert_array_equal(getattr(table, err)[other], getattr(three, err)[other])
        np.testing.assert_array_equal(lv[f"adaptive_previous_{q}"], getattr(three, q)[nodes])
    # the refined nodes: the three finest levels recombined (the coarsest no longer enters)
    a = np.vstack(
        [
            three.levels["real_contact_area_fraction"][1:, nodes],
            lv["adaptive_real_contact_area_fraction"],
        ]
    )
    expect, _ = L.combine_three_pixel_levels(
        *[
            {
                "real_contact_area_fraction": a[i],
                "mean_gap_m": np.ones(nodes.size),
                "mean_reciprocal_gap_per_m": np.ones(nodes.size),
                "full_contact": np.zeros(nodes.size, bool),
                "converged": np.ones(nodes.size, bool),
            }
            for i in range(3)
        ]
    )
    np.testing.assert_allclose(
        table.real_contact_area_fraction[nodes], expect["real_contact_area_fraction"], rtol=1e-14
    )
    np.testing.assert_allclose(
        table.real_contact_area_fraction_error[nodes],
        expect["real_contact_area_fraction_error"],
        rtol=1e-14,
    )
    # the fourth level is an independent cold solve at 1/8 of the texture's pixel
    _, _, surface = _strip_levels(SHAPE4)
    fine = surface(8)
    e = table.effective_modulus_pa
    res = solve_micro(
        fine.heights_m, fine.pixel_size_m, table.pressure_ratio[nodes[0]] * e, e, workers=1
    )
    assert lv["adaptive_real_contact_area_fraction"][0] == pytest.approx(
        res.real_contact_area_fraction, rel=1e-12
    )
    info = json.loads(table.attrs["adaptive_level_json"])
    assert info["input_data_sha256"] == three.attrs["data_sha256"]
    assert (
        info["estimate_range_a_r"] == list(L.ESTIMATE_RANGE_A_R) and info["nodes"] == nodes.tolist()
    )
    assert table.attrs["data_sha256"] != three.attrs["data_sha256"]
    # the lookup and the API report the recombined estimate and the fourth level
    p = table.pressure_ratio[nodes[0]] * e
    rel = L.relative_error_estimate(table, p, e, "real_contact_area_fraction")
    assert rel == pytest.approx(
        table.real_contact_area_fraction_error[nodes[0]]
        / table.real_contact_area_fraction[nodes[0]]
    )
    answer = pixel_error_estimate(table, np.array([[p, 0.0]]), np.array([[0.1, 0.0]]), 0.0, e)
    assert answer["fourth_level"]["pixel_size_um"] == pytest.approx(PIXEL / 8 * 1e6)
    assert answer["fourth_level"]["cells_near"] == 1
    assert "fourth_level" not in pixel_error_estimate(
        three, np.array([[p]]), np.array([[0.1]]), 0.0, e
    )


def test_fourth_level_pass_resumes_and_equals_the_from_scratch_build(fourth_level):
    _three, passed, resumed, solved, resolved, calls, path = fourth_level
    nodes = passed.fourth_level_nodes
    assert solved == [nodes[0]] and resolved == list(nodes[1:])  # only the missing nodes
    assert json.loads(resumed.attrs["adaptive_level_json"])["nodes_resumed"] == 1
    assert calls == [8, 8]  # the 8× surface of the strip, made once per run
    assert table_data_sha256(resumed) == table_data_sha256(passed)
    assert resumed.attrs["data_sha256"] == passed.attrs["data_sha256"]
    from skisnow.app.jobs.table_fourth_level import fourth_level_pass

    with pytest.raises(InputError, match="already"):
        fourth_level_pass(path, path.parent, lambda k: None, progress=False)
