"""The persistent catalogue behind the routes of :mod:`app.api.skis`, :mod:`app.api.grinds`,
:mod:`app.api.items` and :mod:`app.api.jobs`: its state, request checks and answer views.

:func:`start` and :func:`stop` run in the app's lifespan (catalogue database, job runner;
:func:`app.api.factory.create_api`). Thin routes: each checks the request with the helpers here
and calls one function of :mod:`app.jobs.uploads`. Who may change and see what is
:mod:`app.api.access`: changes pass its write guard first; with team tokens, reads show the
caller's team's items and jobs (and the shipped ones and those of no team), another team's are
404. Uploads are refused with 429
beyond the job quotas (``max_jobs_per_team``, ``max_queued_jobs``). See docs/uploads.md.
"""

from __future__ import annotations

import contextlib
import logging
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from fastapi import Depends, FastAPI, Request, UploadFile
from fastapi.responses import JSONResponse
from skisnow.app.api import access
from skisnow.app.api.access import Caller, failed_views
from skisnow.app.errors import (
    ConflictError,
    ForbiddenError,
    UnsupportedContentError,
    UploadTooLargeError,
)
from skisnow.app.jobs import JobRunner, uploads
from skisnow.app.jobs.handlers import job_handlers
from skisnow.app.jobs.runner import queue_info
from skisnow.app.service import UnknownItemError
from skisnow.app.service.live import LiveCatalogue, register_shipped
from skisnow.app.storage.catalogue import CatalogueDB, ItemRow, JobRow
from skisnow.app.storage.layout import Layout
from skisnow.solvers.errors import DataFileError, InputError

__all__ = [
    "UPLOAD_PATHS",
    "CatalogueState",
    "Reader",
    "Team",
    "accepted",
    "busy",
    "catalogue_state",
    "changing_team",
    "failed_views",
    "incoming",
    "item_or_404",
    "job_view",
    "limits",
    "multipart",
    "start",
    "stop",
    "text",
    "writable",
    "writer",
]

log = logging.getLogger(__name__)

#: routes whose bodies may be as large as ``max_upload_bytes`` (others: ``max_body_bytes``)
UPLOAD_PATHS = ("/v1/grinds", "/v1/skis")
_COPY_CHUNK = 1 << 20


@dataclass
class CatalogueState:
    db: CatalogueDB
    layout: Layout
    live: LiveCatalogue
    runner: JobRunner


def start(app: FastAPI) -> None:
    """Open the catalogue database, register the shipped items, load the uploaded ones and
    start the job runner (which resumes interrupted jobs)."""
    settings = app.state.settings
    db = CatalogueDB(settings.catalogue_url)
    layout = Layout(Path(settings.data_dir))
    live = LiveCatalogue(lambda: app.state.catalogue, db)
    register_shipped(db, app.state.catalogue)
    live.sync()
    handlers, on_failure = job_handlers(settings, layout, on_ready=live.put)
    runner = JobRunner(
        db,
        handlers,
        on_failure=on_failure,
        on_poll=live.sync,
        workers=settings.job_workers,
        poll_s=settings.job_poll_s,
        stale_s=settings.job_stale_s,
    )
    runner.start()
    app.state.uploads = CatalogueState(db, layout, live, runner)


def stop(app: FastAPI) -> None:
    """Stop the job runner (running jobs go back to the queue), take the uploads out of the
    served catalogue and close the database. The app can start again (a second lifespan of
    the same app object, as test clients do): without the unloading its uploads would be taken
    for shipped items (read-only names, never replaced or dropped)."""
    state: CatalogueState | None = getattr(app.state, "uploads", None)
    if state is None:
        return
    state.runner.stop()
    state.live.drop_all()
    state.db.close()
    app.state.uploads = None


# ----------------------------------------------------------------------------- helpers


def catalogue_state(request: Request) -> CatalogueState:
    return request.app.state.uploads


def changing_team(request: Request) -> str | None:
    """The changing caller's team from ``Authorization: Bearer TOKEN`` or the login cookie
    (None when teams are off; the write guard of :mod:`app.api.access` has refused a missing
    or bad token already)."""
    tokens = request.app.state.settings.team_tokens
    if not tokens:
        return None
    return access.request_team(request.headers, tokens, required=True)


def limits(request: Request) -> uploads.JobLimits:
    settings = request.app.state.settings
    return uploads.JobLimits(settings.max_jobs_per_team, settings.max_queued_jobs)


