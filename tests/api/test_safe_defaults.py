"""Safe by default (issue #15, point 5): who may change and see what (app/api/access.py), the job
quotas, the limit on the grid a table is solved on, and the web form's result cache keyed on
content. Uploads are the tiny ones of tests/jobs/test_uploads.py (64² grind, 8-point tables)."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest
from skisnow.app.api.access import cross_origin_reason
from skisnow.solvers.texture import PERIODISATION_METHODS, make_periodic, periodic_shape
from test_uploads import (
    CONTACT,
    heights_um,
    is_problem,
    make_client,
    npy_bytes,
    post_grind,
    post_ski,
    stored_files,
    wait_job,
)

TOKENS = {"token-a": "team-a", "token-b": "team-b"}
A = {"authorization": "Bearer token-a"}
B = {"authorization": "Bearer token-b"}
#: the TestClient's requests go to http://testserver
SAME = {"origin": "http://testserver"}
EVIL = {"origin": "http://evil.example"}


# --------------------------------------------------------------- same-origin check


@pytest.mark.parametrize(
    ("headers", "passes"),
    [
        ({"host": "127.0.0.1:8000"}, True),  # curl, scripts: neither Origin nor Referer
        ({"host": "127.0.0.1:8000", "origin": "http://127.0.0.1:8000"}, True),
        ({"host": "127.0.0.1:8000", "referer": "http://127.0.0.1:8000/upload?x=1"}, True),
        ({"host": "SKIS.example", "origin": "https://skis.example"}, True),  # default port
        ({"host": "skis.example:443", "origin": "https://skis.example"}, True),
        ({"host": "[::1]:8000", "origin": "http://[::1]:8000"}, True),
        ({"host": "127.0.0.1:8000", "origin": "http://127.0.0.1:8001"}, False),  # other port
        ({"host": "127.0.0.1:8000", "origin": "http://localhost:8000"}, False),  # other host
        ({"host": "skis.example", "origin": "http://skis.example:8080"}, False),
        ({"host": "127.0.0.1:8000", "origin": "null"}, False),  # sandboxed page, file://
        ({"host": "127.0.0.1:8000", "referer": "http://evil.example/page"}, False),
        # Origin decides when both are sent
        (
            {
                "host": "127.0.0.1:8000",
                "origin": "http://evil.example",
                "referer": "http://127.0.0.1:8000/upload",
            },
            False,
        ),
        ({"host": "127.0.0.1:8000", "origin": "http://127.0.0.1:8000:x"}, False),  # malformed
    ],
)
def test_same_origin_rule(headers, passes):
    reason = cross_origin_reason(headers)
    assert (reason is None) == passes, reason
    if not passes:
        assert "SKISNOW_TEAM_TOKENS" in reason and headers["host"] in reason


def test_trusted_origins_pass():
    headers = {"host": "10.0.0.5:8000", "origin": "https://skis.example"}
    assert cross_origin_reason(headers) is not None
    assert cross_origin_reason(headers, ["https://skis.example:443"]) is None


def test_cross_origin_changes_are_refused_without_tokens(catalogue, tmp_path):
    with make_client(catalogue, tmp_path) as client:
        r = post_grind(client, name="evil", headers=EVIL)
        body = is_problem(r, 403)
        assert "Origin http://evil.example" in body["detail"]
        r = post_grind(client, name="evil", headers={"referer": "http://evil.example/x"})
        assert "Referer" in is_problem(r, 403)["detail"]
        # refused before the body is read: a body over the upload limit is still a 403
        big = b"\x93NUMPY" + bytes(2_000_000)
        is_problem(post_grind(client, name="evil", content=big, headers=EVIL), 403)
        assert stored_files(tmp_path) == [] and client.get("/v1/jobs").json()["jobs"] == []

        # the upload page's own request (same origin, Referer /upload) and curl pass
        page = {**SAME, "referer": "http://testserver/upload"}
        r = post_grind(client, name="mine", headers=page)
        assert r.status_code == 202, r.text
        assert wait_job(client, r.json()["job"])["state"] == "done"
        r = post_grind(client, name="curl", headers={})
        assert r.status_code == 202, r.text
        assert wait_job(client, r.json()["job"])["state"] == "done"

        # renames and deletes are checked the same way
        is_problem(client.patch("/v1/grinds/mine", json={"name": "x"}, headers=EVIL), 403)
        is_problem(client.delete("/v1/grinds/mine", headers=EVIL), 403)
        assert client.get("/v1/grinds/mine").json()["state"] == "ready"
        r = client.patch("/v1/grinds/mine", json={"name": "mine-2"}, headers=SAME)
        assert r.status_code == 200
        assert client.delete("/v1/grinds/mine-2", headers=SAME).status_code == 204

        # computations change nothing and stay open (app/api/access.py READ_ONLY_POSTS)
        r = client.post(
            "/v1/contact", json={"ski": "ski-a", "grind": "curl", **CONTACT}, headers=EVIL
        )
        assert r.status_code == 200, r.text[:300]
        assert "access-control-allow-origin" not in r.headers  # another site cannot read it


def test_trusted_origin_setting_lets_a_proxy_origin_change(catalogue, tmp_path):
    proxy = {"origin": "https://skis.example"}
    with make_client(catalogue, tmp_path, trusted_origins=["https://skis.example"]) as client:
        assert post_grind(client, name="via-proxy", headers=proxy).status_code == 202
        is_problem(post_grind(client, name="evil", headers=EVIL), 403)


def test_with_tokens_a_change_needs_a_token_whatever_its_origin(catalogue, tmp_path):
    with make_client(catalogue, tmp_path, team_tokens=TOKENS) as client:
        r = post_grind(client, name="x", headers=SAME)
        assert is_problem(r, 401) and r.headers["www-authenticate"] == "Bearer"
        r = post_grind(client, name="x", headers={"authorization": "Bearer wrong"})
        is_problem(r, 401)
        # 401 before the body is read (it is over the upload limit here)
        big = b"\x93NUMPY" + bytes(2_000_000)
        is_problem(post_grind(client, name="x", content=big), 401)
        # a browser never adds the bearer token on its own: the token is the check
        r = post_grind(client, name="x", headers={**A, **EVIL})
        assert r.status_code == 202, r.text
        wait_job(client, r.json()["job"], headers=A)


# ------------------------------------------------------------------------ quotas


def _stop_runner(client) -> None:
    """Stop the job runner so that queued jobs stay queued."""
    client.app.state.uploads.runner.stop()


def test_per_team_quota_and_queue_cap(catalogue, tmp_path, upload_csv):
    limits = {"team_tokens": TOKENS, "max_jobs_per_team": 2, "max_queued_jobs": 3}
    with make_client(catalogue, tmp_path, **limits) as client:
        _stop_runner(client)
        for i in range(2):
            assert post_grind(client, name=f"a-{i}", headers=A).status_code == 202
        r = post_grind(client, name="a-2", headers=A)
        body = is_problem(r, 429)
        assert "max_jobs_per_team" in body["detail"] and "team-a" in body["detail"]
        assert int(r.headers["retry-after"]) > 0
        is_problem(post_ski(client, upload_csv, name="a-ski", headers=A), 429)
        # a taken name is refused as such (409), not with "retry later": it stays taken
        body = is_problem(post_grind(client, name="a-0", headers=A), 409)
        assert "already exists" in body["detail"]
        # team b has its own quota, until the service's cap (3) is reached
        assert post_grind(client, name="b-0", headers=B).status_code == 202
        r = post_grind(client, name="b-1", headers=B)
        assert "max_queued_jobs" in is_problem(r, 429)["detail"]
        assert r.headers["retry-after"]
        names = {i.name for i in client.app.state.uploads.db.items("grind")}
        assert {"a-2", "b-1"}.isdisjoint(names)  # refused uploads leave no item
        # a finished job frees its slot: only queued and running jobs count
        db = client.app.state.uploads.db
        db.update_job(db.jobs(states=("queued",))[-1].id, state="done")
        assert post_grind(client, name="a-2", headers=A).status_code == 202


def test_without_tokens_everyone_is_one_team(catalogue, tmp_path):
    with make_client(catalogue, tmp_path, max_jobs_per_team=1) as client:
        _stop_runner(client)
        assert post_grind(client, name="first").status_code == 202
        r = post_grind(client, name="second", headers=SAME)
        detail = is_problem(r, 429)["detail"]
        assert "max_jobs_per_team" in detail and "SKISNOW_MAX_JOBS_PER_TEAM" in detail


def test_defaults_refuse_the_mirror_of_the_largest_upload():
    """The issue's case: a 1 M-point upload (the largest by default) mirrored to 4 M points is
    refused by the default limits; as measured, or a quarter of it mirrored, it passes."""
    from skisnow.app.jobs.uploads import check_solve_grid
    from skisnow.app.settings import Settings
    from skisnow.solvers.errors import InputError

    s = Settings()
    assert 1 <= s.max_jobs_per_team <= s.max_queued_jobs
    side = int(np.sqrt(s.max_solve_grid_points))
    with pytest.raises(InputError, match="max_solve_grid_points"):
        check_solve_grid((side, side), "mirror", s)
    check_solve_grid((side, side), "none", s)
    check_solve_grid((side // 2, side // 2), "mirror", s)


# ------------------------------------------------------------------ solve grid


@pytest.mark.parametrize("method", PERIODISATION_METHODS)
@pytest.mark.parametrize("shape", [(16, 16), (17, 30), (31, 16)])
def test_periodic_shape_is_that_of_make_periodic(method, shape):
    h = np.random.default_rng(3).standard_normal(shape)
    assert periodic_shape(shape, method) == make_periodic(h, method).shape


def test_solve_grid_is_limited_after_periodisation(catalogue, tmp_path):
    """A 64² map is solved on 128² with the default mirror tiling: the limit applies to that
    grid, before anything is stored or queued. By default the map is reduced (block average,
    recorded); with ``reduce=none`` it is refused."""
    limit = 128 * 128 - 1
    with make_client(catalogue, tmp_path, max_solve_grid_points=limit) as client:
        r = post_grind(client, name="mirrored", reduce="none")
        detail = is_problem(r, 422)["detail"]
        assert "128×128 = 16384 points" in detail and "max_solve_grid_points" in detail
        assert stored_files(tmp_path) == [] and client.get("/v1/jobs").json()["jobs"] == []
        r = post_grind(client, name="mirrored")
        assert r.status_code == 202, r.text
        reduction = r.json()["preparation"]["reduction"]
        assert reduction["method"] == "block" and reduction["grid"] == [32, 32]
        assert r.json()["item"]["metadata"]["solve_grid"] == [64, 64]
        wait_job(client, r.json()["job"])
        # as measured (no mirror), the same map is solved on its 64² grid
        r = post_grind(client, name="as-measured", periodic="window")
        assert r.status_code == 202, r.text
        assert r.json()["item"]["metadata"]["solve_grid"] == [64, 64]
        wait_job(client, r.json()["job"])
    with make_client(catalogue, tmp_path / "edge", max_solve_grid_points=128 * 128) as client:
        r = post_grind(client, name="at-the-limit")
        assert r.status_code == 202, r.text  # the limit itself is allowed
        wait_job(client, r.json()["job"])


# -------------------------------------------------------------- team filtering


def test_reads_show_only_the_callers_team_and_the_shipped_items(catalogue, tmp_path):
    with make_client(catalogue, tmp_path, team_tokens=TOKENS) as client:
        r = post_grind(client, name="a-grind", headers=A)
        job_id = r.json()["job"]
        assert wait_job(client, job_id, headers=A)["state"] == "done"

        def grinds(headers):
            return {g["name"] for g in client.get("/v1/grinds", headers=headers).json()["grinds"]}

        assert grinds(A) == {"tiny-grind", "a-grind"}
        assert grinds(B) == grinds({}) == {"tiny-grind"}
        assert client.get("/readyz", headers=A).json()["grinds"] == ["a-grind", "tiny-grind"]
        assert client.get("/readyz", headers=B).json()["grinds"] == ["tiny-grind"]

        # the item: 404 for another team (not 403), and its name is not among the known ones
        assert client.get("/v1/grinds/a-grind", headers=A).json()["team"] == "team-a"
        for headers in (B, {}):
            body = is_problem(client.get("/v1/grinds/a-grind", headers=headers), 404)
            assert "a-grind" not in body["known"] and "tiny-grind" in body["known"]
        assert client.get("/v1/grinds/tiny-grind", headers=B).status_code == 200  # shipped

        # jobs
        assert [j["id"] for j in client.get("/v1/jobs", headers=A).json()["jobs"]] == [job_id]
        assert client.get("/v1/jobs", headers=B).json()["jobs"] == []
        assert client.get("/v1/jobs").json()["jobs"] == []
        is_problem(client.get(f"/v1/jobs/{job_id}", headers=B), 404)
        is_problem(client.get(f"/v1/jobs/{job_id}"), 404)

        # computing with another team's grind is the same 404 as an unknown one
        body = {"ski": "ski-a", "grind": "a-grind", **CONTACT}
        assert client.post("/v1/contact", json=body, headers=A).status_code == 200
        assert (
            "a-grind"
            not in is_problem(client.post("/v1/contact", json=body, headers=B), 404)["known"]
        )
        cmp = {"skis": ["ski-a"], "grinds": ["a-grind"], **CONTACT}
        is_problem(client.post("/v1/compare", json=cmp, headers=B), 404)

        # the web form (a browser sends no token: a caller of no team)
        assert 'value="a-grind"' not in client.get("/").text
        assert 'value="a-grind"' in client.get("/", headers=A).text
        q = {"ski": "ski-a", "grind": "a-grind", "load_kg": 40, "load_position_mm": -160}
        q |= {"snow_modulus_mpa": 200, "porosity": 0.5}
        assert client.get("/results", params=q).status_code == 404
        assert client.get("/results", params=q, headers=A).status_code == 200

        # an invalid token is refused, not read as "no team"
        is_problem(client.get("/v1/jobs", headers={"authorization": "Bearer nope"}), 401)


def check_team_queries(db) -> None:
    """The database's team queries (jobs a team sees, active jobs per team) on ``db``, an empty
    catalogue; run on SQLite here and on PostgreSQL in tests/storage/test_postgres.py."""
    shipped = db.add_item("grind", "shipped", state="ready", read_only=True)
    jobs = {}
    for team in ("team-a", "team-b", None):
        item = db.add_item("grind", f"g-{team}", team=team)
        jobs[team] = [db.add_job("grind-table", item.id).id for _ in range(2)]
    db.update_job(jobs["team-a"][0], state="done")
    db.update_job(jobs["team-b"][0], state="running")
    jobs["shipped"] = [db.add_job("grind-table", shipped.id).id]

    def seen(team):
        return {j.id for j in db.jobs(by_team=True, team=team)}

    public = set(jobs[None]) | set(jobs["shipped"])
    assert seen("team-a") == set(jobs["team-a"]) | public
    assert seen(None) == public
    assert {j.id for j in db.jobs()} == {j for ids in jobs.values() for j in ids}
    assert db.active_job_counts() == {"team-a": 1, "team-b": 2, None: 3}


def test_team_queries_on_sqlite(tmp_path):
    from skisnow.app.storage.catalogue import CatalogueDB

    db = CatalogueDB(f"sqlite:///{tmp_path / 'c.db'}")
    check_team_queries(db)
    db.close()


def test_upload_page_polls_its_job_with_the_token():
    """With team tokens a job is shown only to its team: the page's poll sends the token."""
    from importlib import resources

    js = resources.files("skisnow.app.web").joinpath("static/upload.js").read_text("utf-8")
    poll = js[js.index("function poll()") : js.index("function poll()") + 600]
    assert "authorization" in poll and '"/v1/jobs/"' in poll


