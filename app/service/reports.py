"""What the ski's page and ``GET /v1/skis/{name}`` report about a ski's profile model: the
model it answers with and why, the identification behind an identified beam, its held-out
cases (:func:`profile_report`, :func:`beam_report`).
"""

from __future__ import annotations

import json
import logging
import math

import numpy as np
from skisnow.app import units
from skisnow.app.service.catalogue import Ski
from skisnow.app.service.profiles import (
    held_out_case_errors,
    held_out_mask,
    model_choice,
    profile_model,
    stored_held_out_errors,
)
from skisnow.app.service.rounding import finite_list
from skisnow.app.storage.skis import identified_alternatives, mean_profiles
from skisnow.solvers.band import Z90
from skisnow.solvers.errors import SkisnowError
from skisnow.solvers.identify import measured_stretch, middle_distance

log = logging.getLogger(__name__)


def profile_report(ski: Ski) -> dict:
    """The profile model a ski answers with and why (``GET /v1/skis/{name}``, the ski's page);
    an error message instead when the ski has none."""
    try:
        model = profile_model(ski.record)
        lo, hi = model.load_range_n
    except SkisnowError as exc:
        return {"name": None, "reason": str(exc)}
    out = {
        "name": model.source,
        "reason": model.reason,
        "load_range_kg": [units.n_to_kg(lo), units.n_to_kg(hi)],
        "load_range_rule": model.load_range_rule,
        "held_out_comparison": None,
    }
    choice = model_choice(ski.record.identified)
    if choice is not None:  # both models on the same held-out cases, in µm
        out["held_out_comparison"] = {
            "served": choice["served"],
            "reason": choice["reason"],
            "rule": choice.get("rule", ""),
            "held_out_cases": int(choice.get("held_out_cases", 0)),
            "seed": choice.get("seed"),
            **{
                k[:-2] + "_um": (float(v) * 1e6 if math.isfinite(float(v)) else None)
                for k, v in choice.items()
                if k.endswith("_m") and k.startswith(("beam_", "network_", "noise"))
            },
        }
    return out


#: attributes of the identification's provenance shown with the beam (technician names)
_IDENT_PROVENANCE = ("created_utc", "code_version", "git_commit", "command_line")


def _identification_report(ski: Ski) -> dict:
    """The identification of a ski (docs/physics.md §4c) in technician units: its verdict, noise and
    misfit, the misfit per identified case with the case's load [kg] and position [mm], the
    held-out check (per held-out case: RMS of prediction − measurement [µm]) and provenance."""
    ident = ski.record.identified
    a = ident.get("attrs", {})
    noise = a.get("noise_m")
    out: dict = {
        "ok": bool(a.get("ok", False)),
        "reason": a.get("reason", ""),
        "noise_um": noise * 1e6 if noise is not None else None,
        "misfit_um": a["misfit_m"] * 1e6 if "misfit_m" in a else None,
        "case_misfit_um": finite_list(np.asarray(ident["case_misfit_m"]), 1e6, 4)
        if "case_misfit_m" in ident
        else [],
    }
    # the node spacing of the beam's device model [mm]: the samples' own, or the finer model
    # grid a sparser sampling is identified on (solvers.identify DEFAULT_MODEL_SPACING_M)
    nodes = np.asarray(ident.get("positions_m", []), dtype=float)
    out["model_spacing_mm"] = (
        round(float(nodes[1] - nodes[0]) * 1e3, 4) if nodes.size > 1 and a.get("ok") else None
    )
    held_rms = a.get("held_out_rms_m")
    held_rms = float(held_rms) if held_rms is not None and math.isfinite(held_rms) else None
    out["held_out_cases"] = int(a.get("held_out_cases", 0))
    out["held_out_rms_um"] = None if held_rms is None else held_rms * 1e6
    # where the measured gap is below 0.2 mm: what the held-out check judges (files written
    # before it was stored have none)
    band_rms = a.get("held_out_rms_band_m")
    ok_band = band_rms is not None and math.isfinite(float(band_rms))
    out["held_out_rms_band_um"] = float(band_rms) * 1e6 if ok_band else None
    for key, value in (("misfit_to_noise", a.get("misfit_m")), ("held_out_to_noise", held_rms)):
        ok = value is not None and noise and math.isfinite(value)
        out[key] = round(float(value) / float(noise), 4) if ok else None
    params = json.loads(a["parameters_json"]) if "parameters_json" in a else {}
    out["provenance"] = {k: str(a[k]) for k in _IDENT_PROVENANCE if k in a} | {
        "profiles": params.get("profiles"),
        "held_out_seed": params.get("seed"),
        "iterations": a.get("iterations"),
        "contact_passes": a.get("contact_passes"),
        "solve_time_s": a.get("solve_time_s"),
    }
    cases = _identification_cases(ski)
    if cases is not None:
        loads_n, positions_m, kept, held, error_m, origin = cases
        out["case_load_kg"] = finite_list(units.n_to_kg(loads_n[kept]), 1.0, 4)
        out["case_position_mm"] = finite_list(np.round(positions_m[kept] * 1e3, 3) + 0.0, 1.0, 6)
        if error_m is not None:
            out["held_out"] = {
                "load_kg": finite_list(units.n_to_kg(loads_n[held]), 1.0, 4),
                "position_mm": finite_list(np.round(positions_m[held] * 1e3, 3) + 0.0, 1.0, 6),
                "error_um": finite_list(error_m, 1e6, 4),
                "provenance": origin,
            }
    return out


