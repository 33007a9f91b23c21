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
    s.add_argument(
        "--workers",
        type=int,
        default=None,
        help="worker processes (default: one per usable core, capped by memory)",
    )
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
    from skisnow.app.settings import default_workers

    workers = settings.workers or default_workers()
    print(
        f"skisnow serve: {workers} worker process{'es' if workers > 1 else ''}"
        + ("" if settings.workers else " (one per usable core, capped by memory; SKISNOW_WORKERS)"),
        file=sys.stderr,
        flush=True,
    )
    if workers == 1:
        # uvicorn exits with its STARTUP_FAILURE code (3) itself when the one worker fails
        uvicorn.run(
            "skisnow.app.main:app", host=settings.host, port=settings.port, log_level="info"
        )
        return 0
    return _run_workers(settings.host, settings.port, workers)


def _run_workers(host: str, port: int, workers: int) -> int:
    """Run ``workers`` uvicorn worker processes under uvicorn's supervisor (what
    ``uvicorn.run(..., workers=n)`` does) and return 3 when a worker failed to start.

    The supervisor restarts a worker that dies while serving. One that fails before it serves
    stops the service with exit code 3 (a process manager or ``docker run --restart
    on-failure`` then sees the failure): uvicorn's own supervisor did that only for a worker
    that exits with code 3 itself (an error in the app's lifespan) and returned normally, so
    ``uvicorn.run`` exited 0; a worker that died any other way before serving (an import
    error: code 1; killed) was restarted without end (issue #15, #27)."""
    from uvicorn import Config
    from uvicorn.config import STARTUP_FAILURE

    config = Config("skisnow.app.main:app", host=host, port=port, workers=workers, log_level="info")
    supervisor = _supervisor_class()(config, sockets=[config.bind_socket()])
    try:
        supervisor.run()
    except KeyboardInterrupt:
        pass
    failed = supervisor.failed_at_start or [
        p.pid for p in supervisor.processes if p.exitcode == STARTUP_FAILURE
    ]
    if failed:
        print(
            f"skisnow serve: worker process {failed[0]} failed to start (its log is above); "
            f"the service stopped with exit code {STARTUP_FAILURE}",
            file=sys.stderr,
        )
        return STARTUP_FAILURE
    return 0


def _supervisor_class():
    from uvicorn.supervisors import Multiprocess

    class Supervisor(Multiprocess):
        """uvicorn's supervisor that stops, and records the worker, when one dies before it
        has served (its health check never answered "started"), whatever its exit code."""

        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            self.served: set[int] = set()
            self.failed_at_start: list[int] = []

        def keep_subprocess_alive(self) -> None:
            if self.should_exit.is_set():
                return
            for process in self.processes:
                if process.pid in self.served:
                    continue
                if process.process.is_alive():
                    if process.is_ready(timeout=1):
                        self.served.add(process.pid)
                    continue
                process.join()
                self.failed_at_start.append(process.pid)
                self.should_exit.set()
                return
            super().keep_subprocess_alive()

    return Supervisor
