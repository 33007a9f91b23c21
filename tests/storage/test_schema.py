"""Catalogue schema migrations (Alembic, app/storage/schema.py) on SQLite; test_postgres.py runs
the same checks on PostgreSQL.

A database made by the code before migrations (``create_all`` of the tables below, a frozen copy
of app/storage/catalogue.py at commit bf43247) with rows in it is upgraded to the head revision
and keeps every row; a second upgrade executes nothing; a fresh database and an upgraded one
both match the tables the code uses.
"""

from __future__ import annotations

import datetime as dt

import pytest
import sqlalchemy as sa

#: the catalogue exactly as ``create_all`` made it before migrations (never change this copy)
PRE_ALEMBIC = sa.MetaData()
sa.Table(
    "items",
    PRE_ALEMBIC,
    sa.Column("id", sa.String(32), primary_key=True),
    sa.Column("kind", sa.String(16), nullable=False),
    sa.Column("name", sa.String(64), nullable=False),
    sa.Column("metadata", sa.JSON, nullable=False, default=dict),
    sa.Column("file_path", sa.String(1024)),
    sa.Column("sha256", sa.String(64)),
    sa.Column("state", sa.String(16), nullable=False),
    sa.Column("read_only", sa.Boolean, nullable=False, default=False),
    sa.Column("team", sa.String(64)),
    sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
    sa.UniqueConstraint("kind", "name", name="uq_items_kind_name"),
)
sa.Table(
    "jobs",
    PRE_ALEMBIC,
    sa.Column("id", sa.String(32), primary_key=True),
    sa.Column("kind", sa.String(32), nullable=False),
    sa.Column("item_id", sa.String(32), sa.ForeignKey("items.id", ondelete="CASCADE")),
    sa.Column("state", sa.String(16), nullable=False),
    sa.Column("progress", sa.Float, nullable=False, default=0.0),
    sa.Column("message", sa.Text, nullable=False, default=""),
    sa.Column("error", sa.Text),
    sa.Column("runner", sa.String(128)),
    sa.Column("heartbeat_at", sa.DateTime(timezone=True)),
    sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    sa.Column("updated_at", sa.DateTime(timezone=True), nullable=False),
)

T0 = dt.datetime(2026, 1, 2, 3, 4, 5, tzinfo=dt.UTC)


def _item(i: int, **kw) -> dict:
    return {
        "id": f"{i:032x}",
        "kind": "grind" if i % 2 else "ski",
        "name": f"item-{i}-ä",
        "metadata": {"pixel_size_um": 0.5 * i, "iso25178": {"Sq_m": 1e-6 * i}, "tags": [i]},
        "file_path": f"/data/grinds/{i:032x}.h5" if i % 3 else None,
        "sha256": f"{i:064x}" if i % 3 else None,
        "state": ("pending", "ready", "failed")[i % 3],
        "read_only": i == 1,
        "team": "team-a" if i % 4 == 0 else None,
        "created_at": T0 + dt.timedelta(minutes=i),
        "updated_at": T0 + dt.timedelta(minutes=i, seconds=30),
        **kw,
    }


def _job(i: int, item_id: str | None, state: str) -> dict:
    return {
        "id": f"{1000 + i:032x}",
        "kind": "grind-table" if i % 2 else "ski-network",
        "item_id": item_id,
        "state": state,
        "progress": {"queued": 0.0, "running": 0.375, "done": 1.0, "failed": 0.5}[state],
        "message": f"message {i}",
        "error": "it broke" if state == "failed" else None,
        "runner": f"host:{100 + i}:abcd" if state != "queued" else None,
        "heartbeat_at": T0 + dt.timedelta(hours=1, seconds=i) if state != "queued" else None,
        "created_at": T0 + dt.timedelta(hours=2, seconds=i),
        "updated_at": T0 + dt.timedelta(hours=3, seconds=i),
    }


def make_pre_alembic_catalogue(url: str) -> dict[str, list[dict]]:
    """A catalogue database as the code before migrations left it, with 7 items and 9 jobs
    (every state, a job without item); returns the rows as read back."""
    engine = sa.create_engine(url)
    PRE_ALEMBIC.create_all(engine)
    items = [_item(i) for i in range(1, 8)]
    states = ["queued", "running", "done", "failed"]
    jobs = [_job(i, items[i % 7]["id"], states[i % 4]) for i in range(8)]
    jobs.append(_job(8, None, "done"))
    with engine.begin() as c:
        c.execute(PRE_ALEMBIC.tables["items"].insert(), items)
        c.execute(PRE_ALEMBIC.tables["jobs"].insert(), jobs)
    rows = read_rows(engine)
    engine.dispose()
    assert len(rows["items"]) == 7 and len(rows["jobs"]) == 9
    return rows


def read_rows(engine) -> dict[str, list[dict]]:
    """Every row of the pre-migration columns, sorted by id."""
    out = {}
    with engine.connect() as c:
        for name, table in PRE_ALEMBIC.tables.items():
            cols = [sa.column(col.name, col.type) for col in table.columns]
            q = sa.select(*cols).select_from(sa.table(name)).order_by(sa.column("id"))
            out[name] = [dict(r._mapping) for r in c.execute(q)]
    return out


def schema_diff(engine) -> list:
    """Differences between the database and the tables the code uses (empty: they agree)."""
    from alembic.autogenerate import compare_metadata
    from alembic.runtime.migration import MigrationContext
    from skisnow.app.storage.catalogue import _meta

    with engine.connect() as c:
        return compare_metadata(MigrationContext.configure(c), _meta)


