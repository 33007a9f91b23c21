"""Compiled vs reference active-set loop of :func:`solvers.beam.solve_beam_contact` (issue #12).

Median wall time per call on ski-b's stored beam and identified beam (rigid flat, cached
flexibility), loads 5-150 kg at -300..+100 mm, the two loops alternated in one process, and the
largest relative difference of the reactions and gaps. Run from the repository root:

    python scripts/beam_contact_speed.py [rounds]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from skisnow.app.storage.skis import identified_beam, read_ski
from skisnow.solvers.beam import (
    G_STANDARD,
    BeamFlexibility,
    _solve_beam_contact_reference,
    solve_beam_contact,
)


def main(rounds: int = 3) -> None:
    rec = read_ski(Path(__file__).resolve().parents[1] / "tables" / "skis" / "ski-b.h5")
    cases = []
    for beam in (rec.beam, identified_beam(rec.identified)):
        flex = BeamFlexibility(beam)
        solve_beam_contact(beam, 10.0, 0.0, flexibility=flex)  # compile, cache the columns
        for kg in (5, 40, 75, 150):
            for pos_mm in (-300, -100, 0, 100):
                cases.append((beam, flex, kg * G_STANDARD, pos_mm * 1e-3))
    t_ref, t_new, diff = [], [], 0.0
    for rnd in range(rounds):
        for beam, flex, f, xf in cases:
            order = (0, 1) if rnd % 2 == 0 else (1, 0)
            out = [None, None]
            for which in order:
                fn = _solve_beam_contact_reference if which == 0 else solve_beam_contact
                t = time.perf_counter()
                out[which] = fn(beam, f, xf, flexibility=flex)
                (t_ref if which == 0 else t_new).append(time.perf_counter() - t)
            for field in ("reaction_n", "gap_m"):
                a, b = getattr(out[0], field), getattr(out[1], field)
                diff = max(diff, float(np.abs(a - b).max() / np.abs(a).max()))
    t_ref, t_new = np.array(t_ref), np.array(t_new)
    print(
        f"{t_ref.size} calls each: median reference {np.median(t_ref) * 1e3:.2f} ms, "
        f"compiled {np.median(t_new) * 1e3:.3f} ms, median per-call ratio "
        f"{np.median(t_new / t_ref):.4f}; largest rel. difference {diff:.1e}"
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
