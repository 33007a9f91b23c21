"""The API's OpenAPI document: typed answers and problem+json errors on every route, and the
answers of each route exactly what its response model says (no key more or less, 2 stays 2).

The full before/after comparison of answers is scripts/api_answers.py (issue #16).
"""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from conftest import CONTACT_BODY
from fastapi.routing import APIRoute
from fastapi.testclient import TestClient
from pydantic import BaseModel
from skisnow.app import bounds
from skisnow.app.api import contact, flex, grinds, jobs, ops, skis
from skisnow.app.api.models import CompareBody, ContactBody
from skisnow.app.api.problems import MEDIA_TYPE, Problem
from skisnow.app.main import create_app
from skisnow.app.settings import Settings

PROBLEM_REF = {"$ref": "#/components/schemas/Problem"}


@pytest.fixture(scope="module")
def app(catalogue, tmp_path_factory):
    settings = Settings(
        data_dir=tmp_path_factory.mktemp("api-models"),
        warm_up=False,
        job_poll_s=3600,
        max_upload_bytes=1_000_000,
    )
    return create_app(settings, catalogue=catalogue)


@pytest.fixture(scope="module")
def client(app):
    with TestClient(app, raise_server_exceptions=False) as c:
        app.state.uploads.runner.wake = lambda: None  # uploads stay queued: no job runs
        yield c


@pytest.fixture(scope="module")
def spec(client):
    r = client.get("/openapi.json")
    assert r.status_code == 200
    return r.json()


def _operations(spec):
    for path, operations in spec["paths"].items():
        for method, op in operations.items():
            yield f"{method.upper()} {path}", op


def test_every_route_declares_its_errors_as_problem_json(spec):
    ops = dict(_operations(spec))
    assert len(ops) == 19
    for name, op in ops.items():
        errors = {int(s): r for s, r in op["responses"].items() if int(s) >= 400}
        assert {400, 413, 500} <= set(errors), name
        for status, resp in errors.items():
            assert resp["content"] == {MEDIA_TYPE: {"schema": PROBLEM_REF}}, (name, status)
    # what each kind of route can be refused with, beyond the common 400/413/500
    assert {401, 403, 409, 415, 422, 429} <= set(map(int, ops["POST /v1/skis"]["responses"]))
    assert {401, 404, 422} <= set(map(int, ops["POST /v1/contact"]["responses"]))
    assert {403, 404, 409} <= set(map(int, ops["DELETE /v1/grinds/{name}"]["responses"]))
    assert 503 in map(int, ops["GET /readyz"]["responses"])
    assert "HTTPValidationError" not in spec["components"]["schemas"]


def test_problem_schema_has_the_members_the_code_sends(spec):
    schema = spec["components"]["schemas"]["Problem"]
    assert set(schema["required"]) == {"type", "status", "title", "detail"}
    assert set(schema["properties"]) == {
        "type",
        "status",
        "title",
        "detail",
        "errors",
        "field",
        "known",
    }
    assert spec["components"]["schemas"]["FieldError"]["required"] == ["field", "reason"]


def test_every_answer_is_typed(spec):
    for name, op in _operations(spec):
        ok = [s for s in op["responses"] if int(s) < 300]
        assert ok, name
        for status in ok:
            if status == "204":
                continue
            schema = op["responses"][status]["content"]["application/json"]["schema"]
            assert schema.get("$ref", "").startswith("#/components/schemas/"), (name, schema)


def test_request_bodies_share_one_case_model():
    contact = ContactBody.model_fields
    compare = CompareBody.model_fields
    case = set(contact) - {"ski", "grind"}
    assert case == set(compare) - {"skis", "grinds"}
    for key in case:
        assert contact[key] is compare[key] or repr(contact[key]) == repr(compare[key]), key
    # items first: validation errors name them before the case, as ever
    assert list(contact)[:2] == ["ski", "grind"] and list(compare)[:2] == ["skis", "grinds"]
    # the bounds are app.bounds'
    limits = {type(m).__name__: m for m in contact["load_kg"].metadata}
    assert limits["Le"].le == bounds.LOAD_KG.high and limits["Gt"].gt == bounds.LOAD_KG.low


def _model_of(app, method: str, path: str) -> type[BaseModel]:
    """The response model the route declares (the routers' routes: ``app.routes`` holds the
    included routers, not their routes, in recent FastAPI)."""
    for module in (ops, contact, flex, skis, grinds, jobs):
        for route in module.router.routes:
            if isinstance(route, APIRoute) and route.path == path and method in route.methods:
                return route.response_model
    raise AssertionError(f"no route {method} {path}")


