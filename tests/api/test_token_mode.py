"""Token mode for people (issue #27 point 4): the login cookie, the uploads of no team made
read-only, ``skisnow adopt``, and names unique regardless of case (app/api/access.py,
app/web/login.py, app/commands/adopt.py, app/storage/catalogue.py). Uploads are the tiny ones
of tests/jobs/test_uploads.py."""

from __future__ import annotations

import re
from html import unescape

import pytest
from fastapi.testclient import TestClient
from skisnow.app.storage.catalogue import CatalogueDB, NameTakenError
from test_uploads import is_problem, make_client, post_grind, wait_job

TOKENS = {"token-a": "team-a", "token-b": "team-b"}
A = {"authorization": "Bearer token-a"}
B = {"authorization": "Bearer token-b"}
#: the TestClient's requests go to http://testserver
SAME = {"origin": "http://testserver"}
EVIL = {"origin": "http://evil.example"}
#: another port of the same host: the same site, so SameSite=Strict does not stop the cookie
SAME_SITE = {"origin": "http://testserver:8081"}
#: the login cookie (app.api.access.TOKEN_COOKIE; spelled out: a test of the cookie's name)
TOKEN_COOKIE = "skisnow_token"


def _login(client, token="token-a", next_url="/", headers=None):
    return client.post(
        "/login",
        data={"token": token, "next": next_url},
        headers=headers or SAME,
        follow_redirects=False,
    )


def _set_cookie(resp) -> str:
    return resp.headers.get("set-cookie", "")


# ------------------------------------------------------------------------- the login


def test_login_turns_a_team_token_into_an_httponly_strict_cookie(catalogue, tmp_path):
    with make_client(catalogue, tmp_path, team_tokens=TOKENS) as client:
        page = client.get("/login?next=/upload")
        assert page.status_code == 200 and 'name="token"' in page.text
        assert 'value="/upload"' in page.text

        r = _login(client, next_url="/upload")
        assert r.status_code == 303 and r.headers["location"] == "/upload"
        cookie = _set_cookie(r).lower()
        assert cookie.startswith(f"{TOKEN_COOKIE}=token-a")
        assert "httponly" in cookie and "samesite=strict" in cookie and "path=/" in cookie
        assert "secure" not in cookie  # served over http here
        # the pages know the team: the header names it and offers to log out
        html = client.get("/").text
        assert 'id="login-team">team team-a' in html and 'action="/logout"' in html
        assert 'id="nav-login"' not in html

        r = client.post("/logout", headers=SAME, follow_redirects=False)
        assert r.status_code == 303 and f"{TOKEN_COOKIE}=" in _set_cookie(r)
        assert 'id="nav-login"' in client.get("/").text


def test_the_cookie_is_secure_when_served_over_https(catalogue, tmp_path):
    app = make_client(catalogue, tmp_path, team_tokens=TOKENS).app
    with TestClient(app, base_url="https://testserver") as client:
        r = _login(client, headers={"origin": "https://testserver"})
        assert r.status_code == 303
        assert "secure" in _set_cookie(r).lower()


def test_a_wrong_token_or_a_foreign_page_gets_no_cookie(catalogue, tmp_path):
    with make_client(catalogue, tmp_path, team_tokens=TOKENS) as client:
        r = _login(client, token="nope")
        assert r.status_code == 401 and "set-cookie" not in r.headers
        assert "not a team token" in r.text and 'id="login-error"' in r.text
        r = _login(client, token="")
        assert r.status_code == 401 and "no team token was given" in r.text
        # a login posted by another site's (or origin's) page: refused before it is read
        for origin in (EVIL, SAME_SITE):
            r = _login(client, headers=origin)
            assert "set-cookie" not in r.headers
            assert "login" in is_problem(r, 403)["detail"]
        # a redirect goes nowhere but to this service
        r = _login(client, next_url="//evil.example/x")
        assert r.status_code == 303 and r.headers["location"] == "/"


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ("/upload?grind_job=1", "/upload?grind_job=1"),
        ("/", "/"),
        ("//evil.example", "/"),
        ("/\\evil.example", "/"),
        ("https://evil.example/", "/"),
        ("upload", "/"),
        ("/x\r\nSet-Cookie: a=b", "/"),
        (None, "/"),
    ],
)
def test_safe_next(value, expected):
    from skisnow.app.web.login import safe_next

    assert safe_next(value) == expected


