"""The first start says what it is doing (issue #28: it was silent for about 25 s)."""

from __future__ import annotations

import logging

from fastapi.testclient import TestClient
from skisnow.app.main import create_app
from skisnow.app.settings import Settings


def test_the_start_logs_the_warm_up_and_ready(catalogue, tmp_path, caplog):
    # the handler sits on the logger itself: a uvicorn started earlier in this process
    # (another test) configures "uvicorn" not to propagate to the root logger caplog watches
    logger = logging.getLogger("uvicorn.error")
    caplog.set_level(logging.INFO, logger="uvicorn.error")
    logger.addHandler(caplog.handler)
    settings = Settings(data_dir=tmp_path, warm_up=True)
    try:
        with TestClient(create_app(settings, catalogue=catalogue)) as client:
            assert client.get("/healthz").status_code == 200
    finally:
        logger.removeHandler(caplog.handler)
    lines = [r.getMessage() for r in caplog.records if r.name == "uvicorn.error"]
    assert any(line.startswith("warming up") for line in lines), lines
    assert any(line.startswith("warm-up done in") for line in lines), lines
    assert any(line.startswith("skisnow ready after") for line in lines), lines
