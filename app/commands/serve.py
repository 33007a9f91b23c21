"""``skisnow serve``: the REST API and the technician web form (uvicorn workers)."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from skisnow.app.storage.common import check_data_dir


def register(sub: argparse._SubParsersAction) -> None:
    s = sub.add_parser("serve", help="run the REST API and the technician web form")
    s.add_argument("--host", default=None, help="interface (default 127.0.0.1)")
    s.add_argument("--port", type=int, default=None, help="TCP port (default 8000)")
    s.add_argument("--workers", type=int, default=None, help="worker processes (default 1)")
    s.add_argument("--tables-dir", default=None, help="tables and skis directory")
    s.set_defaults(func=run_serve)


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
    print(
        f"skisnow serve: checking the tables in {settings.tables_dir} and the data folder "
        f"{settings.data_dir}; then each worker loads them and warms up (the first start "
        "compiles the kernels: up to ~30 s)",
        file=sys.stderr,
        flush=True,
    )
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
