"""Plausible answers for the error band of one contact answer (:mod:`app.service.band`):
the camber model's error along the ski (:func:`camber_sigma_m`), the answer solved again with
smooth profile perturbations of that size (rigid shape, :func:`sample_profiles`) or with
plausible beams drawn from the identification's covariance (bending ski, :func:`beam_models`),
and the spread of every quantity about the nominal answer.
"""

from __future__ import annotations

import hashlib
import math
import threading
from dataclasses import dataclass

import numpy as np
from skisnow.app.presets import Preset
from skisnow.app.service import band_calibration
from skisnow.app.service.profiles import served_beam
from skisnow.app.storage.skis import identification_for_sampling, identified_alternatives
from skisnow.solvers.band import (
    Z90,
    model_error_sigma,
    position_error_sigma,
    unit_perturbations,
)
from skisnow.solvers.beam import BeamFlexibility, solve_beam_contact
from skisnow.solvers.errors import InputError, SkisnowError
from skisnow.solvers.flexible import FlexibleModel, prepare_flexible, solve_flexible
from skisnow.solvers.identify import draw_beam_deviations, estimate_noise
from skisnow.solvers.lookup import MicroTable
from skisnow.solvers.macro import ProfileExtruder, solve_macro
from skisnow.solvers.multiscale import multiscale

#: reported quantities with a band (relative half-widths keyed by these names)
QUANTITIES = (
    "apparent_contact_area",
    "total_real_contact_area",
    "average_real_contact_pressure",
    "min_average_separation",
    "total_reciprocal_separation",
)
#: perturbed solves per answer (antithetic pairs); 8 recover the spread to ~25 % (1/√(2·8))
PROFILE_SAMPLES = 8
#: correlation length of the camber model's error [m]: the network's actual error against the
#: beam truth on the demo skis decorrelates over 20–80 mm (autocorrelation 0.49 at 20 mm and
#: 0.31 at 80 mm for ski-a, 0.13 at 20 mm for ski-b)
PROFILE_CORRELATION_M = 0.03
#: solver tolerance of the perturbed solves: their quantities move by ≤ 2e-6 (relative) against
#: the default 1e-8 in the cases measured then, and they cost about 25 % less. Not a bound: where
#: a zone edge's row of a few pixels carries a few Pa, the bending ski's apparent area at this
#: tolerance moved by up to 3.4e-3 (one of the scanned perturbed study beams;
#: docs/studies/flexible-convergence.md), well inside the band's widths
SAMPLE_TOL = 1e-6
#: the perturbations' seed: the same request always gets the same band
BAND_SEED = 12
#: the band of the loaded profile where the camber model is judged (as in training) [m]
CONTACT_BAND_M = 2e-4
#: an answer whose band is wider than this (relative half-width) carries a warning
WIDE_BAND = 0.10


#: moving window of the camber model's error along the ski [m] (:func:`camber_sigma_m`)
SIGMA_WINDOW_M = 0.1
_SIGMA_CACHE: dict[int, tuple[object, np.ndarray | float | None, str]] = {}


