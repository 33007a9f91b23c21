"""A time bound on a synchronous check, kept by the check itself (issue #27).

An upload's checks (the camber CSV's rows, a grind's height map) run in a worker thread of the
service (FastAPI runs the synchronous routes in its thread pool), never on the event loop. Two
things keep them from holding the service: :func:`checkpoint`, called every few dozen rows,
hands the interpreter lock over (``time.sleep(0)``), so the event loop's thread is not left
waiting a whole switch interval (5 ms) for it at every step of another request (``/healthz``
took 1.2 s during a camber check); and it raises :class:`~solvers.errors.InputError` (422)
once the bound that :func:`deadline` set for this thread has passed, so no check holds a
thread longer than ``Settings.max_check_s``.
"""

from __future__ import annotations

import contextlib
import threading
import time

from skisnow.solvers.errors import InputError

__all__ = ["checkpoint", "deadline"]

_local = threading.local()


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


def checkpoint() -> None:
    """Let other threads run, and raise :class:`InputError` when this thread's
    :func:`deadline` has passed."""
    time.sleep(0)
    bound = getattr(_local, "bound", None)
    if bound is not None and time.monotonic() > bound[0]:
        raise InputError(
            f"{bound[2]} took longer than {bound[1]:g} s, the bound of an upload's check "
            "(max_check_s, SKISNOW_MAX_CHECK_S); send a smaller file (one ski's or one grind's "
            "measurements)"
        )
