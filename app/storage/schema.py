"""Create or upgrade the catalogue database to the newest schema (Alembic, run in-process).

The revision scripts are package data (``app/storage/migrations/versions``), so a wheel
installed anywhere migrates its own database; there is no ``alembic.ini`` to find.
:func:`upgrade_schema` is called by ``skisnow serve`` once before the workers start and by
every :class:`~app.storage.catalogue.CatalogueDB` (then a no-op read of ``alembic_version``).

Three starting points end at the head revision:

- an empty database: every revision runs;
- a database made before migrations existed (``items`` and ``jobs`` created by
  ``create_all``, no ``alembic_version``): stamped at the baseline revision ``0001`` (which
  describes exactly those tables), never recreated, then upgraded; every row is kept;
- a database at an older revision: the missing revisions run.

A database at a revision this code does not know (made by a newer skisnow) is refused with
:class:`~solvers.errors.DataFileError`.

Processes starting at once (the uvicorn workers of a first ``docker run``, replicas on one
PostgreSQL) are serialised: PostgreSQL by a transaction-scoped advisory lock around the whole
upgrade (its DDL is transactional, so a loser sees the winner's committed tables), SQLite by
``BEGIN EXCLUSIVE`` on the database file (the busy timeout makes the others wait). Other
databases get no lock.
"""

from __future__ import annotations

import logging
from pathlib import Path

import sqlalchemy as sa
from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from skisnow.solvers.errors import DataFileError

__all__ = [
    "BASELINE_REVISION",
    "MIGRATIONS_DIR",
    "current_revision",
    "head_revision",
    "upgrade_schema",
]

log = logging.getLogger(__name__)

MIGRATIONS_DIR = Path(__file__).with_name("migrations")
#: the revision that describes the tables of the pre-migration ``create_all``
BASELINE_REVISION = "0001"
#: the tables of the baseline; a database with all of them and no ``alembic_version`` is stamped
BASELINE_TABLES = frozenset({"items", "jobs"})
#: key of the PostgreSQL advisory lock held while migrating (any constant; "skisnow" in ASCII)
_PG_LOCK_KEY = 0x736B69736E6F77


def _config(connection=None) -> Config:
    cfg = Config()
    cfg.set_main_option("script_location", str(MIGRATIONS_DIR))
    cfg.attributes["connection"] = connection
    return cfg


def _script() -> ScriptDirectory:
    return ScriptDirectory.from_config(_config())


def head_revision() -> str:
    """The newest revision of the shipped scripts."""
    return _script().get_current_head()


def current_revision(connection) -> str | None:
    """The database's revision (None: no ``alembic_version`` or an empty one)."""
    return MigrationContext.configure(connection).get_current_revision()


def _lock(connection) -> None:
    """Hold the migration lock until the connection's transaction ends."""
    name = connection.dialect.name
    if name == "postgresql":
        connection.execute(sa.select(sa.func.pg_advisory_xact_lock(_PG_LOCK_KEY)))
    elif name == "sqlite":
        # pysqlite starts no transaction of its own before DDL; take the write lock explicitly
        # (waits on the busy timeout) and keep it to the commit
        connection.exec_driver_sql("BEGIN EXCLUSIVE")


def upgrade_schema(engine: sa.Engine) -> str:
    """Bring the catalogue database to the head revision; return the head.

    Parameters
    ----------
    engine : sqlalchemy.Engine
        Engine of the catalogue database (SQLite or PostgreSQL).

    Raises
    ------
    DataFileError
        The database is at a revision this code does not know, or has some but not all of the
        baseline tables without an ``alembic_version``.
    """
    script = _script()
    head = script.get_current_head()
    with engine.connect() as conn:  # the usual case: already at head, no lock taken
        if current_revision(conn) == head:
            return head
    with engine.connect() as conn:
        _lock(conn)
        current = current_revision(conn)
        if current == head:  # another process upgraded it while we waited
            conn.commit()
            return head
        if current is not None and current not in {s.revision for s in script.walk_revisions()}:
            raise DataFileError(
                f"the catalogue database ({engine.url.render_as_string(hide_password=True)}) is "
                f"at schema revision {current!r}, which this skisnow does not know (its newest is "
                f"{head!r}); it was upgraded by a newer skisnow: install that version"
            )
        cfg = _config(conn)
        if current is None:
            tables = set(sa.inspect(conn).get_table_names())
            found = tables & BASELINE_TABLES
            if found == BASELINE_TABLES:
                log.info("catalogue made before migrations: stamped at %s", BASELINE_REVISION)
                command.stamp(cfg, BASELINE_REVISION)
                current = BASELINE_REVISION
            elif found:
                raise DataFileError(
                    f"the catalogue database has table(s) {sorted(found)} but not "
                    f"{sorted(BASELINE_TABLES - found)} and no alembic_version: it is not a "
                    "skisnow catalogue, or a partly created one; move it away"
                )
        log.info("catalogue schema: upgrading from %s to %s", current or "empty", head)
        command.upgrade(cfg, "head")
        conn.commit()
    return head
