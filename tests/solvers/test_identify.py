"""Beam identification (solvers.identify): recovery of EI(X) and c(X) from virtual-device data,
misfit at the noise, honest failure, the Woodbury solve against a dense least-squares oracle."""

import dataclasses
import functools

import numpy as np
import pytest
from skisnow.solvers import identify
from skisnow.solvers.beam import OTHER_DESIGNS, measure_camber, measure_unloaded, solve_beam_contact
from skisnow.solvers.beam_fit import camber_on_flat
from skisnow.solvers.errors import InputError

LOADS_N = np.linspace(10, 90, 7) * 9.82
POSITIONS_M = np.linspace(-0.30, 0.10, 6)

DESIGNS = OTHER_DESIGNS
#: the variant starts (and those on demand) change the chosen beam only where every main fit
#: stays above the noise (variant_choice; at the noise bit for bit the same,
#: test_variant_starts_are_alternatives_only) and cost a start and two fits: tests of the main
#: fits run without them
NO_VARIANTS = {"variant_knot_spacings_m": (), "demand_variant_knot_spacings_m": ()}


@pytest.fixture(autouse=True)
def _model_on_the_data_nodes(monkeypatch):
    """The data of these tests are the device model on their own coarse nodes (4 mm, for
    speed): the forward fits model them on the same nodes (model_spacing_m 0). The finer model
    grid, for samples of a finer device, has its own tests (test_sparse_samples_*)."""
    monkeypatch.setattr(identify, "DEFAULT_MODEL_SPACING_M", 0.0)


def _data(design, spacing_m, noise_m, seed):
    ski = design.build(spacing_m)
    f, xf, y = measure_camber(ski, LOADS_N, POSITIONS_M, noise_m=noise_m, rng=seed)
    return ski, f, xf, y


@functools.lru_cache(maxsize=8)
def _identified(name, spacing_m, noise_m, seed, assumed_noise_m=None, variants=False):
    """Data and identification, shared by the tests that look at the same case. Without the
    variant starts unless ``variants`` (NO_VARIANTS: the main fits alone)."""
    ski, f, xf, y = _data(DESIGNS[name], spacing_m, noise_m, seed)
    kw = {} if variants else NO_VARIANTS
    return ski, identify.identify_beam(ski.positions_m, f, xf, y, noise_m=assumed_noise_m, **kw)


def _held_out(ski, beam, seed, count=12):
    rng = np.random.default_rng(seed)
    f = rng.uniform(15, 85, count) * 9.82
    xf = rng.uniform(-0.28, 0.08, count)
    return identify.predict_gaps(ski, f, xf), identify.predict_gaps(beam, f, xf)


_EI_XFAIL = pytest.mark.xfail(
    strict=True,
    reason="EI(X) in the middle from 42 noise-free cases on a 4 mm grid: 15 % off ('soft') "
    "while held-out profiles agree to 1 um; the forward fit stalls on the small smooth pieces "
    "of the discrete contact model (issue #12; the demo skis' 340 cases at 1 mm give EI within "
    "1-2 % in the middle). 'stiff' (5 % off from one start) is within 3 % since the fits run "
    "from several starts (#26)",
)


@pytest.mark.parametrize("name", ["soft", "stiff"])
def test_noise_free_profiles(name):
    """Noise-free data: every case is reproduced and held-out loaded profiles agree to about
    a µm (measured: 0.4-0.6 µm misfit, 1.0 µm held-out on the 4 mm grid of 42 cases)."""
    ski, ident = _identified(name, 4e-3, 0.0, None, 3e-6)
    assert ident.ok, ident.reason
    assert ident.misfit_m < 1.5e-6
    truth, pred = _held_out(ski, ident.beam, 1)
    near = truth < 2e-4
    assert np.sqrt(np.mean((pred - truth)[near] ** 2)) < 1.5e-6


@pytest.mark.parametrize("name", [pytest.param("soft", marks=_EI_XFAIL), "stiff"])
def test_noise_free_stiffness(name):
    ski, ident = _identified(name, 4e-3, 0.0, None, 3e-6)
    mid = np.abs(ski.positions_m) < 0.25
    rel = ident.beam.bending_stiffness_nm2[mid] / ski.bending_stiffness_nm2[mid] - 1
    assert np.abs(rel).max() < 0.03


@pytest.mark.parametrize(("name", "seed"), [("soft", 7), ("stiff", 5)])
def test_noisy_misfit_at_the_noise(name, seed):
    """3 µm device noise: the noise estimate is right, the misfit of the exact device model
    comes down to the noise in every case, the bands are ordered."""
    _ski, ident = _identified(name, 4e-3, 3e-6, seed)
    assert ident.ok, ident.reason
    assert ident.noise_m == pytest.approx(3e-6, rel=0.05)
    assert ident.misfit_m == pytest.approx(ident.noise_m, rel=0.1)
    assert ident.case_misfit_m.max() < 1.5 * ident.noise_m
    lo, hi = ident.stiffness_band_nm2
    assert np.all(lo < hi) and np.all(ident.camber_band_m > 0)


@pytest.mark.xfail(
    strict=True,
    reason="held-out loaded profiles from 42 cases with 3 um noise on a 4 mm grid: 1.0 um RMS "
    "from the truth near contact ('soft'), 2.5 um ('stiff'); target 0.3 um (issue #12), met by "
    "the demo skis' 340 cases at 1 mm (0.10 / 0.14 um, tests/service/test_demo_identification.py)",
)
@pytest.mark.parametrize(("name", "seed"), [("soft", 7), ("stiff", 5)])
def test_noisy_held_out_profiles(name, seed):
    ski, ident = _identified(name, 4e-3, 3e-6, seed)
    truth, pred = _held_out(ski, ident.beam, 2)
    near = truth < 2e-4
    assert np.sqrt(np.mean((pred - truth)[near] ** 2)) < 3e-7


def test_not_a_beam_is_reported():
    """Cases of two different skis mixed (like left and right sides that differ): no beam fits,
    the result says so instead of returning a bad beam as good."""
    a, f, xf, ya = _data(DESIGNS["stiff"], 4e-3, 3e-6, 3)
    _b, _, _, yb = _data(DESIGNS["soft"], 4e-3, 3e-6, 4)
    y = np.where((np.arange(f.size) % 2 == 0)[:, None], ya, yb)
    ident = identify.identify_beam(a.positions_m, f, xf, y, **NO_VARIANTS)
    assert not ident.ok
    assert "misfit" in ident.reason


def test_too_few_cases_and_one_load():
    ski, f, xf, y = _data(DESIGNS["stiff"], 4e-3, 0.0, None)
    few = identify.identify_beam(ski.positions_m, f[:3], xf[:3], y[:3])
    assert not few.ok and "at least" in few.reason
    same = f == f[0]
    one = identify.identify_beam(ski.positions_m, f[same], xf[same], y[same])
    assert not one.ok and "same load" in one.reason


