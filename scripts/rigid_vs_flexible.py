"""How far the rigid-shape ski model is from the flexible (bending) one, through the service.

For both demo skis (``ski-a``, ``ski-b``), grind ``grind-1``, porosity 0.5, the default
preset, every snow modulus of ``E_SNOW_MPA`` and three loads (20 kg at −80 mm, the papers'
case 40 kg at −160 mm, 80 kg at −150 mm), :func:`app.service.contact` is called once with
``ski_model="rigid"`` and once with ``ski_model="flexible"``. Per case both answers' apparent
contact area, contact zones (name, length, load share), rear load share (zones whose midpoint
lie at x < 0) and the four metrics are recorded, with the relative
differences (rigid − flexible) / flexible. A failing case records its error and the study
goes on.

Outputs (atomic writes): ``docs/studies/rigid-vs-flexible.json`` (all numbers, provenance
inside), ``docs/studies/rigid-vs-flexible.png`` (chart) and ``docs/rigid-vs-flexible.md``
(tables, chart, summary).

Usage::

    python scripts/rigid_vs_flexible.py [--tables-dir tables] [--skis ski-a ski-b]

About 5 s on a quiet 2-core machine (each rigid solve is milliseconds).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app.service import ContactInputs, contact, load_catalogue  # noqa: E402
from skisnow.app.storage import common  # noqa: E402

E_SNOW_MPA = [2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000]
LOADS = [(20.0, -80.0), (40.0, -160.0), (80.0, -150.0)]  # (kg, mm); 40 kg at −160 mm: papers
PAPERS_LOAD = (40.0, -160.0)
GRIND = "grind-1"
POROSITY = 0.5
MODELS = ("rigid", "flexible")
TOLERANCE = 0.02
METRICS = [
    "total_real_contact_area_mm2",
    "average_real_contact_pressure_mpa",
    "min_average_separation_um",
    "total_reciprocal_separation_m",
]
QUANTITIES = [  # (key, axis label)
    ("apparent_area_cm2", "apparent area [cm²]"),
    ("rear_load_share", "rear load share [–]"),
    ("total_real_contact_area_mm2", "total real contact area [mm²]"),
    ("average_real_contact_pressure_mpa", "avg real contact pressure [MPa]"),
    ("min_average_separation_um", "min avg separation [µm]"),
    ("total_reciprocal_separation_m", "total reciprocal separation [m]"),
]
JSON_OUT = REPO / "docs" / "studies" / "rigid-vs-flexible.json"
PNG_OUT = REPO / "docs" / "studies" / "rigid-vs-flexible.png"
MD_OUT = REPO / "docs" / "rigid-vs-flexible.md"


def summarise(out: dict) -> dict:
    """The recorded numbers of one service answer."""
    zones = [
        {
            "name": z["name"],
            "start_mm": z["start_mm"],
            "end_mm": z["end_mm"],
            "length_mm": z["length_mm"],
            "load_share": z["load_share"],
        }
        for z in out["apparent"]["zones"]
    ]
    rear = sum(z["load_share"] for z in zones if (z["start_mm"] + z["end_mm"]) / 2 < 0)
    rec = {
        "apparent_area_cm2": out["apparent"]["contact_area_cm2"],
        "rear_load_share": rear,
        "zones": zones,
    }
    rec.update({k: out["metrics"][k] for k in METRICS})
    return rec


def rel(a, b):
    if a is None or b is None or b == 0:
        return None
    return (a - b) / b


def run_case(cat, ski: str, e_mpa: float, load_kg: float, pos_mm: float) -> dict:
    case = {"ski": ski, "snow_modulus_mpa": e_mpa, "load_kg": load_kg, "load_position_mm": pos_mm}
    for model in MODELS:
        try:
            out = contact(
                cat,
                ContactInputs(ski, GRIND, load_kg, pos_mm, e_mpa, POROSITY, ski_model=model),
            )
            case[model] = summarise(out)
        except Exception as exc:  # one failing case must not stop the study
            case[model] = {"error": f"{type(exc).__name__}: {exc}"}
    r, f = case["rigid"], case["flexible"]
    if "error" not in r and "error" not in f:
        keys = ["apparent_area_cm2", "rear_load_share", *METRICS]
        case["relative_difference"] = {k: rel(r[k], f[k]) for k in keys}
        case["rear_load_share_abs_difference"] = r["rear_load_share"] - f["rear_load_share"]
        mets = [abs(v) for k in METRICS if (v := case["relative_difference"][k]) is not None]
        case["max_abs_metric_difference"] = max(mets) if mets else None
    return case


def plot(cases: list[dict], skis: list[str], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(
        len(QUANTITIES), len(skis), figsize=(5.5 * len(skis), 2.6 * len(QUANTITIES)), sharex=True
    )
    colours = ["tab:blue", "tab:orange", "tab:green"]
    for j, ski in enumerate(skis):
        for i, (key, label) in enumerate(QUANTITIES):
            ax = axes[i][j] if len(skis) > 1 else axes[i]
            for (kg, mm), c in zip(LOADS, colours, strict=True):
                sel = [
                    x
                    for x in cases
                    if x["ski"] == ski and x["load_kg"] == kg and x["load_position_mm"] == mm
                ]
                for model, ls in (("rigid", "-"), ("flexible", "--")):
                    pts = [
                        (x["snow_modulus_mpa"], x[model][key])
                        for x in sel
                        if "error" not in x[model]
                    ]
                    if pts:
                        xs, ys = zip(*pts, strict=True)
                        ax.plot(
                            xs, ys, ls, color=c, marker=".", label=f"{kg:g} kg @ {mm:g} mm, {model}"
                        )
            ax.set_xscale("log")
            ax.set_ylabel(label)
            ax.grid(True, which="both", alpha=0.3)
            if i == 0:
                ax.set_title(f"{ski} (solid rigid, dashed flexible)")
            if i == len(QUANTITIES) - 1:
                ax.set_xlabel("E_snow [MPa]")
    (axes[0][0] if len(skis) > 1 else axes[0]).legend(fontsize=7)
    fig.tight_layout()
    with common.atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)


def pct(v) -> str:
    return "–" if v is None else f"{100 * v:+.1f} %"


def markdown(cases: list[dict], skis: list[str], command: str, seconds: float) -> str:
    lines = [
        "# Rigid versus flexible ski model",
        "",
        "The service answers either with the rigid-shape ski (`ski_model: rigid`, the ski's shape",
        "is not changed by the snow pressure) or with the bending ski on the elastic snow",
        "(`ski_model: flexible`). This page compares the two through `app.service.contact`",
        f"for both demo skis, grind `{GRIND}`, porosity {POROSITY}, default preset.",
        "",
        f"Made with (run time {seconds:.0f} s):",
        "",
        "```text",
        command,
        "```",
        "",
        "Numbers: [`studies/rigid-vs-flexible.json`](studies/rigid-vs-flexible.json). Each cell",
        "below is (rigid − flexible) / flexible of apparent area / rear load share / largest",
        "|difference| among the four metrics; – where the flexible value is 0 (no rear zone).",
        "Rear load share here is the sum over zones whose midpoint lies at x < 0 (the ski's",
        "coordinate origin); the service's `auto` check uses the pressure behind the load position",
        "and compares it as an absolute difference, so its numbers differ from these.",
        "",
    ]
    for ski in skis:
        lines += [f"## {ski}", ""]
        head = "| E_snow [MPa] | " + " | ".join(f"{kg:g} kg @ {mm:g} mm" for kg, mm in LOADS) + " |"
        lines += [head, "|---:|" + "---|" * len(LOADS)]
        for e in E_SNOW_MPA:
            cells = []
            for kg, mm in LOADS:
                c = next(
                    x
                    for x in cases
                    if x["ski"] == ski
                    and x["snow_modulus_mpa"] == e
                    and x["load_kg"] == kg
                    and x["load_position_mm"] == mm
                )
                if "relative_difference" not in c:
                    cells.append("error")
                    continue
                d = c["relative_difference"]
                m = c["max_abs_metric_difference"]
                cells.append(
                    f"{pct(d['apparent_area_cm2'])} / {pct(d['rear_load_share'])} / "
                    f"{'–' if m is None else f'{100 * m:.1f} %'}"
                )
            lines.append(f"| {e:g} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += [
        "![Rigid (solid) and flexible (dashed) ski model per snow modulus and load]"
        "(studies/rigid-vs-flexible.png)",
        "",
        "## Findings",
        "",
        *findings(cases, skis),
        "",
    ]
    return "\n".join(lines)


def findings(cases: list[dict], skis: list[str]) -> list[str]:
    """Sentences derived from the numbers: where the rigid model is within 2 % and where not."""
    ok = [c for c in cases if "relative_difference" in c]
    failed = len(cases) - len(ok)

    def small(v):
        return v is not None and abs(v) <= TOLERANCE

    def where(sel):
        return (
            ", ".join(f"{c['ski']} {c['snow_modulus_mpa']:g} MPa/{c['load_kg']:g} kg" for c in sel)
            or "none"
        )

    area = [c for c in ok if small(c["relative_difference"]["apparent_area_cm2"])]
    mets = [c for c in ok if small(c["max_abs_metric_difference"])]
    rear = [c for c in ok if small(c["relative_difference"]["rear_load_share"])]
    both = [c for c in area if c in mets and c in rear]
    out = [
        f"Of {len(ok)} cases"
        + (f" ({failed} failed, see the JSON)" if failed else "")
        + f", the rigid model is within 2 % of the flexible one in apparent area in {len(area)}"
        f" ({where(area)}), in all four metrics in {len(mets)} ({where(mets)}) and in rear load"
        f" share in {len(rear)} ({where(rear)}); in all three together in {len(both)}"
        f" ({where(both)})."
    ]
    for ski in skis:
        sc = [c for c in ok if c["ski"] == ski]
        if not sc:
            continue
        a = [c["relative_difference"]["apparent_area_cm2"] for c in sc]
        m = [c["max_abs_metric_difference"] for c in sc]
        r = [c["relative_difference"]["rear_load_share"] for c in sc]
        r = [v for v in r if v is not None]
        out.append(
            f"For {ski} the apparent-area difference runs from {pct(min(a))} to {pct(max(a))}, "
            f"the largest metric difference from {100 * min(m):.1f} % to {100 * max(m):.1f} % "
            f"and the rear-load-share difference from {pct(min(r))} to {pct(max(r))}."
        )
    soft = [c for c in ok if c["snow_modulus_mpa"] <= 20]
    hard = [c for c in ok if c["snow_modulus_mpa"] >= 200]
    for name, sel in (("soft snow (E_snow ≤ 20 MPa)", soft), ("hard snow (≥ 200 MPa)", hard)):
        if sel:
            med = sorted(abs(c["relative_difference"]["apparent_area_cm2"]) for c in sel)
            out.append(
                f"On {name} the median |apparent-area difference| is "
                f"{100 * med[len(med) // 2]:.1f} %."
            )
    return [" ".join(out)]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--tables-dir", type=Path, default=REPO / "tables")
    p.add_argument("--skis", nargs="+", default=["ski-a", "ski-b"])
    args = p.parse_args(argv)

    t0 = time.perf_counter()
    cat = load_catalogue(args.tables_dir)
    cases = []
    n = len(args.skis) * len(E_SNOW_MPA) * len(LOADS)
    for ski in args.skis:
        for e in E_SNOW_MPA:
            for kg, mm in LOADS:
                c = run_case(cat, ski, float(e), kg, mm)
                cases.append(c)
                d = c.get("relative_difference")
                msg = (
                    f"area {pct(d['apparent_area_cm2'])}, rear {pct(d['rear_load_share'])}, "
                    f"metrics max {100 * (c['max_abs_metric_difference'] or 0):.1f} %"
                    if d
                    else f"error rigid={c['rigid'].get('error')} "
                    f"flexible={c['flexible'].get('error')}"
                )
                print(
                    f"[{len(cases)}/{n}] {ski} E={e:g} MPa {kg:g} kg @ {mm:g} mm: {msg}", flush=True
                )
    seconds = time.perf_counter() - t0

    params = {
        "skis": args.skis,
        "grind": GRIND,
        "porosity": POROSITY,
        "snow_modulus_mpa": E_SNOW_MPA,
        "loads_kg_position_mm": LOADS,
        "tables_dir": str(args.tables_dir),
    }
    doc = {
        "provenance": common.provenance(params),
        "parameters": params,
        "run_time_s": round(seconds, 1),
        "cases": cases,
    }
    with common.atomic_path(JSON_OUT) as tmp:
        tmp.write_text(json.dumps(doc, indent=1) + "\n")
    plot(cases, args.skis, PNG_OUT)
    command = "python scripts/rigid_vs_flexible.py" + (
        " " + " ".join(sys.argv[1:]) if argv is None and sys.argv[1:] else ""
    )
    with common.atomic_path(MD_OUT) as tmp:
        tmp.write_text(markdown(cases, args.skis, command, seconds))
    print(f"wrote {JSON_OUT}, {PNG_OUT}, {MD_OUT} in {seconds:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
