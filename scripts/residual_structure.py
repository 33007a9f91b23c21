"""Does a ski's camber data show that its identified beam is structurally wrong? (issue #26,
docs/limits.md "Why the three band targets do not all hold at once").

For each ski file given, the served identified beam is run through the device model
(:func:`solvers.identify.predict_gaps`: every measured case, the point load on the rigid flat)
and its residuals against the measured profiles are examined where H* < 0.2 mm:

- the RMS residual [µm] (the device noise, if the beam is right);
- the lag-1 autocorrelation along X (0 for white noise);
- the RMS of the residual averaged over a 51-point window [µm], against the value white noise of
  that RMS would give (RMS / √51). A beam that misses a shape the data resolve (an EI step
  smoothed by the spline) leaves a residual correlated along the ski, and this ratio above 1.

Usage::

    python scripts/residual_structure.py <ski.h5> [<ski.h5> ...]

Seconds per ski. Prints one line per ski and writes nothing.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app.service.profiles import served_beam  # noqa: E402
from skisnow.app.storage.skis import read_ski  # noqa: E402
from skisnow.solvers.identify import predict_gaps  # noqa: E402

NEAR_M = 0.2e-3
HALF_WINDOW = 25


def residual_structure(measured_m: np.ndarray, predicted_m: np.ndarray) -> dict:
    """Residual statistics of profiles (K, N) [m] where the measured gap is below
    :data:`NEAR_M` (module docstring)."""
    r = np.where(measured_m < NEAR_M, measured_m - predicted_m, np.nan)
    a, c = r[:, :-1], r[:, 1:]
    ok = np.isfinite(a) & np.isfinite(c)
    ac1 = float(np.sum(a[ok] * c[ok]) / np.sqrt(np.sum(a[ok] ** 2) * np.sum(c[ok] ** 2)))
    kernel = np.ones(2 * HALF_WINDOW + 1)
    means = []
    for row in r:
        s = np.convolve(np.nan_to_num(row), kernel, "same")
        n = np.convolve(np.isfinite(row).astype(float), kernel, "same")
        with np.errstate(invalid="ignore", divide="ignore"):
            means.append(np.where(n >= HALF_WINDOW, s / n, np.nan))
    rms = float(np.sqrt(np.nanmean(r**2)))
    smoothed = float(np.sqrt(np.nanmean(np.square(means))))
    white = rms / np.sqrt(kernel.size)
    return {
        "rms_m": rms,
        "lag1": ac1,
        "smoothed_m": smoothed,
        "smoothed_over_white": smoothed / white,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("skis", nargs="+", type=Path)
    args = ap.parse_args(argv)
    for path in args.skis:
        rec = read_ski(path)
        beam = served_beam(rec.identified)
        if beam is None:
            print(f"{path.name}: no identified beam served")
            continue
        m = rec.measurements
        pred = predict_gaps(beam, m.loads_n, m.load_positions_m)
        pred = np.array([np.interp(m.positions_m, beam.positions_m, p) for p in pred])
        st = residual_structure(m.profiles_m, pred)
        print(
            f"{path.name}: residual RMS {st['rms_m'] * 1e6:.2f} µm, lag-1 autocorrelation "
            f"{st['lag1']:+.4f}, {2 * HALF_WINDOW + 1}-point mean {st['smoothed_m'] * 1e6:.3f} µm "
            f"= {st['smoothed_over_white']:.2f} × white noise"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
