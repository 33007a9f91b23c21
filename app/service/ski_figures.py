"""The figures of a ski's page ``/skis/{name}`` as SVG: EI(X), c(X) and the misfit per case.

matplotlib draws each in about 0.4 s (≈1.3 s for the three on a demo ski; most of the first
page view once the held-out errors are stored with the identification). They depend only on
the numbers they draw and on the drawing code, so they are drawn once and kept:

- with the ski's record, for the life of the process;
- on disk, one JSON file per ski file (:meth:`app.storage.layout.Layout.ski_figures`), stamped
with a
  sha256 of the drawn numbers (:func:`app.service.beam_report` at :data:`PLOT_POINTS` points
  and the identification's report) and of the drawing code (``app/plots.py``, matplotlib's
  version). Another worker process, or the service after a restart, reuses them; a changed
  ski file or changed code draws anew and replaces them. An unreadable or unwritable cache is
  logged and the figures drawn.

The ski job of an upload draws them as its last step (:mod:`app.jobs.uploads`), so an uploaded ski's
first page view reads them; a demo ski's first view in a new data directory draws them.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
from pathlib import Path

import matplotlib
from skisnow.app import plots, service
from skisnow.app.storage.common import atomic_path

log = logging.getLogger(__name__)

__all__ = ["CACHE_SCHEMA", "PLOT_POINTS", "ski_figures"]

#: points along the ski of the EI(X) and c(X) plots (the JSON API and the page's table: 41)
PLOT_POINTS = 401
CACHE_SCHEMA = "skisnow.ski-figures/1"


@functools.cache
def _code_digest() -> str:
    """sha256 of what draws the figures: ``app/plots.py`` and matplotlib's version."""
    h = hashlib.sha256(Path(plots.__file__).read_bytes())
    h.update(matplotlib.__version__.encode())
    h.update(f"{PLOT_POINTS}".encode())
    return h.hexdigest()


def _inputs(ski: service.Ski) -> tuple[dict | None, dict | None]:
    """The beam report drawn along the ski (None without a beam) and the identification report
    drawn per case (None without one)."""
    beam = service.beam_report(ski, points=PLOT_POINTS)
    ident = beam.get("identification")
    return (beam if beam["available"] else None), (
        ident if ident and "case_load_kg" in ident else None
    )


def _draw(beam: dict | None, ident: dict | None) -> dict[str, str]:
    figures = {}
    if beam is not None:
        figures["stiffness"] = plots.stiffness_svg(beam)
        figures["camber"] = plots.camber_svg(beam)
    if ident is not None:
        figures["misfit"] = plots.misfit_svg(ident)
    return figures


def _read(path: Path, digest: str) -> dict[str, str] | None:
    try:
        content = json.loads(path.read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError) as exc:
        log.warning("ski figure cache %s unreadable, drawing anew: %s", path, exc)
        return None
    if content.get("schema") != CACHE_SCHEMA or content.get("sha256") != digest:
        return None
    figures = content.get("figures")
    ok = isinstance(figures, dict) and all(isinstance(v, str) for v in figures.values())
    return figures if ok else None


def _write(path: Path, digest: str, figures: dict[str, str]) -> None:
    try:
        with atomic_path(path) as tmp:
            tmp.write_text(
                json.dumps({"schema": CACHE_SCHEMA, "sha256": digest, "figures": figures})
            )
    except OSError as exc:
        log.warning("ski figure cache %s not written: %s", path, exc)


def ski_figures(ski: service.Ski, cache_file: Path | None = None) -> dict[str, str]:
    """The SVG of each figure of the ski's page: ``stiffness`` and ``camber`` when the ski has
    a beam, ``misfit`` when it has an identification with cases.

    Parameters
    ----------
    ski : Ski
        The catalogue's ski.
    cache_file : Path, optional
        Where the figures of this ski file are kept between processes (none: memory only).
    """
    rec = ski.record
    key = (rec.identified, rec.beam, rec.network)
    cached = rec.cache.get("page_figures")  # a dataclasses.replace copy shares the cache
    if cached is not None and all(a is b for a, b in zip(cached[0], key, strict=True)):
        return cached[1]
    beam, ident = _inputs(ski)
    digest = hashlib.sha256(
        json.dumps({"beam": beam, "identification": ident, "code": _code_digest()}).encode()
    ).hexdigest()
    figures = _read(cache_file, digest) if cache_file is not None else None
    if figures is None:
        figures = _draw(beam, ident)
        if cache_file is not None:
            _write(cache_file, digest, figures)
    rec.cache["page_figures"] = (key, figures)
    return figures
