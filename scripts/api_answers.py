"""Record the REST API's answers to a fixed set of requests, or compare two recordings.

A check for refactors that must not change any answer (issue #16): run it on the code before
the change and after, then compare::

    python scripts/api_answers.py record before.json
    python scripts/api_answers.py record after.json
    python scripts/api_answers.py compare before.json after.json

Every route of the API is asked, with success and error cases and the ``format=csv`` variants.
The app is the tests' (tests/conftest.py: the demo skis and the small synthetic grind
``tiny-grind``); background jobs are never started (uploads stay queued), so the recording
takes a few seconds. What varies from run to run is normalised: ``timing_ms``, item and job
ids (numbered in order of appearance) and timestamps. HTML pages are recorded by status and
content type only (their bodies belong to the web pages, not the API).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
_UUID = re.compile(
    r"\b[0-9a-f]{32}\b|\b[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}\b"
)
_STAMP = re.compile(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d(\+00:00)?")
#: keys whose values are wall-clock times
_TIMINGS = ("timing_ms", "solve_time_ms", "solve_time_s")
_HEADERS = ("location", "retry-after", "www-authenticate", "content-disposition")


def _create_app():
    try:  # after issue #16: the factory beside the ASGI entry point
        from skisnow.app.main import create_app
    except ImportError:
        from skisnow.app.api import create_app
    return create_app


class _Ids:
    """Replace ids and timestamps by stable placeholders (ids numbered by first appearance)."""

    def __init__(self) -> None:
        self.seen: dict[str, str] = {}

    def text(self, s: str) -> str:
        s = _UUID.sub(lambda m: self.seen.setdefault(m.group(0), f"<id{len(self.seen)}>"), s)
        return _STAMP.sub("<time>", s)

    def value(self, v):
        if isinstance(v, dict):
            return {k: "<timing>" if k in _TIMINGS else self.value(x) for k, x in v.items()}
        if isinstance(v, list):
            return [self.value(x) for x in v]
        if isinstance(v, str):
            return self.text(v)
        return v


def _record(ids: _Ids, resp, html: bool = False) -> dict:
    ctype = resp.headers.get("content-type", "")
    out = {"status": resp.status_code, "content_type": ctype}
    out["headers"] = {h: ids.text(resp.headers[h]) for h in _HEADERS if h in resp.headers}
    if html:
        return out
    if "json" in ctype:
        out["body"] = ids.value(resp.json())
    else:
        out["body"] = ids.text(resp.text)
    return out


def _camber_csv(tmp: Path) -> bytes:
    """The tests' valid camber CSV (tests/conftest.py ``camber_csv``)."""
    import conftest

    class _Factory:  # the one method of pytest's tmp_path_factory the fixture uses
        def mktemp(self, name: str) -> Path:
            (tmp / name).mkdir(exist_ok=True)
            return tmp / name

    return conftest.camber_csv.__wrapped__(_Factory())


def _npy(seed: int = 1) -> bytes:
    import io

    import numpy as np
    from skisnow.solvers.texture import self_affine_surface

    h = self_affine_surface(
        (64, 64), 1e-6, hurst=0.8, rms_height_m=1e-6, rng=np.random.default_rng(seed)
    )
    buf = io.BytesIO()
    np.save(buf, h * 1e6)
    return buf.getvalue()


