"""Routes of the persistent catalogue: uploads of skis and grinds, their jobs, rename, delete.

Mounted by :func:`app.api.create_app`; :func:`start` and :func:`stop` run in the app's
lifespan (catalogue database, job runner). Thin routes: each checks the request and calls one
function of :mod:`app.uploads`. Who may change and see what is :mod:`app.access`: changes
pass its write guard first; with team tokens, reads show the caller's team's items and jobs (and
the shipped ones and those of no team), another team's are 404. Uploads are refused with 429
beyond the job quotas (``max_jobs_per_team``, ``max_queued_jobs``). See docs/uploads.md.
"""

from __future__ import annotations

import contextlib
import logging
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

from fastapi import Depends, FastAPI, File, Form, Request, UploadFile
from fastapi.responses import JSONResponse, Response
from pydantic import BaseModel, ConfigDict, Field
from skisnow.app import access, uploads
from skisnow.app.access import Caller
from skisnow.app.jobs import JobRunner
from skisnow.app.service import UnknownItemError, beam_report, profile_report
from skisnow.app.storage.catalogue import CatalogueDB, ItemRow, JobRow, NameTakenError
from skisnow.solvers.errors import DataFileError, InputError

__all__ = ["UPLOAD_PATHS", "mount", "start", "stop"]

log = logging.getLogger(__name__)

#: routes whose bodies may be as large as ``max_upload_bytes`` (others: ``max_body_bytes``)
UPLOAD_PATHS = ("/v1/grinds", "/v1/skis")
_COPY_CHUNK = 1 << 20


@dataclass
class CatalogueState:
    db: CatalogueDB
    layout: uploads.Layout
    live: uploads.LiveCatalogue
    runner: JobRunner


