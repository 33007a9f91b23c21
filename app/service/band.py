"""The 90 % error band of one contact answer (issue #12 point 4, docs/limits.md "Error band").

Four error sources, each a relative 90 % half-width per reported quantity, combined
in quadrature (:func:`solvers.band.combine`):

``camber_model``
    The loaded profile H*(X) of a ski's camber network is uncertain by its own held-out error
    (``metric_test_rmse_band_m`` minus the device noise, in quadrature). The answer is solved
    again with :data:`PROFILE_SAMPLES` smooth perturbations of that size and correlation length
    :data:`PROFILE_CORRELATION_M`, and the spread of every quantity about the nominal answer
    gives its width. A design beam (the demo skis' own beams) is taken as exact. An answer of
    the bending ski (``flexible``, or ``auto`` when it bends) from an identified beam is solved
    again with :data:`BEAM_SAMPLES` plausible beams (EI(X) and c(X)) drawn from the
    identification's covariance, their deviations × :data:`BEAM_SCALE` (:func:`beam_models`;
    the covariance understates the identified beam's actual error, and the factor is
    calibrated against the demo skis' true beams).
``macro_grid``
    Per answer (:func:`grid_component`): the apparent area from the share of its contact length
    in its zones' end pixels, the minimum average separation from its difference to the grid
    twice as coarse; the real area, real pressure and reciprocal separation from the preset's
    measured grid error (``skisnow bench accuracy``, :attr:`Preset.grid_band`), because no
    per-answer estimate follows their error. Factors calibrated on cases the calibration test
    does not use (``scripts/band_calibration_study.py``; docs/limits.md, Error band); for an
    answer of the bending ski times :data:`FLEXIBLE_GRID_FACTOR`
    (``scripts/flexible_band_study.py``).
``table_interpolation``
    The texture table's interpolation error between its own nodes, estimated by leaving nodes
    out (:func:`solvers.band.table_interpolation_error`), weighted by where the answer loads the
    table.
``ski_model``
    When ``auto`` answers with the rigid shape, the measured difference to the bending ski.

Not covered (listed in every answer): the texture table's pixel-size error (the shipped tables
carry no estimate; ``skisnow bench accuracy`` measures +2–3 % (grind-1) and +8–21 % (grind-2) in
real contact area against the zero-pixel limit, docs/benchmarks.md), and the physics of the
method itself (elastic half-spaces, no friction, no snow plasticity; docs/limits.md).
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass

import numpy as np
from skisnow.app.presets import Preset
from skisnow.app.service.profiles import served_beam
from skisnow.app.storage.skis import identification_for_sampling
from skisnow.solvers.band import (
    Z90,
    combine,
    end_pixel_share,
    model_error_sigma,
    position_error_sigma,
    table_interpolation_error,
    unit_perturbations,
)
from skisnow.solvers.errors import InputError, SkisnowError
from skisnow.solvers.flexible import FlexibleModel, prepare_flexible, solve_flexible
from skisnow.solvers.identify import estimate_noise, sample_beams
from skisnow.solvers.lookup import MicroTable
from skisnow.solvers.macro import ProfileExtruder, solve_macro
from skisnow.solvers.multiscale import multiscale

__all__ = [
    "BAND_SEED",
    "GRID_BAND_FACTOR",
    "K_END_PIXELS",
    "K_MIN_SEPARATION",
    "MIN_SEPARATION_FLOOR",
    "PROFILE_CORRELATION_M",
    "PROFILE_SAMPLES",
    "QUANTITIES",
    "WIDE_BAND",
    "Band",
    "answer_band",
    "camber_sigma_m",
    "grid_component",
]

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
#: the default 1e-8, and they cost about 25 % less
SAMPLE_TOL = 1e-6
#: the perturbations' seed: the same request always gets the same band
BAND_SEED = 12
#: the band of the loaded profile where the camber model is judged (as in training) [m]
CONTACT_BAND_M = 2e-4
#: an answer whose band is wider than this (relative half-width) carries a warning
WIDE_BAND = 0.10


@dataclass
class Band:
    """Relative 90 % half-widths per quantity and source, and the sampled distributions."""

    widths: dict[str, float]
    components: dict[str, dict[str, float]]
    zone_load_widths: list[float]
    pressure_line_band_pa: tuple[np.ndarray, np.ndarray] | None
    samples: int
    camber_sigma_m: float | None
    camber_source: str
    not_covered: list[str]
    #: factor on the identification covariance's deviations of the beam draws (bending-ski
    #: answers of an identified beam), else None
    beam_scale: float | None = None


#: moving window of the camber model's error along the ski [m] (:func:`camber_sigma_m`)
SIGMA_WINDOW_M = 0.1
_SIGMA_CACHE: dict[int, tuple[object, np.ndarray | float | None, str]] = {}


def camber_sigma_m(record, positions_m: np.ndarray) -> tuple[np.ndarray | float | None, str]:
    """Standard deviation [m] of the ski's loaded-profile model error at ``positions_m`` and
    where it comes from; ``(0, …)`` for a ski answered by its design beam, ``(None, …)`` when
    unknown.

    For an identified beam (the profile model of :mod:`app.service.profiles` when its identification
    passed): the stored ``profile_sd_m``, the spread of the loaded profile over beams drawn
    from the identification's covariance (:func:`solvers.identify.profile_sigma`).

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
        return np.interp(np.asarray(positions_m, dtype=float), x, sd), (
            "identified beam: spread of the loaded profile over plausible beams drawn from the "
            f"fit's covariance where H < {CONTACT_BAND_M * 1e3:.1f} mm "
            f"({np.min(sd) * 1e6:.2f}–{np.max(sd) * 1e6:.2f} µm along the ski)"
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
    return np.interp(np.asarray(positions_m, dtype=float), xs, ss), source


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


def touches_profile_end(gap_map, macro) -> bool:
    """Whether a contact zone reaches the first or last row of the ski's footprint (the end of
    the measured profile). There the pressure is singular at the cut-off edge, so the minimum
    average separation keeps falling as the grid is refined: it has no grid-converged value
    (at the papers' light-load cases 4.5 → 3.9 µm from 4 mm to 0.5 mm pixels, ski-a)."""
    rows = np.flatnonzero(np.any(np.isfinite(gap_map.gap_m), axis=1))
    if not rows.size or not macro.zones:
        return False
    dx = gap_map.pixel_size_m[0]
    first, last = gap_map.positions_m[rows[0]], gap_map.positions_m[rows[-1]]
    return any(z.start_m <= first + 1.5 * dx or z.end_m >= last - 1.5 * dx for z in macro.zones)


#: a contact zone shorter than this many pixels along the ski does not resolve its peak
#: pressure, so the minimum average separation inside it is not grid-converged
MIN_SEPARATION_ZONE_PIXELS = 10


def min_separation_unresolved(gap_map, macro, ms) -> str | None:
    """Why the answer's minimum average separation has no grid-converged value, or ``None``.

    It follows the peak pressure of the row where it sits. A contact zone shorter than
    :data:`MIN_SEPARATION_ZONE_PIXELS` pixels does not resolve its peak, and as the grid is
    refined the minimum falls there or moves there from another zone (short tip and tail
    contacts at light loads: ski-a at 13 kg falls 4.5 → 4.1 → 3.8 → 3.4 → 3.3 µm from 8 to
    0.5 mm pixels). A zone reaching the end of the measured profile has a singular pressure at
    the cut-off."""
    if touches_profile_end(gap_map, macro):
        return "a contact zone reaches the end of the measured profile"
    dx = gap_map.pixel_size_m[0]
    short = [z for z in macro.zones if z.end_m - z.start_m < MIN_SEPARATION_ZONE_PIXELS * dx]
    if short:
        z = min(short, key=lambda z: z.end_m - z.start_m)
        length = z.end_m - z.start_m
        return (
            f"a contact zone at {0.5e3 * (z.start_m + z.end_m):.0f} mm is {length * 1e3:.0f} mm "
            f"long ({length / dx:.0f} pixels of {dx * 1e3:g} mm), too short to resolve its peak "
            "pressure, and the minimum moves there as the grid is refined"
        )
    return None


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


def _sample(case: _Case, sigma_m: float | np.ndarray, samples: int, seed: int) -> _Sampled | None:
    """Solve on the coarse grid (:func:`coarse_grid`) the nominal profile and ``samples``
    perturbed ones. The coarse nominal against the answer gives the grid estimate (first-order
    convergence: the error of the answer's grid is the difference to a grid twice as coarse);
    the perturbed ones against the coarse nominal give the camber model's spread."""
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
    perturbed, failed = [], 0
    deltas = (
        _unit_fields(positions_m, samples, seed) * _nonnegative(sigma_m, positions_m)
        if np.any(np.asarray(sigma_m) > 0)
        else np.zeros((0, np.size(positions_m)))
    )
    for d in deltas:
        g = gap_m + d
        g = g - min(float(np.nanmin(g)), 0.0)  # a rigid approach absorbs a constant
        try:
            r = solve(g, m0, m0.pressure_pa)
        except SkisnowError:
            r = None
        if r is None:
            failed += 1
            continue
        perturbed.append(r)
    return _spread(macro, ms, base, perturbed, failed)


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
#: factor on the covariance's parameter deviations of those draws [-]: the smallest of the
#: study's candidates whose camber part alone covers 90 % of the identification's own error in
#: the ``calib`` cases (the answer against the ski's true beam on the answer's grid; 93.3 %,
#: test cases 95.8 %). The covariance understates that error far more than the loaded
#: profile's (about 3×, docs/limits.md): at factor 1 the camber part covers 34 % of it
BEAM_SCALE = 16.0
#: models of plausible beams kept per ski record (one entry per coarse grid and draw setting)
_BEAM_MODELS_MAX = 8


def _prepare(beam, outline, dx: float, ny: int) -> FlexibleModel:
    return prepare_flexible(
        beam,
        outline.width_m,
        pixel_along_m=dx,
        pixels_across=ny,
        width_positions_m=outline.positions_m,
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
    store = record.cache.get("band_beam_models")
    if store is None or store[0] is not ident or store[1] is not record.beam:
        store = (ident, record.beam, {})
        record.cache["band_beam_models"] = store
    hit = store[2].get(key)
    if hit is None:
        nominal = _prepare(beam, record.outline, dx, ny)
        drawn = []
        if drawable and samples > 0 and scale > 0:
            ib = identification_for_sampling(ident)
            if ib is not None:
                beams = sample_beams(ib, samples, seed, scale=scale, antithetic=True)
                drawn = [_prepare(b, record.outline, dx, ny) for b in beams]
        if len(store[2]) >= _BEAM_MODELS_MAX:
            store[2].clear()
        hit = store[2][key] = (nominal, drawn)
    return hit


def _sample_flexible(
    macro, ms, models: tuple[FlexibleModel, list[FlexibleModel]], table, porosity, e_eff
) -> _Sampled | None:
    """The bending-ski answer (``macro``, ``ms``) solved again on the coarse grid: the nominal
    beam (warm-started from the answer's line pressure) for the grid estimate, the plausible
    beams (warm-started from that coarse nominal) for the spread. Tolerance
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
    perturbed, failed = [], 0
    for model in drawn:
        try:
            r = solve(model, base[0].pressure_pa)
        except SkisnowError:
            r = None
        if r is None:
            failed += 1
            continue
        perturbed.append(r)
    return _spread(macro, ms, base, perturbed, failed)


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


_TABLE_ERRORS: dict[int, tuple[MicroTable, dict[str, np.ndarray]]] = {}


def _table_errors(table: MicroTable) -> dict[str, np.ndarray]:
    """Interpolation error estimate per column at the table's partial-contact nodes (computed
    once per table object; the catalogue keeps its tables for the life of the process)."""
    hit = _TABLE_ERRORS.get(id(table))
    if hit is not None and hit[0] is table:
        return hit[1]
    partial = ~np.asarray(table.full_contact, dtype=bool)
    r = np.asarray(table.pressure_ratio, dtype=float)[partial]
    out = {
        c: np.nan_to_num(table_interpolation_error(r, np.asarray(getattr(table, c))[partial]))
        for c in ("real_contact_area_fraction", "mean_gap_m", "mean_reciprocal_gap_per_m")
    }
    _TABLE_ERRORS[id(table)] = (table, out)
    return out


def _table_component(table: MicroTable, macro, porosity: float, e_eff: float) -> dict[str, float]:
    """Interpolation error of the table columns where this answer loads them: the error of
    each column at each loaded pixel's nominal pressure ratio, weighted by the pixel's share of
    the quantity (real area for a_r, load for the gaps)."""
    partial = ~np.asarray(table.full_contact, dtype=bool)
    r_nodes = np.asarray(table.pressure_ratio, dtype=float)[partial]
    if r_nodes.size < 4:
        return {}
    p = np.nan_to_num(macro.pressure_pa).ravel()
    loaded = p > 0
    if not loaded.any():
        return {}
    ratio = p[loaded] * (1 - porosity) / e_eff
    lr, lrn = np.log(ratio), np.log(r_nodes)

    errors = _table_errors(table)

    def err(column: str) -> np.ndarray:
        return np.interp(lr, lrn, errors[column])

    ar = np.interp(lr, lrn, np.asarray(table.real_contact_area_fraction)[partial])
    w_area = ar / ar.sum() if ar.sum() > 0 else np.full(ar.size, 1 / ar.size)
    w_load = p[loaded] / p[loaded].sum()
    e_ar = float(np.sum(w_area * err("real_contact_area_fraction")))
    e_gap = float(np.sum(w_load * err("mean_gap_m")))
    e_rec = float(np.sum(w_load * err("mean_reciprocal_gap_per_m")))
    return {
        "total_real_contact_area": e_ar,  # the leave-one-out estimate is taken as the bound
        "average_real_contact_pressure": e_ar,
        "min_average_separation": e_gap,
        "total_reciprocal_separation": e_rec,
    }


#: The factors below were calibrated on cases the calibration test does not use (other loads and
#: snow moduli of the demo skis and two beam skis of other designs;
#: ``scripts/band_calibration_study.py``, set ``calib``) against the converged answer, the
#: reference grid of ``skisnow bench accuracy`` (0.5 mm × 64 across): each is the smallest that
#: puts 90 % of that set's truths inside (docs/limits.md, Error band).
#:
#: factor on the end-pixel share (:func:`solvers.band.end_pixel_share`) that gives the apparent
#: area's grid half-width
K_END_PIXELS = 0.45
#: factor on the answer's own coarse-grid difference, and the floor added in quadrature, that
#: give the minimum average separation's grid half-width (the narrowest pair on a 0.1 × 0.005
#: grid; where the two grids agree by chance the error is not zero, hence the floor). Fitted
#: on the first 16 of the set's 19 cases with a band; it covers 16 of the 19 (84 %)
K_MIN_SEPARATION = 0.9
MIN_SEPARATION_FLOOR = 0.005
#: factor on the preset's measured grid width (:attr:`Preset.grid_band`, the 90th percentile of
#: 12 benchmark cases) for the quantities without a per-answer estimate
GRID_BAND_FACTOR = {
    "total_real_contact_area": 1.72,
    "average_real_contact_pressure": 1.67,
    "total_reciprocal_separation": 0.94,
}


#: factors on the grid part of an answer of the bending ski, per quantity: each the smallest
#: (step 0.05) that puts 90 % of the ``calib`` truths inside the whole band with the camber
#: part above (``scripts/flexible_band_study.py``; the truth: the ski's true beam bending on
#: the snow on 0.5 mm × 64). Soft snow (2 MPa) needs the larger real-area factors: there the
#: default grid's real area is +1.7…+2.6 % off. The apparent area's is below 1 because the
#: beam draws at factor 16 already move it (zones appear and vanish)
FLEXIBLE_GRID_FACTOR: dict[str, float] = {
    "apparent_contact_area": 0.65,
    "total_real_contact_area": 1.4,
    "average_real_contact_pressure": 1.45,
    "min_average_separation": 1.55,
    "total_reciprocal_separation": 1.05,
}


def grid_component(preset: Preset, macro, sampled: _Sampled | None) -> dict[str, float]:
    """The macro grid's relative 90 % half-width per quantity for one answer.

    - apparent contact area: :data:`K_END_PIXELS` × the answer's end-pixel share
      (:func:`solvers.band.end_pixel_share`, its zones on its own grid);
    - minimum average separation: :data:`K_MIN_SEPARATION` × |q − q_coarse| / |q| (the
      answer against the same solve on the grid twice as coarse) and
      :data:`MIN_SEPARATION_FLOOR` in quadrature, when that solve ran (rigid answers); else the
      preset's measured width;
    - total real contact area, average real contact pressure, total reciprocal separation: the
      preset's measured 90th percentile (:attr:`Preset.grid_band`, against the 0.5 mm × 64
      reference of ``skisnow bench accuracy``) times :data:`GRID_BAND_FACTOR`. Their errors
      do not follow any per-answer estimate we have (log-correlation with the coarse-grid
      difference or the end-pixel share between −0.45 and +0.35 over 208 cases), so a
      constant is the honest width.
    """
    grid = {q: w * GRID_BAND_FACTOR.get(q, 1.0) for q, w in preset.grid_band.items()}
    share = end_pixel_share([z.length_m for z in macro.zones], macro.pixel_size_m[0])
    if math.isfinite(share):
        grid["apparent_contact_area"] = K_END_PIXELS * share
    d = None if sampled is None else sampled.grid.get("min_average_separation")
    if d is not None and math.isfinite(d):
        grid["min_average_separation"] = math.hypot(K_MIN_SEPARATION * d, MIN_SEPARATION_FLOOR)
    return grid


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
        "covariance understates the identified profile's actual error; factor calibrated "
        f"against the demo skis' true beams, docs/limits.md){spread}"
    )


def answer_band(
    *,
    record,
    positions_m: np.ndarray,
    gap_m: np.ndarray,
    preset: Preset,
    macro,
    ms,
    table: MicroTable,
    porosity: float,
    e_eff: float,
    ski_model_used: str,
    beam_is_design: bool,
    rigid_minus_flexible: dict[str, float] | None = None,
    min_separation_unresolved: str | None = None,
    samples: int = PROFILE_SAMPLES,
    seed: int = BAND_SEED,
    beam_samples: int = BEAM_SAMPLES,
    beam_scale: float = BEAM_SCALE,
) -> Band:
    """The band of one answer (``macro``/``ms`` are the answer's own solves, ``positions_m``/
    ``gap_m`` the rigid model's loaded profile behind them). ``min_separation_unresolved``: why
    the minimum average separation has no grid-converged value
    (:func:`min_separation_unresolved`); it then gets no band (``nan``).

    A rigid answer (``ski_model_used`` "rigid") is solved again with ``samples`` perturbed
    loaded profiles (:func:`camber_sigma_m`); an answer of the bending ski with
    ``beam_samples`` plausible beams drawn from the identification's covariance, deviations
    × ``beam_scale`` (:func:`beam_models`; none for a design beam). Both on the grid twice as
    coarse, whose nominal solve also gives the per-answer grid estimate."""
    components: dict[str, dict[str, float]] = {}
    not_covered = [
        "texture pixel size of the table (no estimate stored; skisnow bench accuracy measures "
        "+2–3 % (grind-1) and +8–21 % (grind-2) in real contact area, docs/benchmarks.md)",
        "the method's physics: elastic half-spaces, no friction, no snow plasticity "
        "(docs/limits.md)",
    ]
    rigid = ski_model_used == "rigid"
    sigma, source = None, ""
    sampled = None
    perturbed = samples
    if rigid:
        sigma, source = camber_sigma_m(record, positions_m)
        if sigma is None:
            not_covered.insert(0, "the camber model (" + source + ")")
        case = _Case(positions_m, gap_m, record.outline, preset, macro, ms, table, porosity, e_eff)
        sampled = _sample(case, 0.0 if sigma is None else sigma, samples, seed)
    else:
        models = beam_models(record, preset, samples=beam_samples, seed=seed, scale=beam_scale)
        if models is not None:
            sampled = _sample_flexible(macro, ms, models, table, porosity, e_eff)
        perturbed = 0 if models is None else len(models[1])
        if beam_is_design:
            sigma, source = 0.0, "design beam stored with the ski, taken as exact"
        elif perturbed:
            sigma, source = _beam_sigma(record.identified, beam_scale, perturbed)
        else:
            source = "identified beam: no covariance stored with the identification"
            not_covered.insert(0, "the identified beam's uncertainty (EI(X), c(X)): " + source)
    has_sigma = sigma is not None and bool(np.any(np.asarray(sigma) > 0))
    if sampled is not None and has_sigma:
        components["camber_model"] = sampled.widths
    grid = grid_component(preset, macro, sampled)
    if not rigid:
        grid = {q: w * FLEXIBLE_GRID_FACTOR.get(q, 1.0) for q, w in grid.items()}
    components["macro_grid"] = grid
    components["table_interpolation"] = _table_component(table, macro, porosity, e_eff)
    if rigid and rigid_minus_flexible:
        components["ski_model"] = {
            k: abs(v) for k, v in rigid_minus_flexible.items() if k in QUANTITIES
        }
    widths = combine(components)
    if min_separation_unresolved:
        widths["min_average_separation"] = float("nan")
        not_covered.insert(
            0,
            "the minimum average separation has no grid-converged value here ("
            + min_separation_unresolved
            + "); it falls further with every finer grid, so no band can be given",
        )
    # zone loads: the camber spread per zone, the grid (the benchmark's apparent-area width or
    # this answer's own estimate), the ski-model difference in rear load share (absolute,
    # relative to the zone's share)
    zone_widths = []
    for i, z in enumerate(ms.zones):
        g = preset.grid_band.get("apparent_contact_area", 0.0)
        parts = []
        if sampled is not None:
            if math.isfinite(sampled.zone_grid[i]):
                g = max(g, sampled.zone_grid[i])
            if has_sigma and math.isfinite(sampled.zone_widths[i]):
                parts.append(sampled.zone_widths[i])
        parts.append(g)
        if "ski_model" in components and z.load_share > 0:
            parts.append(abs(rigid_minus_flexible.get("rear_load_share", 0.0)) / z.load_share)
        zone_widths.append(math.sqrt(sum(p * p for p in parts)))
    line_band = None
    if sampled is not None and sampled.line_half_width_pa is not None:
        nom = np.nan_to_num(macro.pressure_line_pa)
        line_band = (
            np.maximum(nom - sampled.line_half_width_pa, 0.0),
            nom + sampled.line_half_width_pa,
        )
    return Band(
        widths=widths,
        components=components,
        zone_load_widths=zone_widths,
        pressure_line_band_pa=line_band,
        samples=(perturbed - sampled.failed) if (sampled is not None and has_sigma) else 0,
        camber_sigma_m=None if sigma is None else float(np.sqrt(np.mean(np.square(sigma)))),
        camber_source=source,
        not_covered=not_covered,
        beam_scale=beam_scale if (not rigid and has_sigma) else None,
    )


#: JSON keys of the answer's values, per quantity: (section, key)
ANSWER_KEYS = {
    "apparent_contact_area": ("apparent", "contact_area_cm2"),
    "total_real_contact_area": ("metrics", "total_real_contact_area_mm2"),
    "average_real_contact_pressure": ("metrics", "average_real_contact_pressure_mpa"),
    "min_average_separation": ("metrics", "min_average_separation_um"),
    "total_reciprocal_separation": ("metrics", "total_reciprocal_separation_m"),
}


def _round(v: float, digits: int = 4) -> float | None:
    return float(f"{v:.{digits}g}") if v is not None and math.isfinite(v) else None


def band_json(band: Band, answer: dict) -> tuple[dict, list[dict]]:
    """The ``band`` section of an answer (intervals in the answer's units), and the warnings it
    raises. Adds ``load_band_90_n`` to each zone of ``answer["apparent"]["zones"]``."""
    intervals, rel = {}, {}
    for q, (section, key) in ANSWER_KEYS.items():
        w = band.widths.get(q, float("nan"))
        v = answer[section][key]
        rel[q] = _round(w)
        intervals[key] = (
            [_round(v * (1 - w), 6), _round(v * (1 + w), 6)] if math.isfinite(w) else None
        )
    # the mean apparent pressure is F / A: the apparent area's relative band
    w_a = band.widths.get("apparent_contact_area", float("nan"))
    v = answer["apparent"]["mean_pressure_kpa"]
    intervals["mean_pressure_kpa"] = [_round(v / (1 + w_a), 6), _round(v / max(1 - w_a, 1e-9), 6)]
    for z, w in zip(answer["apparent"]["zones"], band.zone_load_widths, strict=False):
        z["load_band_90_n"] = [_round(z["load_n"] * (1 - w), 6), _round(z["load_n"] * (1 + w), 6)]
    warnings = []
    wide = {q: w for q, w in band.widths.items() if w > WIDE_BAND}
    if wide:
        worst = max(wide, key=wide.get)
        warnings.append(
            {
                "code": "wide_error_band",
                "detail": f"the 90 % error band is wider than ±{WIDE_BAND:.0%} for "
                f"{', '.join(sorted(wide))} (largest: {worst} ±{wide[worst]:.1%}); see "
                "band.components for the sources",
            }
        )
    out = {
        "level": 0.9,
        "relative_half_width": rel,
        "intervals": intervals,
        "zone_load_relative_half_width": [_round(w) for w in band.zone_load_widths],
        "components": {
            src: {q: _round(w) for q, w in ws.items()} for src, ws in band.components.items()
        },
        "camber_model": {
            "error_sd_um": _round(band.camber_sigma_m * 1e6)
            if band.camber_sigma_m is not None
            else None,
            "source": band.camber_source,
            "perturbed_solves": band.samples,
            # smooth profile perturbations (rigid answers) or beam draws (bending ski)
            "correlation_length_mm": PROFILE_CORRELATION_M * 1e3
            if band.beam_scale is None
            else None,
            "beam_deviation_scale": band.beam_scale,
            "seed": BAND_SEED,
        },
        "not_covered": band.not_covered,
        "method": "relative 90 % half-widths per source combined in quadrature: camber model "
        "(the answer solved again with perturbed loaded profiles, or for the bending ski with "
        "plausible beams drawn from the identification), macro grid (the answer's end-pixel "
        "share and its difference to the grid twice as coarse, and the preset's width measured "
        "by skisnow bench accuracy), table interpolation (leave-one-out on the table's nodes), "
        "and, when auto answers with the rigid shape, its measured difference to the bending "
        "ski (docs/limits.md, Error band)",
    }
    return out, warnings
