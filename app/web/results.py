"""The results page ``/results`` and its CSV ``/results.csv``, and the answers behind them.

Each combination is one :func:`app.service.contact` call; answers are kept in a small
in-memory cache so that the CSV download after a results page costs nothing. The cache is keyed
on the inputs and the sha256 of the ski and grind files, so a renamed item, or one deleted and
uploaded again under its name, is never served an earlier item's answer.
"""

from __future__ import annotations

import csv
import io
import math
import threading
import time
from collections import OrderedDict
from dataclasses import astuple, dataclass

from fastapi import Request
from fastapi.responses import HTMLResponse
from skisnow.app import plots, service
from skisnow.app.snow import SNOW_PRESETS
from skisnow.app.web.form import Query, ski_url, upload_labels
from skisnow.app.web.templating import page, svg
from skisnow.solvers.errors import SkisnowError

#: the four functional parameters: (key in "metrics", label, unit, format)
METRICS = (
    ("total_real_contact_area_mm2", "Total real contact area", "mm²", "{:.4g}"),
    ("average_real_contact_pressure_mpa", "Average real contact pressure", "MPa", "{:.4g}"),
    ("min_average_separation_um", "Minimum average separation", "µm", "{:.4g}"),
    ("total_reciprocal_separation_m", "Total average reciprocal separation", "m", "{:.4g}"),
)

#: the band's name of each metric card
BAND_KEYS = {
    "total_real_contact_area_mm2": "total_real_contact_area",
    "average_real_contact_pressure_mpa": "average_real_contact_pressure",
    "min_average_separation_um": "min_average_separation",
    "total_reciprocal_separation_m": "total_reciprocal_separation",
}

#: CSV columns, units in the names as in the JSON API
CSV_COLUMNS = (
    "ski",
    "grind",
    "load_kg",
    "load_position_mm",
    "snow_modulus_mpa",
    "porosity",
    "base_modulus_mpa",
    "poisson_ratio",
    "total_real_contact_area_mm2",
    "average_real_contact_pressure_mpa",
    "min_average_separation_um",
    "total_reciprocal_separation_m",
    "apparent_contact_area_cm2",
    "mean_apparent_pressure_kpa",
    "apparent_contact_area_band90_rel",
    "apparent_contact_area_band90_rel_above",
    "studied_tail_outside_share",
    "studied_tail_farthest_over_half_width",
    "total_real_contact_area_band90_rel",
    "average_real_contact_pressure_band90_rel",
    "min_average_separation_band90_rel",
    "total_reciprocal_separation_band90_rel",
    "rear_zone_load_share",
    "front_zone_load_share",
    "ski_model",
    "table_file",
    "table_sha256",
    "texture_pixel_size_um",
    "gap_floor_nm",
    "ski_file",
    "ski_sha256",
    "code_version",
    "compute_time_ms",
    # the snow preset the snow numbers came from (app/snow.py); empty for custom numbers
    "snow",
    "warnings",
    "error",
)


# ----------------------------------------------------------------------------- computing


class ResultCache:
    """Thread-safe LRU of :func:`service.contact` answers keyed by the inputs."""

    def __init__(self, maxsize: int = 32) -> None:
        self.maxsize = maxsize
        self._data: OrderedDict[tuple, dict] = OrderedDict()
        self._lock = threading.Lock()

    def get(self, key: tuple) -> dict | None:
        with self._lock:
            if key in self._data:
                self._data.move_to_end(key)
                return self._data[key]
        return None

    def put(self, key: tuple, value: dict) -> None:
        with self._lock:
            self._data[key] = value
            self._data.move_to_end(key)
            while len(self._data) > self.maxsize:
                self._data.popitem(last=False)


@dataclass
class Outcome:
    """Answers for the combinations that worked, and a message for those that did not."""

    results: list[dict]
    failures: list[tuple[service.ContactInputs, str]]
    wall_ms: float


