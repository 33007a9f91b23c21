"""Figures of the paper case (SVG): the web form's along-the-ski plots (:mod:`app.plots`), zone
pressures against E_snow and real area against pressure."""

from __future__ import annotations

import io
import logging

import numpy as np
from matplotlib.figure import Figure
from skisnow.app import plots
from skisnow.app.evidence.paper_case import (
    GRINDS,
    PAPER_LOAD_KG,
    PAPER_POSITION_MM,
    PAPER_SNOW_MODULUS_MPA,
    PUBLISHED_APPARENT,
    SKIS,
    PaperCase,
    fmt,
)

log = logging.getLogger(__name__)


def _figure(title: str, xlabel: str, ylabel: str) -> tuple[Figure, object]:
    fig = Figure(figsize=(7.2, 3.6), layout="constrained")
    ax = fig.add_subplot()
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3, which="both")
    return fig, ax


def _fig_svg(fig: Figure) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight", metadata={"Date": None})
    return buf.getvalue()


def zone_pressure_svg(case: PaperCase) -> str:
    """Mean apparent pressure of the rear and front zones against E_snow [kPa vs MPa]."""
    fig, ax = _figure(
        f"Zone mean apparent pressure, {fmt(PAPER_LOAD_KG)} kg at {fmt(PAPER_POSITION_MM)} mm",
        "snow modulus E_snow [MPa]",
        "mean apparent pressure [kPa]",
    )
    for i, s in enumerate(SKIS):
        rows = [r for r in case.sweep if r["ski"] == s and r["error"] is None]
        e = [r["snow_modulus_mpa"] for r in rows]
        colour = plots._COLOURS[i % len(plots._COLOURS)]
        for side, style in (("rear", "-"), ("front", "--")):
            ax.plot(
                e,
                [r[side]["mean_pressure_kpa"] for r in rows],
                ls=style,
                marker="o",
                ms=3,
                color=colour,
                label=f"{s} {side} zone",
            )
        ax.plot(
            e,
            [r["mean_pressure_kpa"] for r in rows],
            ls=":",
            color=colour,
            lw=1,
            label=f"{s} whole ski F / A_app",
        )
        pub = PUBLISHED_APPARENT.get(s)
        if pub:
            ax.plot(
                [PAPER_SNOW_MODULUS_MPA],
                [pub["mean_pressure_kpa"]],
                marker="*",
                ms=10,
                ls="none",
                color=colour,
                label=f"{s} published F / A_app",
            )
    ax.set_ylim(bottom=0)
    ax.legend(fontsize=7, loc="upper left", ncol=2)
    return _fig_svg(fig)


def real_area_curve_svg(case: PaperCase) -> str:
    """Real contact area fraction a_r [%] against apparent pressure P [kPa], per grind and
    porosity, at E_snow 200 MPa."""
    fig, ax = _figure(
        f"Real contact area against apparent pressure, E_snow = {fmt(PAPER_SNOW_MODULUS_MPA)} MPa"
        " (P_n = P (1 − n))",
        "apparent (nominal macro-scale) pressure P [kPa]",
        "real contact area a_r [% of apparent area]",
    )
    p = np.asarray(case.curves["pressure_kpa"])
    styles = ("--", "-", ":", "-.")
    for i, g in enumerate(GRINDS):
        colour = plots._COLOURS[i % len(plots._COLOURS)]
        for j, (n, ar) in enumerate(case.curves[g].items()):
            y = np.asarray(ar, dtype=float)
            ax.plot(p, np.where(y > 0, y, np.nan), color=colour, ls=styles[j % 4], lw=1.3,
                    label=f"{g}, n = {n}")  # fmt: skip
    for s in SKIS:
        r = case.results[(s, GRINDS[0])]
        x = r["apparent"]["mean_pressure_kpa"]
        ax.axvline(x, color="0.4", lw=0.8, ls=":")
        ax.annotate(f"{s} F/A_app", xy=(x, 0.02), xycoords=("data", "axes fraction"),
                    rotation=90, fontsize=7, color="0.3", ha="right", va="bottom")  # fmt: skip
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.legend(fontsize=7, loc="upper left")
    return _fig_svg(fig)


def _figures(case: PaperCase) -> list[tuple[str, str, str]]:
    """``[(file name, caption, svg text)]`` of every figure."""
    results = [case.results[(s, g)] for s in SKIS for g in GRINDS]
    head = '<?xml version="1.0" encoding="utf-8" standalone="no"?>\n'
    figs = [
        (f"{key.replace('_', '-')}.svg", caption, head + fn(results))
        for key, caption, fn in plots.PLOTS
    ]
    figs.append(
        (
            "zone-pressure-vs-modulus.svg",
            "Mean apparent pressure of the rear and front contact zones against E_snow",
            zone_pressure_svg(case),
        )
    )
    figs.append(
        (
            "real-area-vs-pressure.svg",
            "Real contact area fraction a_r against apparent pressure P for both grinds at "
            "three porosities",
            real_area_curve_svg(case),
        )
    )
    return figs
