"""Hardening (issue #27, part A): who may reach the service (the Host allow-list against DNS
rebinding, the Origin's scheme), and job quotas that hold under concurrent uploads, checked
against a real ``skisnow serve`` process (tests/serve_process.py) on SQLite and PostgreSQL."""

from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor

import httpx
import pytest
import test_postgres
from serve_process import serving
from skisnow.app.api.access import allowed_hosts, cross_origin_reason, host_refusal
from skisnow.app.settings import Settings
from test_postgres import new_database
from test_uploads import heights_um, is_problem, make_client, npy_bytes, post_grind

#: the PostgreSQL cluster of tests/storage/test_postgres.py (started once for this module)
pg_url = test_postgres.pg_url

# ------------------------------------------------------------------------- Host check


@pytest.mark.parametrize(
    ("host", "passes"),
    [
        ("127.0.0.1:8000", True),
        ("127.3.4.5", True),  # all of 127.0.0.0/8 is loopback
        ("localhost:8000", True),
        ("LOCALHOST.:8000", True),
        ("app.localhost:8000", True),  # RFC 6761
        ("[::1]:8000", True),
        ("skis.example", True),  # SKISNOW_ALLOWED_HOSTS below
        ("skis.example:8443", True),
        ("proxy.example", True),  # host of a trusted origin
        ("10.0.0.5:8000", True),  # the listening host
        (None, True),  # no Host: not a browser
        ("evil.example:8000", False),
        ("evil.example", False),
        ("localhost.evil.example", False),
        ("127.0.0.1.evil.example", False),
        ("10.0.0.6:8000", False),
        ("testserver", False),  # only Starlette's in-process test client may name it
        ("127.0.0.1:x", False),  # malformed
        ("", False),
    ],
)
def test_host_allow_list(host, passes):
    settings = Settings(
        host="10.0.0.5",
        allowed_hosts=["skis.example"],
        trusted_origins=["https://proxy.example"],
        _env_file=None,
    )
    allowed = allowed_hosts(settings)
    reason = host_refusal(host, allowed, client=("192.0.2.7", 5555))
    assert (reason is None) == passes, reason
    if not passes:
        assert "SKISNOW_ALLOWED_HOSTS" in reason and repr(host) in reason


def test_wildcard_listening_host_allows_no_name_and_star_allows_any():
    allowed = allowed_hosts(Settings(host="0.0.0.0", _env_file=None))
    assert "0.0.0.0" not in allowed
    assert host_refusal("0.0.0.0:8000", allowed) is not None
    assert host_refusal("evil.example", frozenset({"*"})) is None


def test_other_hosts_are_refused_in_process_and_the_test_client_passes(catalogue, tmp_path):
    """In process: the test client's own host passes, another Host gets 421 on every route
    (not on the probes), before the write guard and before routing."""
    with make_client(catalogue, tmp_path) as client:
        assert client.get("/v1/jobs").status_code == 200
        evil = {"host": "evil.example:8000", "origin": "http://evil.example:8000"}
        is_problem(client.get("/v1/jobs", headers=evil), 421)
        is_problem(client.get("/no/such/route", headers=evil), 421)
        is_problem(post_grind(client, name="rebound", headers=evil), 421)
        is_problem(client.delete("/v1/grinds/tiny-grind", headers=evil), 421)
        assert client.get("/healthz", headers=evil).status_code == 200
        assert "tiny-grind" in client.get("/v1/grinds").text  # nothing was deleted


@pytest.mark.parametrize(
    ("origin", "scheme", "passes"),
    [
        ("http://127.0.0.1:8000", "http", True),
        ("https://127.0.0.1:8000", "http", False),  # same host and port, other scheme
        ("http://skis.example:443", "https", False),
        ("https://skis.example:443", "https", True),
        ("https://127.0.0.1:8000", None, True),  # scheme unknown: not compared
    ],
)
def test_same_origin_check_compares_the_scheme(origin, scheme, passes):
    host = "skis.example:443" if "skis" in origin else "127.0.0.1:8000"
    reason = cross_origin_reason({"host": host, "origin": origin}, scheme=scheme)
    assert (reason is None) == passes, reason


