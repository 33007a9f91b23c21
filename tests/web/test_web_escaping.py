"""User text never reaches an HTML page unescaped (issue #16: pages from Jinja2 templates with
autoescape).

Upload names are restricted to letters, digits, '.', '_' and '-' (:data:`app.jobs.uploads.NAME_RE`),
so a name with ``<script>`` cannot come through an upload. What can:

- an upload's free-text metadata and its file name (a grind uploaded here, job run to the end);
- a name refused by the upload check (its problem+json answer is JSON, and the upload page puts
  answers into the page as text, never as HTML);
- every query parameter a page echoes back: names of unknown skis and grinds, numbers that are
  not numbers, presets, ski models, criteria, a ski page's path;
- a ski or grind whose name or description holds markup (the catalogue accepts any name in
  memory: a table directory's or database's content is not checked by the pages).

Every page that shows one of them is fetched and checked: the text is there, escaped, and the
raw markup is nowhere. Turning autoescape off in ``app/web/templating.py`` fails this test.
"""

from __future__ import annotations

import dataclasses
import re
from importlib import resources
from urllib.parse import quote

import pytest
from fastapi.testclient import TestClient
from markupsafe import escape
from skisnow.app import service
from skisnow.app.main import create_app
from skisnow.app.settings import Settings
from skisnow.app.web.upload_page import GRIND_UPLOAD_FIELDS
from test_uploads import FAST, heights_um, npy_bytes, post_grind, wait_job

#: breaks out of an attribute value and a text node alike: in names of the catalogue
NASTY = "\"'><script>alert(1)</script>"
#: the same in query parameters
ECHO = "\"'><script>alert(2)</script>"
#: what must never be on a page (the pages' own inline script has no alert)
RAW = "<script>alert("
#: how Jinja2 (markupsafe) writes NASTY, and the part of ECHO every echo shows (an error
#: message quotes it with repr(), which adds a backslash before the ')
ESCAPED = "&#34;&#39;&gt;&lt;script&gt;alert(1)&lt;/script&gt;"
ECHO_SHOWN = "&lt;script&gt;alert(2)&lt;/script&gt;"
SKI, GRIND = f"ski{NASTY}", f"grind{NASTY}"
#: the published case for the results page
CASE = {
    "load_kg": "40",
    "load_position_mm": "-160",
    "snow_modulus_mpa": "200",
    "porosity": "0.5",
}


@pytest.fixture(scope="module")
def client(catalogue, tmp_path_factory):
    """An app whose catalogue has a ski and a grind named with markup (copies of ski-a and
    tiny-grind; the ski's description is markup too)."""
    a = catalogue.skis["ski-a"]
    meta = {**a.record.metadata, "description": f"desc{NASTY}"}
    record = dataclasses.replace(a.record, metadata=meta, cache={})
    g = catalogue.grinds["tiny-grind"]
    cat = service.Catalogue(
        tables_dir=catalogue.tables_dir,
        skis={**catalogue.skis, SKI: service.Ski(SKI, a.path, a.sha256, record)},
        grinds={**catalogue.grinds, GRIND: dataclasses.replace(g, name=GRIND)},
    )
    settings = Settings(data_dir=tmp_path_factory.mktemp("escaping"), **FAST)
    with TestClient(create_app(settings, catalogue=cat), raise_server_exceptions=False) as c:
        yield c


def _shown_escaped(r, *, status: int, shown: str = ESCAPED) -> str:
    """The HTML page of ``r``: it shows ``shown`` (escaped text) and never raw markup."""
    assert r.status_code == status, r.text[:500]
    assert r.headers["content-type"].startswith("text/html")
    html = r.text
    assert RAW not in html.lower(), html[max(0, html.lower().find(RAW) - 300) :][:600]
    assert NASTY not in html and ECHO not in html
    assert shown in html
    return html