def compute(cat: service.Catalogue, q: Query, cache: ResultCache) -> Outcome:
    t0 = time.perf_counter()
    results, failures = [], []
    for inp in q.combinations():
        # keyed on content, not names: a renamed, deleted or re-uploaded item is never served
        # an earlier item's answer
        ski, grind = cat.skis.get(inp.ski), cat.grinds.get(inp.grind)
        key = (astuple(inp), ski and ski.sha256, grind and grind.sha256)
        answer = cache.get(key)
        if answer is None:
            try:
                answer = service.contact(cat, inp)
            except SkisnowError as exc:
                failures.append((inp, str(exc)))
                continue
            cache.put(key, answer)
        results.append(answer)
    return Outcome(results, failures, (time.perf_counter() - t0) * 1e3)


# ----------------------------------------------------------------------------- page and CSV


def render_results(request: Request, q: Query, out: Outcome) -> HTMLResponse:
    return page(
        request,
        "results.html",
        "skisnow — results",
        n=q.numbers,
        snow_label=SNOW_PRESETS[q.numbers["snow"]].label if q.numbers.get("snow") else None,
        link=q.link_query(),
        results=out.results,
        failures=out.failures,
        wall_ms=out.wall_ms,
        metrics=METRICS,
        band_keys=BAND_KEYS,
        resolved=[service.resolved_min_separation(r["apparent"]["zones"]) for r in out.results],
        labels=upload_labels(request),
        ski_url=ski_url,
        plots=[(key, caption, svg(figure)) for key, caption, figure in plots.all_svgs(out.results)],
    )


def render_csv(out: Outcome) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(CSV_COLUMNS)
    for r in out.results:
        inp, m, a, p = r["inputs"], r["metrics"], r["apparent"], r["provenance"]
        share = {"rear": 0.0, "front": 0.0}  # zones behind / ahead of the balance point
        for z in a["zones"]:
            behind = z["start_mm"] + z["end_mm"] < 0
            share["rear" if behind else "front"] += z["load_share"]
        tail = (r.get("band") or {}).get("studied_tail") or {}
        row = {
            **{k: inp[k] for k in CSV_COLUMNS[:8]},
            **m,
            "apparent_contact_area_cm2": a["contact_area_cm2"],
            "mean_apparent_pressure_kpa": a["mean_pressure_kpa"],
            **{
                f"{q}_band90_rel": w
                for q, w in r.get("band", {}).get("relative_half_width", {}).items()
            },
            # the band's half-width above the value where it differs from the one below
            "apparent_contact_area_band90_rel_above": (
                r.get("band", {}).get("relative_half_width_above") or {}
            ).get(
                "apparent_contact_area",
                r.get("band", {}).get("relative_half_width", {}).get("apparent_contact_area"),
            ),
            # how far outside their bands the studied answers of this kind fell (none where
            # the own-ski studies do not stand for the answer)
            "studied_tail_outside_share": tail.get("outside_share"),
            "studied_tail_farthest_over_half_width": tail.get("farthest_over_half_width"),
            "rear_zone_load_share": share["rear"],
            "front_zone_load_share": share["front"],
            "ski_model": p["ski_model"]["used"],
            "table_file": p["table"]["file"],
            "table_sha256": p["table"]["sha256"],
            "texture_pixel_size_um": p["table"]["texture_pixel_size_um"],
            "gap_floor_nm": p["table"]["gap_floor_nm"],
            "ski_file": p["ski"]["file"],
            "ski_sha256": p["ski"]["sha256"],
            "code_version": p["code_version"],
            "compute_time_ms": round(r["timing_ms"]["total"], 1),
            "warnings": ";".join(w["code"] for w in r.get("warnings", [])),
            "error": "",
            "snow": (inp.get("snow") or {}).get("name"),
        }
        w.writerow([_csv_value(row.get(c)) for c in CSV_COLUMNS])
    for inp, msg in out.failures:
        row = {k: getattr(inp, k) for k in CSV_COLUMNS[:8]} | {"error": msg, "snow": inp.snow}
        w.writerow([_csv_value(row.get(c)) for c in CSV_COLUMNS])
    return buf.getvalue()


def _csv_value(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.8g}" if math.isfinite(v) else ""
    return str(v)
