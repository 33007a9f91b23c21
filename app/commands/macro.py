"""``skisnow macro``: apparent contact of one ski on snow (docs/physics.md §4).

Technician units (kg, mm, MPa) are converted to SI in :func:`_si_inputs` only.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from skisnow.app import bounds, service
from skisnow.app.service.profiles import profile_model
from skisnow.app.storage.skis import SHIPPED_SKI_DIR, read_camber_csv, read_ski
from skisnow.solvers.beam import G_STANDARD
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.errors import DataFileError, InputError, OutOfRangeError
from skisnow.solvers.macro import (
    GapMap,
    MacroResult,
    extrude_profile,
    interpolate_sides,
    solve_macro,
)

__all__ = ["loaded_profile", "register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``macro`` subcommand."""
    p = subparsers.add_parser(
        "macro",
        help="apparent contact of a ski on snow (macro-scale BEM)",
        description="Press the loaded ski profile into the snow half-space and report the "
        "apparent contact area, mean apparent pressure and contact zones.",
    )
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--ski", metavar="NAME", help="demo or stored ski (tables/skis/NAME.h5)")
    src.add_argument("--profile", metavar="CSV", help="neutral camber CSV with one load case")
    src.add_argument("--gap-map", metavar="NPY", help="gap map [mm], axis 0 along the ski")
    p.add_argument("--width-mm", type=float, help="ski width for --profile [mm]")
    p.add_argument("--pixel-size-mm", type=float, help="pixel size of --gap-map [mm]")
    p.add_argument("--load-kg", type=float, required=True, help="equivalent load [kg]")
    p.add_argument(
        "--load-position-mm",
        type=float,
        required=True,
        help="load position from the balance point, + towards the tip [mm]",
    )
    p.add_argument("--snow-modulus-mpa", type=float, required=True, help="E_snow [MPa]")
    p.add_argument("--base-modulus-mpa", type=float, default=700.0, help="E_base [MPa]")
    p.add_argument("--poisson", type=float, default=0.3, help="Poisson's ratio [-]")
    p.add_argument("--no-tilt", action="store_true", help="no tilt: force balance only")
    p.add_argument(
        "--ski-model",
        choices=["rigid", "flexible", "auto"],
        default="auto",
        help="with --ski: rigid (device shape), flexible (the ski bends on the snow), auto "
        "(default: flexible where it differs from rigid by more than 2 %% in apparent area or "
        "rear load share); --profile and --gap-map have no beam and stay rigid",
    )
    p.add_argument("--json", action="store_true", help="one JSON object with distributions")
    p.set_defaults(func=run)


def _si_inputs(args: argparse.Namespace) -> dict:
    """The one place where technician units become SI."""
    # the service's bounds (app.bounds): the CLI asks for nothing the API refuses
    for bound, value in (
        (bounds.LOAD_KG, args.load_kg),
        (bounds.LOAD_POSITION_MM, args.load_position_mm),
        (bounds.SNOW_MODULUS_MPA, args.snow_modulus_mpa),
        (bounds.BASE_MODULUS_MPA, args.base_modulus_mpa),
        (bounds.POISSON_RATIO, args.poisson),
    ):
        if not bound.contains(value):
            flag = "--poisson" if bound is bounds.POISSON_RATIO else f"--{bound.name}"
            raise InputError(f"{flag.replace('_', '-')} must be in {bound.text()}, got {value:g}")
    out = {
        "load_n": args.load_kg * G_STANDARD,
        "load_position_m": args.load_position_mm * 1e-3,
        "effective_modulus_pa": effective_modulus(
            args.snow_modulus_mpa * 1e6, args.base_modulus_mpa * 1e6, args.poisson
        ),
    }
    if args.width_mm is not None:
        if not np.isfinite(args.width_mm) or args.width_mm <= 0:
            raise InputError(f"--width-mm must be > 0, got {args.width_mm}")
        out["width_m"] = args.width_mm * 1e-3
    if args.pixel_size_mm is not None:
        if not np.isfinite(args.pixel_size_mm) or args.pixel_size_mm <= 0:
            raise InputError(f"--pixel-size-mm must be > 0, got {args.pixel_size_mm}")
        out["pixel_size_m"] = args.pixel_size_mm * 1e-3
    return out


