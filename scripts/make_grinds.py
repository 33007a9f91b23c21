"""Fit and write the shipped synthetic linear grinds ``grind-1.h5`` and ``grind-2.h5``.

The two grinds of docs/physics.md §7 are matched by :func:`solvers.texture.fit_linear_grind` on a
1024 × 1024 grid of 1.5 µm pixels (a 1.536 mm square patch, white-light-interferometer
sampling). Pitches: grind 1 (fine) 0.384 mm, 4 grooves per cell; grind 2 (coarse) 0.768 mm,
2 grooves per cell. The starting points below come from an earlier, longer exploration with
the same fitter; the fit refines them, so the whole run takes a few minutes.

Usage::

    python scripts/make_grinds.py --out tables/textures --seed 1
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from skisnow.app.storage.textures import write_texture
from skisnow.solvers.texture import (
    GRIND_TARGETS,
    GRIND_TOLERANCES,
    GrindParameters,
    Texture,
    fit_linear_grind,
)

log = logging.getLogger("make_grinds")

SHAPE = (1024, 1024)
PIXEL_SIZE_M = 1.5e-6

#: Starting points of the fits (pitch, asymmetry, pitch jitter, Hurst and roll-off stay fixed)
INITIAL: dict[str, GrindParameters] = {
    "grind-1": GrindParameters(
        pitch_m=384e-6,
        depth_m=4.89e-6,
        land_fraction=0.14,
        groove_exponent=0.66,
        asymmetry=-0.3,
        lip_height_m=1.03e-6,
        lip_width_m=21.5e-6,
        pitch_jitter=0.05,
        depth_jitter=0.246,
        roughness_rms_m=1.17e-6,
        roughness_hurst=0.8,
        roughness_long_cutoff_m=150e-6,
        roughness_short_cutoff_m=79.7e-6,
    ),
    "grind-2": GrindParameters(
        pitch_m=768e-6,
        depth_m=24.8e-6,
        land_fraction=0.425,
        groove_exponent=1.68,
        asymmetry=0.12,
        lip_height_m=3.71e-6,
        lip_width_m=8.17e-6,
        pitch_jitter=0.05,
        depth_jitter=0.041,
        roughness_rms_m=1.68e-6,
        roughness_hurst=0.8,
        roughness_long_cutoff_m=100e-6,
        roughness_short_cutoff_m=34.0e-6,
    ),
}

DESCRIPTION = {
    "grind-1": "fine linear stone grind (synthetic stand-in for docs/physics.md §7 Grind 1)",
    "grind-2": "coarse linear stone grind (synthetic stand-in for docs/physics.md §7 Grind 2)",
}


def _fmt(key: str, value: float) -> str:
    if key.endswith("_m"):
        return f"{value * 1e6:9.3f} µm"
    if key == "Sdq":
        return f"{value * 1e3:9.2f} µm/mm"
    return f"{value:9.3f}   "


def report(name: str, fit) -> str:
    """Table of target vs achieved parameters of one fit."""
    lines = [f"{name}: {fit.message}", f"  {'param':8s} {'target':>15s} {'achieved':>15s}  err/tol"]
    for key, target in GRIND_TARGETS[name].items():
        kind, tol = GRIND_TOLERANCES[key]
        tol_txt = f"{tol:.0%} rel" if kind == "rel" else f"±{tol} abs"
        lines.append(
            f"  {key:8s} {_fmt(key, target):>15s} {_fmt(key, fit.achieved[key]):>15s}  "
            f"{fit.errors[key]:+.2f} ({tol_txt})"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("tables/textures"), help="directory")
    parser.add_argument("--seed", type=int, default=1, help="seed of every random draw")
    parser.add_argument("--grinds", nargs="+", default=sorted(INITIAL), choices=sorted(INITIAL))
    parser.add_argument("--max-evaluations", type=int, default=600, help="reduced search")
    parser.add_argument("--polish-evaluations", type=int, default=40, help="full-size polish")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")

    status = 0
    for name in args.grinds:
        t0 = time.perf_counter()
        fit = fit_linear_grind(
            GRIND_TARGETS[name],
            SHAPE,
            PIXEL_SIZE_M,
            args.seed,
            initial=INITIAL[name],
            fit_rows=256,
            max_evaluations=args.max_evaluations,
            polish_evaluations=args.polish_evaluations,
            callback=lambda stage, n, f: log.info(
                "  %s: %d evaluations, objective %.4f", stage, n, f
            ),
        )
        log.info("%s (%.0f s)", report(name, fit), time.perf_counter() - t0)
        if not fit.converged:
            status = 1
        texture = Texture(
            fit.heights_m,
            PIXEL_SIZE_M,
            name,
            0.0,
            f"synthetic: solvers.texture.linear_grind, {DESCRIPTION[name]}",
            detrend="mean",  # linear_grind removes the mean; a periodic map keeps its plane
        )
        path = args.out / f"{name}.h5"
        write_texture(
            texture,
            path,
            periodic=True,
            extra_attrs={
                "synthetic": True,
                "generator": "solvers.texture.linear_grind",
                "generator_seed": args.seed,
                "generator_parameters_json": fit.parameters.to_dict(),
                "target_parameters_json": GRIND_TARGETS[name],
                "target_errors_per_tolerance_json": fit.errors,
                "fit_converged": fit.converged,
                "fit_message": fit.message,
                "description": DESCRIPTION[name],
            },
        )
        log.info("wrote %s", path)
    return status


if __name__ == "__main__":
    raise SystemExit(main())
