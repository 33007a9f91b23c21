"""Pair matching and a skier's best ski from flex sheets (issue #14; docs/flex.md), and the CSV
of the sheet, the pair and the ranking. The sheet itself: :mod:`.sheet`.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math

from skisnow.app.service.answer import ContactInputs, contact
from skisnow.app.service.catalogue import Catalogue, UnknownItemError
from skisnow.app.service.flex.sheet import (
    CRITERIA,
    GAP_FLOOR_MM,
    PAIR_LOAD_POSITION_MM,
    SHARE_FLOOR_PERCENT,
    FlexRequest,
    field_error,
    flex_sheet_answer,
    sig_or_none,
)
from skisnow.solvers.errors import InputError, OutOfRangeError

# ----------------------------------------------------------------------------- pair


def _flat_numbers(ans: dict) -> dict[str, tuple[float | None, float | None, str]]:
    """(value, band, floor kind) of every flex-sheet number of an answer, by a flat name."""
    out = {}
    for p in ans["pockets"]:
        tag = f"{p['gap_mm']:.2f}mm"
        for weight in ("half_weight", "full_weight"):
            q = p[weight]
            for part in ("start", "end", "length"):
                out[f"pocket_{weight}_{tag}_{part}_mm"] = (
                    q[f"{part}_mm"],
                    q[f"{part}_band_mm"],
                    "length",
                )
    ph = ans.get("pocket_height")
    if ph:
        for weight in ("half_weight", "full_weight"):
            out[f"pocket_height_{weight}_largest_gap_mm"] = (
                ph[weight]["largest_gap_mm"],
                None,
                "gap",
            )
    out["foot_gap_half_weight_mm"] = (
        ans["foot_gap_half_weight_mm"],
        ans["foot_gap_half_weight_band_mm"],
        "gap",
    )
    c = ans["closing_load"]
    out["closing_load_kg"] = (c["load_kg"], c["band_kg"], "load")
    k = ans["kick_zone"]["flat"]
    out["kick_zone_flat_half_weight_percent"] = (
        k["half_weight_percent"],
        k["half_weight_band_percent"],
        "share",
    )
    out["kick_zone_flat_full_weight_percent"] = (
        k["full_weight_percent"],
        k["full_weight_band_percent"],
        "share",
    )
    s = ans["kick_zone"]["snow"]
    if s and s.get("available"):
        out["kick_zone_snow_half_weight_percent"] = (
            s["half_weight_percent"],
            s["half_weight_band_percent"],
            "share",
        )
        out["kick_zone_snow_full_weight_percent"] = (
            s["full_weight_percent"],
            s["full_weight_band_percent"],
            "share",
        )
    wb = ans["wheelbase"]
    out["wheelbase_mm"] = (wb["wheelbase_mm"], wb["band_mm"], "length")
    g = ans["glide_check"]
    out["glide_min_gap_mm"] = (g["min_gap_mm"], g["min_gap_band_mm"], "gap")
    out["glide_open_length_mm"] = (g["open_length_mm"], g["open_length_band_mm"], "length")
    return out


#: what a technician reads for each flat name of :func:`_flat_numbers` and the contact metrics
_WEIGHTS = {"half_weight": "half weight", "full_weight": "full weight"}
_FIXED_LABELS = {
    "foot_gap_half_weight_mm": "Gap under the foot at half weight [mm]",
    "pocket_height_half_weight_largest_gap_mm": "Pocket height at half weight [mm]",
    "pocket_height_full_weight_largest_gap_mm": "Pocket height at full weight [mm]",
    "closing_load_kg": "Closing load (0.10 mm under the foot) [kg]",
    "kick_zone_flat_half_weight_percent": "Kick-zone load on the flat, half weight [%]",
    "kick_zone_flat_full_weight_percent": "Kick-zone load on the flat, full weight [%]",
    "kick_zone_snow_half_weight_percent": "Kick-zone load on snow, half weight [%]",
    "kick_zone_snow_full_weight_percent": "Kick-zone load on snow, full weight [%]",
    "wheelbase_mm": "Wheelbase at full weight [mm]",
    "glide_min_gap_mm": "Glide check: smallest gap ahead of the foot [mm]",
    "glide_open_length_mm": "Glide check: open length ahead of the foot [mm]",
    "total_real_contact_area_mm2": "Total real contact area [mm²]",
    "average_real_contact_pressure_mpa": "Average real contact pressure [MPa]",
    "min_average_separation_um": "Minimum average separation [µm]",
    "total_reciprocal_separation_m": "Total reciprocal separation [m]",
}


def quantity_label(name: str) -> str:
    """The words of a pair row's quantity (its flat name stays the API's and the CSV's key)."""
    if name in _FIXED_LABELS:
        return _FIXED_LABELS[name]
    parts = name.split("_")  # pocket_{half|full}_weight_{0.10mm}_{start|end|length}_mm
    if len(parts) == 6 and parts[0] == "pocket":
        weight = _WEIGHTS.get(f"{parts[1]}_{parts[2]}", parts[1])
        gap = parts[3].removesuffix("mm")
        what = {"start": "rear end", "end": "front end", "length": "length"}.get(parts[4], parts[4])
        return f"Wax pocket ≥ {gap} mm at {weight}: {what} [mm]"
    return name


