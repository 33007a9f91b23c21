"""The beam-draw factor of a bending-ski answer's band, per snow modulus, on the own-ski study's
skis (issue #26 point 4; :data:`app.service.band_calibration.BEAM_SCALE_NODES`).

Input: the work folder of ``scripts/own_ski_study.py`` after a run and a ``--rescore`` (the kept
ski files ``skis/<design>-<grid>-d<draw>.h5`` and the rescored cases with their reference truths,
``rescored/<name>.json``). For every ski with an identified beam, every held-out case is asked
again through :func:`app.service.contact`:

- ``flexible`` with the beam draws' deviations × each of :data:`FLEX_SCALES` (the band's
  ``beam_scale``);
- ``rigid`` with the identified profile's spread × each of :data:`RIGID_SCALES`
  (:data:`app.service.band_calibration.IDENTIFIED_SIGMA_GRID_NODES`, the same at every
  modulus and grid), for
  comparison.

Per case it records the answer, its same-grid and reference truths (the true beam on the answer's
grid and on ``own_ski_study.REFERENCE_GRID``), the band's apparent-area half-width and its
components, and the warnings. The summary, per model, snow modulus and factor, over the
calibration draws (``--calib-draws``, default draw 0) and the others: the share of reference
truths inside the band, the mean half-width over the RMS error against the reference truth, and
the answers more than 3 % off, outside the band and without a warning. The chosen factor per
modulus is the smallest candidate that puts ≥ 90 % of the calibration draws' reference truths
inside.

Usage::

    python scripts/beam_scale_study.py --work /work/study/s6/work --out docs/studies/beam-scale.json

About 2–3 min per ski on a 2-core machine; per-ski results are cached in ``<work>/beam-scale``.
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import json
import logging
import math
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app import service  # noqa: E402
from skisnow.app.service import answer as answer_mod  # noqa: E402
from skisnow.app.service import band, band_calibration  # noqa: E402
from skisnow.app.service.profiles import served_beam  # noqa: E402
from skisnow.app.storage import common  # noqa: E402
from skisnow.app.storage.skis import read_ski  # noqa: E402
from skisnow.solvers.elastic import effective_modulus  # noqa: E402

log = logging.getLogger("beam_scale_study")

SCHEMA = "skisnow.beam-scale-study/1"
FLEX_SCALES = (1.0, 2.0, 4.0, 8.0, 16.0)
RIGID_SCALES = (1.0, 1.5, 2.0, 3.0)
COVERAGE_TARGET = 0.90
POROSITY = 0.5
AREA_OFF = 0.03


def cache_file(
    work: Path,
    name: str,
    flex_scales: tuple[float, ...],
    rigid_scales: tuple[float, ...],
    moduli_mpa: tuple[float, ...] | None = None,
) -> Path:
    """Where :func:`ski_rows` keeps ski ``name``'s answers: keyed by the factor lists, the
    snow moduli asked (``None``: every one), the commit, and the SHA-256 of the kept ski file
    and of its rescored truths, so that a ski re-identified (or rescored) at the same commit is
    answered again, not read back stale."""
    digests = [
        hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else None
        for p in (work / "skis" / f"{name}.h5", work / "rescored" / f"{name}.json")
    ]
    key = [list(flex_scales), list(rigid_scales), common.git_commit(), *digests]
    if moduli_mpa is not None:  # the key of a run over every modulus stays as it was
        key.append(sorted(moduli_mpa))
    key = json.dumps(key)
    tag = hashlib.sha256(key.encode()).hexdigest()[:10]
    return work / "beam-scale" / f"{name}-{tag}.json"


def ski_rows(
    work: Path,
    name: str,
    grind: str,
    flex_scales: tuple[float, ...] = FLEX_SCALES,
    rigid_scales: tuple[float, ...] = RIGID_SCALES,
    moduli_mpa: tuple[float, ...] | None = None,
) -> list[dict]:
    """Every held-out case of ski ``name`` (at the snow moduli ``moduli_mpa`` [MPa]; ``None``:
    every one) answered at every candidate factor (cached per ski, factor list, moduli and
    commit: :func:`cache_file`)."""
    cache = cache_file(work, name, flex_scales, rigid_scales, moduli_mpa)
    if cache.is_file():
        return json.loads(cache.read_text(encoding="utf-8"))
    fields = json.loads((work / "rescored" / f"{name}.json").read_text(encoding="utf-8"))["fields"]
    path = work / "skis" / f"{name}.h5"
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    base = service.load_catalogue(REPO / "tables")
    original = answer_mod.answer_band
    rigid_nodes = band_calibration.IDENTIFIED_SIGMA_GRID_NODES
    rows: list[dict] = []
    try:
        for model, scales in (("flexible", flex_scales), ("rigid", rigid_scales)):
            for s in scales:
                # a fresh record per factor: the band's beam models are cached per record
                cat = service.Catalogue(
                    tables_dir=base.tables_dir,
                    skis={name: service.Ski(name, path, sha, read_ski(path))},
                    grinds=dict(base.grinds),
                )
                if model == "flexible":
                    answer_mod.answer_band = functools.partial(original, beam_scale=s)
                else:
                    answer_mod.answer_band = original
                    # the same factor on every grid and node
                    band_calibration.IDENTIFIED_SIGMA_GRID_NODES = tuple(
                        (s,) * len(row) for row in rigid_nodes
                    )
                for c in fields["answers"]:
                    if "truth_ref_cm2" not in c:
                        continue
                    if moduli_mpa is not None and c["snow_modulus_mpa"] not in moduli_mpa:
                        continue
                    inp = service.ContactInputs(
                        name,
                        grind,
                        c["load_kg"],
                        c["load_position_mm"],
                        c["snow_modulus_mpa"],
                        POROSITY,
                        ski_model=model,
                    )
                    row = {
                        "model": model,
                        "scale": s,
                        "e_snow_mpa": c["snow_modulus_mpa"],
                        "load_kg": c["load_kg"],
                        "load_position_mm": c["load_position_mm"],
                    }
                    try:
                        a = service.contact(cat, inp)
                    except Exception as exc:  # a refusal is recorded, not fatal
                        rows.append({**row, "error": f"{type(exc).__name__}: {exc}"[:300]})
                        continue
                    comp = a["band"].get("components", {})
                    key = "rigid" if model == "rigid" else "flexible"
                    rows.append(
                        {
                            **row,
                            "area_cm2": a["apparent"]["contact_area_cm2"],
                            "truth_cm2": c["truth_cm2"][key],
                            "truth_ref_cm2": c["truth_ref_cm2"][key],
                            "half_width": a["band"]["relative_half_width"]["apparent_contact_area"],
                            "half_width_above": (
                                a["band"].get("relative_half_width_above") or {}
                            ).get("apparent_contact_area"),
                            "components": {
                                k: v.get("apparent_contact_area", 0.0) for k, v in comp.items()
                            },
                            "warnings": sorted({w["code"] for w in a.get("warnings", [])}),
                        }
                    )
    finally:
        answer_mod.answer_band = original
        band_calibration.IDENTIFIED_SIGMA_GRID_NODES = rigid_nodes
    cache.parent.mkdir(parents=True, exist_ok=True)
    with common.atomic_path(cache) as tmp:
        tmp.write_text(json.dumps(rows), encoding="utf-8")
    return rows


def served_sides(row: dict) -> tuple[float, float]:
    """The half-widths (below, above) the service serves now for a recorded row: its band's
    parts (``components``) as the service combines them (:func:`app.service.band.
    one_sided_widths`: the grid part below the answer on soft snow, symmetric in log from
    200 MPa); a row without parts, its recorded half-widths."""
    parts = row.get("components") or {}
    if not parts:
        return row["half_width"], row.get("half_width_above", row["half_width"])
    return band.one_sided_widths(parts, effective_modulus(row["e_snow_mpa"] * 1e6, 700e6, 0.3))


def _inside(area: float, truth: float, below: float, above: float | None = None) -> bool:
    """Whether the served band of an answer ``area`` of relative half-widths ``below`` and
    ``above`` (None: the same) holds ``truth`` (:func:`app.service.band.interval_90`)."""
    lo, hi = band.interval_90(area, below, above)
    return lo <= truth <= (math.inf if hi is None else hi)


def stats(rows: list[dict]) -> dict:
    """Coverage of the reference truth (by the band as served now, whatever the rows' commit),
    mean half-width over the RMS error, unwarned misses."""
    ok = [r for r in rows if "area_cm2" in r]
    if not ok:
        return {"answers": 0}
    err = np.array([r["area_cm2"] / r["truth_ref_cm2"] - 1 for r in ok])
    sides = [served_sides(r) for r in ok]
    hw = np.array([0.5 * (b + a) for b, a in sides])  # the mean of the two sides
    inside = np.array(
        [_inside(r["area_cm2"], r["truth_ref_cm2"], *s) for r, s in zip(ok, sides, strict=True)]
    )
    rms = float(np.sqrt(np.mean(err**2)))
    bad = int(
        np.sum((np.abs(err) > AREA_OFF) & ~inside & np.array([not r["warnings"] for r in ok]))
    )
    comp = {
        k: float(np.mean([r["components"].get(k, 0.0) for r in ok]))
        for k in ("camber_model", "macro_grid", "flat_base", "table_interpolation")
    }
    return {
        "answers": len(ok),
        "coverage": float(inside.mean()),
        "mean_half_width": float(hw.mean()),
        "rms_error": rms,
        "half_width_over_rms": float(hw.mean() / rms) if rms > 0 else None,
        "off_3pct_outside_unwarned": bad,
        "mean_components": comp,
    }


def summarise(
    rows: list[dict],
    calib_draws: set[int],
    flex_scales: tuple[float, ...] = FLEX_SCALES,
    rigid_scales: tuple[float, ...] = RIGID_SCALES,
) -> dict:
    out: dict = {}
    for model, scales in (("flexible", flex_scales), ("rigid", rigid_scales)):
        out[model] = {}
        for e in sorted({r["e_snow_mpa"] for r in rows}):
            per = {}
            for s in scales:
                sel = [
                    r
                    for r in rows
                    if r["model"] == model and r["e_snow_mpa"] == e and r["scale"] == s
                ]
                per[f"{s:g}"] = {
                    "calib": stats([r for r in sel if r["draw"] in calib_draws]),
                    "other": stats([r for r in sel if r["draw"] not in calib_draws]),
                    "all": stats(sel),
                }
            chosen = next(
                (
                    s
                    for s in scales
                    if (per[f"{s:g}"]["calib"].get("coverage") or 0) >= COVERAGE_TARGET
                ),
                scales[-1],
            )
            out[model][f"{e:g} MPa"] = {"per_scale": per, "chosen": chosen}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--work", type=Path, required=True, help="own_ski_study.py's work folder")
    ap.add_argument("--out", type=Path, default=REPO / "docs" / "studies" / "beam-scale.json")
    ap.add_argument("--calib-draws", type=int, nargs="+", default=[0])
    ap.add_argument("--grind", default="grind-1")
    ap.add_argument("--skis", nargs="+", help="ski names (default: every rescored ski)")
    ap.add_argument("--flex-scales", type=float, nargs="+", default=list(FLEX_SCALES))
    ap.add_argument("--rigid-scales", type=float, nargs="+", default=list(RIGID_SCALES))
    ap.add_argument(
        "--moduli",
        type=float,
        nargs="+",
        help="ask only the cases at these snow moduli [MPa] (default: every one)",
    )
    ap.add_argument(
        "--rows",
        action="store_true",
        help="write every answer too (MBs; the per-ski cache in <work>/beam-scale keeps them)",
    )
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(message)s")
    t0 = time.perf_counter()
    flex, rigid = tuple(args.flex_scales), tuple(args.rigid_scales)
    names = args.skis or sorted(p.stem for p in (args.work / "rescored").glob("*.json"))
    rows: list[dict] = []
    for i, name in enumerate(names, 1):
        rec = read_ski(args.work / "skis" / f"{name}.h5")
        if served_beam(rec.identified) is None:
            log.info("[%d/%d] %s: no identified beam served, skipped", i, len(names), name)
            continue
        t = time.perf_counter()
        moduli = tuple(args.moduli) if args.moduli else None
        got = ski_rows(args.work, name, args.grind, flex, rigid, moduli)
        design, grid, draw = name.rsplit("-", 2)
        for r in got:
            r.update(ski=name, design=design, grid=grid, draw=int(draw[1:]))
        rows += got
        log.info(
            "[%d/%d] %s: %d answers in %.0f s",
            i,
            len(names),
            name,
            len(got),
            time.perf_counter() - t,
        )
    summary = summarise(rows, set(args.calib_draws), flex, rigid)
    doc = {
        "schema": SCHEMA,
        "provenance": common.provenance(
            {
                "work": str(args.work),
                "calib_draws": args.calib_draws,
                "skis": names,
                "moduli_mpa": args.moduli,
            }
        ),
        "flex_scales": flex,
        "rigid_scales": rigid,
        "coverage_target": COVERAGE_TARGET,
        "summary": summary,
        **({"rows": rows} if args.rows else {}),
        "time_s": round(time.perf_counter() - t0, 1),
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with common.atomic_path(args.out) as tmp:
        tmp.write_text(json.dumps(doc, indent=0), encoding="utf-8")
    for model, per_e in summary.items():
        for e, v in per_e.items():
            print(f"{model} {e}: chosen ×{v['chosen']:g}")
            for s, st in v["per_scale"].items():
                line = []
                for part in ("calib", "other"):
                    x = st[part]
                    if x.get("answers"):
                        line.append(
                            f"{part} {x['answers']:3d}: inside {x['coverage']:.0%}, "
                            f"hw/rms {x['half_width_over_rms']:.2f}, "
                            f"unwarned {x['off_3pct_outside_unwarned']}"
                        )
                print(f"   ×{s:>4}: " + " | ".join(line))
    print(f"written {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
