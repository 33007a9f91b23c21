"""Service layer: the catalogue of skis and grinds, and one contact computation per request.

Routes in :mod:`app.api` validate the request and call :func:`contact` / :func:`compare`; all
unit conversion from technician units happens in :mod:`app.units`.
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from skisnow.app import units
from skisnow.app.band import answer_band, band_json, min_separation_unresolved, touches_profile_end
from skisnow.app.presets import DEFAULT_PRESET, Preset, get_preset
from skisnow.app.profiles import (
    held_out_case_errors,
    held_out_mask,
    no_beam_reason,
    profile_model,
    served_beam,
    stored_held_out_errors,
)
from skisnow.app.storage.common import code_version, sha256_file
from skisnow.app.storage.skis import (
    SKI_MANIFEST,
    SkiRecord,
    mean_profiles,
    read_ski,
    read_ski_manifest,
)
from skisnow.app.storage.tables import read_manifest, read_table
from skisnow.solvers.band import Z90
from skisnow.solvers.beam import BeamSki
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.errors import DataFileError, NotConvergedError, OutOfRangeError, SkisnowError
from skisnow.solvers.flexible import FlexibleModel, prepare_flexible, solve_flexible
from skisnow.solvers.lookup import ERROR_FIELDS, MicroTable, relative_error_estimate
from skisnow.solvers.macro import extrude_profile, solve_macro
from skisnow.solvers.multiscale import multiscale

log = logging.getLogger(__name__)


class UnknownItemError(LookupError):
    """A ski or grind name that the catalogue does not hold (HTTP 404)."""

    def __init__(self, kind: str, name: str, known: list[str]) -> None:
        super().__init__(f"unknown {kind} {name!r}; known: {', '.join(known) or 'none'}")
        self.kind = kind
        self.name = name
        self.known = known


class ModelUnavailableError(SkisnowError):
    """The requested ski model cannot be used for this ski (HTTP 422, the message says why)."""


#: ski models a request can ask for (method.md §4 step 3 and §4b)
SKI_MODELS = ("rigid", "flexible", "auto")
#: an identified beam answers loads up to this × the heaviest measured load (docs/limits.md)
BEAM_LOAD_FACTOR = 1.5
#: ``auto`` answers with the rigid shape when every compared quantity is within this of the
#: flexible solve [-]
AUTO_RIGID_TOLERANCE = 0.02


@dataclass
class Grind:
    name: str
    path: Path
    sha256: str
    table: MicroTable


@dataclass
class Ski:
    name: str
    path: Path
    sha256: str
    record: SkiRecord
    _flexible: dict = field(default_factory=dict, repr=False)

    def beam(self) -> tuple[BeamSki | None, str]:
        """The ski's beam model and where it comes from; or (None, why there is none).

        A beam identified from the ski's camber measurements (method.md §4c) that passed the
        held-out check comes first: the demo skis and uploaded skis alike. A design beam stored
        with the ski (the demo skis' truth) is the fallback.
        """
        ident = self.record.identified
        beam = served_beam(ident)
        if beam is not None:
            a = ident["attrs"]
            held = float(a.get("held_out_rms_m", float("nan")))
            held_txt = (
                f", {a.get('held_out_cases', 0)} held-out cases {held * 1e6:.2f} µm RMS"
                if math.isfinite(held)
                else ""
            )
            return (
                beam,
                f"identified from the camber data (misfit {a['misfit_m'] * 1e6:.2f} µm against "
                f"device noise {a['noise_m'] * 1e6:.2f} µm{held_txt})",
            )
        if self.record.beam is not None:
            return (
                self.record.beam,
                "design beam stored with the ski (demo ski: its own beam)",
            )
        why = no_beam_reason(ident)
        return None, f"ski {self.name!r} has no beam model ({why}); use ski_model 'rigid'"

    @property
    def beam_is_design(self) -> bool:
        """The beam :meth:`beam` answers with is the design beam stored with the ski."""
        return served_beam(self.record.identified) is None and self.record.beam is not None

    def flexible_model(self, pixel_along_m: float, pixels_across: int) -> FlexibleModel:
        """The prepared flexible model on a preset's grid (built once per worker)."""
        key = (float(pixel_along_m), int(pixels_across))
        model = self._flexible.get(key)
        if model is None:
            beam, why = self.beam()
            if beam is None:
                raise ModelUnavailableError(why)
            outline = self.record.outline
            model = prepare_flexible(
                beam,
                outline.width_m,
                pixel_along_m=pixel_along_m,
                pixels_across=pixels_across,
                width_positions_m=outline.positions_m,
            )
            self._flexible[key] = model
        return model

    def _covered(self, lo_key: str, hi_key: str, measured: np.ndarray) -> tuple[float, float]:
        """The range of the measured load cases for an identified beam, else the network's
        trained range (attributes ``lo_key``, ``hi_key``), else the measured range."""
        net = self.record.network
        if profile_model(self.record).source != "identified_beam" and net and "attrs" in net:
            a = net["attrs"]
            lo, hi = a.get(lo_key), a.get(hi_key)
            if lo is not None and hi is not None:
                return float(lo), float(hi)
        v = np.asarray(measured, dtype=float)
        return float(v.min()), float(v.max())

    @property
    def load_range_n(self) -> tuple[float, float]:
        """Loads the ski's camber model covers [N]. An identified beam answers up to
        :data:`BEAM_LOAD_FACTOR` × the heaviest measured load (positions stay in the measured
        range): measured on the demo skis at 110–150 kg, ≤ 0.33 µm from the truth near contact
        and ≤ 3.4 % in apparent area; lighter loads than measured and positions outside the
        measured range err by up to 8 µm and 47 % (ski-b), so they are refused."""
        lo, hi = self._covered("load_min_n", "load_max_n", self.record.measurements.loads_n)
        if profile_model(self.record).source == "identified_beam":
            hi *= BEAM_LOAD_FACTOR
        return lo, hi

    @property
    def position_range_m(self) -> tuple[float, float]:
        """Load positions the ski's camber model covers [m]."""
        return self._covered(
            "load_position_min_m",
            "load_position_max_m",
            self.record.measurements.load_positions_m,
        )


@dataclass
class Catalogue:
    """Skis and grinds loaded once per worker and verified against their manifests."""

    tables_dir: Path
    skis: dict[str, Ski] = field(default_factory=dict)
    grinds: dict[str, Grind] = field(default_factory=dict)

    def ski(self, name: str) -> Ski:
        try:
            return self.skis[name]
        except KeyError:
            raise UnknownItemError("ski", name, sorted(self.skis)) from None

    def grind(self, name: str) -> Grind:
        try:
            return self.grinds[name]
        except KeyError:
            raise UnknownItemError("grind", name, sorted(self.grinds)) from None


def _verify(path: Path, expected_sha: str | None) -> str:
    if not path.is_file():
        raise DataFileError(f"file listed in the manifest is missing: {path}")
    sha = sha256_file(path)
    if expected_sha is not None and sha != expected_sha:
        raise DataFileError(f"{path}: sha256 {sha[:12]}… does not match the manifest")
    return sha


def load_catalogue(tables_dir: str | Path) -> Catalogue:
    """Load and verify every table (``tables_dir/*.h5``) and ski (``tables_dir/skis/*.h5``).

    Raises
    ------
    DataFileError
        A manifest or a file is missing, corrupt, or does not match its checksum; the message
        names the file.
    """
    tables_dir = Path(tables_dir)
    cat = Catalogue(tables_dir=tables_dir)
    manifest = read_manifest(tables_dir)
    for fname, entry in sorted(manifest["files"].items()):
        path = tables_dir / fname
        sha = _verify(path, entry.get("sha256"))
        table = read_table(path)
        cat.grinds[table.name] = Grind(table.name, path, sha, table)
    ski_dir = tables_dir / "skis"
    ski_manifest = read_ski_manifest(ski_dir)
    for fname, entry in sorted(ski_manifest["files"].items()):
        path = ski_dir / fname
        sha = _verify(path, entry.get("sha256"))
        record = read_ski(path)
        name = Path(fname).stem
        cat.skis[name] = Ski(name, path, sha, record)
    if not cat.grinds:
        raise DataFileError(f"no texture tables listed in {tables_dir / 'manifest.json'}")
    if not cat.skis:
        raise DataFileError(f"no skis listed in {ski_dir / SKI_MANIFEST}")
    return cat


# ----------------------------------------------------------------------------- compute


@dataclass
class ContactInputs:
    """One request in technician units (validated by the API schema)."""

    ski: str
    grind: str
    load_kg: float
    load_position_mm: float
    snow_modulus_mpa: float
    porosity: float
    base_modulus_mpa: float = 700.0
    poisson_ratio: float = 0.3
    preset: str = DEFAULT_PRESET
    ski_model: str = "auto"


def _finite_list(a: np.ndarray, scale: float = 1.0, digits: int = 6) -> list[float | None]:
    """``a · scale`` rounded to ``digits`` significant digits, ``None`` where not finite (after
    scaling, so that an overflow never reaches the JSON encoder as inf): for
    every value exactly ``float(f"{v:.{digits}g}")`` (tests/test_service_rounding.py), without
    formatting every value as text (the answer's distributions hold a few thousand values).

    The decimal ``m · 10^k`` (``m`` an integer of ``digits`` digits) is rounded to the nearest
    float in one correctly rounded multiplication or division by the exact power ``10^|k|``
    (|k| ≤ 22), which is what parsing its text does. Where ``m`` itself is uncertain (the scaled
    value within 1e-6 of a rounding tie, or a magnitude outside that range) the value is
    formatted as text."""
    v = np.asarray(a, dtype=float).ravel() * scale
    out = v.copy()
    finite = np.isfinite(v)
    nonzero = finite & (v != 0)
    slow = np.zeros(v.shape, dtype=bool)
    if nonzero.any():
        w = v[nonzero]
        k = np.floor(np.log10(np.abs(w))).astype(int) - (digits - 1)
        ok = (np.abs(k) <= 22) & (digits <= 15)
        kk = np.where(ok, k, 0)
        up = np.power(10.0, np.abs(kk))
        r = np.where(kk >= 0, w / up, w * up)  # w / 10^k (exact power)
        m = np.rint(r)
        tie = np.abs(np.abs(r - np.floor(r)) - 0.5) < 1e-6
        ok &= ~tie & (np.abs(m) < 10.0 ** (digits + 1))
        out[nonzero] = np.where(kk >= 0, m * up, m / up)
        slow[np.flatnonzero(nonzero)[~ok]] = True
    spec = f".{digits}g"
    for i in np.flatnonzero(slow):
        out[i] = float(format(float(v[i]), spec))
    values = out.tolist()
    if finite.all():
        return values
    return [x if f else None for x, f in zip(values, finite.tolist(), strict=True)]


def loaded_profile(ski: Ski, load_n: float, load_position_m: float):
    """Positions [m] and loaded gap [m] of the ski on the rigid flat (:mod:`app.profiles`)."""
    return profile_model(ski.record)(load_n, load_position_m)


def warm_up(cat: Catalogue) -> float:
    """Solve one mid-range case so that compiled kernels and caches are ready before the first
    request (the first solve in a process costs ~1 s of kernel loading). Failures are logged,
    never raised: start-up does not depend on a demo case. Returns the time taken [s]."""
    t0 = time.perf_counter()
    try:
        ski = next(iter(cat.skis.values()))
        grind = next(iter(cat.grinds.values()))
        lo, hi = ski.position_range_m
        contact(
            cat,
            ContactInputs(
                ski=ski.name,
                grind=grind.name,
                load_kg=40.0,
                load_position_mm=0.5 * (lo + hi) * 1e3,
                snow_modulus_mpa=200.0,
                porosity=0.5,
            ),
        )
    except Exception as exc:  # a failed warm-up must not stop the service
        log.warning("warm-up solve failed (%s); the first request will be slower", exc)
    return time.perf_counter() - t0


#: porosity above which the answers are flagged: P_n = P/(1 − n) grows without bound as n → 1
POROSITY_WARN = 0.9
#: load share on pixels below the table's pressure range above which the answer is flagged
BELOW_TABLE_WARN = 0.01


def result_warnings(inp: ContactInputs, gmap, macro, ms) -> list[dict]:
    """Conditions under which an answer is computed but not trustworthy (docs/limits.md).

    Each warning is ``{"code", "detail"}``; the answer is still returned (HTTP 200) so that a
    user can see it, but these flags travel with it in the API, the CSV and the web page.
    """
    out = []
    if inp.porosity >= POROSITY_WARN:
        out.append(
            {
                "code": "porosity_near_one",
                "detail": f"porosity {inp.porosity:g} ≥ {POROSITY_WARN:g}: the texture carries "
                "only P·(1 − n) (method.md eq. 2), so the real contact area shrinks towards zero "
                "while the average real contact pressure F/A_tot (full load F, §6) grows "
                "without bound; very loose snow is outside what the method was made for",
            }
        )
    if touches_profile_end(gmap, macro):
        rows = np.flatnonzero(np.any(np.isfinite(gmap.gap_m), axis=1))
        first, last = gmap.positions_m[rows[0]], gmap.positions_m[rows[-1]]
        out.append(
            {
                "code": "contact_at_ski_end",
                "detail": "contact reaches the end of the measured profile "
                f"({first * 1e3:.0f} … {last * 1e3:.0f} mm): the tip or tail shape beyond "
                "the measurement is not modelled, and the minimum average separation has no "
                "grid-converged value there (no band); try a stiffer snow or a lighter load",
            }
        )
    share = float(ms.diagnostics.get("load_share_below_table_range", 0.0))
    if share > BELOW_TABLE_WARN:
        out.append(
            {
                "code": "below_table_range",
                "detail": f"{share:.1%} of the load sits where the nominal pressure is below "
                "the texture table's range; there the real contact is interpolated towards the "
                "unloaded texture, not solved",
            }
        )
    return out


def contact(
    cat: Catalogue,
    inp: ContactInputs,
    *,
    presets: dict[str, Preset] | None = None,
    error_band: bool = True,
) -> dict:
    """Compute one ski × grind case; returns the JSON-ready answer of ``POST /v1/contact``.

    ``inp.preset`` names the discretisation settings (:mod:`app.presets`); ``presets`` replaces
    the table of named presets (the accuracy benchmark passes candidate settings this way).
    ``error_band=False`` leaves the band out (benchmarks measure its cost this way; every
    answer of the API and the web form has one).

    Raises
    ------
    UnknownItemError, InputError, OutOfRangeError, NotConvergedError
    """
    t0 = time.perf_counter()
    preset = get_preset(inp.preset, presets)
    ski = cat.ski(inp.ski)
    grind = cat.grind(inp.grind)
    load_n = units.kg_to_n(inp.load_kg)
    x_f = units.mm_to_m(inp.load_position_mm)
    lo, hi = ski.position_range_m
    if not (lo - 1e-12 <= x_f <= hi + 1e-12):
        raise OutOfRangeError(
            f"load_position_mm {inp.load_position_mm:g} is outside the range the ski "
            f"{ski.name!r} covers ({lo * 1e3:g} … {hi * 1e3:g} mm)"
        )
    f_lo, f_hi = ski.load_range_n
    if not (f_lo * (1 - 1e-9) <= load_n <= f_hi * (1 + 1e-9)):
        raise OutOfRangeError(
            f"load_kg {inp.load_kg:g} is outside the range the ski {ski.name!r} covers "
            f"({units.n_to_kg(f_lo):.4g} … {units.n_to_kg(f_hi):.4g} kg): its camber model is "
            "not extrapolated"
        )
    e_eff = effective_modulus(
        units.mpa_to_pa(inp.snow_modulus_mpa),
        units.mpa_to_pa(inp.base_modulus_mpa),
        inp.poisson_ratio,
    )
    t1 = time.perf_counter()
    x, gap = loaded_profile(ski, load_n, x_f)
    t2 = time.perf_counter()
    outline = ski.record.outline
    gmap = extrude_profile(
        x,
        gap,
        outline.width_m,
        width_positions_m=outline.positions_m,
        pixel_along_m=preset.pixel_along_m,
        pixels_across=preset.pixels_across,
    )
    macro = solve_macro(gmap, load_n, x_f, e_eff)
    if not macro.converged:
        raise NotConvergedError(
            f"the ski-on-snow solve did not converge ({macro.message}); try a load position "
            "nearer the balance point or a different snow modulus"
        )
    t3 = time.perf_counter()
    ms = multiscale(macro, grind.table, inp.porosity, e_eff)
    t4 = time.perf_counter()
    macro, ms, model_info = _choose_ski_model(inp, ski, preset, macro, ms, grind, e_eff)
    t5 = time.perf_counter()
    band = None
    if error_band:
        band = answer_band(
            record=ski.record,
            positions_m=x,
            gap_m=gap,
            preset=preset,
            macro=macro,
            ms=ms,
            table=grind.table,
            porosity=inp.porosity,
            e_eff=e_eff,
            ski_model_used=model_info["used"],
            beam_is_design=ski.beam_is_design,
            rigid_minus_flexible=model_info.get("rigid_minus_flexible")
            if model_info["requested"] == "auto"
            else None,
            min_separation_unresolved=min_separation_unresolved(gmap, macro, ms),
        )
    t6 = time.perf_counter()
    rows = np.isfinite(ms.average_separation_m)
    answer = {
        "inputs": {
            "ski": inp.ski,
            "grind": inp.grind,
            "load_kg": inp.load_kg,
            "load_position_mm": inp.load_position_mm,
            "snow_modulus_mpa": inp.snow_modulus_mpa,
            "porosity": inp.porosity,
            "base_modulus_mpa": inp.base_modulus_mpa,
            "poisson_ratio": inp.poisson_ratio,
            "preset": preset.name,
            "load_n": load_n,
            "effective_modulus_mpa": e_eff / 1e6,
        },
        "metrics": {
            "total_real_contact_area_mm2": ms.total_real_contact_area_m2 * 1e6,
            "average_real_contact_pressure_mpa": ms.average_real_contact_pressure_pa / 1e6,
            "min_average_separation_um": ms.min_average_separation_m * 1e6,
            "total_reciprocal_separation_m": ms.total_reciprocal_separation_m,
        },
        "apparent": {
            "contact_area_cm2": ms.apparent_contact_area_m2 * 1e4,
            "mean_pressure_kpa": ms.mean_apparent_pressure_pa / 1e3,
            "zones": [
                {
                    "name": "rear" if z.end_m <= x_f else ("front" if z.start_m >= x_f else "mid"),
                    "start_mm": z.start_m * 1e3,
                    "end_mm": z.end_m * 1e3,
                    "length_mm": (z.end_m - z.start_m) * 1e3,
                    "load_n": z.load_n,
                    "load_share": z.load_share,
                    "apparent_area_cm2": z.apparent_area_m2 * 1e4,
                    "real_area_mm2": z.real_area_m2 * 1e6,
                }
                for z in ms.zones
            ],
        },
        "warnings": result_warnings(inp, gmap, macro, ms) + model_info.pop("warnings"),
        "distributions": {
            "position_mm": _finite_list(ms.positions_m[rows], 1e3),
            "pressure_kpa": _finite_list(ms.pressure_pa[rows], 1e-3),
            "clearance_um": _finite_list(ms.clearance_m[rows], 1e6),
            "real_area_fraction": _finite_list(ms.real_area_fraction[rows]),
            "average_separation_um": _finite_list(ms.average_separation_m[rows], 1e6),
            "reciprocal_separation_per_m": _finite_list(ms.reciprocal_separation_per_m[rows]),
        },
        "provenance": {
            "code_version": code_version(),
            "preset": {
                **preset.provenance(),
                "macro_pixel_size_mm": [v * 1e3 for v in macro.pixel_size_m],
                "texture_pixel_size_um": grind.table.pixel_size_m * 1e6,
            },
            "table": {
                "file": grind.path.name,
                "sha256": grind.sha256,
                "texture_pixel_size_um": grind.table.pixel_size_m * 1e6,
                "gap_floor_nm": grind.table.gap_floor_m * 1e9,
                "pixel_error_estimate": pixel_error_estimate(
                    grind.table, macro.pressure_pa, ms.real_area_fraction_map, inp.porosity, e_eff
                ),
            },
            "ski": {
                "file": ski.path.name,
                "sha256": ski.sha256,
                "profile_model": profile_model(ski.record).source,
            },
            "ski_model": model_info,
            "macro": {
                "converged": macro.converged,
                "iterations": macro.iterations,
                "residual": macro.residual,
                "pixel_size_mm": [v * 1e3 for v in macro.pixel_size_m],
                "force_residual": macro.force_residual,
                "moment_residual": macro.moment_residual,
            },
            "multiscale": ms.diagnostics,
        },
        "timing_ms": {
            "profile": (t2 - t1) * 1e3,
            "macro": (t3 - t2) * 1e3,
            "multiscale": (t4 - t3) * 1e3,
            "ski_model": (t5 - t4) * 1e3,
            "band": (t6 - t5) * 1e3,
        },
    }
    if band is None:
        answer["timing_ms"]["total"] = (time.perf_counter() - t0) * 1e3
        return answer
    answer["band"], band_warnings = band_json(band, answer)
    answer["warnings"] += band_warnings
    if band.pressure_line_band_pa is not None:
        lo, hi = band.pressure_line_band_pa
        # two columns like every other distribution (one value per position)
        answer["distributions"]["pressure_band_low_kpa"] = _finite_list(lo[rows], 1e-3)
        answer["distributions"]["pressure_band_high_kpa"] = _finite_list(hi[rows], 1e-3)
    answer["timing_ms"]["total"] = (time.perf_counter() - t0) * 1e3
    return answer


def pixel_error_estimate(
    table: MicroTable, pressure_pa, real_area_fraction_map, porosity: float, e_eff: float
) -> dict:
    """The table's error estimate against the zero-pixel limit at this answer's pressures.

    For each loaded macro cell the tabulated relative estimate is interpolated at its
    ``P_n / E'`` (:func:`solvers.lookup.relative_error_estimate`). Reported: the largest over
    the cells for a_r (``real_contact_area_fraction_rel_max``), the mean gap and the floored
    reciprocal gap, and the a_r-weighted mean for a_r, the relative estimate of the total
    real contact area (equal cells). Tables built on one pixel size: ``estimated`` false.
    """
    levels = json.loads(table.attrs.get("pixel_extrapolation_json", "null") or "null")
    if not table.has_error_estimates or levels is None:
        return {"estimated": False, "pixel_levels": table.attrs.get("pixel_levels", "none")}
    p = np.asarray(pressure_pa, dtype=float)
    loaded = np.isfinite(p) & (p > 0)
    p_n = p[loaded] * (1 - porosity)
    out: dict = {
        "estimated": True,
        "pixel_levels": table.attrs.get("pixel_levels"),
        "level_pixel_size_um": [v * 1e6 for v in levels["level_pixel_size_m"]],
        "orders": levels["orders"],
        # three levels: estimate from successive extrapolants where the order is stable
        "estimate_rule": "successive_extrapolants"
        if len(levels["level_pixel_size_m"]) > 2
        else "richardson_correction",
    }
    short = {
        "real_contact_area_fraction": "real_contact_area_fraction",
        "mean_gap_m": "mean_gap",
        "mean_reciprocal_gap_per_m": "mean_reciprocal_gap",
    }
    for quantity in ERROR_FIELDS:
        rel = np.atleast_1d(relative_error_estimate(table, p_n, e_eff, quantity))
        finite = rel[np.isfinite(rel)]
        out[f"{short[quantity]}_rel_max"] = float(finite.max()) if finite.size else None
        if quantity == "real_contact_area_fraction":
            ar = np.asarray(real_area_fraction_map, dtype=float)[loaded]
            ok = np.isfinite(rel) & np.isfinite(ar)
            total = float(np.sum(ar[ok]))
            out["total_real_contact_area_rel"] = (
                float(np.sum(ar[ok] * rel[ok]) / total) if total > 0 else None
            )
    return out


def rigid_minus_flexible(rigid, flex, ms_rigid=None, ms_flex=None) -> dict[str, float]:
    """What ``auto`` compares: relative differences (rigid − flexible) / flexible of the
    apparent area and, when the multiscale results are given, the four metrics; the rear load
    share (behind the load point) as an absolute difference [-]."""

    def values(macro, ms) -> dict[str, float]:
        out = {"apparent_area": macro.apparent_contact_area_m2}
        if ms is not None:
            out |= {
                "total_real_contact_area": ms.total_real_contact_area_m2,
                "average_real_contact_pressure": ms.average_real_contact_pressure_pa,
                "min_average_separation": ms.min_average_separation_m,
                "total_reciprocal_separation": ms.total_reciprocal_separation_m,
            }
        return out

    def rear_share(macro) -> float:
        p = np.nan_to_num(macro.pressure_pa)
        rear = macro.positions_m < macro.load_position_m
        return float(p[rear].sum() / max(p.sum(), 1e-300))

    a, b = values(rigid, ms_rigid), values(flex, ms_flex)
    diff = {k: (a[k] - b[k]) / b[k] if b[k] else 0.0 for k in a}
    diff["rear_load_share"] = rear_share(rigid) - rear_share(flex)
    return diff


def auto_uses_flexible(diff: dict[str, float]) -> tuple[bool, str]:
    """``auto``'s rule on :func:`rigid_minus_flexible`: flexible when any compared quantity
    differs by more than :data:`AUTO_RIGID_TOLERANCE`; returns the choice and the reason."""
    worst = max(diff, key=lambda k: abs(diff[k]))
    if abs(diff[worst]) <= AUTO_RIGID_TOLERANCE:
        return False, (
            f"the rigid shape is within {AUTO_RIGID_TOLERANCE:.0%} of the flexible ski in every "
            f"compared quantity (largest: {worst} {diff[worst]:+.1%})"
        )
    return True, (
        f"the rigid shape differs from the bending ski by {diff[worst]:+.1%} in {worst} "
        f"(more than {AUTO_RIGID_TOLERANCE:.0%})"
    )


def _choose_ski_model(inp: ContactInputs, ski: Ski, preset: Preset, rigid, ms_rigid, grind, e_eff):
    """Apply ``inp.ski_model``: the rigid answer, the flexible one, or (``auto``) the rigid one
    when it is within :data:`AUTO_RIGID_TOLERANCE` of the flexible one in every compared
    quantity. Returns (macro, multiscale, provenance dict with a ``warnings`` list)."""
    if inp.ski_model not in SKI_MODELS:
        raise ModelUnavailableError(
            f"ski_model must be one of {', '.join(SKI_MODELS)}, got {inp.ski_model!r}"
        )
    info: dict = {"requested": inp.ski_model, "warnings": []}
    if inp.ski_model == "rigid":
        info.update(used="rigid", reason="requested")
        return rigid, ms_rigid, info
    beam, why = ski.beam()
    if beam is None:
        if inp.ski_model == "flexible":
            raise ModelUnavailableError(why)
        info.update(used="rigid", reason=why)
        info["warnings"].append({"code": "flexible_unavailable", "detail": why})
        return rigid, ms_rigid, info
    try:
        model = ski.flexible_model(preset.pixel_along_m, preset.pixels_across)
        # no warm start from the rigid answer: the solver's own row-level start is closer
        # (measured: 3-5 pixel sets instead of 9-11 on the demo skis at the papers' case)
        flex = solve_flexible(model, rigid.load_n, rigid.load_position_m, e_eff)
    except SkisnowError as exc:
        if inp.ski_model == "flexible":
            raise
        reason = f"the flexible model cannot answer this case ({exc})"
        info.update(used="rigid", reason=reason)
        info["warnings"].append({"code": "flexible_unavailable", "detail": reason})
        return rigid, ms_rigid, info
    info["beam_source"] = why
    info["flexible"] = {
        "converged": flex.converged,
        "iterations": flex.iterations,
        "message": flex.message,
        "solve_time_ms": flex.solve_time_s * 1e3,
    }
    if not flex.converged:
        if inp.ski_model == "flexible":
            raise NotConvergedError(
                f"the flexible ski-on-snow solve did not converge: {flex.message}"
            )
        info.update(used="rigid", reason=f"the flexible solve did not converge ({flex.message})")
        info["warnings"].append({"code": "flexible_not_converged", "detail": info["reason"]})
        return rigid, ms_rigid, info
    ms_flex = multiscale(flex, grind.table, inp.porosity, e_eff)
    diff = rigid_minus_flexible(rigid, flex, ms_rigid, ms_flex)
    info["rigid_minus_flexible"] = diff
    if inp.ski_model == "flexible":
        info.update(used="flexible", reason="requested")
        return flex, ms_flex, info
    use_flexible, reason = auto_uses_flexible(diff)
    info.update(used="flexible" if use_flexible else "rigid", reason=reason)
    return (flex, ms_flex, info) if use_flexible else (rigid, ms_rigid, info)


def profile_report(ski: Ski) -> dict:
    """The profile model a ski answers with and why (``GET /v1/skis/{name}``, the ski's page);
    an error message instead when the ski has none."""
    try:
        model = profile_model(ski.record)
    except SkisnowError as exc:
        return {"name": None, "reason": str(exc)}
    return {"name": model.source, "reason": model.reason}


#: attributes of the identification's provenance shown with the beam (technician names)
_IDENT_PROVENANCE = ("created_utc", "code_version", "git_commit", "command_line")


def _identification_report(ski: Ski) -> dict:
    """The identification of a ski (method.md §4c) in technician units: its verdict, noise and
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
        "case_misfit_um": _finite_list(np.asarray(ident["case_misfit_m"]), 1e6, 4)
        if "case_misfit_m" in ident
        else [],
    }
    held_rms = a.get("held_out_rms_m")
    held_rms = float(held_rms) if held_rms is not None and math.isfinite(held_rms) else None
    out["held_out_cases"] = int(a.get("held_out_cases", 0))
    out["held_out_rms_um"] = None if held_rms is None else held_rms * 1e6
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
        out["case_load_kg"] = _finite_list(units.n_to_kg(loads_n[kept]), 1.0, 4)
        out["case_position_mm"] = _finite_list(np.round(positions_m[kept] * 1e3, 3) + 0.0, 1.0, 6)
        if error_m is not None:
            out["held_out"] = {
                "load_kg": _finite_list(units.n_to_kg(loads_n[held]), 1.0, 4),
                "position_mm": _finite_list(np.round(positions_m[held] * 1e3, 3) + 0.0, 1.0, 6),
                "error_um": _finite_list(error_m, 1e6, 4),
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
    (:data:`app.profiles.HELD_OUT_ERRORS`), else predicted from the stored beam (about a second
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
    out["position_mm"] = _finite_list(beam.positions_m[idx], 1e3)
    out["bending_stiffness_nm2"] = _finite_list(beam.bending_stiffness_nm2[idx])
    out["camber_um"] = _finite_list(beam.unloaded_gap_m[idx], 1e6)
    if ident and "stiffness_band_nm2" in ident and beam is not ski.record.beam:
        band = np.asarray(ident["stiffness_band_nm2"])
        out["bending_stiffness_band_90_nm2"] = [
            _finite_list(band[0][idx]),
            _finite_list(band[1][idx]),
        ]
        sd = np.asarray(ident["camber_band_m"])[idx]
        out["camber_sd_um"] = _finite_list(sd, 1e6)
        c = beam.unloaded_gap_m[idx]
        out["camber_band_90_um"] = [
            _finite_list(c - Z90 * sd, 1e6),
            _finite_list(c + Z90 * sd, 1e6),
        ]
    return out
