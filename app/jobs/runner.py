"""Background jobs of the service: persisted in the catalogue database, run in a thread pool.

A :class:`JobRunner` lives in each service process (``job_workers`` ≥ 1, the default), or only in
``skisnow worker`` processes (:mod:`app.commands.worker`; the service with ``job_workers = 0`` then
claims nothing and only polls for finished items). Its poll thread claims jobs from the database
(queued ones, and running ones whose runner stopped beating: a crashed process), runs them in a
small thread pool through a handler per job kind, and beats a heartbeat for the jobs it runs.
Handlers report progress through :class:`JobContext`, which also raises :class:`JobInterrupted`
once the runner is stopping; an interrupted job goes back to ``queued`` and resumes in the next
process that starts (grind tables from their chunk checkpoints, see :mod:`app.jobs.table_build`; ski
networks from the start). A claim is a lease of ``stale_s`` seconds renewed by every heartbeat
(each poll). A process killed mid-job (``kill -9``, a lost machine) stops beating; once its lease
has expired, any other process on the same database claims the job and runs it again (a grind table
from the checkpoints in the shared data directory). Processes on the same host requeue the jobs of
dead local pids at start without waiting for the lease. A runner that finds its job taken over (its
own heartbeats lapsed, e.g. a frozen process) stops it with :class:`JobLeaseLost` and writes
nothing more about it. ``stale_s`` must exceed the longest pause between two polls.

Lanes: each job kind runs in a lane of its own with ``workers`` slots (:data:`LANES`), so a
grind table that builds in seconds never waits behind a ski network that trains for minutes, even
with ``workers`` = 1 (a process then runs up to one job of each lane at once). Within a lane, jobs
run oldest first. :func:`queue_info` gives a queued job's position in its lane and an estimate.

Job states: ``queued`` → ``running`` → ``done`` | ``failed`` (``running`` → ``queued`` when the
service stops mid-job).
"""

from __future__ import annotations

import datetime as _dt
import logging
import os
import socket
import threading
import time
import uuid
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

from skisnow.app.storage.catalogue import CatalogueDB, ItemRow, JobRow
from skisnow.solvers.errors import SkisnowError

__all__ = [
    "LANES",
    "JobContext",
    "JobInterrupted",
    "JobLeaseLost",
    "JobRunner",
    "lane_of",
    "queue_info",
]

log = logging.getLogger(__name__)

#: Job kind → lane. Short jobs (grind tables, seconds to a minute) and long ones (ski networks,
#: minutes) have lanes of their own; a kind not listed gets a lane named after itself.
LANES: dict[str, str] = {"grind-table": "short", "ski-network": "long"}


def lane_of(kind: str) -> str:
    """The lane a job of ``kind`` runs in (:data:`LANES`)."""
    return LANES.get(kind, kind)


class JobInterrupted(Exception):
    """Raised inside a handler when the runner stops; the job goes back to the queue."""


class JobLeaseLost(Exception):
    """Raised inside a handler whose job another runner took over (this runner's lease
    expired); the job's row belongs to the new runner and is left alone."""


@dataclass
class JobContext:
    """What a handler gets: its job and item rows, the database, progress reporting."""

    job: JobRow
    item: ItemRow | None
    db: CatalogueDB
    stop_event: threading.Event
    runner: str | None = None
    _last_write: float = field(default=0.0, repr=False)
    _last_message: str = field(default="", repr=False)

    def check_stop(self) -> None:
        if self.stop_event.is_set():
            raise JobInterrupted("the service is stopping")

    def progress(self, fraction: float, message: str | None = None) -> None:
        """Record progress in [0, 1] (throttled to a write every 0.25 s); may interrupt, and
        raises :class:`JobLeaseLost` when the job is no longer this runner's."""
        self.check_stop()
        fraction = min(max(float(fraction), 0.0), 1.0)
        now = time.monotonic()
        changed = message is not None and message != self._last_message
        if changed or now - self._last_write >= 0.25 or fraction >= 1.0:
            values = {"progress": fraction}
            if message is not None:
                values["message"] = message
                self._last_message = message
            if not self.db.update_job(self.job.id, owner=self.runner, **values):
                raise JobLeaseLost(f"job {self.job.id} was taken over by another runner")
            self._last_write = now


Handler = Callable[[JobContext], str]
FailureHook = Callable[[JobContext, BaseException], None]


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # pragma: no cover - another user's process
        return True
    return True