def test_an_https_origin_is_refused_on_plain_http(catalogue, tmp_path):
    with make_client(catalogue, tmp_path) as client:
        body = is_problem(
            post_grind(client, name="other-scheme", headers={"origin": "https://testserver"}),
            403,
        )
        assert "http://testserver" in body["detail"]


def test_dns_rebinding_is_refused_by_a_real_service(tmp_path):
    """The attack of issue #27 point 1 against ``skisnow serve``: a page on ``evil.example``
    re-pointed at 127.0.0.1 sends Host and Origin of its own name. Upload, delete and the job
    list were 202, 204 and 200; now 421. The service's own names and a configured one pass."""
    env = {
        "SKISNOW_ALLOWED_HOSTS": '["skis.example"]',
        "SKISNOW_JOB_WORKERS": "0",
        "SKISNOW_MAX_UPLOAD_BYTES": "200000",
    }
    with serving(tmp_path, env) as base:
        port = base.rsplit(":", 1)[1]
        evil = {"host": f"evil.example:{port}", "origin": f"http://evil.example:{port}"}
        files = {"file": ("g.npy", npy_bytes(heights_um()), "application/octet-stream")}
        data = {"name": "rebound", "pixel_size_um": "1", "height_unit": "um"}
        with httpx.Client(base_url=base, timeout=60) as c:
            is_problem(c.post("/v1/grinds", files=files, data=data, headers=evil), 421)
            is_problem(c.delete("/v1/grinds/grind-1", headers=evil), 421)
            is_problem(c.get("/v1/jobs", headers=evil), 421)
            is_problem(c.get("/", headers=evil), 421)
            assert c.get("/healthz", headers=evil).status_code == 200
            assert c.get("/v1/jobs").status_code == 200
            assert c.get("/v1/jobs", headers={"host": f"localhost:{port}"}).status_code == 200
            assert c.get("/v1/jobs", headers={"host": "skis.example"}).status_code == 200
            assert c.get("/v1/grinds/grind-1").status_code == 200  # not deleted
            # and through uvicorn, an oversized chunked upload is 413 (issue #27 point 5)
            headers, body = _chunked_upload(300_000)
            is_problem(c.post("/v1/grinds", content=body, headers=headers), 413)


# ---------------------------------------------------------------------------- quotas

#: the quotas of the concurrency tests: per team and in all (``skisnow serve`` settings)
PER_TEAM, TOTAL = 4, 16
TEAMS = {f"token-{t}": f"team-{t}" for t in "abcde"}


def _upload_all(base: str, uploads: list[tuple[str, str | None]]) -> list[int]:
    """Send every ``(name, token)`` grind upload at once (one thread each); their statuses."""
    content = npy_bytes(heights_um())

    def one(upload):
        name, token = upload
        headers = {"authorization": f"Bearer {token}"} if token else {}
        files = {"file": ("g.npy", content, "application/octet-stream")}
        data = {"name": name, "pixel_size_um": "1", "height_unit": "um"}
        r = httpx.post(f"{base}/v1/grinds", files=files, data=data, headers=headers, timeout=120)
        if r.status_code not in (202, 429):
            raise AssertionError(f"{r.status_code}: {r.text[:500]}")
        if r.status_code == 429:
            assert r.headers["content-type"].startswith("application/problem+json")
        return r.status_code

    with ThreadPoolExecutor(len(uploads)) as pool:
        return list(pool.map(one, uploads))


