"""Several service processes starting at once on an empty catalogue (every first ``docker run``
with two uvicorn workers) must all come up: issue #15, "startup race"."""

from __future__ import annotations

import multiprocessing as mp

import pytest

PROCESSES = 6
ROUNDS = 8  # before the fix, 9 of 15 rounds had a process fail with "table items already exists"


def _open(url: str, barrier, queue) -> None:
    from skisnow.app.storage.catalogue import CatalogueDB

    barrier.wait()
    try:
        CatalogueDB(url).close()
        queue.put("ok")
    except Exception as exc:  # reported to the parent, which fails the test with it
        queue.put(f"{type(exc).__name__}: {exc}"[:300])


@pytest.mark.skipif("fork" not in mp.get_all_start_methods(), reason="needs fork")
def test_processes_creating_the_catalogue_at_once_all_succeed(tmp_path):
    # imported before the fork, so that the children race on the schema, not on imports
    import skisnow.app.storage.catalogue  # noqa: F401

    ctx = mp.get_context("fork")
    for r in range(ROUNDS):
        url = f"sqlite:///{tmp_path / f'round{r}' / 'catalogue.db'}"
        barrier, queue = ctx.Barrier(PROCESSES), ctx.Queue()
        procs = [ctx.Process(target=_open, args=(url, barrier, queue)) for _ in range(PROCESSES)]
        for p in procs:
            p.start()
        for p in procs:
            p.join(timeout=60)
        results = [queue.get(timeout=10) for _ in procs]
        assert results == ["ok"] * PROCESSES, (r, [x for x in results if x != "ok"])


def test_serve_refuses_an_unwritable_data_dir_naming_the_setting(tmp_path, monkeypatch, capsys):
    """A data folder the service cannot write (a bind mount owned by another uid in Docker)
    stops ``skisnow serve`` before it binds, with exit code 2 and the setting named (it used to
    exit 0 from inside a worker with ``unable to open database file``)."""
    from skisnow.app.cli import main

    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("SKISNOW_DATA_DIR", str(blocker / "data"))  # cannot be created
    assert main(["serve", "--port", "1"]) == 2
    err = capsys.readouterr().err
    assert "SKISNOW_DATA_DIR" in err and "not writable" in err and "Traceback" not in err


@pytest.mark.parametrize(
    ("host", "tokens", "warned"),
    [
        ("127.0.0.1", {}, False),
        ("::1", {}, False),
        ("localhost", {}, False),
        ("0.0.0.0", {}, True),
        ("192.168.1.5", {}, True),
        ("0.0.0.0", {"secret": "team-a"}, False),
    ],
)
def test_open_writes_on_a_public_address_are_warned_at_start_up(host, tokens, warned):
    from skisnow.app.commands.serve import open_writes_warning

    text = open_writes_warning(host, tokens)
    assert (text is not None) == warned
    if warned:
        assert host in text and "SKISNOW_TEAM_TOKENS" in text


#: a sitecustomize for the test below: in a spawned process (a uvicorn worker), the catalogue
#: points below a plain file (no folder can be made there, not even by root), so the worker
#: fails before it serves, while the ``skisnow serve`` process itself passes its own checks
_WORKERS_FAIL = """
import os, sys
if any("spawn_main" in a for a in getattr(sys, "orig_argv", [])):
    os.environ["SKISNOW_DATABASE_URL"] = "sqlite:///{blocker}/catalogue.db"
"""


def test_serve_exits_non_zero_when_a_worker_fails_to_start(tmp_path):
    """With two workers, a worker that fails at start-up stops ``skisnow serve`` with uvicorn's
    startup-failure code 3 (it exited 0, so ``--restart on-failure`` did nothing: issue #15)."""
    import os
    import socket
    import subprocess
    import sys
    from pathlib import Path

    (tmp_path / "hook").mkdir()
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    (tmp_path / "hook" / "sitecustomize.py").write_text(_WORKERS_FAIL.format(blocker=blocker))
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    repo = Path(__file__).resolve().parents[2]
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(tmp_path / "hook"), str(repo)]),
        "SKISNOW_DATA_DIR": str(tmp_path / "data"),
        "SKISNOW_WARM_UP": "false",
        "OMP_NUM_THREADS": "1",
    }
    env.pop("SKISNOW_DATABASE_URL", None)
    cmd = [sys.executable, "-m", "skisnow.app.cli", "serve", "--port", str(port), "--workers", "2"]
    proc = subprocess.run(cmd, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=180)
    assert proc.returncode == 3, proc.stderr[-2000:]
    assert "failed to start" in proc.stderr
    assert (tmp_path / "data" / "catalogue.db").exists()  # the parent's own checks passed


#: a sitecustomize for the test below: a spawned process (a uvicorn worker) dies at once with
#: exit code 1, as a worker whose app fails to import does
_WORKERS_DIE = """
import os, sys
if any("spawn_main" in a for a in getattr(sys, "orig_argv", [])):
    sys.stderr.write("worker: simulated import failure\\n")
    os._exit(1)
"""


def test_serve_exits_non_zero_when_a_worker_dies_at_start_with_another_code(tmp_path):
    """With two workers, a worker that dies before it serves with a code other than uvicorn's
    startup failure (an import error exits 1) stops ``skisnow serve`` with code 3; uvicorn's
    supervisor restarted such a worker without end (issue #27, "left from the last round")."""
    import os
    import socket
    import subprocess
    import sys

    (tmp_path / "hook").mkdir()
    (tmp_path / "hook" / "sitecustomize.py").write_text(_WORKERS_DIE)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {
        **os.environ,
        "PYTHONPATH": str(tmp_path / "hook"),
        "SKISNOW_DATA_DIR": str(tmp_path / "data"),
        "SKISNOW_WARM_UP": "false",
        "OMP_NUM_THREADS": "1",
    }
    env.pop("SKISNOW_DATABASE_URL", None)
    cmd = [sys.executable, "-m", "skisnow.app.cli", "serve", "--port", str(port), "--workers", "2"]
    try:
        proc = subprocess.run(
            cmd, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=90
        )
    except subprocess.TimeoutExpired as exc:
        raise AssertionError("serve kept restarting a worker that dies at start") from exc
    assert proc.returncode == 3, proc.stderr[-2000:]
    assert "failed to start" in proc.stderr


def test_serve_with_two_workers_stops_cleanly_with_exit_code_0_on_sigterm(tmp_path):
    """The other side of the test above: ``docker stop`` (SIGTERM) is a clean stop, exit 0."""
    import os
    import signal
    import socket
    import subprocess
    import sys
    import time
    from pathlib import Path

    import httpx

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    repo = Path(__file__).resolve().parents[2]
    env = {
        **os.environ,
        "PYTHONPATH": str(repo),
        "SKISNOW_DATA_DIR": str(tmp_path / "data"),
        "SKISNOW_WARM_UP": "false",
        "OMP_NUM_THREADS": "1",
    }
    env.pop("SKISNOW_DATABASE_URL", None)
    cmd = [sys.executable, "-m", "skisnow.app.cli", "serve", "--port", str(port), "--workers", "2"]
    proc = subprocess.Popen(cmd, env=env, cwd=tmp_path, stderr=subprocess.PIPE, text=True)
    try:
        t0 = time.monotonic()
        while time.monotonic() - t0 < 120:
            assert proc.poll() is None, proc.stderr.read()[-2000:]
            try:
                if httpx.get(f"http://127.0.0.1:{port}/readyz", timeout=2).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            time.sleep(0.2)
        else:
            raise AssertionError("not ready in 120 s")
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=60) == 0, proc.stderr.read()[-2000:]
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
