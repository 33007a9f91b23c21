"""Per-ski caches bounded by bytes (issue #27 point 6, "Memory").

Every ski record keeps the objects the service builds from it (its profile model, the band's
plausible beams on the coarse grid, the flex sheet's beam draws, the page figures, the
identification report's cases) in ``record.cache``, a :class:`SkiCache`. All of them share one
process-wide :class:`CacheBudget`: when their estimated size (:func:`deep_nbytes`) passes
``max_bytes`` (setting ``SKISNOW_SKI_CACHE_MB``), the least recently used entries, of any
ski, are dropped and rebuilt on their next use. An entry larger than the whole budget is not
kept (it is used once and rebuilt each time; logged once per key).

Cached objects grow after they are stored (a profile model builds its beam flexibility, 30.5 MB
for a demo ski, on first use), so an entry's size is measured again when it is read, at most
every :data:`REMEASURE_S` (a walk of its objects: ~0.04 ms for a profile model).
"""

from __future__ import annotations

import logging
import sys
import threading
import time
import weakref
from collections import OrderedDict
from collections.abc import Iterator, MutableMapping

import numpy as np

log = logging.getLogger(__name__)

#: default budget of all per-ski caches of one process [bytes] (settings: ski_cache_mb): the
#: two demo skis, once their answers and bands are asked, held 280-360 MB (ski-b's two variant
#: alternatives add 2 × 61 MB; 30.5 MB each since the kept flexibilities are compact); at
#: 256 MB 400 load-test answers dropped and rebuilt 41-48 entries (CPU mean 41-45 ms, p99
#: 101-103 ms; at 512 MB none: 33 ms, 64-66 ms; scripts/cache_budget_check.py,
#: docs/deployment.md)
DEFAULT_MAX_BYTES = 512 * 2**20

#: an entry read after this long [s] since its last measurement is measured again
REMEASURE_S = 1.0

#: types whose instances a cached object only refers to (not owned by the cache entry):
#: not counted, not walked (a profile model refers to its record, whose cache holds it)
_NOT_OWNED: tuple[type, ...] = (type, type(sys), type(len), type(lambda: 0))


def not_owned(*types: type) -> None:
    """Register types that cached objects refer to but do not own (e.g. the ski record)."""
    global _NOT_OWNED
    _NOT_OWNED = tuple({*_NOT_OWNED, *types})


def deep_nbytes(obj, _seen: set | None = None, _depth: int = 0) -> int:
    """Estimated bytes held by ``obj``: numpy buffers, strings and bytes, and the containers
    and object attributes that hold them (each object counted once; 12 levels deep)."""
    seen = set() if _seen is None else _seen
    if id(obj) in seen or _depth > 12 or isinstance(obj, _NOT_OWNED):
        return 0
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        if obj.base is not None and isinstance(obj.base, np.ndarray):
            return deep_nbytes(obj.base, seen, _depth + 1) + 112
        return int(obj.nbytes) + 112
    if isinstance(obj, str | bytes | bytearray | int | float | complex | bool) or obj is None:
        return sys.getsizeof(obj)
    if isinstance(obj, SkiCache):
        return 0
    size = sys.getsizeof(obj, 64)
    if isinstance(obj, dict):
        return size + sum(
            deep_nbytes(k, seen, _depth + 1) + deep_nbytes(v, seen, _depth + 1)
            for k, v in obj.items()
        )
    if isinstance(obj, list | tuple | set | frozenset):
        return size + sum(deep_nbytes(v, seen, _depth + 1) for v in obj)
    attrs = getattr(obj, "__dict__", None)
    if attrs is not None:
        size += deep_nbytes(attrs, seen, _depth + 1)
    for slot in getattr(type(obj), "__slots__", ()):
        if isinstance(slot, str) and hasattr(obj, slot):
            size += deep_nbytes(getattr(obj, slot), seen, _depth + 1)
    return size