def _quota_run(tmp_path, database_urls=(None, None)) -> None:
    """Without tokens: 20 parallel uploads against max_jobs_per_team = 4 are 4 accepted and
    16 refused (all 20 were accepted). With tokens: 20 parallel uploads of one team, then 20
    of four other teams (5 each): 4 of the first, and 12 more in all (max_queued_jobs = 16),
    none over 4 per team. No job runs (SKISNOW_JOB_WORKERS=0), so every accepted job stays
    queued. ``database_urls``: the catalogues of the two runs (None: SQLite)."""
    env = {
        "SKISNOW_JOB_WORKERS": "0",
        "SKISNOW_MAX_JOBS_PER_TEAM": str(PER_TEAM),
        "SKISNOW_MAX_QUEUED_JOBS": str(TOTAL),
    }
    if database_urls[0]:
        env["SKISNOW_DATABASE_URL"] = database_urls[0]
    (tmp_path / "open").mkdir()
    with serving(tmp_path / "open", env) as base:
        statuses = _upload_all(base, [(f"open-{i}", None) for i in range(20)])
        assert statuses.count(202) == PER_TEAM, statuses
        jobs = httpx.get(f"{base}/v1/jobs", timeout=30).json()["jobs"]
        assert sum(j["state"] == "queued" for j in jobs) == PER_TEAM
    (tmp_path / "teams").mkdir()
    if database_urls[1]:  # a fresh catalogue: the first run's jobs are still queued there
        env["SKISNOW_DATABASE_URL"] = database_urls[1]
    env["SKISNOW_TEAM_TOKENS"] = json.dumps(TEAMS)
    with serving(tmp_path / "teams", env) as base:
        first = _upload_all(base, [(f"a-{i}", "token-a") for i in range(20)])
        assert first.count(202) == PER_TEAM, first
        others = [(f"{t}-{i}", f"token-{t}") for t in "bcde" for i in range(5)]
        second = _upload_all(base, others)
        assert second.count(202) == TOTAL - PER_TEAM, second
        for t in "bcde":
            mine = [s for (name, _), s in zip(others, second, strict=True) if name[0] == t]
            assert mine.count(202) <= PER_TEAM, (t, mine)


def test_job_quotas_hold_under_concurrent_uploads_on_sqlite(tmp_path):
    _quota_run(tmp_path)


@pytest.mark.postgres
def test_job_quotas_hold_under_concurrent_uploads_on_postgresql(tmp_path, pg_url):
    _quota_run(tmp_path, (new_database(pg_url, "quotas"), new_database(pg_url, "team_quotas")))


# ------------------------------------------------------------------------ body limits


def _chunked_upload(size: int, chunk: int = 64 * 1024):
    """Headers and a generator (sent as ``Transfer-Encoding: chunked``, no Content-Length) of
    a multipart grind upload whose file part is ``size`` bytes."""
    boundary = "skisnowboundary"
    head = (
        f'--{boundary}\r\nContent-Disposition: form-data; name="name"\r\n\r\nbig\r\n'
        f'--{boundary}\r\nContent-Disposition: form-data; name="file"; filename="g.npy"\r\n'
        "Content-Type: application/octet-stream\r\n\r\n"
    ).encode()
    tail = f"\r\n--{boundary}--\r\n".encode()

    def body():
        yield head
        left = size
        while left > 0:
            n = min(chunk, left)
            yield b"0" * n
            left -= n
        yield tail

    return {"content-type": f"multipart/form-data; boundary={boundary}"}, body()


def test_an_oversized_chunked_upload_is_413(catalogue, tmp_path):
    """A chunked body over ``max_upload_bytes`` is 413 like a declared one (it was 400
    "There was an error parsing the body"); one under it reaches the upload's checks."""
    with make_client(catalogue, tmp_path, max_upload_bytes=200_000) as client:
        headers, body = _chunked_upload(300_000)
        r = client.post("/v1/grinds", content=body, headers=headers)
        assert "content-length" not in r.request.headers
        assert "200000 bytes" in is_problem(r, 413)["detail"]
        headers, body = _chunked_upload(2_000)
        assert client.post("/v1/grinds", content=body, headers=headers).status_code in (415, 422)


