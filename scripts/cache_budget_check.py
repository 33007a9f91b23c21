"""How the per-ski cache budget (``SKISNOW_SKI_CACHE_MB``, :mod:`app.storage.memory`) serves
the load test's answers: the shipped demo skis asked the load test's seeded inputs
(``scripts/loadtest.py``'s draw) in this process, one after the other, with the given budget;
prints the answers' CPU time (median, mean, 99th percentile), the entries the budget
dropped (each rebuilt on its next use: a beam flexibility costs ~40-60 ms), what the caches
hold at the end and the process's peak resident memory.

    python scripts/cache_budget_check.py --budget-mb 256
    python scripts/cache_budget_check.py --budget-mb 1024   # nothing dropped: the working set
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))

from loadtest import draw_requests  # noqa: E402
from skisnow.app import service  # noqa: E402
from skisnow.app.api.models import ContactBody  # noqa: E402
from skisnow.app.storage import memory  # noqa: E402
from skisnow.app.storage.common import tables_dir  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--budget-mb", type=float, default=memory.DEFAULT_MAX_BYTES / 2**20)
    ap.add_argument("--requests", type=int, default=200)
    ap.add_argument("--seed", type=int, default=2026)
    args = ap.parse_args(argv)
    memory.BUDGET.set_max_bytes(int(args.budget_mb * 2**20))
    cat = service.load_catalogue(tables_dir())
    reqs = draw_requests(args.requests, args.seed, ["ski-a", "ski-b"], ["grind-1", "grind-2"])
    cpu = []
    for r in reqs:
        t0 = time.thread_time()
        service.contact(cat, service.ContactInputs(**ContactBody(**r).model_dump()))
        cpu.append(time.thread_time() - t0)
    ms = np.asarray(cpu) * 1e3
    print(
        json.dumps(
            {
                "budget_mb": args.budget_mb,
                "answers": len(ms),
                "cpu_p50_ms": round(float(np.median(ms)), 1),
                "cpu_mean_ms": round(float(np.mean(ms)), 1),
                "cpu_p99_ms": round(float(np.percentile(ms, 99)), 1),
                "cached_mb": round(memory.BUDGET.total_bytes / 2**20, 1),
                "evictions": memory.BUDGET.evictions,
                # ru_maxrss: KiB on Linux
                "max_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024),
            }
        )
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
