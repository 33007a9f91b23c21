"""The ``accuracy`` section of ``docs/benchmarks.md``, rendered from
``docs/bench/accuracy.json``: the page, the end-to-end and network parts (the micro and table
parts are :mod:`app.evidence.accuracy_md_micro`).

One function per subsection. Every number in the prose is read from the JSON or from the
constant that produced it; a sentence that compares or judges ("keeps falling", "hundreds of
times") is worded from the numbers.
"""

from __future__ import annotations

import numpy as np
from skisnow.app.evidence.accuracy_common import (
    ANSWER_METRICS,
    NETWORK_POROSITY,
    SNOW_MODULUS_PA,
    grid_name,
)
from skisnow.app.evidence.accuracy_md_micro import (
    _apct,
    _micro_error,
    _pct,
    micro_section,
    table_section,
)
from skisnow.app.presets import DEFAULT_PRESET
from skisnow.solvers.camber import CONTACT_BAND_M

#: the minimum average separation counts as converged within this of the reference [-]
MIN_SEPARATION_OK = 0.01
#: without a micro stage, a finer grid "buys little accuracy" when it removes less than this
#: share of the default's error [-]
LITTLE_GAIN = 0.5


def _times_words(ratio: float) -> str:
    """Order of magnitude of a ratio in words: "tens of times", "hundreds of times", …"""
    for limit, words in ((10, "a few times"), (100, "tens of times"), (1000, "hundreds of times")):
        if ratio < limit:
            return words
    return "thousands of times"


def _percent_words(v: float) -> str:
    """Size of a relative change in words (|v| as a fraction)."""
    v = abs(v)
    if v < 0.01:
        return "less than a per cent"
    if v < 0.2:
        return "several per cent"
    return "tens of per cent"


# --------------------------------------------------------------------------- end to end


def _why_default(e2e: dict, micro_text: str = "", micro_error: float | None = None) -> list[str]:
    """The reason for the default preset, read off the measured front.

    A finer macro grid "buys little accuracy for its time" when the most it removes from the
    default's error (over the finer grids on the front) is smaller than the micro-scale error
    every preset carries (``micro_error``), or, without one, than half the default's error."""
    by_name = {s["name"]: s for s in e2e["settings"]}
    by_preset = {s["preset"]: s for s in e2e["settings"] if s["preset"]}
    d, f, fi = by_preset.get("default"), by_preset.get("fast"), by_preset.get("fine")
    if d is None:
        return []
    rule = e2e["rule"]["default"]
    tol = 100 * rule["tolerance"]
    front = [by_name[n] for n in e2e["front"]]
    faster = [s for s in front if s["median_total_s"] < d["median_total_s"]]
    d_err = d["max_rel_error_converging"]
    text = (
        f"**Why the default is {d['name']}.** "
        + (
            f"It is the fastest grid on the front with A_app, A_tot, p̄_real and Σ(1/h) within "
            f"{tol:g} % of the reference on every case "
            if rule["fastest_on_front"] == d["name"]
            else f"The rule would pick {rule['fastest_on_front']}; the shipped default stays "
            f"{d['name']} "
        )
        + f"(largest error {_apct(d_err)}, {d['median_total_s'] * 1e3:.0f} ms per request)"
    )
    if faster:
        g = max(faster, key=lambda s: s["median_total_s"])
        text += (
            f"; the next faster point on the front, {g['name']}, saves only "
            f"{(d['median_total_s'] - g['median_total_s']) * 1e3:.0f} ms but reaches "
            f"{_apct(g['max_rel_error_converging'])}"
        )
    if fi is not None:
        text += (
            f"; `fine` ({fi['name']}) costs {fi['time_ratio_vs_default']:.1f}× the time for "
            f"{_apct(fi['max_rel_error_converging'])}"
        )
    if f is not None:
        text += (
            f"; `fast` ({f['name']}) takes {f['time_ratio_vs_default']:.2f}× the time at "
            f"{_apct(f['max_rel_error_converging'])}"
        )
    finer = [
        s
        for s in front
        if s["median_total_s"] > d["median_total_s"] and s["max_rel_error_converging"] < d_err
    ]
    gain = max((d_err - s["max_rel_error_converging"] for s in finer), default=0.0)
    little = gain < (LITTLE_GAIN * d_err if micro_error is None else micro_error)
    text += (
        f". The {tol:g} % line is set by the micro scale: every preset carries the error of the "
        f"shipped tables' texture pixels ({micro_text}; micro section above), so a "
        "finer macro grid than the default buys "
        + ("little accuracy for its time" if little else "accuracy at the price of time")
        + ". The preset changes only the macro grid."
    )
    return [text, ""]


