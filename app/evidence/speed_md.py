"""Section of ``docs/benchmarks.md`` for the stage ``speed`` (``scripts/speed_compare.py``;
issue #29): the CPU time of one answer against a baseline checkout, measured in pairs at the
same time, the load test with 1 and 2 workers, and the GPU backend's status."""

from __future__ import annotations

#: issue #29's targets for the default settings on 2 cores
TARGETS = {"single_p50_ms": 30.0, "throughput_rps": 60.0, "p99_ms": 400.0}


def _targets(runs: list[dict]) -> list[str]:
    """The issue's targets against this commit's run with default settings (none: no lines)."""
    mine = [r for r in runs if r.get("checkout", "this") == "this" and r.get("default_settings")]
    if not mine:
        return []
    r = mine[-1]
    ok = {
        "single_p50_ms": r["single_p50_ms"] <= TARGETS["single_p50_ms"],
        "throughput_rps": r["throughput_rps"] >= TARGETS["throughput_rps"],
        "p99_ms": r["p99_ms"] <= TARGETS["p99_ms"],
    }
    word = {True: "met", False: "**not met**"}
    return [
        "",
        f"Targets with default settings ({r['workers']} workers here): one client p50 "
        f"{r['single_p50_ms']:.1f} ms against ≤ {TARGETS['single_p50_ms']:g} ms "
        f"({word[ok['single_p50_ms']]}); 8 clients {r['throughput_rps']:.1f} req/s against "
        f"≥ {TARGETS['throughput_rps']:g} ({word[ok['throughput_rps']]}) at p99 "
        f"{r['p99_ms']:.0f} ms against ≤ {TARGETS['p99_ms']:g} ms ({word[ok['p99_ms']]}).",
    ]


def render_md(d: dict) -> list[str]:
    lines = [
        "## Speed where users wait (`python scripts/speed_compare.py`, stage `speed`, issue #29)",
        "",
        "CPU time (thread clock) of one `/v1/contact` answer with its band, computation and "
        "JSON encoding, median over 200 seeded load-test inputs, default preset; this commit "
        f"against the baseline `{d.get('baseline')}`, the two measured at the same time (one "
        "pair per row; the machine is shared, so compare within a row).",
        "",
        "| pair | baseline CPU p50 [ms] | this CPU p50 [ms] | ratio | baseline wall p50 [ms] | "
        "this wall p50 [ms] | load average (start → end) |",
        "|---|---|---|---|---|---|---|",
    ]
    for i, p in enumerate(d.get("pairs", []), 1):
        b, t = p["baseline"], p["this"]
        la = p.get("load_average", [float("nan")] * 2)
        lines.append(
            f"| {i} | {b['cpu_p50_ms']:.1f} | {t['cpu_p50_ms']:.1f} | "
            f"{t['cpu_p50_ms'] / b['cpu_p50_ms']:.2f} | {b['wall_p50_ms']:.0f} | "
            f"{t['wall_p50_ms']:.0f} | {la[0]:.1f} → {la[1]:.1f} |"
        )
    runs = d.get("loadtest") or []
    if runs:
        lines += [
            "",
            "`scripts/loadtest.py`, 8 clients, one run per checkout and worker count, one after "
            "the other (the load average says how much of the 2 cores each run had):",
            "",
            "| checkout | workers | 1 client p50 [ms] | 8 clients [req/s] | p50 [ms] | p99 [ms] "
            "| RSS before → after [MB] | 5xx | load average |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in runs:
            la = r.get("load_average", [float("nan")] * 2)
            who = f"`{d.get('baseline')}`" if r.get("checkout") == "baseline" else "this commit"
            workers = f"{r['workers']}" + (" (default)" if r.get("default_settings") else "")
            lines.append(
                f"| {who} | {workers} | {r['single_p50_ms']:.1f} | {r['throughput_rps']:.1f} | "
                f"{r['p50_ms']:.0f} | {r['p99_ms']:.0f} | {r['rss_mb_before']:.0f} → "
                f"{r['rss_mb_after']:.0f} | {r['server_errors_5xx']} | {la[0]:.1f} → {la[1]:.1f} |"
            )
        lines += _targets(runs)
    if d.get("note"):
        # the measurer's reading of this run (speed_compare.py --note / --set-note)
        lines += ["", str(d["note"])]
    lines += [
        "",
        "The micro solver on a GPU (issue #29's other part) has its own stage, `gpu-micro`.",
        "",
    ]
    return lines