def test_bad_input():
    ski, f, xf, y = _data(DESIGNS["stiff"], 4e-3, 0.0, None)
    with pytest.raises(InputError, match="uniform"):
        x = ski.positions_m.copy()
        x[5] += 1e-4
        identify.identify_beam(x, f, xf, y)
    with pytest.raises(InputError, match="loads_n"):
        identify.identify_beam(ski.positions_m, -f, xf, y)
    with pytest.raises(InputError, match="finite"):
        y2 = y.copy()
        y2[0, 0] = np.nan
        identify.identify_beam(ski.positions_m, f, xf, y2)
    with pytest.raises(InputError, match="profiles_m"):
        identify.identify_beam(ski.positions_m, f, xf, y[:, :-1])


def test_estimate_noise():
    _ski, _f, _xf, y = _data(DESIGNS["soft"], 4e-3, 5e-6, 11)
    assert identify.estimate_noise(y) == pytest.approx(5e-6, rel=0.05)


def test_sample_beams_seeded_and_positive():
    ski, f, xf, y = _data(DESIGNS["stiff"], 4e-3, 3e-6, 5)
    ident = identify.identify_beam(ski.positions_m, f, xf, y, **NO_VARIANTS)
    one = identify.sample_beams(ident, 3, 42)
    two = identify.sample_beams(ident, 3, 42)
    for a, b in zip(one, two, strict=True):
        np.testing.assert_array_equal(a.bending_stiffness_nm2, b.bending_stiffness_nm2)
        assert np.all(a.bending_stiffness_nm2 > 0) and a.unloaded_gap_m.min() == 0
    assert not np.array_equal(one[0].unloaded_gap_m, one[1].unloaded_gap_m)
    for bad in (-1.0, float("nan")):
        with pytest.raises(InputError, match="scale must be finite"):
            identify.sample_beams(ident, 2, 42, scale=bad)
    failed = dataclasses.replace(ident, ok=False, reason="misfit too large")
    with pytest.raises(InputError, match="no identified beam to sample: misfit too large"):
        identify.sample_beams(failed, 2, 42)


@pytest.mark.parametrize("smoothing_m", [0.0, 0.03])
def test_block_solve_matches_dense_least_squares(smoothing_m):
    """The per-case elimination + Woodbury (and banded Woodbury with camber smoothing) solve
    equals a dense least-squares solve of the same linear problem."""
    ski = DESIGNS["stiff"].build(1e-2)
    f, xf, y = measure_camber(ski, LOADS_N[::2], POSITIONS_M[::2], noise_m=3e-6, rng=1)
    x = ski.positions_m
    n = x.size
    knots = np.linspace(x[0], x[-1], 11)
    prob = identify._Problem(x, f, xf, y, knots, 3e-6, 10.0, smoothing_m)
    prob.camber_weights = np.random.default_rng(0).uniform(0.1, 1.0, n - 2)
    prob.set_contacts(
        [
            identify._contacts_from_beam(solve_beam_contact(ski, a, b))
            for a, b in zip(f, xf, strict=False)
        ]
    )
    q = prob.phi @ np.full(knots.size, 1e-3)
    blocks, targets = [], []
    for k, st in enumerate(prob.cases):
        cols = [np.ones(n), prob.xn] + [identify._double_integral(mz * q, prob.dx) for mz in st.mz]
        blocks.append((np.stack(cols, 1), np.zeros((n, 0))))
        targets.append(y[k] - identify._double_integral(st.m0 * q, prob.dx))
    c, _, _, _ = prob._solve(blocks, targets, np.zeros((0, 0)), np.zeros(0), 0.0)
    sizes = [b[0].shape[1] for b in blocks]
    off = np.cumsum([0, *sizes])
    rows = len(blocks) * n + (n - 2) + 2
    jac = np.zeros((rows, n + off[-1]))
    rhs = np.zeros(rows)
    s = 1 / 3e-6
    for k, (a_loc, _) in enumerate(blocks):
        jac[k * n : (k + 1) * n, :n] = np.eye(n) * s
        jac[k * n : (k + 1) * n, n + off[k] : n + off[k + 1]] = a_loc * s
        rhs[k * n : (k + 1) * n] = targets[k] * s
    d2 = np.zeros((n - 2, n))
    for i in range(n - 2):
        d2[i, i : i + 3] = (1, -2, 1)
    r0 = len(blocks) * n
    jac[r0 : r0 + n - 2, :n] = np.sqrt(prob.camber_lambda * prob.camber_weights)[:, None] * d2
    jac[-2:, :n] = prob.line.T * s  # c's rigid motion pinned with a one-σ prior
    ref = np.linalg.lstsq(jac, rhs, rcond=None)[0][:n]
    assert np.abs(c - ref).max() < 1e-9 * np.abs(ref).max()


def test_held_out_check_rejects_a_beam_that_does_not_predict():
    """identify_beam_checked: the kept cases identify a clean beam; held-out cases that no beam
    of the kept ones explains (a 30 µm bump) fail the check, and the result says so."""
    ski, f, xf, y = _data(DESIGNS["stiff"], 4e-3, 0.0, None)
    count = round(0.2 * f.size)
    held = np.zeros(f.size, dtype=bool)
    held[np.random.default_rng(3).choice(f.size, count, replace=False)] = True
    bump = 30e-6 * np.exp(-(((ski.positions_m - 0.2) / 0.1) ** 2))
    clean, check = identify.identify_beam_checked(
        ski.positions_m, f, xf, y, seed=3, noise_m=3e-6, **NO_VARIANTS
    )
    assert clean.ok, clean.reason
    assert check["held_out_cases"] == count and check["held_out_rms_m"] < 2e-6
    y_bad = np.where(held[:, None], y + bump, y)
    bad, check = identify.identify_beam_checked(
        ski.positions_m, f, xf, y_bad, seed=3, noise_m=3e-6, **NO_VARIANTS
    )
    assert not bad.ok and "held-out" in bad.reason
    assert check["held_out_rms_m"] > 6e-6


def test_held_out_check_judges_the_contact_band():
    """The held-out check judges where the measured gap is below 0.2 mm (what the answers
    use): held-out cases 30 µm off only where every case stands far above the flat (the
    shovels) pass it, and the whole profile's RMS says how far they are off there."""
    ski, f, xf, y = _data(DESIGNS["stiff"], 4e-3, 0.0, None)
    count = round(0.2 * f.size)
    held = np.zeros(f.size, dtype=bool)
    held[np.random.default_rng(3).choice(f.size, count, replace=False)] = True
    far = y.min(axis=0) > 2 * identify.HELD_OUT_BAND_M  # above the band in every case
    assert far.sum() > 20
    y_far = np.where(held[:, None] & far[None, :], y + 30e-6, y)
    ident, check = identify.identify_beam_checked(
        ski.positions_m, f, xf, y_far, seed=3, noise_m=3e-6, **NO_VARIANTS
    )
    assert ident.ok, ident.reason
    assert check["held_out_rms_band_m"] < 2e-6
    assert check["held_out_rms_m"] > identify.HELD_OUT_LIMIT * 3e-6  # the old rule failed it