def test_without_team_tokens_there_is_nothing_to_log_in_to(catalogue, tmp_path):
    with make_client(catalogue, tmp_path) as client:
        assert 'id="nav-login"' not in client.get("/").text
        assert 'id="login-off"' in client.get("/login").text
        r = _login(client, token="anything")
        assert r.status_code == 404 and "set-cookie" not in r.headers


# ------------------------------------------------- upload → job → contact in the browser


def test_a_logged_in_team_uploads_follows_its_job_and_computes_with_it(catalogue, tmp_path):
    """What the upload page's script does (tests/web/test_browser.py drives the same page):
    post the form with no Authorization header, poll the job, open the done link."""
    with make_client(catalogue, tmp_path, team_tokens=TOKENS) as client:
        # not logged in: the upload page asks for a token, a change without one is 401
        assert client.get("/upload").text.count("Team token") == 2
        r = post_grind(client, name="a-grind", headers={**SAME, "referer": "http://testserver/"})
        assert "/login" in is_problem(r, 401)["detail"]

        assert _login(client).status_code == 303
        upload_page = client.get("/upload").text
        assert "Team token" not in upload_page  # the cookie carries it
        r = post_grind(client, name="a-grind", headers={**SAME, "referer": "http://testserver/"})
        assert r.status_code == 202, r.text
        assert r.json()["item"]["team"] == "team-a"
        job = wait_job(client, r.json()["job"])  # the page polls with the cookie only
        assert job["state"] == "done" and job["item"] == "a-grind"

        # the done link: the page's data-return query + &grind=NAME
        ret = re.search(r'data-kind="grind".*?data-return="([^"]+)"', upload_page, re.S)
        form = client.get(unescape(ret.group(1)) + "&grind=a-grind")
        assert form.status_code == 200, form.text[:300]
        assert "unknown grind" not in form.text
        assert re.search(r'value="a-grind" checked', form.text)
        assert 'value="a-grind"' in client.get("/").text  # the team's uploads are listed
        query = unescape(ret.group(1)).removeprefix("/?") + "&grind=a-grind"
        r = client.get(f"/results?{query}")
        assert r.status_code == 200 and "a-grind" in r.text, r.text[:300]

        # another browser (no cookie) and team b do not see it
        other = TestClient(client.app)  # the same running app (no second lifespan)
        assert "unknown grind &#39;a-grind&#39;" in other.get("/?grind=a-grind").text
        assert _login(other, token="token-b").status_code == 303
        assert 'value="a-grind"' not in other.get("/").text


def test_changes_by_cookie_need_the_services_own_origin(catalogue, tmp_path):
    with make_client(catalogue, tmp_path, team_tokens=TOKENS) as client:
        assert _login(client).status_code == 303
        r = post_grind(client, name="a-grind", headers=SAME)
        assert r.status_code == 202, r.text
        wait_job(client, r.json()["job"])
        # another site's page (the cookie is SameSite=Strict: a browser would not even send
        # it) and another origin of the same site (it would) are refused
        for origin in (EVIL, SAME_SITE):
            detail = is_problem(client.delete("/v1/grinds/a-grind", headers=origin), 403)["detail"]
            assert "login cookie" in detail
            is_problem(post_grind(client, name="evil", headers=origin), 403)
        # with a bearer token the header decides, whatever the origin (as before)
        r = client.patch("/v1/grinds/a-grind", json={"name": "a-grind-2"}, headers={**A, **EVIL})
        assert r.status_code == 200, r.text
        # team b's login cannot touch team a's grind
        client.cookies.set(TOKEN_COOKIE, "token-b")
        is_problem(client.delete("/v1/grinds/a-grind-2", headers=SAME), 404)
        # a login whose token was withdrawn reads as no team and changes nothing
        client.cookies.set(TOKEN_COOKIE, "withdrawn")
        assert client.get("/").status_code == 200
        assert "log in again" in is_problem(client.delete("/v1/grinds/a-grind-2"), 401)["detail"]
        client.cookies.set(TOKEN_COOKIE, "token-a")
        assert client.delete("/v1/grinds/a-grind-2", headers=SAME).status_code == 204

        # a failed ski's page: its delete button asks for a token only when not logged in
        db = client.app.state.uploads.db
        client.app.state.uploads.runner.stop()  # the jobs below are set by hand
        broken = db.add_item("ski", "broken", state="failed", team="team-a")
        db.update_job(db.add_job("ski-network", broken.id).id, state="failed", error="test")
        page = client.get("/skis/broken").text
        field = '<input type="password" data-token'
        assert 'id="delete-ski"' in page and field not in page
        assert client.delete("/v1/skis/broken", headers=SAME).status_code == 204
        orphan = db.add_item("ski", "orphan", state="failed")  # seen by a browser not logged in
        db.update_job(db.add_job("ski-network", orphan.id).id, state="failed", error="test")
        assert field in TestClient(client.app).get("/skis/orphan").text