def _trend_words(values: list[float]) -> str:
    """How a sequence moves with refinement: "keeps falling", "keeps rising" or "keeps moving"."""
    steps = np.diff(values)
    if np.all(steps < 0):
        return "keeps falling"
    if np.all(steps > 0):
        return "keeps rising"
    return "keeps moving"


def _min_separation(e2e: dict) -> list[str]:
    """Where the minimum average separation does not converge, with the worst case."""
    cases = e2e["cases"]
    default = next(s["name"] for s in e2e["settings"] if s["preset"] == DEFAULT_PRESET)
    errs = [abs(c["settings"][default]["rel_error"]["min_average_separation"]) for c in cases]
    worst = cases[int(np.argmax(errs))]
    grids = sorted(
        (
            s
            for s in e2e["settings"]
            if s["preset"] == DEFAULT_PRESET
            or (s["pixels_across"] == 16 and not s["preset"])
            or s["preset"] == "fine"
        ),
        key=lambda s: -s["pixel_along_mm"],
    )
    worst_errs = [
        worst["settings"][g["name"]]["rel_error"]["min_average_separation"] for g in grids
    ]
    seq = [f"{g['name']} {_pct(e)}" for g, e in zip(grids, worst_errs, strict=True)]
    ok = sum(e <= MIN_SEPARATION_OK for e in errs)
    return [
        f"**Minimum average separation.** At the default grid it is within "
        f"{100 * MIN_SEPARATION_OK:g} % of the reference in {ok} of {len(cases)} cases. In "
        f"{worst['ski']} × {worst['grind']}, {worst['load_kg']:g} kg at "
        f"{worst['load_position_mm']:g} mm, the minimum sits in a short tip or tail contact "
        "whose pressure peaks at the contact edge; refining the grid along the ski raises that "
        f"peak pixel by pixel, so min h̄ {_trend_words(worst_errs)} ("
        + "; ".join(seq)
        + "): like the peak pressure (docs/macro.md) it does not converge with the macro grid "
        "there. It is reported with the pixel size (`provenance.preset.macro_pixel_size_mm`) "
        "and left out of the preset rule.",
        "",
    ]


def _unverified(stage: dict) -> list[str]:
    cat = stage.get("catalogue") or {}
    if cat.get("verified_against_manifest", True):
        return []
    return [
        "_The demo ski files did not match their manifest during this run (another job was "
        "rewriting them); this stage read them as they were — sha256 of every file used in "
        "`docs/bench/accuracy.json`._",
        "",
    ]


