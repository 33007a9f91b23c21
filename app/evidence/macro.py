"""``skisnow bench macro``: one macro solve per demo ski (default grid against the fine
reference), the bending ski, the network inference time and the beam identification.

Written by :func:`app.evidence.writer.write_stage` to ``docs/bench/macro.json``;
:func:`render_md` is its section of ``docs/benchmarks.md``.
"""

from __future__ import annotations

import json
import logging
import statistics
import time
from pathlib import Path

import numpy as np
from skisnow.app.evidence import identification as identification_bench
from skisnow.app.evidence import ski_job as ski_job_bench
from skisnow.app.evidence.paper_case import (
    BASE_MODULUS_MPA,
    DOC_POROSITY,
    PAPER_LOAD_KG,
    PAPER_POSITION_MM,
    PAPER_SNOW_MODULUS_MPA,
    POISSON_RATIO,
    PROFILE_MODEL_NAMES,
)
from skisnow.app.service.profiles import profile_model
from skisnow.app.storage.skis import SHIPPED_SKI_DIR, read_ski
from skisnow.solvers.beam import G_STANDARD
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.errors import DataFileError
from skisnow.solvers.macro import (
    DEFAULT_PIXEL_ACROSS,
    DEFAULT_PIXEL_ALONG_M,
    extrude_profile,
    solve_macro,
)

log = logging.getLogger(__name__)


def bench_macro_stage(
    repeats: int = 7, inference_calls: int = 300, identification: bool = True, make_app=None
) -> dict:
    """``skisnow bench macro``: one macro solve per demo ski at the default grid against the
    fine reference (:func:`bench_macro`), the bending ski, the network inference
    time and (``identification``) the beam identification, several starts included, of the
    three demo skis and three study designs on the coarse grid
    (:func:`app.evidence.identification.bench_identification`; minutes per ski on 2 cores; the
    tests leave it out, tests/solvers/test_identify*.py cover the identification) and, given
    ``make_app`` (the API factory, :func:`app.api.factory.create_api`), the ski job end to end
    with the service's default settings (:func:`app.evidence.ski_job.bench_ski_job`; about a
    minute per ski)."""
    from skisnow.solvers import camber

    out = {"skis": bench_macro(repeats=repeats), "inference": {}}
    out["flexible"] = bench_flexible(repeats=repeats)
    if identification:
        out["identification"] = identification_bench.bench_identification()
    if make_app is not None:
        out["ski_job"] = ski_job_bench.bench_ski_job(make_app)
    for name in out["skis"]:
        net = read_ski(SHIPPED_SKI_DIR / f"{name}.h5").network
        if net is None:
            continue
        camber.predict_profile(net, PAPER_LOAD_KG * G_STANDARD, PAPER_POSITION_MM / 1e3)  # warm-up
        times = []
        for _ in range(inference_calls):
            t0 = time.perf_counter()
            camber.predict_profile(net, PAPER_LOAD_KG * G_STANDARD, PAPER_POSITION_MM / 1e3)
            times.append(time.perf_counter() - t0)
        out["inference"][name] = {"calls": inference_calls, "median_s": statistics.median(times)}
    return out


#: the parts of the macro stage; ``--only-identification`` and ``--only-job`` run one of the
#: last two again and keep the others from the last run
PARTS = ("skis", "inference", "flexible", "identification", "ski_job")
#: the parts run on their own and their flags
RERUNNABLE = {"identification": "--only-identification", "ski_job": "--only-job"}


def _kept_parts(d: dict) -> dict[str, dict]:
    """The parts a stored macro run kept from earlier runs, each with the provenance of the run
    that measured it (the per-part form, or the older ``{"parts": [...], "provenance": {...}}``
    one: one provenance for every kept part)."""
    kept = d.get("kept_from_previous_run") or {}
    parts = kept.get("parts", {})
    if isinstance(parts, list):
        return {k: kept.get("provenance", {}) for k in parts}
    return parts


def _kept_provenance(old: dict) -> dict[str, dict]:
    """Per part of a stored macro run, the provenance of the run that measured it: the file's own,
    or, for a part that run kept itself, the one it names."""
    parts = _kept_parts(old)
    return {k: parts.get(k) or old.get("provenance", {}) for k in PARTS if k in old}


