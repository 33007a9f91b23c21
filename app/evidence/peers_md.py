"""The ``micro-peers`` section of ``docs/benchmarks.md`` and its chart (work-precision curves),
from ``docs/bench/micro-peers.json`` (:mod:`app.evidence.peers` measures them)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from skisnow.app.evidence.peers import THREAD_ENV, equal_error_table

ERROR_KEYS = (
    ("err_contact_fraction", "a_r"),
    ("err_mean_gap", "mean gap"),
    ("err_pressure_l2", "pressure L2"),
)


def plot_work_precision(data: dict, path: Path) -> None:
    """One panel per (size, error measure): median time against relative error."""
    from matplotlib.figure import Figure
    from skisnow.app.storage.common import atomic_path

    blocks = data["sizes"]
    fig = Figure(figsize=(4 * len(ERROR_KEYS), 3.4 * len(blocks)))
    for i, block in enumerate(blocks):
        for j, (key, label) in enumerate(ERROR_KEYS):
            ax = fig.add_subplot(len(blocks), len(ERROR_KEYS), i * len(ERROR_KEYS) + j + 1)
            for s, rep in block["solvers"].items():
                pts = rep["points"]
                ax.loglog(
                    [max(p[key], 1e-16) for p in pts],
                    [p["median_time_s"] for p in pts],
                    "o-",
                    label=s,
                )
            ax.invert_xaxis()
            ax.set_xlabel(f"relative error in {label} [-]")
            ax.set_ylabel("median time [s]")
            ax.set_title(f"{block['n']}², P = {data['pressure_pa'] / 1e6:g} MPa", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)


def render_md(d: dict) -> list[str]:
    lines = [
        "## Micro scale: work-precision against peers (`skisnow bench micro --work-precision`)",
        "",
        f"{d['surface']}; E* = {d['e_star_pa'] / 1e6:g} MPa, P = {d['pressure_pa'] / 1e6:g} MPa. "
        f"Every solver in its own fresh process with {d['threads']} threads pinned "
        f"({', '.join(THREAD_ENV)}; our FFT workers the same), one untimed warm-up per "
        f"tolerance, median of {d['repeats']} repeats. Timer: {d['timer']}. Errors are relative "
        f"to one common reference ({d['reference']}): contact area fraction a_r, mean gap, "
        f"pressure field (L2). The machine ({d.get('machine', {}).get('cpus', '?')} cores) was "
        "shared with other jobs while this ran: "
        "compare ratios within one size, not absolute times across runs.",
        "",
    ]
    if d.get("missing"):
        lines += [f"Not installed, so not measured: {', '.join(d['missing'])}.", ""]
    lines += ["Configurations (each as its own documentation's examples call it):", ""]
    for s, c in d["config"].items():
        lines.append(f"- **{s}** — `{c}`; swept: {d['tolerances'][s]['parameter']}.")
    lines.append("")
    for block in d["sizes"]:
        n = block["n"]
        ref = block["reference"]
        lines += [
            f"### {n}²",
            "",
            f"Reference: a_r = {ref['contact_fraction']:.6g}, mean gap "
            f"{ref['mean_gap_m'] * 1e6:.6g} µm, {ref['iterations']} iterations, "
            f"converged {ref['converged']}.",
            "",
            "| solver | tolerance | median [s] | iterations | converged | err a_r | "
            "err mean gap | err pressure L2 |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for s, rep in block["solvers"].items():
            for p in rep["points"]:
                lines.append(
                    f"| {s} | {p['tol']:g} | {p['median_time_s']:.3g} | {p['iterations']} | "
                    f"{p['converged']} | {p['err_contact_fraction']:.1e} | "
                    f"{p['err_mean_gap']:.1e} | {p['err_pressure_l2']:.1e} |"
                )
        lines += [
            "",
            "Time to reach an equal error (log-log interpolation between the two tolerances "
            "that bracket it; — when no converged point reaches it) and the ratio to skisnow. "
            "A solver whose loosest point is already below a target is timed at that loosest "
            "point, so at loose targets a ratio says what its tolerance sweep offers, not what "
            "it could do when stopped earlier:",
            "",
            "| error | target | " + " | ".join(block["solvers"]) + " |",
            "|---|---|" + "---|" * len(block["solvers"]),
        ]
        for row in equal_error_table(block["solvers"]):  # from the stored points
            ours = row["time_s"].get("skisnow", float("nan"))
            cells = []
            for s in block["solvers"]:
                t = row["time_s"][s]
                if not np.isfinite(t):
                    cells.append("—")
                elif s == "skisnow" or not np.isfinite(ours):
                    cells.append(f"{t:.3g} s")
                else:
                    cells.append(f"{t:.3g} s ({t / ours:.1f}×)")
            lines.append(f"| {row['error']} | {row['target']:g} | " + " | ".join(cells) + " |")
        lines += [
            "",
            "In-process against whole-process time (the whole process: interpreter start, "
            "imports, surface, one cold solve, exit; median of fresh processes; at each "
            "solver's second-tightest tolerance):",
            "",
            "| solver | tolerance | in-process median (warm) [s] | cold solve in a fresh process "
            "[s] | whole process [s] | threads seen | versions |",
            "|---|---|---|---|---|---|---|",
        ]
        for s, rep in block["solvers"].items():
            if "whole_process" not in rep:
                continue
            w = rep["whole_process"]
            warm = next(p["median_time_s"] for p in rep["points"] if p["tol"] == w["tol"])
            pools = rep["threads"].get("threadpools")
            seen = (
                ", ".join(f"{q['internal_api']}={q['num_threads']}" for q in pools)
                if isinstance(pools, list)
                else str(pools)
            )
            ver = ", ".join(f"{k} {v}" for k, v in rep["versions"].items())
            lines.append(
                f"| {s} | {w['tol']:g} | {warm:.3g} | {w['cold_solve_in_process_median_s']:.3g} "
                f"| {w['process_median_s']:.3g} | {seen or 'none loaded'} | {ver} |"
            )
        lines.append("")
    if "aspher_probe" in d:
        pr = d["aspher_probe"]
        lines += [
            f"### ASPHER: the 67 against 34 ms per iteration (issue #13), {pr['n']}², tol 1e-8",
            "",
            "| condition | first call [s] | median after warm-up [s] | iterations | "
            "ms / iteration | a_r | threads seen |",
            "|---|---|---|---|---|---|---|",
        ]
        for label, r in pr["rows"].items():
            pools = r["threads"].get("threadpools")
            seen = (
                ", ".join(f"{q['internal_api']}={q['num_threads']}" for q in pools)
                if isinstance(pools, list)
                else str(pools)
            )
            lines.append(
                f"| {label} | {r.get('first_call_s', float('nan')):.3g} | "
                f"{r['median_time_s']:.3g} | {r['iterations']} | "
                f"{r['ms_per_iteration']:.1f} | {r['contact_fraction']:.4g} | {seen} |"
            )
        lines.append("")
    lines += ["![work-precision](bench/micro-peers.png)", ""]
    return lines
