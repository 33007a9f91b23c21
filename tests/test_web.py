"""Technician web form: the form, the results page, the CSV download and every error path."""

from __future__ import annotations

import csv
import io
import re

import pytest
from fastapi.testclient import TestClient

from app import web
from app.api import create_app
from app.settings import Settings

QUERY = {
    "ski": ["ski-a", "ski-b"],
    "grind": "tiny-grind",
    "load_kg": "40",
    "load_position_mm": "-160",
    "snow_modulus_mpa": "200",
    "snow_input": "porosity",
    "porosity": "0.5",
    "base_modulus_mpa": "700",
    "poisson_ratio": "0.3",
}


@pytest.fixture(scope="module", autouse=True)
def _numba_threads_env():
    """Keep ``NUMBA_NUM_THREADS`` at numba's live value while this module runs.

    ``create_app`` sets the variable when absent; once numba's thread pool is up, a later JIT
    compile that sees a different value raises RuntimeError (numba re-reads its config). That
    is the app's start-up concern (``skisnow serve`` sets it before numba loads); these tests
    are about the web layer, so they run with a consistent value whatever ran before.
    """
    import numba

    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NUMBA_NUM_THREADS", str(numba.config.NUMBA_NUM_THREADS))
        yield


@pytest.fixture(scope="module")
def client(catalogue):
    app = create_app(Settings(max_compare_cells=4), catalogue=catalogue)
    with TestClient(app, raise_server_exceptions=False) as c:
        yield c


@pytest.fixture(scope="module")
def results_page(client):
    r = client.get("/results", params=QUERY)
    assert r.status_code == 200, r.text[:500]
    return r.text


def _q(**changes) -> dict:
    q = dict(QUERY)
    for k, v in changes.items():
        if v is None:
            q.pop(k, None)
        else:
            q[k] = v
    return q


def test_form_lists_the_catalogue(client, catalogue):
    r = client.get("/")
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/html")
    html = r.text
    for name in (*catalogue.skis, *catalogue.grinds):
        assert f'value="{name}"' in html
    for field in ("load_kg", "load_position_mm", "snow_modulus_mpa", "porosity"):
        assert f'name="{field}"' in html
    # units on the labels, presets, advanced inputs, no external resources
    for text in ("[kg]", "[mm]", "[MPa]", "[kg/m³]", "40 kg at −160 mm", "Advanced"):
        assert text in html
    assert 'name="base_modulus_mpa"' in html and 'name="poisson_ratio"' in html
    assert not re.search(r'(src|href)="(https?:)?//', html)
    assert 'class="alert"' not in html


def test_form_is_prefilled_from_the_query(client):
    html = client.get("/", params=_q(load_kg="55.5", ski="ski-b")).text
    assert 'value="55.5"' in html
    assert re.search(r'value="ski-b" checked', html)
    assert not re.search(r'value="ski-a" checked', html)


def test_results_page_has_metrics_plots_and_provenance(results_page, catalogue):
    html = results_page
    for _, label, unit, _ in web.METRICS:
        assert label in html and f"[{unit}]" in html
    assert html.count('data-metric="total_real_contact_area_mm2"') == 2  # one card per case
    assert "ski-a × tiny-grind" in html and "ski-b × tiny-grind" in html
    # five inline SVG plots with units on the axes
    assert html.count("<svg") == 5
    assert "<?xml" not in html
    for axis in ("[kPa]", "[mm]", "[µm]", "[1/m]", "[%]"):
        assert axis in html
    # provenance and timing
    assert "sha256 " + catalogue.skis["ski-a"].sha256[:12] in html
    assert "gap floor" in html and "texture pixel" in html and "ms" in html
    assert 'href="/results.csv?' in html


def test_results_metrics_match_the_service(client, catalogue):
    from app import service

    r = client.get("/results", params=_q(ski="ski-a"))
    ref = service.contact(
        catalogue,
        service.ContactInputs("ski-a", "tiny-grind", 40, -160, 200, 0.5, 700, 0.3),
    )
    shown = re.search(
        r'data-metric="total_real_contact_area_mm2">.*?class="value">([^<]+)<', r.text
    ).group(1)
    assert float(shown) == pytest.approx(ref["metrics"]["total_real_contact_area_mm2"], rel=1e-3)


