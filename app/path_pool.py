"""Worker processes for the beam identification's forward paths (``identify-ski`` and the ski
job; :func:`solvers.identify.identify_beam`, ``path_map``).

The identification fits the device model along two independent paths from one start and keeps
the better (docs/camber-identification.md). Each path is mostly single-threaded Python and small
linear algebra, so on two cores the two run side by side in two processes, each held to one
BLAS thread (no oversubscription), and the identification takes the longer path's time
instead of the sum.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager

__all__ = ["path_pool"]


def _one_thread() -> None:
    # load every BLAS first: threadpoolctl limits the libraries loaded when it is called, and
    # scipy's own OpenBLAS loads with scipy.linalg (left at 2 threads it busy-waits against the
    # other process: the two paths took 4x longer side by side than one after the other)
    import scipy.linalg
    import scipy.sparse  # noqa: F401
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


@contextmanager
def path_pool(workers: int | None = None) -> Iterator:
    """A ``map`` over ``workers`` fresh processes (default: the usable cores, at most 2), or
    ``None`` (run in this process) when fewer than 2 cores are usable.

    Processes are spawned, not forked: the caller may be a server with threads."""
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    n = min(2, usable or 1) if workers is None else int(workers)
    if n < 2:
        yield None
        return
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_one_thread) as pool:
        yield pool.map
