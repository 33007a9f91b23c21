"""``skisnow serve`` without ``--workers`` starts the default number of workers and says so
(app.settings.default_workers, issue #29); ``--workers`` and ``SKISNOW_WORKERS`` override it."""

from __future__ import annotations

import argparse
import os

import pytest
from skisnow.app.commands import serve
from skisnow.app.settings import default_workers


@pytest.fixture
def started(monkeypatch, tmp_path):
    """Runs ``run_serve`` up to the point where it starts uvicorn, and records how."""
    calls: list[tuple[str, int]] = []
    import uvicorn

    monkeypatch.setattr(uvicorn, "run", lambda *a, **k: calls.append(("uvicorn.run", 1)))
    monkeypatch.setattr(serve, "_run_workers", lambda h, p, n: calls.append(("supervisor", n)) or 0)
    monkeypatch.setenv("SKISNOW_DATA_DIR", str(tmp_path / "data"))
    monkeypatch.delenv("SKISNOW_WORKERS", raising=False)
    monkeypatch.delenv("SKISNOW_DATABASE_URL", raising=False)
    # run_serve sets these for its workers; restored after the test
    monkeypatch.setenv("OMP_NUM_THREADS", os.environ.get("OMP_NUM_THREADS", "1"))

    def run(workers=None):
        args = argparse.Namespace(host=None, port=None, workers=workers, tables_dir=None)
        assert serve.run_serve(args) == 0
        return calls[-1]

    return run


@pytest.mark.parametrize("cores", [1, 2, 3])
def test_default_is_one_worker_per_core_and_the_log_says_so(started, monkeypatch, capsys, cores):
    monkeypatch.setattr("skisnow.app.settings._available_memory_mb", lambda: 64_000.0)
    monkeypatch.setattr("os.sched_getaffinity", lambda pid: set(range(cores)))
    how, n = started()
    assert n == default_workers() == cores
    assert how == ("uvicorn.run" if cores == 1 else "supervisor")
    err = capsys.readouterr().err
    plural = "es" if cores > 1 else ""
    assert f"skisnow serve: {cores} worker process{plural} (one per usable core" in err


def test_workers_given_are_kept(started, monkeypatch, capsys):
    monkeypatch.setattr("os.sched_getaffinity", lambda pid: {0, 1})
    assert started(workers=3) == ("supervisor", 3)
    assert "skisnow serve: 3 worker processes\n" in capsys.readouterr().err
    monkeypatch.setenv("SKISNOW_WORKERS", "1")
    assert started() == ("uvicorn.run", 1)
