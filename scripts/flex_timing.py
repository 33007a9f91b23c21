"""p50 of a flex sheet through the HTTP layer (issue #14: p50 ≤ 100 ms).

Builds the app in process over the shipped catalogue (tables/), warms each ski once (the
first sheet of a ski builds its beam flexibilities and the flexible model: ~1–3 s, once per
worker), then times ``GET /v1/skis/{name}/flex`` with a snow (the kick-zone share on snow and
every band included) for body weights spread over the ski's range. Prints one JSON object.

Usage::

    PYTHONPATH=. python scripts/flex_timing.py [--requests 60]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
from fastapi.testclient import TestClient
from skisnow.app.main import create_app
from skisnow.app.settings import Settings


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--requests", type=int, default=60, help="timed requests per ski")
    ap.add_argument("--skis", nargs="+", default=["ski-a", "ski-b"])
    args = ap.parse_args(argv)
    app = create_app(Settings(warm_up=False))
    out = {"requests_per_ski": args.requests, "skis": {}}
    with TestClient(app) as client:
        for ski in args.skis:
            params = {"body_weight_kg": 75, "snow_modulus_mpa": 200, "porosity": 0.5}
            t = time.perf_counter()
            r = client.get(f"/v1/skis/{ski}/flex", params=params)
            r.raise_for_status()
            first = time.perf_counter() - t
            weights = np.linspace(40, 120, args.requests)
            times, server = [], []
            for w in weights:
                params["body_weight_kg"] = round(float(w), 2)
                t = time.perf_counter()
                r = client.get(f"/v1/skis/{ski}/flex", params=params)
                times.append(time.perf_counter() - t)
                r.raise_for_status()
                server.append(r.json()["timing_ms"]["total"])
            ms = np.array(times) * 1e3
            out["skis"][ski] = {
                "first_request_ms": round(first * 1e3, 1),
                "p50_ms": round(float(np.median(ms)), 1),
                "p90_ms": round(float(np.percentile(ms, 90)), 1),
                "max_ms": round(float(ms.max()), 1),
                "service_p50_ms": round(float(np.median(server)), 1),
            }
    print(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