def requests_and_answers(tmp: Path) -> dict:
    """Ask every route; return ``{label: recorded answer}`` (order of the requests)."""
    sys.path.insert(0, str(REPO / "tests"))
    import conftest
    from fastapi.testclient import TestClient
    from skisnow.app.settings import Settings

    table = conftest.small_table.__wrapped__()
    cat = conftest.catalogue.__wrapped__(table)
    create_app = _create_app()
    settings = Settings(
        data_dir=tmp / "data",
        warm_up=False,
        job_poll_s=3600,
        max_body_bytes=4096,
        max_upload_bytes=1_000_000,
    )
    ids = _Ids()
    out: dict = {}
    body = dict(conftest.CONTACT_BODY)
    case = {k: v for k, v in body.items() if k not in ("ski", "grind")}
    app = create_app(settings, catalogue=cat)
    with TestClient(app, raise_server_exceptions=False) as c:
        app.state.uploads.runner.wake = lambda: None  # jobs stay queued: no training, no build

        def ask(label, method, url, html=False, **kw):
            out[label] = _record(ids, c.request(method, url, **kw), html=html)

        ask("healthz", "GET", "/healthz")
        ask("readyz", "GET", "/readyz")
        ask("skis", "GET", "/v1/skis")
        ask("grinds", "GET", "/v1/grinds")
        ask("contact", "POST", "/v1/contact", json=body)
        ask(
            "contact rigid fast",
            "POST",
            "/v1/contact",
            json={**body, "ski_model": "rigid", "preset": "fast"},
        )
        ask("contact load too high", "POST", "/v1/contact", json={**body, "load_kg": 200})
        ask("contact E too high", "POST", "/v1/contact", json={**body, "snow_modulus_mpa": 5000})
        ask("contact porosity 1", "POST", "/v1/contact", json={**body, "porosity": 1})
        ask("contact missing", "POST", "/v1/contact", json={"ski": "ski-a"})
        ask("contact extra", "POST", "/v1/contact", json={**body, "colour": "red"})
        ask("contact bad preset", "POST", "/v1/contact", json={**body, "preset": "ultra"})
        ask("contact unknown ski", "POST", "/v1/contact", json={**body, "ski": "nope"})
        ask("contact unknown grind", "POST", "/v1/contact", json={**body, "grind": "nope"})
        ask(
            "contact position outside ski",
            "POST",
            "/v1/contact",
            json={**body, "load_position_mm": 900},
        )
        ask(
            "contact not json",
            "POST",
            "/v1/contact",
            content=b"{not json",
            headers={"content-type": "application/json"},
        )
        ask(
            "contact too large",
            "POST",
            "/v1/contact",
            content=b"x" * 5000,
            headers={"content-type": "application/json"},
        )
        ask("contact GET", "GET", "/v1/contact")
        ask(
            "compare",
            "POST",
            "/v1/compare",
            json={**case, "skis": ["ski-a", "ski-b"], "grinds": ["tiny-grind"]},
        )
        ask(
            "compare too many",
            "POST",
            "/v1/compare",
            json={**case, "skis": [f"s{i}" for i in range(5)], "grinds": list("abcd")},
        )
        ask(
            "compare unknown grind",
            "POST",
            "/v1/compare",
            json={**case, "skis": ["ski-a"], "grinds": ["nope"]},
        )
        ask("compare empty", "POST", "/v1/compare", json={**case, "skis": [], "grinds": ["x"]})
        ask("no route", "GET", "/v1/nothing")

        flex_q = {"body_weight_kg": 75}
        ask("flex", "GET", "/v1/skis/ski-a/flex", params=flex_q)
        ask(
            "flex snow",
            "GET",
            "/v1/skis/ski-a/flex",
            params={**flex_q, "snow_modulus_mpa": 200, "porosity": 0.5},
        )
        ask("flex csv", "GET", "/v1/skis/ski-a/flex", params={**flex_q, "format": "csv"})
        ask("flex heavy", "GET", "/v1/skis/ski-a/flex", params={"body_weight_kg": 400})
        ask("flex bad format", "GET", "/v1/skis/ski-a/flex", params={**flex_q, "format": "xml"})
        ask("flex unknown ski", "GET", "/v1/skis/nope/flex", params=flex_q)
        pair = {"left": "ski-a", "right": "ski-b", "body_weight_kg": 75}
        ask("pair", "GET", "/v1/flex/pair", params=pair)
        ask(
            "pair grind",
            "GET",
            "/v1/flex/pair",
            params={**pair, "grind": "tiny-grind", "snow_modulus_mpa": 200, "porosity": 0.5},
        )
        ask("pair csv", "GET", "/v1/flex/pair", params={**pair, "format": "csv"})
        ask("pair missing", "GET", "/v1/flex/pair", params={"left": "ski-a"})
        ask("pair unknown", "GET", "/v1/flex/pair", params={**pair, "right": "nope"})
        rank = {
            "skis": ["ski-a", "ski-b"],
            "grinds": ["tiny-grind"],
            "body_weight_kg": 75,
            "snow_modulus_mpa": 200,
            "porosity": 0.5,
        }
        ask("ranking", "POST", "/v1/flex/ranking", json=rank)
        ask(
            "ranking separation",
            "POST",
            "/v1/flex/ranking",
            json={**rank, "criterion": "reciprocal_separation"},
        )
        ask("ranking csv", "POST", "/v1/flex/ranking?format=csv", json=rank)
        ask(
            "ranking too many",
            "POST",
            "/v1/flex/ranking",
            json={**rank, "skis": [f"s{i}" for i in range(5)], "grinds": list("abcd")},
        )
        ask("ranking bad", "POST", "/v1/flex/ranking", json={**rank, "porosity": 2})

        ask("ski shipped", "GET", "/v1/skis/ski-a")
        ask("grind shipped", "GET", "/v1/grinds/tiny-grind")
        ask("ski unknown", "GET", "/v1/skis/nope")
        ask("grind unknown", "GET", "/v1/grinds/nope")
        npy = _npy()
        grind_form = {
            "name": "my-grind",
            "pixel_size_um": "1",
            "height_unit": "um",
            "shop_code": "S1",
        }
        ask(
            "grind upload",
            "POST",
            "/v1/grinds",
            data=grind_form,
            files={"file": ("g.npy", npy, "application/octet-stream")},
        )
        ask(
            "grind upload taken",
            "POST",
            "/v1/grinds",
            data=grind_form,
            files={"file": ("g.npy", npy, "application/octet-stream")},
        )
        ask("grind upload json", "POST", "/v1/grinds", json={"name": "x"})
        ask(
            "grind upload garbage",
            "POST",
            "/v1/grinds",
            data={**grind_form, "name": "g2"},
            files={"file": ("g.npy", b"garbage", "application/octet-stream")},
        )
        ask(
            "grind upload bad field",
            "POST",
            "/v1/grinds",
            data={**grind_form, "name": "g3", "along_ski": "z"},
            files={"file": ("g.npy", npy, "application/octet-stream")},
        )
        ski_form = {"name": "my-ski", "length_mm": "2000", "width_mm": "44", "style": "classic"}
        csv = _camber_csv(tmp)
        ask(
            "ski upload",
            "POST",
            "/v1/skis",
            data=ski_form,
            files={"file": ("ski.csv", csv, "text/csv")},
        )
        ask(
            "ski upload bad csv",
            "POST",
            "/v1/skis",
            data={**ski_form, "name": "s2"},
            files={"file": ("ski.csv", b"a,b\n1,2\n", "text/csv")},
        )
        ask("jobs", "GET", "/v1/jobs")
        job = c.get("/v1/jobs").json()["jobs"][0]["id"]
        ask("job", "GET", f"/v1/jobs/{job}")
        ask("job unknown", "GET", "/v1/jobs/nope")
        ask("grind uploaded", "GET", "/v1/grinds/my-grind")
        ask("ski uploaded", "GET", "/v1/skis/my-ski")
        ask("rename", "PATCH", "/v1/grinds/my-grind", json={"name": "my-grind-2"})
        ask("rename bad", "PATCH", "/v1/grinds/my-grind-2", json={"name": ""})
        ask("rename shipped", "PATCH", "/v1/skis/ski-a", json={"name": "x"})
        ask("delete busy", "DELETE", "/v1/grinds/my-grind-2")
        ask("delete shipped", "DELETE", "/v1/grinds/tiny-grind")
        ask("delete unknown", "DELETE", "/v1/skis/nope")
        ask(
            "delete cross-origin",
            "DELETE",
            "/v1/skis/my-ski",
            headers={"origin": "https://evil.example"},
        )
        for page in (
            "/",
            "/results?ski=ski-a&grind=tiny-grind",
            "/upload",
            "/skis/ski-a",
            "/flex",
            "/results?ski=ski-a&grind=tiny-grind&load_kg=900",
        ):
            ask(f"page {page}", "GET", page, html=True)
        ask("results csv", "GET", "/results.csv?ski=ski-a&grind=tiny-grind")

    tokens = Settings(
        data_dir=tmp / "data2", warm_up=False, job_poll_s=3600, team_tokens={"tok-a": "a"}
    )
    with TestClient(create_app(tokens, catalogue=cat), raise_server_exceptions=False) as c:
        out["teams: no token"] = _record(ids, c.delete("/v1/skis/x"))
        out["teams: bad token"] = _record(
            ids, c.delete("/v1/skis/x", headers={"authorization": "Bearer nope"})
        )
    return out