def _e2e_table(e2e: dict) -> list[str]:
    cases = e2e["cases"]
    lines = [
        "### Macro grid spacing and end to end: presets of `/v1/contact`",
        "",
        f"`app.service.contact` (the computation of `POST /v1/contact`) on {len(cases)} "
        "cases (skis × grinds × loads "
        + ", ".join(
            sorted(
                {
                    f"{c['load_kg']:g} kg at {c['load_position_mm']:g} mm, "
                    f"{c['snow_modulus_mpa']:g} MPa, n = {c['porosity']:g}"
                    for c in cases
                }
            )
        )
        + f"), each candidate macro grid against the reference grid {e2e['reference']} on "
        "the same table (the micro error above adds to these and is fixed by the table). "
        "Errors are the largest over the cases; times the median over the cases of "
        "per-case medians (one warm-up first).",
        "",
        "| grid (along × across) | preset | request [s] | macro [s] | time / default | "
        "A_app | A_tot | p̄_real | min h̄ | Σ(1/h) | max without min h̄ |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for s in sorted(e2e["settings"], key=lambda s: s["median_total_s"]):
        e = s["max_rel_error"]
        mark = "**" if s["name"] in e2e["front"] else ""
        lines.append(
            f"| {mark}{s['name']}{mark} | {s['preset'] or ''} | {s['median_total_s']:.3g} | "
            f"{s['median_macro_s']:.3g} | {s['time_ratio_vs_default']:.2f} | "
            + " | ".join(_apct(e[m]) for m in ANSWER_METRICS)
            + f" | {_apct(s['max_rel_error_converging'])} |"
        )
    return lines


def _e2e_rule(e2e: dict) -> list[str]:
    return [
        "",
        "Bold: on the error-versus-time front (no other grid is both faster and more "
        "accurate). Rule: each preset is the fastest grid on the front within its "
        "tolerance — "
        + "; ".join(
            f"`{k}` ≤ {100 * v['tolerance']:g} %: {v['fastest_on_front'] or 'none'}"
            for k, v in e2e["rule"].items()
        )
        + ". Presets shipped: "
        + "; ".join(
            f"`{k}` = {grid_name(p['pixel_along_m'] * 1e3, p['pixels_across'])}"
            for k, p in e2e["presets"].items()
        )
        + ".",
        "",
    ]


def e2e_section(d: dict) -> list[str]:
    """Macro grid spacing and end to end: the presets on the error-versus-time front."""
    e2e = d["end_to_end"]
    return [
        *_e2e_table(e2e),
        *_e2e_rule(e2e),
        *_why_default(e2e, *_micro_error(d)),
        *_min_separation(e2e),
        *_unverified(e2e),
        "![macro grid](bench/accuracy-macro.png)",
        "",
        "![end to end](bench/accuracy-end-to-end.png)",
        "",
    ]


# --------------------------------------------------------------------------- network


def _network_row(s: dict) -> str:
    if "rows" not in s:
        return f"| {s['ski']} | {s['skipped']} |||||||||"
    e = s["max_rel_error"]
    return (
        f"| {s['ski']} | {len(s['rows'])} | {s['median_network_s'] * 1e3:.2f} | "
        f"{s['median_beam_s'] * 1e3:.0f} | "
        f"{s['median_beam_cached_flexibility_s'] * 1e3:.1f} | "
        f"{s['max_contact_band_rmse_um']:.1f} | "
        + " | ".join(
            f"{_apct(e[m])} ({_apct(s['median_abs_rel_error'][m])})" for m in ANSWER_METRICS
        )
        + " |"
    )


def _network_note(nw: dict) -> str:
    """What the table says, worded from it: where the apparent area moves most, and how much
    the network saves against a beam solve with its flexibility rebuilt."""
    skis = [s for s in nw["skis"] if "rows" in s]
    text = (
        "Cells: largest error over the cases (median in brackets). The profile error is "
        "small where it matters for the network's training target (RMSE in the "
        f"{CONTACT_BAND_M * 1e3:g} mm contact band)"
    )
    if not skis:
        return text + "."
    worst = [
        max(s["rows"], key=lambda r: abs(r["rel_error"]["apparent_contact_area"])) for s in skis
    ]
    lightest = min(r["load_kg"] for s in skis for r in s["rows"])
    where = "at light loads" if all(r["load_kg"] == lightest for r in worst) else "at some loads"
    a_max = max(abs(r["rel_error"]["apparent_contact_area"]) for r in worst)
    ratio = min(s["median_beam_s"] / s["median_network_s"] for s in skis)
    return text + (
        f", but {where} the apparent area is set by clearances of a few µm and moves by "
        f"{_percent_words(a_max)}; the macro-grid error above adds to this. The network "
        f"replaces a beam solve that costs {_times_words(ratio)} more (flexibility rebuilt per "
        "request, as without the network)."
    )


def network_section(d: dict) -> list[str]:
    """Camber network against the beam model it learned."""
    nw = d["network"]
    return [
        "### Camber network vs the beam model it learned",
        "",
        "Each ski's network against its beam model (the truth the network was trained on) at "
        "held-out loads × positions, through the whole computation (default grid, "
        f"{nw['grind']}, {SNOW_MODULUS_PA / 1e6:g} MPa snow, n = {NETWORK_POROSITY:g}). Beam "
        "timed as the service would call it (flexibility rebuilt) and with a cached "
        "flexibility.",
        "",
        "| ski | cases | network [ms] | beam [ms] | beam, cached [ms] | max band RMSE [µm] | "
        "A_app | A_tot | p̄_real | min h̄ | Σ(1/h) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
        *(_network_row(s) for s in nw["skis"]),
        "",
        *_unverified(nw),
        _network_note(nw),
        "",
        "![network vs beam](bench/accuracy-network.png)",
        "",
    ]


# --------------------------------------------------------------------------- page


def _wall_times(d: dict) -> list[str]:
    walls = {
        k: d[k].get("wall_time_s") for k in ("micro", "table", "end_to_end", "network") if k in d
    }
    return [
        "Wall time per stage: "
        + ", ".join(f"{k.replace('_', ' ')} {v / 60:.1f} min" for k, v in walls.items() if v)
        + f" (total {sum(v for v in walls.values() if v) / 60:.1f} min). Stages run separately "
        "(`--stages`) record their own command and commit under `measured` in the JSON.",
        "",
    ]


SECTIONS = (
    ("micro", micro_section),
    ("table", table_section),
    ("end_to_end", e2e_section),
    ("network", network_section),
)


def render_md(d: dict) -> list[str]:
    """Section of docs/benchmarks.md for the ``accuracy`` stage."""
    lines = [
        "## Accuracy: error against a converged reference versus time (`skisnow bench accuracy`)",
        "",
        "Every stage is measured in one run; times are medians, compare them as ratios within "
        "the run. Error is relative, `value / reference − 1`.",
        "",
    ]
    for key, section in SECTIONS:
        if key in d:
            lines += section(d)
    return lines + _wall_times(d)
