"""A real ``skisnow serve`` process for tests that must go through uvicorn and a socket (the
Host check, quotas under concurrent uploads, the event loop during a long upload check)."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import httpx

__all__ = ["free_port", "serving"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def serving(tmp_path: Path, env: dict | None = None, workers: int = 1, ready_s: float = 180.0):
    """Run ``skisnow serve`` on a free loopback port with a private data folder (settings
    ``SKISNOW_*`` in ``env``) until it answers ``/readyz``; yields its base URL and stops it
    (SIGTERM) afterwards. Its log is ``tmp_path/serve.log``."""
    port = free_port()
    full = {
        **os.environ,
        "SKISNOW_DATA_DIR": str(tmp_path / "serve-data"),
        "SKISNOW_WARM_UP": "false",
        "OMP_NUM_THREADS": "1",
        **(env or {}),
    }
    if "SKISNOW_DATABASE_URL" not in (env or {}):
        full.pop("SKISNOW_DATABASE_URL", None)
    cmd = [sys.executable, "-m", "skisnow.app.cli", "serve", "--port", str(port)]
    cmd += ["--workers", str(workers)]
    log_path = tmp_path / "serve.log"
    with open(log_path, "w") as log:
        proc = subprocess.Popen(cmd, env=full, cwd=tmp_path, stdout=log, stderr=log)
    base = f"http://127.0.0.1:{port}"
    try:
        t0 = time.monotonic()
        while True:
            if proc.poll() is not None:
                raise AssertionError(f"serve exited {proc.returncode}: {log_path.read_text()}")
            try:
                if httpx.get(f"{base}/readyz", timeout=2).status_code == 200:
                    break
            except httpx.TransportError:
                pass
            if time.monotonic() - t0 > ready_s:
                raise AssertionError(f"not ready in {ready_s} s: {log_path.read_text()[-2000:]}")
            time.sleep(0.2)
        yield base
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
