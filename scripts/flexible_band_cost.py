"""What the error band of a bending-ski answer costs in one ``/v1/contact`` computation (issue #12
point 4, docs/limits.md "Error band").

Per demo ski, ``ski_model`` "flexible" and "auto", papers' case (40 kg at −160 mm, 200 MPa,
porosity 0.5, default preset; ``--modulus`` for other snow), one ``service.contact`` call with:

``no_band``
    no band (``error_band=False``);
``before``
    the band as before this change: no camber part and no coarse solve for an answer of the
    bending ski (:func:`app.service.band.beam_models` answering None);
``coarse``
    the coarse nominal solve only (the per-answer grid estimate, no beam draws);
``draws2``, ``draws4``, ``draws8``
    the coarse nominal and 2, 4 or 8 plausible beams, their deviations × the factor given by
    ``--draw-scale N=S`` (default: the service's factor at the case's snow modulus,
    :func:`app.service.band_calibration.beam_scale_at`; the factor changes how far
    the perturbed solves start from their answer, so it changes their cost a little).

Variants run round-robin, one call each per round, after one warm-up round (which also
prepares and caches the beam models), so that a changing machine load hits them alike; the
medians over ``--repeats`` rounds [ms] are printed as JSON.

Usage::

    python scripts/flexible_band_cost.py --repeats 25 --draw-scale 4=8
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from skisnow.app import service  # noqa: E402
from skisnow.app.service import answer as service_contact  # noqa: E402
from skisnow.app.service import band  # noqa: E402

VARIANTS = ("no_band", "before", "coarse", "draws2", "draws4", "draws8")


def run(cat, inp, variant: str, scales: dict[int, float]) -> dict:
    original_band, original_models = service_contact.answer_band, band.beam_models
    try:
        if variant == "before":
            band.beam_models = lambda *a, **k: None
        elif variant == "coarse":
            service_contact.answer_band = functools.partial(band.answer_band, beam_samples=0)
        elif variant.startswith("draws"):
            n = int(variant[5:])
            service_contact.answer_band = functools.partial(
                band.answer_band, beam_samples=n, beam_scale=scales.get(n)
            )
        return service.contact(cat, inp, error_band=variant != "no_band")
    finally:
        service_contact.answer_band, band.beam_models = original_band, original_models


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=25)
    ap.add_argument("--modulus", type=float, default=200.0, help="snow modulus [MPa]")
    ap.add_argument(
        "--draw-scale",
        action="append",
        default=[],
        metavar="N=S",
        help="deviation factor S of the variant with N draws (repeatable)",
    )
    args = ap.parse_args(argv)
    scales = {int(a.split("=")[0]): float(a.split("=")[1]) for a in args.draw_scale}
    cat = service.load_catalogue(REPO / "tables")
    out: dict = {"repeats": args.repeats, "snow_modulus_mpa": args.modulus, "scales": scales}
    for ski in ("ski-a", "ski-b"):
        for mode in ("flexible", "auto"):
            inp = service.ContactInputs(
                ski, "grind-1", 40.0, -160.0, args.modulus, 0.5, ski_model=mode
            )
            times: dict[str, list[float]] = {v: [] for v in VARIANTS}
            band_ms: dict[str, list[float]] = {v: [] for v in VARIANTS}
            used = None
            for rnd in range(args.repeats + 1):
                for v in VARIANTS:
                    t0 = time.perf_counter()
                    ans = run(cat, inp, v, scales)
                    dt = time.perf_counter() - t0
                    used = ans["provenance"]["ski_model"]["used"]
                    if rnd:  # round 0 is the warm-up
                        times[v].append(dt * 1e3)
                        band_ms[v].append(ans["timing_ms"]["band"])
            out[f"{ski}/{mode}"] = {
                "used": used,
                "request_ms": {v: round(float(np.median(t)), 1) for v, t in times.items()},
                "band_ms": {v: round(float(np.median(t)), 1) for v, t in band_ms.items()},
            }
            print(json.dumps({f"{ski}/{mode}": out[f"{ski}/{mode}"]}), flush=True)
    return out


if __name__ == "__main__":
    main()
