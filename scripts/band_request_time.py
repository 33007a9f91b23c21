"""Request time of one answer with its band (issue #26 point 4: before/after the flat-base
regime and the network factor).

Median wall time of ``--repeats`` calls of :func:`app.service.contact` after one warm-up, and
the median of the answer's own ``timing_ms.band``. Run it on two checkouts alternately (the
machine's load changes) to compare them.

Usage::

    python scripts/band_request_time.py --ski ski-a --load-kg 40 --position-mm -160
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app import service  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ski", default="ski-a")
    ap.add_argument("--load-kg", type=float, default=40.0)
    ap.add_argument("--position-mm", type=float, default=-160.0)
    ap.add_argument("--snow-mpa", type=float, default=200.0)
    ap.add_argument("--repeats", type=int, default=15)
    args = ap.parse_args(argv)
    cat = service.load_catalogue(REPO / "tables")
    inp = service.ContactInputs(
        args.ski, "grind-1", args.load_kg, args.position_mm, args.snow_mpa, 0.5, ski_model="rigid"
    )
    service.contact(cat, inp)
    total, band = [], []
    for _ in range(args.repeats):
        t = time.perf_counter()
        a = service.contact(cat, inp)
        total.append(time.perf_counter() - t)
        band.append(a["timing_ms"]["band"])
    print(f"total ms median {np.median(total) * 1e3:.1f} band ms median {np.median(band):.1f}")


if __name__ == "__main__":
    main()