#: provenance of held-out errors predicted on reading a file that does not store them
HELD_OUT_COMPUTED = "computed on read (the file stores no held-out errors)"


def _identification_cases(ski: Ski):
    """The cases of the stored identification: loads [N], positions [m], the identified and
    held-out indices, the held-out cases' RMS error [m] (None when the stored beam cannot
    predict) and where that error comes from (a dict: ``source`` and, for stored errors, their
    provenance). None when the stored misfits do not match the ski's measurements.

    The held-out errors are read from the file when the identification stores them
    (:data:`app.service.profiles.HELD_OUT_ERRORS`), else predicted from the stored beam (about a
    second
    for 85 cases: files identified before they were stored); either way once per ski record."""
    ident = ski.record.identified
    # keyed on the group itself: a dataclasses.replace copy of the record shares the cache
    cached = ski.record.cache.get("identification_cases")
    if cached is not None and cached[0] is ident and cached[1] is ski.record.measurements:
        return cached[2]
    result = None
    if "case_misfit_m" in ident:
        data = ski.record.measurements
        loads_n, positions_m, profiles_m, _ = mean_profiles(data)
        held = held_out_mask(ident, loads_n.size)
        if held is not None:
            error_m, origin = None, {}
            stored = stored_held_out_errors(ident, held) if held.any() else None
            if stored is not None:
                error_m, attrs = stored
                origin = {"source": str(attrs.get("source", "stored"))} | {
                    k: str(attrs[k]) for k in _IDENT_PROVENANCE if k in attrs
                }
            elif held.any():
                try:  # a failed identification may have stored NaN arrays: InputError
                    error_m = held_out_case_errors(
                        ident, loads_n, positions_m, profiles_m, nodes_m=data.positions_m
                    )
                    origin = {"source": HELD_OUT_COMPUTED}
                except SkisnowError as exc:
                    log.info("no held-out predictions for ski %r: %s", ski.name, exc)
            result = (
                loads_n,
                positions_m,
                np.flatnonzero(~held),
                np.flatnonzero(held),
                error_m,
                origin,
            )
    ski.record.cache["identification_cases"] = (ident, ski.record.measurements, result)
    return result


def beam_report(ski: Ski, points: int = 41) -> dict:
    """The ski's beam for ``GET /v1/skis/{name}``: where it comes from, EI(X) and c(X) sampled
    along the ski (with the identification's 90 % band on EI, and on c its 1-σ spread and the
    90 % band ± Z90·σ), and the identification: misfit per identified case with the case's load
    and position, the held-out check with each held-out case's error, provenance. Technician
    units: mm, kg, N·m², µm."""
    beam, source = ski.beam()
    out: dict = {"available": beam is not None, "source": source, "used_by_auto": beam is not None}
    ident = ski.record.identified
    if ident:
        out["identification"] = _identification_report(ski)
    if beam is None:
        return out
    idx = np.linspace(0, beam.positions_m.size - 1, points).round().astype(int)
    out["position_mm"] = finite_list(beam.positions_m[idx], 1e3)
    out["bending_stiffness_nm2"] = finite_list(beam.bending_stiffness_nm2[idx])
    out["camber_um"] = finite_list(beam.unloaded_gap_m[idx], 1e6)
    if ident and "stiffness_band_nm2" in ident and beam is not ski.record.beam:
        band = np.asarray(ident["stiffness_band_nm2"])
        out["bending_stiffness_band_90_nm2"] = [
            finite_list(band[0][idx]),
            finite_list(band[1][idx]),
        ]
        sd = np.asarray(ident["camber_band_m"])[idx]
        out["camber_sd_um"] = finite_list(sd, 1e6)
        c = beam.unloaded_gap_m[idx]
        out["camber_band_90_um"] = [
            finite_list(c - Z90 * sd, 1e6),
            finite_list(c + Z90 * sd, 1e6),
        ]
        if "stiffness_data_share" in ident and "knots_m" in ident:
            share = np.interp(
                beam.positions_m[idx],
                np.asarray(ident["knots_m"], dtype=float),
                np.asarray(ident["stiffness_data_share"], dtype=float),
            )
            out["bending_stiffness_data_share"] = finite_list(np.clip(share, 0.0, 1.0))
            stretch = measured_stretch(ident["knots_m"], ident["stiffness_data_share"])
            out["bending_stiffness_measured_mm"] = (
                None if stretch is None else [round(v * 1e3, 3) for v in stretch]
            )
        alts = identified_alternatives(ident)
        if alts and all(a.positions_m.size == beam.positions_m.size for a in alts):
            out["alternatives"] = _alternatives_report(beam, alts, idx)
    return out


def _alternatives_report(beam, alts: list, idx: np.ndarray) -> dict:
    """The identification's alternative beams (other fits that explain the camber cases almost
    as well; the band answers with each) at the report's points, and how far each lies from the
    served beam over the middle half of the ski: max |Δc| [µm], and EI's largest ratio [-]."""
    far = [middle_distance(a, beam) for a in alts]
    return {
        "count": len(alts),
        "bending_stiffness_nm2": [finite_list(a.bending_stiffness_nm2[idx]) for a in alts],
        "camber_um": [finite_list(a.unloaded_gap_m[idx], 1e6) for a in alts],
        "max_camber_difference_middle_um": [round(dc * 1e6, 3) for dc, _ in far],
        "max_stiffness_ratio_middle": [round(math.exp(dl), 4) for _, dl in far],
    }