# ------------------------------------------------------------ the uploads of no team


def test_uploads_of_no_team_are_read_only_once_tokens_are_on_until_adopted(
    catalogue, tmp_path, monkeypatch, capsys
):
    from skisnow.app.cli import main

    with make_client(catalogue, tmp_path) as client:  # before tokens
        for name in ("old-grind", "old-grind-2"):
            r = post_grind(client, name=name)
            assert r.status_code == 202 and wait_job(client, r.json()["job"])["state"] == "done"
    with make_client(catalogue, tmp_path, team_tokens=TOKENS) as client:
        for headers in (A, B):
            assert client.get("/v1/grinds/old-grind", headers=headers).status_code == 200
            r = client.patch("/v1/grinds/old-grind", json={"name": "mine"}, headers=headers)
            assert "skisnow adopt" in is_problem(r, 403)["detail"]
            is_problem(client.delete("/v1/grinds/old-grind", headers=headers), 403)
        assert _login(client).status_code == 303  # by cookie too
        is_problem(client.delete("/v1/grinds/old-grind", headers=SAME), 403)

        # the operator gives one to team a (in the service's data directory)
        monkeypatch.setenv("SKISNOW_DATA_DIR", str(tmp_path / "elsewhere"))
        assert main(["adopt", "--list"]) == 2
        assert "no catalogue at" in capsys.readouterr().err
        assert not (tmp_path / "elsewhere").exists()  # nothing made there
        monkeypatch.setenv("SKISNOW_DATA_DIR", str(tmp_path))
        monkeypatch.setenv("SKISNOW_TEAM_TOKENS", '{"token-a": "team-a", "token-b": "team-b"}')
        assert main(["adopt", "--list"]) == 0
        out = capsys.readouterr().out
        assert "grind\told-grind\tready" in out and "tiny-grind" not in out
        assert main(["adopt", "--team", "team-c", "old-grind"]) == 2
        assert "not a configured team" in capsys.readouterr().err
        assert main(["adopt", "--team", "team-a", "no-such"]) == 2
        assert main(["adopt", "--team", "team-a", "tiny-grind"]) == 2  # shipped
        assert "shipped" in capsys.readouterr().err
        assert main(["adopt", "--team", "team-a", "old-grind"]) == 0
        assert "1 item(s) adopted by team team-a" in capsys.readouterr().out
        assert main(["adopt", "--team", "team-b", "old-grind"]) == 2  # never taken over
        assert "belongs to team 'team-a' already" in capsys.readouterr().err

        client.app.state.uploads.live.sync()  # the service's poll (job_poll_s)
        is_problem(client.get("/v1/grinds/old-grind", headers=B), 404)
        r = client.patch("/v1/grinds/old-grind", json={"name": "a-old"}, headers=A)
        assert r.status_code == 200 and r.json()["team"] == "team-a"
        # the other stays read-only, until --all gives it away
        is_problem(client.delete("/v1/grinds/old-grind-2", headers=A), 403)
        assert main(["adopt", "--team", "team-b", "--all"]) == 0
        client.app.state.uploads.live.sync()
        assert client.delete("/v1/grinds/old-grind-2", headers=B).status_code == 204


# ------------------------------------------------------------ names regardless of case


