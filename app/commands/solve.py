"""``skisnow solve``: one ski × grind case on the command line, the same answer as
``POST /v1/contact`` (the same request model and bounds, the same service call)."""

from __future__ import annotations

import argparse
import json
import sys

from skisnow.app.presets import DEFAULT_PRESET, PRESETS
from skisnow.app.snow import DEFAULT_SNOW, SNOW_PRESETS


def register(sub: argparse._SubParsersAction) -> None:
    v = sub.add_parser("solve", help="one ski × grind case (the same answer as /v1/contact)")
    v.add_argument(
        "--ski", required=True, help="a shipped ski, or one uploaded to the service (--data-dir)"
    )
    v.add_argument(
        "--grind",
        required=True,
        help="a shipped grind, or one uploaded to the service (--data-dir)",
    )
    v.add_argument("--load-kg", type=float, required=True, help="equivalent load [kg]")
    v.add_argument(
        "--load-position-mm",
        type=float,
        required=True,
        help="load position from the balance point, + towards the tip [mm]",
    )
    v.add_argument(
        "--snow",
        choices=list(SNOW_PRESETS),
        default=None,
        help="snow by type and temperature (app/snow.py): fills --snow-modulus-mpa and "
        f"--porosity where not given; the web form's default is {DEFAULT_SNOW}",
    )
    v.add_argument(
        "--snow-modulus-mpa", type=float, default=None, help="snow modulus [MPa] (or --snow)"
    )
    v.add_argument("--porosity", type=float, default=None, help="snow porosity n [-] (or --snow)")
    v.add_argument("--base-modulus-mpa", type=float, default=700.0)
    v.add_argument("--poisson", type=float, default=0.3)
    v.add_argument("--tables-dir", default=None)
    v.add_argument(
        "--preset",
        default=DEFAULT_PRESET,
        choices=list(PRESETS),
        help="accuracy preset (macro grid; docs/benchmarks.md)",
    )
    v.add_argument(
        "--ski-model",
        default="auto",
        choices=["rigid", "flexible", "auto"],
        help="rigid: the device's loaded shape (the papers' model); flexible: the ski bends on "
        "the snow; auto (default): rigid where within 2 %% of flexible",
    )
    v.add_argument("--json", action="store_true", help="print the full JSON answer")
    v.set_defaults(func=run_solve)


