"""The errors of the application's edges, one small hierarchy under
:class:`skisnow.solvers.errors.SkisnowError` (which holds the kernels' InputError,
DataFileError, OutOfRangeError, NotConvergedError): each is one HTTP status of the API and the
web pages (:mod:`app.api`), and a one-line message with exit status 2 on the command line.
"""

from __future__ import annotations

from skisnow.solvers.errors import SkisnowError

__all__ = [
    "ConflictError",
    "ForbiddenError",
    "QuotaError",
    "UnauthorizedError",
    "UnsupportedContentError",
    "UploadTooLargeError",
]


class UnsupportedContentError(SkisnowError):
    """The upload's bytes are not what its kind or name promises (HTTP 415)."""


class ConflictError(SkisnowError):
    """A name is taken, or the item is used by a job (HTTP 409)."""


class ForbiddenError(SkisnowError):
    """A shipped read-only item, or another team's item (HTTP 403)."""


class UnauthorizedError(SkisnowError):
    """Teams are configured and the request has no valid bearer token (HTTP 401)."""


class UploadTooLargeError(SkisnowError):
    """The uploaded file exceeds ``max_upload_bytes`` (HTTP 413)."""


class QuotaError(SkisnowError):
    """Too many jobs queued or running, for the team or for the service (HTTP 429 with
    ``Retry-After: retry_after_s``)."""

    #: what the answer's ``Retry-After`` asks [s]: about the time a table build at the default
    #: settings takes on one worker, so that a retry is likely to find a free slot
    retry_after_s = 60
