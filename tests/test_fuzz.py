"""The HTTP API fuzzed from its own OpenAPI schema (schemathesis 4; issue 6 §3).

Every operation of ``/openapi.json`` (``/healthz``, ``/readyz``, ``/v1/skis``, ``/v1/grinds``,
``/v1/contact``, ``/v1/compare``) is called in process (schemathesis' ASGI client, one session
for the module) with:

- **positive** cases: bodies that fit the schema; three in four of them get the catalogue's
  ski and grind names, and half of those a load and position inside the camber network's trained
  range, so the macro and multiscale solvers run on schema-valid extremes (modulus 1 MPa with
  150 kg, porosity 0.999…, Poisson 0.499…);
- **negative** cases: bodies, queries and headers that violate the schema (wrong types,
  missing or extra fields, out-of-range numbers, malformed JSON).

Each answer must be below 500, and every error (4xx) must be an RFC 9457 problem body:
``application/problem+json`` with ``status`` (equal to the HTTP status), ``title`` and
``detail`` strings. Successful answers must be JSON (``allow_nan=False`` in the response
renderer turns a NaN into a 500, so finiteness is checked on the way).

The app runs on the fast test catalogue (``tests/conftest.py``: the demo skis and a 64 × 64
synthetic grind ``tiny-grind``), so a solved request takes tens of milliseconds. Runs are
derandomized (the same requests every run). The default run sends 520 requests (about 60 s on
a loaded 2-core machine); a ten times longer run is marked ``slow`` and skipped unless asked for::

    SKISNOW_SLOW_TESTS=1 python -m pytest -q -m slow tests/test_fuzz.py
"""

from __future__ import annotations

import json
import math
import os

import pytest
import schemathesis
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from schemathesis import GenerationMode
from schemathesis.python import asgi

from app import service
from app.api import create_app
from app.settings import Settings

#: requests per test in the default (CI) run, 520 in all; the slow run sends ten times more
REQUESTS = 200
#: schema-valid contact and compare requests (most of them solved: ~0.1 s each)
SOLVER_REQUESTS = 120
LONG = os.environ.get("SKISNOW_SLOW_TESTS") == "1"

#: load [kg] and position [mm] ranges of the demo skis' camber networks (trained range)
LOAD_KG = (10.0, 82.0)
POSITION_MM = (-300.0, 100.0)


@pytest.fixture(scope="module")
def fuzz_catalogue(catalogue):
    """A private copy of the test catalogue: requests that rename or delete items must not
    change the session's shared one."""
    return service.Catalogue(
        tables_dir=catalogue.tables_dir, skis=dict(catalogue.skis), grinds=dict(catalogue.grinds)
    )


@pytest.fixture(scope="module")
def app(fuzz_catalogue, tmp_path_factory):
    settings = Settings(
        max_body_bytes=4096,
        max_compare_cells=4,  # compare matrices of at most 4 solves keep each request short
        warm_up=False,
        data_dir=tmp_path_factory.mktemp("fuzz-data"),  # catalogue database and uploads
    )
    return create_app(settings, catalogue=fuzz_catalogue)


@pytest.fixture(scope="module")
def schema(app):
    return schemathesis.openapi.from_asgi("/openapi.json", app)


@pytest.fixture(scope="module")
def session(app):
    with asgi.get_client(app) as client:
        yield client


def test_schema_lists_every_api_operation(schema):
    labels = {op.ok().label for op in schema.get_all_operations()}
    assert labels >= {
        "GET /healthz",
        "GET /readyz",
        "GET /v1/skis",
        "GET /v1/grinds",
        "POST /v1/contact",
        "POST /v1/compare",
    }


def _check_answer(case, response) -> None:
    """No 5xx; errors are problem+json naming status, title and detail; 2xx is JSON."""
    where = f"{case.operation.label}\n{case.as_curl_command()}"
    status = response.status_code
    assert status < 500, f"{status} on {where}\n{response.text[:500]}"
    ctype = (response.headers.get("content-type") or [""])[0]
    if status >= 400:
        assert ctype.startswith("application/problem+json"), f"{ctype!r} on {where}"
        body = json.loads(response.content)
        assert isinstance(body, dict), where
        assert body.get("status") == status, (body, where)
        for key in ("title", "detail"):
            assert isinstance(body.get(key), str) and body[key].strip(), (key, body, where)
        if "errors" in body:
            assert all(isinstance(e.get("field"), str) for e in body["errors"]), (body, where)
    else:
        assert status == 200, where
        assert ctype.startswith("application/json"), f"{ctype!r} on {where}"
        body = json.loads(response.content)  # strict JSON: a NaN would not parse back
        if case.operation.label == "POST /v1/contact":
            assert all(math.isfinite(v) for v in body["metrics"].values()), (body, where)
            assert body["provenance"]["macro"]["converged"] is True, where