class CacheBudget:
    """One byte budget over many :class:`SkiCache` objects, least recently used first out."""

    def __init__(self, max_bytes: int = DEFAULT_MAX_BYTES) -> None:
        self.max_bytes = int(max_bytes)
        self._lock = threading.RLock()
        #: (id of the cache, key) -> (weak reference to the cache, bytes, when measured)
        self._entries: OrderedDict[tuple[int, object], tuple] = OrderedDict()
        self.total_bytes = 0
        #: entries dropped to stay within the budget, and entries too large to keep
        self.evictions = 0
        self.refused = 0
        self._warned: set = set()

    def set_max_bytes(self, max_bytes: int) -> None:
        with self._lock:
            self.max_bytes = int(max_bytes)
            self._evict()

    def _add(self, cache: SkiCache, key, nbytes: int) -> bool:
        with self._lock:
            self._drop(cache, key)
            if nbytes > self.max_bytes:
                self.refused += 1
                if key not in self._warned:
                    self._warned.add(key)
                    log.warning(
                        "ski cache entry %r (%.1f MB) is larger than the whole budget "
                        "(SKISNOW_SKI_CACHE_MB = %.0f MB): not kept, rebuilt on every use",
                        key,
                        nbytes / 2**20,
                        self.max_bytes / 2**20,
                    )
                return False
            self._entries[id(cache), key] = (weakref.ref(cache), nbytes, time.monotonic())
            self.total_bytes += nbytes
            self._evict(keep=(id(cache), key))
            return True

    def _drop(self, cache: SkiCache, key) -> None:
        with self._lock:
            hit = self._entries.pop((id(cache), key), None)
            if hit is not None:
                self.total_bytes -= hit[1]

    def _touch(self, cache: SkiCache, key, value) -> None:
        """A read: the entry becomes the most recent; measured again if its size is older
        than :data:`REMEASURE_S` (it may have grown), then the budget is enforced."""
        with self._lock:
            hit = self._entries.get((id(cache), key))
            if hit is None:
                return
            self._entries.move_to_end((id(cache), key))
            ref, nbytes, measured = hit
            now = time.monotonic()
            if now - measured < REMEASURE_S:
                return
            new = deep_nbytes(value)
            self._entries[id(cache), key] = (ref, new, now)
            self.total_bytes += new - nbytes
            if new > self.max_bytes:
                self._drop(cache, key)
                dict.pop(cache._data, key, None)
                self.refused += 1
            else:
                self._evict(keep=(id(cache), key))

    def _forget(self, cache_id: int) -> None:
        """A cache was garbage-collected: its entries leave the budget."""
        with self._lock:
            for k in [k for k in self._entries if k[0] == cache_id]:
                self.total_bytes -= self._entries.pop(k)[1]

    def _evict(self, keep=None) -> None:
        while self.total_bytes > self.max_bytes and self._entries:
            (cid, key), (ref, nbytes, _) = next(iter(self._entries.items()))
            if (cid, key) == keep:  # the newest entry fits alone; everything older went
                break
            del self._entries[cid, key]
            self.total_bytes -= nbytes
            self.evictions += 1
            cache = ref()
            if cache is not None:
                dict.pop(cache._data, key, None)


#: the budget every ski record's cache uses (the service sets its size from the settings)
BUDGET = CacheBudget()


class SkiCache(MutableMapping):
    """A dict of per-process objects built from one ski record, within :data:`BUDGET`."""

    def __init__(self, budget: CacheBudget | None = None) -> None:
        self._budget = budget or BUDGET
        self._data: dict = {}
        weakref.finalize(self, self._budget._forget, id(self))

    def __getitem__(self, key):
        value = self._data[key]
        self._budget._touch(self, key, value)
        return value

    def __setitem__(self, key, value) -> None:
        if self._budget._add(self, key, deep_nbytes(value)):
            self._data[key] = value
        else:
            self._data.pop(key, None)

    def __delitem__(self, key) -> None:
        del self._data[key]
        self._budget._drop(self, key)

    def __iter__(self) -> Iterator:
        return iter(list(self._data))

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return f"SkiCache({sorted(map(str, self._data))})"

    def __reduce__(self):
        # a copy or another process starts empty (the objects are rebuilt there on use): the
        # cache is per process, and its budget holds a lock
        return (SkiCache, ())
