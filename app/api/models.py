"""Request bodies of the REST API (pydantic); every number has bounds and a unit in its name.

The inputs of one ski × grind case are written once, in :class:`app.bounds.CaseInputs` (shared
with the CLI and the web form): ``POST /v1/contact`` adds one ski and one grind,
``POST /v1/compare`` lists of them.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field
from skisnow.app.bounds import CaseInputs

__all__ = ["CompareBody", "ContactBody", "RenameBody"]


class _OneSkiOneGrind(BaseModel):
    ski: str = Field(..., min_length=1, max_length=64, examples=["ski-a"])
    grind: str = Field(..., min_length=1, max_length=64, examples=["grind-1"])


class _SkisAndGrinds(BaseModel):
    skis: list[str] = Field(..., min_length=1, max_length=16, examples=[["ski-a", "ski-b"]])
    grinds: list[str] = Field(..., min_length=1, max_length=16, examples=[["grind-1", "grind-2"]])


# The item fields are a second base: pydantic puts the fields of later bases first, so a body
# lists (and its validation errors name) the skis and grinds before the case, as ever.


class ContactBody(CaseInputs, _OneSkiOneGrind):
    """Body of ``POST /v1/contact``: one ski, one grind and the case."""


class CompareBody(CaseInputs, _SkisAndGrinds):
    """Body of ``POST /v1/compare``: the case for every ski × grind combination."""


class RenameBody(BaseModel):
    """Body of ``PATCH /v1/skis/{name}`` and ``PATCH /v1/grinds/{name}``."""

    model_config = ConfigDict(extra="forbid")
    name: str = Field(..., min_length=1, max_length=64, examples=["my-ski-2025"])
