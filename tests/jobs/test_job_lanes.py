"""Short and long jobs run in lanes of their own (app/jobs/runner.py, issue #28): a grind table
queued right behind a ski network is done before the ski job ends, even with one worker; a
queued job knows its position in its lane and gets an estimate from finished jobs of its kind.
"""

from __future__ import annotations

import threading
import time

from skisnow.app.jobs import JobRunner
from skisnow.app.jobs import handlers as job_handlers_module
from skisnow.app.jobs.runner import queue_info
from skisnow.app.jobs.uploads import GRIND_JOB, SKI_JOB
from skisnow.app.storage.catalogue import CatalogueDB
from skisnow.app.web.upload_page import example_camber_csv
from skisnow.solvers.errors import SkisnowError
from test_uploads import make_client, post_grind, post_ski, wait_job


def _wait(predicate, timeout_s: float = 20.0) -> None:
    t0 = time.monotonic()
    while not predicate():
        if time.monotonic() - t0 > timeout_s:
            raise AssertionError("timed out")
        time.sleep(0.01)


def test_a_short_job_does_not_wait_behind_a_long_one_with_one_worker(tmp_path):
    db = CatalogueDB(f"sqlite:///{tmp_path / 'c.db'}")
    release = threading.Event()

    def ski(ctx):
        release.wait(20)
        return "trained"

    runner = JobRunner(db, {SKI_JOB: ski, GRIND_JOB: lambda ctx: "built"}, poll_s=0.02, workers=1)
    long_job = db.add_job(SKI_JOB, None)
    short_job = db.add_job(GRIND_JOB, None)
    second_long = db.add_job(SKI_JOB, None)
    runner.start()
    try:
        _wait(lambda: db.job(short_job.id).state == "done")
        assert db.job(long_job.id).state == "running"
        # one slot per lane: the second ski job waits for the first, as the first in its lane
        assert db.job(second_long.id).state == "queued"
        info = queue_info(db, db.job(second_long.id))
        assert info["lane"] == "long" and info["queue_position"] == 1 and info["ahead"] == 1
        release.set()
        _wait(lambda: db.job(second_long.id).state == "done")
    finally:
        release.set()
        runner.stop()
        db.close()


def test_queue_position_and_estimate_from_finished_jobs(tmp_path):
    db = CatalogueDB(f"sqlite:///{tmp_path / 'c.db'}")
    try:
        grind = db.add_job(GRIND_JOB, None)
        assert queue_info(db, grind)["estimate_s"] is None  # nothing finished yet: no guess
        jobs = [db.add_job(SKI_JOB, None) for _ in range(3)]
        assert [queue_info(db, j)["queue_position"] for j in jobs] == [1, 2, 3]
        assert queue_info(db, grind)["queue_position"] == 1  # its own lane
        db.update_job(jobs[0].id, state="running", progress=0.5)
        done = db.add_job(SKI_JOB, None)
        db.update_job(done.id, state="done")
        took_s = (db.job(done.id).updated_at - db.job(done.id).created_at).total_seconds()
        last = queue_info(db, db.job(jobs[2].id))
        assert last["queue_position"] == 2 and last["ahead"] == 2 and last["estimate_basis"] == 1
        assert abs(last["estimate_s"] - round(3 * took_s, 1)) <= 0.1
        running = queue_info(db, db.job(jobs[0].id))
        assert running["queue_position"] is None
        assert abs(running["estimate_s"] - round(0.5 * took_s, 1)) <= 0.1
        assert queue_info(db, db.job(done.id))["estimate_s"] is None
    finally:
        db.close()


def test_a_grind_uploaded_behind_a_ski_upload_is_done_before_the_ski_job_ends(
    catalogue, tmp_path, monkeypatch
):
    """Through the API with SKISNOW_JOB_WORKERS = 1: the ski job (held open here to stand for
    a network that trains for minutes) is still running when the grind uploaded after it is
    done, and the job view shows the lanes."""
    release = threading.Event()
    started = threading.Event()

    def slow_ski_job(ctx, layout, settings, on_ready):
        started.set()
        release.wait(60)
        raise SkisnowError("stopped by the test")

    monkeypatch.setattr(job_handlers_module, "run_ski_job", slow_ski_job)
    with make_client(catalogue, tmp_path, job_workers=1) as client:
        try:
            # the upload page's example file: a valid camber CSV, quick to make
            r = post_ski(client, example_camber_csv(), name="slow-ski")
            assert r.status_code == 202, r.text
            ski_job = r.json()["job"]
            r = post_grind(client, name="quick-grind")
            assert r.status_code == 202, r.text
            grind_job = r.json()["job"]
            assert started.wait(20)
            assert wait_job(client, grind_job, timeout_s=60)["state"] == "done"
            ski = client.get(f"/v1/jobs/{ski_job}").json()
            assert ski["state"] == "running" and ski["lane"] == "long"
            assert client.get(f"/v1/jobs/{grind_job}").json()["lane"] == "short"
        finally:
            release.set()
        assert wait_job(client, ski_job, timeout_s=30)["state"] == "failed"
