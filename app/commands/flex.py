"""``skisnow flex``: the technician's flex sheet of a stored ski (issue #14; docs/flex.md).

The same numbers as ``GET /v1/skis/{name}/flex`` (:func:`app.service.flex.flex_sheet_answer`), read
from ``tables/skis/NAME.h5`` (no texture tables needed).
"""

from __future__ import annotations

import argparse
import json

from skisnow.app import bounds, service
from skisnow.app.service import flex
from skisnow.app.snow import SNOW_PRESETS, resolve_snow
from skisnow.app.storage.common import sha256_file, tables_dir
from skisnow.app.storage.skis import read_ski
from skisnow.solvers.errors import InputError

__all__ = ["register", "run"]


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``flex`` subcommand."""
    p = subparsers.add_parser(
        "flex",
        help="flex sheet of a ski: wax pocket, closing load, kick-zone load, wheelbase",
        description="Wax pocket at 0.10/0.15/0.20/0.30 mm under half and full body weight "
        "(8 cm behind the balance point), closing load, kick-zone load share on the flat (and "
        "on snow with --snow-modulus-mpa), wheelbase and glide check, each with its 90 %% band "
        "from the camber model (docs/flex.md).",
    )
    p.add_argument("--ski", metavar="NAME", required=True, help="stored ski (tables/skis/NAME.h5)")
    p.add_argument("--body-weight-kg", type=float, required=True, help="skier's weight [kg]")
    p.add_argument(
        "--snow",
        choices=list(SNOW_PRESETS),
        help="snow by type and temperature (app/snow.py): kick share on snow with its modulus",
    )
    p.add_argument("--snow-modulus-mpa", type=float, help="E_snow [MPa]: kick share on snow")
    p.add_argument("--base-modulus-mpa", type=float, default=700.0, help="E_base [MPa]")
    p.add_argument("--poisson", type=float, default=0.3, help="Poisson's ratio [-]")
    p.add_argument("--preset", default="default", help="macro grid of the snow share")
    out = p.add_mutually_exclusive_group()
    out.add_argument("--json", action="store_true", help="the JSON answer of the API")
    out.add_argument("--csv", action="store_true", help="quantity,value,band rows")
    p.set_defaults(func=run)


def _catalogue(name: str) -> service.Catalogue:
    ski_dir = tables_dir() / "skis"
    path = ski_dir / f"{name}.h5"
    cat = service.Catalogue(tables_dir=tables_dir())
    if path.is_file():
        cat.skis[name] = service.Ski(name, path, sha256_file(path), read_ski(path))
    else:
        known = sorted(p.stem for p in ski_dir.glob("*.h5"))
        raise flex.field_error(
            InputError, "ski", f"unknown ski {name!r}; known: {', '.join(known)}"
        )
    return cat


def _fmt(v, unit: str = "", band=None, digits: int = 1) -> str:
    if v is None:
        return "—"
    text = f"{v:.{digits}f}" if isinstance(v, float) else str(v)
    if band:
        text += f" ± {band:.2g}"
    return text + (f" {unit}" if unit else "")


def run(args: argparse.Namespace) -> int:
    """Execute ``skisnow flex``; exit 0."""
    # the bounds of GET /v1/skis/{name}/flex (app.bounds)
    for bound, flag, value in (
        (bounds.BODY_WEIGHT_KG, "--body-weight-kg", args.body_weight_kg),
        (bounds.SNOW_MODULUS_MPA, "--snow-modulus-mpa", args.snow_modulus_mpa),
        (bounds.BASE_MODULUS_MPA, "--base-modulus-mpa", args.base_modulus_mpa),
        (bounds.POISSON_RATIO, "--poisson", args.poisson),
    ):
        if value is not None and not bound.contains(value):
            raise flex.field_error(
                InputError, bound.name, f"{flag} must be in {bound.text()}, got {value:g}"
            )
    cat = _catalogue(args.ski)
    e, n = resolve_snow(args.snow, args.snow_modulus_mpa, None)
    req = flex.FlexRequest(
        args.ski,
        args.body_weight_kg,
        e,
        n,
        args.base_modulus_mpa,
        args.poisson,
        args.preset,
        args.snow,
    )
    ans = flex.flex_sheet_answer(cat, req, profiles=args.json)
    if args.json:
        print(json.dumps(ans))
        return 0
    if args.csv:
        print(flex.sheet_csv(ans), end="")
        return 0
    w = ans["inputs"]["body_weight_kg"]
    print(f"flex sheet of {args.ski} for {w:g} kg (foot 80 mm behind the balance point)")
    print(f"verdict           {ans['verdict']['text']}")
    ph = ans["pocket_height"]
    print(
        f"pocket height     half {_fmt(ph['half_weight']['largest_gap_mm'], 'mm', digits=2)}, "
        f"full {_fmt(ph['full_weight']['largest_gap_mm'], 'mm', digits=2)} (largest gap "
        f"{ph['span']}); under the foot half "
        f"{_fmt(ph['half_weight']['foot_gap_mm'], 'mm', digits=2)}, full "
        f"{_fmt(ph['full_weight']['foot_gap_mm'], 'mm', digits=2)}"
    )
    print("wax pocket        half weight                    full weight")
    for p in ans["pockets"]:
        h, f = p["half_weight"], p["full_weight"]
        print(
            f"  ≥ {p['gap_mm']:.2f} mm  {_fmt(h['length_mm'], 'mm', h['length_band_mm']):>18} "
            f"[{_fmt(h['start_mm'])}, {_fmt(h['end_mm'])}]   "
            f"{_fmt(f['length_mm'], 'mm', f['length_band_mm']):>18} "
            f"[{_fmt(f['start_mm'])}, {_fmt(f['end_mm'])}]"
        )
    c = ans["closing_load"]
    if c["closed_at_min_load"]:
        closing = f"≤ {c['min_load_kg']:g} kg (closed at the lightest load the camber model covers)"
    elif not c["closes_below_max"]:
        closing = f"does not close up to {c['max_load_kg']:g} kg"
    else:
        closing = _fmt(c["load_kg"], "kg", c["band_kg"])
    print(f"closing load      {closing}")
    k = ans["kick_zone"]
    fl = k["flat"]
    print(
        f"kick-zone load    flat: half {_fmt(fl['half_weight_percent'], '%')}, "
        f"full {_fmt(fl['full_weight_percent'], '%', fl['full_weight_band_percent'])}"
    )
    s = k["snow"]
    if s and s.get("available"):
        print(
            f"                  snow {s['snow_modulus_mpa']:g} MPa: half "
            f"{_fmt(s['half_weight_percent'], '%', s['half_weight_band_percent'])}, full "
            f"{_fmt(s['full_weight_percent'], '%', s['full_weight_band_percent'])} "
            "(shops aim for 33–50 % at full weight)"
        )
    wb = ans["wheelbase"]
    print(f"wheelbase         {_fmt(wb['wheelbase_mm'], 'mm', wb['band_mm'])}")
    g = ans["glide_check"]
    print(
        f"glide check       {'passed' if g['passed'] else 'failed'} (min gap "
        f"{_fmt(g['min_gap_mm'], 'mm', digits=3)} ahead of the foot at full weight, 150 mm behind)"
    )
    print(f"band              {ans['band']['source']}")
    return 0
