"""The catalogue and the jobs on a real PostgreSQL (issue #15 point 1), started here.

A throwaway cluster (``initdb`` + ``pg_ctl``, PostgreSQL 15 on the machine image) on a loopback
port in a temp folder; as root it runs as the ``postgres`` user (PostgreSQL refuses root). The
module is skipped, with the reason, only where no ``initdb`` is installed.
"""

from __future__ import annotations

import datetime as dt
import os
import shutil
import socket
import subprocess
import tempfile
import threading
from pathlib import Path

import pytest

pytestmark = pytest.mark.postgres

INITDB = shutil.which("initdb")
PG_CTL = shutil.which("pg_ctl")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _as_postgres(cmd: list[str]) -> list[str]:
    """Run ``cmd`` as the ``postgres`` user when we are root (initdb refuses root)."""
    if os.geteuid() != 0:
        return cmd
    return ["runuser", "-u", "postgres", "--", *cmd]


@pytest.fixture(scope="module")
def pg_url():
    if not (INITDB and PG_CTL):
        pytest.skip("PostgreSQL (initdb, pg_ctl) is not installed")
    pytest.importorskip("psycopg")
    root = Path(tempfile.mkdtemp(prefix="skisnow-pg-"))
    data, sock = root / "data", root / "sock"
    sock.mkdir()
    if os.geteuid() == 0:
        shutil.chown(root, "postgres")
        shutil.chown(sock, "postgres")
    port = _free_port()
    run = dict(check=True, capture_output=True, text=True, timeout=120)
    try:
        subprocess.run(
            _as_postgres([INITDB, "-D", str(data), "-A", "trust", "-U", "postgres", "-E", "UTF8"]),
            **run,
        )
        opts = f"-p {port} -k {sock} -h 127.0.0.1 -c fsync=off"
        subprocess.run(
            _as_postgres(
                [PG_CTL, "-D", str(data), "-o", opts, "-l", str(root / "log"), "-w", "start"]
            ),
            **run,
        )
    except subprocess.CalledProcessError as exc:
        shutil.rmtree(root, ignore_errors=True)
        pytest.fail(f"could not start PostgreSQL: {exc.stderr or exc.stdout}")
    import psycopg

    with psycopg.connect(f"host=127.0.0.1 port={port} user=postgres dbname=postgres") as c:
        c.autocommit = True
        c.execute("CREATE DATABASE skisnow")
    try:
        yield f"postgresql+psycopg://postgres@127.0.0.1:{port}/skisnow"
    finally:
        subprocess.run(
            _as_postgres([PG_CTL, "-D", str(data), "-m", "immediate", "stop"]),
            capture_output=True,
            timeout=60,
        )
        shutil.rmtree(root, ignore_errors=True)


def new_database(pg_url: str, name: str) -> str:
    """URL of a new empty database ``name`` on the test cluster."""
    import psycopg

    port = pg_url.split("@", 1)[1].split("/", 1)[0].split(":")[1]
    with psycopg.connect(f"host=127.0.0.1 port={port} user=postgres dbname=postgres") as c:
        c.autocommit = True
        c.execute(f"CREATE DATABASE {name}")
    return pg_url.rsplit("/", 1)[0] + "/" + name


def test_catalogue_items_and_names(pg_url):
    from app.storage.catalogue import CatalogueDB, NameTakenError

    db = CatalogueDB(pg_url)
    item = db.add_item("grind", "pg-grind", metadata={"pixel_size_um": 1.0})
    assert db.item_by_name("grind", "pg-grind").id == item.id
    assert db.item(item.id).metadata == {"pixel_size_um": 1.0}
    with pytest.raises(NameTakenError):
        db.add_item("grind", "pg-grind")
    db.update_item(item.id, name="pg-grind-2")
    assert db.item_by_name("grind", "pg-grind") is None
    assert db.item_by_name("grind", "pg-grind-2").id == item.id
    db.delete_item(item.id)
    assert db.item(item.id) is None
    db.close()


def test_team_queries(pg_url, tmp_path):
    """The job quota's and the team filter's queries (tests/test_safe_defaults.py) on
    PostgreSQL, in a database of their own."""
    import psycopg
    from test_safe_defaults import check_team_queries

    from app.storage.catalogue import CatalogueDB

    server = pg_url.rsplit("/", 1)[0]
    with psycopg.connect(server.replace("postgresql+psycopg", "postgresql") + "/postgres") as c:
        c.autocommit = True
        c.execute("CREATE DATABASE skisnow_teams")
    db = CatalogueDB(server + "/skisnow_teams")
    check_team_queries(db)
    db.close()


