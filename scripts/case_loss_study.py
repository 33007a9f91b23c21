"""How much a camber file's cases left out for readings lost inside the span cost (#26).

A reading lost in the middle of the span costs its whole case (``app.storage.skis``,
unmeasured="drop"). This study measures what that does to the ski job's beam: each design
is measured by the virtual device (the own-ski study's noise and grids, with the unloaded
profile), identified as the ski job identifies it (its held-out draw, the pool), then again
with ``k`` loaded cases left out (drawn with a seed, never a held-out case). Per run: served or
not (and why), misfit and held-out RMS over the noise, and the held-out profiles' error against
the true beam's where H* < 0.2 mm.

    python scripts/case_loss_study.py --designs random-701 touring-classic skate \\
        --grid coarse --spacing-mm 5 --lose 0 1 2 --out docs/studies/case-loss-coarse.json \\
        --md docs/studies/case-loss-coarse.md

``--designs example`` runs the example file of ``/upload`` (demo ski A), each seed another draw
of the cases left out.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import own_ski_study as st
from skisnow.app.path_pool import identify_with_pool
from skisnow.app.storage import common
from skisnow.app.storage.skis import mean_profiles
from skisnow.app.training.data import draw_held_out
from skisnow.solvers.identify import identify_beam_checked, predict_gaps
from skisnow.solvers.ski_designs import get_design

BAND_M = 0.2e-3


#: ``--designs example``: the example file of ``/upload`` (demo ski A, 9 × 5 every 5 mm, the
#: unloaded profile), its true beam the demo ski's; the seed then only draws the cases left out
EXAMPLE = "example"


def _example() -> tuple:
    """The example file's measurements and demo ski A's true beam."""
    import tempfile

    from skisnow.app.storage.skis import SHIPPED_SKI_DIR, read_camber_csv, read_ski
    from skisnow.app.web.upload_page import EXAMPLE_SKI, example_camber_csv

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "example.csv"
        path.write_text(example_camber_csv())
        data = read_camber_csv(path)
    return data, read_ski(SHIPPED_SKI_DIR / f"{EXAMPLE_SKI}.h5").beam


def run_one(design: str, grid: str, spacing_mm: float, lose: int, seed: int) -> dict:
    """One identification of ``design`` measured on ``grid`` with ``lose`` cases left out."""
    if design == EXAMPLE:
        data, truth = _example()
        grid, spacing_mm = "coarse", data.sample_spacing_mm
    else:
        truth = get_design(design).build(st.SPACING_M)
        data = st.camber_data(design, truth, grid, seed, True, spacing_mm)
    f, xf, y, _ = mean_profiles(data)
    held = draw_held_out(f, xf)
    loaded = np.flatnonzero(f > 0)
    candidates = np.setdiff1d(loaded, held)
    gone = np.random.default_rng(seed + 1000 + lose).choice(candidates, lose, replace=False)
    keep = np.setdiff1d(np.arange(f.size), gone)
    # held-out indices into the kept cases
    held_kept = np.searchsorted(keep, held)
    t0 = time.perf_counter()
    ident, check = identify_with_pool(
        identify_beam_checked,
        data.positions_m,
        f[keep],
        xf[keep],
        y[keep],
        held_out_index=held_kept,
    )
    wall = time.perf_counter() - t0
    out = {
        "design": design,
        "grid": grid,
        "spacing_mm": spacing_mm,
        "seed": seed,
        "cases_left_out": int(lose),
        "loaded_cases": int((f[keep] > 0).sum()),
        "served": bool(ident.ok),
        "reason": ident.reason or "",
        "misfit_over_noise": float(ident.misfit_m / ident.noise_m),
        "held_out_over_noise": (
            float(check["held_out_rms_band_m"] / ident.noise_m)
            if check["held_out_rms_band_m"] is not None
            else None
        ),
        "wall_s": round(wall, 1),
    }
    if ident.ok:
        pred = predict_gaps(ident.beam, f[held], xf[held], data.positions_m)
        true = predict_gaps(truth, f[held], xf[held], data.positions_m)
        band = true < BAND_M
        out["held_out_profile_error_um"] = float(np.sqrt(np.mean((pred - true)[band] ** 2))) * 1e6
    return out


def write_md(rows: list[dict], path: Path, meta: dict) -> None:
    lines = [
        "# Cases left out for readings lost inside the span (issue #26)",
        "",
        f"_{meta['created']}, commit {meta['commit'][:12]}: {meta['command']}_",
        "",
        "Each design measured by the virtual device (3 µm noise, the unloaded profile), "
        "identified as the ski job does (its held-out draw), then with k loaded cases left "
        "out (never a held-out one). Held-out profile error: the served beam against the true "
        "beam on the held-out cases where H* < 0.2 mm.",
        "",
        "| design | grid | spacing [mm] | seed | left out | loaded cases | served | misfit / "
        "noise | held-out / noise | held-out profile error [µm] | time [s] |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        err = r.get("held_out_profile_error_um")
        ho = r["held_out_over_noise"]
        lines.append(
            f"| {r['design']} | {r['grid']} | {r['spacing_mm']:g} | {r['seed']} | "
            f"{r['cases_left_out']} | {r['loaded_cases']} | {'yes' if r['served'] else 'no'} | "
            f"{r['misfit_over_noise']:.3f} | {'–' if ho is None else f'{ho:.2f}'} | "
            f"{'–' if err is None else f'{err:.2f}'} | {r['wall_s']:.0f} |"
        )
    by_k: dict[int, list[dict]] = {}
    for r in rows:
        by_k.setdefault(r["cases_left_out"], []).append(r)
    lines += [
        "",
        "| left out | served | held-out profile error, median / max [µm] |",
        "|---|---|---|",
    ]
    for k, rs in sorted(by_k.items()):
        errs = [r["held_out_profile_error_um"] for r in rs if r["served"]]
        med = f"{np.median(errs):.2f} / {max(errs):.2f}" if errs else "–"
        lines.append(f"| {k} | {sum(r['served'] for r in rs)} of {len(rs)} | {med} |")
    path.write_text("\n".join(lines) + "\n")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--designs", nargs="+", required=True)
    ap.add_argument("--grid", choices=sorted(st.GRIDS), default="coarse")
    ap.add_argument("--spacing-mm", type=float, default=5.0)
    ap.add_argument("--lose", nargs="+", type=int, default=[0, 1, 2])
    ap.add_argument("--seeds", nargs="+", type=int, default=[11])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--md", type=Path)
    args = ap.parse_args(argv)
    rows = []
    for design in args.designs:
        for seed in args.seeds:
            for k in args.lose:
                row = run_one(design, args.grid, args.spacing_mm, k, seed)
                rows.append(row)
                print(json.dumps(row), flush=True)
    params = {k: str(v) for k, v in vars(args).items()}
    common.write_study_json(args.out, "skisnow.case-loss/1", params, {"rows": rows})
    if args.md:
        prov = common.provenance(params)
        meta = {
            "created": prov["created_utc"],
            "commit": prov["git_commit"],
            "command": f"`{prov['command_line']}`",
        }
        write_md(rows, args.md, meta)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
