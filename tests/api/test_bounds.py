"""One source of input bounds (app/bounds.py): the API, the CLI and the web form agree."""

from __future__ import annotations

import math

import pytest
from pydantic import ValidationError
from skisnow.app import bounds
from skisnow.app.api.models import ContactBody
from skisnow.app.cli import main

CASE = {"ski": "ski-a", "grind": "grind-1", "load_position_mm": -160, "porosity": 0.5}


def test_bound_ends_open_and_closed():
    b = bounds.Bound("x", 0, 1, "kg", low_open=True)
    assert not b.contains(0) and b.contains(1e-12) and b.contains(1) and not b.contains(1.0001)
    assert not b.contains(math.nan) and not b.contains(math.inf)
    assert b.text() == "(0, 1] kg" and b.field() == {"gt": 0, "le": 1}
    assert bounds.POROSITY.field() == {"ge": 0, "lt": 1} and bounds.POROSITY.text() == "[0, 1)"
    with pytest.raises(ValueError, match=r"x must be in \(0, 1\] kg, got 2"):
        b.check(2)


@pytest.mark.parametrize(
    ("flag", "key", "value"),
    [
        ("--load-kg", "load_kg", 180),  # the CLI took up to 200 kg, the API 150
        ("--snow-modulus-mpa", "snow_modulus_mpa", 5000),  # the CLI took up to 10 000 MPa
        ("--load-position-mm", "load_position_mm", -1200),  # the CLI took ±1500 mm
    ],
)
def test_macro_command_refuses_what_the_api_refuses(capsys, flag, key, value):
    args = {"--load-kg": "40", "--load-position-mm": "-160", "--snow-modulus-mpa": "200"}
    args[flag] = str(value)
    argv = ["macro", "--ski", "ski-a", *[x for kv in args.items() for x in kv]]
    assert main(argv) == 2
    assert f"{flag} must be in" in capsys.readouterr().err
    body = {**CASE, "load_kg": 40, "snow_modulus_mpa": 200, key: value}
    with pytest.raises(ValidationError, match=key):
        ContactBody(**body)


def test_flex_command_refuses_what_the_api_refuses(capsys):
    assert main(["flex", "--ski", "ski-a", "--body-weight-kg", "400"]) == 2
    assert "--body-weight-kg must be in (0, 300] kg" in capsys.readouterr().err