def _known_names(draw, case, catalogue) -> None:
    """Put catalogue names (and sometimes a load in the trained range) into three in four
    positive cases, so that most of them reach the solvers rather than a 404."""
    if not draw(st.integers(0, 3)):
        return
    skis, grinds = sorted(catalogue.skis), sorted(catalogue.grinds)
    if isinstance(case.path_parameters, dict) and "name" in case.path_parameters:
        plural = case.operation.path.split("/")[2]
        case.path_parameters["name"] = draw(st.sampled_from(skis if plural == "skis" else grinds))
    body = case.body
    if not isinstance(body, dict):
        return
    if "ski" in body:
        body["ski"] = draw(st.sampled_from(skis))
        body["grind"] = draw(st.sampled_from(grinds))
    if "skis" in body:
        body["skis"] = draw(st.lists(st.sampled_from(skis), min_size=1, max_size=2))
        body["grinds"] = draw(st.lists(st.sampled_from(grinds), min_size=1, max_size=2))
    if "load_kg" in body and draw(st.booleans()):
        body["load_kg"] = draw(st.floats(*LOAD_KG))
        body["load_position_mm"] = draw(st.floats(*POSITION_MM))


def _fuzz(schema, session, catalogue, mode: GenerationMode, examples: int, operations=None) -> dict:
    """Send ``examples`` generated requests (to every operation, or to ``operations``: a list
    of (path, method)); return the counts per operation and status."""
    counts: dict[str, int] = {}
    if operations is None:
        strategy = schema.as_strategy(generation_mode=mode)
    else:
        strategy = st.one_of(
            [schema[path][method].as_strategy(generation_mode=mode) for path, method in operations]
        )

    @settings(
        max_examples=examples,
        derandomize=True,
        deadline=None,
        database=None,
        phases=[Phase.generate, Phase.shrink],
        suppress_health_check=list(HealthCheck),
    )
    @given(data=st.data())
    def run(data):
        case = data.draw(strategy, label="case")
        if mode is GenerationMode.POSITIVE:
            _known_names(data.draw, case, catalogue)
        try:
            response = case.call(session=session)
        except Exception as exc:  # the app raised instead of answering
            pytest.fail(f"{type(exc).__name__}: {exc} on {case.as_curl_command()}")
        key = f"{case.operation.label} {response.status_code}"
        counts[key] = counts.get(key, 0) + 1
        _check_answer(case, response)

    run()
    return counts


SOLVER_OPERATIONS = [("/v1/contact", "POST"), ("/v1/compare", "POST")]


def _assert_coverage(
    counts: dict, examples: int, mode: GenerationMode, min_solved: int | None = None
) -> None:
    """``min_solved``: answered contacts (200) required; default ``examples // 40``. Runs over
    every operation spread their examples over ~15 operations in a way that depends on the
    hypothesis version, so they only require that the solvers ran at all."""
    assert sum(counts.values()) >= examples, counts
    ops = {k.rsplit(" ", 1)[0] for k in counts}
    assert {"POST /v1/contact", "POST /v1/compare"} <= ops, counts
    statuses = {int(k.rsplit(" ", 1)[1]) for k in counts}
    assert 422 in statuses, counts
    if mode is GenerationMode.POSITIVE:
        # the solvers ran (200) and unknown names were refused (404)
        need = examples // 40 if min_solved is None else min_solved
        assert counts.get("POST /v1/contact 200", 0) >= need, counts
        assert {200, 404} <= statuses, counts


def test_fuzz_every_operation_positive(schema, session, fuzz_catalogue):
    counts = _fuzz(schema, session, fuzz_catalogue, GenerationMode.POSITIVE, REQUESTS)
    _assert_coverage(counts, REQUESTS, GenerationMode.POSITIVE, min_solved=1)


def test_fuzz_solver_operations_positive(schema, session, fuzz_catalogue):
    """Schema-valid contact and compare bodies: the solvers on the extremes of the schema."""
    counts = _fuzz(
        schema, session, fuzz_catalogue, GenerationMode.POSITIVE, SOLVER_REQUESTS, SOLVER_OPERATIONS
    )
    _assert_coverage(counts, SOLVER_REQUESTS, GenerationMode.POSITIVE)
    # at least a tenth of the requests were solved; contact and compare both run the solvers,
    # and how the derandomized draw splits between them moves with the schema's shape (adding
    # ski_model moved it from contact to compare)
    solved = counts.get("POST /v1/contact 200", 0) + counts.get("POST /v1/compare 200", 0)
    assert solved >= SOLVER_REQUESTS // 10, counts


def test_fuzz_every_operation_negative(schema, session, fuzz_catalogue):
    counts = _fuzz(schema, session, fuzz_catalogue, GenerationMode.NEGATIVE, REQUESTS)
    _assert_coverage(counts, REQUESTS, GenerationMode.NEGATIVE)


@pytest.mark.slow
@pytest.mark.skipif(not LONG, reason="long fuzz run: set SKISNOW_SLOW_TESTS=1")
@pytest.mark.parametrize("mode", [GenerationMode.POSITIVE, GenerationMode.NEGATIVE])
@pytest.mark.parametrize("operations", [None, SOLVER_OPERATIONS], ids=["every", "solvers"])
def test_fuzz_long(schema, session, fuzz_catalogue, mode, operations):
    counts = _fuzz(schema, session, fuzz_catalogue, mode, 10 * REQUESTS, operations)
    _assert_coverage(counts, 10 * REQUESTS, mode)