def multipart(request: Request) -> None:
    ctype = request.headers.get("content-type", "")
    if not ctype.lower().startswith("multipart/form-data"):
        raise UnsupportedContentError(
            f"uploads are multipart/form-data (a file part and form fields), got {ctype or 'none'}"
        )


Team = Annotated[str | None, Depends(changing_team)]
Reader = Annotated[Caller, Depends(access.caller)]


def writer(request: Request, team: str | None) -> Caller:
    return Caller(team, bool(request.app.state.settings.team_tokens))


def job_view(db: CatalogueDB, job: JobRow) -> dict:
    item = db.item(job.item_id) if job.item_id else None
    queue = queue_info(db, job)
    return {
        "id": job.id,
        "kind": job.kind,
        "item": item.name if item else None,
        "item_id": job.item_id,
        "state": job.state,
        "progress": round(job.progress, 4),
        "message": job.message,
        "error": job.error,
        "created_at": job.created_at.isoformat(timespec="seconds"),
        "updated_at": job.updated_at.isoformat(timespec="seconds"),
        "lane": queue["lane"],
        "queue_position": queue["queue_position"],
        "ahead": queue["ahead"],
        "estimate_s": queue["estimate_s"],
        "estimate_basis": queue["estimate_basis"],
    }


def item_or_404(state: CatalogueState, kind: str, name: str, who: Caller) -> ItemRow:
    """The item, or 404 naming the items ``who`` may see (another team's is not found)."""
    row = state.db.item_by_name(kind, name)
    if row is None or not who.sees(row.team, row.read_only):
        known = [i.name for i in state.db.items(kind) if who.sees(i.team, i.read_only)]
        raise UnknownItemError(kind, name, known)
    return row


def writable(request: Request, row: ItemRow, team: str | None) -> None:
    """Refuse (403) a change of a shipped item, of another team's and, with team tokens, of
    an item of no team (:func:`app.api.access.team_may_change`)."""
    if row.read_only:
        raise ForbiddenError(f"{row.kind} {row.name!r} is a shipped demo item (read-only)")
    why = access.team_may_change(row.team, team, bool(request.app.state.settings.team_tokens))
    if why is not None:
        raise ForbiddenError(f"{row.kind} {row.name!r} {why}")


def busy(state: CatalogueState, row: ItemRow) -> None:
    active = state.db.jobs(item_id=row.id, states=("queued", "running"))
    if active:
        raise ConflictError(
            f"{row.kind} {row.name!r} is used by job {active[0].id} ({active[0].state}); "
            "wait for it to finish"
        )


@contextlib.contextmanager
def incoming(state: CatalogueState, file: UploadFile, limit: int):
    """Copy the upload to a private temporary file (removed afterwards, whatever happens)."""
    incoming = state.layout.root / ".incoming"
    incoming.mkdir(parents=True, exist_ok=True)
    suffix = Path(file.filename or "").suffix.lower()[:16]
    with tempfile.NamedTemporaryFile(dir=incoming, suffix=suffix, delete=False) as tmp:
        path = Path(tmp.name)
        try:
            size = 0
            while chunk := file.file.read(_COPY_CHUNK):
                size += len(chunk)
                if size > limit:
                    raise UploadTooLargeError(f"file exceeds the upload limit of {limit} bytes")
                tmp.write(chunk)
        except BaseException:
            tmp.close()
            path.unlink(missing_ok=True)
            raise
    try:
        yield path
    except DataFileError as exc:
        raise InputError(str(exc).replace(str(path), file.filename or "file")) from None
    except InputError as exc:
        if str(path) in str(exc):
            raise InputError(str(exc).replace(str(path), file.filename or "file")) from None
        raise
    finally:
        path.unlink(missing_ok=True)


def text(value: str | None, field: str, max_len: int = 2000) -> str:
    value = (value or "").strip()
    if len(value) > max_len:
        raise InputError(f"{field} is longer than {max_len} characters")
    return value


def grind_provenance(table) -> str:
    """The table's ``texture_provenance``: 'measured: …' (the shipped ski base), 'uploaded: …'
    (an upload); 'synthetic' when absent (the shipped synthetic grinds)."""
    return str(table.attrs.get("texture_provenance") or "synthetic")


def accepted(item, job_id: str, **extra) -> JSONResponse:
    """202 answer of an upload: the item, its job and where to follow it."""
    url = f"/v1/jobs/{job_id}"
    return JSONResponse(
        {"item": item.public(), "job": job_id, "job_url": url, **extra},
        status_code=202,
        headers={"Location": url},
    )
