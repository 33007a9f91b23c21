"""``skisnow build-tables``: the micro-scale lookup tables of textures
(:mod:`app.jobs.table_build`), optionally with the adaptive fourth pixel level
(:mod:`app.jobs.table_fourth_level`) and the light-load levels
(:mod:`app.jobs.table_light_levels`)."""

from __future__ import annotations

import argparse
import functools
import logging
import time
from collections.abc import Sequence
from pathlib import Path

from skisnow.app.jobs.table_build import build_tables
from skisnow.app.jobs.table_fourth_level import fourth_level_pass
from skisnow.app.jobs.table_settings import BuildSettings
from skisnow.app.storage.tables import (
    PIXEL_LEVEL_MODES,
    read_table,
    refinements,
)
from skisnow.solvers.errors import InputError
from skisnow.solvers.texture import DETREND_METHODS, Texture

__all__ = ["register"]

log = logging.getLogger(__name__)


def _load_textures(specs: Sequence[str], detrend: str | None = None) -> list[Texture]:
    from skisnow.app.storage.topography import load_texture

    return [load_texture(spec, detrend=detrend) for spec in specs]


def _command(args: argparse.Namespace) -> int:
    settings = BuildSettings(
        points=args.points,
        ratio_min=args.ratio_min,
        ratio_max=args.ratio_max,
        chunk_size=args.chunk_size,
        tol=args.tol,
        max_iterations=args.max_iterations,
        gap_floor_m=args.gap_floor_nm * 1e-9,
        pixel_levels=args.pixel_levels,
    )
    if args.light_load_levels:
        return _light_load_command(args)
    if args.from_table is not None:
        return _fourth_level_command(args)
    textures = _load_textures(args.textures, args.detrend)
    refined = None
    factors = refinements(args.pixel_levels)
    if factors:
        from skisnow.app.storage.textures import refined_texture

        if args.detrend is not None:
            raise InputError(
                f"--pixel-levels {args.pixel_levels} takes the stored synthetic texture as is"
            )
        refined = {
            t.name: [refined_texture(spec, k) for k in factors]
            for t, spec in zip(textures, args.textures, strict=True)
        }
    fourth_level = None
    if args.adaptive_level:
        from skisnow.app.storage.textures import refined_texture

        fourth_level = {
            t.name: functools.partial(refined_texture, spec)
            for t, spec in zip(textures, args.textures, strict=True)
        }
    t0 = time.perf_counter()
    paths = build_tables(
        textures,
        args.out,
        settings,
        scheduler=args.scheduler,
        workers=args.workers,
        keep_checkpoints=args.keep_checkpoints,
        refined=refined,
        device=args.device,
        fourth_level=fourth_level,
    )
    for name, path in paths.items():
        print(f"{name}: {path}")
    print(f"manifest: {Path(args.out) / 'manifest.json'} ({time.perf_counter() - t0:.1f} s)")
    return 0


def _fourth_level_command(args: argparse.Namespace) -> int:
    """``build-tables TEXTURE --adaptive-level --from-table PATH``: the pass alone."""
    from skisnow.app.storage.textures import refined_texture

    if not args.adaptive_level:
        raise InputError("--from-table runs the fourth-level pass: give --adaptive-level too")
    if len(args.textures) != 1:
        raise InputError(f"--from-table takes one texture, got {args.textures}")
    spec = args.textures[0]
    t0 = time.perf_counter()
    path = fourth_level_pass(
        args.from_table,
        args.out,
        functools.partial(refined_texture, spec),
        keep_checkpoints=args.keep_checkpoints,
        device=args.device,
    )
    print(f"{read_table(path).name}: {path} ({time.perf_counter() - t0:.1f} s)")
    return 0


def _light_load_command(args: argparse.Namespace) -> int:
    """``build-tables TEXTURE --light-load-levels --from-table PATH``: the light-load pass."""
    from skisnow.app.jobs.table_light_levels import light_load_pass
    from skisnow.app.storage.textures import refined_texture

    if args.from_table is None:
        raise InputError(
            "--light-load-levels runs on an existing table of several pixel levels: "
            "give --from-table PATH"
        )
    if args.adaptive_level:
        raise InputError("run --adaptive-level and --light-load-levels one after the other")
    if len(args.textures) != 1:
        raise InputError(f"--from-table takes one texture, got {args.textures}")
    t0 = time.perf_counter()
    path = light_load_pass(
        args.from_table,
        args.out,
        functools.partial(refined_texture, args.textures[0]),
        finest_grid=args.finest_grid,
        keep_checkpoints=args.keep_checkpoints,
        device=args.device,
    )
    print(f"{read_table(path).name}: {path} ({time.perf_counter() - t0:.1f} s)")
    return 0


