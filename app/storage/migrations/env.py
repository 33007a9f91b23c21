"""Alembic environment: run the migrations on the connection handed over in
``config.attributes["connection"]`` (online only; no offline SQL scripts)."""

from __future__ import annotations

from alembic import context

connection = context.config.attributes.get("connection")
if connection is None:  # pragma: no cover - guarded by app.storage.schema
    raise RuntimeError(
        "the catalogue migrations run through app.storage.schema.upgrade_schema(url), which "
        "hands over a connection; there is no alembic.ini URL"
    )
# render_as_batch: SQLite alters tables by copying them (ALTER TABLE is limited there)
context.configure(
    connection=connection,
    render_as_batch=connection.dialect.name == "sqlite",
    transaction_per_migration=False,
)
with context.begin_transaction():
    context.run_migrations()