def start(app: FastAPI) -> None:
    """Open the catalogue database, register the shipped items, load the uploaded ones and
    start the job runner (which resumes interrupted jobs)."""
    settings = app.state.settings
    db = CatalogueDB(settings.catalogue_url)
    layout = uploads.Layout(Path(settings.data_dir))
    live = uploads.LiveCatalogue(lambda: app.state.catalogue, db)
    uploads.register_shipped(db, app.state.catalogue)
    live.sync()
    handlers = {
        uploads.GRIND_JOB: lambda ctx: uploads.run_grind_job(ctx, layout, settings, live.put),
        uploads.SKI_JOB: lambda ctx: uploads.run_ski_job(ctx, layout, settings, live.put),
    }
    runner = JobRunner(
        db,
        handlers,
        on_failure=lambda ctx, exc: uploads.on_job_failure(ctx, layout),
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


class RenameBody(BaseModel):
    """Body of ``PATCH /v1/skis/{name}`` and ``PATCH /v1/grinds/{name}``."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(..., min_length=1, max_length=64, examples=["my-ski-2025"])


def _state(request: Request) -> CatalogueState:
    return request.app.state.uploads


def _team(request: Request) -> str | None:
    """The changing caller's team from ``Authorization: Bearer TOKEN`` (None when teams are
    off; the write guard of :mod:`app.access` has refused a missing or bad token already)."""
    tokens = request.app.state.settings.team_tokens
    if not tokens:
        return None
    return access.bearer_team(request.headers, tokens, required=True)


def _limits(request: Request) -> uploads.JobLimits:
    settings = request.app.state.settings
    return uploads.JobLimits(settings.max_jobs_per_team, settings.max_queued_jobs)


def _multipart(request: Request) -> None:
    ctype = request.headers.get("content-type", "")
    if not ctype.lower().startswith("multipart/form-data"):
        raise uploads.UnsupportedContentError(
            f"uploads are multipart/form-data (a file part and form fields), got {ctype or 'none'}"
        )


Team = Annotated[str | None, Depends(_team)]
Reader = Annotated[Caller, Depends(access.caller)]


def _writer(request: Request, team: str | None) -> Caller:
    return Caller(team, bool(request.app.state.settings.team_tokens))


def _job_view(db: CatalogueDB, job: JobRow) -> dict:
    item = db.item(job.item_id) if job.item_id else None
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
    }


def _item_or_404(state: CatalogueState, kind: str, name: str, who: Caller) -> ItemRow:
    """The item, or 404 naming the items ``who`` may see (another team's is not found)."""
    row = state.db.item_by_name(kind, name)
    if row is None or not who.sees(row.team, row.read_only):
        known = [i.name for i in state.db.items(kind) if who.sees(i.team, i.read_only)]
        raise UnknownItemError(kind, name, known)
    return row


def _writable(state: CatalogueState, row: ItemRow, team: str | None) -> None:
    if row.read_only:
        raise uploads.ForbiddenError(f"{row.kind} {row.name!r} is a shipped demo item (read-only)")
    if team is not None and row.team is not None and row.team != team:
        raise uploads.ForbiddenError(f"{row.kind} {row.name!r} belongs to another team")


def _busy(state: CatalogueState, row: ItemRow) -> None:
    active = state.db.jobs(item_id=row.id, states=("queued", "running"))
    if active:
        raise uploads.ConflictError(
            f"{row.kind} {row.name!r} is used by job {active[0].id} ({active[0].state}); "
            "wait for it to finish"
        )


@contextlib.contextmanager
def _incoming(state: CatalogueState, file: UploadFile, limit: int):
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
                    raise uploads.UploadTooLargeError(
                        f"file exceeds the upload limit of {limit} bytes"
                    )
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


def _text(value: str | None, field: str, max_len: int = 2000) -> str:
    value = (value or "").strip()
    if len(value) > max_len:
        raise InputError(f"{field} is longer than {max_len} characters")
    return value


# ------------------------------------------------------------------------------ routes


def _accepted(item, job_id: str, **extra) -> JSONResponse:
    """202 answer of an upload: the item, its job and where to follow it."""
    url = f"/v1/jobs/{job_id}"
    return JSONResponse(
        {"item": item.public(), "job": job_id, "job_url": url, **extra},
        status_code=202,
        headers={"Location": url},
    )


def mount(app: FastAPI) -> None:
    """Add the catalogue routes and the status codes of :mod:`app.uploads` errors."""
    from skisnow.app.api import problem

    statuses = {
        uploads.UnsupportedContentError: (415, "Unsupported Media Type"),
        uploads.ConflictError: (409, "Conflict"),
        uploads.ForbiddenError: (403, "Forbidden"),
        uploads.UnauthorizedError: (401, "Unauthorized"),
        uploads.UploadTooLargeError: (413, "Payload Too Large"),
        uploads.QuotaError: (429, "Too Many Requests"),
        NameTakenError: (409, "Conflict"),
    }
    for exc_class, (status, title) in statuses.items():

        async def _handler(request, exc, status=status, title=title):
            resp = problem(status, title, str(exc))
            if status == 401:
                resp.headers["WWW-Authenticate"] = "Bearer"
            if status == 429:
                resp.headers["Retry-After"] = str(exc.retry_after_s)
            return resp

        app.add_exception_handler(exc_class, _handler)

    @app.post("/v1/grinds", status_code=202, tags=["catalogue"], dependencies=[Depends(_multipart)])
    def post_grind(
        request: Request,
        team: Team,
        file: Annotated[
            UploadFile, File(description="topography: x3p, instrument files, .npy, .csv")
        ],
        name: Annotated[str, Form(min_length=1, max_length=64)],
        shop_code: Annotated[str, Form(max_length=64)] = "",
        machine: Annotated[str, Form(max_length=128)] = "",
        pattern_family: Annotated[str, Form(max_length=128)] = "",
        coarseness_grade: Annotated[str, Form(max_length=64)] = "",
        temperature_window: Annotated[str, Form(max_length=64)] = "",
        notes: Annotated[str, Form(max_length=2000)] = "",
        pixel_size_um: Annotated[float | None, Form(gt=0, le=1000)] = None,
        height_unit: Annotated[str | None, Form(max_length=8)] = None,
        along_ski: Annotated[Literal["x", "y"], Form()] = "x",
        periodic: Annotated[Literal["mirror", "window", "none"], Form()] = "mirror",
        detrend: Annotated[
            Literal["plane", "mean", "none"] | None,
            Form(
                description=(
                    "removed from the heights before the solve: plane (default), mean "
                    "(default with periodic=none) or none; recorded in the item's metadata"
                )
            ),
        ] = None,
    ) -> JSONResponse:
        """Upload a grind's topography: detrended and checked at once (ISO 25178 parameters in
        the answer); its table is built by a background job (``job`` → ``GET /v1/jobs/{id}``)."""
        state = _state(request)
        settings = request.app.state.settings
        # a taken name first (409), then the job quota (429), both before the file is read
        uploads.check_name_free(state.db, "grind", name)
        uploads.check_job_quota(state.db, team, _limits(request))
        meta = {
            "shop_code": _text(shop_code, "shop_code"),
            "machine": _text(machine, "machine"),
            "pattern_family": _text(pattern_family, "pattern_family"),
            "coarseness_grade": _text(coarseness_grade, "coarseness_grade"),
            "temperature_window": _text(temperature_window, "temperature_window"),
            "notes": _text(notes, "notes"),
        }
        with _incoming(state, file, settings.max_upload_bytes) as path:
            item, job_id, iso = uploads.accept_grind(
                state.db,
                state.layout,
                settings,
                upload_path=path,
                filename=file.filename or "upload",
                name=name,
                metadata=meta,
                pixel_size_um=pixel_size_um,
                height_unit=height_unit,
                along_ski=along_ski,
                periodic=periodic,
                detrend=detrend,
                team=team,
                limits=_limits(request),
            )
        state.runner.wake()
        return _accepted(item, job_id, iso25178=iso)

    @app.post("/v1/skis", status_code=202, tags=["catalogue"], dependencies=[Depends(_multipart)])
    def post_ski(
        request: Request,
        team: Team,
        file: Annotated[UploadFile, File(description="neutral camber CSV")],
        name: Annotated[str, Form(min_length=1, max_length=64)],
        length_mm: Annotated[float, Form(gt=0, description="ski length [mm]")],
        width_mm: Annotated[str, Form(description="running-surface width [mm]: one or a list")],
        width_positions_mm: Annotated[str | None, Form()] = None,
        style: Annotated[Literal["classic", "skate"], Form()] = "classic",
        brand_model: Annotated[str, Form(max_length=128)] = "",
        owner_team: Annotated[str, Form(max_length=64)] = "",
        notes: Annotated[str, Form(max_length=2000)] = "",
    ) -> JSONResponse:
        """Upload a ski's camber measurements: validated at once (line-numbered errors; data
        too sparse for the accuracy check are refused); its network is trained by a job."""
        state = _state(request)
        settings = request.app.state.settings
        # a taken name first (409), then the job quota (429), both before the file is read
        uploads.check_name_free(state.db, "ski", name)
        uploads.check_job_quota(state.db, team, _limits(request))
        meta = {
            "brand_model": _text(brand_model, "brand_model"),
            "style": style,
            "owner_team": _text(owner_team, "owner_team") or (team or ""),
            "notes": _text(notes, "notes"),
        }
        with _incoming(state, file, settings.max_upload_bytes) as path:
            item, job_id, figures = uploads.accept_ski(
                state.db,
                state.layout,
                data=path.read_bytes(),
                filename=file.filename or "upload",
                name=name,
                metadata=meta,
                length_mm=length_mm,
                width_mm=width_mm,
                width_positions_mm=width_positions_mm,
                team=team,
                limits=_limits(request),
            )
        state.runner.wake()
        return _accepted(item, job_id, data=figures)

    @app.get("/v1/jobs/{job_id}", tags=["catalogue"])
    def get_job(request: Request, job_id: str, who: Reader) -> dict:
        """A background job: state (queued, running, done, failed), progress 0..1, errors
        (another team's job is 404)."""
        state = _state(request)
        job = state.db.job(job_id)
        item = state.db.item(job.item_id) if job is not None and job.item_id else None
        if job is None or (item is not None and not who.sees(item.team, item.read_only)):
            return problem(404, "Unknown job", f"no job {job_id!r}")
        return _job_view(state.db, job)

    @app.get("/v1/jobs", tags=["catalogue"])
    def list_jobs(request: Request, who: Reader) -> dict:
        """The 100 most recent jobs (with team tokens: those the caller's team may see)."""
        state = _state(request)
        jobs = state.db.jobs(by_team=who.teams_on, team=who.team)
        return {"jobs": [_job_view(state.db, j) for j in jobs]}

    for kind, plural in (("ski", "skis"), ("grind", "grinds")):
        _item_routes(app, kind, plural)


def _item_routes(app: FastAPI, kind: str, plural: str) -> None:
    @app.get(f"/v1/{plural}/{{name}}", tags=["catalogue"], name=f"show_{kind}")
    def show(request: Request, name: str, who: Reader) -> dict:
        """One item: state, metadata, file and its jobs; for a usable ski also its profile model
        (name and why) and its beam: EI(X), c(X) with their bands, the misfit per case and the
        held-out check (the ski's page ``/skis/{name}`` shows the same)."""
        state = _state(request)
        row = _item_or_404(state, kind, name, who)
        if row.state == "ready":
            state.live.catch_up(kind, name)
        cat = request.app.state.catalogue
        out = {
            **row.public(),
            "usable": name in getattr(cat, plural),
            "jobs": [_job_view(state.db, j) for j in state.db.jobs(item_id=row.id)],
        }
        if kind == "ski" and name in cat.skis:
            out["profile_model"] = profile_report(cat.skis[name])
            out["beam"] = beam_report(cat.skis[name])
        return out

    @app.patch(f"/v1/{plural}/{{name}}", tags=["catalogue"], name=f"rename_{kind}")
    def rename(request: Request, name: str, body: RenameBody, team: Team) -> dict:
        """Rename an uploaded item (shipped items are read-only)."""
        state = _state(request)
        row = _item_or_404(state, kind, name, _writer(request, team))
        _writable(state, row, team)
        new = uploads.check_name(body.name)
        with state.live.lock:
            row = state.db.update_item(row.id, name=new)
            state.live.rename(row)
        return row.public()

    @app.delete(f"/v1/{plural}/{{name}}", tags=["catalogue"], status_code=204, name=f"del_{kind}")
    def delete(request: Request, name: str, team: Team) -> Response:
        """Delete an uploaded item and its files (409 while a job uses it)."""
        state = _state(request)
        row = _item_or_404(state, kind, name, _writer(request, team))
        _writable(state, row, team)
        _busy(state, row)
        with state.live.lock:
            state.live.drop(row.id)
            state.db.delete_item(row.id)
        state.layout.remove_item_files(row.id)
        return Response(status_code=204)
