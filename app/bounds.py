"""Bounds of every number a user can ask for: one source for the API, the CLI and the web form.

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

__all__ = [
    "BASE_MODULUS_MPA",
    "BODY_WEIGHT_KG",
    "LOAD_KG",
    "LOAD_POSITION_MM",
    "POISSON_RATIO",
    "POROSITY",
    "SNOW_MODULUS_MPA",
    "Bound",
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
