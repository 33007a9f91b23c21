"""Check the shipped tables' pixel-size error estimate against finer solves (issue #13 point 3).

At chosen nodes of a shipped table of two or three pixel levels, solve the same surface at the
given sizes: below the texture's by block average, 1024² (the texture), above it refined by its
generator (:func:`app.storage.textures.refined_texture`: 2048², 4096², 8192²), and compare the
stored value and its estimate with the zero-pixel limit from the two finest sizes given
(Richardson, order 1). Writes JSON lines (one per node) to stdout, with the table's per-level
values and, for three-level tables, the observed order and the estimate rule at the node;
docs/studies/table-pixel-checks.json holds runs, docs/tables.md the tables made from them.

Usage::

    python scripts/table_pixel_check.py grind-2 --nodes 37 42 46 50 54 60 > out.jsonl
    python scripts/table_pixel_check.py grind-2 --nodes 38 --sizes 4096 8192 --table-levels

A 4096² solve takes 25–35 s on one core, an 8192² solve a few minutes and ~6 GB; run them on
a quiet machine.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from skisnow.app.storage.common import tables_dir
from skisnow.app.storage.tables import read_table
from skisnow.app.storage.textures import read_texture, refined_texture
from skisnow.solvers.lookup import ERROR_FIELDS, richardson
from skisnow.solvers.micro import solve_micro


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("grind", help="shipped grind name (grind-1, grind-2)")
    parser.add_argument("--nodes", type=int, nargs="+", required=True, help="table node indices")
    parser.add_argument(
        "--sizes", type=int, nargs="+", default=[512, 1024, 2048, 4096], help="grid sizes"
    )
    parser.add_argument(
        "--table-levels",
        action="store_true",
        help="take the table's own value at sizes it stores as a level instead of solving",
    )
    args = parser.parse_args(argv)

    table = read_table(tables_dir() / f"{args.grind}.h5")
    e = table.effective_modulus_pa
    base = read_texture(tables_dir() / "textures" / f"{args.grind}.h5")
    n = base.heights_m.shape[0]
    levels = {}
    for size in args.sizes:
        if size < n:
            k = n // size
            h = base.heights_m.reshape(size, k, size, k).mean(axis=(1, 3))
            levels[size] = (h, base.pixel_size_m * k)
        elif size == n:
            levels[size] = (base.heights_m, base.pixel_size_m)
        else:
            t = refined_texture(args.grind, size // n)
            levels[size] = (t.heights_m, t.pixel_size_m)
    finest = sorted(levels)[-2:]
    stored_levels = {}
    if args.table_levels and table.levels is not None:
        for i, dx in enumerate(table.levels["pixel_size_m"]):
            stored_levels[round(n * base.pixel_size_m / float(dx))] = i
    for node in args.nodes:
        ratio = float(table.pressure_ratio[node])
        row = {"grind": args.grind, "node": node, "pressure_ratio": ratio, "levels": {}}
        for size, (h, dx) in sorted(levels.items()):
            if size in stored_levels:
                i = stored_levels[size]
                row["levels"][size] = {
                    **{q: float(table.levels[q][i, node]) for q in ERROR_FIELDS},
                    "from_table": True,
                }
                continue
            t0 = time.perf_counter()
            res = solve_micro(h, dx, ratio * e, e, tol=table.tol, gap_floor_m=table.gap_floor_m)
            row["levels"][size] = {
                **{q: float(getattr(res, q)) for q in ERROR_FIELDS},
                "iterations": res.iterations,
                "converged": bool(res.converged),
                "time_s": time.perf_counter() - t0,
            }
        a = [row["levels"][s]["real_contact_area_fraction"] for s in finest]
        limit, _ = richardson(a[0], a[1], 1.0)
        stored = float(table.real_contact_area_fraction[node])
        claim = (
            float(table.real_contact_area_fraction_error[node])
            if table.has_error_estimates
            else None
        )
        row.update(
            limit_sizes=finest,
            limit_real_contact_area_fraction=float(limit),
            stored_real_contact_area_fraction=stored,
            stored_estimate_rel=None if claim is None else claim / stored,
            stored_minus_limit_rel=stored / limit - 1,
            within_estimate=None if claim is None else bool(abs(stored - limit) <= claim),
        )
        q = "real_contact_area_fraction"
        if table.levels is not None:
            row["table_levels"] = [float(v) for v in table.levels[q][:, node]]
            for key in (f"observed_order_{q}", f"three_level_estimate_{q}"):
                if key in table.levels:
                    row[key] = float(table.levels[key][node])
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