def test_a_job_is_claimed_exactly_once_by_competing_processes(pg_url):
    """Two service processes (two connections) race for every queued job: each job has one
    winner."""
    from app.storage.catalogue import CatalogueDB

    a, b = CatalogueDB(pg_url), CatalogueDB(pg_url)
    jobs = [a.add_job("grind-table", None) for _ in range(20)]
    stale = dt.datetime.now(dt.UTC) - dt.timedelta(minutes=5)
    wins: dict[str, list[str]] = {"a": [], "b": []}

    def claim(db, who):
        for j in jobs:
            if db.claim_job(j.id, who, stale):
                wins[who].append(j.id)

    threads = [threading.Thread(target=claim, args=(db, w)) for db, w in ((a, "a"), (b, "b"))]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert sorted(wins["a"] + wins["b"]) == sorted(j.id for j in jobs)
    assert not set(wins["a"]) & set(wins["b"])
    for j in jobs:
        assert a.job(j.id).state == "running"
        # done: 20 jobs left running would fill the job quota of the next test's uploads
        a.update_job(j.id, state="done")
    a.close()
    b.close()


def test_schema_creation_races_are_harmless(pg_url):
    """Several processes opening an empty database at once (the first start of a deployment)."""
    from app.storage.catalogue import CatalogueDB

    pg_url = new_database(pg_url, "empty_race")

    dbs = []
    errors = []

    def open_db():
        try:
            dbs.append(CatalogueDB(pg_url))
        except Exception as exc:  # reported below
            errors.append(exc)

    threads = [threading.Thread(target=open_db) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert not errors, errors
    for db in dbs:
        db.close()


def test_schema_upgrade_races_between_processes_are_harmless(pg_url):
    """Six forked processes upgrade one pre-migration catalogue at once: all come up, the rows
    are kept, the revision is the head (the advisory lock serialises them)."""
    import multiprocessing as mp

    import sqlalchemy as sa
    from test_catalogue_race import _open
    from test_schema import make_pre_alembic_catalogue, read_rows

    from app.storage.schema import current_revision, head_revision

    url = new_database(pg_url, "upgrade_race")
    before = make_pre_alembic_catalogue(url)
    ctx = mp.get_context("fork")
    barrier, queue = ctx.Barrier(6), ctx.Queue()
    procs = [ctx.Process(target=_open, args=(url, barrier, queue)) for _ in range(6)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(timeout=60)
    assert [queue.get(timeout=10) for _ in procs] == ["ok"] * 6
    engine = sa.create_engine(url)
    with engine.connect() as c:
        assert current_revision(c) == head_revision()
    assert read_rows(engine) == before
    engine.dispose()


def test_pre_alembic_catalogue_is_upgraded_and_keeps_every_row_on_postgres(pg_url):
    from test_schema import check_upgrade_keeps_rows

    check_upgrade_keeps_rows(new_database(pg_url, "pre_alembic"))


def test_fresh_catalogue_is_created_at_head_on_postgres(pg_url):
    from test_schema import check_fresh_database

    check_fresh_database(new_database(pg_url, "fresh"))


def test_upload_job_and_contact_on_postgres(pg_url, catalogue, tmp_path):
    """A grind uploaded to a service whose catalogue is PostgreSQL: the job builds its table,
    the grind answers /v1/contact, and a second service process on the same database sees it."""
    from test_uploads import CONTACT, make_client, post_grind, wait_job

    with make_client(catalogue, tmp_path / "a", database_url=pg_url) as one:
        r = post_grind(one, name="pg-upload")
        assert r.status_code == 202, r.text
        job = wait_job(one, r.json()["job"])
        assert job["state"] == "done", job
        answer = one.post("/v1/contact", json={"ski": "ski-a", "grind": "pg-upload", **CONTACT})
        assert answer.status_code == 200, answer.text
        with make_client(catalogue, tmp_path / "a", database_url=pg_url) as two:
            names = [g["name"] for g in two.get("/v1/grinds").json()["grinds"]]
            assert "pg-upload" in names
