"""Jobs in a separate ``skisnow worker`` process (issue #16): a service with
``job_workers = 0`` claims nothing; a worker on the same database runs the job, and the
service serves the finished item."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

from skisnow.app.commands.worker import run_worker
from skisnow.app.settings import Settings
from test_uploads import CONTACT, FAST, make_client, post_grind, wait_job


def test_a_service_without_job_workers_leaves_jobs_to_a_worker(catalogue, tmp_path):
    with make_client(catalogue, tmp_path, job_workers=0) as client:
        r = post_grind(client, name="by-worker")
        assert r.status_code == 202, r.text
        job_id = r.json()["job"]
        time.sleep(0.5)  # ten polls of the service's runner
        assert client.get(f"/v1/jobs/{job_id}").json()["state"] == "queued"

        stop = threading.Event()
        settings = Settings(data_dir=tmp_path, **FAST)
        worker = threading.Thread(target=run_worker, args=(settings, stop), kwargs={"jobs": 1})
        worker.start()
        try:
            job = wait_job(client, job_id)
        finally:
            stop.set()
            worker.join(60)
        assert not worker.is_alive()
        assert job["state"] == "done", job
        shown = client.get("/v1/grinds/by-worker").json()
        assert shown["state"] == "ready" and shown["usable"] is True
        r = client.post("/v1/contact", json={"ski": "ski-a", "grind": "by-worker", **CONTACT})
        assert r.status_code == 200, r.text[:500]


def test_worker_command_stops_cleanly_on_sigterm(tmp_path):
    env = {**os.environ, "SKISNOW_DATA_DIR": str(tmp_path), "SKISNOW_JOB_POLL_S": "0.1"}
    proc = subprocess.Popen(
        [sys.executable, "-m", "skisnow.app.cli", "worker"],
        env=env,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        first = proc.stderr.readline()
        assert "skisnow worker: running up to 1 job(s)" in first, first
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(60) == 0
        assert "stopped" in proc.stderr.read()
        assert (tmp_path / "catalogue.db").exists()
    finally:
        if proc.poll() is None:
            proc.kill()


def test_worker_refuses_a_bad_job_count(tmp_path):
    env = {**os.environ, "SKISNOW_DATA_DIR": str(tmp_path)}
    r = subprocess.run(
        [sys.executable, "-m", "skisnow.app.cli", "worker", "--jobs", "0"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2 and "--jobs must be from 1 to 16" in r.stderr
    assert "Traceback" not in r.stderr