def _floor(kind: str, node_mm: float, tol_kg: float) -> float:
    return {"length": node_mm, "load": tol_kg, "share": SHARE_FLOOR_PERCENT, "gap": GAP_FLOOR_MM}[
        kind
    ]


def _difference(name, lv, lb, rv, rb, floor) -> dict:
    """One row of the pair: difference left − right and whether it exceeds the combined band
    ``hypot(band_left, band_right)`` or, where the bands are 0 or unknown, the floor."""
    if lv is None or rv is None:
        # one side closed (NaN ends) or missing: different when exactly one side has a value
        flagged = (lv is None) != (rv is None)
        return {
            "quantity": name,
            "label": quantity_label(name),
            "left": lv,
            "right": rv,
            "difference": None,
            "allowed": None,
            "flagged": flagged,
        }
    band = math.hypot(lb or 0.0, rb or 0.0)
    allowed = max(band, floor)
    diff = lv - rv
    return {
        "quantity": name,
        "label": quantity_label(name),
        "left": lv,
        "right": rv,
        "difference": sig_or_none(diff),
        "allowed": sig_or_none(allowed),
        "flagged": bool(abs(diff) > allowed),
    }


def _metrics(cat, ski, grind, body_weight_kg, req: FlexRequest, ski_model: str) -> dict:
    ans = contact(
        cat,
        ContactInputs(
            ski=ski,
            grind=grind,
            load_kg=body_weight_kg,
            load_position_mm=PAIR_LOAD_POSITION_MM,
            snow_modulus_mpa=req.snow_modulus_mpa,
            porosity=req.porosity,
            base_modulus_mpa=req.base_modulus_mpa,
            poisson_ratio=req.poisson_ratio,
            preset=req.preset,
            ski_model=ski_model,
            snow=req.snow,
        ),
    )
    return ans


_METRIC_BAND_KEYS = {
    "total_real_contact_area_mm2": "total_real_contact_area",
    "average_real_contact_pressure_mpa": "average_real_contact_pressure",
    "min_average_separation_um": "min_average_separation",
    "total_reciprocal_separation_m": "total_reciprocal_separation",
}


def _camber_abs_band(ans: dict, key: str) -> float:
    """Absolute camber-model part of a contact metric's band (the other sources, grid and
    table, are common to two skis on one grid and one table)."""
    rel = ans["band"]["components"].get("camber_model", {}).get(_METRIC_BAND_KEYS[key])
    v = ans["metrics"][key]
    return 0.0 if rel is None or v is None else abs(rel * v)