class JobRunner:
    """Claim and run the catalogue's jobs in this process.

    Parameters
    ----------
    db : CatalogueDB
        The catalogue database.
    handlers : dict
        Job kind → ``handler(ctx) -> final message``; raising fails the job (the message of a
        :class:`~solvers.errors.SkisnowError` or ``ImportError`` is the job's error).
    on_failure : callable, optional
        ``on_failure(ctx, exc)`` after a job failed (clean-up of partial outputs).
    on_poll : callable, optional
        Called on every poll (the service syncs its live catalogue with the database there).
    workers : int
        Jobs run at once in each lane (:data:`LANES`); 0: this process claims no job and only
        polls (``on_poll``), the jobs run in separate ``skisnow worker`` processes on the same
        database.
    poll_s : float
        Poll interval [s].
    stale_s : float
        A running job whose heartbeat is older than this is taken over [s].
    """

    def __init__(
        self,
        db: CatalogueDB,
        handlers: dict[str, Handler],
        *,
        on_failure: FailureHook | None = None,
        on_poll: Callable[[], None] | None = None,
        workers: int = 1,
        poll_s: float = 1.0,
        stale_s: float = 120.0,
    ) -> None:
        self.db = db
        self.handlers = handlers
        self.on_failure = on_failure
        self.on_poll = on_poll
        self.workers = int(workers)
        self.poll_s = float(poll_s)
        self.stale_s = float(stale_s)
        self.host = socket.gethostname()
        self.runner_id = f"{self.host}:{os.getpid()}:{uuid.uuid4().hex[:8]}"
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._active: dict[str, tuple[str | None, Future, str]] = {}  # job → (item, fut, lane)
        self._lock = threading.Lock()
        self._pools: dict[str, ThreadPoolExecutor] = {}
        self._thread: threading.Thread | None = None
        self._beat_thread: threading.Thread | None = None

    # ------------------------------------------------------------------------ control

    def start(self) -> None:
        """Requeue jobs of dead processes on this host, then start polling."""
        self._requeue_dead_local_runners()
        if self.workers > 0:  # 0: poll only (on_poll); the jobs run in `skisnow worker`
            for lane in sorted({lane_of(kind) for kind in self.handlers}):
                self._pools[lane] = ThreadPoolExecutor(
                    self.workers, thread_name_prefix=f"skisnow-job-{lane}"
                )
        self._thread = threading.Thread(target=self._loop, name="skisnow-jobs", daemon=True)
        self._thread.start()
        self._beat_thread = threading.Thread(
            target=self._beat_loop, name="skisnow-job-heartbeat", daemon=True
        )
        self._beat_thread.start()

    def stop(self, timeout: float = 60.0) -> None:
        """Interrupt running jobs (they go back to ``queued``) and wait for the threads."""
        self._stop.set()
        self._wake.set()
        for thread in (self._thread, self._beat_thread):
            if thread is not None:
                thread.join(timeout)
        for pool in self._pools.values():
            pool.shutdown(wait=True, cancel_futures=True)

    def wake(self) -> None:
        """Poll now (a job was just queued)."""
        self._wake.set()

    def busy_item_ids(self) -> set[str]:
        with self._lock:
            return {item for item, _, _ in self._active.values() if item}

    # ------------------------------------------------------------------------ internals

    def _requeue_dead_local_runners(self) -> None:
        for job in self.db.running_jobs_of(f"{self.host}:"):
            try:
                pid = int((job.runner or "").split(":")[1])
            except (IndexError, ValueError):
                continue
            if not _pid_alive(pid):
                log.info("job %s: its process %d is gone; requeued", job.id, pid)
                self.db.update_job(  # unless another process requeued and claimed it
                    job.id,
                    owner=job.runner,
                    state="queued",
                    runner=None,
                    message="requeued after a crash",
                )

    def _loop(self) -> None:
        while not self._stop.is_set():
            try:
                self._poll()
            except Exception:  # pragma: no cover - keep the runner alive on DB hiccups
                log.exception("job runner poll failed")
            self._wake.wait(self.poll_s)
            self._wake.clear()

    def _beat_loop(self) -> None:
        """Renew the lease of this runner's jobs every poll interval, in a thread of its own:
        a slow ``on_poll`` (loading a large new item) or a slow claim never lets a running job's
        lease expire, which would have another process take it over and redo it."""
        while not self._stop.wait(self.poll_s):
            with self._lock:
                active = [j for j, (_, fut, _) in self._active.items() if not fut.done()]
            try:
                self.db.heartbeat(active, self.runner_id)
            except Exception:  # pragma: no cover - keep beating through DB hiccups
                log.exception("job heartbeat failed")

    def _poll(self) -> None:
        with self._lock:
            done = [j for j, (_, fut, _) in self._active.items() if fut.done()]
            for j in done:
                del self._active[j]
            active = dict(self._active)
        if self.on_poll is not None:
            self.on_poll()
        if not self._pools or self._stop.is_set():
            return
        free = {lane: self.workers for lane in self._pools}
        for _, _, lane in active.values():
            free[lane] -= 1
        if all(n <= 0 for n in free.values()):
            return
        stale_before = _dt.datetime.now(_dt.UTC) - _dt.timedelta(seconds=self.stale_s)
        for job in self.db.claimable_jobs(stale_before):  # oldest first
            if self._stop.is_set() or all(n <= 0 for n in free.values()):
                break
            if job.id in active or job.kind not in self.handlers:
                continue
            lane = lane_of(job.kind)
            if free[lane] <= 0:
                continue  # its lane is full; a job of another lane may still start
            if not self.db.claim_job(job.id, self.runner_id, stale_before):
                continue  # another process was quicker
            fut = self._pools[lane].submit(self._run, job.id)
            with self._lock:
                self._active[job.id] = (job.item_id, fut, lane)
            free[lane] -= 1

    def _run(self, job_id: str) -> None:
        job = self.db.job(job_id)
        item = self.db.item(job.item_id) if job.item_id else None
        ctx = JobContext(job, item, self.db, self._stop, self.runner_id)
        me = self.runner_id
        log.info("job %s (%s) started by %s, attempt %d", job_id, job.kind, me, job.attempts)
        t0 = time.perf_counter()
        try:
            if job.item_id and item is None:
                raise SkisnowError("the job's item was deleted")
            message = self.handlers[job.kind](ctx)
        except JobLeaseLost:
            log.warning("job %s: taken over by another runner; %s stops it", job_id, me)
            return
        except JobInterrupted:
            log.info("job %s interrupted; it resumes at the next start", job_id)
            self.db.update_job(
                job_id,
                owner=me,
                state="queued",
                runner=None,
                message="interrupted by a service stop; resumes at the next start",
            )
            return
        except BaseException as exc:
            if isinstance(exc, SkisnowError | ImportError):
                error = str(exc)
            else:
                log.exception("job %s (%s) failed", job_id, job.kind)
                error = f"internal error ({type(exc).__name__}: {exc}); it was logged"
            # clean up first, then say "failed": a client that sees the job failed finds its
            # item failed too (the other order let a fast client see the item still pending)
            owned = self.db.update_job(job_id, owner=me, message="failed; cleaning up")
            if not owned:  # another runner has it: its files are not ours to remove
                log.warning("job %s failed in %s after a takeover; left alone", job_id, me)
            else:
                if self.on_failure is not None:
                    try:
                        self.on_failure(ctx, exc)
                    except Exception:  # pragma: no cover
                        log.exception("clean-up of failed job %s failed", job_id)
                self.db.update_job(job_id, owner=me, state="failed", error=error, message="failed")
            if not isinstance(exc, Exception):
                raise
            return
        finished = self.db.update_job(
            job_id,
            owner=me,
            state="done",
            progress=1.0,
            message=message or f"done in {time.perf_counter() - t0:.1f} s",
        )
        if not finished:
            log.warning("job %s finished in %s after another runner took it over", job_id, me)