def statements_of(engine, fn) -> list[str]:
    """The SQL statements ``fn()`` executes on ``engine``."""
    seen: list[str] = []

    def record(conn, cursor, statement, *args):
        seen.append(statement)

    sa.event.listen(engine, "before_cursor_execute", record)
    try:
        fn()
    finally:
        sa.event.remove(engine, "before_cursor_execute", record)
    return seen


def check_upgrade_keeps_rows(url: str) -> None:
    """The migration checks shared with tests/storage/test_postgres.py."""
    from skisnow.app.storage.catalogue import CatalogueDB
    from skisnow.app.storage.schema import BASELINE_REVISION, current_revision, head_revision

    before = make_pre_alembic_catalogue(url)
    head = head_revision()
    assert head != BASELINE_REVISION  # there is a revision to run after the stamp

    db = CatalogueDB(url)  # upgrades
    with db.engine.connect() as c:
        assert current_revision(c) == head
    assert read_rows(db.engine) == before  # every row, every value
    assert schema_diff(db.engine) == []
    jobs = {j.id: j for j in db.jobs(limit=100)}
    assert len(jobs) == 9 and {j.attempts for j in jobs.values()} == {0}
    item = db.item(before["items"][2]["id"])
    assert item.metadata == before["items"][2]["metadata"]
    assert item.created_at == T0 + dt.timedelta(minutes=3)

    # a second upgrade (another process starting) reads the revision and writes nothing
    from skisnow.app.storage.schema import upgrade_schema

    sql = statements_of(db.engine, lambda: upgrade_schema(db.engine))
    writes = [s for s in sql if s.split(None, 1)[0].upper() in ("CREATE", "ALTER", "INSERT")]
    assert sql and writes == [], sql
    assert read_rows(db.engine) == before

    # the upgraded catalogue works: a new job is claimed once and counts its attempt
    job = db.add_job("grind-table", item.id)
    assert db.claim_job(job.id, "me", T0) and db.job(job.id).attempts == 1
    db.close()


def check_fresh_database(url: str) -> None:
    from skisnow.app.storage.catalogue import CatalogueDB
    from skisnow.app.storage.schema import current_revision, head_revision

    db = CatalogueDB(url)
    with db.engine.connect() as c:
        assert current_revision(c) == head_revision()
    assert schema_diff(db.engine) == []
    db.close()


# --------------------------------------------------------------------------------- SQLite


def test_pre_alembic_sqlite_catalogue_is_stamped_upgraded_and_keeps_every_row(tmp_path):
    check_upgrade_keeps_rows(f"sqlite:///{tmp_path / 'catalogue.db'}")


def test_fresh_sqlite_catalogue_is_created_at_head(tmp_path):
    check_fresh_database(f"sqlite:///{tmp_path / 'catalogue.db'}")


def test_sqlite_catalogue_at_an_old_revision_is_upgraded(tmp_path):
    from alembic import command
    from skisnow.app.storage.catalogue import CatalogueDB
    from skisnow.app.storage.schema import _config, current_revision, head_revision

    url = f"sqlite:///{tmp_path / 'catalogue.db'}"
    engine = sa.create_engine(url)
    with engine.begin() as c:
        command.upgrade(_config(c), "0001")
        assert current_revision(c) == "0001"
    engine.dispose()
    db = CatalogueDB(url)
    with db.engine.connect() as c:
        assert current_revision(c) == head_revision()
    db.close()


def test_a_catalogue_from_a_newer_skisnow_is_refused(tmp_path):
    from skisnow.app.storage.catalogue import CatalogueDB
    from skisnow.solvers.errors import DataFileError

    url = f"sqlite:///{tmp_path / 'catalogue.db'}"
    CatalogueDB(url).close()
    engine = sa.create_engine(url)
    with engine.begin() as c:
        c.execute(sa.text("UPDATE alembic_version SET version_num = 'f00dcafe'"))
    engine.dispose()
    with pytest.raises(DataFileError, match=r"f00dcafe.*newer skisnow"):
        CatalogueDB(url)


def test_a_database_with_part_of_the_tables_is_refused(tmp_path):
    from skisnow.app.storage.catalogue import CatalogueDB
    from skisnow.solvers.errors import DataFileError

    url = f"sqlite:///{tmp_path / 'catalogue.db'}"
    engine = sa.create_engine(url)
    PRE_ALEMBIC.tables["items"].create(engine)
    engine.dispose()
    with pytest.raises(DataFileError, match=r"\['items'\] but not \['jobs'\]"):
        CatalogueDB(url)


def test_the_migration_scripts_are_package_data():
    """The wheel ships the scripts (pyproject package data) and nothing reads an alembic.ini
    from the working directory."""
    import tomllib
    from pathlib import Path

    from skisnow.app.storage.schema import MIGRATIONS_DIR

    repo = Path(__file__).resolve().parents[2]
    config = tomllib.loads((repo / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert "skisnow.app.storage.migrations.versions" in config["packages"]
    assert "script.py.mako" in config["package-data"]["skisnow.app.storage.migrations"]
    assert sorted(p.name for p in (MIGRATIONS_DIR / "versions").glob("0*.py")) == [
        "0001_baseline.py",
        "0002_job_attempts.py",
        "0003_names_nocase.py",
    ]