def flex_pair(
    cat: Catalogue,
    left: str,
    right: str,
    req: FlexRequest,
    *,
    grind: str | None = None,
    ski_model: str = "auto",
) -> dict:
    """Two skis side by side (``GET /v1/flex/pair``): both sheets, the difference in every
    flex-sheet number and (with a grind and a snow) in the four contact metrics under full
    weight at :data:`PAIR_LOAD_POSITION_MM`, each flagged when it exceeds the camber model's
    band of the two skis combined in quadrature (or the resolution floor where the band is 0)."""
    for fld, name in (("left", left), ("right", right)):
        if name not in cat.skis:
            exc = UnknownItemError("ski", name, sorted(cat.skis))
            exc.field = fld
            raise exc
    if grind is not None:
        cat.grind(grind)
        if req.snow_modulus_mpa is None or req.porosity is None:
            missing = "snow_modulus_mpa" if req.snow_modulus_mpa is None else "porosity"
            raise field_error(InputError, missing, f"{missing} is needed with a grind")
    sheets = {}
    for side, name in (("left", left), ("right", right)):
        try:
            sheets[side] = flex_sheet_answer(cat, dataclasses.replace(req, ski=name))
        except (InputError, OutOfRangeError) as exc:
            if getattr(exc, "field", None) == "ski":
                exc.field = side
            raise
    node_mm = max(s["provenance"]["node_spacing_mm"] for s in sheets.values())
    tol_kg = sheets["left"]["closing_load"]["tolerance_kg"]
    ln, rn = _flat_numbers(sheets["left"]), _flat_numbers(sheets["right"])
    rows = [
        _difference(k, *ln[k][:2], *rn[k][:2], _floor(ln[k][2], node_mm, tol_kg))
        for k in ln
        if k in rn
    ]
    metrics = None
    if grind is not None:
        la = _metrics(cat, left, grind, req.body_weight_kg, req, ski_model)
        ra = _metrics(cat, right, grind, req.body_weight_kg, req, ski_model)
        metrics = []
        for key in _METRIC_BAND_KEYS:
            lv, rv = la["metrics"][key], ra["metrics"][key]
            floor = 0.0
            metrics.append(
                _difference(
                    key, lv, _camber_abs_band(la, key), rv, _camber_abs_band(ra, key), floor
                )
            )
    flagged = [r["quantity"] for r in rows + (metrics or []) if r["flagged"]]
    return {
        "inputs": {
            "left": left,
            "right": right,
            "body_weight_kg": req.body_weight_kg,
            "snow_modulus_mpa": req.snow_modulus_mpa,
            "porosity": req.porosity,
            "snow": req.snow,
            "grind": grind,
            "preset": req.preset,
            "ski_model": ski_model,
            "metrics_load_position_mm": PAIR_LOAD_POSITION_MM,
        },
        "flagged": bool(flagged),
        "flagged_quantities": flagged,
        "flex_differences": rows,
        "metric_differences": metrics,
        "rule": "a difference is flagged when |left − right| exceeds hypot(band_left, "
        "band_right) of the camber model (90 %), or where both bands are 0 (design beams) a "
        f"resolution floor: one node spacing ({node_mm:g} mm) for lengths, the closing-load "
        f"tolerance ({tol_kg:g} kg), {SHARE_FLOOR_PERCENT:g} percentage points for shares, "
        f"{GAP_FLOOR_MM * 1e3:g} µm for gaps; a number that exists on one side only (a "
        "closed pocket) is flagged",
        "left": sheets["left"],
        "right": sheets["right"],
    }


# ----------------------------------------------------------------------------- ranking


