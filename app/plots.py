"""Server-side SVG plots of contact results (matplotlib ``Figure``, no pyplot, no global state).

Every function takes answers of :func:`app.service.contact` (technician units: mm, kPa, µm), or
for a ski's page the ``beam`` report of :func:`app.service.beam_report` (mm, kg, N·m², µm), and
returns one SVG document as a string, ready to be inlined in HTML. Quantities and symbols follow
``docs/physics.md``: P(X) apparent pressure, H(X) loaded camber clearance, a_r(X) real contact
area fraction, h̄_n(X) average interfacial separation, (1/h)‾_n(X) average reciprocal separation.
X is the position along the ski from the balance point, positive towards the tip.
"""

from __future__ import annotations

import io
from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

#: wax-layer thicknesses drawn on the clearance plot [mm]
WAX_LAYERS_MM = (0.1, 0.2)
#: the clearance plot shows at most this much clearance [mm]; the tip and tail rise far higher
CLEARANCE_TOP_MM = 1.0

_X_LABEL = "position X from the balance point, + towards the tip [mm]"
_COLOURS = (
    "#1f77b4",
    "#d62728",
    "#2ca02c",
    "#9467bd",
    "#ff7f0e",
    "#17becf",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
)


def _array(values: Sequence[float | None]) -> np.ndarray:
    """A list with ``None`` for missing values as a float array with NaN."""
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def _svg(fig: Figure) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight", metadata={"Date": None})
    text = buf.getvalue()
    # inline use: drop the XML declaration and DOCTYPE in front of <svg
    return text[text.index("<svg") :]


def _figure(title: str, ylabel: str) -> tuple[Figure, object]:
    fig = Figure(figsize=(7.2, 3.2), layout="constrained")
    ax = fig.add_subplot()
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(_X_LABEL)
    ax.set_ylabel(ylabel)
    ax.grid(True, alpha=0.3, which="both")
    return fig, ax


def _panels(title: str, rows: int = 1, cols: int = 1, **kwargs) -> tuple[Figure, np.ndarray]:
    """A figure of ``rows`` × ``cols`` axes (a flat array) with a title and light grids."""
    height = 3.2 if rows == 1 else 4.6
    fig = Figure(figsize=(7.2, height), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False, **kwargs)).ravel()
    fig.suptitle(title, fontsize=10)
    for ax in axes:
        ax.grid(True, alpha=0.3, which="both")
    return fig, axes


def _legend_below(fig: Figure, ax, ncols: int = 3) -> None:
    """The legend under the axes, outside them, so that it never covers a curve (a legend
    inside the axes hid the tail end of the clearance curves and the flex sheet's peak)."""
    handles, labels = ax.get_legend_handles_labels()
    unique = dict(zip(labels, handles, strict=True))  # one entry per label
    fig.legend(
        list(unique.values()),
        list(unique),
        loc="outside lower center",
        ncols=min(ncols, len(unique)),
        fontsize=9,
        frameon=False,
    )


def _label(result: dict, *, with_grind: bool = True) -> str:
    inp = result["inputs"]
    return f"{inp['ski']} × {inp['grind']}" if with_grind else str(inp["ski"])


def _per_ski(results: Sequence[dict]) -> list[dict]:
    """One result per ski: P(X) and H(X) come from the macro scale and do not depend on the
    grind."""
    seen: dict[str, dict] = {}
    for r in results:
        seen.setdefault(r["inputs"]["ski"], r)
    return list(seen.values())


def _load_line(ax, results: Sequence[dict]) -> None:
    positions = sorted({float(r["inputs"]["load_position_mm"]) for r in results})
    for i, x in enumerate(positions):
        ax.axvline(x, color="k", ls=":", lw=1, label="load position" if i == 0 else None)


def pressure_svg(results: Sequence[dict]) -> str:
    """Apparent contact pressure P(X) [kPa] (mean across the width) with the contact zones
    shaded and labelled with their load share."""
    fig, ax = _figure("Apparent contact pressure along the ski", "pressure P [kPa]")
    for i, r in enumerate(_per_ski(results)):
        colour = _COLOURS[i % len(_COLOURS)]
        d = r["distributions"]
        x = _array(d["position_mm"])
        ax.plot(
            x, _array(d["pressure_kpa"]), color=colour, lw=1.4, label=_label(r, with_grind=False)
        )
        if "pressure_band_low_kpa" in d:
            lo, hi = _array(d["pressure_band_low_kpa"]), _array(d["pressure_band_high_kpa"])
            ax.fill_between(
                x,
                lo,
                hi,
                color=colour,
                alpha=0.35,
                lw=0,
                label=f"{_label(r, with_grind=False)} 90 % band",
            )
        for z in r["apparent"]["zones"]:
            ax.axvspan(
                z["start_mm"],
                z["end_mm"],
                color="0.5",
                alpha=0.10,
                lw=0,
                label="contact zone",
            )
            ax.annotate(
                f"{z['name']} {100 * z['load_share']:.0f} %",
                xy=(0.5 * (z["start_mm"] + z["end_mm"]), 1.0),
                xycoords=("data", "axes fraction"),
                xytext=(0, -4 - 11 * i),
                textcoords="offset points",
                ha="center",
                va="top",
                fontsize=8,
                color=colour,
            )
    _load_line(ax, results)
    ax.set_ylim(bottom=0)
    ax.margins(y=0.25)
    _legend_below(fig, ax, ncols=3)
    return _svg(fig)