def rerun_only(previous: Path, part: str, run) -> dict:
    """The macro stage with only ``part`` (a key of :data:`RERUNNABLE`) run again by ``run()``,
    every other part the ``previous`` run's JSON holds copied, named under
    ``kept_from_previous_run`` (``parts``: part → the provenance of the run that measured it).
    DataFileError without a previous run."""
    if not Path(previous).is_file():
        raise DataFileError(
            f"{previous}: no previous macro run to keep the other parts from; run "
            "`skisnow bench macro` once in full"
        )
    old = json.loads(Path(previous).read_text(encoding="utf-8"))
    provenance = _kept_provenance(old)
    out = {k: old[k] for k in PARTS if k in old and k != part}
    out["kept_from_previous_run"] = {"parts": {k: provenance[k] for k in out}}
    out[part] = run()
    return out


def _kept_md(d: dict) -> list[str]:
    """The note naming the parts kept from earlier runs, grouped by the run that measured them,
    and the part run again."""
    parts = _kept_parts(d)
    if not parts:
        return []
    runs: dict[tuple, list[str]] = {}
    for name, prov in parts.items():
        key = (prov.get("created_utc", "?"), str(prov.get("git_commit", "?"))[:12])
        runs.setdefault(key, []).append(name)
    words = "; ".join(
        f"{', '.join(names)} from the run of {when} (commit {commit})"
        for (when, commit), names in runs.items()
    )
    again = [
        f"{name.replace('_', ' ')} (`skisnow bench macro {flag}`)"
        for name, flag in RERUNNABLE.items()
        if name in d and name not in parts
    ]
    return [
        "",
        f"Parts kept from earlier runs: {words}; run again here: {', '.join(again) or 'none'}.",
    ]


def bench_flexible(repeats: int = 7, skis: tuple[str, ...] = ("ski-a", "ski-b")) -> dict:
    """Per demo ski at the papers' case, default grid, in one run: the beam's loaded profile on
    the flat (cached flexibility), the rigid solve of that profile, the flexible solve (cold, from
    its own row-level start, as the service calls it; and warm-started from the rigid pressure),
    and one whole ``/v1/contact`` computation (``service.contact``) with ``ski_model`` rigid and
    auto. Medians [s]."""
    from skisnow.app import service
    from skisnow.solvers.flexible import prepare_flexible, solve_flexible

    e_eff = effective_modulus(PAPER_SNOW_MODULUS_MPA * 1e6, BASE_MODULUS_MPA * 1e6, POISSON_RATIO)
    load_n, xf = PAPER_LOAD_KG * G_STANDARD, PAPER_POSITION_MM / 1e3
    cat = service.load_catalogue(SHIPPED_SKI_DIR.parent)
    grind = sorted(cat.grinds)[0]

    def median_of(fn) -> tuple[float, object]:
        res = fn()  # warm-up
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            res = fn()
            times.append(time.perf_counter() - t0)
        return float(np.median(times)), res

    out: dict = {}
    for name in skis:
        rec = cat.ski(name).record
        beam, _ = cat.ski(name).beam()
        if beam is None:
            continue
        pm = profile_model(rec)
        t_prof, (x_prof, gap_prof) = median_of(lambda pm=pm: pm(load_n, xf))
        gm = extrude_profile(
            x_prof, gap_prof, rec.outline.width_m, width_positions_m=rec.outline.positions_m
        )
        t_rigid, rigid = median_of(lambda gm=gm: solve_macro(gm, load_n, xf, e_eff))
        model = prepare_flexible(
            beam, rec.outline.width_m, width_positions_m=rec.outline.positions_m
        )
        t_cold, flex = median_of(lambda m=model: solve_flexible(m, load_n, xf, e_eff))
        t_warm, _ = median_of(
            lambda m=model, r=rigid: solve_flexible(
                m, load_n, xf, e_eff, initial_pressure_pa=r.pressure_pa
            )
        )
        req = {}
        for mode in ("rigid", "auto"):
            inp = service.ContactInputs(
                name,
                grind,
                PAPER_LOAD_KG,
                PAPER_POSITION_MM,
                PAPER_SNOW_MODULUS_MPA,
                DOC_POROSITY,
                ski_model=mode,
            )
            req[mode], _ = median_of(lambda inp=inp: service.contact(cat, inp))
            req[mode + "_no_band"], _ = median_of(
                lambda inp=inp: service.contact(cat, inp, error_band=False)
            )
        out[name] = {
            "profile_model": pm.source,
            "beam_profile_s": t_prof,
            "rigid_solve_s": t_rigid,
            "flexible_cold_s": t_cold,
            "flexible_warm_s": t_warm,
            "flexible_iterations": flex.iterations,
            "rigid_area_cm2": rigid.apparent_contact_area_m2 * 1e4,
            "flexible_area_cm2": flex.apparent_contact_area_m2 * 1e4,
            "contact_rigid_s": req["rigid"],
            "contact_auto_s": req["auto"],
            "contact_rigid_no_band_s": req["rigid_no_band"],
            "contact_auto_no_band_s": req["auto_no_band"],
            "grind": grind,
        }
    return out


