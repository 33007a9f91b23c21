"""Bounds of every number a user can ask for: one source for the API, the CLI and the web form.

As numbers (:class:`Bound`: the ends, open or closed, and the unit) and as the pydantic model of
one case's inputs (:class:`CaseInputs`: load, snow, base, preset, ski model), which the API's
bodies extend (:mod:`app.api.models`) and the web form validates with.

The REST models (:mod:`app.api.models`, and through them ``skisnow solve`` and the web form),
``skisnow macro`` and ``skisnow flex`` (checked before the solve, :meth:`Bound.contains`) and
the flex pages read these; a CLI user cannot ask for what the service refuses. Units are
technician units, in the names (kg, mm, MPa, -). These are the limits of the inputs, not of
the model: a ski's camber model covers a narrower load and position range of its own
(:attr:`app.service.Ski.load_range_n`), checked by the service with a 422.

Imports nothing from the rooms of app/ (anyone in app/ may import it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator
from skisnow.app.snow import SNOW_PRESETS, SnowName

__all__ = [
    "BASE_MODULUS_MPA",
    "BODY_WEIGHT_KG",
    "LOAD_KG",
    "LOAD_POSITION_MM",
    "POISSON_RATIO",
    "POROSITY",
    "SNOW_MODULUS_MPA",
    "Bound",
    "CaseInputs",
    "PresetName",
    "SkiModelName",
    "out_of_bounds_message",
]


@dataclass(frozen=True)
class Bound:
    """An interval of accepted values of one input.

    ``low_open``/``high_open``: the end itself is refused (``gt``/``lt`` instead of
    ``ge``/``le``). ``unit`` is written after values in messages ("" for dimensionless).
    Whole-number ends are ints, so that schemas, messages and the form's ``min``/``max``
    attributes read ``150``, not ``150.0``.
    """

    name: str
    low: int | float
    high: int | float
    unit: str = ""
    low_open: bool = False
    high_open: bool = False

    def field(self) -> dict[str, int | float]:
        """Keyword arguments of :func:`pydantic.Field` / ``fastapi.Query`` (``gt``/``ge``,
        ``lt``/``le``)."""
        return {
            "gt" if self.low_open else "ge": self.low,
            "lt" if self.high_open else "le": self.high,
        }

    def text(self) -> str:
        """The interval in words, e.g. ``(0, 150] kg``."""
        lo, hi = "(" if self.low_open else "[", ")" if self.high_open else "]"
        return f"{lo}{self.low:g}, {self.high:g}{hi}" + (f" {self.unit}" if self.unit else "")

    def contains(self, value: float) -> bool:
        """True when ``value`` is a finite number inside the interval."""
        if not math.isfinite(value):
            return False
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and below

    def check(self, value: float, name: str | None = None) -> float:
        """``value`` if inside, else ``ValueError`` naming the input and the interval."""
        if not self.contains(value):
            raise ValueError(f"{name or self.name} must be in {self.text()}, got {value:g}")
        return value


#: equivalent load on one ski [kg] (the service's limit; a skier's full weight on one ski)
LOAD_KG = Bound("load_kg", 0, 150, "kg", low_open=True)
#: load position from the balance point, positive towards the tip [mm]
LOAD_POSITION_MM = Bound("load_position_mm", -1000, 1000, "mm")
#: Young's modulus of the snow [MPa]
SNOW_MODULUS_MPA = Bound("snow_modulus_mpa", 1, 2000, "MPa")
#: snow porosity n = 1 − ρ/917 [-]
POROSITY = Bound("porosity", 0, 1, high_open=True)
#: Young's modulus of the ski base [MPa]
BASE_MODULUS_MPA = Bound("base_modulus_mpa", 1, 20000, "MPa")
#: Poisson's ratio of snow and base [-]
POISSON_RATIO = Bound("poisson_ratio", 0, 0.5, high_open=True)
#: skier's body weight of the flex sheet [kg]
BODY_WEIGHT_KG = Bound("body_weight_kg", 0, 300, "kg", low_open=True)


#: every bound by its input name
BOUNDS: dict[str, Bound] = {
    b.name: b
    for b in (
        LOAD_KG,
        LOAD_POSITION_MM,
        SNOW_MODULUS_MPA,
        POROSITY,
        BASE_MODULUS_MPA,
        POISSON_RATIO,
        BODY_WEIGHT_KG,
    )
}

#: what an input is, in a technician's words, where the bare interval does not say it
_WHAT = {
    "porosity": "a fraction, 0 for solid ice up to below 1 (a groomed track is about 0.5)",
    "poisson_ratio": "a fraction below 0.5 (0.3 for snow and polyethylene)",
}


def out_of_bounds_message(name: str, value: float | None = None) -> str:
    """A plain-words message for an input outside its bound (instead of pydantic's "Input
    should be less than 1"): the interval in words and, where the input is a fraction typed as
    a percentage (porosity 50), what was probably meant. Names without a bound get a generic
    message."""
    bound = BOUNDS.get(name)
    if bound is None:
        return "is outside the accepted range"
    unit = f" {bound.unit}" if bound.unit else ""
    lo, hi = f"{bound.low:g}", f"{bound.high:g}"
    text = {
        (False, False): f"must be from {lo} to {hi}{unit}",
        (False, True): f"must be from {lo} to below {hi}{unit}",
        (True, False): f"must be more than {lo} and at most {hi}{unit}",
        (True, True): f"must be more than {lo} and below {hi}{unit}",
    }[bound.low_open, bound.high_open]
    if name in _WHAT:
        text += f": it is {_WHAT[name]}"
    if value is not None and math.isfinite(value):
        text += f"; got {value:g}{unit}"
        if name in _WHAT and 1 < value <= 100 and bound.contains(value / 100):
            text += f" — if you meant {value:g} %, enter {value / 100:g}"
    return text


#: names of :data:`app.presets.PRESETS` (checked equal in tests/service/test_presets.py)
PresetName = Literal["fast", "default", "fine"]
_PRESET_DOC = (
    "accuracy preset: fast (8 mm × 4), default (4 mm × 8), fine (1 mm × 16) macro pixels; "
    "see docs/benchmarks.md"
)


SkiModelName = Literal["rigid", "flexible", "auto"]
_SKI_MODEL_DOC = (
    "rigid: the ski keeps its loaded shape on the measuring device's flat (the papers' model); "
    "flexible: the ski bends on the snow (beam and snow solved together, docs/physics.md §4b); "
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
SNOW_DOC = (
    "snow by type and temperature (app/snow.py, docs/snow.md): its modulus and porosity fill "
    "snow_modulus_mpa and porosity where those are not given; "
    + "; ".join(
        f"{p.name}: {p.snow_modulus_mpa:g} MPa, n = {p.porosity:g}" for p in SNOW_PRESETS.values()
    )
)


def fill_snow(data):
    """``data`` (a request's fields) with ``snow_modulus_mpa`` and ``porosity`` taken from the
    snow preset it names, where they are missing or None; anything else unchanged (an unknown
    name is left for the field's own check)."""
    if not isinstance(data, dict):
        return data
    name = data.get("snow")
    if not isinstance(name, str) or name not in SNOW_PRESETS:  # a list is unhashable: a 422
        return data
    p = SNOW_PRESETS[name]
    out = dict(data)
    for key, value in (("snow_modulus_mpa", p.snow_modulus_mpa), ("porosity", p.porosity)):
        if out.get(key) is None:
            out[key] = value
    return out


class CaseInputs(BaseModel):
    """Load, snow, base and discretisation of one case (shared by contact and compare)."""

    model_config = ConfigDict(extra="forbid")

    load_kg: float = Field(..., **LOAD_KG.field(), description=LOAD_DOC, examples=[40])
    load_position_mm: float = Field(
        ..., **LOAD_POSITION_MM.field(), examples=[-160], description=POSITION_DOC
    )
    snow: SnowName | None = Field(None, description=SNOW_DOC, examples=["fine-grained"])
    snow_modulus_mpa: float = Field(
        ...,
        **SNOW_MODULUS_MPA.field(),
        description=SNOW_MODULUS_DOC + " (default: the snow preset's)",
        examples=[200],
    )
    porosity: float = Field(
        ...,
        **POROSITY.field(),
        description=POROSITY_DOC + " (default: the snow preset's)",
        examples=[0.5],
    )
    base_modulus_mpa: float = Field(700.0, **BASE_MODULUS_MPA.field(), description=BASE_MODULUS_DOC)
    poisson_ratio: float = Field(0.3, **POISSON_RATIO.field(), description=POISSON_DOC)
    preset: PresetName = Field("default", description=_PRESET_DOC)
    ski_model: SkiModelName = Field("auto", description=_SKI_MODEL_DOC)

    @model_validator(mode="before")
    @classmethod
    def _snow_preset(cls, data):
        """A named snow fills the snow numbers not given (given ones are kept: the answer's
        ``inputs.snow`` says which number is whose)."""
        return fill_snow(data)
