"""Request bodies of the REST API (pydantic); every number has bounds and a unit in its name.

The bounds are those of :mod:`app.bounds` (shared with the CLI and the web form). The inputs of
one ski × grind case are written once, in :class:`CaseInputs`: ``POST /v1/contact`` adds one ski
and one grind, ``POST /v1/compare`` lists of them.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field
from skisnow.app import bounds

__all__ = [
    "CaseInputs",
    "CompareBody",
    "ContactBody",
    "PresetName",
    "RenameBody",
    "SkiModelName",
]

#: names of :data:`app.presets.PRESETS` (checked equal in tests/test_presets.py)
PresetName = Literal["fast", "default", "fine"]
_PRESET_DOC = (
    "accuracy preset: fast (8 mm × 4), default (4 mm × 8), fine (1 mm × 16) macro pixels; "
    "see docs/benchmarks.md"
)


SkiModelName = Literal["rigid", "flexible", "auto"]
_SKI_MODEL_DOC = (
    "rigid: the ski keeps its loaded shape on the measuring device's flat (the papers' model); "
    "flexible: the ski bends on the snow (beam and snow solved together, method.md §4b); "
    "auto: rigid where it is within 2 % of flexible in apparent area, rear load share and the "
    "four metrics, flexible elsewhere. provenance.ski_model says which was used and why."
)

#: descriptions of the bounded numbers (API, flex routes and web form show the same words)
LOAD_DOC = "equivalent load [kg]"
POSITION_DOC = "load position from the balance point, positive towards the tip [mm]"
SNOW_MODULUS_DOC = "Young's modulus of the snow [MPa]"
POROSITY_DOC = "snow porosity n = 1 − ρ/917 [-]"
BASE_MODULUS_DOC = "Young's modulus of the ski base [MPa]"
POISSON_DOC = "Poisson's ratio [-]"


class CaseInputs(BaseModel):
    """Load, snow, base and discretisation of one case (shared by contact and compare)."""

    model_config = ConfigDict(extra="forbid")

    load_kg: float = Field(..., **bounds.LOAD_KG.field(), description=LOAD_DOC, examples=[40])
    load_position_mm: float = Field(
        ..., **bounds.LOAD_POSITION_MM.field(), examples=[-160], description=POSITION_DOC
    )
    snow_modulus_mpa: float = Field(
        ..., **bounds.SNOW_MODULUS_MPA.field(), description=SNOW_MODULUS_DOC, examples=[200]
    )
    porosity: float = Field(
        ..., **bounds.POROSITY.field(), description=POROSITY_DOC, examples=[0.5]
    )
    base_modulus_mpa: float = Field(
        700.0, **bounds.BASE_MODULUS_MPA.field(), description=BASE_MODULUS_DOC
    )
    poisson_ratio: float = Field(0.3, **bounds.POISSON_RATIO.field(), description=POISSON_DOC)
    preset: PresetName = Field("default", description=_PRESET_DOC)
    ski_model: SkiModelName = Field("auto", description=_SKI_MODEL_DOC)


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
