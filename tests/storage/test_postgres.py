"""The catalogue and the jobs on a real PostgreSQL (issue #15 point 1), started here.

A throwaway cluster (``initdb`` + ``pg_ctl``, PostgreSQL 15 on the machine image) on a loopback
port in a temp folder; as root it runs as the ``postgres`` user (PostgreSQL refuses root). The
module is skipped, with the reason, only where no ``initdb`` is installed.

Covered: items and names, job claims, schema creation and upgrade races, the Alembic upgrade of
a pre-migration catalogue with rows in it (tests/storage/test_schema.py has the checks), upload →
job →
contact in-process, and two ``skisnow serve`` subprocesses on one database (about 35 s).
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
    from skisnow.app.storage.catalogue import CatalogueDB, NameTakenError

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
    """The job quota's and the team filter's queries (tests/api/test_safe_defaults.py) on
    PostgreSQL, in a database of their own."""
    import psycopg
    from skisnow.app.storage.catalogue import CatalogueDB
    from test_safe_defaults import check_team_queries

    server = pg_url.rsplit("/", 1)[0]
    with psycopg.connect(server.replace("postgresql+psycopg", "postgresql") + "/postgres") as c:
        c.autocommit = True
        c.execute("CREATE DATABASE skisnow_teams")
    db = CatalogueDB(server + "/skisnow_teams")
    check_team_queries(db)
    db.close()


def test_names_are_unique_regardless_of_case_on_postgres(pg_url):
    """``Grind-1`` beside ``grind-1``: refused by the check in the insert's transaction and
    by the unique index on lower(name) (tests/api/test_token_mode.py, the same on SQLite)."""
    from test_token_mode import check_catalogue_names_nocase

    check_catalogue_names_nocase(new_database(pg_url, "names_nocase"))


def test_a_job_is_claimed_exactly_once_by_competing_processes(pg_url):
    """Two service processes (two connections) race for every queued job: each job has one
    winner."""
    from skisnow.app.storage.catalogue import CatalogueDB

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
    from skisnow.app.storage.catalogue import CatalogueDB

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
    from skisnow.app.storage.schema import current_revision, head_revision
    from test_catalogue_race import _open
    from test_schema import make_pre_alembic_catalogue, read_rows

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


# ------------------------------------------------------------ two `skisnow serve` replicas

#: settings of both replicas (SKISNOW_*): small tables, quick polls, a short job lease
REPLICA_ENV = {
    "SKISNOW_WARM_UP": "false",
    "SKISNOW_TABLE_POINTS": "8",
    "SKISNOW_TABLE_CHUNK_SIZE": "1",
    "SKISNOW_TABLE_PROCESSES": "false",
    "SKISNOW_JOB_WORKERS": "1",
    "SKISNOW_JOB_POLL_S": "0.1",
    "SKISNOW_JOB_STALE_S": "3",
    "SKISNOW_MAX_UPLOAD_BYTES": "1000000",
    # 20 uploads at once: above the default job quotas (tests/api/test_safe_defaults.py)
    "SKISNOW_MAX_JOBS_PER_TEAM": "32",
    "SKISNOW_MAX_QUEUED_JOBS": "32",
    "OMP_NUM_THREADS": "1",
}
REPO = Path(__file__).resolve().parents[2]


def _start_replica(url: str, data_dir: Path, log: Path) -> tuple[subprocess.Popen, str]:
    import sys

    port = _free_port()
    env = {
        **os.environ,
        **REPLICA_ENV,
        "SKISNOW_DATABASE_URL": url,
        "SKISNOW_DATA_DIR": str(data_dir),
        "PYTHONPATH": str(REPO),
    }
    # one worker process per replica: the test tells the replicas apart by their pid
    cmd = [sys.executable, "-m", "skisnow.app.cli", "serve", "--port", str(port), "--workers", "1"]
    with open(log, "ab") as out:
        proc = subprocess.Popen(cmd, env=env, cwd=REPO, stdout=out, stderr=subprocess.STDOUT)
    return proc, f"http://127.0.0.1:{port}"


def _wait_ready(proc: subprocess.Popen, base: str, log: Path, timeout_s: float = 60) -> None:
    import time

    import httpx

    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        if proc.poll() is not None:
            raise AssertionError(f"replica exited {proc.returncode}: {log.read_text()[-2000:]}")
        try:
            if httpx.get(f"{base}/readyz", timeout=2).status_code == 200:
                return
        except httpx.TransportError:
            pass
        time.sleep(0.1)
    raise AssertionError(f"replica not ready in {timeout_s} s: {log.read_text()[-2000:]}")


def _upload(base: str, name: str, heights_um, periodic: str) -> str:
    import httpx
    from test_uploads import npy_bytes

    r = httpx.post(
        f"{base}/v1/grinds",
        files={"file": ("g.npy", npy_bytes(heights_um), "application/octet-stream")},
        data={"name": name, "pixel_size_um": "1", "height_unit": "um", "periodic": periodic},
        timeout=30,
    )
    assert r.status_code == 202, r.text
    return r.json()["job"]


def _wait_jobs(db, job_ids, timeout_s: float) -> None:
    import time

    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        jobs = [db.job(j) for j in job_ids]
        if all(j.state in ("done", "failed") for j in jobs):
            return
        time.sleep(0.2)
    raise AssertionError(
        f"jobs not finished in {timeout_s} s: {[(j.state, j.message) for j in jobs]}"
    )


def _wait_listed(base: str, names: set[str], timeout_s: float = 10) -> None:
    """Wait until GET /v1/grinds of ``base`` lists ``names`` (replicas sync every poll)."""
    import time

    import httpx

    t0 = time.monotonic()
    while True:
        listed = {g["name"] for g in httpx.get(f"{base}/v1/grinds").json()["grinds"]}
        if names <= listed:
            return
        assert time.monotonic() - t0 < timeout_s, f"{base} does not list {names - listed}"
        time.sleep(0.1)


def _grind_data_sha256(base: str, data_dir: Path, name: str) -> tuple[str, int]:
    import h5py
    import httpx

    item_id = httpx.get(f"{base}/v1/grinds/{name}", timeout=10).json()["id"]
    with h5py.File(data_dir / "grinds" / f"{item_id}.h5") as f:
        return str(f.attrs["data_sha256"]), int(f.attrs.get("chunks_resumed", 0))


def test_two_replicas_share_jobs_take_over_a_killed_build_and_see_every_item(pg_url, tmp_path):
    """Two ``skisnow serve`` processes on one PostgreSQL and one data directory, as a
    deployment runs them:

    - 20 grind uploads, alternating between the replicas, run each job exactly once (the
      database counts the claims of every job: ``attempts``) and both replicas run some;
    - ``kill -9`` of the replica building a table: the other one takes the job over once its
      lease (``SKISNOW_JOB_STALE_S``) has expired, resumes from the killed one's checkpoints
      and builds the same table (data sha256) as an undisturbed build of the same upload;
    - both replicas list every finished grind (the survivor also the one it took over).
    """
    import signal
    import time

    from skisnow.app.storage.catalogue import CatalogueDB
    from test_uploads import heights_um

    url = new_database(pg_url, "replicas")
    data_dir = tmp_path / "data"
    CatalogueDB(url).close()  # as `skisnow serve` would; done once here so the replicas race less
    logs = [tmp_path / "a.log", tmp_path / "b.log"]
    t_start = time.monotonic()
    replicas = [_start_replica(url, data_dir, log) for log in logs]
    db = CatalogueDB(url)
    try:
        for (proc, base), log in zip(replicas, logs, strict=True):
            _wait_ready(proc, base, log)
        t_start = time.monotonic() - t_start
        bases = [base for _, base in replicas]
        pids = {proc.pid for proc, _ in replicas}

        # 20 uploads spread over both: 19 tiny maps and the reference of the kill test
        tiny = heights_um(16, seed=7)
        big = heights_um(256, seed=8)  # mirrored to 512²: ~3 s of chunks after the first
        t0 = time.monotonic()
        jobs = {f"g{i:02d}": _upload(bases[i % 2], f"g{i:02d}", tiny, "none") for i in range(19)}
        jobs["reference"] = _upload(bases[1], "reference", big, "mirror")
        _wait_jobs(db, jobs.values(), timeout_s=120)
        t_uploads = time.monotonic() - t0
        rows = [db.job(j) for j in jobs.values()]
        assert [r.state for r in rows] == ["done"] * 20, [(r.state, r.error) for r in rows]
        assert [r.attempts for r in rows] == [1] * 20  # each job ran exactly once
        ran_by = {int(r.runner.split(":")[1]) for r in rows}
        assert ran_by == pids, (ran_by, pids)  # both replicas took jobs
        for base in bases:  # each lists the grinds both built
            _wait_listed(base, set(jobs))

        # kill -9 the replica building a table, mid-build
        t1 = time.monotonic()
        job_id = _upload(bases[0], "killed", big, "mirror")
        while True:
            job = db.job(job_id)
            assert job.state in ("queued", "running"), job
            if job.state == "running" and job.progress > 0:
                break  # a chunk is checkpointed
            assert time.monotonic() - t1 < 60, job
            time.sleep(0.05)
        victim_pid, victim_progress = int(job.runner.split(":")[1]), job.progress
        assert victim_pid in pids
        os.kill(victim_pid, signal.SIGKILL)
        victim = next(i for i, (p, _) in enumerate(replicas) if p.pid == victim_pid)
        replicas[victim][0].wait(timeout=10)
        survivor = replicas[1 - victim][1]
        _wait_jobs(db, [job_id], timeout_s=120)
        t_takeover = time.monotonic() - t1
        job = db.job(job_id)
        assert job.state == "done", job
        assert job.attempts == 2  # the killed run and the takeover
        assert int(job.runner.split(":")[1]) == replicas[1 - victim][0].pid
        killed_sha, resumed = _grind_data_sha256(survivor, data_dir, "killed")
        reference_sha, _ = _grind_data_sha256(survivor, data_dir, "reference")
        assert resumed >= 1  # the survivor used the killed replica's checkpoints
        assert killed_sha == reference_sha

        _wait_listed(survivor, {*jobs, "killed"})
        print(
            f"2 replicas up in {t_start:.1f} s; 20 uploads: {t_uploads:.1f} s; kill and takeover: "
            f"{t_takeover:.1f} s (lease {REPLICA_ENV['SKISNOW_JOB_STALE_S']} s, "
            f"killed at {victim_progress:.2f}, {resumed} chunks resumed)"
        )
    finally:
        db.close()
        for proc, _ in replicas:
            if proc.poll() is None:
                proc.terminate()
        for proc, _ in replicas:
            try:
                proc.wait(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(timeout=10)