def _flexible_md(d: dict) -> list[str]:
    if not d:
        return []
    lines = [
        "### The bending ski (issue #12)",
        "",
        "Papers' case, default grid, same run. Profile: the ski's profile model as the service "
        "calls it (identified beam: one device solve on the flat with the cached flexibility; "
        "target ≤ 10 ms). Flexible "
        "solve: beam and snow as one complementarity problem (target ≤ 2 × rigid and ≤ 40 ms), "
        "cold (its own row-level start, as the service calls it) and warm-started from the rigid "
        "pressure. Request: one "
        "`service.contact` computation (profile, macro, multiscale; auto also solves the "
        "flexible ski), with its 90 % error band and without it (the band re-solves a rigid "
        "answer 9 times on a grid twice as coarse, an answer of the bending ski once plus once "
        "per plausible beam drawn from the identification; docs/limits.md, Error band).",
        "",
        "| ski | profile model | profile [ms] | rigid solve [ms] | flexible cold [ms] | "
        "flexible warm [ms] | cold / rigid | request rigid [ms] (no band) | request auto [ms] "
        "(no band) | area rigid → flexible [cm²] |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in d.items():
        nb_rigid = 1e3 * r.get("contact_rigid_no_band_s", float("nan"))
        nb_auto = 1e3 * r.get("contact_auto_no_band_s", float("nan"))
        lines.append(
            f"| {name} | {r.get('profile_model', 'design_beam')} | "
            f"{1e3 * r['beam_profile_s']:.2f} | {1e3 * r['rigid_solve_s']:.1f} | "
            f"{1e3 * r['flexible_cold_s']:.1f} | {1e3 * r['flexible_warm_s']:.1f} | "
            f"{r['flexible_cold_s'] / r['rigid_solve_s']:.1f} | "
            f"{1e3 * r['contact_rigid_s']:.1f} ({nb_rigid:.1f}) | "
            f"{1e3 * r['contact_auto_s']:.1f} ({nb_auto:.1f}) | "
            f"{r['rigid_area_cm2']:.2f} → {r['flexible_area_cm2']:.2f} |"
        )
    lines.append("")
    return lines


def _case_words() -> str:
    """ "40 kg at −160 mm, E_snow 200 MPa": the case every solve of this stage runs."""
    position = f"{PAPER_POSITION_MM:g}".replace("-", "−")
    return f"{PAPER_LOAD_KG:g} kg at {position} mm, E_snow {PAPER_SNOW_MODULUS_MPA:g} MPa"


def _profile_words(d: dict) -> str:
    """Which profile model the solves used, as the run recorded it (the flexible rows name the
    ski's profile model; ``bench_macro`` loads the same one, ``commands.macro.loaded_profile``)."""
    models = {r.get("profile_model") for r in d.get("flexible", {}).values()}
    if len(models) == 1 and None not in models:
        return f"{PROFILE_MODEL_NAMES.get(models.pop(), 'served')} profile"
    return "profile from its profile model"


def render_md(d: dict) -> list[str]:
    lines = [
        "## Macro scale: one ski-on-snow solve (`skisnow bench macro`)",
        "",
        f"Papers' case ({_case_words()}), each demo ski's {_profile_words(d)}; "
        "default grid against the 0.5 mm × 16 reference. Targets: ≤ 30 ms per solve, apparent "
        "area within 1 %, network inference ≤ 1 ms.",
        "",
        "| ski | grid [mm] | median solve [ms] | apparent area [cm²] | peak pressure [kPa] "
        "| iterations | area error | peak error | reference time / default |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for name, r in d["skis"].items():
        dflt, fine = r["default"], r["fine"]
        for label, row in (("default", dflt), ("fine", fine)):
            err = (
                f"{100 * r['area_error']:+.2f} % | {100 * r['peak_pressure_error']:+.1f} %"
                if label == "default"
                else "— | —"
            )
            ratio = (
                f"{fine['median_time_s'] / dflt['median_time_s']:.1f}" if label == "fine" else ""
            )
            lines.append(
                f"| {name} ({label}) | {row['pixel_mm'][0]:g} × {row['pixel_mm'][1]:.2f} | "
                f"{1e3 * row['median_time_s']:.1f} | {row['area_cm2']:.2f} | "
                f"{row['peak_pressure_kpa']:.0f} | {row['iterations']} | {err} | {ratio} |"
            )
    for name, r in d.get("inference", {}).items():
        lines.append("")
        lines.append(
            f"Network inference, {name}: median {1e3 * r['median_s']:.2f} ms over "
            f"{r['calls']} calls."
        )
    lines.append("")
    lines += _flexible_md(d.get("flexible", {}))
    lines += _kept_md(d)
    lines += identification_bench.render_md(d.get("identification", {}))
    lines += ski_job_bench.render_md(d.get("ski_job", {}))
    return lines


def bench_macro(repeats: int = 7, skis: tuple[str, ...] = ("ski-a", "ski-b")) -> dict:
    """Median time of one macro solve per demo ski at the default grid vs a fine reference.

    One untimed warm-up solve per grid first (numba compilation, kernel cache), as in the
    running service. The fine reference is 0.5 mm × 16 pixels across, timed twice.

    Returns a dict per ski: default and fine grid (pixel sizes [mm]), median solve time [s],
    apparent area [cm²] (sub-pixel zone edges), the same area by pixel counting [cm²], peak
    pressure [kPa], iterations, and the relative errors of the default grid.
    """
    e_eff = effective_modulus(200e6, 0.7e9, 0.3)
    load_n, xf = 40.0 * G_STANDARD, -0.160
    out: dict = {}
    for name in skis:
        ski = read_ski(SHIPPED_SKI_DIR / f"{name}.h5")
        x, gap = profile_model(ski)(load_n, xf)
        width = float(ski.outline.width_m.max())
        rows = {}
        for label, dx, ny in (
            ("default", DEFAULT_PIXEL_ALONG_M, DEFAULT_PIXEL_ACROSS),
            ("fine", 0.5e-3, 16),
        ):
            gm = extrude_profile(x, gap, width, pixel_along_m=dx, pixels_across=ny)
            res = solve_macro(gm, load_n, xf, e_eff)  # warm-up
            times = []
            for _ in range(repeats if label == "default" else 2):
                t0 = time.perf_counter()
                res = solve_macro(gm, load_n, xf, e_eff)
                times.append(time.perf_counter() - t0)
            p = np.nan_to_num(res.pressure_pa)
            rows[label] = {
                "pixel_mm": (dx * 1e3, width / ny * 1e3),
                "median_time_s": float(np.median(times)),
                "area_cm2": res.apparent_contact_area_m2 * 1e4,
                "pixel_count_area_cm2": float(np.count_nonzero(p > 0) * dx * width / ny * 1e4),
                "peak_pressure_kpa": res.peak_pressure_pa * 1e-3,
                "iterations": res.iterations,
                "converged": res.converged,
            }
        d, f = rows["default"], rows["fine"]
        rows["area_error"] = d["area_cm2"] / f["area_cm2"] - 1
        rows["peak_pressure_error"] = d["peak_pressure_kpa"] / f["peak_pressure_kpa"] - 1
        out[name] = rows
    return out
