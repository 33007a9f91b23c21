"""Alembic migrations of the catalogue database (:mod:`app.storage.schema` runs them).

``env.py`` runs the scripts of ``versions/`` on the connection that
:func:`app.storage.schema.upgrade_schema` hands over; it never reads a URL or an ``alembic.ini``
of its own, so the scripts work from any install (they are package data of the wheel). A new
revision: ``alembic -c app/storage/migrations/alembic.ini revision -m "what changes"`` from a
source checkout, then write its ``upgrade()`` (and ``downgrade()``) by hand.
"""