def queue_info(db: CatalogueDB, job: JobRow, *, history: int = 20) -> dict:
    """Where ``job`` stands in its lane, and a rough estimate of when it is done.

    Returns ``queue_position`` (1: next to start in its lane; None unless queued), ``ahead``
    (jobs of its lane queued before it or running), ``estimate_s`` (seconds until done: the
    median upload-to-done time of the last ``history`` finished jobs of its kind, times the
    jobs ahead plus itself for a queued job, times the part left for a running one; None when
    no job of its kind has finished yet or the job is no longer active) and ``estimate_basis``
    (how many finished jobs the estimate rests on). The estimate assumes one slot per lane.
    """
    out = {"lane": lane_of(job.kind), "queue_position": None, "ahead": 0}
    out |= {"estimate_s": None, "estimate_basis": 0}
    if job.state not in ("queued", "running"):
        return out
    lane = out["lane"]
    kinds = [k for k in {*LANES, job.kind} if lane_of(k) == lane]
    active = [j for j in db.jobs(states=("queued", "running"), limit=1000) if j.kind in kinds]
    if job.state == "queued":
        ahead = [
            j
            for j in active
            if j.id != job.id and (j.state == "running" or j.created_at < job.created_at)
        ]
        out["ahead"] = len(ahead)
        out["queue_position"] = 1 + sum(1 for j in ahead if j.state == "queued")
    done = [j for j in db.jobs(states=("done",), limit=500) if j.kind == job.kind][:history]
    if done:
        took = sorted((j.updated_at - j.created_at).total_seconds() for j in done)
        typical_s = took[len(took) // 2]
        if job.state == "queued":
            estimate = typical_s * (out["ahead"] + 1)
        else:
            estimate = typical_s * (1.0 - job.progress)
        out["estimate_s"] = round(max(estimate, 0.0), 1)
        out["estimate_basis"] = len(done)
    return out
