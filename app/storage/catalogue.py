"""The persistent catalogue: items (skis, grinds) and background jobs in a SQL database.

SQLAlchemy 2 Core over any URL it knows; SQLite (one file under the data directory) by default,
PostgreSQL for several replicas sharing one catalogue (tests/storage/test_postgres.py). The database
holds the records; the data themselves are the self-describing HDF5 files it points to. The
schema is made and upgraded by the Alembic revisions of :mod:`app.storage.schema`; the tables
below mirror the head revision (a test compares them).

Tables
------
``items``
    ``id`` (hex uuid), ``kind`` (``ski`` | ``grind``), ``name`` (unique per kind regardless
    of case: a unique index on ``lower(name)``, and a check inside every insert and rename),
    ``metadata`` (JSON: the upload's technician fields and derived figures), ``file_path``
    (the ready HDF5 file; NULL until the item's job is done), ``sha256`` of that file,
    ``state`` (``pending`` | ``ready`` | ``failed``), ``read_only`` (shipped demo items),
    ``team`` (owner team or NULL), ``created_at``, ``updated_at`` (UTC).
``jobs``
    ``id`` (hex uuid), ``kind`` (``grind-table`` | ``ski-network``), ``item_id``, ``state``
    (``queued`` | ``running`` | ``done`` | ``failed``), ``progress`` (0..1), ``message``,
    ``error``, ``runner`` (``host:pid:nonce`` of the runner holding it), ``heartbeat_at``,
    ``attempts`` (times claimed: 1 for a job run once, 2 after a takeover), ``created_at``,
    ``updated_at``.

A job is claimed with one conditional ``UPDATE`` (``WHERE state = 'queued'`` or a heartbeat
older than the lease), so two processes never run the same job at once; the runner renews its
lease by beating ``heartbeat_at``, and writes about a job only while ``runner`` is still its own
(``owner=``), so a runner whose lease was taken over cannot finish or fail the job.
"""

from __future__ import annotations

import datetime as _dt
import logging
import sqlite3
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

import sqlalchemy as sa
from skisnow.solvers.errors import InputError

from .schema import upgrade_schema

log = logging.getLogger(__name__)

__all__ = ["ITEM_KINDS", "JOB_STATES", "CatalogueDB", "ItemRow", "JobRow", "NameTakenError"]

ITEM_KINDS = ("ski", "grind")
ITEM_STATES = ("pending", "ready", "failed")
JOB_STATES = ("queued", "running", "done", "failed")
#: PostgreSQL advisory lock key of the job-quota check (:meth:`CatalogueDB.add_item_with_job`)
QUOTA_LOCK_KEY = 0x736B69736E6F77  # "skisnow"

_meta = sa.MetaData()

