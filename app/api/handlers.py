"""Every exception a request can raise, answered as a problem body (:mod:`app.api.problems`).

One table maps the service's, the solver's and the uploads' errors to HTTP statuses: invalid
input 422 (``errors: [{field, reason}]`` where a field is named), unknown skis or grinds 404
with the known names, results outside the tables or non-converged solves 422 with what to
change, upload refusals 401/403/409/413/415/429, anything else 500 (logged, not shown).
"""

from __future__ import annotations

import logging

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from skisnow.app import service
from skisnow.app.api.problems import problem
from skisnow.app.errors import (
    ConflictError,
    ForbiddenError,
    QuotaError,
    UnauthorizedError,
    UnsupportedContentError,
    UploadTooLargeError,
)
from skisnow.app.storage.catalogue import NameTakenError
from skisnow.solvers.errors import InputError, NotConvergedError, OutOfRangeError, SkisnowError
from starlette.exceptions import HTTPException as StarletteHTTPException

__all__ = ["field_errors", "install"]

log = logging.getLogger(__name__)

#: refusals of the catalogue's changes (:mod:`app.jobs.uploads`): status and title
UPLOAD_STATUSES = {
    UnsupportedContentError: (415, "Unsupported Media Type"),
    ConflictError: (409, "Conflict"),
    ForbiddenError: (403, "Forbidden"),
    UnauthorizedError: (401, "Unauthorized"),
    UploadTooLargeError: (413, "Payload Too Large"),
    QuotaError: (429, "Too Many Requests"),
    NameTakenError: (409, "Conflict"),
}


def _named(exc: Exception) -> dict:
    """``errors: [{field, reason}]`` for a service error that names its request field."""
    field = getattr(exc, "field", None)
    return {"errors": [{"field": field, "reason": str(exc)}]} if field else {}


def field_errors(exc: RequestValidationError) -> list[dict]:
    """``[{field, reason}]`` of a request validation error (dotted field, no location)."""
    out = []
    for err in exc.errors():
        loc = [str(p) for p in err.get("loc", ()) if p not in ("body", "query", "path")]
        out.append({"field": ".".join(loc) or "body", "reason": err.get("msg", "invalid")})
    return out


def install(app: FastAPI) -> None:
    """Add the exception handlers to ``app``."""

    @app.exception_handler(RequestValidationError)
    async def _validation(request: Request, exc: RequestValidationError):
        errors = field_errors(exc)
        detail = "; ".join(f"{e['field']}: {e['reason']}" for e in errors)
        return problem(422, "Invalid input", detail, errors=errors)

    @app.exception_handler(StarletteHTTPException)
    async def _http(request: Request, exc: StarletteHTTPException):
        return problem(exc.status_code, str(exc.detail), str(exc.detail))

    @app.exception_handler(service.UnknownItemError)
    async def _unknown(request: Request, exc: service.UnknownItemError):
        field = getattr(exc, "field", exc.kind)
        return problem(404, f"Unknown {exc.kind}", str(exc), field=field, known=exc.known)

    @app.exception_handler(OutOfRangeError)
    async def _range(request: Request, exc: OutOfRangeError):
        return problem(422, "Outside the model's range", str(exc), **_named(exc))

    @app.exception_handler(NotConvergedError)
    async def _nc(request: Request, exc: NotConvergedError):
        return problem(422, "Solver did not converge", str(exc))

    @app.exception_handler(InputError)
    async def _input(request: Request, exc: InputError):
        return problem(422, "Invalid input", str(exc), **_named(exc))

    @app.exception_handler(SkisnowError)
    async def _other(request: Request, exc: SkisnowError):
        return problem(422, "Cannot compute this case", str(exc))

    @app.exception_handler(Exception)
    async def _internal(request: Request, exc: Exception):
        log.exception("internal error on %s", request.url.path)
        return problem(500, "Internal Server Error", "an internal error occurred; it was logged")

    for exc_class, (status, title) in UPLOAD_STATUSES.items():

        async def _refused(request, exc, status=status, title=title):
            resp = problem(status, title, str(exc))
            if status == 401:
                resp.headers["WWW-Authenticate"] = "Bearer"
            if status == 429:
                resp.headers["Retry-After"] = str(exc.retry_after_s)
            return resp

        app.add_exception_handler(exc_class, _refused)
