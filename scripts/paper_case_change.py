"""The change in each paper-case metric between two runs of ``skisnow report paper-case``.

Usage: ``python scripts/paper_case_change.py OLD.json NEW.json [--md OUT.md]``

Compares the four functional parameters and the apparent contact area of every ski × grind
case of the two ``docs/paper-case/paper-case.json`` files (same inputs required) and prints a
Markdown table of old, new and relative change, with the tables' provenance (data sha256) of
each run, so a table rebuild's effect on the published case is on record.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

METRICS = {
    "total_real_contact_area_mm2": ("real contact area", "mm²"),
    "average_real_contact_pressure_mpa": ("average real pressure", "MPa"),
    "min_average_separation_um": ("min. average separation", "µm"),
    "total_reciprocal_separation_m": ("total reciprocal separation", "m"),
}


def _cases(doc: dict) -> dict[tuple[str, str], dict]:
    return {(r["inputs"]["ski"], r["inputs"]["grind"]): r for r in doc["results"]}


def change_table(old: dict, new: dict) -> list[str]:
    """Markdown lines: one row per case and quantity (old, new, change in %)."""
    a, b = _cases(old), _cases(new)
    if set(a) != set(b):
        raise SystemExit(f"the runs have different cases: {sorted(a)} vs {sorted(b)}")
    lines = ["| ski | grind | quantity | before | after | change |", "|---|---|---|---|---|---|"]
    for key in sorted(a):
        # an input a run did not record (added later) and one recorded as None are the same
        ia = {k: v for k, v in a[key]["inputs"].items() if k != "preset" and v is not None}
        ib = {k: v for k, v in b[key]["inputs"].items() if k != "preset" and v is not None}
        if ia != ib:
            raise SystemExit(f"{key}: different inputs {ia} vs {ib}")
        rows = [
            (label, unit, a[key]["metrics"][m], b[key]["metrics"][m])
            for m, (label, unit) in METRICS.items()
        ]
        rows.append(
            (
                "apparent contact area",
                "cm²",
                a[key]["apparent"]["contact_area_cm2"],
                b[key]["apparent"]["contact_area_cm2"],
            )
        )
        for label, unit, x, y in rows:
            lines.append(
                f"| {key[0]} | {key[1]} | {label} [{unit}] | {x:.4g} | {y:.4g} | "
                f"{(y - x) / x * 100:+.1f} % |"
            )
    return lines


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("old", type=Path)
    p.add_argument("new", type=Path)
    p.add_argument("--md", type=Path, help="also write the table to this Markdown file")
    args = p.parse_args(argv)
    old, new = (json.loads(f.read_text()) for f in (args.old, args.new))
    lines = change_table(old, new)
    text = "\n".join(lines) + "\n"
    print(text)
    if args.md:
        args.md.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
