"""The job runner's lease (app/jobs/runner.py): a heartbeat keeps a job, an expired lease is taken
over, and a runner whose job was taken over writes nothing more about it. SQLite here; the same
runner on PostgreSQL across two processes is tests/storage/test_postgres.py."""

from __future__ import annotations

import datetime as dt
import threading
import time

import pytest
from skisnow.app.jobs import JobRunner
from skisnow.app.storage.catalogue import CatalogueDB
from skisnow.solvers.errors import SkisnowError


def _wait(predicate, timeout_s: float = 10.0) -> None:
    t0 = time.monotonic()
    while not predicate():
        assert time.monotonic() - t0 < timeout_s, "timed out"
        time.sleep(0.01)


def test_a_beating_runner_keeps_its_job_past_the_lease(tmp_path):
    """A job that runs 4 leases long is never taken by a second runner: the heartbeat renews
    the lease every poll."""
    db = CatalogueDB(f"sqlite:///{tmp_path / 'c.db'}")
    job = db.add_job("slow", None)
    release = threading.Event()
    ran: list[str] = []

    def slow(ctx):
        ran.append(ctx.runner)
        release.wait(10)
        return "ok"

    lease_s = 0.3
    a = JobRunner(db, {"slow": slow}, poll_s=0.02, stale_s=lease_s)
    b = JobRunner(db, {"slow": slow}, poll_s=0.02, stale_s=lease_s)
    a.start()
    try:
        _wait(lambda: db.job(job.id).state == "running")
        b.start()
        time.sleep(4 * lease_s)
        release.set()
        _wait(lambda: db.job(job.id).state == "done")
    finally:
        release.set()
        a.stop()
        b.stop()
    assert ran == [a.runner_id]
    assert db.job(job.id).attempts == 1
    db.close()


def test_a_slow_poll_does_not_let_a_running_job_lease_expire(tmp_path):
    """The heartbeat has its own thread: while ``on_poll`` (the catalogue resync) blocks for
    several leases, the running job keeps its lease and a second runner does not take it."""
    db = CatalogueDB(f"sqlite:///{tmp_path / 'c.db'}")
    job = db.add_job("slow", None)
    release, polling_slowly = threading.Event(), threading.Event()
    ran: list[str] = []

    def slow(ctx):
        ran.append(ctx.runner)
        release.wait(10)
        return "ok"

    def slow_poll():
        if db.job(job.id).state == "running":
            polling_slowly.set()
            release.wait(10)  # blocks a's poll thread until the job is released

    lease_s = 0.3
    a = JobRunner(db, {"slow": slow}, on_poll=slow_poll, poll_s=0.02, stale_s=lease_s)
    b = JobRunner(db, {"slow": slow}, poll_s=0.02, stale_s=lease_s)
    a.start()
    try:
        assert polling_slowly.wait(10)
        b.start()
        time.sleep(4 * lease_s)
        assert db.job(job.id).runner == a.runner_id
        release.set()
        _wait(lambda: db.job(job.id).state == "done")
    finally:
        release.set()
        a.stop()
        b.stop()
    assert ran == [a.runner_id]
    assert db.job(job.id).attempts == 1
    db.close()


def test_an_expired_lease_is_taken_over(tmp_path):
    """A job left running by a runner on another host (no heartbeat since) is run by this one
    once the lease has expired, not before."""
    db = CatalogueDB(f"sqlite:///{tmp_path / 'c.db'}")
    job = db.add_job("noop", None)
    assert db.claim_job(job.id, "other-host:1:gone", dt.datetime.now(dt.UTC))
    lease_s = 1.0
    runner = JobRunner(db, {"noop": lambda ctx: "ok"}, poll_s=0.02, stale_s=lease_s)
    t0 = time.monotonic()
    runner.start()
    try:
        _wait(lambda: db.job(job.id).state == "done")
    finally:
        runner.stop()
    waited_s = time.monotonic() - t0
    row = db.job(job.id)
    assert row.runner == runner.runner_id and row.attempts == 2
    assert waited_s >= 0.9 * lease_s  # the heartbeat is a little older than the claim
    db.close()


@pytest.mark.parametrize("then", ["progress", "finish", "fail"])
def test_a_runner_whose_job_was_taken_over_writes_nothing_more(tmp_path, then):
    """The job is claimed by another runner while this one still runs it (this one froze past
    its lease). Whatever this one does next, reporting progress (stopped with JobLeaseLost),
    finishing or failing, it writes nothing about the new owner's job and cleans nothing up."""
    db = CatalogueDB(f"sqlite:///{tmp_path / 'c.db'}")
    item = db.add_item("grind", "g")
    job = db.add_job("work", item.id)
    taken = threading.Event()
    outcome: list[str] = []
    cleaned: list[str] = []

    def work(ctx):
        ctx.progress(0.1)
        taken.wait(10)
        try:
            if then == "progress":
                ctx.progress(0.5, "next chunk")  # a new message is written at once
            elif then == "fail":
                raise SkisnowError("broke after the takeover")
        except BaseException as exc:
            outcome.append(type(exc).__name__)
            raise
        outcome.append("returned")
        return "ok"

    runner = JobRunner(
        db,
        {"work": work},
        on_failure=lambda ctx, exc: cleaned.append(ctx.job.id),
        poll_s=0.02,
        stale_s=60,
    )
    runner.start()
    try:
        _wait(lambda: db.job(job.id).progress == 0.1)
        stale = dt.datetime.now(dt.UTC) + dt.timedelta(seconds=1)  # as if the lease lapsed
        assert db.claim_job(job.id, "other-host:2:new", stale)
        taken.set()
        _wait(lambda: outcome)
        time.sleep(0.2)
    finally:
        runner.stop()
    expected = {"progress": "JobLeaseLost", "finish": "returned", "fail": "SkisnowError"}
    assert outcome == [expected[then]]
    row = db.job(job.id)
    assert (row.state, row.runner, row.progress, row.attempts) == (
        "running",
        "other-host:2:new",
        0.1,
        2,
    )
    assert cleaned == []
    db.close()
