"""One ski's flex sheet for the technician (issue #14; docs/flex.md); pair and ranking:
:mod:`.compare`.

Service functions over :mod:`solvers.flex`: they pick the ski's profile model (the one every
contact answer uses, :mod:`app.service.profiles`), check the request against the model's range,
add the kick-zone load share on snow (the bending ski of :mod:`solvers.flexible` on the preset's
grid) and the band from the camber model, and shape JSON in technician units (unit in every key).

Band (90 % half-width, absolute, in the quantity's unit)
    The sheet is computed again for plausible camber models and ``Z90 · rms(draw − nominal)``
    is the band (:data:`solvers.band.Z90`), as the contact answers' band does
    (:mod:`app.service.band`):

    - identified beam: :data:`app.service.band.BEAM_SAMPLES` beams drawn from the identification's
      covariance in antithetic pairs, deviations × the largest factor of the ski's measurement
      grid (:func:`app.service.band_sampling.sheet_beam_scale`; :data:`BEAM_SCALE` overrides
      it when set, as ``scripts/flex_band_check.py`` does), seed
      :data:`app.service.band.BAND_SEED` (:func:`app.service.band.beam_models` on snow, the same
      draws on the flat);
    - camber network: :data:`app.service.band.PROFILE_SAMPLES` smooth profile perturbations of the
      network's own error (:func:`app.service.band.camber_sigma_m`), the same field at every load;
    - design beam: taken as exact (band 0), as in every answer.

    On snow the kick-zone share's band adds the difference between the preset's grid and the
    grid twice as coarse in quadrature.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
from skisnow.app import units
from skisnow.app.presets import DEFAULT_PRESET, get_preset
from skisnow.app.service.band import (
    BAND_SEED,
    BEAM_SAMPLES,
    PROFILE_CORRELATION_M,
    PROFILE_SAMPLES,
    beam_models,
    camber_sigma_m,
)
from skisnow.app.service.band_sampling import sheet_beam_scale
from skisnow.app.service.catalogue import Catalogue, Ski
from skisnow.app.service.gate import gated
from skisnow.app.service.profiles import profile_model
from skisnow.app.snow import snow_record
from skisnow.app.storage.common import code_version
from skisnow.app.storage.skis import identification_for_sampling
from skisnow.solvers.band import Z90, unit_perturbations
from skisnow.solvers.beam import BeamFlexibility, BeamSki
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.errors import InputError, NotConvergedError, OutOfRangeError
from skisnow.solvers.flex import (
    CLOSED_GAP_M,
    CONTACT_GAP_M,
    GLIDE_POSITION_M,
    POCKET_POSITION_M,
    ClosingLoad,
    FlatProfile,
    FlexSheet,
    beam_profile,
    closing_load,
    flex_sheet,
    span_load_share,
)
from skisnow.solvers.flexible import solve_flexible
from skisnow.solvers.identify import sample_beams

__all__ = [
    "CRITERIA",
    "OPEN_GAP_M",
    "PAIR_LOAD_POSITION_MM",
    "FlexRequest",
    "compute_sheet",
    "field_error",
    "flex_sheet_answer",
    "pocket_height",
    "verdict",
]

#: where the pair's and the ranking's contact metrics load the ski: full weight at the glide
#: check's foot position (gliding on one ski) [mm]
PAIR_LOAD_POSITION_MM = GLIDE_POSITION_M * 1e3
#: resolution floors of a pair difference, per kind of number (below these a difference is
#: not resolved by the sheet itself): lengths and positions one node spacing (set per ski),
#: loads the bisection tolerance, shares 0.1 percentage point, gaps 1 µm
SHARE_FLOOR_PERCENT = 0.1
GAP_FLOOR_MM = 1e-3

#: ranking criteria: (metric key of the contact answer, larger is better, why; docs/physics.md §1)
CRITERIA = {
    "real_area": (
        "total_real_contact_area_mm2",
        True,
        "largest real contact area: cold, abrasive snow, where friction is dry and a larger "
        "real area spreads the load over more asperities (lower real pressure, less "
        "ploughing and wear; docs/physics.md §1)",
    ),
    "reciprocal_separation": (
        "total_reciprocal_separation_m",
        False,
        "smallest total reciprocal separation: wet snow, where the melt-water film's viscous "
        "shear and capillary bridges grow with 1/separation (docs/physics.md §1)",
    ),
}


def field_error(exc_type, field: str, message: str):
    """``exc_type(message)`` that names the request field it comes from (the API puts it in the
    problem body's ``errors``)."""
    exc = exc_type(message)
    exc.field = field
    return exc


@dataclasses.dataclass(frozen=True)
class FlexRequest:
    """One flex sheet in technician units (validated by the route)."""

    ski: str
    body_weight_kg: float
    snow_modulus_mpa: float | None = None
    porosity: float | None = None
    base_modulus_mpa: float = 700.0
    poisson_ratio: float = 0.3
    preset: str = DEFAULT_PRESET
    #: the snow preset the numbers came from (app/snow.py), None for raw numbers
    snow: str | None = None


# ----------------------------------------------------------------------------- profile models


def _beam_fn(ski: Ski):
    """The flat-profile callable of the beam the ski's profile model answers with (its
    flexibility is the profile model's own), or None for a network ski."""
    pm = profile_model(ski.record)
    if pm.beam is None:
        return None

    def fn(load_n: float, load_position_m: float) -> FlatProfile:
        res = pm.beam_result(load_n, load_position_m)
        return FlatProfile(res.positions_m, res.gap_m, res.reaction_n, load_n, load_position_m)

    return fn


#: node spacing of the band's beam draws and of their nominal [m]: twice the served beam's
#: 1 mm, as the contact band solves its draws on the grid twice as coarse (a 1 mm flexibility
#: is 32 MB, held per draw and ski)
BAND_NODE_SPACING_M = 2e-3


def _coarse(beam: BeamSki) -> BeamSki:
    """``beam`` on every k-th node, k = round(:data:`BAND_NODE_SPACING_M` / dx) (≥ 1)."""
    k = max(1, round(BAND_NODE_SPACING_M / beam.spacing_m))
    if k == 1:
        return beam
    sl = slice(None, None, k)
    return BeamSki(beam.positions_m[sl], beam.bending_stiffness_nm2[sl], beam.unloaded_gap_m[sl])


def _network_fn(record, delta_m: np.ndarray | None = None):
    from skisnow.solvers import camber

    def fn(load_n: float, load_position_m: float) -> FlatProfile:
        x, g = camber.predict_profile(record.network, load_n, load_position_m)
        if delta_m is not None:
            g = np.maximum(g + delta_m, 0.0)
        return FlatProfile(x, g, None, load_n, load_position_m)

    return fn


def _profile_fn(ski: Ski):
    fn = _beam_fn(ski)
    return fn if fn is not None else _network_fn(ski.record)


#: the beam draws' factor for every ski [-]; None: each ski's own
#: (:func:`app.service.band_sampling.sheet_beam_scale`). A study varies it
BEAM_SCALE: float | None = None


def _beam_scale(record) -> float:
    return BEAM_SCALE if BEAM_SCALE is not None else sheet_beam_scale(record)


def _draw_fns(ski: Ski) -> tuple[list, str, float | None]:
    """Profile callables of the plausible camber models (module docstring), the band's words and
    the deviation scale (None for profile perturbations)."""
    rec = ski.record
    pm = profile_model(rec)
    if pm.source == "design_beam":
        return [], "design beam stored with the ski, taken as exact", None
    if pm.source == "identified_beam":
        scale = _beam_scale(rec)
        store = rec.cache.get("flex_draws")
        if store is None or store[0] is not rec.identified:
            ib = identification_for_sampling(rec.identified)
            beams = (
                []
                if ib is None
                else sample_beams(ib, BEAM_SAMPLES, BAND_SEED, scale=scale, antithetic=True)
            )
            coarse = [_coarse(b) for b in ([pm.beam, *beams] if beams else [])]
            store = (rec.identified, [(b, BeamFlexibility(b)) for b in coarse])
            rec.cache["flex_draws"] = store
        if not store[1]:
            return [], "identified beam: no covariance stored with the identification", None
        fns = [beam_profile(b, f) for b, f in store[1]]
        return (
            fns,
            f"identified beam: {len(fns) - 1} plausible beams (EI(X), c(X)) drawn from the "
            f"fit's covariance in antithetic pairs, deviations × {scale:g}, seed "
            f"{BAND_SEED}; their spread about the served beam, both on "
            f"{BAND_NODE_SPACING_M * 1e3:g} mm nodes",
            scale,
        )
    probe = _network_fn(rec)(float(np.mean(ski.load_range_n)), float(np.mean(ski.position_range_m)))
    x_net = probe.positions_m
    sigma, source = camber_sigma_m(rec, x_net)
    if sigma is None:
        return [], "camber network: " + source, None
    unit = unit_perturbations(x_net, PROFILE_CORRELATION_M, PROFILE_SAMPLES, BAND_SEED)
    return (
        [_network_fn(rec, u * sigma) for u in unit],
        f"{source}; {PROFILE_SAMPLES} smooth perturbations (ℓ = "
        f"{PROFILE_CORRELATION_M * 1e3:g} mm, seed {BAND_SEED}), the same at every load",
        None,
    )


#: quantities that jump between draws rather than spread about the served value: the wheelbase
#: switches between pairs of contact zones when a stretch of the base near the flat touches or
#: not (docs/flex.md, "The band"). Their band is at least the farthest draw's distance from the
#: served beam's value and one node of the draws (:data:`BAND_NODE_SPACING_M`), on which they
#: are resolved: on the own-ski study's 36 skis (``scripts/flex_band_check.py --own-ski-work``)
#: Z90 · RMS alone covered 82 % of the wheelbases' actual errors, this 90 %
JUMPING_QUANTITIES = ("wheelbase_m",)


def _jump_half_width(nominal: float, samples: list[float], half: float) -> float:
    """The band of a :data:`JUMPING_QUANTITIES` quantity: the larger of the Z90 · RMS half-width
    ``half``, the farthest finite sample's distance from ``nominal`` and one draw node."""
    v = np.asarray(samples, dtype=float)
    v = v[np.isfinite(v)]
    if not math.isfinite(half) or not math.isfinite(nominal):
        return half
    far = float(np.max(np.abs(v - nominal))) if v.size else 0.0
    return max(half, far, BAND_NODE_SPACING_M)


def _half_width(nominal: float, samples: list[float]) -> float:
    """Absolute 90 % half-width ``Z90 · rms(sample − nominal)`` over the finite samples; NaN
    with fewer than two or a non-finite nominal (as :func:`solvers.band.sampled_half_width`)."""
    v = np.asarray(samples, dtype=float)
    v = v[np.isfinite(v)]
    if v.size < 2 or not math.isfinite(nominal):
        return float("nan")
    return float(Z90 * np.sqrt(np.mean((v - nominal) ** 2)))


# ----------------------------------------------------------------------------- the sheet


def _check_request(ski: Ski, req: FlexRequest) -> float:
    """Body weight [N] after the range checks (named fields)."""
    w = req.body_weight_kg
    if not (isinstance(w, (int, float)) and math.isfinite(w) and w > 0):
        raise field_error(InputError, "body_weight_kg", f"body_weight_kg must be > 0, got {w!r}")
    w_n = units.kg_to_n(w)
    lo, hi = ski.load_range_n
    if not (lo * (1 - 1e-9) <= 0.5 * w_n and w_n <= hi * (1 + 1e-9)):
        raise field_error(
            OutOfRangeError,
            "body_weight_kg",
            f"body_weight_kg {w:g}: half and full weight must lie in the loads the ski "
            f"{ski.name!r} covers ({units.n_to_kg(lo):.4g} … {units.n_to_kg(hi):.4g} kg), "
            f"i.e. {2 * units.n_to_kg(lo):.4g} … {units.n_to_kg(hi):.4g} kg; its camber model is "
            "not extrapolated",
        )
    p_lo, p_hi = ski.position_range_m
    for x in (POCKET_POSITION_M, GLIDE_POSITION_M):
        if not (p_lo - 1e-12 <= x <= p_hi + 1e-12):
            raise field_error(
                OutOfRangeError,
                "ski",
                f"the ski {ski.name!r} covers load positions {p_lo * 1e3:g} … {p_hi * 1e3:g} mm, "
                f"not the flex sheet's {x * 1e3:g} mm",
            )
    if req.snow_modulus_mpa is not None:
        e = req.snow_modulus_mpa
        if not (math.isfinite(e) and 1 <= e <= 2000):
            raise field_error(
                InputError, "snow_modulus_mpa", f"snow_modulus_mpa must be in [1, 2000], got {e}"
            )
    if req.porosity is not None and not (0 <= req.porosity < 1):
        raise field_error(InputError, "porosity", f"porosity must be in [0, 1), got {req.porosity}")
    return w_n


def _snow_shares(ski: Ski, model, sheet: FlexSheet, e_eff: float, *, tol: float = 1e-8):
    """Kick-zone load share on snow under W/2 and W at the pocket position (bending ski)."""
    span = (sheet.wax_zone.start_m, sheet.wax_zone.end_m)
    out = []
    for f in (0.5 * sheet.body_weight_n, sheet.body_weight_n):
        res = solve_flexible(model, f, sheet.pocket_position_m, e_eff, tol=tol)
        if not res.converged:
            raise NotConvergedError(f"the bending ski on snow did not converge: {res.message}")
        out.append(span_load_share(model.positions_m, res.extra["beam_reaction_row_n"], span))
    return out


#: contact threshold of a camber network's profile [m]: its contact zones are 0 to about its
#: own error (1.1 µm RMS on the demo skis), not exactly 0 as a beam's
NETWORK_CONTACT_GAP_M = 2e-6


def _sheet(ski: Ski, w_n: float, fn=None) -> FlexSheet:
    network = profile_model(ski.record).beam is None
    return flex_sheet(
        fn if fn is not None else _profile_fn(ski),
        w_n,
        max_closing_load_n=ski.load_range_n[1],
        min_closing_load_n=ski.load_range_n[0],
        contact_gap_m=NETWORK_CONTACT_GAP_M if network else CONTACT_GAP_M,
    )


#: "open at half weight" for the verdict: at least this gap under the foot [m] (three layers of
#: hard kick wax stay off the flat; the sheet's second wax gap)
OPEN_GAP_M = 0.15e-3
#: where the pocket height is read when the wax zone is closed at half weight: this far on either
#: side of the foot [m]
POCKET_HEIGHT_HALF_SPAN_M = 0.25


def _open_limit(ski: Ski, sheet: FlexSheet) -> ClosingLoad:
    """The load under which the gap under the foot falls to :data:`OPEN_GAP_M` (bisection as the
    closing load's): twice it is the heaviest skier the ski stands open for at half weight."""
    return closing_load(
        _profile_fn(ski),
        sheet.pocket_position_m,
        open_load_n=0.5 * sheet.body_weight_n,
        max_load_n=ski.load_range_n[1],
        min_load_n=ski.load_range_n[0],
        closed_gap_m=OPEN_GAP_M,
    )


def _suit_range_kg(closing: ClosingLoad, open_limit: ClosingLoad) -> tuple[float, float] | None:
    """(lightest, heaviest) body weight [kg] the ski suits: closed at full weight (W ≥ closing
    load) and ≥ :data:`OPEN_GAP_M` under the foot at half weight (W/2 ≤ the open limit); None
    when no weight in the camber model's range does (closed at its lightest load, or not
    closing up to its heaviest)."""
    if not closing.closes or closing.closed_at_min:
        return None
    low = units.n_to_kg(closing.load_n)
    if open_limit.closed_at_min:
        high = 2 * units.n_to_kg(open_limit.bracket_n[1])
    elif not open_limit.closes:
        high = 2 * units.n_to_kg(open_limit.max_load_n)
    else:
        high = 2 * units.n_to_kg(open_limit.load_n)
    return (low, high) if high >= low else None


def verdict(w_kg: float, closing: ClosingLoad, open_limit: ClosingLoad) -> dict:
    """Whether the ski suits a skier of ``w_kg`` [kg], in words, with the weights it suits."""
    rng = _suit_range_kg(closing, open_limit)
    c_kg = units.n_to_kg(closing.load_n)
    rule = (
        f"suits W when the pocket is closed at full weight (≤ {CLOSED_GAP_M * 1e3:.2f} mm under "
        f"the foot at W) and stands open at half weight (≥ {OPEN_GAP_M * 1e3:.2f} mm at W/2), "
        f"foot {POCKET_POSITION_M * 1e3:g} mm from the balance point, on the rigid flat"
    )
    if closing.closed_at_min:
        lo_kg = units.n_to_kg(closing.bracket_n[1])
        kind, text = (
            "too_soft",
            (
                f"too soft for {w_kg:g} kg: closed already at {lo_kg:.0f} kg, the lightest "
                "load its camber model covers; it suits no adult skier"
            ),
        )
    elif not closing.closes:
        kind, text = (
            "too_stiff",
            (
                f"too stiff for {w_kg:g} kg: does not close up to "
                f"{units.n_to_kg(closing.max_load_n):.0f} kg"
            ),
        )
    elif rng is None:
        kind, text = (
            "too_soft",
            (
                f"too soft for {w_kg:g} kg: closes at {c_kg:.0f} kg, but is below "
                f"{OPEN_GAP_M * 1e3:.2f} mm under the foot at any half weight above that"
            ),
        )
    elif w_kg < rng[0]:
        kind, text = "too_stiff", f"too stiff for {w_kg:g} kg: closes at {c_kg:.0f} kg"
    elif w_kg > rng[1]:
        kind, text = "too_soft", f"too soft for {w_kg:g} kg: closes at {c_kg:.0f} kg"
    else:
        kind, text = "suits", f"suits {w_kg:g} kg: closes at {c_kg:.0f} kg"
    if rng is not None:
        text += f"; suits about {rng[0]:.0f}–{rng[1]:.0f} kg"
    return {
        "kind": kind,
        "text": text,
        "suits_body_weight_kg": None if rng is None else [round(rng[0]), round(rng[1])],
        "open_limit_kg": sig_or_none(units.n_to_kg(open_limit.load_n), 4),
        "rule": rule,
    }


def _max_gap(profile: FlatProfile, span: tuple[float, float]) -> float:
    x, g = profile.positions_m, profile.gap_m
    inside = (x > span[0]) & (x < span[1])
    ends = np.interp(span, x, g)
    return float(max(np.max(ends), np.max(g[inside], initial=0.0)))


def pocket_height(sheet: FlexSheet) -> dict:
    """The pocket's height at half and full weight: the largest gap over the wax zone and the
    gap under the foot [mm]; where the wax zone is closed at half weight, the largest gap within
    :data:`POCKET_HEIGHT_HALF_SPAN_M` of the foot (said in ``span``)."""
    wax = sheet.wax_zone
    if wax.is_open:
        span = (wax.start_m, wax.end_m)
        where = f"over the wax zone (pocket at {CLOSED_GAP_M * 1e3:.2f} mm under half weight)"
    else:
        x0 = sheet.pocket_position_m
        span = (x0 - POCKET_HEIGHT_HALF_SPAN_M, x0 + POCKET_HEIGHT_HALF_SPAN_M)
        where = (
            f"within {POCKET_HEIGHT_HALF_SPAN_M * 1e3:g} mm of the foot (the wax zone is closed "
            "at half weight)"
        )
    out = {"span_mm": [_mm(v) for v in span], "span": where}
    for tag, prof in (("half_weight", sheet.half), ("full_weight", sheet.full)):
        out[tag] = {
            "largest_gap_mm": _mm(_max_gap(prof, span), 3),
            "foot_gap_mm": _mm(
                float(np.interp(sheet.pocket_position_m, prof.positions_m, prof.gap_m)), 3
            ),
        }
    return out


def _mm(v: float, digits: int = 6) -> float | None:
    return None if not math.isfinite(v) else float(f"{v * 1e3:.{digits}g}")


def sig_or_none(v: float, digits: int = 6) -> float | None:
    """``v`` to ``digits`` significant digits, ``None`` where not finite."""
    return None if v is None or not math.isfinite(v) else float(f"{v:.{digits}g}")


def compute_sheet(cat: Catalogue, req: FlexRequest, *, band: bool = True) -> dict:
    """The flex sheet of ``req`` as plain numbers in SI (the nominal :class:`FlexSheet`, its
    bands, the snow shares); :func:`flex_sheet_answer` shapes it."""
    ski = cat.ski(req.ski)
    w_n = _check_request(ski, req)
    t0 = time.perf_counter()
    sheet = _sheet(ski, w_n)
    open_limit = _open_limit(ski, sheet)
    t1 = time.perf_counter()
    nominal = sheet.scalars()
    widths: dict[str, float] = {}
    draws_fns, band_source, scale = ([], "not computed", None)
    draw_sheets: list[FlexSheet] = []
    if band:
        draws_fns, band_source, scale = _draw_fns(ski)
        reference = nominal
        if scale is not None:  # beam draws: the first is the served beam on their nodes
            reference = _sheet(ski, w_n, draws_fns[0]).scalars()
            draws_fns = draws_fns[1:]
        draw_sheets = [_sheet(ski, w_n, fn) for fn in draws_fns]
        exact = profile_model(ski.record).source == "design_beam"
        for k, v in nominal.items():
            if exact:
                widths[k] = 0.0 if math.isfinite(v) else float("nan")
            else:
                values = [d.scalars()[k] for d in draw_sheets]
                widths[k] = _half_width(reference[k], values)
                if k in JUMPING_QUANTITIES and scale is not None:
                    widths[k] = _jump_half_width(reference[k], values, widths[k])
        w_close = widths.get("closing_load_n", float("nan"))
        if not exact and math.isfinite(w_close):
            # the closing load is bisected to its tolerance: draws that agree within it say
            # nothing finer (with the fixed covariance the demo skis' four draws close within
            # 0.05 kg of each other and the band was 0)
            widths["closing_load_n"] = max(w_close, sheet.closing.tolerance_n)
    t2 = time.perf_counter()
    snow = None
    if req.snow_modulus_mpa is not None:
        snow = _snow_part(ski, req, sheet, band)
    t3 = time.perf_counter()
    return {
        "ski": ski,
        "sheet": sheet,
        "open_limit": open_limit,
        "nominal": nominal,
        "widths": widths,
        "band_source": band_source,
        "band_scale": scale,
        "draws": len(draw_sheets),
        "draws_not_closing": sum(not d.closing.closes for d in draw_sheets),
        "snow": snow,
        "timing_ms": {
            "sheet": (t1 - t0) * 1e3,
            "band": (t2 - t1) * 1e3,
            "snow": (t3 - t2) * 1e3,
            "total": (t3 - t0) * 1e3,
        },
    }


def _snow_part(ski: Ski, req: FlexRequest, sheet: FlexSheet, band: bool) -> dict:
    e_eff = effective_modulus(
        units.mpa_to_pa(req.snow_modulus_mpa),
        units.mpa_to_pa(req.base_modulus_mpa),
        req.poisson_ratio,
    )
    beam, why = ski.beam()
    if beam is None:
        return {"available": False, "reason": why}
    preset = get_preset(req.preset)
    model = ski.flexible_model(preset.pixel_along_m, preset.pixels_across)
    half, full = _snow_shares(ski, model, sheet, e_eff)
    widths = [float("nan"), float("nan")]
    if band:
        models = beam_models(
            ski.record, preset, samples=BEAM_SAMPLES, seed=BAND_SEED, scale=_beam_scale(ski.record)
        )
        coarse, drawn = models
        tol = 1e-6
        c_half, c_full = _snow_shares(ski, coarse, sheet, e_eff, tol=tol)
        d = [_snow_shares(ski, m, sheet, e_eff, tol=tol) for m in drawn]
        for i, (nom, c) in enumerate(((half, c_half), (full, c_full))):
            grid = abs(c - nom)
            camber = 0.0 if not d else _half_width([c_half, c_full][i], [s[i] for s in d])
            widths[i] = math.hypot(grid, camber) if math.isfinite(camber) else grid
    return {
        "available": True,
        "reason": why,
        "effective_modulus_pa": e_eff,
        "shares": (half, full),
        "widths": widths,
        "pixel_along_m": preset.pixel_along_m,
    }


def _pocket_json(p, nominal: dict, widths: dict, tag: str) -> dict:
    key = f"pocket_{tag}_{p.threshold_m * 1e3:.2f}mm"
    return {
        "start_mm": _mm(p.start_m),
        "end_mm": _mm(p.end_m),
        "length_mm": _mm(p.length_m),
        "length_band_mm": _mm(widths.get(f"{key}_length_m", float("nan"))),
        "start_band_mm": _mm(widths.get(f"{key}_start_m", float("nan"))),
        "end_band_mm": _mm(widths.get(f"{key}_end_m", float("nan"))),
    }


def _profile_json(sheet: FlexSheet, step_m: float = 5e-3) -> dict:
    x = sheet.half.positions_m
    stride = max(1, round(step_m / float(x[1] - x[0])))
    sel = slice(None, None, stride)
    return {
        "positions_mm": [round(v * 1e3, 3) for v in x[sel].tolist()],
        "half_weight_gap_mm": [round(v * 1e3, 5) for v in sheet.half.gap_m[sel].tolist()],
        "full_weight_gap_mm": [round(v * 1e3, 5) for v in sheet.full.gap_m[sel].tolist()],
    }


@gated
def flex_sheet_answer(cat: Catalogue, req: FlexRequest, *, profiles: bool = True) -> dict:
    """The flex sheet of ``GET /v1/skis/{name}/flex`` and ``skisnow flex``: numbers in mm, kg
    and percent with their 90 % bands (module docstring, docs/flex.md).

    Raises
    ------
    UnknownItemError, InputError, OutOfRangeError (with ``field``), NotConvergedError
    """
    out = compute_sheet(cat, req)
    return _answer(req, out, profiles=profiles)


def _answer(req: FlexRequest, out: dict, *, profiles: bool) -> dict:
    ski, sheet, nom, wid = out["ski"], out["sheet"], out["nominal"], out["widths"]
    w_kg = req.body_weight_kg
    half_w, full_w = 0.5 * sheet.body_weight_n, sheet.body_weight_n
    closing = sheet.closing
    c_kg = units.n_to_kg(closing.load_n)

    def pct(v: float) -> float | None:
        return sig_or_none(100.0 * v) if v is not None and math.isfinite(v) else None

    snow = out["snow"]
    if snow is None:
        snow_json = None
    elif not snow["available"]:
        snow_json = {"available": False, "reason": snow["reason"]}
    else:
        snow_json = {
            "available": True,
            "snow_modulus_mpa": req.snow_modulus_mpa,
            "effective_modulus_mpa": sig_or_none(snow["effective_modulus_pa"] / 1e6),
            "half_weight_percent": pct(snow["shares"][0]),
            "full_weight_percent": pct(snow["shares"][1]),
            "half_weight_band_percent": pct(snow["widths"][0]),
            "full_weight_band_percent": pct(snow["widths"][1]),
            "macro_pixel_along_mm": snow["pixel_along_m"] * 1e3,
            "beam_source": snow["reason"],
            "target_full_weight_percent": [33, 50],
        }
    wax = sheet.wax_zone
    g = sheet.glide
    answer = {
        "inputs": {
            "ski": ski.name,
            "body_weight_kg": w_kg,
            "half_weight_kg": 0.5 * w_kg,
            "snow_modulus_mpa": req.snow_modulus_mpa,
            "porosity": req.porosity,
            "snow": snow_record(req.snow, req.snow_modulus_mpa, req.porosity),
            "base_modulus_mpa": req.base_modulus_mpa,
            "poisson_ratio": req.poisson_ratio,
            "preset": req.preset,
            "pocket_position_mm": POCKET_POSITION_M * 1e3,
            "glide_position_mm": GLIDE_POSITION_M * 1e3,
            "closed_gap_mm": CLOSED_GAP_M * 1e3,
        },
        "pockets": [
            {
                "gap_mm": round(ph.threshold_m * 1e3, 6),
                "half_weight": _pocket_json(ph, nom, wid, "half"),
                "full_weight": _pocket_json(pf, nom, wid, "full"),
            }
            for ph, pf in zip(sheet.pockets_half, sheet.pockets_full, strict=True)
        ],
        "verdict": verdict(w_kg, closing, out["open_limit"]),
        "pocket_height": pocket_height(sheet),
        "foot_gap_half_weight_mm": _mm(wax.foot_gap_m),
        "foot_gap_half_weight_band_mm": _mm(wid.get("foot_gap_half_m", float("nan"))),
        "wax_zone": {
            "start_mm": _mm(wax.start_m),
            "end_mm": _mm(wax.end_m),
            "length_mm": _mm(wax.length_m),
            "definition": f"pocket at {CLOSED_GAP_M * 1e3:g} mm under half weight",
        },
        "closing_load": {
            "load_kg": sig_or_none(c_kg),
            "band_kg": sig_or_none(units.n_to_kg(wid.get("closing_load_n", float("nan")))),
            "closes_below_max": closing.closes,
            "closed_at_min_load": closing.closed_at_min,
            "min_load_kg": sig_or_none(units.n_to_kg(closing.bracket_n[1]))
            if closing.closed_at_min
            else None,
            "max_load_kg": sig_or_none(units.n_to_kg(closing.max_load_n)),
            "tolerance_kg": sig_or_none(units.n_to_kg(closing.tolerance_n)),
            "residual_camber_mm": _mm(closing.residual_gap_m),
            "wax_zone_max_gap_mm": _mm(closing.wax_zone_max_gap_m),
            "draws_not_closing": out["draws_not_closing"],
            "closes_at_full_weight": closing.closed_at(full_w),
            "open_at_half_weight": not closing.closed_at(half_w),
        },
        "kick_zone": {
            "flat": {
                "half_weight_percent": pct(sheet.kick_share_half),
                "full_weight_percent": pct(sheet.kick_share_full),
                "half_weight_band_percent": pct(wid.get("kick_share_half", float("nan"))),
                "full_weight_band_percent": pct(wid.get("kick_share_full", float("nan"))),
            },
            "snow": snow_json,
            "target_full_weight_percent": [33, 50],
        },
        "wheelbase": {
            "wheelbase_mm": _mm(sheet.zones.wheelbase_m),
            "band_mm": _mm(wid.get("wheelbase_m", float("nan"))),
            "rear_zone_mm": [_mm(v) for v in sheet.zones.rear_m],
            "front_zone_mm": [_mm(v) for v in sheet.zones.front_m],
            "centroid_distance_mm": _mm(sheet.zones.centroid_distance_m),
        },
        "glide_check": {
            "passed": g.passed,
            "load_kg": w_kg,
            "load_position_mm": GLIDE_POSITION_M * 1e3,
            "span_mm": [_mm(v) for v in g.span_m],
            "min_gap_mm": _mm(g.min_gap_m),
            "min_gap_band_mm": _mm(wid.get("glide_min_gap_m", float("nan"))),
            "open_length_mm": _mm(g.open_length_m),
            "open_length_band_mm": _mm(wid.get("glide_open_length_m", float("nan"))),
        },
        "band": {
            "level": 0.9,
            "kind": "absolute half-width in the quantity's unit",
            "source": out["band_source"],
            "draws": out["draws"],
            "beam_deviation_scale": out["band_scale"],
            "seed": BAND_SEED,
        },
        "provenance": {
            "code_version": code_version(),
            "ski": {
                "file": ski.path.name,
                "sha256": ski.sha256,
                "profile_model": profile_model(ski.record).source,
            },
            "node_spacing_mm": sig_or_none(
                float(sheet.half.positions_m[1] - sheet.half.positions_m[0]) * 1e3
            ),
            "closing_solves": closing.iterations,
            "closing_converged": closing.converged,
        },
        "timing_ms": out["timing_ms"],
    }
    if profiles:
        answer["profiles"] = _profile_json(sheet)
    return answer
