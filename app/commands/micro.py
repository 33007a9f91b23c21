"""``skisnow micro``: one direct micro-scale solve on a height map or a shipped grind."""

from __future__ import annotations

import argparse
import json

from skisnow.app import units
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.errors import InputError
from skisnow.solvers.micro import solve_micro
from skisnow.solvers.texture import DETREND_METHODS, PERIODISATION_METHODS, make_periodic


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "micro",
        help="one micro-scale solve: a texture pressed into the snow at a nominal pressure",
        description=(
            "Press a rigid ski-base texture into the elastic snow at a nominal pressure "
            "(periodic FFT boundary elements) and print real contact area, mean gap and mean "
            "reciprocal gap. HEIGHTMAP is a shipped grind name (grind-1, grind-2) or a height "
            "map file, recognised by its content: measured .x3p (ISO 5436-2000 and ISO "
            "25178-72), instrument formats (.sur, .datx, .plu, .opd, .sdf, ...), a texture .h5, "
            "or a .npy/.csv grid (then --pixel-size-um and --height-unit are required). "
            "Measured maps are not periodic: --periodic says how they are made to fit the "
            "periodic solver (docs/topography.md). --detrend says what is removed from the "
            "heights first; the choice is printed and in the JSON answer."
        ),
    )
    p.add_argument("heightmap", metavar="HEIGHTMAP")
    p.add_argument(
        "--nominal-pressure-kpa",
        type=float,
        required=True,
        help="nominal pressure P_n on the texture [kPa]",
    )
    p.add_argument(
        "--snow-modulus-mpa", type=float, required=True, help="Young's modulus of the snow [MPa]"
    )
    p.add_argument(
        "--base-modulus-mpa",
        type=float,
        default=700.0,
        help="Young's modulus of the ski base [MPa] (default 700)",
    )
    p.add_argument("--poisson", type=float, default=0.3, help="Poisson's ratio (default 0.3)")
    p.add_argument(
        "--pixel-size-um", type=float, default=None, help="pixel size of a .npy/.csv grid [µm]"
    )
    p.add_argument("--height-unit", default=None, help="unit of .npy/.csv heights: m, mm, um, nm")
    p.add_argument(
        "--periodic",
        choices=PERIODISATION_METHODS,
        default=None,
        help=(
            "how a non-periodic map fits the periodic solver: mirror (even reflection, 4x the "
            "points), window (cosine taper to the mean plane at the edges) or none; default "
            "none for synthetic (periodic) textures such as the shipped grinds, mirror for "
            "measured maps"
        ),
    )
    p.add_argument(
        "--detrend",
        choices=DETREND_METHODS,
        default=None,
        help=(
            "what is removed from a height map's heights before the solve: plane (the "
            "least-squares plane), mean, or none; default plane for measured maps, mean when "
            "the map is declared periodic (--periodic none); a texture (.h5, shipped grind) is "
            "kept as stored (synthetic textures: mean) unless --detrend is given"
        ),
    )
    p.add_argument(
        "--along-ski",
        choices=("x", "y"),
        default="x",
        help="axis of the file that runs along the ski (default x; y transposes the map)",
    )
    p.add_argument(
        "--channel", type=int, default=None, help="0-based channel of a multi-channel file"
    )
    p.add_argument("--tol", type=float, default=1e-6, help="solver tolerance (default 1e-6)")
    p.add_argument("--max-iterations", type=int, default=2000)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from skisnow.app.storage.topography import load_texture

    if args.nominal_pressure_kpa is None or not args.nominal_pressure_kpa >= 0:
        raise InputError(f"--nominal-pressure-kpa must be >= 0, got {args.nominal_pressure_kpa}")
    detrend = args.detrend
    if detrend is None and args.periodic == "none":  # declared periodic: no plane to remove
        detrend = "mean"
    texture = load_texture(
        args.heightmap,
        pixel_size_um=args.pixel_size_um,
        height_unit=args.height_unit,
        detrend=detrend,
        along_ski=args.along_ski,
        channel=args.channel,
    )
    periodic = args.periodic
    if periodic is None:  # synthetic textures are periodic by construction (solvers.texture)
        periodic = "none" if texture.source.startswith("synthetic") else "mirror"
    heights_m = make_periodic(texture.heights_m, periodic)
    e_eff = effective_modulus(
        units.mpa_to_pa(args.snow_modulus_mpa),
        units.mpa_to_pa(args.base_modulus_mpa),
        args.poisson,
    )
    res = solve_micro(
        heights_m,
        texture.pixel_size_m,
        units.kpa_to_pa(args.nominal_pressure_kpa),
        e_eff,
        tol=args.tol,
        max_iterations=args.max_iterations,
    )
    out = {
        "texture": texture.name,
        "nominal_pressure_kpa": args.nominal_pressure_kpa,
        "effective_modulus_mpa": e_eff / 1e6,
        "real_contact_area_fraction": res.real_contact_area_fraction,
        "mean_gap_um": res.mean_gap_m * 1e6,
        "mean_reciprocal_gap_per_m": res.mean_reciprocal_gap_per_m,
        "mean_reciprocal_gap_raw_per_m": res.mean_reciprocal_gap_raw_per_m,
        "gap_floor_nm": res.gap_floor_m * 1e9,
        "full_contact": res.full_contact,
        "converged": res.converged,
        "iterations": res.iterations,
        "residual": res.residual,
        "message": res.message,
        "solve_time_s": res.solve_time_s,
        "grid": list(texture.heights_m.shape),
        "detrend": texture.detrend,
        "periodic": periodic,
        "solved_grid": list(heights_m.shape),
        "pixel_size_um": texture.pixel_size_m * 1e6,
    }
    if args.json:
        print(json.dumps(out))
    else:
        print(
            f"texture                      {texture.name}  {out['grid'][0]}x{out['grid'][1]} "
            f"px, {out['pixel_size_um']:.3g} µm/px; detrend {texture.detrend}; "
            f"periodisation {periodic} "
            f"(solved on {heights_m.shape[0]}x{heights_m.shape[1]})"
        )
        print(
            f"nominal pressure             {args.nominal_pressure_kpa:.6g} kPa "
            f"(E' = {out['effective_modulus_mpa']:.4g} MPa)"
        )
        print(f"real contact area fraction   {res.real_contact_area_fraction:.6g}")
        print(f"mean gap                     {out['mean_gap_um']:.6g} µm")
        print(
            f"mean reciprocal gap          {res.mean_reciprocal_gap_per_m:.6g} 1/m "
            f"(floor {out['gap_floor_nm']:.3g} nm; raw {res.mean_reciprocal_gap_raw_per_m:.6g} 1/m)"
        )
        print(f"solver                       {res.message}; {res.solve_time_s:.3f} s")
    return 0 if res.converged else 1
