"""One CPU-bound answer at a time per process (app.service.gate, issue #29), and the default
number of serving workers (app.settings.default_workers)."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest
from skisnow.app import service
from skisnow.app.service import answer as answer_module
from skisnow.app.service import gate
from skisnow.app.service.gate import gated
from skisnow.app.settings import WORKER_MEMORY_MB, WORKERS_MAX, default_workers


class _Overlap:
    """Wraps a function and records the most calls of it running at once."""

    def __init__(self, fn, hold_s: float = 0.02) -> None:
        self.fn, self.hold_s = fn, hold_s
        self.active = self.most = 0
        self._lock = threading.Lock()

    def __call__(self, *args, **kwargs):
        with self._lock:
            self.active += 1
            self.most = max(self.most, self.active)
        try:
            time.sleep(self.hold_s)  # lets another thread in, if nothing holds it out
            return self.fn(*args, **kwargs)
        finally:
            with self._lock:
                self.active -= 1


def test_gated_functions_run_one_at_a_time_and_nest():
    probe = _Overlap(lambda x: x * 2)
    inner = gated(probe)
    outer = gated(lambda x: inner(x) + 1)  # re-entrant: a gated call inside a gated call
    with ThreadPoolExecutor(6) as pool:
        got = list(pool.map(outer, range(12)))
    assert got == [2 * x + 1 for x in range(12)]
    assert probe.most == 1
    # the same probe without the gate does overlap: the test can fail
    free = _Overlap(lambda x: x)
    with ThreadPoolExecutor(6) as pool:
        list(pool.map(free, range(12)))
    assert free.most > 1


def test_contact_answers_run_one_at_a_time_with_the_same_answers(catalogue, monkeypatch):
    cat = catalogue
    inputs = [
        service.ContactInputs("ski-a", "tiny-grind", kg, -160.0, 200.0, 0.5, ski_model="rigid")
        for kg in (30.0, 40.0, 50.0, 60.0)
    ]
    alone = [service.contact(cat, i) for i in inputs]
    probe = _Overlap(answer_module.solve_macro)
    monkeypatch.setattr(answer_module, "solve_macro", probe)
    with ThreadPoolExecutor(4) as pool:
        together = list(pool.map(lambda i: service.contact(cat, i), inputs))
    assert probe.most == 1
    for a, b in zip(alone, together, strict=True):
        assert a["metrics"] == b["metrics"] and a["band"] == b["band"]
    # nothing holds the slot afterwards
    assert gate._GATE.acquire(blocking=False)
    gate._GATE.release()


@pytest.mark.parametrize(
    ("cores", "available_mb", "expected"),
    [
        (2, 24_000, 2),  # the benchmark machine
        (1, 24_000, 1),
        (16, 128_000, WORKERS_MAX),  # capped
        (16, 4 * WORKER_MEMORY_MB, 2),  # half the memory holds two workers
        (4, 0.5 * WORKER_MEMORY_MB, 1),  # never below one
        (3, None, 3),  # no /proc/meminfo: cores only
    ],
)
def test_default_workers(cores, available_mb, expected, monkeypatch):
    if available_mb is None:
        monkeypatch.setattr("skisnow.app.settings._available_memory_mb", lambda: None)
    assert default_workers(cores, available_mb) == expected


def test_settings_leave_workers_to_the_default(monkeypatch):
    from skisnow.app.settings import Settings

    monkeypatch.delenv("SKISNOW_WORKERS", raising=False)
    assert Settings().workers is None
    monkeypatch.setenv("SKISNOW_WORKERS", "3")
    assert Settings().workers == 3