def loaded_profile(ski, load_n: float, load_position_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Loaded camber H*(X) of a stored ski record from its profile model
    (:mod:`app.service.profiles`: identified beam, else camber network, else design beam).

    Returns
    -------
    positions_m, gap_m : ndarray
    """
    return profile_model(ski)(load_n, load_position_m)


def _flexible_choice(args: argparse.Namespace, si: dict, rigid):
    """The flexible solve of a stored ski with a beam, and which model answers (the service's
    rule and beam sources; without a grind, auto compares apparent area and rear load share)."""
    from skisnow.solvers.flexible import prepare_flexible, solve_flexible

    record = read_ski(_ski_path(args.ski))
    beam, why = service.Ski(record.ski_id, _ski_path(args.ski), "", record).beam()
    if beam is None:
        if args.ski_model == "flexible":
            raise InputError(why)
        return rigid, f"rigid ({why})"
    model = prepare_flexible(
        beam, record.outline.width_m, width_positions_m=record.outline.positions_m
    )
    flex = solve_flexible(
        model,
        si["load_n"],
        si["load_position_m"],
        si["effective_modulus_pa"],
        initial_pressure_pa=rigid.pressure_pa,
    )
    if args.ski_model == "flexible":
        return flex, "flexible"
    if not flex.converged:
        return rigid, f"rigid (the flexible solve did not converge: {flex.message})"
    use_flexible, reason = service.auto_uses_flexible(service.rigid_minus_flexible(rigid, flex))
    return (flex, f"flexible ({reason})") if use_flexible else (rigid, f"rigid ({reason})")


def _check_covered(args: argparse.Namespace, ski) -> None:
    """Refuse, in the user's units (kg, mm), a load or position outside the range the ski's
    profile model covers (the service's rule, :attr:`app.service.Ski.load_range_n`)."""
    covered = service.Ski(ski.ski_id, Path(), "", ski)
    lo, hi = covered.load_range_n
    if not (lo * (1 - 1e-9) <= args.load_kg * G_STANDARD <= hi * (1 + 1e-9)):
        raise OutOfRangeError(
            f"--load-kg {args.load_kg:g} is outside the range the ski {ski.ski_id!r} covers "
            f"({lo / G_STANDARD:.4g} … {hi / G_STANDARD:.4g} kg): its camber model is not "
            "extrapolated"
        )
    lo, hi = covered.position_range_m
    if not (lo - 1e-12 <= args.load_position_mm * 1e-3 <= hi + 1e-12):
        raise OutOfRangeError(
            f"--load-position-mm {args.load_position_mm:g} is outside the range the ski "
            f"{ski.ski_id!r} covers ({lo * 1e3:g} … {hi * 1e3:g} mm)"
        )


def _ski_path(name: str) -> Path:
    path = Path(name)
    return path if path.suffix else SHIPPED_SKI_DIR / f"{name}.h5"


def _gap_map(args: argparse.Namespace, si: dict) -> GapMap:
    if args.ski:
        ski = read_ski(_ski_path(args.ski))
        _check_covered(args, ski)
        x, gap = loaded_profile(ski, si["load_n"], si["load_position_m"])
        return extrude_profile(
            x, gap, ski.outline.width_m, width_positions_m=ski.outline.positions_m
        )
    if args.profile:
        if "width_m" not in si:
            raise InputError("--profile needs --width-mm")
        data = read_camber_csv(args.profile)
        by_side = dict(zip(data.sides, data.profiles_m, strict=False))
        if len({(f, p) for f, p in zip(data.loads_n, data.load_positions_m, strict=True)}) != 1:
            raise InputError(
                f"--profile must hold one load case (a loaded profile), got {len(data.sides)} cases"
            )
        if "left" in by_side and "right" in by_side:
            return interpolate_sides(
                data.positions_m, by_side["left"], by_side["right"], si["width_m"]
            )
        prof = by_side.get("mean", next(iter(by_side.values())))
        return extrude_profile(data.positions_m, prof, si["width_m"])
    if "pixel_size_m" not in si:
        raise InputError("--gap-map needs --pixel-size-mm")
    try:
        arr = np.load(args.gap_map, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise DataFileError(f"cannot read gap map {args.gap_map}: {exc}") from exc
    if arr.ndim != 2:
        raise InputError(f"gap map must be 2-D, got shape {arr.shape}")
    d = si["pixel_size_m"]
    x = (np.arange(arr.shape[0]) - (arr.shape[0] - 1) / 2) * d
    return GapMap(np.asarray(arr, float) * 1e-3, x, (d, d))


def _report(res: MacroResult, with_distributions: bool) -> dict:
    out = {
        "apparent_contact_area_cm2": res.apparent_contact_area_m2 * 1e4,
        "mean_apparent_pressure_kpa": res.mean_apparent_pressure_pa * 1e-3,
        "zones": [
            {
                "start_mm": z.start_m * 1e3,
                "end_mm": z.end_m * 1e3,
                "length_mm": z.length_m * 1e3,
                "load_share": z.load_share,
            }
            for z in res.zones
        ],
        "approach_um": res.approach_m * 1e6,
        "tilt_mrad": res.tilt_rad * 1e3,
        "converged": res.converged,
        "iterations": res.iterations,
        "solve_time_s": res.solve_time_s,
        "message": res.message,
    }
    if with_distributions:
        out["position_mm"] = (res.positions_m * 1e3).tolist()
        out["pressure_kpa"] = (res.pressure_line_pa * 1e-3).tolist()
        out["clearance_um"] = [None if not np.isfinite(v) else v * 1e6 for v in res.clearance_m]
    return out


def run(args: argparse.Namespace) -> int:
    """Execute ``skisnow macro``; returns the exit code (1 if the solve did not converge)."""
    si = _si_inputs(args)
    gm = _gap_map(args, si)
    res = solve_macro(
        gm, si["load_n"], si["load_position_m"], si["effective_modulus_pa"], tilt=not args.no_tilt
    )
    used = "rigid"
    if args.ski and args.ski_model != "rigid":
        res, used = _flexible_choice(args, si, res)
    elif args.ski_model == "flexible":
        raise InputError("--ski-model flexible needs --ski (a profile or gap map has no beam)")
    rep = _report(res, args.json)
    rep["ski_model"] = used
    if args.json:
        print(json.dumps(rep))
    else:
        print(f"apparent_contact_area_cm2  {rep['apparent_contact_area_cm2']:.2f}")
        print(f"mean_apparent_pressure_kpa {rep['mean_apparent_pressure_kpa']:.2f}")
        print("zones")
        for z in rep["zones"]:
            print(
                f"  start_mm {z['start_mm']:8.1f}  end_mm {z['end_mm']:8.1f}  "
                f"length_mm {z['length_mm']:6.1f}  load_share {z['load_share']:.3f}"
            )
        print(f"ski_model                  {used}")
        print(f"converged                  {rep['converged']}")
        print(f"iterations                 {rep['iterations']}")
        print(f"solve_time_s               {rep['solve_time_s']:.4f}")
    return 0 if res.converged else 1