def clearance_svg(results: Sequence[dict]) -> str:
    """Loaded camber clearance H(X) [mm] with the wax-layer thicknesses of
    :data:`WAX_LAYERS_MM`; the axis stops at :data:`CLEARANCE_TOP_MM`."""
    fig, ax = _figure(
        f"Loaded camber clearance H (axis cut at {CLEARANCE_TOP_MM:g} mm)", "clearance H [mm]"
    )
    for i, r in enumerate(_per_ski(results)):
        d = r["distributions"]
        ax.plot(
            _array(d["position_mm"]),
            _array(d["clearance_um"]) * 1e-3,
            color=_COLOURS[i % len(_COLOURS)],
            lw=1.4,
            label=_label(r, with_grind=False),
        )
    for thickness, style in zip(WAX_LAYERS_MM, ("--", "-."), strict=True):
        ax.axhline(thickness, color="0.35", ls=style, lw=1, label=f"{thickness:g} mm wax layer")
    _load_line(ax, results)
    ax.set_ylim(0, CLEARANCE_TOP_MM)
    _legend_below(fig, ax, ncols=5)
    return _svg(fig)


def _per_case(results: Sequence[dict], key: str, scale: float, title: str, ylabel: str, *, log):
    fig, ax = _figure(title, ylabel)
    for i, r in enumerate(results):
        d = r["distributions"]
        y = _array(d[key]) * scale
        if log:
            y = np.where(y > 0, y, np.nan)
        ax.plot(
            _array(d["position_mm"]),
            y,
            color=_COLOURS[i % len(_COLOURS)],
            lw=1.2,
            label=_label(r),
        )
    if log:
        ax.set_yscale("log")
    _load_line(ax, results)
    ax.legend(fontsize=8, loc="best")
    return _svg(fig)


def real_area_svg(results: Sequence[dict]) -> str:
    """Real contact area fraction a_r(X) [%] for every ski × grind."""
    return _per_case(
        results,
        "real_area_fraction",
        100.0,
        "Real contact area fraction",
        "real contact area a_r [%]",
        log=False,
    )


def separation_svg(results: Sequence[dict]) -> str:
    """Average interfacial separation h̄_n(X) [µm] on a log axis."""
    return _per_case(
        results,
        "average_separation_um",
        1.0,
        "Average interfacial separation",
        "separation h̄ [µm]",
        log=True,
    )


def reciprocal_svg(results: Sequence[dict]) -> str:
    """Average reciprocal interfacial separation (1/h)‾_n(X) [1/m] on a log axis."""
    return _per_case(
        results,
        "reciprocal_separation_per_m",
        1.0,
        "Average reciprocal interfacial separation",
        "reciprocal separation (1/h)‾ [1/m]",
        log=True,
    )


#: the quantities of the error-band chart: (section, key, band key, label, unit)
BAND_QUANTITIES = (
    ("apparent", "contact_area_cm2", "apparent_contact_area", "apparent area", "cm²"),
    ("metrics", "total_real_contact_area_mm2", "total_real_contact_area", "real area", "mm²"),
    (
        "metrics",
        "average_real_contact_pressure_mpa",
        "average_real_contact_pressure",
        "real pressure",
        "MPa",
    ),
    ("metrics", "min_average_separation_um", "min_average_separation", "min. separation", "µm"),
    (
        "metrics",
        "total_reciprocal_separation_m",
        "total_reciprocal_separation",
        "reciprocal sep.",
        "m",
    ),
)


#: font size of the error-band chart's labels [pt]: its SVG is drawn at 72 px per inch and
#: shown about that wide, so 10 pt is about 10 px (7 pt, before, was unreadable)
BAND_FONT_PT = 10


