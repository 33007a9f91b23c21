"""Load test of ``skisnow serve`` on this machine (loopback only).

Starts ``skisnow serve`` on a free 127.0.0.1 port (unless ``--url`` is given), draws seeded,
varied ``/v1/contact`` requests (loads, positions, moduli, porosities, skis, grinds), then

1. one client sends each request once, sequentially (latency percentiles);
2. ``--clients`` concurrent clients send ``--requests`` requests drawn from the same set
   (throughput, percentiles, errors), and every answer is compared with the single-client
   answer for the same input (metrics, apparent contact and distributions must be identical).

Results go to ``docs/bench/service.json`` and the section of ``docs/benchmarks.md``.
Bounded in count and time; it stops by itself.

    python scripts/loadtest.py --clients 8 --requests 1000
    python scripts/loadtest.py --clients 32 --duration-s 3600 --stage memory  # RSS by minute
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def draw_requests(n: int, seed: int, skis: list[str], grinds: list[str]) -> list[dict]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        out.append(
            {
                "ski": str(rng.choice(skis)),
                "grind": str(rng.choice(grinds)),
                "load_kg": round(float(rng.uniform(20, 80)), 2),
                "load_position_mm": round(float(rng.uniform(-250, 50)), 1),
                "snow_modulus_mpa": round(float(rng.uniform(50, 400)), 1),
                "porosity": round(float(rng.uniform(0.3, 0.7)), 3),
            }
        )
    return out


def answer_key(d: dict) -> str:
    return json.dumps({k: d[k] for k in ("metrics", "apparent", "distributions")}, sort_keys=True)


def percentile(xs: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(xs), q))


def wait_ready(url: str, timeout_s: float = 120) -> None:
    t0 = time.time()
    while time.time() - t0 < timeout_s:
        try:
            if httpx.get(f"{url}/readyz", timeout=2).status_code == 200:
                return
        except httpx.HTTPError:
            pass
        time.sleep(0.5)
    raise SystemExit(f"server at {url} not ready after {timeout_s} s")


def rss_mb(pid: int) -> float:
    try:
        import psutil

        p = psutil.Process(pid)
        return sum(c.memory_info().rss for c in [p, *p.children(recursive=True)]) / 1e6
    except Exception:
        return float("nan")


def rss_per_process_mb(pid: int) -> dict[str, float]:
    """Resident memory [MB] of the server's processes: the supervisor (with several workers)
    and each worker, keyed "pid (role)"."""
    try:
        import psutil

        p = psutil.Process(pid)
        procs = [p, *p.children(recursive=True)]
        out = {}
        for q in procs:
            role = "worker" if (q is not p or len(procs) == 1) else "supervisor"
            try:
                if (
                    role == "worker"
                    and "multiprocessing" in " ".join(q.cmdline())
                    and ("resource_tracker" in " ".join(q.cmdline()))
                ):
                    role = "helper"
                out[f"{q.pid} ({role})"] = q.memory_info().rss / 1e6
            except psutil.Error:
                continue
        return out
    except Exception:
        return {}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--url", default=None, help="existing server (default: start one)")
    ap.add_argument(
        "--workers",
        type=int,
        default=None,
        help="server workers if started here (default: the service's default, "
        "app.settings.default_workers)",
    )
    ap.add_argument("--clients", type=int, default=8)
    ap.add_argument("--requests", type=int, default=1000, help="requests of the concurrent run")
    ap.add_argument("--distinct", type=int, default=200, help="distinct seeded inputs")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument(
        "--duration-s",
        type=float,
        default=0,
        help="run the concurrent phase for this long instead of a fixed number of requests",
    )
    ap.add_argument("--stage", default="service", help="name of the docs/bench entry")
    ap.add_argument(
        "--idle-s",
        type=float,
        default=0,
        help="after the concurrent run, leave the server idle this long and sample its memory",
    )
    args = ap.parse_args(argv)

    proc = None
    url = args.url
    if url is None:
        port = free_port()
        url = f"http://127.0.0.1:{port}"
        env = {k: v for k, v in os.environ.items() if k != "SKISNOW_WORKERS"}
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "skisnow.app.cli",
                "serve",
                "--port",
                str(port),
                *(["--workers", str(args.workers)] if args.workers else []),
            ],
            cwd=REPO,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
    try:
        wait_ready(url)
        ready = httpx.get(f"{url}/readyz").json()
        reqs = draw_requests(args.distinct, args.seed, ready["skis"], ready["grinds"])
        client = httpx.Client(timeout=30)
        # warm-up (JIT, caches), not measured
        for r in reqs[:5]:
            client.post(f"{url}/v1/contact", json=r)
        single_lat, reference, errors_single = [], {}, 0
        for i, r in enumerate(reqs):
            t0 = time.perf_counter()
            resp = client.post(f"{url}/v1/contact", json=r)
            single_lat.append((time.perf_counter() - t0) * 1e3)
            if resp.status_code == 200:
                reference[i] = answer_key(resp.json())
            else:
                errors_single += 1
                reference[i] = f"status {resp.status_code}: {resp.text[:200]}"
        mem_before = rss_mb(proc.pid) if proc else float("nan")
        per_process_before = rss_per_process_mb(proc.pid) if proc else {}

        rng = np.random.default_rng(args.seed + 1)
        order = rng.integers(0, len(reqs), size=10**7 if args.duration_s else args.requests)
        lat, mismatches, errors, done = [], 0, 0, 0
        deadline = time.time() + args.duration_s if args.duration_s else None

        def worker(k: int) -> tuple[list[float], int, int, int]:
            c = httpx.Client(timeout=30)
            my_lat, my_mis, my_err, my_n = [], 0, 0, 0
            for idx in order[k :: args.clients]:
                if deadline and time.time() > deadline:
                    break
                t0 = time.perf_counter()
                resp = c.post(f"{url}/v1/contact", json=reqs[idx])
                my_lat.append((time.perf_counter() - t0) * 1e3)
                my_n += 1
                if resp.status_code >= 500:
                    my_err += 1
                key = (
                    answer_key(resp.json())
                    if resp.status_code == 200
                    else f"status {resp.status_code}: {resp.text[:200]}"
                )
                if key != reference[int(idx)]:
                    my_mis += 1
            return my_lat, my_mis, my_err, my_n

        samples: list[float] = []
        sampling = threading.Event()

        def sample_memory() -> None:
            while not sampling.wait(1.0):
                if proc is not None:
                    samples.append(rss_mb(proc.pid))

        sampler = threading.Thread(target=sample_memory, daemon=True)
        sampler.start()
        t0 = time.perf_counter()
        with cf.ThreadPoolExecutor(args.clients) as ex:
            for my_lat, my_mis, my_err, my_n in ex.map(worker, range(args.clients)):
                lat += my_lat
                mismatches += my_mis
                errors += my_err
                done += my_n
        wall = time.perf_counter() - t0
        sampling.set()
        sampler.join()
        mem_after = rss_mb(proc.pid) if proc else float("nan")
        per_process_after = rss_per_process_mb(proc.pid) if proc else {}
        idle = []
        if args.idle_s and proc is not None:
            t_idle = time.time()
            while time.time() - t_idle < args.idle_s:
                time.sleep(1.0)
                idle.append(rss_mb(proc.pid))
        per_process_idle = rss_per_process_mb(proc.pid) if (proc and idle) else {}
        tenth = max(len(samples) // 10, 1)
        result = {
            "url_started_here": proc is not None,
            "server_workers": (sum(k.endswith("(worker)") for k in per_process_before) or None)
            if proc
            else None,
            "server_workers_default": proc is not None and args.workers is None,
            "distinct_inputs": len(reqs),
            "single": {
                "requests": len(reqs),
                "non_200": errors_single,
                "p50_ms": percentile(single_lat, 50),
                "p90_ms": percentile(single_lat, 90),
                "p99_ms": percentile(single_lat, 99),
            },
            "concurrent": {
                "clients": args.clients,
                "requests": done,
                "wall_s": wall,
                "throughput_rps": done / wall,
                "p50_ms": percentile(lat, 50),
                "p99_ms": percentile(lat, 99),
                "server_errors_5xx": errors,
                "answers_differing_from_single_client": mismatches,
                "server_rss_mb_before": mem_before,
                "server_rss_mb_after": mem_after,
                # per process (supervisor, workers) before, after and after the idle time
                "server_rss_mb_per_process_before": per_process_before,
                "server_rss_mb_per_process_after": per_process_after,
                "server_rss_mb_per_process_idle": per_process_idle,
                "idle_s": args.idle_s,
                "server_rss_mb_idle_end": idle[-1] if idle else float("nan"),
                # memory drift during the run: median of the last tenth of the 1 s samples
                # against the first tenth (flat memory: close to 0)
                "server_rss_mb_samples": len(samples),
                "server_rss_mb_max": max(samples) if samples else float("nan"),
                "server_rss_mb_drift": (
                    float(np.median(samples[-tenth:]) - np.median(samples[:tenth]))
                    if samples
                    else float("nan")
                ),
                # median of each tenth of the run: warm-up growth that levels off vs a leak
                "server_rss_mb_by_tenth": [
                    float(np.median(part)) for part in np.array_split(samples, 10) if len(part)
                ],
                # median of each minute (1 s samples): the memory run of issue #15
                "server_rss_mb_by_minute": [
                    float(np.median(samples[i : i + 60])) for i in range(0, len(samples), 60)
                ],
                # drift over the second half only (after warm-up): ~0 when memory is flat
                "server_rss_mb_drift_second_half": (
                    float(
                        np.median(samples[-tenth:])
                        - np.median(samples[len(samples) // 2 :][:tenth])
                    )
                    if len(samples) >= 20
                    else float("nan")
                ),
            },
        }
        print(json.dumps(result, indent=1))
        from skisnow.app.evidence.writer import write_stage

        write_stage(args.stage, result, None)
        ok = errors == 0 and mismatches == 0
        return 0 if ok else 1
    finally:
        if proc is not None:
            proc.terminate()
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()


if __name__ == "__main__":
    sys.exit(main())
