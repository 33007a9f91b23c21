"""CPU time of one `/v1/contact` answer, this checkout against a baseline checkout, measured in
pairs at the same time (issue #29: the machine is shared, so only ratios measured together
count), and the load test's throughput of both checkouts with the given server workers (0: each
checkout's default settings), one after the other. Writes the ``speed``
stage of docs/benchmarks.md (:mod:`app.evidence.speed_md`).

Each pair runs two processes at once, one per checkout: each answers the same 200 seeded
load-test inputs (``scripts/loadtest.py``'s draw) after 5 warm-up answers, timing the
computation and the route's JSON encoding with the thread's CPU clock (``time.thread_time``;
less sensitive to the other jobs on the machine than wall time, not immune to them).

    git archive BASE | tar -x -C /tmp/base
    python scripts/speed_compare.py --baseline /tmp/base --pairs 3 --loadtest-workers 1 0
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

#: one checkout's measurement (run with that checkout's ``skisnow`` first on the path)
MEASURE = r"""
import json, sys, time
sys.path.insert(0, sys.argv[1])
import numpy as np
from loadtest import draw_requests
from skisnow.app import service
from skisnow.app.api.models import ContactBody
from skisnow.app.storage.common import tables_dir
try:
    from skisnow.app.api.contact import AnswerResponse as R
except ImportError:
    from fastapi.responses import JSONResponse as R
cat = service.load_catalogue(tables_dir())
reqs = draw_requests(200, 2026, ["ski-a", "ski-b"], ["grind-1", "grind-2"])
def answer(r):
    return R(service.contact(cat, service.ContactInputs(**ContactBody(**r).model_dump())))
for r in reqs[:5]:
    answer(r)
cpu, wall = [], []
for r in reqs:
    t, w = time.thread_time(), time.perf_counter()
    answer(r)
    cpu.append(time.thread_time() - t)
    wall.append(time.perf_counter() - w)
print(json.dumps({"code": service.__file__, "cpu_p50_ms": float(np.median(cpu)) * 1e3,
                  "cpu_mean_ms": float(np.mean(cpu)) * 1e3,
                  "wall_p50_ms": float(np.median(wall)) * 1e3}))
"""


def _shim(baseline: Path, where: Path) -> Path:
    """A folder whose ``skisnow`` package is the baseline checkout (PYTHONPATH goes before
    the editable install of this one)."""
    pkg = where / "skisnow"
    pkg.mkdir(parents=True)
    for name in ("app", "solvers", "tables"):
        (pkg / name).symlink_to(baseline / name)
    return where


def _load() -> float:
    return float(Path("/proc/loadavg").read_text().split()[0])


def _loadtest(checkout: str, workers: int, env: dict, requests: int) -> dict:
    """One ``scripts/loadtest.py`` run (8 clients) against ``checkout``'s ``skisnow serve``
    (``env`` puts it first on the path) with ``workers`` processes (0: the checkout's default
    settings)."""
    with tempfile.TemporaryDirectory() as tmp:
        load0 = _load()
        subprocess.run(
            [
                sys.executable,
                str(REPO / "scripts" / "loadtest.py"),
                *(["--workers", str(workers)] if workers else []),
                "--clients",
                "8",
                "--requests",
                str(requests),
                "--stage",
                "speed-loadtest-tmp",
            ],
            check=False,
            env=env,
            stdout=open(Path(tmp) / "out.json", "w"),
        )
        d = json.loads((Path(tmp) / "out.json").read_text())
    c = d["concurrent"]
    return {
        "checkout": checkout,
        "workers": d.get("server_workers") or workers,
        "default_settings": not workers,
        "single_p50_ms": d["single"]["p50_ms"],
        "clients": c["clients"],
        "throughput_rps": c["throughput_rps"],
        "p50_ms": c["p50_ms"],
        "p99_ms": c["p99_ms"],
        "rss_mb_before": c["server_rss_mb_before"],
        "rss_mb_after": c["server_rss_mb_after"],
        "server_errors_5xx": c["server_errors_5xx"],
        "load_average": [load0, _load()],
    }


def _set_note(note: str, docs_dir: Path | None = None) -> int:
    """The stored run's note replaced (atomically; the measurement and its provenance kept),
    and docs/benchmarks.md rewritten."""
    from skisnow.app.evidence.writer import write_benchmarks_md
    from skisnow.app.storage.common import atomic_path

    docs_dir = REPO / "docs" if docs_dir is None else docs_dir
    path = docs_dir / "bench" / "speed.json"
    d = json.loads(path.read_text(encoding="utf-8"))
    d["note"] = note
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(d, indent=1, default=float), encoding="utf-8")
    write_benchmarks_md(docs_dir)
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--baseline", type=Path, help="checkout of the baseline (to measure)")
    ap.add_argument("--baseline-name", default=None, help="its commit, for the record")
    ap.add_argument("--pairs", type=int, default=3)
    ap.add_argument(
        "--loadtest-workers",
        type=int,
        nargs="*",
        default=[],
        help="server workers of the load tests, each run on both checkouts (0: default settings)",
    )
    ap.add_argument("--loadtest-requests", type=int, default=500)
    ap.add_argument("--note", default=None, help="what the run shows, printed under its tables")
    ap.add_argument(
        "--set-note",
        default=None,
        help="do not measure: set the note of the stored run (docs/bench/speed.json, its "
        "measurement and provenance kept) and rewrite docs/benchmarks.md",
    )
    args = ap.parse_args(argv)
    if args.set_note is not None:
        return _set_note(args.set_note)
    if args.baseline is None:
        ap.error("--baseline is required to measure")
    pairs = []
    with tempfile.TemporaryDirectory() as shim_tmp:
        shim = _shim(args.baseline.resolve(), Path(shim_tmp) / "base")
        env_new = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        env_base = {**env_new, "PYTHONPATH": str(shim)}
        cmd = [sys.executable, "-c", MEASURE, str(REPO / "scripts")]
        for _ in range(args.pairs):
            load0 = _load()
            procs = {
                name: subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, text=True)
                for name, env in (("baseline", env_base), ("this", env_new))
            }
            got = {
                name: json.loads(p.communicate()[0].splitlines()[-1]) for name, p in procs.items()
            }
            got["load_average"] = [load0, _load()]
            pairs.append(got)
            print(json.dumps(got))
        runs = []
        for w in args.loadtest_workers:
            for name, env in (("baseline", env_base), ("this", env_new)):
                runs.append(_loadtest(name, w, env, args.loadtest_requests))
                print(json.dumps(runs[-1]))
    for stale in (REPO / "docs" / "bench").glob("speed-loadtest-tmp.json"):
        stale.unlink()
    from skisnow.app.evidence.writer import write_stage

    write_stage(
        "speed",
        {
            "baseline": args.baseline_name or str(args.baseline),
            "pairs": pairs,
            "loadtest": runs,
            "measured_at": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
            **({"note": args.note} if args.note else {}),
        },
        None,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