def test_csv_one_row_per_combination(client, results_page):
    r = client.get("/results.csv", params=QUERY)
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/csv")
    assert 'filename="skisnow-contact.csv"' in r.headers["content-disposition"]
    rows = list(csv.DictReader(io.StringIO(r.text)))
    assert [(row["ski"], row["grind"]) for row in rows] == [
        ("ski-a", "tiny-grind"),
        ("ski-b", "tiny-grind"),
    ]
    header = r.text.splitlines()[0].split(",")
    for col in (
        "total_real_contact_area_mm2",
        "average_real_contact_pressure_mpa",
        "min_average_separation_um",
        "total_reciprocal_separation_m",
        "load_kg",
        "load_position_mm",
    ):
        assert col in header
    for row in rows:
        assert float(row["total_real_contact_area_mm2"]) > 0
        assert row["error"] == ""
        # the full load over the real area, as in the API
        assert float(row["average_real_contact_pressure_mpa"]) == pytest.approx(
            40 * 9.82 / float(row["total_real_contact_area_mm2"]), rel=1e-6
        )


def test_porosity_from_density(client):
    r = client.get(
        "/results.csv",
        params=_q(ski="ski-a", snow_input="density", porosity=None, snow_density_kg_m3="458.5"),
    )
    assert r.status_code == 200, r.text[:300]
    row = next(csv.DictReader(io.StringIO(r.text)))
    assert float(row["porosity"]) == pytest.approx(1 - 458.5 / 917)


@pytest.mark.parametrize(
    ("changes", "field", "status"),
    [
        ({"load_kg": "-3"}, "load_kg", 422),
        ({"load_kg": "151"}, "load_kg", 422),
        ({"load_kg": "abc"}, "load_kg", 422),
        ({"load_kg": "nan"}, "load_kg", 422),
        ({"load_kg": None}, "load_kg", 422),
        ({"load_position_mm": "5000"}, "load_position_mm", 422),
        ({"snow_modulus_mpa": "0"}, "snow_modulus_mpa", 422),
        ({"porosity": "1"}, "porosity", 422),
        ({"poisson_ratio": "0.5"}, "poisson_ratio", 422),
        ({"base_modulus_mpa": "1e9"}, "base_modulus_mpa", 422),
        ({"snow_input": "density", "snow_density_kg_m3": "950"}, "snow_density_kg_m3", 422),
        ({"ski": None}, "ski", 422),
        ({"grind": None}, "grind", 422),
        ({"ski": "ski-z"}, "ski", 404),
        ({"grind": "grind-9"}, "grind", 404),
    ],
)
def test_bad_input_reshows_the_form(client, changes, field, status):
    for path in ("/results", "/results.csv"):
        r = client.get(path, params=_q(**changes))
        assert r.status_code == status, (path, r.text[:300])
        assert r.headers["content-type"].startswith("text/html")
        html = r.text
        assert 'class="alert"' in html and 'id="contact-form"' in html
        assert f'id="{field}-error"' in html
        assert "Traceback" not in html


def test_unknown_ski_lists_the_known_ones(client):
    html = client.get("/results", params=_q(ski="ski-z")).text
    assert "unknown ski &#x27;ski-z&#x27;; known: ski-a, ski-b" in html


def test_out_of_range_position_says_what_to_change(client):
    # inside ContactBody's bounds, outside the range the demo skis' camber model covers
    r = client.get("/results", params=_q(load_position_mm="400"))
    assert r.status_code == 422
    assert 'id="load_position_mm-error"' in r.text
    assert "outside the range the ski" in r.text and "-300" in r.text


def test_too_many_combinations(catalogue):
    app = create_app(Settings(max_compare_cells=1), catalogue=catalogue)
    with TestClient(app, raise_server_exceptions=False) as c:
        r = c.get("/results", params=_q(ski=["ski-a", "ski-b"]))
        assert r.status_code == 422
        assert 'id="grind-error"' in r.text and "at most 1 per page" in r.text
        r = c.get("/results.csv", params=_q(ski=["ski-a", "ski-a"]))
        assert r.status_code == 200  # duplicates are dropped
        assert len(r.text.splitlines()) == 2


def test_html_is_escaped(client):
    r = client.get("/results", params=_q(ski="<script>alert(1)</script>"))
    assert r.status_code == 404
    assert "<script>alert(1)</script>" not in r.text
