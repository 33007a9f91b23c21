"""Request bodies of the REST API (pydantic); every number has bounds and a unit in its name."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

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


class ContactBody(BaseModel):
    """Body of ``POST /v1/contact``."""

    model_config = ConfigDict(extra="forbid")

    ski: str = Field(..., min_length=1, max_length=64, examples=["ski-a"])
    grind: str = Field(..., min_length=1, max_length=64, examples=["grind-1"])
    load_kg: float = Field(..., gt=0, le=150, description="equivalent load [kg]", examples=[40])
    load_position_mm: float = Field(
        ...,
        ge=-1000,
        le=1000,
        examples=[-160],
        description="load position from the balance point, positive towards the tip [mm]",
    )
    snow_modulus_mpa: float = Field(
        ..., ge=1, le=2000, description="Young's modulus of the snow [MPa]", examples=[200]
    )
    porosity: float = Field(
        ..., ge=0, lt=1, description="snow porosity n = 1 − ρ/917 [-]", examples=[0.5]
    )
    base_modulus_mpa: float = Field(
        700.0, ge=1, le=20000, description="Young's modulus of the ski base [MPa]"
    )
    poisson_ratio: float = Field(0.3, ge=0, lt=0.5, description="Poisson's ratio [-]")
    preset: PresetName = Field("default", description=_PRESET_DOC)
    ski_model: SkiModelName = Field("auto", description=_SKI_MODEL_DOC)


class CompareBody(BaseModel):
    """Body of ``POST /v1/compare``: the same as contact with lists of skis and grinds."""

    model_config = ConfigDict(extra="forbid")

    skis: list[str] = Field(..., min_length=1, max_length=16, examples=[["ski-a", "ski-b"]])
    grinds: list[str] = Field(..., min_length=1, max_length=16, examples=[["grind-1", "grind-2"]])
    load_kg: float = Field(..., gt=0, le=150, examples=[40])
    load_position_mm: float = Field(..., ge=-1000, le=1000, examples=[-160])
    snow_modulus_mpa: float = Field(..., ge=1, le=2000, examples=[200])
    porosity: float = Field(..., ge=0, lt=1, examples=[0.5])
    base_modulus_mpa: float = Field(700.0, ge=1, le=20000)
    poisson_ratio: float = Field(0.3, ge=0, lt=0.5)
    preset: PresetName = Field("default", description=_PRESET_DOC)
    ski_model: SkiModelName = Field("auto", description=_SKI_MODEL_DOC)
