"""One CPU-bound answer at a time per process (issue #29).

The routes run in a thread pool, so with 8 clients a worker computes 8 answers in 8 threads.
Under the GIL they then cost far more than one after the other: the solvers' numpy steps are
short (a few hundred pixels), each releases and re-takes the GIL, and the threads spend their
time handing it over. Measured on the 2-core benchmark machine (``scripts/loadtest.py``,
8 clients, one worker, ski-a/b/c on grind-1/2):

- without the gate: 47 ms of CPU per answer, 24.6 answers/s, p99 559 ms;
- with it: 21 ms of CPU per answer (a single client's 18 ms plus the HTTP work), 52.3 answers/s,
  p99 174 ms.

Gated: :func:`app.service.contact` and the flex sheet, the answers users wait for. A flex pair or
ranking (up to 16 cells) and a compare pass the gate once per sheet or answer, so that other
answers take their turn between its cells instead of waiting for all of them. A ski's model
report and page figures (longer, rarer, cached per ski) are not gated, so that an answer never
queues behind one.

The gate is re-entrant (a gated computation may call another) and holds nothing but the order of
the computations: the answers are the same. Waiting
requests keep their place in the server's thread pool; the job runner's threads are not gated.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from typing import TypeVar

__all__ = ["gated"]

_GATE = threading.RLock()

F = TypeVar("F", bound=Callable)


def gated(fn: F) -> F:
    """``fn`` run alone among the process's gated computations (the process's one
    re-entrant lock)."""

    @functools.wraps(fn)
    def run(*args, **kwargs):
        with _GATE:
            return fn(*args, **kwargs)

    return run  # type: ignore[return-value]