# ------------------------------------------------------- web result cache (content)


def _csv_row(client, grind: str) -> dict:
    q = {"ski": "ski-a", "grind": grind, "load_kg": 40, "load_position_mm": -160}
    q |= {"snow_modulus_mpa": 200, "porosity": 0.5, "ski_model": "rigid"}
    r = client.get("/results.csv", params=q)
    assert r.status_code == 200, r.text[:300]
    (row,) = csv.DictReader(io.StringIO(r.text))
    return row


def test_web_cache_follows_a_delete_and_reupload_under_the_same_name(catalogue, tmp_path):
    """Upload, compute, delete, upload other heights under the same name, compute: the new
    grind's answer (the cache was keyed by names only and served the deleted grind's)."""
    with make_client(catalogue, tmp_path) as client:
        r = post_grind(client, name="shop-grind")
        assert wait_job(client, r.json()["job"])["state"] == "done"
        first = _csv_row(client, "shop-grind")
        assert _csv_row(client, "shop-grind") == first  # the same inputs: the same answer

        # a rename: the answer of the same content under its new name
        assert client.patch("/v1/grinds/shop-grind", json={"name": "renamed"}).status_code == 200
        renamed = _csv_row(client, "renamed")
        assert renamed["table_sha256"] == first["table_sha256"]
        assert renamed["total_real_contact_area_mm2"] == first["total_real_contact_area_mm2"]
        assert client.patch("/v1/grinds/renamed", json={"name": "shop-grind"}).status_code == 200

        assert client.delete("/v1/grinds/shop-grind").status_code == 204
        rougher = npy_bytes(3.0 * heights_um(seed=2))
        r = post_grind(client, name="shop-grind", content=rougher)
        assert wait_job(client, r.json()["job"])["state"] == "done"
        second = _csv_row(client, "shop-grind")
        assert second["table_sha256"] != first["table_sha256"]
        a1 = float(first["total_real_contact_area_mm2"])
        a2 = float(second["total_real_contact_area_mm2"])
        # three times the roughness: clearly less real contact area (not a rounding change)
        assert a2 < 0.8 * a1, (a1, a2)
