"""Flexible against rigid solve per case, the two alternated in one process (issue #12).

For each demo ski and case (load, position, snow modulus): the rigid solve of the ski's loaded
profile (the profile model as the service calls it) and the flexible solve (cold, row-level
start), alternated ``repeats`` times; prints both medians [ms], the median of the per-pair
ratios flexible / rigid, CG iterations and active-set updates. Ratios from one run are what
counts on a shared machine. Run from the repository root (to compare two commits, run a copy
in each tree, alternating):

    python scripts/flexible_speed.py [repeats] [paper|all]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from skisnow.app import service
from skisnow.app.service.profiles import profile_model
from skisnow.app.storage.skis import SHIPPED_SKI_DIR as SKI_DIR
from skisnow.solvers.beam import G_STANDARD
from skisnow.solvers.elastic import effective_modulus
from skisnow.solvers.flexible import prepare_flexible, solve_flexible
from skisnow.solvers.macro import extrude_profile, solve_macro

#: (load [kg], position [mm], snow modulus [MPa]); the papers' case first
CASES = {
    "paper": [(40, -160, 200)],
    "all": [
        (40, -160, 200),
        (40, -160, 2),
        (40, -160, 2000),
        (10, -300, 200),
        (90, 100, 200),
        (10, 100, 200),
        (90, -300, 200),
    ],
}


def main(repeats: int = 15, which: str = "paper") -> None:
    cat = service.load_catalogue(SKI_DIR.parent)
    for name in ("ski-a", "ski-b"):
        rec = cat.ski(name).record
        beam, _ = cat.ski(name).beam()
        pm = profile_model(rec)
        model = prepare_flexible(
            beam, rec.outline.width_m, width_positions_m=rec.outline.positions_m
        )
        for kg, mm, mpa in CASES[which]:
            e_eff = effective_modulus(mpa * 1e6, 0.7e9, 0.3)
            f, xf = kg * G_STANDARD, mm * 1e-3
            x, g = pm(f, xf)
            gm = extrude_profile(
                x, g, rec.outline.width_m, width_positions_m=rec.outline.positions_m
            )
            solve_macro(gm, f, xf, e_eff)  # warm-up
            res = solve_flexible(model, f, xf, e_eff)
            t_rigid, t_flex = [], []
            for _ in range(repeats):
                t0 = time.perf_counter()
                solve_macro(gm, f, xf, e_eff)
                t_rigid.append(time.perf_counter() - t0)
                t0 = time.perf_counter()
                solve_flexible(model, f, xf, e_eff)
                t_flex.append(time.perf_counter() - t0)
            ratio = float(np.median(np.array(t_flex) / np.array(t_rigid)))
            print(
                f"{name} {kg:3d} kg {mm:+5d} mm {mpa:5g} MPa: rigid "
                f"{np.median(t_rigid) * 1e3:6.2f} ms, flexible {np.median(t_flex) * 1e3:6.2f} ms,"
                f" ratio {ratio:4.2f}, {res.iterations} CG iterations,"
                f" {res.extra['set_updates']} sets"
            )


if __name__ == "__main__":
    main(
        int(sys.argv[1]) if len(sys.argv) > 1 else 15,
        sys.argv[2] if len(sys.argv) > 2 else "paper",
    )