def test_forward_paths_side_by_side_give_the_same_beam():
    """``path_map`` runs the two forward paths in worker processes (app/path_pool.py): the same
    candidates, objectives and beam as one after the other in this process at the workers' one
    BLAS thread (the start, with the variant starts, runs in the workers too: at another thread
    count it moves by ~1e-5 relative, rounding, and 3 steps carry that further)."""
    from skisnow.app.path_pool import fixed_blas_threads, path_pool

    ski = DESIGNS["stiff"].build(2e-3)
    f, xf, y = measure_camber(ski, LOADS_N[::3], POSITIONS_M[::2], noise_m=3e-6, rng=5)
    # a few steps per path (the same steps either way is what is checked, not the fit); on
    # 2 mm nodes the coarse path sees every 2nd node at 4 mm
    run = functools.partial(
        identify.identify_beam,
        ski.positions_m,
        f,
        xf,
        y,
        max_steps=3,
        forward_coarse_spacings_m=(0.004, 0.0),
        start_smoothing=identify.START_SMOOTHING_FACTOR * identify.DEFAULT_SMOOTHING,
    )
    with fixed_blas_threads():
        here = run()
    with path_pool(2) as pmap:
        assert pmap is not None
        pooled = run(path_map=pmap)
    # every start (projection, uniform) on both paths
    cands = here.extra["forward_candidates"]
    assert len(cands) == 2 * len({c["start"] for c in cands}) >= 4
    assert {c["coarse_spacing_m"] for c in cands} == {0.004, 0.0}
    for a, b in zip(
        here.extra["forward_candidates"], pooled.extra["forward_candidates"], strict=True
    ):
        assert a["objective"] == pytest.approx(b["objective"], rel=1e-6)
        assert a["steps"] == b["steps"]
    np.testing.assert_allclose(
        pooled.beam.bending_stiffness_nm2, here.beam.bending_stiffness_nm2, rtol=1e-5
    )
    np.testing.assert_allclose(pooled.beam.unloaded_gap_m, here.beam.unloaded_gap_m, atol=1e-10)


def _restart_run(monkeypatch, sigmas):
    """A small, few-step identification with RESTART_SIGMAS set to ``sigmas``."""
    monkeypatch.setattr(identify, "RESTART_SIGMAS", sigmas)
    monkeypatch.setattr(identify, "MISFIT_LIMIT", 1e9)  # 3 steps leave the fit far off
    ski = DESIGNS["stiff"].build(4e-3)
    f, xf, y = measure_camber(ski, LOADS_N[::2], POSITIONS_M[::2], noise_m=3e-6, rng=5)
    return identify.identify_beam(
        ski.positions_m, f, xf, y, max_steps=3, forward_coarse_spacings_m=(0.0,), **NO_VARIANTS
    )


def test_a_fit_above_the_noise_is_redone_from_a_stiffer_start(monkeypatch):
    """The global step on demand: a forward fit whose misfit stays above the noise (forced
    here: a threshold below 1) is redone from further starts with the priors
    RESTART_SMOOTHING_FACTORS × smoothing in turn, and the lowest objective of all paths is kept;
    a fit under the threshold is not redone."""
    again = _restart_run(monkeypatch, -1e9)
    cands = again.extra["forward_candidates"]
    assert again.extra["restarted"] is True
    # both projection starts were made and checked on the device model (a start that misses
    # by far runs no fit; see test_a_start_whose_device_model_misses_by_far_is_not_used)
    factors = sorted(
        s["smoothing"] / identify.DEFAULT_SMOOTHING
        for s in again.extra["starts"]
        if s["start"] == "projection"
    )
    # forced above the noise, every restart prior runs in turn
    assert factors == pytest.approx(
        [identify.START_SMOOTHING_FACTOR, *identify.RESTART_SMOOTHING_FACTORS]
    )
    used = {
        s["smoothing"] for s in again.extra["starts"] if s["start"] == "projection" and s["used"]
    }
    assert {c["start_smoothing"] for c in cands if c["start"] == "projection"} == used
    kept = min(cands, key=lambda c: (not c["converged"], c["objective"]))
    assert again.extra["start_smoothing"] == kept["start_smoothing"]
    assert again.misfit_m == pytest.approx(kept["misfit_m"], rel=1e-12)
    once = _restart_run(monkeypatch, 1e9)
    assert once.extra["restarted"] is False
    assert {s["start"] for s in once.extra["starts"]} == {"projection", "uniform"}
    used = [s["start"] for s in once.extra["starts"] if s["used"]]
    assert [c["start"] for c in once.extra["forward_candidates"]] == used


# ----------------------------------------------------------------- #26: the unloaded profile,
# several starts checked on the device model, honest failure


def _with_unloaded(ski, f, xf, y, seed):
    """The cases plus the unloaded profile: the camber on the flat plus 3 µm noise (the device
    model of 0 N; on these coarse grids a ClassicSkiDesign's sampled camber does not touch
    zero, min 2.6 µm at 4 mm, so measure_unloaded's raw camber would carry a line)."""
    y0 = identify.predict_gaps(ski, np.zeros(1), np.zeros(1))[0]
    y0 = y0 + np.random.default_rng(seed).normal(0.0, 3e-6, y0.size)
    return np.r_[0.0, f], np.r_[0.0, xf], np.vstack([y0, y])


def test_unloaded_case_through_predict_gaps_and_identify_start():
    """A 0 N case is the unloaded profile: predict_gaps answers the camber on the flat (x_F
    ignored), identify_start fits it (no 'loads_n must be > 0'); a negative load is still an
    error that names it."""
    ski, f, xf, y = _data(DESIGNS["stiff"], 4e-3, 3e-6, 5)
    g = identify.predict_gaps(ski, np.array([0.0, f[0]]), np.array([0.55, xf[0]]))
    np.testing.assert_array_equal(g[0], camber_on_flat(ski.positions_m, ski.unloaded_gap_m))
    assert g[0].min() == 0.0
    np.testing.assert_allclose(g[1], solve_beam_contact(ski, f[0], xf[0]).gap_m)
    f0, xf0, y0 = _with_unloaded(ski, f, xf, y, 6)
    start = identify.identify_start(ski.positions_m, f0, xf0, y0)
    assert start.ok, start.reason
    assert start.case_misfit_m.size == f0.size
    assert start.case_misfit_m[0] < 1.5 * start.noise_m  # c + a line fits the unloaded profile
    with pytest.raises(InputError, match="loads_n must be > 0"):
        identify.predict_gaps(ski, np.array([-1.0]), np.array([0.0]))
    with pytest.raises(InputError, match="loads_n must be > 0"):
        identify.identify_start(ski.positions_m, np.r_[-1.0, f[1:]], xf, y)


