"""``skisnow serve`` and ``skisnow solve``: the service, and one case on the command line."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from skisnow.app.presets import DEFAULT_PRESET, PRESETS
from skisnow.app.storage.common import check_data_dir


def register(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("serve", help="run the REST API and the technician web form")
    s.add_argument("--host", default=None, help="interface (default 127.0.0.1)")
    s.add_argument("--port", type=int, default=None, help="TCP port (default 8000)")
    s.add_argument("--workers", type=int, default=None, help="worker processes (default 1)")
    s.add_argument("--tables-dir", default=None, help="tables and skis directory")
    s.set_defaults(func=run_serve)

    v = sub.add_parser("solve", help="one ski × grind case (the same answer as /v1/contact)")
    v.add_argument("--ski", required=True)
    v.add_argument("--grind", required=True)
    v.add_argument("--load-kg", type=float, required=True, help="equivalent load [kg]")
    v.add_argument(
        "--load-position-mm",
        type=float,
        required=True,
        help="load position from the balance point, + towards the tip [mm]",
    )
    v.add_argument("--snow-modulus-mpa", type=float, required=True, help="snow modulus [MPa]")
    v.add_argument("--porosity", type=float, required=True, help="snow porosity n [-]")
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


def open_writes_warning(host: str, team_tokens: dict) -> str | None:
    """The start-up warning when anyone who reaches the port may upload, rename, delete and
    queue jobs: no team tokens, on an address other than loopback."""
    import ipaddress

    if team_tokens:
        return None
    try:
        loopback = ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = host == "localhost"
    if loopback:
        return None
    return (
        f"listening on {host} with no team tokens (SKISNOW_TEAM_TOKENS): anyone who reaches "
        "this port can upload, rename and delete skis and grinds and queue table builds; set "
        "team tokens or bind to 127.0.0.1 behind an authenticating proxy"
    )


def run_serve(args: argparse.Namespace) -> int:
    from skisnow.app.settings import Settings

    # BLAS/OpenMP thread count per worker (worker processes inherit it). NUMBA_NUM_THREADS
    # is not touched here: numba is already imported and refuses a change after import.
    os.environ.setdefault("OMP_NUM_THREADS", str(Settings().threads_per_worker))
    import uvicorn

    overrides = {
        k: v
        for k, v in {
            "host": args.host,
            "port": args.port,
            "workers": args.workers,
            "tables_dir": args.tables_dir,
        }.items()
        if v is not None
    }
    settings = Settings(**overrides)
    # fail fast, before binding, with a message naming a missing or corrupt file
    from skisnow.app.service import load_catalogue

    load_catalogue(settings.tables_dir)
    check_data_dir(Path(settings.data_dir))
    # the catalogue's schema is created or upgraded here (Alembic, app.storage.schema), once,
    # before the workers start; they find it at the head revision
    from skisnow.app.storage.catalogue import CatalogueDB

    CatalogueDB(settings.catalogue_url).close()
    for key, value in overrides.items():
        os.environ[f"SKISNOW_{key.upper()}"] = str(value)
    warning = open_writes_warning(settings.host, settings.team_tokens)
    if warning:
        print(f"skisnow serve: WARNING: {warning}", file=sys.stderr)
    if settings.workers == 1:
        # uvicorn exits with its STARTUP_FAILURE code (3) itself when the one worker fails
        uvicorn.run(
            "skisnow.app.main:app", host=settings.host, port=settings.port, log_level="info"
        )
        return 0
    return _run_workers(settings.host, settings.port, settings.workers)


def _run_workers(host: str, port: int, workers: int) -> int:
    """Run ``workers`` uvicorn worker processes under uvicorn's supervisor (what
    ``uvicorn.run(..., workers=n)`` does) and return 3 when a worker failed to start.

    The supervisor restarts a worker that dies while serving, but when one fails before it
    serves (a broken catalogue, database or port) it stops every worker and returns normally:
    through ``uvicorn.run`` the command then exited 0, and ``docker run --restart on-failure``
    or a process manager took the failure for a clean stop (issue #15)."""
    from uvicorn import Config
    from uvicorn.config import STARTUP_FAILURE
    from uvicorn.supervisors import Multiprocess

    config = Config("skisnow.app.main:app", host=host, port=port, workers=workers, log_level="info")
    supervisor = Multiprocess(config, sockets=[config.bind_socket()])
    try:
        supervisor.run()
    except KeyboardInterrupt:
        pass
    failed = [p.pid for p in supervisor.processes if p.exitcode == STARTUP_FAILURE]
    if failed:
        print(
            f"skisnow serve: worker process {failed[0]} failed to start (its log is above); "
            f"the service stopped with exit code {STARTUP_FAILURE}",
            file=sys.stderr,
        )
        return STARTUP_FAILURE
    return 0


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
            snow_modulus_mpa=args.snow_modulus_mpa,
            porosity=args.porosity,
            base_modulus_mpa=args.base_modulus_mpa,
            poisson_ratio=args.poisson,
            preset=args.preset,
            ski_model=args.ski_model,
        )
    except ValidationError as exc:
        msgs = "; ".join(
            f"--{'-'.join(str(x) for x in e['loc']).replace('_', '-')}: {e['msg']}"
            for e in exc.errors()
        )
        raise InputError(msgs) from None
    settings = Settings(**({"tables_dir": args.tables_dir} if args.tables_dir else {}))
    cat = service.load_catalogue(settings.tables_dir)
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
        f"E_snow {args.snow_modulus_mpa:g} MPa, porosity {args.porosity:g}"
    )
    rel = out.get("band", {}).get("relative_half_width", {})

    def pm(q: str) -> str:
        w = rel.get(q)
        return "  (no band: not grid-converged)" if w is None else f"  ± {100 * w:4.1f} %"

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
        print(f"  {label:32s} {value:10.4g} {unit}{pm(q)}")
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
