"""The service room: what one answer needs, without HTTP, files of the caller or jobs.

- :mod:`.catalogue` — the skis and grinds the service answers for (shipped tables, demo skis);
- :mod:`.answer` — one contact computation per request (macro solve, table interpolation,
  warnings, band, provenance);
- :mod:`.band` — the error band of an answer; :mod:`.profiles` — a ski's profile model;
- :mod:`.flex` — the flex sheet, pair and ranking; :mod:`.reports` — a ski's model report;
- :mod:`.rounding` — number lists of the JSON answers.

May import: ``storage``, :mod:`skisnow.solvers` and the shared top-level modules of ``app``
(settings, units, presets, bounds). Never ``api``, ``web``, ``jobs`` or ``commands``.

The names below are the room's interface to the layers above (``from skisnow.app import
service``; ``service.contact(...)``). Modules inside the room import each other by their own
module paths, never through this package, so that the room has no import circle.
"""

from skisnow.app.service.answer import (
    ContactInputs,
    auto_uses_flexible,
    contact,
    loaded_profile,
    pixel_error_estimate,
    resolved_min_separation,
    result_warnings,
    rigid_minus_flexible,
    warm_up,
)
from skisnow.app.service.catalogue import (
    AUTO_RIGID_TOLERANCE,
    BEAM_LOAD_FACTOR,
    SKI_MODELS,
    Catalogue,
    Grind,
    ModelUnavailableError,
    Ski,
    UnknownItemError,
    load_catalogue,
)
from skisnow.app.service.reports import HELD_OUT_COMPUTED, beam_report, profile_report
from skisnow.app.storage.common import code_version

__all__ = [
    "AUTO_RIGID_TOLERANCE",
    "BEAM_LOAD_FACTOR",
    "HELD_OUT_COMPUTED",
    "SKI_MODELS",
    "Catalogue",
    "ContactInputs",
    "Grind",
    "ModelUnavailableError",
    "Ski",
    "UnknownItemError",
    "auto_uses_flexible",
    "beam_report",
    "code_version",
    "contact",
    "load_catalogue",
    "loaded_profile",
    "pixel_error_estimate",
    "profile_report",
    "resolved_min_separation",
    "result_warnings",
    "rigid_minus_flexible",
    "warm_up",
]
