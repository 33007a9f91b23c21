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
    identification's covariance, their deviations × a factor per snow modulus
    (:func:`app.service.band_calibration.beam_scale_at`, :func:`beam_models`; the covariance
    understates the identified beam's actual error, the more so the stiffer the snow, and the
    factor is calibrated against the own-ski study designs' true beams).
``macro_grid``
    Per answer (:func:`grid_component`): the apparent area from the share of its contact length
    in its zones' end pixels, the minimum average separation from its difference to the grid
    twice as coarse; the real area, real pressure and reciprocal separation from the preset's
    measured grid error (``skisnow bench accuracy``, :attr:`Preset.grid_band`), because no
    per-answer estimate follows their error. Factors calibrated on cases the calibration test
    does not use (``scripts/band_calibration_study.py``; docs/limits.md, Error band); for an
    answer of the bending ski times :func:`flexible_grid_factors` (:data:`FLEXIBLE_GRID_FACTOR`,
    ``scripts/flexible_band_study.py``; the apparent area's per snow modulus,
    ``scripts/flexible_grid_factor_study.py``), for a rigid one the apparent area's times
    :func:`rigid_grid_factors` (per snow modulus, ``scripts/rigid_grid_factor_study.py``). An
    ``auto`` answer of the rigid shape that was compared to the bending ski takes the apparent
    area's part from the bending ski's answer (it stands for the bending ski; docs/limits.md).
``table_interpolation``
    The texture table's interpolation error between its own nodes, estimated by leaving nodes
    out (:func:`solvers.band.table_interpolation_error`), weighted by where the answer loads the
    table.
``flat_base``
    A rigid answer in the flat-base regime (docs/physics.md §4c): the spread of the answer when the
    stretch of its loaded profile within ``FLAT_GAP_M`` of the flat is perturbed by
    ``FLAT_SIGMA_M`` (:mod:`app.service.band_calibration`); such an answer also warns.
``ski_model``
    When ``auto`` answers with the rigid shape, the measured difference to the bending ski; when
    it could not compare (no beam, or the flexible solve failed), the largest difference measured
    on comparable skis at the answer's snow modulus
    (:func:`app.service.band_calibration.bending_ignored_widths`), and ``not_covered`` says that
    the bending is ignored.

A camber network's σ(X) is multiplied by ``NETWORK_SIGMA_SCALE``, calibrated across 20–2000 MPa
(:mod:`app.service.band_calibration`, ``scripts/network_band_study.py``).

Not covered (listed in every answer): the texture table's pixel-size error, which is not added
to the band: a table built on several pixel sizes (the shipped grinds) stores its own estimate
against the zero-pixel limit, reported beside the band in ``provenance.table.
pixel_error_estimate`` (docs/tables.md); a table on one pixel size (an upload) stores none
(:func:`pixel_size_not_covered`). And the physics of the method itself (elastic half-spaces,
no friction, no snow plasticity; docs/limits.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from skisnow.app.presets import Preset
from skisnow.app.service import band_calibration
from skisnow.app.service.band_calibration import (
    FLAT_GAP_M,
    FLAT_MIN_WIDTH,
    FLAT_SIGMA_M,
    FLAT_STRETCH_M,
    beam_scale_at,
    bending_ignored_widths,
    flexible_area_grid_factor_at,
    grid_above_share_at,
    identified_sigma_scale_at,
    loaded_cases,
    network_studied_tail_at,
    rigid_area_grid_factor_at,
    studied_tail_at,
)
from skisnow.app.service.band_sampling import (
    BAND_SEED,
    BEAM_SAMPLES,
    PROFILE_CORRELATION_M,
    PROFILE_SAMPLES,
    QUANTITIES,
    WIDE_BAND,
    _beam_sigma,
    _Case,
    _sample,
    _sample_flexible,
    _Sampled,
    alternative_models,
    alternative_profiles,
    beam_models,
    camber_sigma_m,
)
from skisnow.app.service.profiles import served_beam
from skisnow.solvers.band import (
    combine,
    end_pixel_share,
    flat_stretch,
    one_sided_part,
    table_interpolation_error,
)
from skisnow.solvers.identify import measured_stretch
from skisnow.solvers.lookup import MicroTable

__all__ = [
    "BAND_SEED",
    "BEAM_SCALE_FLOOR",
    "GRID_BAND_FACTOR",
    "GRID_ONE_SIDED",
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
    "flexible_grid_factors",
    "grid_component",
    "interval_90",
    "one_sided_widths",
    "rigid_grid_factors",
]


@dataclass
class Band:
    """Relative 90 % half-widths per quantity and source, and the sampled distributions.

    ``widths`` is each quantity's half-width below the answer (the band's lower end is
    value × (1 − w)); ``widths_above`` the half-width above it where the two differ
    (:data:`GRID_ONE_SIDED`; the upper end is value ÷ (1 − w_above)), else the same."""

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
    #: the flat-base regime (:mod:`app.service.band_calibration`): length [m] and midpoint [m]
    #: of the stretch near the flat and the apparent area's half-width from it; None outside
    flat_base: tuple[float, float, float] | None = None
    #: ``auto`` answered with the rigid shape without comparing it to the bending ski
    bending_ignored: str | None = None
    #: a bending-ski answer of an identified beam whose contact reaches beyond the stretch
    #: where the camber cases set EI (:func:`unmeasured_contact`): the footprint's rear and
    #: front end and the measured stretch's [m]; None otherwise
    unmeasured_stiffness: tuple[float, float, float, float] | None = None
    #: factors on the grid part per quantity (:func:`flexible_grid_factors` of a bending-ski
    #: answer, :func:`rigid_grid_factors` of a rigid one; a quantity not named: 1)
    grid_factors: dict[str, float] | None = None
    #: alternative beams of the identification the answer was solved again with (and those
    #: that did not converge); their largest deviation is the component ``beam_alternatives``
    alternative_beams: tuple[int, int] = (0, 0)
    #: factor on the identified profile's spread of a rigid answer
    #: (:func:`app.service.band_calibration.identified_sigma_scale_at`), else None
    profile_scale: float | None = None
    #: an answer of an identified beam that predicts its held-out camber cases worse than
    #: :data:`HELD_OUT_WARN_RATIO` × the device noise (:func:`held_out_excess`): (held-out
    #: RMS, device noise) [m]; None otherwise
    held_out_error: tuple[float, float] | None = None
    #: an answer of an identified beam whose camber file was sampled coarser than the
    #: recommended spacing: (its spacing [mm], then
    #: :func:`app.service.band_calibration.sampling_accuracy`'s three items); None otherwise
    sparse_sampling: tuple | None = None
    #: a bending-ski answer whose plausible beams mostly did not converge on this snow (fewer
    #: than 2 solved, so the camber part has no width and is left out): (solved, drawn)
    beam_draws_failed: tuple[int, int] | None = None
    #: the same for a rigid answer's perturbed loaded profiles: (solved, drawn)
    profile_draws_failed: tuple[int, int] | None = None
    #: a bending-ski answer whose plausible beams mostly did not converge at the calibrated
    #: factor, drawn again at half of it (down to :data:`BEAM_SCALE_FLOOR`) until 2 did:
    #: (calibrated factor, solved, drawn) at that factor; ``beam_scale`` is the one used
    beam_scale_reduced: tuple[float, int, int] | None = None
    #: half-widths above the answer of the quantities whose grid part is one-sided
    #: (:data:`GRID_ONE_SIDED`); a quantity not named: its ``widths`` value
    widths_above: dict[str, float] | None = None
    #: share of the grid part kept above the answer
    #: (:func:`app.service.band_calibration.grid_above_share_at`)
    grid_above_share: float | None = None
    #: how the studies' answers of this kind fell outside their bands
    #: (:func:`app.service.band_calibration.studied_tail_at` for an identified beam,
    #: :func:`~app.service.band_calibration.network_studied_tail_at` for a rigid answer of the
    #: camber network): (share outside, farthest truth ÷ the half-width on its side, answers
    #: studied); None for an answer the studies do not stand for (a design beam, auto's
    #: compared or rigid-for-bending answers)
    studied_tail: tuple[float, float, int] | None = None
    #: which studies :attr:`studied_tail` comes from: "identified_beam" or "network"
    studied_tail_of: str | None = None

    def width_above(self, quantity: str) -> float:
        """The relative half-width above the answer of ``quantity`` [-]."""
        above = (self.widths_above or {}).get(quantity)
        return self.widths.get(quantity, float("nan")) if above is None else above


#: quantities whose macro-grid part is a bias (the default grid's value above the converged
#: one, docs/studies/grid-bias.md): the band adds it below the answer and keeps only
#: :func:`app.service.band_calibration.grid_above_share_at` of it above
#: (:func:`solvers.band.one_sided_part`). The other quantities' grid errors were not measured
#: signed; their parts stay symmetric
GRID_ONE_SIDED = ("apparent_contact_area",)


def one_sided_widths(
    parts: dict[str, float | None], e_eff_pa: float, share_above: float | None = None
) -> tuple[float, float]:
    """The half-widths (below, above) [-] the band serves for a quantity of
    :data:`GRID_ONE_SIDED` whose parts per source are ``parts`` (``band.components``'s values
    for it): their quadrature (:func:`solvers.band.combine`), with the ``macro_grid`` part moved
    below the answer (:func:`solvers.band.one_sided_part`) at the snow's share
    (:func:`app.service.band_calibration.grid_above_share_at` of ``e_eff_pa`` [Pa], or
    ``share_above``). The studies rebuild recorded answers' bands with it."""
    width = combine({src: {"q": w} for src, w in parts.items()}).get("q", 0.0)
    share = grid_above_share_at(e_eff_pa) if share_above is None else share_above
    return one_sided_part(width, parts.get("macro_grid") or 0.0, share)


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
#: a contact zone whose width-averaged pressure peaks in one of its this many end rows does
#: not resolve the rise of its pressure at that edge (a smooth contact's pressure vanishes at
#: its edges and peaks inside): the profile turns sharply there (a kink, the start of the tip's
#: rise) and the pressure is singular at the corner, so the minimum average separation keeps
#: falling as the grid is refined. Measured on a seeded random classic design (random-102 of
#: ``solvers.ski_designs``, 68 kg at +14 mm, 20 MPa, the true beam): the tip zone's pressure
#: peaks in its last row, and its minimum separation falls 2.56 → 2.38 → 2.29 → 2.21 → 2.12 µm
#: from 4 mm to 0.25 mm pixels (−3.5 … −7 % per halving, no limit), where the coarse-grid
#: difference read 1–3 % (docs/studies/metric-bands.md)
MIN_SEPARATION_EDGE_ROWS = 3
#: on grids finer than the default (4 mm: its 3 end rows span 12 mm, where the rule above was
#: measured) the contact climbs a few pixels up the corner's steep side, so the peak sits a
#: few rows inside the zone: a peak within this distance of the zone's end [m] and in the
#: zone's outer quarter is an edge peak too. Measured on the `fine` preset (1 mm): ski-b 80 kg
#: at −100 mm, 20 MPa, tail and tip zones peak 5 and 2 mm from their ends (121 and 58 mm long;
#: peak / mean pressure 5.1 and 4.9), random-102's true beam 5 and 6 mm (54 and 63 mm long),
#: where smooth zones peak 21–205 mm inside (ski-a 40 kg at −160 mm, 200 MPa, 44 and 109 mm
#: long: 21 and 51 mm; peak / mean 1.3–1.75). The demo skis' cases are the test
#: test_an_edge_peak_on_the_fine_grid_is_found_a_few_pixels_inside_its_zone (tests/service);
#: random-102 is the true beam of docs/studies/own-ski-random-101-104.json, solved rigid on the
#: fine preset's grid
MIN_SEPARATION_EDGE_M = 12e-3


def edge_peak_m(positions_m, pressure_pa, zone) -> float | None:
    """X [m] of a contact zone's pressure peak when it lies in one of the zone's
    :data:`MIN_SEPARATION_EDGE_ROWS` end rows, or (finer grids) within
    :data:`MIN_SEPARATION_EDGE_M` of its end and in its outer quarter (its edge's pressure rise
    not resolved), else ``None``. ``positions_m``, ``pressure_pa``: the answer's width-averaged
    pressure line (uniform rows); zones too short to tell (:data:`MIN_SEPARATION_ZONE_PIXELS`)
    are ``None`` (their own rule)."""
    x = np.asarray(positions_m, dtype=float)
    rows = np.flatnonzero((x >= zone.start_m) & (x <= zone.end_m))
    p = np.asarray(pressure_pa, dtype=float)[rows]
    if rows.size < MIN_SEPARATION_ZONE_PIXELS or not np.isfinite(p).any():
        return None
    k = int(np.nanargmax(p))
    inside = min(k, rows.size - 1 - k)  # rows between the peak and the zone's nearer end
    dx = float(x[rows[1]] - x[rows[0]])
    near_end = inside * dx < MIN_SEPARATION_EDGE_M and inside < rows.size / 4
    if inside < MIN_SEPARATION_EDGE_ROWS or near_end:
        return float(x[rows[k]])
    return None


def _pixels(n: float) -> str:
    """ "1 pixel", "8 pixels": a zone's length in pixels, rounded."""
    k = round(n)
    return f"{k} pixel" + ("" if k == 1 else "s")


def min_separation_unresolved(gap_map, macro, ms) -> str | None:
    """Why the answer's minimum average separation has no grid-converged value, or ``None``.

    It follows the peak pressure of the row where it sits. A contact zone shorter than
    :data:`MIN_SEPARATION_ZONE_PIXELS` pixels does not resolve its peak, and as the grid is
    refined the minimum falls there or moves there from another zone (short tip and tail
    contacts at light loads: ski-a at 13 kg falls 4.5 → 4.1 → 3.8 → 3.4 → 3.3 µm from 8 to
    0.5 mm pixels). A zone reaching the end of the measured profile has a singular pressure at
    the cut-off, and so has a zone whose pressure peaks at its edge (:func:`edge_peak_m`). The
    rules in the order of :func:`zone_unresolved_reasons`."""
    if touches_profile_end(gap_map, macro):
        return "a contact zone reaches the end of the measured profile"
    dx = gap_map.pixel_size_m[0]
    short = [z for z in macro.zones if z.end_m - z.start_m < MIN_SEPARATION_ZONE_PIXELS * dx]
    if short:
        z = min(short, key=lambda z: z.end_m - z.start_m)
        length = z.end_m - z.start_m
        return (
            f"a contact zone at {0.5e3 * (z.start_m + z.end_m):.0f} mm is {length * 1e3:.0f} mm "
            f"long ({_pixels(length / dx)} of {dx * 1e3:g} mm), too short to resolve its peak "
            "pressure, and the minimum moves there as the grid is refined"
        )
    for z in ms.zones:
        at = edge_peak_m(ms.positions_m, ms.pressure_pa, z)
        if at is not None:
            return (
                f"the contact zone at {0.5e3 * (z.start_m + z.end_m):.0f} mm has its peak "
                f"pressure at its edge ({at * 1e3:.0f} mm): the profile turns sharply there and "
                "the pressure is singular at the corner, so the minimum keeps falling as the grid "
                "is refined"
            )
    return None


def footprint_ends_m(gap_map) -> tuple[float, float]:
    """X of the tail end and the tip end of the ski's footprint [m] (its first and last rows
    with a finite gap; ±inf without any)."""
    rows = np.flatnonzero(np.any(np.isfinite(gap_map.gap_m), axis=1))
    if not rows.size:
        return -np.inf, np.inf
    return float(gap_map.positions_m[rows[0]]), float(gap_map.positions_m[rows[-1]])


def zone_unresolved_reasons(gap_map, ms) -> list[str | None]:
    """Per contact zone of the answer's multiscale result ``ms``, why its minimum average
    separation is not grid-converged (the rules of :func:`min_separation_unresolved`: reaching
    the end of the measured profile, shorter than :data:`MIN_SEPARATION_ZONE_PIXELS` pixels, or
    its pressure peaking at its edge), or ``None`` for a resolved zone."""
    rows = np.flatnonzero(np.any(np.isfinite(gap_map.gap_m), axis=1))
    dx = gap_map.pixel_size_m[0]
    first = gap_map.positions_m[rows[0]] if rows.size else -np.inf
    last = gap_map.positions_m[rows[-1]] if rows.size else np.inf
    out: list[str | None] = []
    for z in ms.zones:
        length = z.end_m - z.start_m
        if z.start_m <= first + 1.5 * dx or z.end_m >= last - 1.5 * dx:
            out.append("it reaches the end of the measured profile")
        elif length < MIN_SEPARATION_ZONE_PIXELS * dx:
            out.append(
                f"it is {length * 1e3:.0f} mm long ({_pixels(length / dx)} of {dx * 1e3:g} mm), "
                "too short to resolve its peak pressure"
            )
        elif (at := edge_peak_m(ms.positions_m, ms.pressure_pa, z)) is not None:
            out.append(
                f"its pressure peaks at its edge ({at * 1e3:.0f} mm), a sharp turn of the profile "
                "the grid does not resolve"
            )
        else:
            out.append(None)
    return out


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


#: the smallest factor on the identification's covariance that the bending ski's band draws are
#: halved down to when fewer than 2 of its plausible beams converge on the snow at the
#: calibrated one (1: the covariance as fitted). Measured on random-19's 9 × 5 ski with a 25 mm
#: knot beam at 2000 MPa: at × 12 1 of 4 beams converged on each of 6 cases, at × 8 and × 6 3 of
#: 4, at × 4 3–4 of 4 (docs/limits.md)
BEAM_SCALE_FLOOR = 1.0

#: factors on the grid part of an answer of the bending ski, per quantity: each the smallest
#: (step 0.05) that puts 90 % of the demo skis' ``calib`` truths inside the whole band with the
#: service's camber part (its beam draws at the factor per snow modulus,
#: :func:`app.service.band_calibration.beam_scale_at`; ``python scripts/flexible_band_study.py
#: --service-only --sets calib``; the truth: the ski's true beam bending on the snow on
#: 0.5 mm × 64). Soft snow (2 MPa) needs the larger real-area factors: there the default
#: grid's real area is +1.7…+2.6 % off. The apparent area's was 0.65 while the beam draws were
#: scaled × 16 at every modulus: those draws moved the demo skis' zones far beyond their
#: identification's error and stood in for the grid's. With draws scaled to the identification's
#: error one factor would be 1.7 (calib 91.7 % inside at 1.96 × the RMS error; at 0.65 68.8 %),
#: but per snow modulus the demo skis need 2.0 at 2 MPa and 0.75–0.85 from 10 MPa up, so the
#: apparent area's factor is calibrated per snow modulus on them and the own-ski study together
#: (:data:`app.service.band_calibration.FLEXIBLE_AREA_GRID_NODES`)
FLEXIBLE_GRID_FACTOR: dict[str, float] = {
    "total_real_contact_area": 1.4,
    "average_real_contact_pressure": 1.45,
    "min_average_separation": 1.65,
    "total_reciprocal_separation": 1.15,
}


#: the band's "not covered" entry of every answer from an identified beam: what the camber data
#: cannot show (docs/limits.md, "Why the three band targets do not all hold at once")
IDENTIFIED_STRUCTURE_NOT_COVERED = (
    "the beam model's shape error: a step in EI(X) or c(X) sharper than the model's smooth "
    "splines (a binding plate, an asymmetric flex) fits the camber data as well as the true "
    "shape does, so the data cannot show it; the band's factors were calibrated on six "
    "designs with such skis among them, on which about 1 answer in 50 lies more than 3 % off "
    "and outside its band (docs/limits.md)"
)


def flexible_grid_factors(e_eff_pa: float) -> dict[str, float]:
    """The factors on a bending-ski answer's grid part per quantity at the effective modulus
    [Pa]: :data:`FLEXIBLE_GRID_FACTOR`, and for the apparent area its factor per snow modulus
    (:func:`app.service.band_calibration.flexible_area_grid_factor_at`)."""
    return {
        "apparent_contact_area": flexible_area_grid_factor_at(e_eff_pa),
        **FLEXIBLE_GRID_FACTOR,
    }


def rigid_grid_factors(e_eff_pa: float) -> dict[str, float]:
    """The factors on a rigid answer's grid part per quantity at the effective modulus [Pa]:
    the apparent area's per snow modulus
    (:func:`app.service.band_calibration.rigid_area_grid_factor_at`), 1 for the others (their
    grid parts are calibrated as they are)."""
    return {"apparent_contact_area": rigid_area_grid_factor_at(e_eff_pa)}


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


def pixel_size_not_covered(table: MicroTable) -> str:
    """The band's "not covered" entry for the table's pixel size: where its estimate is (a
    table on several pixel sizes) or that there is none (one pixel size)."""
    if table.real_contact_area_fraction_error is None:
        return (
            "texture pixel size of the table (a table on one pixel size stores no estimate; on "
            "the shipped grinds' 1.5 µm grid alone skisnow bench accuracy measured +2–3 % "
            "(grind-1) and +8–21 % (grind-2) in real contact area, docs/benchmarks.md)"
        )
    return (
        "texture pixel size of the table: not in the band; the table's own estimate against the "
        "zero-pixel limit is in provenance.table.pixel_error_estimate (docs/tables.md)"
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
    flexible_end_pixel_share: float | None = None,
    bending_ignored: str | None = None,
    min_separation_unresolved: str | None = None,
    samples: int = PROFILE_SAMPLES,
    seed: int = BAND_SEED,
    beam_samples: int = BEAM_SAMPLES,
    beam_scale: float | None = None,
) -> Band:
    """The band of one answer (``macro``/``ms`` are the answer's own solves, ``positions_m``/
    ``gap_m`` the rigid model's loaded profile behind them). ``min_separation_unresolved``: why
    the minimum average separation has no grid-converged value
    (:func:`min_separation_unresolved`); it then gets no band (``nan``).

    A rigid answer (``ski_model_used`` "rigid") is solved again with ``samples`` perturbed
    loaded profiles (:func:`camber_sigma_m`); an answer of the bending ski with
    ``beam_samples`` plausible beams drawn from the identification's covariance, deviations
    × ``beam_scale`` (default: calibrated per snow modulus,
    :func:`app.service.band_calibration.beam_scale_at`; :func:`beam_models`; none for a design
    beam). Both on the grid twice as
    coarse, whose nominal solve also gives the per-answer grid estimate.

    A rigid answer whose loaded profile lies within :data:`FLAT_GAP_M` of the flat over at
    least :data:`FLAT_STRETCH_M` is also solved with that stretch perturbed by
    :data:`FLAT_SIGMA_M`; a spread of its apparent area above :data:`FLAT_MIN_WIDTH` puts it
    in the flat-base regime (component ``flat_base``, ``Band.flat_base``).

    ``flexible_end_pixel_share``: when ``auto`` answered with the rigid shape after comparing it
    to the bending ski (``rigid_minus_flexible``), the bending ski's end-pixel share
    (:func:`solvers.band.end_pixel_share`); the apparent area's grid part is then the bending
    ski's (its share × :data:`K_END_PIXELS` × its factor per snow modulus), since such an answer
    stands for the bending ski: its error is the difference (component ``ski_model``) plus the
    bending ski's grid error.

    ``bending_ignored``: why ``auto`` answered with the rigid shape without a comparison to
    the bending ski (no beam, or the flexible solve failed); the band then adds the measured
    rigid-versus-bending difference of comparable skis (component ``ski_model``,
    :func:`app.service.band_calibration.bending_ignored_widths`)."""
    components: dict[str, dict[str, float]] = {}
    not_covered = [
        pixel_size_not_covered(table),
        "the method's physics: elastic half-spaces, no friction, no snow plasticity "
        "(docs/limits.md)",
    ]
    held_out = None
    sparse = None
    # the answer's profile is the ski's identified beam (not a design beam, not the network)
    identified = not beam_is_design and served_beam(record.identified) is not None
    if identified:
        not_covered.insert(0, IDENTIFIED_STRUCTURE_NOT_COVERED)
        held_out = held_out_excess(record.identified)
        sparse = sparse_sampling(record)
    rigid = ski_model_used == "rigid"
    # a rigid answer from the ski's camber network (no beam served, none given with the ski)
    network_served = rigid and not identified and not beam_is_design and record.network is not None
    unmeasured = None
    scale_reduced = None
    sigma, source = None, ""
    sampled = None
    perturbed = samples
    if rigid:
        sigma, source = camber_sigma_m(record, positions_m, e_eff)
        if sigma is None:
            not_covered.insert(0, "the camber model (" + source + ")")
        case = _Case(positions_m, gap_m, record.outline, preset, macro, ms, table, porosity, e_eff)
        from skisnow.app.service.band_sampling import PROFILE_CORRELATION_M as ell

        stretch, stretch_mid, weight = flat_stretch(positions_m, gap_m, FLAT_GAP_M, ell)
        flat_sigma = FLAT_SIGMA_M * weight if stretch >= FLAT_STRETCH_M else None
        alt_gaps = (
            []
            if beam_is_design
            else alternative_profiles(record, macro.load_n, macro.load_position_m, positions_m)
        )
        sampled = _sample(
            case,
            0.0 if sigma is None else sigma,
            samples,
            seed,
            flat_sigma,
            alternative_gaps_m=alt_gaps,
        )
    else:
        if beam_scale is None:
            beam_scale = beam_scale_at(e_eff, loaded_cases(record))
        alternatives = [] if beam_is_design else alternative_models(record, preset)
        if not beam_is_design:
            unmeasured = unmeasured_contact(record.identified, macro)
        while True:
            models = beam_models(record, preset, samples=beam_samples, seed=seed, scale=beam_scale)
            if models is not None:
                sampled = _sample_flexible(
                    macro, ms, models, table, porosity, e_eff, alternatives=alternatives
                )
            perturbed = 0 if models is None else len(models[1])
            if (
                not perturbed
                or perturbed - sampled.failed >= 2
                or beam_scale / 2 < BEAM_SCALE_FLOOR
            ):
                break
            # too few plausible beams converged on this snow at this factor (a finer-knotted
            # beam's covariance is wider, and the factors were calibrated on 50 mm knots):
            # drawn again at half the factor, and the answer says so
            if scale_reduced is None:
                scale_reduced = (beam_scale, perturbed - sampled.failed, perturbed)
            beam_scale /= 2
        if beam_is_design:
            sigma, source = 0.0, "design beam stored with the ski, taken as exact"
        elif perturbed:
            sigma, source = _beam_sigma(record.identified, beam_scale, perturbed)
        else:
            source = "identified beam: no covariance stored with the identification"
            not_covered.insert(0, "the identified beam's uncertainty (EI(X), c(X)): " + source)
    has_sigma = sigma is not None and bool(np.any(np.asarray(sigma) > 0))
    draws_failed = None
    if sampled is not None and has_sigma and perturbed - sampled.failed < 2:
        # a width needs 2 solved draws: the camber part is left out, and the answer says so
        draws_failed = (perturbed - sampled.failed, perturbed)
        what = (
            f"the camber model ({source}): only {draws_failed[0]} of {perturbed} perturbed "
            "loaded profiles"
            if rigid
            else f"the identified beam's uncertainty (EI(X), c(X)): only {draws_failed[0]} of "
            f"{perturbed} plausible beams (deviations × {beam_scale:g}"
            + ("" if scale_reduced is None else f", halved from × {scale_reduced[0]:g}")
            + ")"
        )
        not_covered.insert(0, what + " converged on this snow, so the band has no camber part")
    if scale_reduced is not None and draws_failed is None:
        not_covered.insert(
            0,
            f"the identified beam's uncertainty at its calibrated factor: at × "
            f"{scale_reduced[0]:g} only {scale_reduced[1]} of {scale_reduced[2]} plausible "
            f"beams converged on this snow; the camber part is from × {beam_scale:g}, at which "
            f"{perturbed - sampled.failed} did",
        )
    if sampled is not None and has_sigma and draws_failed is None:
        components["camber_model"] = sampled.widths
    if sampled is not None and sampled.alternatives:
        # the data do not decide between these beams: the answer's spread over them is part of
        # its error, however small the covariance draws of the chosen one
        components["beam_alternatives"] = sampled.alternatives
    flat = None if sampled is None else sampled.flat
    flat_base = None
    if flat is not None and flat.widths.get("apparent_contact_area", 0.0) > FLAT_MIN_WIDTH:
        # the apparent area (and with it the mean apparent pressure and the zone loads) is what
        # the regime leaves unfixed (docs/physics.md §4c); the other quantities' spread is not added
        # (docs/limits.md: it would take the held-out calibration's width past its target
        # without covering one more case)
        components["flat_base"] = {"apparent_contact_area": flat.widths["apparent_contact_area"]}
        flat_base = (stretch, stretch_mid, flat.widths["apparent_contact_area"])
        not_covered.insert(
            0,
            f"the flat-base regime: the loaded base lies within {FLAT_GAP_M * 1e6:g} µm of the "
            f"flat over {stretch * 1e3:.0f} mm; camber data at a few µm of noise do not fix "
            f"that stretch, and the band's flat_base part (the profile there perturbed by "
            f"{FLAT_SIGMA_M * 1e6:g} µm) is an estimate of that freedom on the apparent area and "
            "the zone loads, not a bound; its smaller effect on the real area and the "
            "separations is not added",
        )
    else:
        flat = None
    grid = grid_component(preset, macro, sampled)
    grid_factors = flexible_grid_factors(e_eff) if not rigid else rigid_grid_factors(e_eff)
    grid = {q: w * grid_factors.get(q, 1.0) for q, w in grid.items()}
    if rigid and rigid_minus_flexible and flexible_end_pixel_share is not None:
        # auto answered with the rigid shape after comparing it to the bending ski, whose
        # answer is the truth it stands for: its error is the difference (ski_model) plus the
        # bending ski's grid error, so the apparent area's grid part is the bending ski's
        grid_factors = {
            **grid_factors,
            "apparent_contact_area": flexible_area_grid_factor_at(e_eff),
        }
        grid["apparent_contact_area"] = (
            K_END_PIXELS * flexible_end_pixel_share * grid_factors["apparent_contact_area"]
        )
    components["macro_grid"] = grid
    components["table_interpolation"] = _table_component(table, macro, porosity, e_eff)
    if rigid and rigid_minus_flexible:
        # the comparison names the apparent area "apparent_area"
        diff = {
            ("apparent_contact_area" if k == "apparent_area" else k): v
            for k, v in rigid_minus_flexible.items()
        }
        components["ski_model"] = {k: abs(v) for k, v in diff.items() if k in QUANTITIES}
    elif rigid and bending_ignored:
        components["ski_model"] = bending_ignored_widths(e_eff)
        not_covered.insert(
            0,
            f"the ski's bending on the snow: auto answered with the rigid shape ({bending_ignored})"
            "; the band's ski_model part is the largest rigid-versus-bending difference measured "
            "on 32 comparable ski designs at this snow modulus "
            "(docs/studies/auto-without-beam.json), not this ski's own",
        )
    widths = combine(components)
    share = grid_above_share_at(e_eff)
    widths_above = {}
    for q in GRID_ONE_SIDED:
        if q in widths:
            parts = {src: ws.get(q) for src, ws in components.items()}
            widths[q], widths_above[q] = one_sided_widths(parts, e_eff, share)
    if min_separation_unresolved:
        widths["min_average_separation"] = float("nan")
        # its parts mean nothing without a converged value: none is listed (the page and the
        # JSON would show a grid part of a quantity that has no band)
        for ws in components.values():
            ws.pop("min_average_separation", None)
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
            if flat is not None and math.isfinite(flat.zone_widths[i]):
                parts.append(flat.zone_widths[i])
            alt_z = sampled.alternative_zone_widths
            if alt_z is not None and math.isfinite(alt_z[i]):
                parts.append(alt_z[i])
        parts.append(g)
        if rigid_minus_flexible and "ski_model" in components and z.load_share > 0:
            parts.append(abs(rigid_minus_flexible.get("rear_load_share", 0.0)) / z.load_share)
        elif "ski_model" in components:
            # bending ignored: the study measured no zone loads; the apparent area's width
            # stands in for them (a stand-in, not a measurement)
            parts.append(components["ski_model"].get("apparent_contact_area", 0.0))
        zone_widths.append(math.sqrt(sum(p * p for p in parts)))
    line_band = None
    if sampled is not None and sampled.line_half_width_pa is not None:
        nom = np.nan_to_num(macro.pressure_line_pa)
        line_band = (
            np.maximum(nom - sampled.line_half_width_pa, 0.0),
            nom + sampled.line_half_width_pa,
        )
    # the studies that stand for this answer (none for auto's compared or rigid-for-bending
    # answers, nor for a design beam)
    tail_of = (
        None
        if "ski_model" in components
        else "identified_beam"
        if identified
        else "network"
        if network_served
        else None
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
        flat_base=flat_base,
        unmeasured_stiffness=unmeasured,
        held_out_error=held_out,
        sparse_sampling=sparse,
        beam_draws_failed=None if rigid else draws_failed,
        beam_scale_reduced=scale_reduced if has_sigma and draws_failed is None else None,
        profile_draws_failed=draws_failed if rigid else None,
        bending_ignored=bending_ignored if "ski_model" in components and bending_ignored else None,
        grid_factors=grid_factors,
        widths_above=widths_above,
        grid_above_share=share,
        alternative_beams=(0, 0)
        if sampled is None
        else (sampled.alternatives_solved, sampled.alternatives_failed),
        profile_scale=identified_sigma_scale_at(e_eff, loaded_cases(record))
        if rigid and has_sigma and identified
        else None,
        studied_tail=None
        if tail_of is None
        else studied_tail_at(ski_model_used, e_eff, loaded_cases(record))
        if tail_of == "identified_beam"
        else network_studied_tail_at(e_eff),
        studied_tail_of=tail_of,
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


def _interval(value: float, width: float) -> list[float]:
    """The 90 % interval of a zone load of relative half-width ``width``: value × (1 ± width),
    the lower end at 0 when the band is wider than the load itself (a zone load cannot be
    negative; the zones' loads share the ski's load, so their errors are not ratios)."""
    return [_round(max(value * (1 - width), 0.0), 6), _round(value * (1 + width), 6)]


def interval_90(value: float, width: float, width_above: float | None = None) -> list[float | None]:
    """The 90 % interval of a positive quantity (the metrics, the apparent contact area and
    pressure) of relative half-width ``width``: symmetric in log, value × (1 − width) …
    value ÷ (1 − width); no upper end (None) when ``width`` ≥ 1 (the lower end is then 0).
    With ``width_above`` (a band whose parts are not all symmetric, :data:`GRID_ONE_SIDED`)
    the upper end is value ÷ (1 − width_above), None when that is ≥ 1.

    Their errors are ratios: the answer to a stiffer or softer profile is the value times a
    factor, and a factor of 0.6 is as likely as one of 1 / 0.6. Value × (1 ± width), served
    until 2026-11-29, reached only width / (1 + width) above the value: every bending-ski
    truth outside its band at 2000 MPa over the eleven own-ski populations (71 of 2184) lay
    above it, and the log band holds them (docs/limits.md "The bands across eleven
    populations"). The lower end is as before, so an answer's band only grew above."""
    above = width if width_above is None or not math.isfinite(width_above) else width_above
    lo = 0.0 if width >= 1.0 else _round(value * (1.0 - width), 6)
    hi = None if above >= 1.0 else _round(value / (1.0 - above), 6)
    return [lo, hi]


def inside_interval(err, below, above) -> np.ndarray:
    """Whether each truth lies in its served interval value × (1 − below) … value ÷ (1 −
    above) (:func:`interval_90`), for answers ``err`` = value / truth − 1 off (arrays or
    floats): truth ≥ value (1 − below) ⇔ 1 / (1 + err) ≥ 1 − below; truth ≤ value / (1 −
    above) ⇔ err ≥ −above (an ``above`` ≥ 1 has no upper end)."""
    err, below, above = (np.asarray(a, dtype=float) for a in (err, below, above))
    return (1.0 / (1.0 + err) >= 1.0 - below) & (err >= -above)


def reach_over_side(err, below, above) -> np.ndarray:
    """How far each truth lies from its answer, in units of the band's half-width on the
    truth's side: the smallest factor k for which the interval of half-widths k × below,
    k × above holds it (:func:`inside_interval`); 0 for an exact answer, inf for a side of 0
    with the truth beyond it."""
    err, below, above = (np.asarray(a, dtype=float) for a in (err, below, above))
    dist = np.where(err >= 0, err / (1.0 + err), -err)
    side = np.where(err >= 0, below, above)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(dist > 0, dist / side, 0.0)


#: how far [m] a footprint may reach beyond the measured stretch's last knot before the answer
#: warns: half the stiffness knots' spacing (the knot's hat function still reaches there)
UNMEASURED_REACH_M = 0.025


def unmeasured_contact(identified: dict | None, macro) -> tuple[float, float, float, float] | None:
    """(footprint rear end, front end, measured stretch's first, last knot) [m] when the
    bending ski's contact zones reach more than :data:`UNMEASURED_REACH_M` beyond the stretch
    where the camber cases set EI (:func:`solvers.identify.measured_stretch`); else None (also
    for an identification that stores no data share)."""
    if not identified or "stiffness_data_share" not in identified or not macro.zones:
        return None
    stretch = measured_stretch(identified["knots_m"], identified["stiffness_data_share"])
    rear = min(z.start_m for z in macro.zones)
    front = max(z.end_m for z in macro.zones)
    if stretch is None:
        return rear, front, float("nan"), float("nan")
    if rear < stretch[0] - UNMEASURED_REACH_M or front > stretch[1] + UNMEASURED_REACH_M:
        return rear, front, stretch[0], stretch[1]
    return None


#: held-out RMS ÷ device noise above which an identified beam's answers are warned about
#: (:func:`held_out_excess`). The band's factors were calibrated on skis whose beams predict
#: their held-out camber cases at 0.99-1.11 × the noise (27 of 28; offcentre-peak on 9 × 5 at
#: 1.26 ×); a ratio of 1.2 is a model error of 0.66 × the noise (about 2 µm at 3 µm noise) that
#: the noise does not explain, far beyond the ratio's sampling spread over a few thousand
#: held-out samples (docs/limits.md, "Beams that predict their held-out cases above the noise")
HELD_OUT_WARN_RATIO = 1.2


def sparse_sampling(record) -> tuple | None:
    """(sample spacing [mm], the measured spacing standing for it [mm], its accuracy row, the
    9 × 5 grid's shares or None) of a ski whose camber measurements are sampled coarser than
    the recommended spacing (:func:`app.service.band_calibration.sampling_accuracy`); None
    otherwise or without measurements."""
    meas = getattr(record, "measurements", None)
    if meas is None or np.size(meas.positions_m) < 2:
        return None
    spacing_mm = meas.sample_spacing_mm
    found = band_calibration.sampling_accuracy(spacing_mm, loaded_cases(record))
    return None if found is None else (spacing_mm, *found)


def held_out_excess(identified: dict | None) -> tuple[float, float] | None:
    """(held-out RMS, device noise) [m] of a stored identification whose beam predicts the
    camber cases held out from its fit worse than :data:`HELD_OUT_WARN_RATIO` × the noise;
    None for one within it or without a held-out check."""
    attrs = (identified or {}).get("attrs", {})
    try:
        rms, noise = float(attrs["held_out_rms_m"]), float(attrs["noise_m"])
    except (KeyError, TypeError, ValueError):
        return None
    if not (math.isfinite(rms) and math.isfinite(noise) and noise > 0):
        return None
    return (rms, noise) if rms > HELD_OUT_WARN_RATIO * noise else None


def band_json(band: Band, answer: dict) -> tuple[dict, list[dict]]:
    """The ``band`` section of an answer (intervals in the answer's units), and the warnings it
    raises. Adds ``load_band_90_n`` to each zone of ``answer["apparent"]["zones"]``."""
    intervals, rel = {}, {}
    for q, (section, key) in ANSWER_KEYS.items():
        w = band.widths.get(q, float("nan"))
        v = answer[section][key]
        rel[q] = _round(w)
        intervals[key] = interval_90(v, w, band.width_above(q)) if math.isfinite(w) else None
    rel_above = {q: _round(band.width_above(q)) for q in GRID_ONE_SIDED if q in band.widths}
    # the mean apparent pressure is F / A: the apparent area's band inverted, which a band
    # symmetric in log is with the same widths, its sides swapped (an area too large is a
    # pressure too small)
    w_a = band.widths.get("apparent_contact_area", float("nan"))
    v = answer["apparent"]["mean_pressure_kpa"]
    intervals["mean_pressure_kpa"] = (
        interval_90(v, band.width_above("apparent_contact_area"), w_a)
        if math.isfinite(w_a)
        else None
    )
    for z, w in zip(answer["apparent"]["zones"], band.zone_load_widths, strict=False):
        z["load_band_90_n"] = _interval(z["load_n"], w)
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
    if band.flat_base is not None:
        length, mid, w_flat = band.flat_base
        warnings.append(
            {
                "code": "flat_base",
                "detail": f"the loaded base lies within {FLAT_GAP_M * 1e6:g} µm of the flat over "
                f"{length * 1e3:.0f} mm around {mid * 1e3:.0f} mm: camber measurements with a "
                "few µm of noise cannot fix which part of that stretch touches the snow first, "
                f"and a {FLAT_SIGMA_M * 1e6:g} µm change there moves the apparent contact area "
                f"by ±{w_flat:.0%} (90 %); the band includes it (band.components.flat_base). "
                "A heavier load makes the answer less sensitive to that stretch",
            }
        )
    if band.unmeasured_stiffness is not None:
        rear, front, lo, hi = band.unmeasured_stiffness
        where = (
            "the camber cases bent it nowhere enough to set EI"
            if not math.isfinite(lo)
            else f"the camber cases set EI only between {lo * 1e3:.0f} and {hi * 1e3:.0f} mm"
        )
        warnings.append(
            {
                "code": "stiffness_not_measured",
                "detail": f"the bending ski touches the snow from {rear * 1e3:.0f} to "
                f"{front * 1e3:.0f} mm, but {where} (the device's loads did not bend the ski "
                "beyond): there the identification's smoothing prior sets EI. The band's beam "
                "draws carry the prior's uncertainty (band.components.camber_model); camber "
                "cases with loads nearer the tip and tail would measure it",
            }
        )
    if band.held_out_error is not None:
        rms, noise = band.held_out_error
        excess = math.sqrt(max(rms**2 - noise**2, 0.0))
        warnings.append(
            {
                "code": "beam_held_out_error",
                "detail": f"the identified beam predicts the camber cases held out from its fit "
                f"to {rms * 1e6:.2f} µm RMS, {rms / noise:.2f} × the device noise "
                f"({noise * 1e6:.2f} µm): a model error of about {excess * 1e6:.1f} µm that the "
                "noise does not explain. The band was calibrated on skis whose beams nearly all "
                "predict their held-out cases within 1.11 × the noise, so this answer may be "
                "further off than its band says. More camber cases (at least 13 loads × 9 "
                "positions, the unloaded profile included) usually fix the beam better; on a "
                "ski measured so, check that both sides and the device agree",
            }
        )
    if band.sparse_sampling is not None:
        spacing, measured, ((lo, hi), rigid_share, flex_share), coarse = band.sparse_sampling
        best = band_calibration.SPACING_ACCURACY[band_calibration.RECOMMENDED_SAMPLE_SPACING_MM]
        fewer = (
            f"; with 9 loads × 5 positions, nearer this ski's cases, {100 * coarse[0]:.0f} % "
            f"and {100 * coarse[1]:.0f} %"
            if coarse is not None
            else ""
        )
        warnings.append(
            {
                "code": "sparse_camber_sampling",
                "detail": f"the ski's camber was sampled every {spacing:.3g} mm: on four "
                f"comparable skis sampled every {measured:g} mm, {100 * rigid_share:.0f} % of "
                f"rigid and {100 * flex_share:.0f} % of bending apparent areas were within 3 % "
                f"of the truth ({100 * best[1]:.0f} % and {100 * best[2]:.0f} % sampled every "
                f"{band_calibration.RECOMMENDED_SAMPLE_SPACING_MM:g} mm; 13 loads × 9 "
                f"positions{fewer}), loaded profiles "
                f"{lo:.2f}–{hi:.2f} µm off, and a few answers more than 3 % off lay outside "
                "their band. Measure every "
                f"{band_calibration.RECOMMENDED_SAMPLE_SPACING_MM:g} mm for the most accurate "
                "answers",
            }
        )
    if band.beam_draws_failed is not None:
        solved, drawn = band.beam_draws_failed
        warnings.append(
            {
                "code": "band_beam_draws_failed",
                "detail": f"only {solved} of the {drawn} plausible beams drawn from the "
                "identification converged on this snow, so the error band leaves out the "
                "identified beam's own uncertainty (band.not_covered): the answer may be "
                "further off than its band says",
            }
        )
    if band.beam_scale_reduced is not None:
        scale, solved, drawn = band.beam_scale_reduced
        warnings.append(
            {
                "code": "band_beam_scale_reduced",
                "detail": f"at the calibrated factor (× {scale:g} on the identification's "
                f"covariance) only {solved} of the {drawn} plausible beams converged on this "
                f"snow, so the band's camber part is from beams drawn at × {band.beam_scale:g}: "
                "the factors were calibrated on beams with 50 mm stiffness knots, and this "
                "answer's band is less tested than most",
            }
        )
    if band.profile_draws_failed is not None:
        solved, drawn = band.profile_draws_failed
        warnings.append(
            {
                "code": "band_profile_draws_failed",
                "detail": f"only {solved} of the {drawn} perturbed loaded profiles converged on "
                "this snow, so the error band leaves out the camber model's uncertainty "
                "(band.not_covered): the answer may be further off than its band says",
            }
        )
    tail = None
    if band.studied_tail is not None and math.isfinite(w_a):
        share, k, n = band.studied_tail
        tail = {
            "answers": n,
            "outside_share": share,
            "farthest_over_half_width": k,
            # the apparent area's band stretched as far as the farthest studied truth outside
            "contact_area_cm2_at_farthest": interval_90(
                answer["apparent"]["contact_area_cm2"],
                k * w_a,
                k * band.width_above("apparent_contact_area"),
            ),
            "of": band.studied_tail_of,
            "source": "docs/studies/population-bands.md (identified beams of fourteen own-ski "
            "populations, this ski model, measurement grid and snow modulus)"
            if band.studied_tail_of != "network"
            else "docs/camber-identification.md, 'With the service's default network' (rigid "
            "answers of camber networks: the demo skis' and four unseen designs' on 13 × 9 "
            "cases, this snow modulus; scripts/network_band_study.py)",
        }
    out = {
        "level": 0.9,
        "relative_half_width": rel,
        # the half-width above the answer, where it differs from the one below (the grid part
        # of these quantities is a bias, kept above at grid_above_share of its size)
        "relative_half_width_above": rel_above,
        "grid_above_share": _round(band.grid_above_share)
        if band.grid_above_share is not None
        else None,
        "intervals": intervals,
        # how far outside the band the studied answers of this kind fell (the band is 90 %:
        # some truths lie outside by design); None where the studies do not stand for it
        "studied_tail": tail,
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
            # the calibrated factor, when too few beams converged at it (then halved)
            "beam_deviation_scale_calibrated": None
            if band.beam_scale_reduced is None
            else band.beam_scale_reduced[0],
            # the factor on the identified profile's spread (rigid answers of an identified
            # beam; per snow modulus and measurement grid)
            "profile_sd_scale": band.profile_scale,
            # the identification's alternative beams the bending ski was solved again with
            # (component beam_alternatives: their largest deviation) and those left out
            "alternative_beams": band.alternative_beams[0],
            "alternative_beams_not_converged": band.alternative_beams[1],
            "seed": BAND_SEED,
        },
        # the factors on the macro grid part per quantity (one not named: 1)
        "macro_grid_factor": None
        if band.grid_factors is None
        else {q: _round(k) for q, k in band.grid_factors.items()},
        "not_covered": band.not_covered,
        "method": "relative 90 % half-widths per source combined in quadrature: camber model "
        "(the answer solved again with perturbed loaded profiles, or for the bending ski with "
        "plausible beams drawn from the identification, and its largest deviation over the "
        "identification's alternative beams: other fits that explain the measurements almost "
        "as well), macro grid (the answer's end-pixel "
        "share and its difference to the grid twice as coarse, and the preset's width measured "
        "by skisnow bench accuracy), table interpolation (leave-one-out on the table's nodes), "
        "in the flat-base regime the answer solved again with the stretch near the flat "
        "perturbed by the data's blind spot, and, when auto answers with the rigid shape, its "
        "measured difference to the bending ski (or, without a beam, the largest difference "
        "measured on comparable skis); the intervals are symmetric in log, value × (1 − w) "
        "… value ÷ (1 − w), zone loads value × (1 ± w); the apparent area's grid part is a "
        "bias (the default grid's area is too large): it is added below the answer and kept "
        "above at grid_above_share of its size, so its interval is value × (1 − w) … value ÷ "
        "(1 − w_above) (relative_half_width_above), the mean apparent pressure's the same "
        "sides swapped (docs/limits.md, Error band)",
    }
    return out, warnings
