"""Charts of ``skisnow bench accuracy``: ``docs/bench/accuracy-<stage>.png``."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
from skisnow.app.evidence.accuracy_common import (
    ANSWER_METRICS,
    MICRO_METRICS,
    PRESET_TOLERANCES,
    TABLE_METRICS,
    rel_diff,
)
from skisnow.solvers.lookup import (
    ERROR_FIELDS,
)

log = logging.getLogger(__name__)


def _fig(n: int):
    """A figure with n panels, two per row from three panels on."""
    from matplotlib.figure import Figure
    from matplotlib.ticker import NullFormatter

    cols = n if n < 3 else 2
    rows = -(-n // cols)
    fig = Figure(figsize=(5.2 * cols, 4.2 * rows))
    axes = [fig.add_subplot(rows, cols, k + 1) for k in range(n)]
    for ax in axes:
        ax.xaxis.set_minor_formatter(NullFormatter())
        ax.yaxis.set_minor_formatter(NullFormatter())
    return fig, axes


def _save(fig, path: Path) -> None:
    from skisnow.app.storage.common import atomic_path

    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=100)


def _floor(v: float) -> float:
    return max(abs(v), 1e-6)


def _plot_before_after(mi: dict, path: Path) -> None:
    """|error| against the zero-pixel limit of the shipped tables' value, before (1024²) and
    after (two-level extrapolation, with the estimate it stores as an error bar)."""
    series = [s for s in mi["series"] if s.get("two_level")]
    if not series:
        return
    metrics = list(ERROR_FIELDS)
    fig, axes = _fig(len(metrics))
    x = np.arange(len(series))
    for ax, m in zip(axes, metrics, strict=True):
        before = [abs(s["two_level"]["before_rel_error"][m]) for s in series]
        after = [abs(s["two_level"]["after_rel_error"][m]) for s in series]
        est = [s["two_level"]["estimate_rel"][m] for s in series]
        ax.bar(x - 0.2, [100 * v for v in before], 0.4, label="before: 1024² (1.5 µm)")
        ax.bar(x + 0.2, [100 * v for v in after], 0.4, label="after: 1024² + 2048² extrapolated")
        ax.errorbar(
            x + 0.2,
            [0.0] * len(est),
            yerr=[[0.0] * len(est), [100 * v for v in est]],
            fmt="none",
            ecolor="k",
            capsize=4,
            label="after: stored estimate",
        )
        if m == "real_contact_area_fraction":
            ax.axhline(3.0, color="r", lw=0.8, ls="--", label="aim: 3 %")
        ax.set_xticks(x, [f"{s['grind']}\n{s['nominal_pressure_kpa']:g} kPa" for s in series])
        ax.set_title(MICRO_METRICS[m], fontsize=9)
        ax.set_ylabel("|rel. error| vs zero-pixel limit [%]")
        ax.grid(True, axis="y", alpha=0.3)
    for ax in axes[len(metrics) :]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7)
    fig.suptitle(
        f"shipped tables before/after; limit from {mi['sizes'][-2]}² and {mi['sizes'][-1]}²",
        fontsize=10,
    )
    _save(fig, path)


def plot_accuracy(data: dict, path: Path) -> None:
    """Charts ``accuracy-<stage>.png`` beside ``path`` (the stage's own png is the front)."""
    out = path.parent
    if "micro" in data:
        fig, axes = _fig(len(MICRO_METRICS))
        for ax, (m, label) in zip(axes, MICRO_METRICS.items(), strict=True):
            for s in data["micro"]["series"]:
                rows = s["rows"][:-1]
                ax.loglog(
                    [r["median_time_s"] for r in rows],
                    [_floor(r["rel_error"][m]) for r in rows],
                    "o-",
                    label=f"{s['grind']}, {s['nominal_pressure_kpa']:g} kPa",
                )
                for r in rows:
                    ax.annotate(
                        f"{r['n']}²", (r["median_time_s"], _floor(r["rel_error"][m])), fontsize=7
                    )
                t = s.get("two_level")
                if t and m in t["value"]:  # after: the two-level table value (vs the finest)
                    y = _floor(rel_diff(t["value"][m], s["rows"][-1][m]))
                    ax.loglog(t["time_s"], y, "*", ms=11, color=ax.lines[-1].get_color())
                    ax.annotate("1024²+2048² extrap.", (t["time_s"], y), fontsize=6)
            ax.set_title(label, fontsize=9)
            ax.set_xlabel("median solve time [s]")
            ax.set_ylabel(f"|rel. error| vs {data['micro']['sizes'][-1]}²")
            ax.grid(True, which="both", alpha=0.3)
        axes[0].legend(fontsize=7)
        fig.suptitle(f"micro: grid size on a {data['micro']['patch_mm']:.3f} mm patch", fontsize=10)
        _save(fig, out / "accuracy-micro.png")
        _plot_before_after(data["micro"], out / "accuracy-tables-before-after.png")
    if "table" in data:
        fig, axes = _fig(len(TABLE_METRICS))
        for ax, m in zip(axes, TABLE_METRICS, strict=True):
            for g in data["table"]["grinds"]:
                rows = [
                    r
                    for r in g["rows"]
                    if "build_cost_s" in r and r["max_rel_error"][m] is not None
                ]
                ax.loglog(
                    [r["build_cost_s"] for r in rows],
                    [_floor(r["max_rel_error"][m]) for r in rows],
                    "o-",
                    label=g["grind"],
                )
                for r in rows:
                    ax.annotate(
                        f"{r['points']} pts",
                        (r["build_cost_s"], _floor(r["max_rel_error"][m])),
                        fontsize=7,
                    )
            ax.set_title(MICRO_METRICS[m], fontsize=9)
            ax.set_xlabel("table build cost (points × median solve) [s]")
            ax.set_ylabel("max |rel. error| vs direct solve")
            ax.grid(True, which="both", alpha=0.3)
        axes[0].legend(fontsize=7)
        fig.suptitle("table: PCHIP interpolation vs direct solves (pressure-grid density)")
        _save(fig, out / "accuracy-table.png")
    if "end_to_end" in data:
        e2e = data["end_to_end"]
        cand = [s for s in e2e["settings"] if s["name"] != "reference"]
        for key, tkey, fname, title, front_key in (
            (
                "apparent_contact_area",
                "median_macro_s",
                "accuracy-macro.png",
                "macro: grid spacing (apparent contact area)",
                "macro_front",
            ),
            (None, "median_total_s", "accuracy-end-to-end.png", "end to end: /v1/contact", "front"),
        ):
            fig, axes = _fig(1 if key else 2)
            fig.set_size_inches(7 if key else 13, 5)
            ax = axes[0]

            def err(s, key=key):
                return s["max_rel_error"][key] if key else s["max_rel_error_converging"]

            if not key:  # the minimum average separation beside, on its own panel
                ax2 = axes[1]
                for s in cand:
                    x, y = s[tkey], _floor(s["max_rel_error"]["min_average_separation"])
                    ax2.loglog(x, y, "s" if s["preset"] else "o", color="C1", ms=5)
                    ax2.annotate(
                        s["name"] + (f"  [{s['preset']}]" if s["preset"] else ""),
                        (x, y),
                        fontsize=7,
                        xytext=(3, 3),
                        textcoords="offset points",
                    )
                ax2.set_xlabel("whole request median time [s]")
                ax2.set_ylabel(f"max |rel. error| of min h̄ vs {e2e['reference']}")
                ax2.set_title(
                    "minimum average separation (does not converge where it sits at a "
                    "short tip/tail contact)",
                    fontsize=8,
                )
                ax2.grid(True, which="both", alpha=0.3)

            for s in cand:
                x, y = s[tkey], _floor(err(s))
                style = "s" if s["preset"] else "o"
                ax.loglog(
                    x, y, style, color="C3" if s["preset"] else "C0", ms=7 if s["preset"] else 5
                )
                lab = s["name"] + (f"  [{s['preset']}]" if s["preset"] else "")
                ax.annotate(lab, (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
            fr = sorted((s for s in cand if s["name"] in e2e[front_key]), key=lambda s: s[tkey])
            ax.loglog([s[tkey] for s in fr], [_floor(err(s)) for s in fr], "-", color="grey", lw=1)
            for tol in PRESET_TOLERANCES.values():
                ax.axhline(tol, ls=":", color="grey", lw=0.8)
            ax.set_xlabel(("macro solve" if key else "whole request") + " median time [s]")
            ax.set_ylabel(
                "max |rel. error| "
                + ("of the apparent area" if key else "of A_app, A_tot, p̄_real, Σ(1/h)")
                + f" vs {e2e['reference']}"
            )
            ax.set_title(title + " (grey: front; red squares: named presets)", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
            _save(fig, out / fname)
    if "network" in data:
        fig, (ax,) = _fig(1)
        fig.set_size_inches(7, 4.5)
        for k, s in enumerate(x for x in data["network"]["skis"] if "rows" in x):
            for j, m in enumerate(ANSWER_METRICS):
                ax.loglog(
                    s["median_network_s"],
                    _floor(s["max_rel_error"][m]),
                    "os^vD"[j],
                    color=f"C{j}",
                    label=m.replace("_", " ") if k == 0 else None,
                )
            ax.annotate(
                s["ski"],
                (s["median_network_s"], _floor(s["max_rel_error"]["apparent_contact_area"])),
                fontsize=8,
            )
            ax.axvline(
                s["median_beam_s"],
                color=f"C{5 + k}",
                ls="--",
                lw=1,
                label=f"beam {s['ski']} (truth, error 0)",
            )
            ax.axvline(
                s["median_beam_cached_flexibility_s"],
                color=f"C{5 + k}",
                ls=":",
                lw=1,
                label=f"beam {s['ski']}, cached flexibility",
            )
        ax.set_xlabel("median time of the loaded profile [s]")
        ax.set_ylabel("max |rel. error| network vs beam")
        ax.set_title("network vs the beam model it learned", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        _save(fig, out / "accuracy-network.png")
