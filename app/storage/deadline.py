"""A time bound on a synchronous check, kept by the check itself (issue #27).

An upload's checks (the camber CSV's rows, a grind's height map) run in a worker thread of the
service (FastAPI runs the synchronous routes in its thread pool), never on the event loop. Two
things keep them from holding the service: :func:`checkpoint`, called every few dozen rows,
hands the interpreter lock over (``time.sleep(0)``), so the event loop's thread is not left
waiting a whole switch interval (5 ms) for it at every step of another request (``/healthz``
took 1.2 s during a camber check); and it raises :class:`~solvers.errors.InputError` (422)
once the bound that :func:`deadline` set for this thread has passed, so no check holds a
thread longer than ``Settings.max_check_s``. A step that does not call it (a file format's
reader in compiled code) is bounded by :func:`run_bounded`, which runs the check in a thread of
its own and answers 422 when it has not finished in time (the thread runs on to the end of that
step, and its result is dropped; :data:`CHECK_THREADS` of them per process at most, so such
checks queue rather than pile up).
"""

from __future__ import annotations

import contextlib
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from concurrent.futures import TimeoutError as FutureTimeout

from skisnow.solvers.errors import InputError

__all__ = ["CHECK_THREADS", "checkpoint", "deadline", "run_bounded"]

#: threads per process that run bounded checks (:func:`run_bounded`)
CHECK_THREADS = 4
#: time a bounded check gets past its bound to stop at its own next checkpoint [s]
_GRACE_S = 1.0
_local = threading.local()
_pool: ThreadPoolExecutor | None = None
_pool_lock = threading.Lock()


@contextlib.contextmanager
def deadline(seconds: float | None, what: str = "the check of this upload"):
    """Bound the checks of this thread to ``seconds`` from now (None: no bound) while the
    block runs; ``what`` names the check in the error."""
    previous = getattr(_local, "bound", None)
    _local.bound = None if seconds is None else (time.monotonic() + seconds, seconds, what)
    try:
        yield
    finally:
        _local.bound = previous


def _timeout_error(seconds: float, what: str) -> InputError:
    return InputError(
        f"{what} took longer than {seconds:g} s, the bound of an upload's check "
        "(max_check_s, SKISNOW_MAX_CHECK_S); send a smaller file (one ski's or one grind's "
        "measurements)"
    )


def run_bounded(seconds: float | None, what: str, fn, /, *args, **kwargs):
    """``fn(*args, **kwargs)`` under :func:`deadline` ``(seconds, what)``, in a check thread;
    :class:`InputError` when it has not returned ``seconds`` (+ 1 s of grace) after it was
    submitted, whether or not it reached a :func:`checkpoint`. ``seconds=None``: called here,
    unbounded."""
    global _pool
    if seconds is None:
        return fn(*args, **kwargs)

    def bounded():
        with deadline(seconds, what):
            return fn(*args, **kwargs)

    with _pool_lock:
        if _pool is None:
            _pool = ThreadPoolExecutor(CHECK_THREADS, thread_name_prefix="skisnow-check")
    future = _pool.submit(bounded)
    try:
        return future.result(timeout=seconds + _GRACE_S)
    except FutureTimeout:
        future.cancel()
        raise _timeout_error(seconds, what) from None


def checkpoint() -> None:
    """Let other threads run, and raise :class:`InputError` when this thread's
    :func:`deadline` has passed."""
    time.sleep(0)
    bound = getattr(_local, "bound", None)
    if bound is not None and time.monotonic() > bound[0]:
        raise _timeout_error(bound[1], bound[2])