def camber_sigma_m(
    record, positions_m: np.ndarray, e_eff_pa: float | None = None
) -> tuple[np.ndarray | float | None, str]:
    """Standard deviation [m] of the ski's loaded-profile model error at ``positions_m`` and
    where it comes from; ``(0, …)`` for a ski answered by its design beam, ``(None, …)`` when
    unknown.

    For an identified beam (the profile model of :mod:`app.service.profiles` when its identification
    passed): the stored ``profile_sd_m``, the spread of the loaded profile over beams drawn
    from the identification's covariance (:func:`solvers.identify.profile_sigma`), × the
    factor at the answer's effective modulus ``e_eff_pa`` [Pa]
    (:func:`app.service.band_calibration.identified_sigma_scale_at`).

    For a camber network: its held-out (test split) profiles against the measured ones, inside
    the contact band H < 0.2 mm, as a moving RMS along the ski with the device noise removed
    (:func:`solvers.band.position_error_sigma`); the network's error is twice as large near the
    tip and tail as behind the binding, and light loads touch there."""
    ident = record.identified
    if served_beam(ident) is not None:
        sd = ident.get("profile_sd_m")
        if sd is None:
            return None, "the identified beam stores no profile spread"
        x = np.asarray(ident["positions_m"], dtype=float)
        sd = np.asarray(sd, dtype=float)
        # read at call time: a study varies the nodes
        scale = band_calibration.identified_sigma_scale_at(
            e_eff_pa, band_calibration.loaded_cases(record)
        )
        return scale * np.interp(np.asarray(positions_m, dtype=float), x, sd), (
            "identified beam: spread of the loaded profile over plausible beams drawn from the "
            f"fit's covariance where H < {CONTACT_BAND_M * 1e3:.1f} mm "
            f"({np.min(sd) * 1e6:.2f}–{np.max(sd) * 1e6:.2f} µm along the ski), × {scale:g} "
            "(the covariance understates the identified profile's error on designs the model "
            "does not fit exactly; calibrated on the own-ski study: "
            "app/service/band_calibration.py)"
        )
    net = record.network
    if net is None:
        if record.beam is not None:
            return 0.0, "design beam stored with the ski, taken as exact"
        return None, "the camber model's error is not known for this ski"
    hit = _SIGMA_CACHE.get(id(record))
    if hit is None or hit[0] is not record:
        hit = (record, *_network_sigma(record))
        _SIGMA_CACHE[id(record)] = hit
    sigma_nodes, source = hit[1], hit[2]
    if sigma_nodes is None:
        return None, source
    xs, ss = sigma_nodes
    scale = band_calibration.NETWORK_SIGMA_SCALE  # read at call time: the study varies it
    if scale != 1.0:
        source += (
            f", × {scale:g} (calibrated across 20–2000 MPa against true beams, "
            "app/service/band_calibration.py)"
        )
    return scale * np.interp(np.asarray(positions_m, dtype=float), xs, ss), source


def _network_sigma(record):
    from skisnow.solvers import camber

    net, meas = record.network, record.measurements
    f = np.asarray(net.get("split_test_loads_n", np.empty(0)), dtype=float)
    xf = np.asarray(net.get("split_test_load_positions_m", np.empty(0)), dtype=float)
    if f.size == 0:
        return None, "the camber network stores no held-out cases"
    mf = np.asarray(meas.loads_n, dtype=float)
    mx = np.asarray(meas.load_positions_m, dtype=float)
    profiles = np.asarray(meas.profiles_m, dtype=float)
    x = np.asarray(meas.positions_m, dtype=float)
    pred = camber.predict_profiles(net, f, xf)
    residuals = np.full((f.size, x.size), np.nan)
    for k in range(f.size):
        rows = np.flatnonzero(
            np.isclose(mf, f[k], rtol=1e-9, atol=1e-9) & np.isclose(mx, xf[k], atol=1e-9)
        )
        if rows.size == 0:
            continue
        measured = profiles[rows].mean(axis=0)
        model = np.interp(x, pred.positions_m, pred.gaps_m[k])
        residuals[k] = np.where(measured < CONTACT_BAND_M, model - measured, np.nan)
    noise = float(estimate_noise(profiles))
    if not np.isfinite(residuals).any():
        return None, "the camber network's held-out cases are not among the measurements"
    overall = model_error_sigma(float(np.sqrt(np.nanmean(residuals**2))), noise)
    sigma = position_error_sigma(x, residuals, noise, SIGMA_WINDOW_M, floor_m=overall / 2)
    return (x, sigma), (
        f"camber network: held-out profiles against the measured ones where H < "
        f"{CONTACT_BAND_M * 1e3:.1f} mm, device noise {noise * 1e6:.2f} µm removed → model error "
        f"{overall * 1e6:.2f} µm RMS ({np.min(sigma) * 1e6:.2f}–{np.max(sigma) * 1e6:.2f} µm "
        "along the ski)"
    )


def _quantities(macro, ms) -> dict[str, float]:
    return {
        "apparent_contact_area": ms.apparent_contact_area_m2,
        "total_real_contact_area": ms.total_real_contact_area_m2,
        "average_real_contact_pressure": ms.average_real_contact_pressure_pa,
        "min_average_separation": ms.min_average_separation_m,
        "total_reciprocal_separation": ms.total_reciprocal_separation_m,
    }


