"""Sections of ``docs/benchmarks.md`` for the stages ``scripts/loadtest.py`` writes
(``service``, ``service-32``, ``memory``): ``skisnow serve`` under sequential and concurrent
load, and its memory."""

from __future__ import annotations


def render_md(d: dict) -> list[str]:
    s, c = d["single"], d["concurrent"]
    return [
        f"## Service load test (`python scripts/loadtest.py`, stage `{d['stage']}`)",
        "",
        f"`skisnow serve` with {d.get('server_workers')} worker processes on this machine, "
        f"{d['distinct_inputs']} distinct seeded `/v1/contact` inputs (skis, grinds, loads, "
        "positions, moduli, porosities).",
        "",
        "| run | requests | p50 [ms] | p99 [ms] | throughput [req/s] | 5xx | answers ≠ single |",
        "|---|---|---|---|---|---|---|",
        f"| 1 client, sequential | {s['requests']} | {s['p50_ms']:.1f} | {s['p99_ms']:.1f} | "
        f"{1e3 / s['p50_ms']:.1f} (1/p50) | {s['non_200']} non-200 | — |",
        f"| {c['clients']} concurrent clients | {c['requests']} | {c['p50_ms']:.1f} | "
        f"{c['p99_ms']:.1f} | {c['throughput_rps']:.1f} | {c['server_errors_5xx']} | "
        f"{c['answers_differing_from_single_client']} |",
        "",
        f"Server memory (RSS, all workers): {c['server_rss_mb_before']:.0f} MB before the "
        f"concurrent run, {c['server_rss_mb_after']:.0f} MB after"
        + (
            f"; sampled every second during it ({c['server_rss_mb_samples']} samples): "
            f"max {c['server_rss_mb_max']:.0f} MB, drift (last tenth − first tenth, medians) "
            f"{c['server_rss_mb_drift']:+.1f} MB."
            if c.get("server_rss_mb_samples")
            else "."
        )
        + (
            " Median RSS per tenth of the run: "
            + ", ".join(f"{v:.0f}" for v in c["server_rss_mb_by_tenth"])
            + f" MB; drift over the second half {c['server_rss_mb_drift_second_half']:+.1f} MB."
            if c.get("server_rss_mb_by_tenth")
            else ""
        ),
        "",
        *(
            [
                "Median RSS by minute [MB]: "
                + ", ".join(f"{v:.0f}" for v in c["server_rss_mb_by_minute"])
                + f" ({c['wall_s'] / 60:.0f} min).",
                "",
            ]
            if len(c.get("server_rss_mb_by_minute", [])) >= 5
            else []
        ),
        *_per_process(c),
    ]


def _per_process(c: dict) -> list[str]:
    """Resident memory per server process (supervisor, workers): before the concurrent run,
    after it, and after ``idle_s`` seconds idle (issue #27 point 6)."""
    before, after = (
        c.get("server_rss_mb_per_process_before"),
        c.get("server_rss_mb_per_process_after"),
    )
    if not before or not after:
        return []
    idle = c.get("server_rss_mb_per_process_idle") or {}
    head = "| process | before [MB] | after the run [MB] |" + (
        f" after {c.get('idle_s', 0):.0f} s idle [MB] |" if idle else ""
    )
    rows = [
        "Resident memory per server process:",
        "",
        head,
        "|---|---|---|" + ("---|" if idle else ""),
    ]
    for name in sorted(set(before) | set(after)):
        cells = [before.get(name), after.get(name)] + ([idle.get(name)] if idle else [])
        rows.append(
            f"| {name} | " + " | ".join("—" if v is None else f"{v:.0f}" for v in cells) + " |"
        )
    return [*rows, ""]
