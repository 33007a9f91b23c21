"""Problem bodies (RFC 9457, ``application/problem+json``): the one way errors leave the service.

:func:`problem` renders one; :class:`Problem` is its schema, declared in OpenAPI for every
error a route can send (:func:`responses`, :func:`add_to_openapi`). Used by the API's routes and
handlers, by the write guard of :mod:`app.api.access` and free for the web pages. Imports nothing
from app/ (web may import it without importing the API's routes).
"""

from __future__ import annotations

from http import HTTPStatus
from typing import Any

from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field
from pydantic.json_schema import models_json_schema

__all__ = [
    "COMMON",
    "MEDIA_TYPE",
    "FieldError",
    "Problem",
    "add_to_openapi",
    "problem",
    "responses",
]

MEDIA_TYPE = "application/problem+json"


class FieldError(BaseModel):
    """One request field and what is wrong with it."""

    model_config = ConfigDict(extra="forbid")
    field: str = Field(..., description="the field, dotted for nested ones (body: the body)")
    reason: str


class Problem(BaseModel):
    """An error answer (RFC 9457). ``errors`` names the offending fields of invalid input;
    an unknown ski or grind has ``field`` and the ``known`` names."""

    model_config = ConfigDict(extra="forbid")
    type: str = Field(..., description="always about:blank: the status says it all")
    status: int = Field(..., description="the HTTP status code")
    title: str
    detail: str = Field(..., description="what went wrong, and what to change")
    # present only where they apply (absent, not null, elsewhere)
    errors: list[FieldError] | None = Field(None, description="invalid fields (422)")
    field: str | None = Field(None, description="the request field naming an unknown item")
    known: list[str] | None = Field(None, description="the names that exist (404 of an item)")


def problem(status: int, title: str, detail: str, **extra) -> JSONResponse:
    """A problem answer with ``status``; ``extra`` are further members (``errors``, ...)."""
    body = {"type": "about:blank", "status": status, "title": title, "detail": detail, **extra}
    return JSONResponse(body, status_code=status, media_type=MEDIA_TYPE)


#: why each status is sent, as written in the OpenAPI description of the route's answers
WHY = {
    400: "Bad Request: an invalid Content-Length",
    401: "Unauthorized: a change without a valid team bearer token (team tokens set)",
    403: "Forbidden: a cross-origin change, a shipped (read-only) item or another team's",
    404: "Not Found: an unknown ski, grind or job (the known names are listed)",
    409: "Conflict: the name is taken, or a job still uses the item",
    413: "Payload Too Large: the body exceeds the service's limit",
    415: "Unsupported Media Type: not multipart, or a file whose content is not its format",
    422: "Invalid input (errors name the fields), outside the model's range, or not converged",
    429: "Too Many Requests: the job quota is full (Retry-After)",
    500: "Internal Server Error: logged; the answer says no more",
    503: "Not ready: the catalogue is not loaded",
}


#: what any request can be answered with: a bad or too large Content-Length (the body limit
#: checks every request), an internal error
COMMON = (400, 413, 500)


def responses(*statuses: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses=`` of a route: each of ``statuses`` and :data:`COMMON` answered with
    a :class:`Problem`."""
    ref = {"$ref": f"#/components/schemas/{Problem.__name__}"}
    return {
        s: {
            "description": WHY.get(s, HTTPStatus(s).phrase),
            "content": {MEDIA_TYPE: {"schema": ref}},
        }
        for s in sorted({*statuses, *COMMON})
    }


def add_to_openapi(schema: dict) -> dict:
    """Add :class:`Problem` (and :class:`FieldError`) to the OpenAPI components that
    :func:`responses` refers to; FastAPI adds only the schemas of models it is given."""
    _, defs = models_json_schema(
        [(Problem, "serialization")], ref_template="#/components/schemas/{model}"
    )
    schema.setdefault("components", {}).setdefault("schemas", {}).update(defs["$defs"])
    return schema
