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

__all__ = ["fixed_blas_threads", "identify_with_pool", "path_pool"]

#: BLAS threads of an identification, in this process and in every worker: the beam must not
#: depend on the machine's thread count (#26: the basin of a fit turns on perturbations of 1e-5
#: relative, and a different BLAS thread count changes the rounding)
IDENTIFICATION_BLAS_THREADS = 1


def _one_thread() -> None:
    # load every BLAS first: threadpoolctl limits the libraries loaded when it is called, and
    # scipy's own OpenBLAS loads with scipy.linalg (left at 2 threads it busy-waits against the
    # other process: the two paths took 4x longer side by side than one after the other)
    import scipy.linalg
    import scipy.sparse  # noqa: F401
    from threadpoolctl import threadpool_limits

    threadpool_limits(IDENTIFICATION_BLAS_THREADS)


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


@contextmanager
def fixed_blas_threads(threads: int = IDENTIFICATION_BLAS_THREADS) -> Iterator[None]:
    """Hold every BLAS/OpenMP library of this process to ``threads`` threads for the block
    (numpy's and scipy's OpenBLAS both: scipy's is loaded first, threadpoolctl only limits the
    libraries already loaded), restored afterwards."""
    import scipy.linalg
    import scipy.sparse  # noqa: F401
    from threadpoolctl import threadpool_limits

    with threadpool_limits(threads):
        yield


def identify_with_pool(identify, *args, workers: int | None = None, **kwargs):
    """Run an identification (``identify(*args, path_map=..., **kwargs)``, e.g.
    :func:`solvers.identify.identify_beam_checked`) with its thread counts fixed: this process
    at IDENTIFICATION_BLAS_THREADS BLAS threads (the start and the held-out check run here) and
    its forward fits in :func:`path_pool`'s workers, each held to the same count. The same data
    and seed then give the same beam whatever the machine's default thread count."""
    with fixed_blas_threads(), path_pool(workers) as pmap:
        return identify(*args, path_map=pmap, **kwargs)
