"""Which reduction of a large map keeps the real contact area fraction a_r closer: a centred crop
or a block average (docs/topography.md, "Large maps").

For each shipped grind texture a ``SIDE``-point patch is the reference (solved whole, mirror
periodisation); it is then reduced 2× per side both ways (solvers.measured.reduce_map) and
solved again at the same P_n / E'. Prints a_r of each and the relative error of the reduced
maps. Run: ``python scripts/measure_map_reduction.py`` (a few CPU minutes).
"""

from __future__ import annotations

import sys
import time

import numpy as np
from skisnow.app.storage.textures import SHIPPED_TEXTURES_DIR, read_texture
from skisnow.solvers.measured import reduce_map
from skisnow.solvers.micro import solve_micro
from skisnow.solvers.texture import make_periodic

SIDE = 256  # reference patch [points]
RATIOS = (1e-3, 1e-2)  # P_n / E' [-]
MODULUS_PA = 1e8


def contact_fraction(h: np.ndarray, px: float, ratio: float) -> float:
    r = solve_micro(make_periodic(h, "mirror"), px, ratio * MODULUS_PA, MODULUS_PA, tol=1e-5)
    return float(r.real_contact_area_fraction)


def main() -> int:
    limit = (SIDE // 2) ** 2 * 4  # solve points after mirror: a SIDE/2 map
    print("grind   P/E'    a_r full   crop (err)          block (err)")
    for name in ("grind-1", "grind-2"):
        tex = read_texture(SHIPPED_TEXTURES_DIR / f"{name}.h5")
        h = tex.heights_m[:SIDE, :SIDE] - tex.heights_m[:SIDE, :SIDE].mean()
        crop = reduce_map(h, tex.pixel_size_m, "crop", max_solve_points=limit)
        block = reduce_map(h, tex.pixel_size_m, "block", max_solve_points=limit)
        for ratio in RATIOS:
            t0 = time.time()
            full = contact_fraction(h, tex.pixel_size_m, ratio)
            c = contact_fraction(crop.heights_m, crop.pixel_size_m, ratio)
            b = contact_fraction(block.heights_m, block.pixel_size_m, ratio)
            print(
                f"{name} {ratio:7.0e} {full:9.5f}  {c:9.5f} ({(c - full) / full:+6.1%})  "
                f"{b:9.5f} ({(b - full) / full:+6.1%})   [{time.time() - t0:.0f} s]",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