def test_uniform_start_takes_c_from_the_unloaded_profile_and_finds_ei():
    """The unloaded-profile start: c is the measured unloaded profile (on the flat) and a
    uniform EI comes from a line search of the device model; on a uniform beam, noise-free,
    it finds that EI (grid 13 points per 4 decades refined to 0.005 in log10)."""
    d = DESIGNS["stiff"].build(4e-3)
    ski = identify.BeamSki(d.positions_m, np.full(d.positions_m.size, 1700.0), d.unloaded_gap_m)
    f, xf, y = measure_camber(ski, LOADS_N[::2], POSITIONS_M[::2], noise_m=0.0)
    start = identify._uniform_stiffness_start(ski.positions_m, f, xf, y, ski.unloaded_gap_m)
    assert start.bending_stiffness_nm2 == pytest.approx(1700.0, rel=0.03)
    np.testing.assert_allclose(
        start.unloaded_gap_m, camber_on_flat(ski.positions_m, ski.unloaded_gap_m), atol=1e-12
    )


@functools.lru_cache(maxsize=2)
def _with_unloaded_identified(seed=5):
    ski, f, xf, y = _data(DESIGNS["stiff"], 4e-3, 3e-6, seed)
    f0, xf0, y0 = _with_unloaded(ski, f, xf, y, seed + 1)
    return ski, identify.identify_beam(ski.positions_m, f0, xf0, y0, **NO_VARIANTS)


def test_several_starts_are_checked_run_and_reported():
    """identify_beam with an unloaded case: two starts (projection, uniform from the unloaded
    profile), each checked on the device model and reported; every (start, path) fit is a
    candidate; the lowest objective is kept; how far apart the converged candidates are is
    reported (misfits, objectives, max |Δc| and |Δ log EI| in the middle of the ski)."""
    _ski, ident = _with_unloaded_identified()
    assert ident.ok, ident.reason
    assert ident.extra["unloaded_cases"] == 1
    starts = {s["start"]: s for s in ident.extra["starts"]}
    assert set(starts) == {"projection", "uniform"}
    assert "unloaded profile" in starts["uniform"]["note"]
    assert all(np.isfinite(s["device_misfit_m"]) for s in starts.values())
    cands = ident.extra["forward_candidates"]
    assert {c["start"] for c in cands} == {"projection", "uniform"}
    kept = min((c for c in cands if c["converged"]), key=lambda c: c["objective"])
    assert ident.misfit_m == pytest.approx(kept["misfit_m"], rel=1e-12)
    assert kept["max_dc_middle_m"] == 0.0 and kept["max_dlog_ei_middle"] == 0.0
    spread = ident.extra["candidate_spread"]
    assert spread["converged"] >= 2
    assert spread["misfit_min_m"] == pytest.approx(ident.misfit_m, rel=1e-12)
    assert spread["objective_range"] >= 0 and spread["max_dc_middle_m"] >= 0
    assert spread["max_dlog_ei_middle"] == max(
        c["max_dlog_ei_middle"] for c in cands if c["converged"]
    )
    # the unloaded case is fitted like the others: its residual is at the noise
    assert ident.case_misfit_m[0] < 1.5 * ident.noise_m
    # what the several starts cost (the bench's columns): starts and fits counted, wall times
    # split between the forward fits (here one after the other: at least their own times) and
    # the rest
    assert ident.extra["starts_run"] == len({(c["start"], c["start_smoothing"]) for c in cands})
    assert ident.extra["forward_fits"] == len(cands)
    assert ident.extra["wall_forward_s"] >= sum(c["time_s"] for c in cands)
    assert ident.extra["wall_starts_s"] > 0
    assert ident.extra["wall_forward_s"] + ident.extra["wall_starts_s"] == pytest.approx(
        ident.solve_time_s, rel=1e-9
    )


def test_a_start_whose_device_model_misses_by_far_is_not_used(monkeypatch):
    """A projection start that fits its own model but whose beam, solved on the device model,
    misses the cases by far (constructed: its EI × 1000, the failure #26 measured: 1221 µm)
    is not used; the reason is recorded and the fit comes from the other start."""
    real = identify.identify_start

    def stiff_start(*args, **kwargs):
        out = real(*args, **kwargs)
        b = out.beam
        out.beam = identify.BeamSki(b.positions_m, 1e3 * b.bending_stiffness_nm2, b.unloaded_gap_m)
        return out

    monkeypatch.setattr(identify, "identify_start", stiff_start)
    ski, f, xf, y = _data(DESIGNS["stiff"], 4e-3, 3e-6, 5)
    f0, xf0, y0 = _with_unloaded(ski, f, xf, y, 6)
    ident = identify.identify_beam(ski.positions_m, f0, xf0, y0, max_steps=5, **NO_VARIANTS)
    proj = [s for s in ident.extra["starts"] if s["start"] == "projection"]
    assert proj and not any(s["used"] for s in proj)
    assert "device model" in proj[0]["note"] and "not used" in proj[0]["note"]
    assert proj[0]["device_misfit_m"] > 100 * ident.noise_m
    # every fit from the uniform start (and, its fits above the noise in 5 steps, the tapered
    # start on demand), none from the projection start
    used = {c["start"] for c in ident.extra["forward_candidates"]}
    assert "uniform" in used and used <= {"uniform", "tapered"}


def test_a_variant_whose_projection_start_misses_starts_from_the_uniform_start(monkeypatch):
    """The 33 mm variant's projection start made to miss by far on the device model (its EI
    × 1000, as in the test above; random-31 9 × 5 measured both variant starts 33 µm off):
    the variant is not left out, its fits start from the uniform-EI start with the variant's
    knots, reported as such; with the fallback off it is left out, as before."""
    real = identify.identify_start

    def variant_misses(*args, knot_spacing_m, **kwargs):
        out = real(*args, knot_spacing_m=knot_spacing_m, **kwargs)
        if knot_spacing_m != identify.DEFAULT_KNOT_SPACING_M:
            b = out.beam
            ei = 1e3 * b.bending_stiffness_nm2
            out.beam = identify.BeamSki(b.positions_m, ei, b.unloaded_gap_m)
        return out

    monkeypatch.setattr(identify, "identify_start", variant_misses)
    run = _quick_identification("soft", 1)
    got = run(demand_variant_knot_spacings_m=())
    (vs,) = got.extra["variant_starts"]
    assert vs["start"] == "uniform, knots 33 mm" and vs["used"]
    assert "projection start with these knots is not used" in vs["note"]
    assert "device model misses" in vs["note"] and "uniform-EI start" in vs["note"]
    uniform = [s for s in got.extra["starts"] if s["start"] == "uniform"]
    assert vs["device_misfit_m"] == uniform[0]["device_misfit_m"]
    rows = got.extra["variant_candidates"]
    assert rows and {r["start"] for r in rows} == {"uniform, knots 33 mm"}
    assert all(r["start_smoothing"] is None for r in rows)
    assert all(np.isfinite(r["misfit_m"]) for r in rows)
    monkeypatch.setattr(identify, "UNIFORM_VARIANT_FALLBACK", False)
    off = run(demand_variant_knot_spacings_m=())
    (vs_off,) = off.extra["variant_starts"]
    assert vs_off["start"] == "projection, knots 33 mm" and not vs_off["used"]
    assert "variant not used" in vs_off["note"] and off.extra["variant_candidates"] == []


