"""How well the flex sheet's band covers the identified beam's actual error (docs/flex.md).

The demo skis are answered by the beam identified from their noisy camber data; their true
(design) beam is stored with them. For body weights over the skis' range, the sheet of the
identified beam (with its band, :mod:`app.service.flex`) is compared with the sheet of the true
beam; per quantity the share of cases where |identified − true| ≤ band is the band's coverage
(target 90 %). Prints one JSON object.

Usage::

    PYTHONPATH=. python scripts/flex_band_check.py [--weights 30 50 70 90 110 130]
"""

from __future__ import annotations

import argparse
import json
import math

from skisnow.app.service import flex, load_catalogue
from skisnow.app.storage.common import tables_dir
from skisnow.solvers.beam import G_STANDARD
from skisnow.solvers.flex import beam_profile, flex_sheet


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--weights", type=float, nargs="+", default=[30, 50, 70, 90, 110, 130])
    ap.add_argument("--skis", nargs="+", default=["ski-a", "ski-b"])
    args = ap.parse_args(argv)
    cat = load_catalogue(tables_dir())
    counts: dict[str, list[int]] = {}
    ratios: dict[str, list[float]] = {}
    for name in args.skis:
        ski = cat.ski(name)
        true_fn = beam_profile(ski.record.beam)
        for w in args.weights:
            out = flex.compute_sheet(cat, flex.FlexRequest(name, w))
            true = flex_sheet(
                true_fn, w * G_STANDARD, max_closing_load_n=ski.load_range_n[1]
            ).scalars()
            for k, v in out["nominal"].items():
                b, t = out["widths"].get(k, math.nan), true[k]
                if not (math.isfinite(v) and math.isfinite(t) and math.isfinite(b)):
                    continue
                if v == t == 0:
                    continue
                c = counts.setdefault(k, [0, 0])
                c[0] += abs(v - t) <= b
                c[1] += 1
                if b > 0:
                    ratios.setdefault(k, []).append(abs(v - t) / b)
    report = {
        k: {
            "covered": c[0],
            "cases": c[1],
            "coverage": round(c[0] / c[1], 3),
            "max_error_over_band": round(max(ratios.get(k, [math.nan])), 2),
        }
        for k, c in sorted(counts.items())
    }
    print(
        json.dumps({"weights_kg": args.weights, "skis": args.skis, "quantities": report}, indent=1)
    )
    return report


if __name__ == "__main__":
    main()
