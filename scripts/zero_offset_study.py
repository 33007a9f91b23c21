"""How small is a load case's smallest gap when the device is zeroed on the flat? The basis of
the upload check for a device zero set below the flat (issue #26 point 5,
:data:`app.jobs.uploads.ZERO_OFFSET_LIMIT_MM`, docs/uploads.md "Zero offset").

A ski pressed on the flat touches it, so the gap reads 0 (± the device noise) somewhere in each
load case. The upload needs samples every ≤ 5 mm over ≥ 80 % of the ski's length, so the
touching part lies among the samples when the contact lies within that span. This measures
it: every study and validation design and ``random-0`` … ``random-<n-1>``, measured by the
virtual device (:func:`solvers.beam.measure_camber`) at the coarse grid of the own-ski study (9
loads 10–90 kg × 5 load positions −300 … +100 mm), 3 µm noise, then sampled every 5 mm (a
random start) over the central 80 % of the beam. Per design: each load case's smallest gap,
its largest over the cases and the median over the cases. Then, for each offset tried, how
many designs the check flags (the median above the limit): 0 at no offset is the false
alarm rate on these designs.

Seconds. Usage::

    python scripts/zero_offset_study.py [--randoms 300] [--out docs/studies/zero-offset.json]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app.evidence.identification import (  # noqa: E402
    GRIDS,
    LOAD_RANGE_KG,
    NOISE_M,
    POSITION_RANGE_M,
)
from skisnow.app.jobs.uploads import (  # noqa: E402
    MAX_SAMPLE_SPACING_MM,
    MIN_SPAN_FRACTION,
    ZERO_OFFSET_LIMIT_MM,
)
from skisnow.app.storage import common  # noqa: E402
from skisnow.solvers.beam import G_STANDARD, measure_camber  # noqa: E402
from skisnow.solvers.ski_designs import (  # noqa: E402
    STUDY_DESIGNS,
    VALIDATION_DESIGNS,
    random_design,
)

SCHEMA = "skisnow.zero-offset-study/1"
SEED = 2_612_07
OFFSETS_MM = (0.0, 0.01, 0.02, 0.03, 0.05, 0.1)
OUT = REPO / "docs" / "studies" / "zero-offset.json"


def smallest_gaps_mm(design, rng: np.random.Generator) -> np.ndarray:
    """Each loaded case's smallest sampled gap [mm] of ``design`` as the upload's sparsest
    accepted file would sample it (module docstring)."""
    beam = design.build(1e-3)
    x = beam.positions_m
    n_loads, n_positions = GRIDS["coarse"]
    loads = np.linspace(*LOAD_RANGE_KG, n_loads) * G_STANDARD
    positions = np.linspace(*POSITION_RANGE_M, n_positions)
    _, _, y = measure_camber(beam, loads, positions, noise_m=NOISE_M, rng=rng)
    centre, length = 0.5 * (x[0] + x[-1]), x[-1] - x[0]
    inside = np.flatnonzero(np.abs(x - centre) <= MIN_SPAN_FRACTION * length / 2)
    step = round(MAX_SAMPLE_SPACING_MM * 1e-3 / float(x[1] - x[0]))  # nodes per sample
    kept = inside[int(rng.integers(step)) :: step]
    return y[:, kept].min(axis=1) * 1e3


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--randoms", type=int, default=300, help="random designs 0 … n-1")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(SEED)
    designs = {**STUDY_DESIGNS, **VALIDATION_DESIGNS}
    designs.update({f"random-{s}": random_design(s)[1] for s in range(args.randoms)})
    rows = []
    for name, design in designs.items():
        g = smallest_gaps_mm(design, rng)
        rows.append(
            {"design": name, "largest_mm": float(g.max()), "median_mm": float(np.median(g))}
        )
    medians = np.array([r["median_mm"] for r in rows])
    flagged = {f"{o:g}": int(np.sum(medians + o > ZERO_OFFSET_LIMIT_MM)) for o in OFFSETS_MM}
    body = {
        "designs": len(rows),
        "limit_mm": ZERO_OFFSET_LIMIT_MM,
        "largest_case_minimum_mm": float(max(r["largest_mm"] for r in rows)),
        "median_range_mm": [float(medians.min()), float(medians.max())],
        "flagged_per_offset_mm": flagged,
        "rows": rows,
    }
    params = {"randoms": args.randoms, "seed": SEED, "offsets_mm": OFFSETS_MM}
    common.write_study_json(args.out, SCHEMA, params, body)
    print(
        f"{len(rows)} designs: largest case minimum {body['largest_case_minimum_mm'] * 1e3:.2f} µm,"
        f" medians {medians.min() * 1e3:.2f} … {medians.max() * 1e3:.2f} µm; flagged of "
        f"{len(rows)} per offset [mm]: {flagged}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