def test_stiffness_taper_is_one_in_the_middle_and_the_end_ratio_at_the_ends():
    x = np.linspace(-0.9, 1.1, 201)
    np.testing.assert_array_equal(identify.stiffness_taper(x, 1.0), np.ones(x.size))
    t = identify.stiffness_taper(x, 0.2)
    assert t[0] == pytest.approx(0.2) and t[-1] == pytest.approx(0.2)
    assert t[100] == pytest.approx(1.0) and t.max() == pytest.approx(1.0)
    assert np.all(np.diff(t[:101]) > 0) and np.all(np.diff(t[100:]) < 0)


def test_a_tapered_start_fits_a_ski_with_soft_ends_better_than_one_ei():
    """'stiff' (EI at the ends 0.2 × the middle's): the tapered start of end ratio 0.2 misses
    the cases on the device model by less than the uniform start (measured 14.9 against
    19.9 µm), and the tapered start at ratio 1 is the uniform start itself."""
    ski, f, xf, y = _data(DESIGNS["stiff"], 4e-3, 3e-6, 5)
    f0, xf0, y0 = _with_unloaded(ski, f, xf, y, 6)
    x = ski.positions_m
    misses = {}
    for r in (1.0, 0.2):
        beam = identify._uniform_stiffness_start(x, f0, xf0, y0, y0[0], end_ratio=r)
        misses[r] = identify._device_misfit(beam, f0, xf0, y0)
    assert misses[0.2] < 0.8 * misses[1.0], misses
    same = identify._uniform_stiffness_start(x, f0, xf0, y0, y0[0])
    one = identify._uniform_stiffness_start(x, f0, xf0, y0, y0[0], end_ratio=1.0)
    np.testing.assert_array_equal(same.bending_stiffness_nm2, one.bending_stiffness_nm2)


def test_the_tapered_start_runs_only_when_the_fits_stay_above_the_noise(monkeypatch):
    """On demand: a fit at the noise never runs it ('soft', seed 1, the identification of the
    variant tests); with every fit counted above the noise (the threshold made negative; no
    restarts, no variants on demand) it runs after the other starts, on every path, reported
    with its end ratio, and the kept fit is the lowest objective of all; off with ()."""
    _ski, at_noise = _identified("soft", 4e-3, 3e-6, 1, variants=True)
    assert "tapered" not in {s["start"] for s in at_noise.extra["starts"]}
    monkeypatch.setattr(identify, "RESTART_SIGMAS", -1e9)
    monkeypatch.setattr(identify, "RESTART_SMOOTHING_FACTORS", ())
    run = _quick_identification("stiff", 5)
    got = run(**NO_VARIANTS)
    (entry,) = [s for s in got.extra["starts"] if s["start"] == "tapered"]
    assert entry["used"] and "on demand" in entry["note"]
    assert any(f"× {r:g} at the ends" in entry["note"] for r in identify.TAPERED_START_END_RATIOS)
    rows = got.extra["forward_candidates"]
    assert [r["start"] for r in rows].count("tapered") == 1  # one path in the quick run
    assert rows[-1]["start"] == "tapered"
    finite = [r for r in rows if np.isfinite(r["objective"])]
    kept = min(finite, key=lambda r: (not r["converged"], r["objective"]))
    assert got.extra["start"] == kept["start"] and got.misfit_m == kept["misfit_m"]
    monkeypatch.setattr(identify, "TAPERED_START_END_RATIOS", ())
    off = run(**NO_VARIANTS)
    assert "tapered" not in {s["start"] for s in off.extra["starts"]}
    assert "tapered" not in {r["start"] for r in off.extra["forward_candidates"]}


def test_failure_names_its_cause(monkeypatch):
    """Honest failure (#26): with one start only, a fit above the limit is 'no start reached
    the forward fit's basin', never 'not one beam'; 'not one beam' needs fits from several
    starts all above the limit (forced here by a limit below the noise)."""
    monkeypatch.setattr(identify, "MISFIT_LIMIT", 0.5)
    ski, f, xf, y = _data(DESIGNS["stiff"], 4e-3, 3e-6, 5)
    f0, xf0, y0 = _with_unloaded(ski, f, xf, y, 6)
    one = identify.identify_beam(
        ski.positions_m,
        f0,
        xf0,
        y0,
        starts=("projection",),
        start_smoothing=100.0,
        max_steps=8,
        **NO_VARIANTS,
    )
    assert not one.ok
    assert "no start reached the forward fit's basin" in one.reason
    assert "not explained by one beam" not in one.reason
    several = identify.identify_beam(ski.positions_m, f0, xf0, y0, max_steps=8, **NO_VARIANTS)
    assert not several.ok
    conv = {(c["start"], c["start_smoothing"]) for c in several.extra["forward_candidates"]}
    if len(conv) >= 2 and all(c["converged"] for c in several.extra["forward_candidates"]):
        assert "not explained by one beam" in several.reason
        assert "different starts" in several.reason
    else:
        assert "no start reached" in several.reason or "did not converge" in several.reason


def test_the_unloaded_case_is_never_held_out():
    """identify_beam_checked draws the held-out cases among the loaded ones; without an
    unloaded case the draw is the one it always was (stored identifications keep theirs)."""
    n = 30
    for seed in range(5):
        f = np.r_[0.0, np.linspace(100, 800, n - 1)]
        held = _held_index(f, seed)
        assert 0 not in held and len(held) == round(0.2 * (n - 1))
    f = np.linspace(100, 800, n)
    assert _held_index(f, 3) == sorted(
        np.random.default_rng(3).choice(n, round(0.2 * n), replace=False).tolist()
    )


def _held_index(f, seed):
    """The held-out indices identify_beam_checked draws (the identification itself stubbed)."""
    import unittest.mock

    def fake(x, loads, xfs, y, **kw):
        return unittest.mock.Mock(ok=False, reason="stub")

    with unittest.mock.patch.object(identify, "identify_beam", fake):
        _, check = identify.identify_beam_checked(
            np.linspace(0, 1, 50), f, np.zeros(f.size), np.zeros((f.size, 50)), seed=seed
        )
    return check["held_out_index"]


# ----------------------------------------------------------------- #26: alternative beams


def _fit(beam, misfit_m, objective, converged=True):
    from types import SimpleNamespace

    return SimpleNamespace(beam=beam, misfit_m=misfit_m, objective=objective, converged=converged)