def register(subparsers) -> None:
    """Add the ``build-tables`` subcommand."""
    d = BuildSettings()
    p = subparsers.add_parser(
        "build-tables",
        help="build micro-scale lookup tables (Dask)",
        description="Tabulate texture contact over P_n/E' on a Dask cluster; resumable.",
    )
    p.add_argument("textures", nargs="+", metavar="TEXTURE", help="shipped name or file path")
    p.add_argument("--out", required=True, type=Path, help="output directory")
    p.add_argument("--points", type=int, default=d.points, help=f"ratio grid points ({d.points})")
    p.add_argument("--ratio-min", type=float, default=d.ratio_min, help="lowest P_n/E' [-]")
    p.add_argument("--ratio-max", type=float, default=d.ratio_max, help="highest P_n/E' [-]")
    p.add_argument("--scheduler", default=None, help="address of an existing Dask scheduler")
    p.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes (2)")
    p.add_argument("--chunk-size", type=int, default=d.chunk_size, help="points per task")
    p.add_argument("--tol", type=float, default=d.tol, help="solver tolerance [-]")
    p.add_argument("--max-iterations", type=int, default=d.max_iterations)
    p.add_argument(
        "--device",
        choices=("cpu", "cuda", "torch-cpu"),
        default="cpu",
        help="where the micro solves run: cpu (numpy/pyFFTW, default), cuda (the torch "
        "backend on a GPU; torch with CUDA needed, one GPU per Dask worker) or torch-cpu",
    )
    p.add_argument(
        "--gap-floor-nm", type=float, default=d.gap_floor_m * 1e9, help="gap floor h_c [nm]"
    )
    p.add_argument("--keep-checkpoints", action="store_true", help="keep chunk checkpoints")
    p.add_argument(
        "--pixel-levels",
        choices=PIXEL_LEVEL_MODES,
        default=d.pixel_levels,
        help=(
            "none: the texture's grid only; refine: plus the same synthetic surface at half "
            "the pixel (shipped grinds); refine3: plus the surface at a half and a quarter of "
            "the pixel; coarsen: plus the texture at twice the pixel (any map). Several "
            "levels: zero-pixel extrapolation with a per-point error estimate"
        ),
    )
    p.add_argument(
        "--adaptive-level",
        action="store_true",
        help=(
            "refine3 only: after the three levels, solve the nodes with a_r in [1e-3, 0.9] "
            "where the three-level rule fell back once more at half the finest pixel (one at "
            "a time, ~12 GB for 8192²) and recombine them from their three finest levels"
        ),
    )
    p.add_argument(
        "--light-load-levels",
        action="store_true",
        help=(
            "with --from-table (a table of two or three levels): solve the nodes with a_r in "
            "[1e-4, 1e-3) and the node below on every finer pixel level down to "
            "--finest-grid, one at a time, and recombine them from their three finest levels "
            "(16384²: ~35 GB, a GPU's job: --device cuda)"
        ),
    )
    p.add_argument(
        "--finest-grid",
        type=int,
        default=16384,
        metavar="N",
        help="grid of the finest light-load level [pixels per side] (16384)",
    )
    p.add_argument(
        "--from-table",
        type=Path,
        default=None,
        metavar="PATH",
        help=(
            "with --adaptive-level or --light-load-levels: run only that pass on this existing "
            "table of TEXTURE (three levels for --adaptive-level; its own grid and solver "
            "settings, the options above are not used) and write OUT/<name>.h5"
        ),
    )
    p.add_argument(
        "--detrend",
        choices=DETREND_METHODS,
        default=None,
        help=(
            "what is removed from a height map file's heights: plane, mean (for a periodic "
            "map) or none; default plane for raw/measured maps, a stored texture (.h5, "
            "shipped grind) as it is (synthetic: mean); recorded in the table"
        ),
    )
    p.set_defaults(func=_command)
