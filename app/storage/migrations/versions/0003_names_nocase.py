"""items: names unique regardless of case, per kind (``Grind-1`` beside ``grind-1`` is refused).

A unique index on ``(kind, lower(name))``, on SQLite and PostgreSQL alike (names are ASCII:
``lower`` is the same on both). A catalogue that already holds names differing only in case
keeps them (no row is renamed or dropped): the index is then left out, a warning names the
clashing names, and :class:`~app.storage.catalogue.CatalogueDB` still refuses every new clash
inside the insert's transaction (docs/deployment.md: rename one of each pair, then
``skisnow serve`` adds the index at its next start).

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-26
"""

from __future__ import annotations

import logging

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None

log = logging.getLogger("skisnow.app.storage.schema")

INDEX = "uq_items_kind_lower_name"


def case_clashes(bind) -> list[tuple[str, str]]:
    """``(kind, names)`` of the names that differ only in case (empty: the index fits)."""
    q = sa.text(
        "SELECT kind, lower(name) FROM items GROUP BY kind, lower(name) HAVING count(*) > 1"
    )
    out = []
    for kind, lname in bind.execute(q).all():
        names = bind.execute(
            sa.text("SELECT name FROM items WHERE kind = :k AND lower(name) = :n ORDER BY name"),
            {"k": kind, "n": lname},
        ).scalars()
        out.append((kind, ", ".join(names)))
    return out


def upgrade() -> None:
    bind = op.get_bind()
    clashes = case_clashes(bind)
    if clashes:
        log.warning(
            "catalogue: names that differ only in case are kept, and the unique index %s is "
            "left out until one of each is renamed: %s",
            INDEX,
            "; ".join(f"{kind}s {names}" for kind, names in clashes),
        )
        return
    op.create_index(INDEX, "items", ["kind", sa.text("lower(name)")], unique=True)


def downgrade() -> None:
    op.execute(sa.text(f"DROP INDEX IF EXISTS {INDEX}"))
