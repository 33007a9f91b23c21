"""How often does the bending-ski solve (:func:`solvers.flexible.solve_flexible`) fail to converge?

Issue #26 (the own-ski study's non-converged flexible answers): every study design
(:data:`solvers.ski_designs.STUDY_DESIGNS`, true beams at 1 mm) over a grid of loads ×
positions × snow moduli, solved as the service solves them (E' from the snow modulus and the
default base, 44 mm wide as the study's uploads), on up to three grids (``--grids``):

- ``answer``: the default preset's grid, default tolerance, no warm start (the answer);
- ``coarse``: the band's coarse grid (:func:`app.service.band_sampling.coarse_grid`), solved
  as the answer is;
- ``band``: the coarse grid as the band solves its nominal beam: warm-started from the
  answer's line pressure, tolerance ``SAMPLE_TOL``.

Optionally beams perturbed as an identification might miss them (``--perturb N``: N seeded
draws per design of EI × (1 + s_ei·smooth noise) and c + s_c·smooth noise).

Prints one line per non-converged case and a table of counts per design, grid and modulus;
``--json`` writes every case (converged, iterations, set updates, residual, time, message).

Usage::

    python scripts/flexible_convergence_scan.py [--designs binding-plate ...] [--loads 20 30 ...]
        [--positions -100 -80 ...] [--moduli 20 200 2000] [--grids answer,coarse,band]
        [--perturb 0] [--seed 2026] [--json out.json]
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app.presets import get_preset  # noqa: E402
from skisnow.app.service.band_sampling import SAMPLE_TOL, coarse_grid  # noqa: E402
from skisnow.solvers.beam import G_STANDARD, BeamSki  # noqa: E402
from skisnow.solvers.elastic import effective_modulus  # noqa: E402
from skisnow.solvers.flexible import prepare_flexible, solve_flexible  # noqa: E402
from skisnow.solvers.ski_designs import STUDY_DESIGNS  # noqa: E402

#: the study's uploaded outline: 44 mm wide from tail to tip
WIDTH_M = 0.044
LOADS_KG = (20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0)
POSITIONS_MM = (-100.0, -80.0, -60.0, -40.0, -20.0, 0.0, 20.0, 40.0, 60.0)
MODULI_MPA = (20.0, 200.0, 2000.0)
BASE_MODULUS_PA = 700e6
POISSON = 0.3


def perturbed(beam: BeamSki, rng: np.random.Generator, s_ei: float, s_c_m: float) -> BeamSki:
    """EI × (1 + s_ei · g1) and c + s_c · g2 with g smooth (5 random Fourier modes) [-, m]."""
    x = beam.positions_m
    s = (x - x[0]) / np.ptp(x)

    def smooth() -> np.ndarray:
        k = np.arange(1, 6)
        a = rng.normal(size=5) / k
        ph = rng.uniform(0, 2 * np.pi, size=5)
        g = (a[:, None] * np.sin(np.pi * k[:, None] * s[None, :] + ph[:, None])).sum(axis=0)
        return g / max(np.max(np.abs(g)), 1e-30)

    ei = beam.bending_stiffness_nm2 * (1.0 + s_ei * smooth())
    c = beam.unloaded_gap_m + s_c_m * smooth()
    return BeamSki(x, ei, c - c.min())


def solve_case(
    model, kg: float, mm: float, e_mpa: float, tol: float = 1e-8, start_pa=None
) -> tuple[dict, object]:
    """One solve as the service runs it (the answer: default tolerance, no warm start);
    returns (the case's numbers, the MacroResult)."""
    e_eff = effective_modulus(e_mpa * 1e6, BASE_MODULUS_PA, POISSON)
    t0 = time.perf_counter()
    r = solve_flexible(
        model, kg * G_STANDARD, mm * 1e-3, e_eff, tol=tol, initial_pressure_pa=start_pa
    )
    case = {
        "snow_modulus_mpa": e_mpa,
        "load_kg": kg,
        "load_position_mm": mm,
        "converged": bool(r.converged),
        "iterations": int(r.iterations),
        "set_updates": int(r.extra.get("set_updates", -1)),
        "residual": float(r.residual),
        "time_s": time.perf_counter() - t0,
        "area_cm2": float(r.apparent_contact_area_m2 * 1e4),
        "message": r.message,
    }
    return case, r


def study_beams(
    designs, perturb: int, seed: int, ei_scale: float = 0.05, c_scale_m: float = 5e-6
) -> list[tuple[str, str, BeamSki]]:
    """(design, label, beam): each design's true beam ("true") and ``perturb`` perturbed ones
    ("p0", "p1", ...), drawn in this order from one generator seeded ``seed``."""
    rng = np.random.default_rng(seed)
    out = []
    for name in designs:
        truth = STUDY_DESIGNS[name].build(1e-3)
        out.append((name, "true", truth))
        for k in range(perturb):
            out.append((name, f"p{k}", perturbed(truth, rng, ei_scale, c_scale_m)))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--designs", nargs="*", default=list(STUDY_DESIGNS))
    ap.add_argument("--loads", nargs="*", type=float, default=list(LOADS_KG))
    ap.add_argument("--positions", nargs="*", type=float, default=list(POSITIONS_MM))
    ap.add_argument("--moduli", nargs="*", type=float, default=list(MODULI_MPA))
    ap.add_argument("--grids", default="answer,coarse")
    ap.add_argument("--perturb", type=int, default=0, help="perturbed beams per design")
    ap.add_argument("--ei-scale", type=float, default=0.05, help="relative EI perturbation")
    ap.add_argument("--c-scale-um", type=float, default=5.0, help="camber perturbation [µm]")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)

    preset = get_preset("default")
    spacing = {
        "answer": (preset.pixel_along_m, preset.pixels_across),
        "coarse": coarse_grid(preset),
        "band": coarse_grid(preset),
    }
    grids = args.grids.split(",")
    cases = []
    counts: dict[tuple, list[int]] = {}
    t_all = time.perf_counter()
    beams = study_beams(
        args.designs, args.perturb, args.seed, args.ei_scale, args.c_scale_um * 1e-6
    )
    for name, label, beam in beams:
        models = {
            g: prepare_flexible(beam, WIDTH_M, pixel_along_m=dx, pixels_across=ny)
            for g, (dx, ny) in spacing.items()
            if g in grids or (g == "answer" and "band" in grids)
        }
        for e_mpa, kg, mm in itertools.product(args.moduli, args.loads, args.positions):
            done = {}
            for gname in ("answer", "coarse", "band"):
                if gname not in models:
                    continue
                if gname == "band":
                    # as app.service.band_sampling solves the nominal coarse beam: warm-started
                    # from the answer's line pressure, at SAMPLE_TOL
                    ans = done["answer"][1]
                    m = models["band"]
                    inside = np.isfinite(m.unloaded_map.gap_m)
                    line = np.interp(
                        m.positions_m, ans.positions_m, np.nan_to_num(ans.pressure_line_pa)
                    )
                    start = np.where(inside, line[:, None], 0.0)
                    done[gname] = solve_case(m, kg, mm, e_mpa, SAMPLE_TOL, start)
                else:
                    done[gname] = solve_case(models[gname], kg, mm, e_mpa)
                if gname not in grids:
                    continue
                case = done[gname][0]
                case.update(design=name, beam=label, grid=gname)
                cases.append(case)
                tally = counts.setdefault((name, gname, e_mpa), [0, 0])
                tally[0] += 1
                tally[1] += int(not case["converged"])
                if not case["converged"]:
                    print(
                        f"NOT CONVERGED {name} {label} {gname} {e_mpa:g} MPa {kg:g} kg "
                        f"{mm:+g} mm: {case['message']}",
                        flush=True,
                    )
    print(f"\n{'design':16s} {'grid':7s} {'MPa':>6s} {'failed':>7s} / cases")
    for (name, gname, e_mpa), (n, bad) in counts.items():
        print(f"{name:16s} {gname:7s} {e_mpa:6g} {bad:7d} / {n}")
    total = sum(v[0] for v in counts.values())
    bad = sum(v[1] for v in counts.values())
    times = np.array([c["time_s"] for c in cases])
    print(
        f"total {bad} / {total} not converged; solve time median {np.median(times) * 1e3:.1f} ms, "
        f"max {times.max() * 1e3:.0f} ms; wall {time.perf_counter() - t_all:.0f} s"
    )
    if args.json:
        args.json.write_text(json.dumps({"cases": cases}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
