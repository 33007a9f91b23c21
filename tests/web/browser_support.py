"""What the browser tests share (tests/web/test_browser.py, tests/web/test_browser_login.py):
Debian's Chromium and its flags, the app under uvicorn in a thread, an upload-ready app's
settings, and a grind as ``.npy`` bytes."""

from __future__ import annotations

import contextlib
import io
import socket
import threading
import time
from pathlib import Path

import pytest

CHROMIUM = "/usr/bin/chromium"
REPO = Path(__file__).resolve().parents[2]
SCREENSHOTS = REPO / "docs" / "screenshots"
ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def serve(app):
    """Run ``app`` under uvicorn in a background thread; yield its base URL."""
    import uvicorn

    port = _free_port()
    srv = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=srv.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not srv.started:
        if time.monotonic() > deadline or not thread.is_alive():
            pytest.fail("uvicorn did not start")
        time.sleep(0.05)
    try:
        yield f"http://127.0.0.1:{port}"
    finally:
        srv.should_exit = True
        thread.join(timeout=10)


@contextlib.contextmanager
def serve_uploads(catalogue, data_dir: Path, **settings):
    """The app on its own data directory and a copy of ``catalogue``, with table settings so
    small that a grind's table builds in seconds (as tests/jobs/test_uploads.py); more
    ``Settings`` fields in ``settings`` (team tokens, …). Yields its base URL."""
    from skisnow.app import service
    from skisnow.app.main import create_app
    from skisnow.app.settings import Settings

    cat = service.Catalogue(
        tables_dir=catalogue.tables_dir, skis=dict(catalogue.skis), grinds=dict(catalogue.grinds)
    )
    config = Settings(
        data_dir=data_dir,
        warm_up=False,
        table_points=8,
        table_chunk_size=2,
        table_processes=False,
        job_poll_s=0.05,
        max_upload_bytes=1_000_000,
        **settings,
    )
    with serve(create_app(config, catalogue=cat)) as url:
        yield url


def npy_bytes(a) -> bytes:
    """``a`` as the bytes of a ``.npy`` file."""
    import numpy as np

    buf = io.BytesIO()
    np.save(buf, a)
    return buf.getvalue()