def test_alternative_fits_keeps_close_different_converged_fits():
    """alternative_fits: converged fits within ALTERNATIVE_MISFIT_RANGE of the chosen misfit
    that are other beams (middle of the ski), lowest objective first, no two alike, at most
    ALTERNATIVES_MAX; not the chosen fit, a non-converged one, one too far off, or a copy."""
    ski = DESIGNS["stiff"].build(4e-3)
    x = ski.positions_m
    r = identify.ALTERNATIVE_MISFIT_RANGE

    def scaled(k):
        return type(ski)(x, k * ski.bending_stiffness_nm2, ski.unloaded_gap_m)

    def shifted(dc_m):
        return type(ski)(x, ski.bending_stiffness_nm2, ski.unloaded_gap_m + dc_m)

    chosen = _fit(ski, 3e-6, 100.0)
    fits = [
        chosen,
        _fit(scaled(1.0 + 0.5 * identify.ALTERNATIVE_MIN_DLOG_EI), 3.01e-6, 100.5),  # too alike
        _fit(scaled(1.3), 3e-6 * (1 + 0.5 * r), 102.0),  # kept, second
        _fit(shifted(3 * identify.ALTERNATIVE_MIN_DC_M), 3e-6 * (1 + 0.2 * r), 101.0),  # first
        _fit(scaled(1.3 * 1.001), 3e-6 * (1 + 0.6 * r), 102.5),  # a copy of the kept 1.3
        _fit(scaled(0.7), 3e-6 * (1 + 2 * r), 103.0),  # too far off in misfit
        _fit(scaled(0.6), 3e-6, 99.0, converged=False),  # not converged
        _fit(scaled(0.8), float("nan"), float("nan")),
    ]
    assert identify.alternative_fits(chosen, fits) == [3, 2]
    many = [chosen] + [_fit(scaled(1.1 + 0.1 * k), 3e-6, 100.0 + k) for k in range(6)]
    kept = identify.alternative_fits(chosen, many)
    assert kept == list(range(1, identify.ALTERNATIVES_MAX + 1))
    # the variant starts' slot: its own count, and distinct from the beams already kept (the
    # main alternatives), which it does not displace
    kept_beams = tuple(fits[i].beam for i in (3, 2))
    variants = [
        _fit(scaled(1.3 * 1.001), 3e-6, 90.0),  # like a kept main alternative: not again
        _fit(scaled(1.6), 3e-6 * (1 + 0.5 * r), 95.0),
        _fit(scaled(1.9), 3e-6 * (1 + 0.5 * r), 96.0),
        _fit(scaled(2.2), 3e-6 * (1 + 0.5 * r), 97.0),
    ]
    got = identify.alternative_fits(chosen, variants, kept=kept_beams, max_count=2)
    assert got == [1, 2]
    # a tighter misfit range of their own (VARIANT_MISFIT_RANGE): the fits 1 % above are out
    tight = identify.alternative_fits(
        chosen, variants, kept=kept_beams, max_count=2, misfit_range=0.2 * r
    )
    assert tight == []


def test_variant_choice_only_when_the_main_fits_stay_above_the_noise():
    """variant_choice: a variant fit replaces the main ones only when they stay above the noise
    threshold and it reaches it; of those the lowest misfit, converged and finite only. Misfits
    in units of the noise (σ = 1)."""
    beam = DESIGNS["stiff"].build(4e-3)
    at = 1.005
    fits = [
        _fit(beam, 1.004, 10.0),
        _fit(beam, 0.990, 50.0),  # the lowest misfit at the noise, though not the lowest objective
        _fit(beam, 0.980, 1.0, converged=False),
        _fit(beam, float("nan"), float("nan")),
        _fit(beam, 1.2, 0.5),
    ]
    assert identify.variant_choice(1.27, fits, at) == 1
    # the main fit at the noise: it stays, whatever the variants reach
    assert identify.variant_choice(1.005, fits, at) is None
    assert identify.variant_choice(0.999, fits, at) is None
    assert identify.variant_choice(float("nan"), fits, at) is None
    # no variant at the noise: the main fit stays (a variant better but above the noise too)
    assert identify.variant_choice(1.27, [fits[4], _fit(beam, 1.1, 1.0)], at) is None
    # just above the threshold, a variant just at it: chosen (random-26 9 × 5: 1.0115 × and
    # 1.0076 × against 1.0078 ×); one just above it: not
    assert identify.variant_choice(1.0051, [_fit(beam, 1.005, 1.0)], at) == 0
    assert identify.variant_choice(1.0051, [_fit(beam, 1.00501, 1.0)], at) is None
    assert identify.variant_choice(1.27, [], at) is None


def test_identification_reports_its_alternative_beams():
    """identify_beam keeps the alternative beams alternative_fits picks among its converged
    forward candidates (extra['alternatives'] indexes forward_candidates), each a beam on the
    same nodes whose candidate misfit is within the range of the chosen one. On 'soft' (seed
    1) the second start ends 0.14 % above the chosen fit's misfit in another beam."""
    _ski, ident = _identified("soft", 4e-3, 3e-6, 1, variants=True)
    idx = ident.extra["alternatives"]
    v_idx = ident.extra["variant_alternatives"]
    assert len(idx) >= 1
    assert len(idx) <= identify.ALTERNATIVES_MAX
    assert len(v_idx) <= identify.VARIANT_ALTERNATIVES_MAX
    assert len(ident.alternative_beams) == len(idx) + len(v_idx)
    cands = [ident.extra["forward_candidates"][i] for i in idx]
    cands += [ident.extra["variant_candidates"][i] for i in v_idx]
    for c in cands:
        assert c["converged"]
        assert c["misfit_m"] <= (1 + identify.ALTERNATIVE_MISFIT_RANGE) * ident.misfit_m
    for b in ident.alternative_beams:
        np.testing.assert_array_equal(b.positions_m, ident.beam.positions_m)
        assert not np.array_equal(b.bending_stiffness_nm2, ident.beam.bending_stiffness_nm2)