def test_names_differing_only_in_case_are_refused(catalogue, tmp_path):
    with make_client(catalogue, tmp_path, team_tokens=TOKENS) as client:
        body = is_problem(post_grind(client, name="Tiny-Grind", headers=A), 409)
        assert "'tiny-grind'" in body["detail"] and "regardless of case" in body["detail"]
        r = post_grind(client, name="a-grind", headers=A)
        wait_job(client, r.json()["job"], headers=A)
        # team b does not see team a's grind, but the name is one namespace
        body = is_problem(post_grind(client, name="A-GRIND", headers=B), 409)
        assert "regardless of case" in body["detail"]
        # a rename onto another item's name in another case; its own name in another case is
        # fine
        r = post_grind(client, name="b-grind", headers=A)
        wait_job(client, r.json()["job"], headers=A)
        r = client.patch("/v1/grinds/b-grind", json={"name": "A-Grind"}, headers=A)
        assert "'a-grind'" in is_problem(r, 409)["detail"]
        r = client.patch("/v1/grinds/b-grind", json={"name": "B-Grind"}, headers=A)
        assert r.status_code == 200 and r.json()["name"] == "B-Grind"


def check_catalogue_names_nocase(url: str) -> None:
    """The database's own refusal (shared with tests/storage/test_postgres.py): the check in
    the insert's transaction names the clash, and the unique index holds without it."""
    db = CatalogueDB(url)
    try:
        db.add_item("grind", "grind-1", state="ready", read_only=True)
        db.add_item("ski", "Grind-1")  # another kind: another namespace
        with pytest.raises(NameTakenError, match="existing ski 'Grind-1'"):
            db.add_item("ski", "grind-1")
        with pytest.raises(NameTakenError, match="existing grind 'grind-1'"):
            db.add_item("grind", "Grind-1")
        other = db.add_item("grind", "grind-2")
        with pytest.raises(NameTakenError, match="'grind-1'"):
            db.update_item(other.id, name="GRIND-1")
        # the index alone (a concurrent insert passes the check before either commits)
        import sqlalchemy as sa
        from skisnow.app.storage.catalogue import ITEMS

        row = {
            "id": "f" * 32,
            "kind": "grind",
            "name": "GRIND-2",
            "metadata": {},
            "state": "pending",
            "read_only": False,
            "created_at": other.created_at,
            "updated_at": other.created_at,
        }
        with pytest.raises(sa.exc.IntegrityError), db.engine.begin() as c:
            c.execute(ITEMS.insert().values(**row))
        assert [i.name for i in db.items("grind")] == ["grind-1", "grind-2"]
    finally:
        db.close()


def test_catalogue_names_are_unique_regardless_of_case_on_sqlite(tmp_path):
    check_catalogue_names_nocase(f"sqlite:///{tmp_path / 'catalogue.db'}")


def test_old_catalogue_with_case_clashes_keeps_them_and_refuses_new_ones(tmp_path, caplog):
    """Revision 0003 renames nothing: names that differ in case already are kept (with a
    warning, and no index), and new clashes are still refused."""
    import sqlalchemy as sa
    from alembic import command
    from skisnow.app.storage.schema import _config

    url = f"sqlite:///{tmp_path / 'catalogue.db'}"
    engine = sa.create_engine(url)
    with engine.begin() as c:
        command.upgrade(_config(c), "0002")
        for i, name in enumerate(("Grind-1", "grind-1")):
            c.execute(
                sa.text(
                    "INSERT INTO items (id, kind, name, metadata, state, read_only, "
                    "created_at, updated_at) VALUES (:id, 'grind', :n, '{}', 'ready', 0, "
                    "'2026-01-01', '2026-01-01')"
                ),
                {"id": f"{i:032x}", "n": name},
            )
    engine.dispose()
    with caplog.at_level("WARNING"):
        db = CatalogueDB(url)
    assert "grinds Grind-1, grind-1" in caplog.text
    try:
        assert sorted(i.name for i in db.items("grind")) == ["Grind-1", "grind-1"]
        with pytest.raises(NameTakenError, match="regardless of case"):
            db.add_item("grind", "GRIND-1")
        # once one of them is renamed, the next start adds the index
        db.update_item(db.item_by_name("grind", "Grind-1").id, name="grind-1b")
    finally:
        db.close()
    db = CatalogueDB(url)
    try:
        with db.engine.connect() as c:
            indexes = c.exec_driver_sql("SELECT name FROM sqlite_master WHERE type = 'index'")
            assert "uq_items_kind_lower_name" in set(indexes.scalars())
    finally:
        db.close()
