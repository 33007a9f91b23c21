"""The error band of a bending-ski answer, case by case (issue #12 point 4, docs/limits.md
"Error band", "Answers of the bending ski").

For each case (demo ski, load F at x_F, snow modulus) the answer is solved as the service does
with ``ski_model`` "flexible": the ski's identified beam (its served beam) on the default
preset's grid, then the texture table. Recorded per quantity:

- the answer, its solve on the grid twice as coarse (``c2``, the band's per-answer grid
  estimate) and the **truth**: the ski's own design beam (no device noise) on the reference
  grid of ``skisnow bench accuracy`` (0.5 mm × 64 across, as the rigid calibration test);
- the answer with the ski's true beam on the answer's own grid (``design``): its difference
  to the answer is the identification's own error, which the camber part stands for;
- the band's components: ``macro_grid`` (:func:`app.service.band.grid_component` with the coarse
  nominal; ``macro_grid_preset`` without it) and ``table_interpolation``, and the
  ``camber_model`` spread for each of :data:`SCALES` (factor on the identification
  covariance's deviations of the beam draws) and each kind of draw (:data:`KINDS`):
  ``full8``, ``full4``, ``full2`` (EI(X) and c(X) drawn together,
  :func:`solvers.identify.sample_beams`, 8, 4 or 2 draws: what the service does with
  ``BEAM_SAMPLES`` of that value) and ``camber8`` (the 8 draws' c(X) on the identified EI(X),
  so that all draws share one flexibility);
- the answer's and the band's solve times.

Two sets of cases:

``test``
    the calibration test's own cases (tests/service/test_band.py, the bending-ski tests): the camber
    network's test-split loads of both demo skis (6 per ski, seed 0) at 5, 20, 200 and
    2000 MPa;
``calib``
    cases the test does not use: the identification's held-out loads not among the test's
    (6 per ski, seed 1) at 2, 10, 50 and 500 MPa.

The summary fits, per kind of draw, the factor (the smallest of :data:`SCALES` whose camber
part alone covers 90 % of the ``calib`` identification errors), then per quantity the grid
factor (the smallest of :data:`GRID_FACTORS` that puts 90 % of the ``calib`` truths inside the
whole band), and checks both on ``test``; then it prints the service's own constants
(:data:`app.service.band.BEAM_SAMPLES`, :data:`app.service.band_sampling.BEAM_SCALE`,
:data:`app.service.band.FLEXIBLE_GRID_FACTOR`) on both sets. ``--summary`` reprints it from a
written file.

Usage::

    python scripts/flexible_band_study.py --out /tmp/flex_band.json
    python scripts/flexible_band_study.py --summary /tmp/flex_band.json

About 45 min on a loaded 2-core machine (the reference truth is 10–20 s per case).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app.presets import PRESETS  # noqa: E402
from skisnow.app.service import (  # noqa: E402
    band,
    band_sampling,
)
from skisnow.app.service.band_calibration import beam_scale_at  # noqa: E402
from skisnow.app.service.profiles import served_beam  # noqa: E402
from skisnow.app.storage.skis import identification_for_sampling, read_ski  # noqa: E402
from skisnow.app.storage.tables import read_table  # noqa: E402
from skisnow.solvers.beam import BeamSki  # noqa: E402
from skisnow.solvers.elastic import effective_modulus  # noqa: E402
from skisnow.solvers.flexible import prepare_flexible, solve_flexible  # noqa: E402
from skisnow.solvers.identify import sample_beams  # noqa: E402
from skisnow.solvers.multiscale import multiscale  # noqa: E402

TABLES = REPO / "tables"
#: the truth's grid: the reference of ``skisnow bench accuracy`` (as tests/service/test_band.py)
REFERENCE_GRID = (0.5e-3, 64)
SCALES = (1.0, 2.0, 4.0, 8.0, 12.0, 16.0, 24.0, 32.0)
#: draw counts compared: n antithetic draws are the first n/2 pairs of the 8 (the service's
#: draws for ``BEAM_SAMPLES = n`` exactly, same seed)
DRAW_COUNTS = (8, 4, 2)
#: the kinds of camber part compared: ``full<n>`` (EI and c, n draws), ``camber8``
KINDS = (*(f"full{n}" for n in DRAW_COUNTS), "camber8")
TEST_MODULI_MPA = (5.0, 20.0, 200.0, 2000.0)
CALIB_MODULI_MPA = (2.0, 10.0, 50.0, 500.0)
CASES_PER_SKI = 6


def _prepare(beam, rec, dx, ny):
    o = rec.outline
    return prepare_flexible(
        beam, o.width_m, pixel_along_m=dx, pixels_across=ny, width_positions_m=o.positions_m
    )


def test_loads(rec) -> list[tuple[float, float]]:
    """The test set's loads of a demo ski: its network's test split, 6 drawn with seed 0."""
    f = np.asarray(rec.network["split_test_loads_n"], dtype=float)
    x = np.asarray(rec.network["split_test_load_positions_m"], dtype=float)
    pick = np.random.default_rng(0).choice(f.size, CASES_PER_SKI, replace=False)
    return [(float(f[i]), float(x[i])) for i in pick]


def calib_loads(rec) -> list[tuple[float, float]]:
    """The calib set's loads: the identification's held-out cases not in the test's, 6 drawn
    with seed 1."""
    idx = np.asarray(rec.identified["held_out_index"], dtype=int)
    mf, mx = rec.measurements.loads_n[idx], rec.measurements.load_positions_m[idx]
    used = {(round(f, 6), round(x, 6)) for f, x in test_loads(rec)}
    keep = [k for k in range(idx.size) if (round(mf[k], 6), round(mx[k], 6)) not in used]
    pick = np.random.default_rng(1).choice(keep, CASES_PER_SKI, replace=False)
    return [(float(mf[k]), float(mx[k])) for k in pick]


class SkiModels:
    """Every flexible model of one demo ski the study needs, prepared once. ``service_only``:
    only the service's own draws (:meth:`service_draws`), not the candidates of
    :data:`SCALES` and :data:`KINDS`."""

    def __init__(self, rec, preset, service_only: bool = False):
        self.rec = rec
        self._service: dict[float, list] = {}
        dx, ny = band_sampling.coarse_grid(preset)
        ident = served_beam(rec.identified)
        self.answer = _prepare(ident, rec, preset.pixel_along_m, preset.pixels_across)
        self.coarse = _prepare(ident, rec, dx, ny)
        self.design = _prepare(rec.beam, rec, preset.pixel_along_m, preset.pixels_across)
        self.truth = _prepare(rec.beam, rec, *REFERENCE_GRID)
        ib = self._ib = identification_for_sampling(rec.identified)
        self._coarse_grid = (dx, ny)
        self.draws = {}
        for s in () if service_only else SCALES:
            beams = sample_beams(ib, max(DRAW_COUNTS), band.BAND_SEED, scale=s, antithetic=True)
            full = [_prepare(b, rec, dx, ny) for b in beams]
            half = len(full) // 2
            for n in DRAW_COUNTS:
                self.draws[(f"full{n}", s)] = full[: n // 2] + full[half : half + n // 2]
            shared = [
                BeamSki(b.positions_m, ident.bending_stiffness_nm2, b.unloaded_gap_m) for b in beams
            ]
            self.draws[("camber8", s)] = [_prepare(b, rec, dx, ny) for b in shared]

    def service_draws(self, scale: float) -> list:
        """The service's draws at ``scale`` (:data:`app.service.band.BEAM_SAMPLES`, antithetic,
        seed :data:`app.service.band.BAND_SEED`) on the coarse grid, prepared once per scale."""
        if scale not in self._service:
            beams = sample_beams(
                self._ib, band.BEAM_SAMPLES, band.BAND_SEED, scale=scale, antithetic=True
            )
            self._service[scale] = [_prepare(b, self.rec, *self._coarse_grid) for b in beams]
        return self._service[scale]


def case_row(name, models: SkiModels, table, f, xf, e_mpa, preset):
    e = effective_modulus(e_mpa * 1e6, 700e6, 0.3)
    t0 = time.perf_counter()
    m = solve_flexible(models.answer, f, xf, e)
    ms = multiscale(m, table, 0.5, e)
    t_answer = time.perf_counter() - t0
    unresolved = band.min_separation_unresolved(models.answer.unloaded_map, m, ms)
    spreads, t_band = {}, {}
    t0 = time.perf_counter()
    sampled = band._sample_flexible(m, ms, (models.coarse, []), table, 0.5, e)
    t_band["coarse"] = time.perf_counter() - t0
    for key, drawn in models.draws.items():
        t0 = time.perf_counter()
        draws = band._sample_flexible(m, ms, (models.coarse, drawn), table, 0.5, e)
        t_band[f"{key[0]}:{key[1]:g}"] = time.perf_counter() - t0
        spreads[f"{key[0]}:{key[1]:g}"] = None if draws is None else draws.widths
    # the service's own camber part: its draws at its factor for this snow modulus
    scale = beam_scale_at(e)
    t0 = time.perf_counter()
    draws = band._sample_flexible(
        m, ms, (models.coarse, models.service_draws(scale)), table, 0.5, e
    )
    t_band["service"] = time.perf_counter() - t0
    spreads[SERVICE_KEY] = None if draws is None else draws.widths
    grid = band.grid_component(preset, m, sampled)
    grid_no_coarse = band.grid_component(preset, m, None)
    tab = band._table_component(table, m, 0.5, e)
    design = solve_flexible(models.design, f, xf, e)
    design_q = band_sampling._quantities(design, multiscale(design, table, 0.5, e))
    t0 = time.perf_counter()
    truth = solve_flexible(models.truth, f, xf, e)
    mst = multiscale(truth, table, 0.5, e)
    t_truth = time.perf_counter() - t0
    return {
        "ski": name,
        "load_n": f,
        "load_position_m": xf,
        "e_snow_mpa": e_mpa,
        "converged": bool(m.converged and truth.converged),
        "values": {
            "answer": band_sampling._quantities(m, ms),
            "c2": None if sampled is None else sampled.grid,
            "truth": band_sampling._quantities(truth, mst),
            "design": design_q,
        },
        "camber_model": spreads,
        "macro_grid": grid,
        "macro_grid_preset": grid_no_coarse,
        "table_interpolation": tab,
        "min_separation_unresolved": unresolved,
        "time_s": {"answer": t_answer, "band": t_band, "truth": t_truth},
        "zones": len(ms.zones),
    }


# ----------------------------------------------------------------------------- summary

#: the camber part of the service's own draws (factor per snow modulus) in a row's spreads
SERVICE_KEY = "service:0"


def service_summary(rows) -> dict[str, float]:
    """The grid factors fitted on ``calib`` with the service's own camber part (its draws at
    :func:`app.service.band_calibration.beam_scale_at`), and the band they give on both sets,
    per quantity and snow modulus; returns the factors."""
    rows = [r for r in rows if "values" in r and r["converged"]]
    calib = [r for r in rows if r["set"] == "calib"]
    test = [r for r in rows if r["set"] == "test"]
    k = fit_grid(calib, "service", 0.0, "coarse")
    print("\nThe service's draws (factor per snow modulus); grid factors fitted on calib:", k)
    print("served now:", band.FLEXIBLE_GRID_FACTOR, "apparent area per snow modulus")
    print("| set | quantity | cases | inside | mean half-width | RMS error | ratio |")
    print("|---|---|---|---|---|---|---|")
    for factors, label in ((k, "fitted"), (served_factors, "served")):
        for name, sel in (("calib", calib), ("test", test)):
            for q in band.QUANTITIES:
                print(
                    _row(f"{label} {name} | {q}", pairs(sel, "service", 0.0, factors, "coarse", q))
                )
            print(_row(f"{label} {name} | all", pairs(sel, "service", 0.0, factors)))
            for e_mpa in sorted({r["e_snow_mpa"] for r in sel}):
                sub = [r for r in sel if r["e_snow_mpa"] == e_mpa]
                print(_row(f"{label} {name} | {e_mpa:g} MPa", pairs(sub, "service", 0.0, factors)))
    return k


#: candidate factors on a bending-ski answer's grid part, per quantity
GRID_FACTORS = tuple(float(k) for k in np.round(np.arange(0.5, 4.001, 0.05), 2))
#: the share of ``calib`` truths each factor must put inside (as the rigid grid factors)
COVER = 0.9


def _finite(w) -> bool:
    return w is not None and math.isfinite(w)


def served_factors(row) -> dict[str, float]:
    """The service's factors on the grid part of ``row``'s answer, per quantity
    (:func:`app.service.band.flexible_grid_factors` at its snow modulus)."""
    return band.flexible_grid_factors(effective_modulus(row["e_snow_mpa"] * 1e6, 700e6, 0.3))


def widths(row, kind, scale, grid_factor=None, min_sep="coarse"):
    """The band of ``row`` (relative half-widths per quantity) with the camber part of draws
    ``kind`` at deviations × ``scale``, the grid part × ``grid_factor`` (per quantity; 1 when
    missing; a callable gives them per row, e.g. :func:`served_factors`) and the minimum
    separation's grid part from the coarse solve (``coarse``) or the preset's constant
    (``preset``)."""
    if callable(grid_factor):
        grid_factor = grid_factor(row)
    camber = row["camber_model"].get(f"{kind}:{scale:g}") or {}
    grid = dict(row["macro_grid"] if min_sep == "coarse" else row["macro_grid_preset"])
    grid = {q: w * (grid_factor or {}).get(q, 1.0) for q, w in grid.items()}
    out = band.combine(
        {
            "camber_model": camber,
            "macro_grid": grid,
            "table_interpolation": row["table_interpolation"],
        }
    )
    if row["min_separation_unresolved"]:
        out["min_average_separation"] = float("nan")
    return out


def errors(row, against="truth"):
    a, t = row["values"]["answer"], row["values"][against]
    return {q: abs(a[q] / t[q] - 1) if t[q] else float("nan") for q in band.QUANTITIES}


def pairs(rows, kind, scale, grid_factor=None, min_sep="coarse", quantity=None):
    """(actual error, half-width) per answer and quantity with a band."""
    out = []
    for r in rows:
        w, e = widths(r, kind, scale, grid_factor, min_sep), errors(r)
        for q in band.QUANTITIES if quantity is None else (quantity,):
            if _finite(w.get(q)) and _finite(e[q]):
                out.append((q, e[q], w[q]))
    return out


def stats(p) -> tuple[int, float, float, float]:
    """Cases, share inside, mean half-width, RMS actual error."""
    if not p:
        return 0, float("nan"), float("nan"), float("nan")
    err = np.array([x[1] for x in p])
    wid = np.array([x[2] for x in p])
    return len(p), float(np.mean(err <= wid)), float(wid.mean()), float(np.sqrt(np.mean(err**2)))


def fit_scale(rows, kind) -> float:
    """The smallest scale whose camber part alone covers :data:`COVER` of the identification's
    own error (the answer against the true beam on the answer's grid) on ``rows``."""
    for scale in SCALES:
        ins = []
        for r in rows:
            c = r["camber_model"].get(f"{kind}:{scale:g}") or {}
            e = errors(r, "design")
            unresolved = r["min_separation_unresolved"]
            for q in band.QUANTITIES:
                if q == "min_average_separation" and unresolved:
                    continue
                if _finite(c.get(q)) and _finite(e[q]):
                    ins.append(e[q] <= c[q])
        if np.mean(ins) >= COVER:
            return scale
    return SCALES[-1]


def fit_grid(rows, kind, scale, min_sep) -> dict[str, float]:
    """Per quantity the smallest factor of :data:`GRID_FACTORS` on the grid part that puts
    :data:`COVER` of the ``rows``' truths inside the whole band."""
    out = {}
    for q in band.QUANTITIES:
        out[q] = GRID_FACTORS[-1]
        for k in GRID_FACTORS:
            _, ins, _, _ = stats(pairs(rows, kind, scale, {q: k}, min_sep, q))
            if ins >= COVER:
                out[q] = k
                break
    return out


def _row(label, p) -> str:
    n, ins, w, e = stats(p)
    return f"| {label} | {n} | {ins:.1%} | {w:.2%} | {e:.2%} | {w / e:.2f} |"


def summary(rows) -> None:
    rows = [r for r in rows if "values" in r and r["converged"]]
    calib = [r for r in rows if r["set"] == "calib"]
    test = [r for r in rows if r["set"] == "test"]
    print("Identification error alone (answer against the true beam on the answer's grid) against")
    print("the camber part, and the whole error (against the reference truth), per draw kind:")
    print(
        "| set | draws | scale | id. error inside camber part | camber width (mean) | "
        "id. error RMS | whole error inside band (grid × 1) |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, sel in (("calib", calib), ("test", test)):
        for kind in KINDS:
            for scale in SCALES:
                ins, wid, err = [], [], []
                for r in sel:
                    c = r["camber_model"].get(f"{kind}:{scale:g}") or {}
                    e = errors(r, "design")
                    for q in band.QUANTITIES:
                        if q == "min_average_separation" and r["min_separation_unresolved"]:
                            continue
                        if _finite(c.get(q)) and _finite(e[q]):
                            ins.append(e[q] <= c[q])
                            wid.append(c[q])
                            err.append(e[q])
                _, whole, _, _ = stats(pairs(sel, kind, scale))
                print(
                    f"| {name} | {kind} | {scale:g} | {np.mean(ins):.1%} | {np.mean(wid):.3%} | "
                    f"{np.sqrt(np.mean(np.square(err))):.3%} | {whole:.1%} |"
                )
    print("\nPer kind of camber part: its scale fitted on calib, then the grid factors (minimum")
    print("separation from the coarse estimate, or the preset's constant):")
    print(
        "| kind | scale | min. separation | grid factors | calib inside | calib ratio | "
        "test inside | test ratio | test worst quantity |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for kind in (*KINDS, "none"):
        scale = 1.0 if kind == "none" else fit_scale(calib, kind)
        for min_sep in ("coarse", "preset"):
            k = fit_grid(calib, kind, scale, min_sep)
            c = stats(pairs(calib, kind, scale, k, min_sep))
            t = stats(pairs(test, kind, scale, k, min_sep))
            worst = min(
                (stats(pairs(test, kind, scale, k, min_sep, q))[1], q) for q in band.QUANTITIES
            )
            print(
                f"| {kind} | {scale:g} | {min_sep} | {k} | {c[1]:.1%} | {c[2] / c[3]:.2f} | "
                f"{t[1]:.1%} | {t[2] / t[3]:.2f} | {worst[1]} {worst[0]:.1%} |"
            )
    kind = f"full{band.BEAM_SAMPLES}"
    k = served_factors
    # contact answers now scale their draws per snow modulus (band_calibration.beam_scale_at,
    # calibrated on the own-ski study); this summary keeps the demo-ski factor (the flex sheet's)
    print(
        f"\nthe flex sheet's factor: {kind}, scale {band_sampling.BEAM_SCALE:g}, grid factors "
        "served (apparent area per snow modulus)"
    )
    print("| set | quantity | cases | inside | mean half-width | RMS error | ratio |")
    print("|---|---|---|---|---|---|---|")
    for name, sel in (("calib", calib), ("test", test)):
        for q in band.QUANTITIES:
            print(_row(f"{name} | {q}", pairs(sel, kind, band_sampling.BEAM_SCALE, k, "coarse", q)))
        print(_row(f"{name} | all", pairs(sel, kind, band_sampling.BEAM_SCALE, k)))
    for name, sel in (("calib", calib), ("test", test)):
        for e_mpa in sorted({r["e_snow_mpa"] for r in sel}):
            sub = [r for r in sel if r["e_snow_mpa"] == e_mpa]
            print(
                _row(
                    f"{name} | {e_mpa:g} MPa",
                    pairs(sub, kind, band_sampling.BEAM_SCALE, served_factors),
                )
            )
        print(_row(f"{name} | all, grid × 1", pairs(sel, kind, band_sampling.BEAM_SCALE)))
        print(_row(f"{name} | all, no camber part", pairs(sel, "none", 1.0, served_factors)))
    tb = {k: np.median([r["time_s"]["band"][k] for r in rows]) for k in rows[0]["time_s"]["band"]}
    print("\nmedian band time [ms]:", {k: round(float(v) * 1e3, 1) for k, v in tb.items()})
    t_answer = np.median([r["time_s"]["answer"] for r in rows])
    print("median answer time (flexible solve and multiscale) [ms]:", round(1e3 * t_answer, 1))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path)
    ap.add_argument("--summary", type=Path, help="print the summary of a written file")
    ap.add_argument("--sets", nargs="+", default=["calib", "test"])
    ap.add_argument(
        "--service-only",
        action="store_true",
        help="only the service's own draws (its factor per snow modulus): fits the grid factors",
    )
    args = ap.parse_args(argv)
    if args.summary:
        rows = json.loads(args.summary.read_text())
        if not any(
            SERVICE_KEY in r.get("camber_model", {}) and len(r["camber_model"]) == 1 for r in rows
        ):
            summary(rows)
        service_summary(rows)
        return
    if args.out is None:
        ap.error("--out or --summary is required")
    table = read_table(TABLES / "grind-1.h5")
    preset = PRESETS["default"]
    rows = []
    for name in ("ski-a", "ski-b"):
        rec = read_ski(TABLES / "skis" / f"{name}.h5")
        models = SkiModels(replace(rec, cache={}), preset, args.service_only)
        for s in args.sets:
            loads = test_loads(rec) if s == "test" else calib_loads(rec)
            moduli = TEST_MODULI_MPA if s == "test" else CALIB_MODULI_MPA
            for f, xf in loads:
                for e in moduli:
                    try:
                        r = case_row(name, models, table, f, xf, e, preset)
                    except Exception as exc:  # a failing case is recorded, the study goes on
                        r = {"ski": name, "load_n": f, "load_position_m": xf, "e_snow_mpa": e}
                        r["error"] = repr(exc)
                    r["set"] = s
                    rows.append(r)
                    print(s, name, f"{f:.0f} N {xf * 1e3:.0f} mm {e:g} MPa", file=sys.stderr)
                    args.out.write_text(json.dumps(rows, default=float, indent=1))
    if not args.service_only:
        summary(rows)
    service_summary(rows)


if __name__ == "__main__":
    main()
