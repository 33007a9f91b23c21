"""``skisnow worker``: run the catalogue's jobs (grind tables, ski networks) in a process of
their own, beside any number of ``skisnow serve`` processes on the same database.

The service runs jobs in-process by default (``job_workers`` = 1). A deployment that keeps the
CPU-heavy builds away from the processes answering requests sets ``SKISNOW_JOB_WORKERS=0`` for
``skisnow serve`` (its processes then claim no job and only poll for finished items) and starts
one or more workers with the same ``SKISNOW_DATA_DIR`` / ``SKISNOW_DATABASE_URL``:

    SKISNOW_JOB_WORKERS=0 skisnow serve --workers 2 &
    skisnow worker --jobs 1

A worker claims queued jobs (and running ones whose process stopped beating, see
:mod:`app.jobs.runner`) in two lanes of ``--jobs`` slots each, short (grind tables) and long
(ski networks), so a grind never waits behind a ski; it runs them and writes the finished items
into the data directory and the database; SIGTERM or Ctrl-C puts its running jobs back in the
queue (a grind table resumes from its checkpoints in the next process) and exits 0.
"""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
from pathlib import Path

log = logging.getLogger(__name__)


def register(sub: argparse._SubParsersAction) -> None:
    w = sub.add_parser(
        "worker",
        help="run the catalogue's jobs (uploads' tables and networks) apart from the service",
    )
    w.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="jobs run at once in each lane, short (grind tables) and long (ski networks) "
        "(default SKISNOW_JOB_WORKERS, at least 1)",
    )
    w.add_argument(
        "--poll-s", type=float, default=None, help="poll interval [s] (default SKISNOW_JOB_POLL_S)"
    )
    w.set_defaults(func=run)


def run_worker(settings, stop: threading.Event, *, jobs: int) -> None:
    """Run jobs of the catalogue in ``settings`` until ``stop`` is set (then requeue the
    running ones and return)."""
    from skisnow.app.jobs.handlers import job_handlers
    from skisnow.app.jobs.runner import JobRunner
    from skisnow.app.storage.catalogue import CatalogueDB
    from skisnow.app.storage.layout import Layout

    layout = Layout(Path(settings.data_dir))
    db = CatalogueDB(settings.catalogue_url)
    try:
        handlers, on_failure = job_handlers(settings, layout, on_ready=lambda item: None)
        runner = JobRunner(
            db,
            handlers,
            on_failure=on_failure,
            workers=jobs,
            poll_s=settings.job_poll_s,
            stale_s=settings.job_stale_s,
        )
        runner.start()
        try:
            stop.wait()
        finally:
            runner.stop()
    finally:
        db.close()


def run(args: argparse.Namespace) -> int:
    from skisnow.app.settings import Settings
    from skisnow.app.storage.common import check_data_dir
    from skisnow.solvers.errors import InputError

    overrides = {"job_poll_s": args.poll_s} if args.poll_s is not None else {}
    settings = Settings(**overrides)
    jobs = args.jobs if args.jobs is not None else max(settings.job_workers, 1)
    if not 1 <= jobs <= 16:
        raise InputError(f"--jobs must be from 1 to 16, got {jobs}")
    check_data_dir(Path(settings.data_dir))
    stop = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda *_: stop.set())
    print(
        f"skisnow worker: running up to {jobs} job(s) at once from {settings.catalogue_url} "
        f"(data in {settings.data_dir}); Ctrl-C or SIGTERM to stop",
        file=sys.stderr,
        flush=True,
    )
    run_worker(settings, stop, jobs=jobs)
    print("skisnow worker: stopped (running jobs are back in the queue)", file=sys.stderr)
    return 0