def band_svg(results: Sequence[dict]) -> str:
    """Every case's apparent area and four metrics with their 90 % error bands, one panel per
    quantity (a missing band: no whisker and an open marker)."""
    fig = Figure(figsize=(7.2, 1.6 + 0.4 * max(len(results), 1) + 1.2), layout="constrained")
    axes = fig.subplots(1, len(BAND_QUANTITIES), sharey=True)
    fig.suptitle("The five answers with their 90 % error bands", fontsize=11)
    labels = [_label(r) for r in results]
    y = np.arange(len(results))
    for ax, (section, key, bkey, name, unit) in zip(axes, BAND_QUANTITIES, strict=True):
        for i, r in enumerate(results):
            v = r[section][key]
            w = r.get("band", {}).get("relative_half_width", {}).get(bkey)
            wa = (r.get("band", {}).get("relative_half_width_above") or {}).get(bkey, w)
            colour = _COLOURS[i % len(_COLOURS)]
            if w is None:
                ax.plot([v], [i], "o", mfc="none", color=colour)
            elif wa is None or wa >= 1:  # no upper bound: an arrow to the right
                ax.errorbar(
                    [v], [i], xerr=[[v * min(w, 1.0)], [0.0]], fmt="o", color=colour, capsize=3
                )
                ax.plot([2 * v], [i], ">", color=colour)
            else:  # v (1 − w) … v / (1 − wa) (app.service.band.interval_90)
                xerr = [[v * min(w, 1.0)], [v * wa / (1 - wa)]]
                ax.errorbar([v], [i], xerr=xerr, fmt="o", color=colour, capsize=3)
        ax.set_title(f"{name}\n[{unit}]", fontsize=BAND_FONT_PT)
        ax.tick_params(labelsize=BAND_FONT_PT)
        ax.xaxis.set_major_locator(MaxNLocator(nbins=2, min_n_ticks=2))
        ax.margins(x=0.25)
        ax.grid(True, alpha=0.3)
    axes[0].set_yticks(y, labels, fontsize=BAND_FONT_PT)
    axes[0].invert_yaxis()
    return _svg(fig)


#: (key, caption, function) of the plots on the results page, in page order
PLOTS = (
    ("band", "The answers with their 90 % error bands", band_svg),
    (
        "pressure",
        "Apparent pressure P(X) of each ski with its 90 % band from the camber model (shaded in "
        "the ski's colour); contact zones shaded grey, each labelled at the top with its name "
        "and load share; dotted: the load position",
        pressure_svg,
    ),
    ("clearance", "Loaded camber clearance H(X) with 0.1 and 0.2 mm wax layers", clearance_svg),
    ("real_area", "Real contact area fraction a_r(X)", real_area_svg),
    ("separation", "Average interfacial separation h̄(X)", separation_svg),
    ("reciprocal", "Average reciprocal separation (1/h)(X)", reciprocal_svg),
)


def all_svgs(results: Sequence[dict]) -> list[tuple[str, str, str]]:
    """``[(key, caption, svg)]`` for every plot of :data:`PLOTS`."""
    return [(key, caption, fn(results)) for key, caption, fn in PLOTS]


# ----------------------------------------------------------------------------- a ski's beam

#: the camber plot's axis stops at this factor × the largest c(X) over the middle of the ski
#: (the tip and tail rise tens of mm and would flatten the camber pocket)
CAMBER_TOP_FACTOR = 1.3
#: the share of the ski's length, centred, over which that largest c(X) is taken [-]
CAMBER_MIDDLE_SHARE = 0.8


def _band(beam: dict, key: str) -> tuple[np.ndarray, np.ndarray] | None:
    band = beam.get(key)
    if not band:
        return None
    return _array(band[0]), _array(band[1])


def _along_with_band(
    title: str,
    x: np.ndarray,
    y: np.ndarray,
    band: tuple[np.ndarray, np.ndarray] | None,
    *,
    colour: str,
    ylabel: str,
    width_label: str,
    half_width,
    ylim: tuple[float, float | None],
    others: tuple | list = (),
) -> str:
    """A quantity along the ski with its 90 % band shaded and, when there is a band, a lower
    panel with the band's half-width (``half_width(lo, hi, y)``): the bands of an identified
    beam are often too narrow to see on the upper axis. ``others``: the same quantity of the
    identification's alternative beams, drawn thin and dashed."""
    if band is None:
        fig, (ax,) = _panels(title)
    else:
        fig, (ax, ax_w) = _panels(title, 2, 1, sharex=True, height_ratios=(3, 1.3))
    for i, o in enumerate(others):
        label = f"other beams that fit ({len(others)})" if i == 0 else None
        ax.plot(x, o, color="0.35", lw=0.8, ls="--", label=label)
    ax.plot(x, y, color=colour, lw=1.4, label=ylabel.split(" [")[0])
    if band is not None:
        ax.fill_between(x, *band, color=colour, alpha=0.3, lw=0, label="90 % band")
        ax_w.plot(x, half_width(*band, y), color=colour, lw=1.2)
        ax_w.set_ylabel(width_label)
        ax_w.set_ylim(bottom=0)
        ax_w.set_xlabel(_X_LABEL)
    else:
        ax.set_xlabel(_X_LABEL)
    ax.set_ylabel(ylabel)
    ax.set_ylim(*ylim)
    ax.legend(fontsize=8, loc="lower center")
    return _svg(fig)