def test_variant_starts_are_alternatives_only(monkeypatch):
    """The variant starts (the projection start with other stiffness knots) run their own
    forward fits, reported apart (variant_starts, variant_candidates); where the main fit
    reaches the noise they never change the chosen beam or the main candidates (the same
    identification without them is bitwise the same; variant_choice otherwise). On 'soft'
    (seed 1, 4 mm) the variant's best fit ends 1.7 % above the chosen misfit in another beam:
    outside VARIANT_MISFIT_RANGE, so not an alternative; with the range widened to 2 % it is
    one, after the main alternatives."""
    ski, f, xf, y = _data(DESIGNS["soft"], 4e-3, 3e-6, 1)
    _ski, with_v = _identified("soft", 4e-3, 3e-6, 1, variants=True)
    at_noise = (1.0 + identify.RESTART_SIGMAS / np.sqrt(2.0 * y.size)) * with_v.noise_m
    assert with_v.misfit_m <= at_noise and with_v.extra["variant_chosen"] is None
    without = identify.identify_beam(ski.positions_m, f, xf, y, variant_knot_spacings_m=())
    np.testing.assert_array_equal(
        with_v.beam.bending_stiffness_nm2, without.beam.bending_stiffness_nm2
    )
    np.testing.assert_array_equal(with_v.beam.unloaded_gap_m, without.beam.unloaded_gap_m)

    def timeless(cands):
        return [{k: v for k, v in c.items() if k != "time_s"} for c in cands]

    assert timeless(with_v.extra["forward_candidates"]) == timeless(
        without.extra["forward_candidates"]
    )
    assert without.extra["variant_candidates"] == [] and without.extra["variant_starts"] == []
    starts = with_v.extra["variant_starts"]
    assert [s["start"] for s in starts] == [
        f"projection, knots {v * 1e3:g} mm" for v in identify.VARIANT_KNOT_SPACINGS_M
    ]
    assert all(s["used"] for s in starts)
    # every used variant start runs on every path, with its knots (another parameter count)
    vc = with_v.extra["variant_candidates"]
    paths = {c["coarse_spacing_m"] for c in with_v.extra["forward_candidates"]}
    assert len(vc) == len(starts) * len(paths)
    assert {c["coarse_spacing_m"] for c in vc} == paths
    assert all(c["converged"] for c in vc)
    best = min(c["misfit_m"] for c in vc) / with_v.misfit_m - 1
    assert identify.VARIANT_MISFIT_RANGE < best < identify.ALTERNATIVE_MISFIT_RANGE
    assert with_v.extra["variant_alternatives"] == []
    assert len(with_v.alternative_beams) == len(with_v.extra["alternatives"])
    # the range widened: the variant fit becomes an alternative beam, after the main ones
    monkeypatch.setattr(identify, "VARIANT_MISFIT_RANGE", identify.ALTERNATIVE_MISFIT_RANGE)
    wide = identify.identify_beam(ski.positions_m, f, xf, y)
    v_idx = wide.extra["variant_alternatives"]
    assert v_idx and wide.extra["alternatives"] == with_v.extra["alternatives"]
    assert len(wide.alternative_beams) == len(wide.extra["alternatives"]) + len(v_idx)
    for i in v_idx:
        c = wide.extra["variant_candidates"][i]
        assert c["misfit_m"] <= (1 + identify.ALTERNATIVE_MISFIT_RANGE) * wide.misfit_m
        assert (
            c["max_dc_middle_m"] > identify.ALTERNATIVE_MIN_DC_M
            or c["max_dlog_ei_middle"] > identify.ALTERNATIVE_MIN_DLOG_EI
        )
    for a, b in zip(with_v.alternative_beams, wide.alternative_beams, strict=False):
        np.testing.assert_array_equal(a.bending_stiffness_nm2, b.bending_stiffness_nm2)


def _quick_identification(name: str, seed: int):
    """identify_beam on a design's 12 cases (every other load and position, 4 mm, 3 µm noise,
    ``seed``), 3 forward steps on one path: a quick run; keyword arguments go on to it."""
    ski = DESIGNS[name].build(4e-3)
    f, xf, y = measure_camber(ski, LOADS_N[::2], POSITIONS_M[::2], noise_m=3e-6, rng=seed)
    return functools.partial(
        identify.identify_beam,
        ski.positions_m,
        f,
        xf,
        y,
        max_steps=3,
        forward_coarse_spacings_m=(0.0,),
    )


def test_a_variant_at_the_noise_is_chosen_when_the_main_fits_stay_above(monkeypatch):
    """'soft', 12 cases, seed 1: the main fit ends at 0.99 × the noise and the 33 mm variant's
    at 1.002 ×. With every fit on the main and on the 33 mm knots made to miss by 1.3 ×
    (fit_forward wrapped; no restarts), the main fits converge above the noise and no variant
    reaches it: a 25 mm variant start asked for on demand (``demand_variant_knot_spacings_m``,
    off by default) runs and its fit is chosen (variant_choice):
    its beam, its knots and covariance through to the bands and the draws, ok, the choice
    reported. This checks the wiring; the cases it is for are measured in the own-ski study
    (random-23 13 × 9: main fits 1.27 ×, 33 mm variant 0.9945 ×; random-19 9 × 5: main 1.013 ×,
    33 mm variant 1.021 ×, 25 mm variant 1.0008 ×)."""
    run = _quick_identification("soft", 1)
    x = run.args[0]
    knots = {s: identify.stiffness_knots(x, s) for s in (0.05, 0.033, 0.025)}
    assert identify.DEFAULT_KNOT_SPACING_M == 0.05
    assert identify.VARIANT_KNOT_SPACINGS_M == (0.033,)
    fit_forward = identify.fit_forward

    def fits_miss(*args, stiffness_knots_m, **kwargs):
        fit = fit_forward(*args, stiffness_knots_m=stiffness_knots_m, **kwargs)
        if any(np.array_equal(stiffness_knots_m, knots[s]) for s in (0.05, 0.033)):
            fit = dataclasses.replace(fit, misfit_m=1.3 * fit.misfit_m)
        return fit

    monkeypatch.setattr(identify, "fit_forward", fits_miss)
    monkeypatch.setattr(identify, "RESTART_SMOOTHING_FACTORS", ())
    got = run(max_steps=80, demand_variant_knot_spacings_m=(0.025,))
    k = got.extra["variant_chosen"]
    assert k is not None and got.ok, got.reason
    starts = got.extra["variant_starts"]
    assert [s["start"] for s in starts] == ["projection, knots 33 mm", "projection, knots 25 mm"]
    assert "on demand" in starts[1]["note"] and "variant chosen" in starts[1]["note"]
    rows = got.extra["variant_candidates"]
    assert [r["start"] for r in rows] == ["projection, knots 33 mm", "projection, knots 25 mm"]
    row = rows[k]
    assert row["start"] == got.extra["start"] == "projection, knots 25 mm"
    assert row["converged"] and got.misfit_m == row["misfit_m"]
    assert rows[0]["misfit_m"] > 1.25 * got.noise_m
    assert got.extra["main_misfit_m"] > 1.25 * got.noise_m > got.misfit_m
    assert row["max_dc_middle_m"] == 0.0 and row["max_dlog_ei_middle"] == 0.0
    # the variant's knots throughout: compliance, covariance, data share, bands, draws
    m = knots[0.025].size
    np.testing.assert_array_equal(got.knots_m, knots[0.025])
    assert got.log_compliance.shape == (m,)
    assert got.log_compliance_covariance.shape == (m, m)
    assert got.camber_sensitivity.shape == (x.size, m)
    assert len(got.extra["stiffness_data_share"]) == m
    lo, hi = got.stiffness_band_nm2
    assert lo.shape == hi.shape == x.shape and np.all(lo < hi)
    for b in identify.sample_beams(got, 4, 3):
        assert np.all(b.bending_stiffness_nm2 > 0) and np.all(np.isfinite(b.unloaded_gap_m))