def compare(before: dict, after: dict) -> list[str]:
    """Differences between two recordings (empty: identical)."""
    diffs = []
    for label in sorted(set(before) | set(after)):
        if label not in before or label not in after:
            diffs.append(f"{label}: only in {'after' if label in after else 'before'}")
        else:
            for key in ("status", "content_type", "headers", "body"):
                # as text: 2 and 2.0 differ; key order is reported apart
                a, b = (json.dumps(x[label].get(key), sort_keys=True) for x in (before, after))
                if a != b:
                    diffs.append(f"{label}: {key} differs")
                elif json.dumps(before[label].get(key)) != json.dumps(after[label].get(key)):
                    diffs.append(f"{label}: {key} has its keys in another order")
    return diffs


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("out", type=Path)
    c = sub.add_parser("compare")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    args = p.parse_args(argv)
    if args.cmd == "record":
        with tempfile.TemporaryDirectory() as tmp:
            answers = requests_and_answers(Path(tmp))
        args.out.write_text(json.dumps(answers, indent=1))
        print(f"{len(answers)} answers -> {args.out}")
        return 0
    diffs = compare(json.loads(args.before.read_text()), json.loads(args.after.read_text()))
    n = len(json.loads(args.before.read_text()))
    print("\n".join(diffs) or f"identical: {n} answers")
    return 1 if diffs else 0


if __name__ == "__main__":
    raise SystemExit(main())
