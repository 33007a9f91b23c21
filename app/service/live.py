"""The live catalogue: the service's skis and grinds kept in step with the database's ready
uploaded items (:class:`LiveCatalogue`), and the shipped items registered in it
(:func:`register_shipped`)."""

from __future__ import annotations

import contextlib
import logging
import threading
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from skisnow.app import service
from skisnow.app.storage.catalogue import CatalogueDB, ItemRow
from skisnow.app.storage.common import sha256_file
from skisnow.solvers.errors import DataFileError, SkisnowError

log = logging.getLogger(__name__)


def load_live(item: ItemRow):
    """The :mod:`app.service` object of a ready item (file verified against its sha256)."""
    from skisnow.app.storage.skis import read_ski
    from skisnow.app.storage.tables import read_table

    path = Path(item.file_path)
    if not path.is_file():
        raise DataFileError(f"{item.kind} {item.name!r}: file {path} is missing")
    sha = sha256_file(path)
    if sha != item.sha256:
        raise DataFileError(f"{item.kind} {item.name!r}: {path.name} does not match its sha256")
    if item.kind == "grind":
        return service.Grind(item.name, path, sha, read_table(path))
    return service.Ski(item.name, path, sha, read_ski(path))


def _locked(method):
    def wrapper(self, *args, **kwargs):
        with self.lock:
            return method(self, *args, **kwargs)

    wrapper.__name__ = method.__name__
    wrapper.__doc__ = method.__doc__
    return wrapper


class LiveCatalogue:
    """Keeps ``app.state.catalogue`` in step with the database's ready uploaded items.

    Dicts are replaced, never mutated in place, so a request iterating over them is safe.
    """

    def __init__(self, get_catalogue: Callable[[], service.Catalogue], db: CatalogueDB) -> None:
        self._get = get_catalogue
        self.db = db
        self.lock = threading.RLock()
        # item id -> (kind, name, sha256, team)
        self.loaded: dict[str, tuple[str, str, str, str | None]] = {}

    def _dicts(self, kind: str) -> tuple[service.Catalogue, str]:
        return self._get(), "grinds" if kind == "grind" else "skis"

    @_locked
    def put(self, item: ItemRow) -> None:
        obj = load_live(item)
        cat, attr = self._dicts(item.kind)
        d = dict(getattr(cat, attr))
        old = self.loaded.get(item.id)
        if old is not None:
            d.pop(old[1], None)
        d[item.name] = obj
        setattr(cat, attr, d)
        self.loaded[item.id] = (item.kind, item.name, item.sha256, item.team)

    @_locked
    def drop(self, item_id: str) -> None:
        old = self.loaded.pop(item_id, None)
        if old is None:
            return
        cat, attr = self._dicts(old[0])
        d = dict(getattr(cat, attr))
        d.pop(old[1], None)
        setattr(cat, attr, d)

    @_locked
    def drop_all(self) -> None:
        """Take every loaded upload out of the catalogue (the service stops): the catalogue is
        the shipped one again, and a new start loads the uploads afresh."""
        for item_id in list(self.loaded):
            self.drop(item_id)

    @_locked
    def rename(self, item: ItemRow) -> None:
        old = self.loaded.get(item.id)
        if old is None:
            return
        cat, attr = self._dicts(item.kind)
        d = dict(getattr(cat, attr))
        obj = d.pop(old[1], None)
        if obj is not None:
            d[item.name] = replace(obj, name=item.name)
        setattr(cat, attr, d)
        self.loaded[item.id] = (item.kind, item.name, item.sha256, item.team)

    @_locked
    def owned_by_others(self, team: str | None) -> set[tuple[str, str]]:
        """``(kind, name)`` of the served uploads that belong to a team other than ``team``
        (items of no team belong to nobody; shipped items are never here)."""
        return {(k, n) for k, n, _, owner in self.loaded.values() if owner not in (None, team)}

    def catch_up(self, kind: str, name: str) -> bool:
        """Load ``name`` now when this process does not serve it and the database holds it
        ready (another process finished its job before this one's next poll). True when it is
        served afterwards. Costs nothing for a served name, one query for an unknown one."""
        cat, attr = self._dicts(kind)
        if name in getattr(cat, attr):
            return True
        row = self.db.item_by_name(kind, name)
        if row is None or row.state != "ready" or row.read_only:
            return False
        self.sync()
        cat, attr = self._dicts(kind)
        return name in getattr(cat, attr)

    @_locked
    def sync(self) -> None:
        """Load new ready items, drop deleted ones, follow renames (other processes too)."""
        ready = {i.id: i for i in self.db.items(state="ready") if not i.read_only}
        for item_id in list(self.loaded):
            if item_id not in ready:
                self.drop(item_id)
        for item in ready.values():
            old = self.loaded.get(item.id)
            if old == (item.kind, item.name, item.sha256, item.team):
                continue
            if old is not None and old[2] == item.sha256:
                self.rename(item)
                continue
            cat, attr = self._dicts(item.kind)
            if old is None and item.name in getattr(cat, attr):
                continue  # a shipped item of that name is served (see register_shipped)
            try:
                self.put(item)
            except SkisnowError as exc:
                log.error("cannot load %s %r: %s", item.kind, item.name, exc)


def register_shipped(db: CatalogueDB, cat: service.Catalogue) -> None:
    """Record the shipped demo items as read-only rows (names reserved, never deletable)."""
    shipped = {("grind", n): g for n, g in cat.grinds.items()}
    shipped |= {("ski", n): s for n, s in cat.skis.items()}
    for row in db.items():
        if row.read_only and (row.kind, row.name) not in shipped:
            db.delete_item(row.id)
    for (kind, name), obj in shipped.items():
        row = db.item_by_name(kind, name)
        if row is None:
            with contextlib.suppress(SkisnowError):
                db.add_item(
                    kind,
                    name,
                    metadata={"shipped": True},
                    state="ready",
                    file_path=str(obj.path),
                    sha256=obj.sha256,
                    read_only=True,
                )
        elif row.read_only:
            if row.sha256 != obj.sha256 or row.file_path != str(obj.path):
                db.update_item(row.id, file_path=str(obj.path), sha256=obj.sha256)
        else:
            log.warning(
                "uploaded %s %r has the name of a shipped one; the shipped one is served",
                kind,
                name,
            )


def add_uploads(cat: service.Catalogue, settings) -> list[str]:
    """Add the ready uploaded skis and grinds of the service's data folder to ``cat`` (for the
    command line, which serves nothing: ``skisnow --data-dir DIR solve`` or
    ``SKISNOW_DATA_DIR``). Uploads of every team are included: whoever runs the command reads
    the folder anyway. A folder without a catalogue is left alone (none is created); an
    upload whose file is missing or changed is skipped and named in the returned notes, as is
    one whose name a shipped item takes."""
    notes: list[str] = []
    url = settings.catalogue_url
    if settings.database_url is None and not (Path(settings.data_dir) / "catalogue.db").is_file():
        return notes
    db = CatalogueDB(url)
    try:
        for item in db.items(state="ready"):
            if item.read_only:
                continue
            attr = "grinds" if item.kind == "grind" else "skis"
            if item.name in getattr(cat, attr):
                notes.append(f"upload {item.kind} {item.name!r} hidden by a shipped one")
                continue
            try:
                getattr(cat, attr)[item.name] = load_live(item)
            except SkisnowError as exc:
                notes.append(f"upload {item.kind} {item.name!r} skipped: {exc}")
    finally:
        db.close()
    return notes