def test_variant_starts_run_beside_the_start_in_the_pool():
    """With a pool, the start and the variant starts run side by side in the workers (one
    BLAS thread each): the same starts and fits as in this process at one BLAS thread, to
    rounding (at another thread count a start moves by ~1e-5 relative: rounding)."""
    from skisnow.app.path_pool import fixed_blas_threads, path_pool

    run = _quick_identification("stiff", 5)
    with fixed_blas_threads():
        here = run()
    with path_pool(2) as pmap:
        pooled = run(path_map=pmap)
    assert len(here.extra["starts"]) >= 2
    assert len(here.extra["variant_starts"]) == len(identify.VARIANT_KNOT_SPACINGS_M)
    for key in ("starts", "variant_starts"):
        a, b = here.extra[key], pooled.extra[key]
        assert [s["start"] for s in a] == [s["start"] for s in b]
        for sa, sb in zip(a, b, strict=True):
            assert sa["device_misfit_m"] == pytest.approx(sb["device_misfit_m"], rel=1e-6)
    for a, b in zip(
        here.extra["variant_candidates"], pooled.extra["variant_candidates"], strict=True
    ):
        assert a["objective"] == pytest.approx(b["objective"], rel=1e-6)


def test_covariance_root_holds_parameters_of_very_different_scales():
    """A joint covariance of camber coefficients [m] (variances ~1e-13 m²) and log-compliances
    (~1): the root reproduces every covariance to rounding relative to its own scale; the
    eigen-decomposition of the covariance itself misses the small block's by percent."""
    rng = np.random.default_rng(5)
    a = rng.standard_normal((8, 8))
    corr = a @ a.T + 0.5 * np.eye(8)
    scale = np.array([3e-7] * 5 + [1.0, 0.5, 2.0])
    cov = corr * np.outer(scale, scale)
    root = identify._covariance_root(cov)
    rel = np.abs(root @ root.T - cov) / np.outer(scale, scale)
    assert rel.max() < 1e-10
    vals, vecs = np.linalg.eigh(cov)
    plain = vecs * np.sqrt(np.maximum(vals, 0.0))
    assert (np.abs(plain @ plain.T - cov) / np.outer(scale, scale)).max() > 1e-6


def test_variant_refit_jobs_place_their_knots():
    """identify_beam's ``variant_refit_knot_spacings_m`` jobs: the variant start's beam, new
    stiffness knots evenly over the nodes (as identify_start places them), a label naming both
    spacings; a spacing that is not finite and > 0 is refused."""
    x = np.linspace(-1.0, 1.0, 501)
    beam = DESIGNS["stiff"].build(4e-3)
    jobs = identify.variant_refit_jobs(x, 0.033, 7.0, beam, (0.025, 0.5, 5.0))
    assert [j[0] for j in jobs] == [
        f"forward from the 33 mm variant start, knots {s:g} mm" for s in (25, 500, 5000)
    ]
    for (_, sm, b, knots), n in zip(jobs, (81, 5, 3), strict=True):
        assert sm == 7.0 and b is beam
        np.testing.assert_allclose(knots, np.linspace(-1.0, 1.0, n))
    assert identify.variant_refit_jobs(x, 0.033, 7.0, beam, ()) == []
    for bad in (0.0, -0.01, float("nan")):
        with pytest.raises(InputError, match="refit knot spacings"):
            identify.variant_refit_jobs(x, 0.033, 7.0, beam, (bad,))


def test_variant_refits_run_as_variant_candidates_only():
    """With ``variant_refit_knot_spacings_m`` each used variant start is also fitted forward on
    the new knots, on every path; those fits are variant candidates (never the chosen beam: it
    and the main candidates are bitwise those of the run without them). 'soft', 12 cases, seed
    1: its variant start is used."""
    run = _quick_identification("soft", 1)
    plain = run()
    refit = run(variant_refit_knot_spacings_m=(0.025,))
    np.testing.assert_array_equal(
        refit.beam.bending_stiffness_nm2, plain.beam.bending_stiffness_nm2
    )
    np.testing.assert_array_equal(refit.beam.unloaded_gap_m, plain.beam.unloaded_gap_m)
    assert [c["objective"] for c in refit.extra["forward_candidates"]] == [
        c["objective"] for c in plain.extra["forward_candidates"]
    ]
    used = [s for s in refit.extra["variant_starts"] if s["used"]]
    assert used
    labels = [c["start"] for c in refit.extra["variant_candidates"]]
    want = [
        f"forward from the {v * 1e3:g} mm variant start, knots 25 mm"
        for v in identify.VARIANT_KNOT_SPACINGS_M
    ]
    assert [x for x in labels if x.startswith("forward from")] == want[: len(used)]
    assert len(labels) == 2 * len(plain.extra["variant_candidates"])


#: the shipped default, before the module's fixture sets the model on the data's nodes
_SHIPPED_MODEL_SPACING_M = identify.DEFAULT_MODEL_SPACING_M


def test_sparse_samples_are_identified_on_a_finer_model_grid(monkeypatch):
    """Samples every 5 mm of a device that touches the ski anywhere (the virtual device on
    1 mm nodes), the unloaded profile and 9 × 5 cases, identified as the ski job does (held-out
    check, shipped defaults): the beam comes on 1 mm nodes with the samples among them, and it
    predicts unseen loaded profiles near contact far better than a beam on the samples' nodes.
    Measured: 0.61 µm against 1.53 µm (13 s against 10 s)."""
    monkeypatch.setattr(identify, "DEFAULT_MODEL_SPACING_M", _SHIPPED_MODEL_SPACING_M)
    truth = DESIGNS["stiff"].build(1e-3)
    f, xf, y = measure_camber(
        truth, np.linspace(10, 90, 9) * 9.82, np.linspace(-0.30, 0.10, 5), noise_m=3e-6, rng=9
    )
    y0 = measure_unloaded(truth, noise_m=3e-6, rng=10)
    f, xf, y = np.r_[0.0, f], np.r_[0.0, xf], np.vstack([y0, y])[:, ::5]
    x = truth.positions_m[::5]
    rng = np.random.default_rng(3)
    hf, hx = rng.uniform(15, 85, 12) * 9.82, rng.uniform(-0.28, 0.08, 12)
    exact = identify.predict_gaps(truth, hf, hx)
    near = exact < 2e-4
    errors = {}
    for spacing in (None, 0.0):
        ident, check = identify.identify_beam_checked(
            x, f, xf, y, model_spacing_m=spacing, **NO_VARIANTS
        )
        assert ident.ok, ident.reason
        assert check["held_out_rms_m"] < 1.3 * ident.noise_m  # read at the samples' nodes
        pred = identify.predict_gaps(ident.beam, hf, hx, truth.positions_m)
        errors[spacing] = float(np.sqrt(np.mean((pred - exact)[near] ** 2)))
        if spacing is None:
            xb = ident.beam.positions_m
            assert xb.size == (x.size - 1) * 5 + 1 and np.array_equal(xb[::5], x)
            assert ident.extra["model_spacing_m"] == pytest.approx(1e-3)
            assert ident.camber_sd_m.shape == xb.shape
    assert errors[None] < 0.9e-6
    assert errors[None] < 0.6 * errors[0.0]