def _alternatives(beam: dict, key: str) -> list:
    """The alternative beams' ``key`` in a beam report (:func:`app.service.beam_report`)."""
    return (beam.get("alternatives") or {}).get(key, [])


def stiffness_svg(beam: dict) -> str:
    """Bending stiffness EI(X) [N·m²] with its 90 % band and the identification's alternative
    beams, and below it the band's half-width relative to EI [%]; a beam without a band (a
    design beam) is drawn alone."""
    band = _band(beam, "bending_stiffness_band_90_nm2")
    return _along_with_band(
        "Bending stiffness EI(X) of the beam",
        _array(beam["position_mm"]),
        _array(beam["bending_stiffness_nm2"]),
        band,
        colour=_COLOURS[0],
        ylabel="EI(X) [N·m²]",
        width_label="90 % half-\nwidth [%]",
        half_width=lambda lo, hi, y: 50.0 * (hi - lo) / y,
        ylim=(0, None),
        others=[_array(v) for v in _alternatives(beam, "bending_stiffness_nm2")],
    )


def camber_top_mm(beam: dict) -> float:
    """Top of the camber plot's axis [mm]: :data:`CAMBER_TOP_FACTOR` × the largest c(X) over
    the middle :data:`CAMBER_MIDDLE_SHARE` of the sampled length."""
    x, c = _array(beam["position_mm"]), _array(beam["camber_um"]) * 1e-3
    mid, half = 0.5 * (x[0] + x[-1]), 0.5 * CAMBER_MIDDLE_SHARE * (x[-1] - x[0])
    inner = c[np.abs(x - mid) <= half]
    top = np.nanmax(inner) if np.isfinite(inner).any() else np.nanmax(c)
    return float(CAMBER_TOP_FACTOR * top) if top > 0 else 1.0


def camber_svg(beam: dict) -> str:
    """Unloaded camber c(X) [mm] with its 90 % band and the identification's alternative beams
    (axis cut at :func:`camber_top_mm`), and below it the band's half-width [µm]; a beam
    without a band is drawn alone."""
    top = camber_top_mm(beam)
    band = _band(beam, "camber_band_90_um")
    return _along_with_band(
        f"Unloaded camber c(X), the gap on a rigid flat without load (axis cut at {top:.2g} mm)",
        _array(beam["position_mm"]),
        _array(beam["camber_um"]) * 1e-3,
        None if band is None else (band[0] * 1e-3, band[1] * 1e-3),
        colour=_COLOURS[1],
        ylabel="c(X) [mm]",
        width_label="90 % half-\nwidth [µm]",
        half_width=lambda lo, hi, y: 500.0 * (hi - lo),
        ylim=(0, top),
        others=[_array(v) * 1e-3 for v in _alternatives(beam, "camber_um")],
    )


def misfit_svg(identification: dict) -> str:
    """RMS misfit per camber case [µm] against the case's load [kg] and load position [mm]:
    the identified cases (filled), the held-out cases' prediction error (open) and the device
    noise σ estimated from the data (dashed)."""
    fig, axes = _panels("Misfit per camber case", 1, 2, sharey=True)
    fit = _array(identification.get("case_misfit_um", []))
    held = identification.get("held_out") or {}
    for ax, key, label in zip(
        axes,
        ("load_kg", "position_mm"),
        ("load on the ski [kg]", "load position X_F from the balance point [mm]"),
        strict=True,
    ):
        ax.plot(
            _array(identification[f"case_{key}"]),
            fit,
            "o",
            ms=3,
            color=_COLOURS[0],
            alpha=0.6,
            label=f"identified cases ({fit.size})",
        )
        if held:
            err = _array(held["error_um"])
            ax.plot(
                _array(held[key]),
                err,
                "s",
                ms=4,
                mfc="none",
                color=_COLOURS[1],
                label=f"held-out cases ({err.size}): prediction error",
            )
        noise = identification.get("noise_um")
        if noise is not None:
            ax.axhline(noise, color="k", ls="--", lw=1, label=f"device noise σ {noise:.2f} µm")
        ax.set_xlabel(label)
    axes[0].set_ylabel("RMS misfit per case [µm]")
    # the axis is not cut at 0: the spread about the noise is what the plot is for
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=3)
    return _svg(fig)