def _zone_loads(macro, zones) -> np.ndarray:
    """Load [N] of ``macro`` inside each of the nominal ``zones``: every loaded row belongs to
    the nearest zone (a perturbed answer may split or merge zones)."""
    if not zones:
        return np.zeros(0)
    x = macro.positions_m
    row_load = np.nansum(np.nan_to_num(macro.pressure_pa), axis=1) * float(
        np.prod(macro.pixel_size_m)
    )
    starts = np.array([z.start_m for z in zones])
    ends = np.array([z.end_m for z in zones])
    dist = np.maximum(starts[None, :] - x[:, None], 0) + np.maximum(x[:, None] - ends[None, :], 0)
    owner = np.argmin(dist, axis=1)
    return np.bincount(owner, weights=row_load, minlength=len(zones))


def _rel_half_width(nominal: float, values: np.ndarray) -> float:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 2 or not math.isfinite(nominal) or nominal == 0:
        return float("nan")
    return float(Z90 * np.sqrt(np.mean((v - nominal) ** 2)) / abs(nominal))


def coarse_grid(preset: Preset) -> tuple[float, int]:
    """The grid twice as coarse as ``preset`` in both directions: (pixel along [m], pixels
    across); the perturbed solves and the per-answer grid estimate run on it."""
    return 2 * preset.pixel_along_m, max(preset.pixels_across // 2, 2)


@dataclass
class _Sampled:
    widths: dict[str, float]  # camber model, relative 90 % half-widths
    zone_widths: list[float]
    line_half_width_pa: np.ndarray | None  # on the nominal answer's positions
    grid: dict[str, float]  # per-answer grid estimate |q − q_coarse| / |q|
    zone_grid: list[float]
    failed: int
    #: the spread under the flat-base regime's perturbations (:func:`_sample`), when asked
    flat: _Sampled | None = None
    #: the bending ski's alternative beams (:func:`alternative_models`): per quantity the
    #: largest relative deviation of their answers from the coarse nominal's [-]; None: none
    alternatives: dict[str, float] | None = None
    #: the same per zone load [-]
    alternative_zone_widths: list[float] | None = None
    #: alternatives solved (converged) and left out (not converged)
    alternatives_solved: int = 0
    alternatives_failed: int = 0


@dataclass(frozen=True)
class _Case:
    """One answer: the rigid loaded profile behind it, its grid, solves and texture."""

    positions_m: np.ndarray
    gap_m: np.ndarray
    outline: object
    preset: Preset
    macro: object
    ms: object
    table: MicroTable
    porosity: float
    e_eff: float


def _sample(
    case: _Case,
    sigma_m: float | np.ndarray,
    samples: int,
    seed: int,
    flat_sigma_m: np.ndarray | None = None,
    alternative_gaps_m: list[np.ndarray] | tuple = (),
) -> _Sampled | None:
    """Solve on the coarse grid (:func:`coarse_grid`) the nominal profile and ``samples``
    perturbed ones, and the loaded profiles of the identification's alternative beams
    (``alternative_gaps_m`` on ``case.positions_m``, :func:`alternative_profiles`). The coarse
    nominal against the answer gives the grid estimate (first-order convergence: the error of
    the answer's grid is the difference to a grid twice as coarse); the perturbed ones against
    the coarse nominal give the camber model's spread, the alternatives their largest deviation
    (``_Sampled.alternatives``).

    ``flat_sigma_m`` (per position; the flat-base regime, :mod:`app.service.band_calibration`):
    ``samples`` more solves with perturbations of that size (seed ``seed + 1``, independent of
    the camber model's), whose spread is returned as ``_Sampled.flat``."""
    positions_m, gap_m, outline, preset = case.positions_m, case.gap_m, case.outline, case.preset
    macro, ms, table, porosity, e_eff = case.macro, case.ms, case.table, case.porosity, case.e_eff
    dx, ny = coarse_grid(preset)

    extrude = ProfileExtruder(  # the coarse grid and footprint, set up once for all solves
        positions_m,
        outline.width_m,
        width_positions_m=outline.positions_m,
        pixel_along_m=dx,
        pixels_across=ny,
    )

    def solve(g, near, near_pressure_pa):
        gm = extrude(g)
        if near_pressure_pa is None:  # the answer's line pressure on the coarse rows
            line = np.interp(gm.positions_m, near.positions_m, np.nan_to_num(near.pressure_line_pa))
            near_pressure_pa = np.where(np.isfinite(gm.gap_m), line[:, None], 0.0)
        m = solve_macro(
            gm,
            macro.load_n,
            macro.load_position_m,
            e_eff,
            tol=SAMPLE_TOL,
            initial_pressure_pa=near_pressure_pa,
            initial_rigid_body=(near.approach_m, near.tilt_rad),
            window_gap_m=near.window_gap_m,
        )
        if not m.converged:
            return None
        return m, multiscale(m, table, porosity, e_eff)

    # every coarse solve starts near its answer: the nominal one from the answer itself (its
    # approach, tilt, window and line pressure; the window check still grows the window until
    # it holds, so only the path changes: 8.6 -> 2.9 ms, and the quantities move within the
    # solver tolerance SAMPLE_TOL), the perturbed ones from the coarse nominal
    try:
        base = solve(gap_m, macro, None)
    except SkisnowError:
        base = None
    if base is None:
        return None
    m0 = base[0]
    deltas = (
        _unit_fields(positions_m, samples, seed) * _nonnegative(sigma_m, positions_m)
        if np.any(np.asarray(sigma_m) > 0)
        else np.zeros((0, np.size(positions_m)))
    )

    def near(g):  # a profile solved from the coarse nominal; a rigid approach absorbs a constant
        return solve(g - min(float(np.nanmin(g)), 0.0), m0, m0.pressure_pa)

    perturbed, failed = _solve_each(near, [gap_m + d for d in deltas])
    out = _spread(macro, ms, base, perturbed, failed)
    if flat_sigma_m is not None and np.any(np.asarray(flat_sigma_m) > 0):
        fields = _unit_fields(positions_m, samples, seed + 1) * _nonnegative(
            flat_sigma_m, positions_m
        )
        flat, flat_failed = _solve_each(near, [gap_m + d for d in fields])
        out.flat = _spread(macro, ms, base, flat, flat_failed)
    alt, alt_failed = _solve_each(near, alternative_gaps_m)
    return _add_alternatives(out, ms, base, alt, alt_failed)


def _solve_each(solve, items) -> tuple[list, int]:
    """``solve(item)`` for each of ``items``: the results that converged (a solve that raises
    :class:`SkisnowError` or returns None did not) and how many did not."""
    done, failed = [], 0
    for item in items:
        try:
            r = solve(item)
        except SkisnowError:
            r = None
        if r is None:
            failed += 1
        else:
            done.append(r)
    return done, failed


def _add_alternatives(out: _Sampled, ms, base, alt: list, failed: int) -> _Sampled:
    """Store on ``out`` the largest relative deviation of the ``alt`` solves (pairs of macro and
    multiscale results of the alternative beams) from the coarse nominal ``base``, per quantity
    and per zone load, and how many were solved and left out."""
    out.alternatives_solved, out.alternatives_failed = len(alt), failed
    if not alt:
        return out
    q0 = _quantities(*base)
    z0 = _zone_loads(base[0], ms.zones)
    qa = [_quantities(*r) for r in alt]
    za = [_zone_loads(r[0], ms.zones) for r in alt]
    out.alternatives = {
        k: max(abs(q[k] / q0[k] - 1) for q in qa) if q0[k] else float("nan") for k in q0
    }
    out.alternative_zone_widths = [
        max(abs(z[i] / z0[i] - 1) for z in za) if z0[i] else float("nan") for i in range(z0.size)
    ]
    return out


def _spread(macro, ms, base, perturbed, failed: int) -> _Sampled:
    """The answer (``macro``, ``ms``) against its coarse nominal ``base`` (the grid estimate)
    and the ``perturbed`` coarse solves (pairs of macro and multiscale results) against that
    nominal (the camber model's spread)."""
    m0, s0 = base
    q_nom, q0 = _quantities(macro, ms), _quantities(m0, s0)
    z_nom, z0 = _zone_loads(macro, ms.zones), _zone_loads(m0, ms.zones)
    grid = {k: abs(q0[k] / q_nom[k] - 1) if q_nom[k] else float("nan") for k in q_nom}
    zone_grid = [abs(a / b - 1) if b else float("nan") for a, b in zip(z0, z_nom, strict=True)]
    qs: dict[str, list[float]] = {k: [] for k in q_nom}
    zs, lines = [], []
    for m, s in perturbed:
        for k, v in _quantities(m, s).items():
            qs[k].append(v)
        zs.append(_zone_loads(m, ms.zones))
        lines.append(np.nan_to_num(m.pressure_line_pa))
    widths = {k: _rel_half_width(q0[k], np.array(v)) for k, v in qs.items()}
    zone_w = [
        _rel_half_width(z0[i], np.array([z[i] for z in zs])) if zs else float("nan")
        for i in range(z0.size)
    ]
    line = None
    if len(lines) >= 2:
        half = Z90 * np.sqrt(
            np.mean((np.array(lines) - np.nan_to_num(m0.pressure_line_pa)) ** 2, 0)
        )
        line = np.interp(macro.positions_m, m0.positions_m, half)
    return _Sampled(widths, zone_w, line, grid, zone_grid, failed)


# ----------------------------------------------------------------------------- bending ski

#: plausible beams per answer of the bending ski: antithetic pairs of draws from the
#: identification's covariance (:func:`solvers.identify.sample_beams`). 4 calibrate as 8 do
#: (test cases 94.4 % inside at 1.19× the RMS error, against 94.8 % at 1.21×) at about half
#: the band's cost; 2 need a larger factor and cover the apparent area less (87.5 %)
#: (``scripts/flexible_band_study.py``; docs/limits.md, Error band)
BEAM_SAMPLES = 4
#: factor on the covariance's parameter deviations of those draws [-] for the flex sheet (its
#: profile draws and snow shares), which has no snow modulus, when the ski's measurement grid is
#: not known: the largest of the contact answers' factors per snow modulus and grid
#: (:data:`app.service.band_calibration.BEAM_SCALE_NODES`; a ski with measurements gets its
#: grid's, :func:`sheet_beam_scale`).
#: It was 16, the smallest of ``scripts/flexible_band_study.py``'s candidates whose camber part
#: alone covered 90 % of the demo skis' identification error, fitted on the covariance before
#: its cut-off was fixed (docs/limits.md, "The covariance's cut-off"): that covariance held
#: zero variance wherever only the smoothing prior set EI, and × 16 on the fixed one would
#: move the tips' EI by e^14
BEAM_SCALE = float(max(band_calibration.BEAM_SCALE_NODES))


def sheet_beam_scale(record) -> float:
    """The flex sheet's factor for the ski ``record`` [-]: the largest of the contact answers'
    factors at the ski's measurement grid (:func:`app.service.band_calibration.beam_scale_at`
    at each node modulus with its loaded cases); :data:`BEAM_SCALE` (every grid's largest)
    when its cases are not known."""
    from skisnow.solvers.elastic import effective_modulus

    cases = band_calibration.loaded_cases(record)
    if cases is None:
        return BEAM_SCALE
    return max(
        band_calibration.beam_scale_at(effective_modulus(e * 1e6, 700e6, 0.3), cases)
        for e in band_calibration.BEAM_SCALE_E_SNOW_MPA
    )


#: models of plausible beams kept per ski record (one entry per coarse grid and draw setting)
_BEAM_MODELS_MAX = 8
#: one build of plausible beam models at a time (concurrent first requests built one set each);
#: re-entrant, since a build reads the nominal model and the unit draws through ``_cached``
_BEAM_MODELS_LOCK = threading.RLock()


def _prepare(beam, outline, dx: float, ny: int, like: FlexibleModel | None = None) -> FlexibleModel:
    """The bending ski of ``beam`` on the grid (dx, ny); ``like``: a model of the same outline
    and grid whose snow parts it shares (:func:`solvers.flexible.prepare_flexible`)."""
    return prepare_flexible(
        beam,
        outline.width_m,
        pixel_along_m=dx,
        pixels_across=ny,
        width_positions_m=outline.positions_m,
        like=like,
    )


def beam_models(
    record, preset: Preset, *, samples: int, seed: int, scale: float
) -> tuple[FlexibleModel, list[FlexibleModel]] | None:
    """The bending ski on the grid twice as coarse as ``preset`` (:func:`coarse_grid`): the
    nominal model of the beam the ski answers with, and ``samples`` models of plausible beams
    drawn from its identification's covariance with deviations × ``scale`` (antithetic pairs,
    seeded: the same request always gets the same band); the second is empty for a design
    beam (taken as exact). None when the ski has no beam. Prepared once per record, grid and
    draw setting and kept in ``record.cache`` (~1 s for 8 draws on a loaded machine)."""
    ident = record.identified
    beam = served_beam(ident)
    drawable = beam is not None
    if beam is None:
        beam = record.beam
    if beam is None:
        return None
    dx, ny = coarse_grid(preset)
    key = (float(dx), int(ny), int(samples), int(seed), float(scale))
    return _cached(
        record,
        "band_beam_models",
        (ident, record.beam),
        key,
        lambda: _build_beam_models(record, ident, beam, drawable, key, dx, ny),
    )


def _cached(record, name: str, owners: tuple, key, build):
    """``build()`` for ``key``, kept in ``record.cache[name]`` while the objects ``owners``
    (the ski's identification, its beam) are the record's: built once under the lock, at most
    ``_BEAM_MODELS_MAX`` keys per entry (then the entry starts afresh). The lock is re-entrant:
    a build may read other entries through here."""
    store = record.cache.get(name)
    if (
        store is None
        or len(store[0]) != len(owners)
        or any(a is not b for a, b in zip(store[0], owners, strict=True))
    ):
        store = (owners, {})
        record.cache[name] = store
    hit = store[1].get(key)
    if hit is None:
        with _BEAM_MODELS_LOCK:
            hit = store[1].get(key)
            if hit is None:
                hit = build()
                if len(store[1]) >= _BEAM_MODELS_MAX:
                    store[1].clear()
                store[1][key] = hit
    return hit


def _build_beam_models(record, ident, beam, drawable, key, dx, ny):
    """The models of :func:`beam_models` for ``key`` (dx, ny, samples, seed, scale). The
    nominal model (per grid) and the unit draws (per draw count and seed:
    :func:`solvers.identify.draw_beam_deviations`, the covariance's eigen-decomposition) are
    kept apart in ``record.cache``, since the scale changes with the snow modulus from one
    request to the next: only the drawn beams are prepared again (the same models, bit for
    bit, as drawing afresh), sharing the nominal's snow parts (the same footprint)."""
    samples, seed, scale = key[2], key[3], key[4]
    nominal = _cached(
        record,
        "band_nominal_model",
        (ident, record.beam),
        (float(dx), int(ny)),
        lambda: _prepare(beam, record.outline, dx, ny),
    )
    drawn = []
    if drawable and samples > 0 and scale > 0:
        ib = identification_for_sampling(ident)
        if ib is not None:
            draws = _cached(
                record,
                "band_beam_draws",
                (ident,),
                (int(samples), int(seed)),
                lambda: draw_beam_deviations(ib, samples, seed, antithetic=True),
            )
            drawn = [_prepare(b, record.outline, dx, ny, like=nominal) for b in draws.beams(scale)]
    return nominal, drawn


def alternative_models(record, preset: Preset) -> list[FlexibleModel]:
    """The bending ski of each alternative beam stored with the ski's identification
    (:func:`app.storage.skis.identified_alternatives`) on the grid twice as coarse as
    ``preset``; empty when it stores none. Prepared once per record and grid and kept in
    ``record.cache``."""
    ident = record.identified
    beams = identified_alternatives(ident) if served_beam(ident) is not None else []
    if not beams:
        return []
    dx, ny = coarse_grid(preset)
    return _cached(
        record,
        "band_alternative_models",
        (ident,),
        (float(dx), int(ny)),
        lambda: [_prepare(b, record.outline, dx, ny) for b in beams],
    )


def alternative_profiles(
    record, load_n: float, load_position_m: float, positions_m: np.ndarray
) -> list[np.ndarray]:
    """Loaded profiles H*(X) [m] on the rigid flat of the alternative beams stored with the
    ski's served identification, under ``load_n`` [N] at ``load_position_m`` [m], on
    ``positions_m``; empty when it stores none (or the beam is not served). A beam whose solve
    does not converge is left out.

    Each beam's flexibility is kept in ``record.cache`` as an entry of its own (one beam solve
    with it: ~1 ms, without it ~40 ms; at 1 mm nodes over 2 m it holds 30.5 MB, its columns
    only, :attr:`solvers.beam.BeamFlexibility.columns`), so the per-ski cache
    budget drops them one by one
    (docs/deployment.md)."""
    ident = record.identified
    beams = identified_alternatives(ident) if served_beam(ident) is not None else []
    out = []
    for i, b in enumerate(beams):
        key = f"band_alternative_flexibility_{i}"
        hit = record.cache.get(key)
        if hit is None or hit[0] is not ident:
            with _BEAM_MODELS_LOCK:
                hit = record.cache.get(key)
                if hit is None or hit[0] is not ident:
                    hit = (ident, BeamFlexibility(b))
                    record.cache[key] = hit
        res = solve_beam_contact(b, load_n, load_position_m, flexibility=hit[1])
        if res.converged:
            out.append(np.interp(positions_m, res.positions_m, res.gap_m))
    return out


def _sample_flexible(
    macro,
    ms,
    models: tuple[FlexibleModel, list[FlexibleModel]],
    table,
    porosity,
    e_eff,
    alternatives: list[FlexibleModel] | tuple = (),
) -> _Sampled | None:
    """The bending-ski answer (``macro``, ``ms``) solved again on the coarse grid: the nominal
    beam (warm-started from the answer's line pressure) for the grid estimate, the plausible
    beams (warm-started from that coarse nominal) for the spread, and the ``alternatives``
    (:func:`alternative_models`) for their largest deviation (``_Sampled.alternatives``; one
    that does not converge is left out and counted in ``failed``). Tolerance
    :data:`SAMPLE_TOL`."""
    nominal, drawn = models
    f, xf = macro.load_n, macro.load_position_m

    def solve(model, start_pa):
        m = solve_flexible(model, f, xf, e_eff, tol=SAMPLE_TOL, initial_pressure_pa=start_pa)
        if not m.converged:
            return None
        return m, multiscale(m, table, porosity, e_eff)

    inside = np.isfinite(nominal.unloaded_map.gap_m)
    line = np.interp(nominal.positions_m, macro.positions_m, np.nan_to_num(macro.pressure_line_pa))
    try:
        base = solve(nominal, np.where(inside, line[:, None], 0.0))
    except SkisnowError:
        base = None
    if base is None:
        return None

    def near(model):  # warm-started from the coarse nominal
        return solve(model, base[0].pressure_pa)

    perturbed, failed = _solve_each(near, drawn)
    out = _spread(macro, ms, base, perturbed, failed)
    alt, alt_failed = _solve_each(near, alternatives)
    return _add_alternatives(out, ms, base, alt, alt_failed)


#: unit perturbation fields per profile grid (:func:`_unit_fields`); a ski's profile model
#: answers on one grid, so a process holds a few entries (at most _UNIT_FIELDS_MAX)
_UNIT_FIELDS: dict[tuple, np.ndarray] = {}
_UNIT_FIELDS_MAX = 16


def _unit_fields(positions_m: np.ndarray, samples: int, seed: int) -> np.ndarray:
    """:func:`solvers.band.unit_perturbations` on ``positions_m`` (ℓ =
    :data:`PROFILE_CORRELATION_M`), kept per grid: they depend on the grid, the count and the
    seed only, and × σ they are :func:`solvers.band.profile_perturbations` exactly (~1 ms of
    convolutions per answer saved)."""
    x = np.ascontiguousarray(positions_m, dtype=float)
    key = (x.size, hashlib.sha1(x.tobytes()).hexdigest(), PROFILE_CORRELATION_M, samples, seed)
    hit = _UNIT_FIELDS.get(key)
    if hit is None:
        hit = unit_perturbations(x, PROFILE_CORRELATION_M, samples, seed)
        hit.flags.writeable = False
        if len(_UNIT_FIELDS) >= _UNIT_FIELDS_MAX:
            _UNIT_FIELDS.clear()
        _UNIT_FIELDS[key] = hit
    return hit


def _nonnegative(sigma_m, positions_m) -> np.ndarray:
    sigma = np.broadcast_to(np.asarray(sigma_m, dtype=float), np.shape(positions_m))
    if not np.all(sigma >= 0):
        raise InputError("sigma_m must be ≥ 0")
    return sigma


def _beam_sigma(identified: dict, scale: float, draws: int) -> tuple[float | None, str]:
    """RMS [m] of the loaded profile's spread implied by the beam draws (the stored
    ``profile_sd_m`` × ``scale``; None when not stored) and the band's words for them."""
    sd = identified.get("profile_sd_m")
    rms = None if sd is None else scale * float(np.sqrt(np.mean(np.square(sd))))
    spread = (
        ""
        if rms is None
        else f"; on the flat their loaded profiles spread {rms * 1e6:.2f} µm RMS along the ski"
    )
    return rms, (
        f"identified beam: the bending ski solved again with {draws} plausible beams (EI(X) and "
        f"c(X)) drawn from the fit's covariance in antithetic pairs, deviations × {scale:g} (the "
        "covariance understates the identified profile's actual error; factor per snow modulus "
        "and measurement grid, calibrated against the true beams of the own-ski study's designs, "
        f"docs/limits.md){spread}"
    )