# ------------------------------------------------------------- long checks, bounded


def _camber_csv(cases: int, rows_per_case: int) -> bytes:
    """A large camber CSV of well-formed rows (``cases`` load cases); its content is not a
    ski's (the checks after the reading refuse it), only its size matters here."""
    lines = ["ski_id,side,load_kg,load_position_mm,position_mm,gap_mm"]
    for c in range(cases):
        load, position = 5 + c % 60, -300 + (c // 60) * 4
        lines += [
            f"big,mean,{load},{position},{-970 + 5 * i},{6.7746 - 0.001 * i:.4f}"
            for i in range(rows_per_case)
        ]
    return ("\n".join(lines) + "\n").encode()


def test_a_long_camber_check_lets_the_event_loop_run(tmp_path):
    """While a thread reads a large camber CSV (as an upload's check does, in the service's
    thread pool), another thread (the event loop's, which answers ``/healthz``) gets the
    interpreter at once whenever it wants it: the reader hands it over every 32 rows. Before,
    the waiting thread waited out the interpreter's switch interval (5 ms) at every step, and
    ``/healthz`` took 1.2 s during a 46 s check (issue #27 point 3). Measured: a 0.5 ms sleep
    overshot by 0.73–1.6 ms on the median before, 0.10–0.13 ms after (loaded 2-core machine)."""
    import statistics
    import threading
    import time

    from skisnow.app.storage.skis import read_camber_csv

    path = tmp_path / "big.csv"
    path.write_bytes(_camber_csv(300, 300))  # 90 000 rows, about 2 s
    done = threading.Event()
    errors = []

    def read():
        try:
            read_camber_csv(path)
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)
        finally:
            done.set()

    reader = threading.Thread(target=read)
    reader.start()
    overshoot_s = []
    while not done.is_set():
        t0 = time.perf_counter()
        time.sleep(0.0005)
        overshoot_s.append(time.perf_counter() - t0 - 0.0005)
    reader.join()
    assert not errors, errors
    assert len(overshoot_s) > 50
    assert statistics.median(overshoot_s) < 0.5e-3, statistics.median(overshoot_s)


def test_an_upload_check_longer_than_max_check_s_is_refused(catalogue, tmp_path):
    """An upload whose check runs past ``max_check_s`` is refused with 422 naming the setting,
    and leaves nothing behind (a 790 000-case CSV was checked for 46 s)."""
    from test_uploads import post_ski

    with make_client(catalogue, tmp_path, max_check_s=0.05, max_upload_bytes=8_000_000) as c:
        r = post_ski(c, _camber_csv(300, 200), name="slow-check")
        body = is_problem(r, 422)
        assert "max_check_s" in body["detail"] and "0.05 s" in body["detail"], body
        assert c.get("/v1/skis/slow-check").status_code == 404
        assert c.get("/v1/jobs").json()["jobs"] == []


def test_a_check_stuck_outside_its_checkpoints_is_refused_in_time(catalogue, tmp_path, monkeypatch):
    """A step of a check that never reaches a checkpoint (a format reader in compiled code;
    here a reader that sleeps 4 s) is still answered at ``max_check_s`` + 1 s: the check runs
    in a thread of its own and the route stops waiting (app/storage/deadline.py)."""
    import time

    from skisnow.app.jobs import uploads

    real = uploads.read_grind_upload

    def stuck(*args, **kwargs):
        time.sleep(4.0)
        return real(*args, **kwargs)

    monkeypatch.setattr(uploads, "read_grind_upload", stuck)
    with make_client(catalogue, tmp_path, max_check_s=0.2) as client:
        t0 = time.perf_counter()
        body = is_problem(post_grind(client, name="stuck"), 422)
        waited_s = time.perf_counter() - t0
        assert "max_check_s" in body["detail"] and "'g.npy'" in body["detail"], body
        assert waited_s < 3.0, waited_s
        assert client.get("/v1/grinds/stuck").status_code == 404
