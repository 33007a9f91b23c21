"""How well the identification's covariance describes the error of its EI(X): the plain
pseudo-inverse of before 2026-11-27 against the Jacobi-scaled inverse (docs/limits.md, "The
covariance's cut-off").

For each ski file of an own-ski study work folder (``scripts/own_ski_study.py --work``) whose
identification passed: the forward fit is evaluated again at the served beam on the same
cases (the stored held-out cases left out; one step from the converged fit, no continuation),
once with each inverse, and per stiffness knot z = |log EI_served − log EI_true| ÷ the
covariance's standard deviation of log EI (the truth: the design's own beam,
``solvers.ski_designs.get_design``). A calibrated covariance has a median z of about 0.67 and
about 95 % of knots within 2 σ.

Usage::

    python scripts/covariance_z_scores.py <work>/skis [<work>/skis ...] \\
        --out docs/studies/covariance-z-scores.json

About 15 s per ski on 2 cores.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import h5py
import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app.storage import common  # noqa: E402
from skisnow.app.storage.skis import mean_profiles, read_ski  # noqa: E402
from skisnow.solvers import beam_fit  # noqa: E402
from skisnow.solvers.beam import BeamSki  # noqa: E402
from skisnow.solvers.identify import DEFAULT_SMOOTHING  # noqa: E402
from skisnow.solvers.ski_designs import get_design  # noqa: E402

SCHEMA = "skisnow.covariance-z-scores/1"
#: the knots of the median z: the ski's middle, where answers depend on EI [m]
MIDDLE_M = 0.6


def _plain_inverse(h: np.ndarray) -> np.ndarray:
    """The inverse before the fix: ``pinv`` cut at 1e-15 × the largest singular value."""
    return np.linalg.pinv(h, hermitian=True)


def refit_covariance(path: Path, inverse) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(knots [m], served log EI at the knots, sd of log EI) of the forward fit evaluated at
    the ski file's served beam with ``inverse`` as the normal matrix's inverse."""
    rec = read_ski(path)
    with h5py.File(path, "r") as f:
        g = f["identified"]
        knots = g["knots_m"][:]
        x = g["positions_m"][:]
        beam = BeamSki(x, g["bending_stiffness_nm2"][:], g["unloaded_gap_m"][:])
        noise = float(g.attrs["noise_m"])
        kinks = g["kinks_m"][:]
        held = g["held_out_index"][:]
    loads, xfs, y, _ = mean_profiles(rec.measurements)
    keep = np.ones(loads.size, dtype=bool)
    keep[held] = False
    saved = beam_fit._scaled_inverse
    beam_fit._scaled_inverse = inverse
    try:
        fit = beam_fit.fit_forward(
            rec.measurements.positions_m,
            loads[keep],
            xfs[keep],
            y[keep],
            beam,
            noise_m=noise,
            stiffness_knots_m=knots,
            smoothing=DEFAULT_SMOOTHING,
            kinks_m=kinks,
            max_steps=1,
            foundation_length_m=0.0,
            coarse_spacing_m=0.0,
        )
    finally:
        beam_fit._scaled_inverse = saved
    nc = fit.camber_coefficients.size
    sd = np.sqrt(np.maximum(np.diag(fit.covariance)[nc:], 0.0))
    log_ei = np.log(np.interp(knots, x, beam.bending_stiffness_nm2))
    return knots, log_ei, sd


def ski_z_scores(path: Path) -> dict:
    name = path.stem
    truth = get_design(name.rsplit("-", 2)[0]).build()
    out = {"ski": name}
    for label, inverse in (("plain", _plain_inverse), ("scaled", beam_fit._scaled_inverse)):
        knots, log_ei, sd = refit_covariance(path, inverse)
        true_log_ei = np.log(np.interp(knots, truth.positions_m, truth.bending_stiffness_nm2))
        err = np.abs(log_ei - true_log_ei)
        with np.errstate(divide="ignore"):
            z = err / sd
        mid = np.abs(knots) < MIDDLE_M
        out[label] = {
            "median_z_middle": float(np.median(z[mid])),
            "max_z": float(np.max(z)),
            "share_within_2_sd": float(np.mean(z <= 2.0)),
            "zero_sd_knots": int(np.sum(sd == 0.0)),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folders", type=Path, nargs="+", help="own-ski study work/skis folders")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args(argv)
    rows = []
    for folder in args.folders:
        for path in sorted(folder.glob("*.h5")):
            with h5py.File(path, "r") as f:
                if not f["identified"].attrs.get("ok", False):
                    continue
            r = ski_z_scores(path)
            rows.append(r)
            p, s = r["plain"], r["scaled"]
            print(
                f"| {r['ski']} | {p['median_z_middle']:.2f} → {s['median_z_middle']:.2f} | "
                f"{p['max_z']:.3g} → {s['max_z']:.3g} | "
                f"{p['share_within_2_sd']:.0%} → {s['share_within_2_sd']:.0%} |",
                flush=True,
            )
    if args.out:
        params = {"folders": [str(f) for f in args.folders], "middle_m": MIDDLE_M}
        common.write_study_json(args.out, SCHEMA, params, {"skis": rows})
        print("written", args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