def _same(model: type[BaseModel], answer) -> None:
    """``answer`` is exactly ``model``: validation (extra keys refused) and back, as text."""
    dumped = model.model_validate(answer).model_dump(mode="json", exclude_unset=True)
    assert json.dumps(dumped, sort_keys=True) == json.dumps(answer, sort_keys=True)


def test_answers_are_their_response_models(app, client, upload_csv):
    body = dict(CONTACT_BODY)
    case = {k: v for k, v in body.items() if k not in ("ski", "grind")}
    fast = {"preset": "fast", "ski_model": "rigid"}
    weight = {"body_weight_kg": 75}
    rank = {
        "skis": ["ski-a"],
        "grinds": ["tiny-grind"],
        "body_weight_kg": 75,
        "snow_modulus_mpa": 200,
        "porosity": 0.5,
    }
    buf = io.BytesIO()
    np.save(buf, np.random.default_rng(1).normal(size=(64, 64)))
    asked = [
        ("GET", "/healthz", "/healthz", {}),
        ("GET", "/readyz", "/readyz", {}),
        ("GET", "/v1/skis", "/v1/skis", {}),
        ("GET", "/v1/grinds", "/v1/grinds", {}),
        ("POST", "/v1/contact", "/v1/contact", {"json": body}),
        (
            "POST",
            "/v1/compare",
            "/v1/compare",
            {"json": {**case, **fast, "skis": ["ski-a", "ski-b"], "grinds": ["tiny-grind"]}},
        ),
        ("GET", "/v1/skis/{name}/flex", "/v1/skis/ski-a/flex", {"params": weight}),
        (
            "GET",
            "/v1/flex/pair",
            "/v1/flex/pair",
            {"params": {**weight, "left": "ski-a", "right": "ski-b"}},
        ),
        ("POST", "/v1/flex/ranking", "/v1/flex/ranking", {"json": rank}),
        ("GET", "/v1/skis/{name}", "/v1/skis/ski-a", {}),
        ("GET", "/v1/grinds/{name}", "/v1/grinds/tiny-grind", {}),
        (
            "POST",
            "/v1/grinds",
            "/v1/grinds",
            {
                "data": {"name": "g-models", "pixel_size_um": "1", "height_unit": "um"},
                "files": {"file": ("g.npy", buf.getvalue(), "application/octet-stream")},
            },
        ),
        (
            "POST",
            "/v1/skis",
            "/v1/skis",
            {
                "data": {"name": "s-models", "length_mm": "2000", "width_mm": "44"},
                "files": {"file": ("ski.csv", upload_csv, "text/csv")},
            },
        ),
        ("GET", "/v1/jobs", "/v1/jobs", {}),
        ("GET", "/v1/grinds/{name}", "/v1/grinds/g-models", {}),
        ("PATCH", "/v1/grinds/{name}", "/v1/grinds/g-models", {"json": {"name": "g-models-2"}}),
    ]
    for method, route, url, kw in asked:
        r = client.request(method, url, **kw)
        assert r.status_code in (200, 202), (url, r.text[:300])
        _same(_model_of(app, method, route), r.json())
    job = client.get("/v1/jobs").json()["jobs"][0]["id"]
    _same(_model_of(app, "GET", "/v1/jobs/{job_id}"), client.get(f"/v1/jobs/{job}").json())


@pytest.mark.parametrize(
    ("method", "route", "url", "kw", "status"),
    [
        ("POST", "/v1/contact", "/v1/contact", {"json": {"ski": "ski-a"}}, 422),
        ("POST", "/v1/contact", "/v1/contact", {"json": {**CONTACT_BODY, "ski": "no"}}, 404),
        ("POST", "/v1/contact", "/v1/contact", {"content": b"x" * 70_000}, 413),
        ("GET", "/v1/skis/{name}", "/v1/skis/no", {}, 404),
        ("GET", "/v1/jobs/{job_id}", "/v1/jobs/no", {}, 404),
        ("DELETE", "/v1/grinds/{name}", "/v1/grinds/tiny-grind", {}, 403),
        ("POST", "/v1/grinds", "/v1/grinds", {"json": {"name": "x"}}, 415),
        ("GET", "/v1/flex/pair", "/v1/flex/pair", {"params": {"left": "ski-a"}}, 422),
    ],
)
def test_error_answers_are_declared_problems(app, client, spec, method, route, url, kw, status):
    r = client.request(method, url, **kw)
    assert r.status_code == status, r.text[:300]
    assert r.headers["content-type"] == MEDIA_TYPE
    _same(Problem, r.json())
    assert str(status) in spec["paths"][route][method.lower()]["responses"]
