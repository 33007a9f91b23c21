"""The technician's flex sheet, pair matching and a skier's best ski (issue #14; docs/flex.md).

- :mod:`.sheet` — one ski's sheet: profile models, range checks, pocket, closing load, kick
  share on the flat and on snow, band, JSON in technician units;
- :mod:`.compare` — pair matching, ranking, and the CSV of each.

The names below are the interface the API, the web pages and ``skisnow flex`` use
(``from skisnow.app.service import flex``; ``flex.flex_sheet_answer(...)``).
"""

from skisnow.app.service.flex.compare import (
    flex_pair,
    flex_ranking,
    pair_csv,
    ranking_csv,
    sheet_csv,
)
from skisnow.app.service.flex.sheet import (
    CRITERIA,
    PAIR_LOAD_POSITION_MM,
    FlexRequest,
    compute_sheet,
    field_error,
    flex_sheet_answer,
)

__all__ = [
    "CRITERIA",
    "PAIR_LOAD_POSITION_MM",
    "FlexRequest",
    "compute_sheet",
    "field_error",
    "flex_pair",
    "flex_ranking",
    "flex_sheet_answer",
    "pair_csv",
    "ranking_csv",
    "sheet_csv",
]
