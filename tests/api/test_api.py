"""REST API: every endpoint, every error path and the problem-body shape."""

from __future__ import annotations

import pytest
from conftest import CONTACT_BODY
from fastapi.testclient import TestClient
from skisnow.app.main import create_app
from skisnow.app.settings import Settings

BODY = CONTACT_BODY


@pytest.fixture(scope="module")
def client(catalogue):
    app = create_app(Settings(max_body_bytes=4096), catalogue=catalogue)
    with TestClient(app, raise_server_exceptions=False) as c:
        yield c


def _is_problem(r, status):
    assert r.status_code == status, r.text[:300]
    body = r.json()
    assert body["status"] == status
    assert isinstance(body["title"], str) and isinstance(body["detail"], str)
    assert r.headers["content-type"].startswith("application/problem+json")
    return body


def test_health_and_ready(client):
    assert client.get("/healthz").json() == {"status": "ok"}
    r = client.get("/readyz").json()
    assert r["status"] == "ready" and "ski-a" in r["skis"] and "tiny-grind" in r["grinds"]


def test_catalogue_lists(client):
    skis = client.get("/v1/skis").json()["skis"]
    assert {s["name"] for s in skis} >= {"ski-a", "ski-b"}
    grinds = client.get("/v1/grinds").json()["grinds"]
    assert grinds[0]["name"] == "tiny-grind" and grinds[0]["gap_floor_nm"] == pytest.approx(10)


def test_contact_answer(client):
    r = client.post("/v1/contact", json=BODY)
    assert r.status_code == 200, r.text[:300]
    d = r.json()
    m = d["metrics"]
    assert m["total_real_contact_area_mm2"] > 0
    # F / A_tot with the full load
    assert m["average_real_contact_pressure_mpa"] == pytest.approx(
        40 * 9.82 / (m["total_real_contact_area_mm2"] * 1e-6) / 1e6, rel=1e-9
    )
    a = d["apparent"]
    assert a["mean_pressure_kpa"] == pytest.approx(
        40 * 9.82 / (a["contact_area_cm2"] * 1e-4) / 1e3, rel=1e-9
    )
    assert sum(z["load_share"] for z in a["zones"]) == pytest.approx(1.0, abs=1e-6)
    dist = d["distributions"]
    n = len(dist["position_mm"])
    assert n > 100 and all(len(v) == n for v in dist.values())
    assert d["provenance"]["table"]["gap_floor_nm"] == pytest.approx(10)
    # the small test table is built on one pixel size: no estimate, said so
    assert d["provenance"]["table"]["pixel_error_estimate"]["estimated"] is False
    assert d["provenance"]["macro"]["converged"] is True
    assert d["timing_ms"]["total"] > 0


def test_compare_matrix(client):
    body = {k: v for k, v in BODY.items() if k not in ("ski", "grind")}
    r = client.post(
        "/v1/compare", json={**body, "skis": ["ski-a", "ski-b"], "grinds": ["tiny-grind"]}
    )
    assert r.status_code == 200, r.text[:300]
    res = r.json()["results"]
    assert [x["inputs"]["ski"] for x in res] == ["ski-a", "ski-b"]
    # the ski with the larger apparent area has the lower mean apparent pressure
    a, b = (x["apparent"] for x in res)
    assert (a["contact_area_cm2"] - b["contact_area_cm2"]) * (
        a["mean_pressure_kpa"] - b["mean_pressure_kpa"]
    ) < 0


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("load_kg", 0),
        ("load_kg", -5),
        ("load_kg", 1e6),
        ("load_position_mm", 5000),
        ("snow_modulus_mpa", 0.5),
        ("snow_modulus_mpa", 5000),
        ("porosity", 1.0),
        ("porosity", -0.1),
        ("poisson_ratio", 0.5),
        ("load_kg", "forty"),
        ("load_kg", None),
    ],
)
def test_bad_numbers_are_422_naming_the_field(client, field, value):
    body = _is_problem(client.post("/v1/contact", json={**BODY, field: value}), 422)
    assert body["errors"][0]["field"] == field


def test_missing_and_extra_fields(client):
    body = {k: v for k, v in BODY.items() if k != "porosity"}
    assert _is_problem(client.post("/v1/contact", json=body), 422)["errors"][0]["field"] == (
        "porosity"
    )
    _is_problem(client.post("/v1/contact", json={**BODY, "colour": "red"}), 422)
    _is_problem(
        client.post(
            "/v1/contact", content=b"{not json", headers={"content-type": "application/json"}
        ),
        422,
    )


def test_unknown_items_are_404_listing_known(client):
    body = _is_problem(client.post("/v1/contact", json={**BODY, "ski": "ski-z"}), 404)
    assert "ski-a" in body["known"] and body["field"] == "ski"
    body = _is_problem(client.post("/v1/contact", json={**BODY, "grind": "nope"}), 404)
    assert body["known"] == ["tiny-grind"]


def test_position_outside_ski_model_is_422(client):
    body = _is_problem(client.post("/v1/contact", json={**BODY, "load_position_mm": 900}), 422)
    assert "load_position_mm" in body["detail"]


def test_oversized_body_is_413(client):
    big = {**BODY, "ski": "x" * 10000}
    _is_problem(client.post("/v1/contact", json=big), 413)


def test_unknown_route_is_problem_404(client):
    _is_problem(client.get("/v1/nothing"), 404)
    _is_problem(client.get("/v1/contact"), 405)


def test_warm_up_solves_once_and_never_raises(catalogue, caplog):
    from skisnow.app import service

    assert service.warm_up(catalogue) > 0
    empty = service.Catalogue(tables_dir=catalogue.tables_dir)
    with caplog.at_level("WARNING"):
        service.warm_up(empty)  # nothing to solve: logged, not raised
    assert "warm-up solve failed" in caplog.text