def test_upload_text_is_escaped_on_every_page(client):
    """A grind uploaded with markup in every free-text field and in its file name: its job
    runs, it is in the catalogue, and no page shows raw markup; a markup name is refused (JSON)."""
    text = {
        f.name: f"{f.name}{NASTY}"
        for f in GRIND_UPLOAD_FIELDS
        if f.kind in ("text", "textarea") and f.name != "name"
    }
    assert {"shop_code", "machine", "notes"} <= set(text)
    r = post_grind(client, "xss-grind", npy_bytes(heights_um()), f"g{NASTY}.npy", **text)
    assert r.status_code == 202, r.text[:500]
    assert wait_job(client, r.json()["job"])["state"] == "done"
    assert client.get("/v1/grinds/xss-grind").json()["metadata"]["notes"] == text["notes"]
    pages = [
        "/",
        "/upload",
        "/flex",
        "/flex/pair",
        "/flex/ranking",
        "/?grind=xss-grind&ski=ski-a",
        "/results?" + "&".join(f"{k}={v}" for k, v in CASE.items()) + "&ski=ski-a&grind=xss-grind",
    ]
    for url in pages:
        r = client.get(url)
        assert r.status_code < 500 and r.headers["content-type"].startswith("text/html"), url
        assert ("xss-grind" in r.text) == (url not in ("/upload", "/flex")), url  # no grinds
        assert RAW not in r.text.lower(), url

    # a name with markup is refused by the upload check, as JSON (not a page)
    r = post_grind(client, f"g{NASTY}", npy_bytes(heights_um()))
    assert r.status_code == 422
    assert r.headers["content-type"].startswith("application/problem+json")
    # the upload page shows such answers as text: its script never writes HTML
    js = resources.files("skisnow.app.web").joinpath("static/upload.js").read_text("utf-8")
    assert not re.search(r"innerHTML|outerHTML|insertAdjacentHTML|document\.write", js)


def test_echoed_query_text_is_escaped(client):
    """Every query parameter a page shows back: unknown names, non-numbers, unknown choices."""

    def shown(r, status):
        return _shown_escaped(r, status=status, shown=ECHO_SHOWN)

    q = {**CASE, "ski": ECHO, "grind": ECHO, "preset": ECHO, "ski_model": ECHO}
    for path, status in (("/", 200), ("/results", 404), ("/results.csv", 404)):
        assert 'value="ski-a"' in shown(client.get(path, params=q), status)  # the form
    bad = {**CASE, "ski": "ski-a", "grind": "tiny-grind", "load_kg": ECHO}
    html = shown(client.get("/", params=bad), 200)
    assert 'name="load_kg" value="&#34;&#39;&gt;&lt;script&gt;alert(2)' in html
    shown(client.get("/results", params=bad), 422)
    shown(client.get("/skis/" + quote(ECHO, safe="")), 404)
    flex = {"body_weight_kg": ECHO, "snow_modulus_mpa": ECHO, "porosity": ECHO}
    shown(client.get("/flex", params={"ski": ECHO, **flex}), 422)
    shown(client.get("/flex", params={"ski": ECHO, "body_weight_kg": "75"}), 422)
    pair = {"left": "ski-a", "right": ECHO, "body_weight_kg": "75"}
    shown(client.get("/flex/pair", params=pair), 422)
    shown(client.get("/flex/pair", params={**pair, **flex}), 422)
    ranking = {"ski": "ski-a", "grind": "tiny-grind", "criterion": ECHO, "body_weight_kg": "75"}
    ranking |= {"snow_modulus_mpa": "20", "porosity": "0.5"}
    shown(client.get("/flex/ranking", params=ranking), 422)
    shown(client.get("/flex/ranking", params={**ranking, **flex}), 422)


def test_names_with_markup_are_escaped_on_every_page(client):
    """A ski and a grind named with markup, on every page that lists or shows them."""
    both = {**CASE, "ski": SKI, "grind": GRIND}
    pages = [
        ("/", {}, 200),
        ("/", both, 200),
        ("/results", both, 200),
        ("/skis/" + quote(SKI, safe=""), {}, 200),
        ("/skis/no-such-ski", {}, 404),  # lists the skis one can open
        ("/upload", {}, 200),
        ("/flex", {}, 200),
        ("/flex", {"ski": SKI, "body_weight_kg": "75"}, 200),
        ("/flex/pair", {"left": SKI, "right": "ski-a", "body_weight_kg": "75"}, 200),
        (
            "/flex/ranking",
            {"ski": SKI, "grind": GRIND, "body_weight_kg": "75", **CASE},
            200,
        ),
    ]
    for path, params, status in pages:
        html = _shown_escaped(client.get(path, params=params), status=status)
        if path == "/results":
            # the card, the comparison table and the plots' legends (SVG) name the pair
            assert html.count(f"ski{ESCAPED} × grind{ESCAPED}") >= 1
            assert html.count("<svg") == 6
        if params.get("ski") == SKI and path != "/":
            assert f"ski{ESCAPED}" in html
    # the sheet's CSV/JSON links carry the name percent-encoded in the path (a raw name would
    # end the path segment at its first "/" or "?")
    sheet = client.get("/flex", params={"ski": SKI, "body_weight_kg": "75"}).text
    link = "/v1/skis/" + quote(SKI, safe="") + "/flex?"
    assert sheet.count(str(escape(link))) == 2
    # the description of the ski, on the form and on its page
    assert f"desc{ESCAPED}" in client.get("/").text
    assert f"desc{ESCAPED}" in client.get("/skis/" + quote(SKI, safe="")).text
