"""An idle worker gives freed memory back (issue #27 point 6): app/api/idle.py."""

from __future__ import annotations

import time

from conftest import CONTACT_BODY
from fastapi.testclient import TestClient
from skisnow.app.api.idle import IdleTrimmer
from skisnow.app.main import create_app
from skisnow.app.settings import Settings


def test_a_worker_trims_once_per_idle_period_after_requests(catalogue):
    app = create_app(Settings(idle_trim_s=0.2), catalogue=catalogue)
    with TestClient(app) as c:
        trimmer = app.state.idle_trimmer
        time.sleep(0.6)
        assert trimmer.trims == 0  # nothing to give back before the first request
        assert c.post("/v1/contact", json=CONTACT_BODY).status_code == 200
        deadline = time.monotonic() + 5
        while trimmer.trims == 0 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert trimmer.trims == 1
        time.sleep(0.6)
        assert trimmer.trims == 1  # once per idle period, not every check


def test_no_trim_while_a_request_is_in_flight():
    t = IdleTrimmer(0.0)
    t.begin()
    t.end()
    t.begin()
    assert not t.check()
    t.end()
    assert t.check() and not t.check()


def test_zero_switches_it_off(catalogue):
    app = create_app(Settings(idle_trim_s=0), catalogue=catalogue)
    with TestClient(app):
        assert app.state.idle_trimmer._thread is None