def run_solve(args: argparse.Namespace) -> int:
    from pydantic import ValidationError
    from skisnow.app import service
    from skisnow.app.api.models import ContactBody
    from skisnow.app.settings import Settings
    from skisnow.solvers.errors import InputError

    try:
        body = ContactBody(
            ski=args.ski,
            grind=args.grind,
            load_kg=args.load_kg,
            load_position_mm=args.load_position_mm,
            base_modulus_mpa=args.base_modulus_mpa,
            poisson_ratio=args.poisson,
            preset=args.preset,
            ski_model=args.ski_model,
            **{
                k: v
                for k, v in (
                    ("snow", args.snow),
                    ("snow_modulus_mpa", args.snow_modulus_mpa),
                    ("porosity", args.porosity),
                )
                if v is not None
            },
        )
    except ValidationError as exc:
        from skisnow.app.bounds import out_of_bounds_message

        def reason(e: dict) -> str:
            if e["type"] in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
                return out_of_bounds_message(str(e["loc"][0]), float(e["input"]))
            return e["msg"]

        msgs = "; ".join(
            f"--{'-'.join(str(x) for x in e['loc']).replace('_', '-')}: {reason(e)}"
            for e in exc.errors()
        )
        raise InputError(msgs) from None
    settings = Settings(**({"tables_dir": args.tables_dir} if args.tables_dir else {}))
    cat = service.load_catalogue(settings.tables_dir)
    from skisnow.app.service.live import add_uploads

    for note in add_uploads(cat, settings):  # the service's uploads (--data-dir)
        print(f"skisnow solve: {note}", file=sys.stderr)
    try:
        out = service.contact(cat, service.ContactInputs(**body.model_dump()))
    except service.UnknownItemError as exc:
        raise InputError(str(exc)) from None
    if args.json:
        print(json.dumps(out))
        return 0
    m, a = out["metrics"], out["apparent"]
    print(
        f"{args.ski} × {args.grind}: {args.load_kg:g} kg at {args.load_position_mm:g} mm, "
        f"E_snow {body.snow_modulus_mpa:g} MPa, porosity {body.porosity:g}"
        + (f" (snow {args.snow})" if args.snow else "")
    )
    rel = out.get("band", {}).get("relative_half_width", {})
    rel_above = out.get("band", {}).get("relative_half_width_above") or {}

    def pm(q: str, mirrored: bool = False) -> str:
        # value × (1 − w) … value ÷ (1 − w_above) (w_above = w unless the band names it); a
        # mirrored quantity (the mean apparent pressure, F / A) swaps the apparent area's sides
        w, wa = rel.get(q), rel_above.get(q, rel.get(q))
        if w is None:
            return "  (not grid-converged: see below)"
        if mirrored:
            w, wa = wa, w
        lo = "100" if w >= 1 else f"{100 * w:.1f}"
        if wa >= 1:
            return f"  −{lo} % / no upper bound"
        hi = f"{100 * wa / (1 - wa):.1f}"
        return f"  ± {lo:>4} %" if lo == hi else f"  −{lo} % / +{hi} %"

    print("  90 % error band after each value (sources: --json, band)")
    rows = (
        (
            "total real contact area",
            m["total_real_contact_area_mm2"],
            "mm² ",
            "total_real_contact_area",
        ),
        (
            "average real contact pressure",
            m["average_real_contact_pressure_mpa"],
            "MPa ",
            "average_real_contact_pressure",
        ),
        (
            "min. average separation",
            m["min_average_separation_um"],
            "µm  ",
            "min_average_separation",
        ),
        (
            "total reciprocal separation",
            m["total_reciprocal_separation_m"],
            "m   ",
            "total_reciprocal_separation",
        ),
        ("apparent contact area", a["contact_area_cm2"], "cm² ", "apparent_contact_area"),
        ("mean apparent pressure", a["mean_pressure_kpa"], "kPa ", "apparent_contact_area"),
    )
    for label, value, unit, q in rows:
        print(f"  {label:32s} {value:10.4g} {unit}{pm(q, label == 'mean apparent pressure')}")
        if q == "min_average_separation" and rel.get(q) is None:
            sep = service.resolved_min_separation(a["zones"])
            over = (
                f"{sep['value_um']:.4g} µm ({sep['zone']} zone)"
                if sep["value_um"] is not None
                else "no zone is resolved"
            )
            print(f"    over the resolved zones: {over}")
            for u in sep["unresolved"]:
                print(f"    not resolved: {u['zone']} zone ({u['reason']})")
    tail = out.get("band", {}).get("studied_tail")
    if tail:
        lo, hi = tail["contact_area_cm2_at_farthest"]
        print(
            f"    studied tail: {100 * tail['outside_share']:.1f} % of {tail['answers']} answers "
            "like this one lay outside their band,\n"
            f"    the farthest {tail['farthest_over_half_width']:g} × its half-width away "
            f"(apparent contact area {lo:.4g} … "
            + ("no upper bound" if hi is None else f"{hi:.4g} cm²")
            + " that far)"
        )
    for z in a["zones"]:
        print(
            f"  zone {z['name']:5s} {z['start_mm']:7.0f} … {z['end_mm']:5.0f} mm  "
            f"load share {z['load_share']:.1%}  real area {z['real_area_mm2']:.4g} mm²"
            + (
                f"  load {z['load_band_90_n'][0]:.4g} … {z['load_band_90_n'][1]:.4g} N (90 %)"
                if z.get("load_band_90_n") and z["load_band_90_n"][0] is not None
                else ""
            )
        )
    sm = out["provenance"]["ski_model"]
    print(f"  ski model        {sm['used']} ({sm['reason']})")
    for w in out["warnings"]:
        print(f"  WARNING {w['code']}: {w['detail']}")
    print(f"  time {out['timing_ms']['total']:.0f} ms (preset {args.preset})")
    return 0
