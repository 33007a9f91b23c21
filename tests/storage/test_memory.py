"""Per-ski caches bounded by bytes (issue #27 point 6): app/storage/memory.py."""

from __future__ import annotations

import numpy as np
import pytest
from skisnow.app.storage import memory
from skisnow.app.storage.memory import CacheBudget, SkiCache, deep_nbytes

MB = 2**20


def _block(mb: float) -> np.ndarray:
    return np.zeros(int(mb * MB) // 8)


def test_deep_nbytes_counts_buffers_in_containers_and_objects_once():
    a = _block(1)

    class Holder:
        def __init__(self):
            self.x = a
            self.y = {"again": a, "view": a[:10], "other": _block(2)}

    n = deep_nbytes(Holder())
    assert 3 * MB <= n < 3 * MB + 10_000


def test_caches_share_one_budget_and_drop_the_least_recently_used():
    budget = CacheBudget(3.5 * MB)
    first, second = SkiCache(budget), SkiCache(budget)
    first["a"] = _block(1)
    second["b"] = _block(1)
    first["c"] = _block(1)
    assert first["a"] is not None  # read: now the most recent
    second["d"] = _block(1)  # over 3.5 MB: the oldest unread entry (b) goes
    assert "b" not in second and {"a", "c"} <= set(first) and "d" in second
    assert budget.total_bytes <= budget.max_bytes
    assert budget.evictions == 1


def test_an_entry_larger_than_the_budget_is_not_kept():
    budget = CacheBudget(1 * MB)
    c = SkiCache(budget)
    c["big"] = _block(2)
    assert "big" not in c and budget.total_bytes == 0 and budget.refused == 1


def test_an_entry_that_grows_after_it_was_stored_is_measured_again(monkeypatch):
    """A profile model builds its 61 MB beam flexibility after it is cached."""
    monkeypatch.setattr(memory, "REMEASURE_S", 0.0)
    budget = CacheBudget(3 * MB)
    c = SkiCache(budget)
    c["old"] = _block(1)
    grows = {"parts": []}
    c["model"] = grows
    grows["parts"].append(_block(2.5))
    assert c["model"] is grows  # measured again on this read: 3.5 MB in all, the old one goes
    assert "old" not in c
    assert budget.total_bytes <= budget.max_bytes


def test_a_collected_cache_leaves_the_budget():
    import gc

    budget = CacheBudget(10 * MB)
    c = SkiCache(budget)
    c["x"] = _block(1)
    del c
    gc.collect()
    assert budget.total_bytes == 0


def test_the_service_bounds_the_ski_records_caches_by_the_setting(monkeypatch):
    """Two demo skis' profile models hold 61 MB each once their beam flexibility is built;
    a 100 MB budget keeps one of them (SKISNOW_SKI_CACHE_MB). Entries are measured again on
    every read here (in service at most once a second: a model that grew is caught by its
    next read after that)."""
    monkeypatch.setattr(memory, "REMEASURE_S", 0.0)
    from skisnow.app import service
    from skisnow.app.api.factory import create_api
    from skisnow.app.settings import Settings
    from skisnow.app.storage.common import tables_dir

    old = memory.BUDGET.max_bytes
    try:
        create_api(Settings(ski_cache_mb=100))
        assert memory.BUDGET.max_bytes == 100 * MB
        cat = service.load_catalogue(tables_dir())
        for ski in ("ski-a", "ski-b", "ski-a", "ski-b"):
            assert isinstance(cat.ski(ski).record.cache, SkiCache)
            service.contact(cat, service.ContactInputs(ski, "grind-1", 40, -160, 200, 0.5))
        held = sum(
            deep_nbytes(v) for s in ("ski-a", "ski-b") for v in cat.ski(s).record.cache.values()
        )
        assert held <= 100 * MB
        assert memory.BUDGET.total_bytes <= 100 * MB
    finally:
        memory.BUDGET.set_max_bytes(old)


@pytest.mark.parametrize("mb", [0, -1])
def test_the_setting_must_be_positive(mb):
    from pydantic import ValidationError
    from skisnow.app.settings import Settings

    with pytest.raises(ValidationError):
        Settings(ski_cache_mb=mb)


def test_a_pickled_or_copied_cache_starts_empty():
    import copy
    import pickle

    c = SkiCache(CacheBudget(10 * MB))
    c["x"] = _block(1)
    for other in (pickle.loads(pickle.dumps(c)), copy.deepcopy(c)):
        assert isinstance(other, SkiCache) and len(other) == 0


def test_concurrent_first_requests_build_a_skis_flexibility_once(monkeypatch):
    """Eight threads asking a fresh profile model for its flexibility at once build one (each
    built its own 61 MB copy before: one of two workers at 1148 MB after 100 answers)."""
    import threading
    import time

    from skisnow.app import service
    from skisnow.app.service import profiles
    from skisnow.app.storage.common import tables_dir

    built = []
    real = profiles.BeamFlexibility

    def slow(beam):
        built.append(1)
        time.sleep(0.2)
        return real(beam)

    monkeypatch.setattr(profiles, "BeamFlexibility", slow)
    rec = service.load_catalogue(tables_dir()).ski("ski-a").record
    model = profiles.ProfileModel(rec)
    assert model.beam is not None
    threads = [threading.Thread(target=lambda: model.flexibility) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(built) == 1
