"""The small exception hierarchy of skisnow.

Every error a user can cause derives from :class:`SkisnowError`; the web layer maps each class
to one HTTP status in a single handler.

- :class:`InputError` (also a ``ValueError``): an argument is out of its domain, NaN/inf, of the
  wrong shape or unit. The message names the offending parameter and value.
- :class:`OutOfRangeError`: a lookup outside the tabulated range (never extrapolated).
- :class:`DataFileError`: a file is missing, truncated, corrupt or of an unknown schema.
- :class:`NotConvergedError`: raised only where a caller asks for a converged answer
  (solvers themselves return ``converged=False`` instead of raising).
"""


class SkisnowError(Exception):
    """Base class of every skisnow error."""


class InputError(SkisnowError, ValueError):
    """An input value is invalid; the message names the parameter and the value."""


class OutOfRangeError(SkisnowError, ValueError):
    """A value lies outside the range covered by a table or model."""


class DataFileError(SkisnowError):
    """A data file is missing, unreadable, corrupt or of an unsupported schema."""


class NotConvergedError(SkisnowError):
    """A solve did not converge where a converged answer was required."""
