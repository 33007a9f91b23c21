"""The data directory of the service (``Settings.data_dir``): where uploads, finished items,
job scratch space and caches live (:class:`Layout`).

Storage layout::

    catalogue.db                 SQLite catalogue (default database URL)
    uploads/<item id>.texture.h5 detrended texture of an uploaded grind (until its table is built)
    uploads/<item id>.csv        camber CSV of an uploaded ski (kept: the ski's raw data)
    work/<item id>/              a job's scratch space (table checkpoints; removed when done)
    grinds/<item id>.h5          finished texture table (schema skisnow.table/…)
    skis/<item id>.h5            finished ski file with its network (schema skisnow.ski/1)
    cache/ski-figures/<stem>.json the figures of a ski's page (``<stem>``: the ski file's name,
                                 ``<item id>`` for an upload; removed with it)

Files are named by item id so renaming touches only the database.
"""

from __future__ import annotations

import contextlib
import shutil
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Layout"]


@dataclass(frozen=True)
class Layout:
    """Paths of the data directory (see the module docstring)."""

    root: Path

    @property
    def uploads(self) -> Path:
        return self.root / "uploads"

    def work(self, item_id: str) -> Path:
        return self.root / "work" / item_id

    def grind_texture(self, item_id: str) -> Path:
        return self.uploads / f"{item_id}.texture.h5"

    def ski_csv(self, item_id: str) -> Path:
        return self.uploads / f"{item_id}.csv"

    def grind_table(self, item_id: str) -> Path:
        return self.root / "grinds" / f"{item_id}.h5"

    def ski_file(self, item_id: str) -> Path:
        return self.root / "skis" / f"{item_id}.h5"

    def ski_figures(self, stem: str) -> Path:
        """The ski page's figures of ski file ``{stem}.h5`` (:mod:`app.service.ski_figures`)."""
        return self.root / "cache" / "ski-figures" / f"{stem}.json"

    def remove_item_files(self, item_id: str) -> None:
        for path in (
            self.grind_texture(item_id),
            self.ski_csv(item_id),
            self.grind_table(item_id),
            self.ski_file(item_id),
            self.ski_figures(item_id),
        ):
            with contextlib.suppress(FileNotFoundError):
                path.unlink()
        shutil.rmtree(self.work(item_id), ignore_errors=True)