def flex_ranking(
    cat: Catalogue,
    skis: list[str],
    grinds: list[str],
    req: FlexRequest,
    *,
    criterion: str = "real_area",
    ski_model: str = "auto",
) -> dict:
    """Rank ski × grind combinations for a skier (``POST /v1/flex/ranking``).

    Skis that do not suit the skier (the sheet's verdict: pocket closed at full weight, open by
    :data:`.sheet.OPEN_GAP_M` at half weight) are left out with the verdict as the reason; when
    none is left, ``qualifies`` is false and ``message`` says why. The rest are ranked by
    ``criterion`` (:data:`CRITERIA`) on the contact answer under full weight at
    :data:`PAIR_LOAD_POSITION_MM`; each entry carries the metric's 90 % band (the contact
    answer's full band); neighbours whose bands overlap are marked "not distinguishable"."""
    if criterion not in CRITERIA:
        raise field_error(
            InputError,
            "criterion",
            f"criterion must be one of {', '.join(CRITERIA)}, got {criterion!r}",
        )
    if req.snow_modulus_mpa is None or req.porosity is None:
        missing = "snow_modulus_mpa" if req.snow_modulus_mpa is None else "porosity"
        raise field_error(InputError, missing, f"{missing} is needed for a ranking")
    for s in skis:
        if s not in cat.skis:
            exc = UnknownItemError("ski", s, sorted(cat.skis))
            exc.field = "skis"
            raise exc
    for g in grinds:
        if g not in cat.grinds:
            exc = UnknownItemError("grind", g, sorted(cat.grinds))
            exc.field = "grinds"
            raise exc
    key, larger, why = CRITERIA[criterion]
    left_out, entries = [], []
    for s in skis:
        sheet = flex_sheet_answer(cat, dataclasses.replace(req, ski=s), profiles=False)
        c = sheet["closing_load"]
        v = sheet["verdict"]
        reason = None if v["kind"] == "suits" else v["text"]
        if reason:
            left_out.append(
                {
                    "ski": s,
                    "reason": reason,
                    "closing_load_kg": c["load_kg"],
                    "suits_body_weight_kg": v["suits_body_weight_kg"],
                }
            )
            continue
        for g in grinds:
            ans = _metrics(cat, s, g, req.body_weight_kg, req, ski_model)
            v = ans["metrics"][key]
            interval = ans["band"]["intervals"].get(key)
            entries.append(
                {
                    "ski": s,
                    "grind": g,
                    key: v,
                    "band_low": interval[0] if interval else None,
                    "band_high": interval[1] if interval else None,
                    "closing_load_kg": c["load_kg"],
                    "kick_zone_snow_full_weight_percent": (sheet["kick_zone"]["snow"] or {}).get(
                        "full_weight_percent"
                    ),
                    "ski_model_used": ans["provenance"]["ski_model"]["used"],
                }
            )
    entries.sort(key=lambda e: -e[key] if larger else e[key])
    for i, e in enumerate(entries):
        e["rank"] = i + 1
        e["not_distinguishable_from"] = [
            j + 1 for j, o in enumerate(entries) if o is not e and _overlap(e, o)
        ]
    return {
        "inputs": {
            "skis": skis,
            "grinds": grinds,
            "body_weight_kg": req.body_weight_kg,
            "snow_modulus_mpa": req.snow_modulus_mpa,
            "porosity": req.porosity,
            "snow": req.snow,
            "preset": req.preset,
            "ski_model": ski_model,
            "load_position_mm": PAIR_LOAD_POSITION_MM,
        },
        "criterion": {
            "name": criterion,
            "metric": key,
            "label": quantity_label(key),
            # the unit of the metric and of each entry's band_low / band_high (the key's suffix)
            "unit": key.rsplit("_", 1)[-1],
            "better": "larger" if larger else "smaller",
            "mechanism": why,
            "choices": {k: v[2] for k, v in CRITERIA.items()},
        },
        "ranking": entries,
        "left_out": left_out,
        "qualifies": bool(entries),
        "message": None
        if entries
        else f"No ski qualifies for {req.body_weight_kg:g} kg: "
        + "; ".join(f"{o['ski']}: {o['reason']}" for o in left_out),
        "rule": "ranks whose 90 % bands (band_low … band_high) overlap are not distinguishable",
    }


def _overlap(a: dict, b: dict) -> bool:
    if None in (a["band_low"], a["band_high"], b["band_low"], b["band_high"]):
        return True
    return a["band_low"] <= b["band_high"] and b["band_low"] <= a["band_high"]


# ----------------------------------------------------------------------------- CSV


def _csv(rows: list[dict], columns: list[str]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=columns, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in columns})
    return buf.getvalue()


def sheet_csv(answer: dict) -> str:
    """The sheet's numbers as ``quantity,value,band`` rows (units in the quantity names)."""
    rows = [
        {"quantity": k, "value": v, "band": b} for k, (v, b, _) in _flat_numbers(answer).items()
    ]
    rows.append({"quantity": "glide_check_passed", "value": answer["glide_check"]["passed"]})
    return _csv(rows, ["quantity", "value", "band"])


def pair_csv(answer: dict) -> str:
    """The pair's differences, flex numbers then contact metrics."""
    rows = answer["flex_differences"] + (answer["metric_differences"] or [])
    return _csv(rows, ["quantity", "left", "right", "difference", "allowed", "flagged"])


def ranking_csv(answer: dict) -> str:
    """The ranking (left-out skis as rows without a rank, with the reason)."""
    key = answer["criterion"]["metric"]
    rows = [
        {
            **e,
            "value": e[key],
            "not_distinguishable_from": " ".join(map(str, e["not_distinguishable_from"])),
        }
        for e in answer["ranking"]
    ]
    rows += [{"ski": o["ski"], "left_out": o["reason"]} for o in answer["left_out"]]
    return _csv(
        rows,
        [
            "rank",
            "ski",
            "grind",
            "value",
            "band_low",
            "band_high",
            "not_distinguishable_from",
            "closing_load_kg",
            "left_out",
        ],
    )