ITEMS = sa.Table(
    "items",
    _meta,
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
#: names are unique regardless of case (revision 0003; names are ASCII)
NOCASE_INDEX = "uq_items_kind_lower_name"
_NOCASE = sa.Index(NOCASE_INDEX, ITEMS.c.kind, sa.func.lower(ITEMS.c.name), unique=True)

JOBS = sa.Table(
    "jobs",
    _meta,
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
    sa.Column("attempts", sa.Integer, nullable=False, server_default=sa.text("0")),
)


class NameTakenError(InputError):
    """An item of this kind already has the name (HTTP 409)."""


def _now() -> _dt.datetime:
    return _dt.datetime.now(_dt.UTC)


def _utc(value: _dt.datetime | None) -> _dt.datetime | None:
    # SQLite gives naive datetimes back; they were stored as UTC
    if value is not None and value.tzinfo is None:
        return value.replace(tzinfo=_dt.UTC)
    return value


@dataclass(frozen=True)
class ItemRow:
    id: str
    kind: str
    name: str
    metadata: dict
    file_path: str | None
    sha256: str | None
    state: str
    read_only: bool
    team: str | None
    created_at: _dt.datetime
    updated_at: _dt.datetime

    def public(self) -> dict:
        """JSON-ready view (no server paths)."""
        return {
            "id": self.id,
            "kind": self.kind,
            "name": self.name,
            "state": self.state,
            "read_only": self.read_only,
            "team": self.team,
            "metadata": self.metadata,
            "file": Path(self.file_path).name if self.file_path else None,
            "sha256": self.sha256,
            "created_at": self.created_at.isoformat(timespec="seconds"),
            "updated_at": self.updated_at.isoformat(timespec="seconds"),
        }


@dataclass(frozen=True)
class JobRow:
    id: str
    kind: str
    item_id: str | None
    state: str
    progress: float
    message: str
    error: str | None
    runner: str | None
    heartbeat_at: _dt.datetime | None
    created_at: _dt.datetime
    updated_at: _dt.datetime
    attempts: int


def _item(row) -> ItemRow:
    d = dict(row._mapping)
    for k in ("created_at", "updated_at"):
        d[k] = _utc(d[k])
    d["metadata"] = dict(d["metadata"] or {})
    return ItemRow(**d)


def _job(row) -> JobRow:
    d = dict(row._mapping)
    for k in ("created_at", "updated_at", "heartbeat_at"):
        d[k] = _utc(d[k])
    return JobRow(**d)


def _item_values(
    item_id: str,
    kind: str,
    name: str,
    now,
    *,
    metadata: dict | None = None,
    state: str = "pending",
    file_path: str | None = None,
    sha256: str | None = None,
    read_only: bool = False,
    team: str | None = None,
) -> dict:
    """The columns of a new ``items`` row."""
    return {
        "id": item_id,
        "kind": kind,
        "name": name,
        "metadata": metadata or {},
        "file_path": file_path,
        "sha256": sha256,
        "state": state,
        "read_only": read_only,
        "team": team,
        "created_at": now,
        "updated_at": now,
    }


def _job_values(job_id: str, kind: str, item_id: str | None, message: str, now) -> dict:
    """The columns of a new, queued ``jobs`` row."""
    return {
        "id": job_id,
        "kind": kind,
        "item_id": item_id,
        "state": "queued",
        "progress": 0.0,
        "message": message,
        "created_at": now,
        "updated_at": now,
    }


class CatalogueDB:
    """Items and jobs in one database (thread-safe: one short transaction per call).

    Parameters
    ----------
    url : str
        SQLAlchemy database URL, e.g. ``sqlite:////var/lib/skisnow/catalogue.db`` or
        ``postgresql+psycopg://user@host/skisnow``. The schema is created or upgraded to
        the newest revision (:func:`app.storage.schema.upgrade_schema`).
    """

    def __init__(self, url: str) -> None:
        kwargs: dict = {"future": True}
        if url.startswith("sqlite"):
            path = url.split(":///", 1)[-1]
            if path and path != ":memory:":
                Path(path).parent.mkdir(parents=True, exist_ok=True)
            kwargs["connect_args"] = {"check_same_thread": False, "timeout": 30}
        self.url = url
        self.engine = sa.create_engine(url, **kwargs)
        if url.startswith("sqlite"):

            @sa.event.listens_for(self.engine, "connect")
            def _pragmas(dbapi_conn, _record):  # pragma: no cover - trivial
                cur = dbapi_conn.cursor()
                # switching a new database to WAL takes an exclusive lock and does not wait on
                # the busy timeout: processes starting at once retry it (it is a no-op once set)
                for attempt in range(100):
                    try:
                        cur.execute("PRAGMA journal_mode=WAL")
                        break
                    except sqlite3.OperationalError as exc:
                        if "locked" not in str(exc).lower() or attempt == 99:
                            raise
                        time.sleep(0.02 + 0.01 * (attempt % 5))
                cur.execute("PRAGMA foreign_keys=ON")
                cur.close()

        upgrade_schema(self.engine)
        self._ensure_nocase_index()

    def _ensure_nocase_index(self) -> None:
        """Add the unique index on ``(kind, lower(name))`` that revision 0003 left out of a
        catalogue holding names that differ only in case, once none do any more (a cheap
        look-up of the index when it is there)."""
        dialect = self.engine.dialect.name
        if dialect == "sqlite":
            look = "SELECT name FROM sqlite_master WHERE type = 'index' AND name = :n"
        elif dialect == "postgresql":
            look = "SELECT indexname FROM pg_indexes WHERE indexname = :n"
        else:
            return
        with self.engine.connect() as c:
            if c.execute(sa.text(look), {"n": NOCASE_INDEX}).first() is not None:
                return
        try:
            with self.engine.begin() as c:
                c.execute(sa.schema.CreateIndex(_NOCASE, if_not_exists=True))
        except sa.exc.IntegrityError:  # names that differ only in case: still left out
            log.warning(
                "catalogue: names that differ only in case are kept and the unique index %s is "
                "left out until one of each is renamed",
                NOCASE_INDEX,
            )

    def close(self) -> None:
        self.engine.dispose()

    # ------------------------------------------------------------------------- items

    def add_item(
        self,
        kind: str,
        name: str,
        *,
        metadata: dict | None = None,
        state: str = "pending",
        file_path: str | None = None,
        sha256: str | None = None,
        read_only: bool = False,
        team: str | None = None,
    ) -> ItemRow:
        """Insert an item; :class:`NameTakenError` if ``(kind, name)`` exists."""
        if kind not in ITEM_KINDS or state not in ITEM_STATES:
            raise InputError(f"bad item kind/state {kind!r}/{state!r}")
        now = _now()
        values = _item_values(
            uuid.uuid4().hex,
            kind,
            name,
            now,
            metadata=metadata,
            state=state,
            file_path=file_path,
            sha256=sha256,
            read_only=read_only,
            team=team,
        )
        try:
            with self.engine.begin() as c:
                self._refuse_clash(c, kind, name)
                c.execute(ITEMS.insert().values(**values))
        except sa.exc.IntegrityError:  # a concurrent insert won the race (the unique indexes)
            raise self._taken(kind, name) from None
        return self.item(values["id"])

    def _taken(self, kind: str, name: str, same: ItemRow | None = None) -> NameTakenError:
        """The 409 error for ``name``, naming the existing item it clashes with."""
        same = same or self.item_by_name_nocase(kind, name)
        if same is None or same.name == name:
            return NameTakenError(f"a {kind} named {name!r} already exists; choose another name")
        return NameTakenError(
            f"a {kind} named {name!r} clashes with the existing {kind} {same.name!r}: names "
            "are unique regardless of case; choose another name"
        )

    def _refuse_clash(self, c, kind: str, name: str, item_id: str | None = None) -> None:
        """Raise :class:`NameTakenError` when another ``kind`` item (not ``item_id``) has
        ``name`` regardless of case; run inside the insert's or rename's transaction."""
        q = ITEMS.select().where(ITEMS.c.kind == kind, sa.func.lower(ITEMS.c.name) == name.lower())
        if item_id is not None:
            q = q.where(ITEMS.c.id != item_id)
        row = c.execute(q.limit(1)).first()
        if row is not None:
            raise self._taken(kind, name, _item(row))

    def item_by_name_nocase(self, kind: str, name: str) -> ItemRow | None:
        """The ``kind`` item named ``name`` regardless of case (the exact name first)."""
        with self.engine.connect() as c:
            rows = c.execute(
                ITEMS.select()
                .where(ITEMS.c.kind == kind, sa.func.lower(ITEMS.c.name) == name.lower())
                .order_by(ITEMS.c.name)
            ).all()
        rows = sorted((_item(r) for r in rows), key=lambda r: r.name != name)
        return rows[0] if rows else None

    def add_item_with_job(
        self,
        kind: str,
        name: str,
        job_kind: str,
        *,
        item_id: str | None = None,
        metadata: dict | None = None,
        team: str | None = None,
        message: str = "queued",
        check_quota=None,
    ) -> tuple[ItemRow, JobRow]:
        """Insert a ``pending`` item and its queued job in one transaction that first calls
        ``check_quota(counts)`` with :meth:`active_job_counts` as the transaction sees them
        (it raises to refuse; nothing is written then).

        The check and the inserts are serialised across threads and processes, so that
        concurrent uploads cannot all pass a quota that leaves room for one: SQLite takes its
        write lock first (``BEGIN IMMEDIATE``); PostgreSQL takes a transaction-scoped advisory
        lock (:data:`QUOTA_LOCK_KEY`), held until the commit. ``item_id`` (default: a new
        one) lets the caller write the item's files before the job becomes visible to a
        runner. :class:`NameTakenError` if ``(kind, name)`` exists.
        """
        if kind not in ITEM_KINDS:
            raise InputError(f"bad item kind {kind!r}")
        now = _now()
        item_id = item_id or uuid.uuid4().hex
        job_id = uuid.uuid4().hex
        dialect = self.engine.dialect.name
        with self.engine.connect() as c:
            if dialect == "sqlite":
                c.exec_driver_sql("BEGIN IMMEDIATE")
            elif dialect == "postgresql":
                c.execute(sa.text("SELECT pg_advisory_xact_lock(:k)"), {"k": QUOTA_LOCK_KEY})
            if check_quota is not None:
                check_quota(self._active_job_counts(c))
            self._refuse_clash(c, kind, name)
            try:
                c.execute(
                    ITEMS.insert().values(
                        **_item_values(item_id, kind, name, now, metadata=metadata, team=team)
                    )
                )
            except sa.exc.IntegrityError:  # a concurrent insert won the race (unique indexes)
                raise self._taken(kind, name) from None
            c.execute(JOBS.insert().values(**_job_values(job_id, job_kind, item_id, message, now)))
            c.commit()
        return self.item(item_id), self.job(job_id)

    def item(self, item_id: str) -> ItemRow | None:
        with self.engine.connect() as c:
            row = c.execute(ITEMS.select().where(ITEMS.c.id == item_id)).first()
        return _item(row) if row else None

    def item_by_name(self, kind: str, name: str) -> ItemRow | None:
        with self.engine.connect() as c:
            row = c.execute(
                ITEMS.select().where(ITEMS.c.kind == kind, ITEMS.c.name == name)
            ).first()
        return _item(row) if row else None

    def items(self, kind: str | None = None, state: str | None = None) -> list[ItemRow]:
        q = ITEMS.select().order_by(ITEMS.c.kind, ITEMS.c.name)
        if kind is not None:
            q = q.where(ITEMS.c.kind == kind)
        if state is not None:
            q = q.where(ITEMS.c.state == state)
        with self.engine.connect() as c:
            return [_item(r) for r in c.execute(q)]

    def update_item(self, item_id: str, **values) -> ItemRow:
        """Update columns of an item; renaming onto a taken name (regardless of case; another
        case of its own name is fine) raises NameTakenError."""
        values["updated_at"] = _now()
        name = values.get("name")
        kind = None
        try:
            with self.engine.begin() as c:
                if name is not None:
                    kind = c.execute(
                        sa.select(ITEMS.c.kind).where(ITEMS.c.id == item_id)
                    ).scalar_one_or_none()
                    if kind is not None:
                        self._refuse_clash(c, kind, name, item_id)
                c.execute(ITEMS.update().where(ITEMS.c.id == item_id).values(**values))
        except sa.exc.IntegrityError:
            if kind is not None:
                raise self._taken(kind, name) from None
            raise NameTakenError(f"name {name!r} is already taken") from None
        return self.item(item_id)

    def adopt_item(self, item_id: str, team: str) -> bool:
        """Give an upload of no team to ``team`` (one conditional ``UPDATE``): True when it
        was of no team and not shipped, else nothing is written."""
        with self.engine.begin() as c:
            res = c.execute(
                ITEMS.update()
                .where(ITEMS.c.id == item_id, ITEMS.c.team.is_(None), ITEMS.c.read_only.is_(False))
                .values(team=team, updated_at=_now())
            )
        return res.rowcount == 1

    def delete_item(self, item_id: str) -> None:
        with self.engine.begin() as c:
            c.execute(JOBS.delete().where(JOBS.c.item_id == item_id))
            c.execute(ITEMS.delete().where(ITEMS.c.id == item_id))

    def delete_failed_item(self, item_id: str) -> bool:
        """Delete an item and its jobs only if it is ``failed`` and no job of it is queued or
        running (one transaction); True when it was deleted. A failed item frees its name this
        way: the re-upload of the same name replaces it."""
        with self.engine.begin() as c:
            active = c.execute(
                JOBS.select().where(
                    JOBS.c.item_id == item_id, JOBS.c.state.in_(("queued", "running"))
                )
            ).first()
            if active is not None:
                return False
            gone = c.execute(
                ITEMS.delete().where(ITEMS.c.id == item_id, ITEMS.c.state == "failed")
            ).rowcount
            if gone:
                c.execute(JOBS.delete().where(JOBS.c.item_id == item_id))
        return bool(gone)

    def failed_items(self, kind: str) -> list[tuple[ItemRow, JobRow | None]]:
        """The ``failed`` items of ``kind`` by name, each with its last failed job (its
        ``error`` is the reason; None when no job row is left)."""
        out = []
        for item in self.items(kind, state="failed"):
            jobs = self.jobs(item_id=item.id, states=("failed",))
            out.append((item, max(jobs, key=lambda j: j.updated_at) if jobs else None))
        return out

    # -------------------------------------------------------------------------- jobs

    def add_job(self, kind: str, item_id: str | None, message: str = "queued") -> JobRow:
        now = _now()
        job_id = uuid.uuid4().hex
        with self.engine.begin() as c:
            c.execute(JOBS.insert().values(**_job_values(job_id, kind, item_id, message, now)))
        return self.job(job_id)

    def job(self, job_id: str) -> JobRow | None:
        with self.engine.connect() as c:
            row = c.execute(JOBS.select().where(JOBS.c.id == job_id)).first()
        return _job(row) if row else None

    def jobs(
        self,
        *,
        item_id: str | None = None,
        states=None,
        limit: int = 100,
        by_team: bool = False,
        team: str | None = None,
    ) -> list[JobRow]:
        """The most recent jobs (newest first); with ``by_team``, only those a member of
        ``team`` may see: jobs of shipped items, of items of no team and of ``team``'s items
        (``team=None``: a caller of no team)."""
        q = JOBS.select().order_by(JOBS.c.created_at.desc()).limit(limit)
        if item_id is not None:
            q = q.where(JOBS.c.item_id == item_id)
        if states is not None:
            q = q.where(JOBS.c.state.in_(list(states)))
        if by_team:
            seen = [ITEMS.c.team.is_(None), ITEMS.c.read_only.is_(True)]
            if team is not None:
                seen.append(ITEMS.c.team == team)
            q = q.select_from(JOBS.outerjoin(ITEMS, JOBS.c.item_id == ITEMS.c.id)).where(
                sa.or_(*seen)
            )
        with self.engine.connect() as c:
            return [_job(r) for r in c.execute(q)]

    def active_job_counts(self) -> dict[str | None, int]:
        """Queued and running jobs per team of their item (``None``: items of no team)."""
        with self.engine.connect() as c:
            return self._active_job_counts(c)

    @staticmethod
    def _active_job_counts(c) -> dict[str | None, int]:
        q = (
            sa.select(ITEMS.c.team, sa.func.count())
            .select_from(JOBS.outerjoin(ITEMS, JOBS.c.item_id == ITEMS.c.id))
            .where(JOBS.c.state.in_(("queued", "running")))
            .group_by(ITEMS.c.team)
        )
        return {team: int(n) for team, n in c.execute(q)}

    def update_job(self, job_id: str, *, owner: str | None = None, **values) -> bool:
        """Update columns of a job; with ``owner``, only while the job's runner is ``owner``
        (False: another runner took it over, nothing was written)."""
        now = _now()
        values["updated_at"] = now
        if values.get("state") == "running" or "progress" in values:
            values.setdefault("heartbeat_at", now)
        q = JOBS.update().where(JOBS.c.id == job_id)
        if owner is not None:
            q = q.where(JOBS.c.runner == owner)
        with self.engine.begin() as c:
            res = c.execute(q.values(**values))
        return res.rowcount == 1

    def heartbeat(self, job_ids, runner: str) -> None:
        if not job_ids:
            return
        with self.engine.begin() as c:
            c.execute(
                JOBS.update()
                .where(JOBS.c.id.in_(list(job_ids)), JOBS.c.runner == runner)
                .values(heartbeat_at=_now())
            )

    def claim_job(self, job_id: str, runner: str, stale_before: _dt.datetime) -> bool:
        """Atomically mark a queued (or stale running) job as running by ``runner``."""
        now = _now()
        with self.engine.begin() as c:
            res = c.execute(
                JOBS.update()
                .where(
                    JOBS.c.id == job_id,
                    sa.or_(
                        JOBS.c.state == "queued",
                        sa.and_(
                            JOBS.c.state == "running",
                            sa.or_(
                                JOBS.c.heartbeat_at.is_(None), JOBS.c.heartbeat_at < stale_before
                            ),
                        ),
                    ),
                )
                .values(
                    state="running",
                    runner=runner,
                    heartbeat_at=now,
                    updated_at=now,
                    attempts=JOBS.c.attempts + 1,
                )
            )
        return res.rowcount == 1

    def claimable_jobs(self, stale_before: _dt.datetime) -> list[JobRow]:
        """Queued jobs, and running jobs whose runner stopped beating (oldest first)."""
        q = (
            JOBS.select()
            .where(
                sa.or_(
                    JOBS.c.state == "queued",
                    sa.and_(
                        JOBS.c.state == "running",
                        sa.or_(JOBS.c.heartbeat_at.is_(None), JOBS.c.heartbeat_at < stale_before),
                    ),
                )
            )
            .order_by(JOBS.c.created_at)
        )
        with self.engine.connect() as c:
            return [_job(r) for r in c.execute(q)]

    def running_jobs_of(self, runner_prefix: str) -> list[JobRow]:
        """Jobs marked running by runners whose id starts with ``runner_prefix`` (a host)."""
        q = JOBS.select().where(JOBS.c.state == "running", JOBS.c.runner.like(f"{runner_prefix}%"))
        with self.engine.connect() as c:
            return [_job(r) for r in c.execute(q)]