#: wax-layer lines of the flex sheet's profile plot: gap [mm] and hard-wax layers
FLEX_WAX_LINES = ((0.10, "2 layers"), (0.15, "3 layers"), (0.20, "4 layers"), (0.30, "6 layers"))


def flex_profile_svg(answer: dict) -> str:
    """The loaded gap H*(X) on the rigid flat under half and full body weight at the pocket's
    foot position (an answer of :func:`app.service.flex.flex_sheet_answer` with ``profiles``), the
    wax-layer lines (0.10/0.15/0.20/0.30 mm) and the wax zone (the 0.10 mm pocket under half
    weight) shaded; the foot is a vertical line. Units: mm on both axes."""
    prof = answer["profiles"]
    x = _array(prof["positions_mm"])
    half = _array(prof["half_weight_gap_mm"])
    full = _array(prof["full_weight_gap_mm"])
    w = answer["inputs"]["body_weight_kg"]
    fig, ax = _figure(
        f"{answer['inputs']['ski']}: loaded camber on the flat, foot at "
        f"{answer['inputs']['pocket_position_mm']:g} mm",
        "gap H*(X) [mm]",
    )
    ax.plot(x, half, color=_COLOURS[0], lw=1.4, label=f"half weight ({0.5 * w:g} kg)")
    ax.plot(x, full, color=_COLOURS[1], lw=1.4, label=f"full weight ({w:g} kg)")
    for gap, layers in FLEX_WAX_LINES:
        ax.axhline(gap, color="0.4", lw=0.7, ls="--")
        ax.annotate(
            f"{gap:.2f} mm ({layers})",
            (x[0], gap),
            textcoords="offset points",
            xytext=(2, 2),
            fontsize=7,
            color="0.3",
        )
    wax = answer["wax_zone"]
    if wax["start_mm"] is not None:
        ax.axvspan(
            wax["start_mm"],
            wax["end_mm"],
            color=_COLOURS[2],
            alpha=0.15,
            label=f"wax zone {wax['length_mm']:.0f} mm (≥ 0.10 mm at half weight)",
        )
    ax.axvline(answer["inputs"]["pocket_position_mm"], color="k", lw=0.8, ls=":", label="foot")
    mid = np.abs(x) < 600
    top = np.nanmax(half[mid]) if np.any(mid) else np.nanmax(half)
    ax.set_ylim(0, float(np.clip(1.15 * top, 0.4, 3.0)))
    _legend_below(fig, ax, ncols=2)
    return _svg(fig)


def flex_pair_svg(left: dict, right: dict) -> str:
    """The two skis of a pair overlaid: loaded gap H*(X) on the rigid flat under half (solid) and
    full (dashed) body weight at the pocket's foot position (two answers of
    :func:`app.service.flex.flex_sheet_answer` with ``profiles``), the 0.10 mm wax-layer line
    and the foot. Units: mm on both axes."""
    w = left["inputs"]["body_weight_kg"]
    fig, ax = _figure(
        f"{left['inputs']['ski']} | {right['inputs']['ski']}: loaded camber on the flat, "
        f"foot at {left['inputs']['pocket_position_mm']:g} mm",
        "gap H*(X) [mm]",
    )
    tops = []
    for i, ans in enumerate((left, right)):
        prof = ans["profiles"]
        x = _array(prof["positions_mm"])
        half = _array(prof["half_weight_gap_mm"])
        full = _array(prof["full_weight_gap_mm"])
        name = ans["inputs"]["ski"]
        ax.plot(x, half, color=_COLOURS[i], lw=1.4, label=f"{name}, half weight ({0.5 * w:g} kg)")
        ax.plot(x, full, color=_COLOURS[i], lw=1.4, ls="--", label=f"{name}, full ({w:g} kg)")
        mid = np.abs(x) < 600
        tops.append(np.nanmax(half[mid]) if np.any(mid) else np.nanmax(half))
    ax.axhline(0.10, color="0.4", lw=0.7, ls=":")
    ax.axvline(left["inputs"]["pocket_position_mm"], color="k", lw=0.8, ls=":", label="foot")
    ax.set_ylim(0, float(np.clip(1.15 * max(tops), 0.4, 3.0)))
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    return _svg(fig)
