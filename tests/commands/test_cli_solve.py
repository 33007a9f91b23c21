"""``skisnow solve``: one case on the command line, the same answer as ``POST /v1/contact``."""

from __future__ import annotations

import json

import pytest
from skisnow.app import service
from skisnow.app.cli import main

CASE = [
    "solve",
    "--ski",
    "ski-a",
    "--grind",
    "grind-1",
    "--load-kg",
    "40",
    "--load-position-mm",
    "-160",
    "--snow-modulus-mpa",
    "200",
    "--porosity",
    "0.5",
]


@pytest.fixture(scope="module")
def shipped():
    from skisnow.app.settings import Settings

    return service.load_catalogue(Settings().tables_dir)


def test_json_answer_equals_the_service(capsys, shipped):
    assert main([*CASE, "--json", "--preset", "fast"]) == 0
    out = json.loads(capsys.readouterr().out)
    ref = service.contact(
        shipped,
        service.ContactInputs(
            ski="ski-a",
            grind="grind-1",
            load_kg=40,
            load_position_mm=-160,
            snow_modulus_mpa=200,
            porosity=0.5,
            preset="fast",
        ),
    )
    assert out["metrics"] == ref["metrics"]
    assert out["provenance"]["preset"]["name"] == "fast"


def test_text_output_has_units_and_warnings(capsys):
    assert main([*CASE[:-1], "0.95"]) == 0
    text = capsys.readouterr().out
    assert "mm²" in text and "MPa" in text and "µm" in text
    assert "WARNING porosity_near_one" in text


def test_text_output_prints_the_band_as_served(capsys, shipped):
    """The band after each value is the served interval's reach: −w % below, +w / (1 − w) %
    above (symmetric in log), or ± w % where both agree to 0.1 %."""
    assert main([*CASE, "--json"]) == 0
    band = json.loads(capsys.readouterr().out)["band"]
    rel = band["relative_half_width"]
    assert main(CASE) == 0
    text = capsys.readouterr().out
    w = rel["apparent_contact_area"]
    lo, hi = f"{100 * w:.1f}", f"{100 * w / (1 - w):.1f}"
    assert lo != hi  # a band of a few % already differs at 0.1 %
    (line,) = [x for x in text.splitlines() if x.strip().startswith("apparent contact area")]
    assert line.endswith(f"−{lo} % / +{hi} %")
    # the studied tail after the apparent values, its numbers the answer's
    tail = band["studied_tail"]
    far_lo, far_hi = tail["contact_area_cm2_at_farthest"]
    assert f"studied tail: {100 * tail['outside_share']:.1f} % of {tail['answers']} answers" in text
    assert f"{far_lo:.4g} … {far_hi:.4g} cm² that far" in text


def test_text_output_prints_the_soft_snow_band_one_sided(capsys):
    """On soft snow the apparent area's band reaches further below (its grid part is a bias):
    −w % / +w_a / (1 − w_a) %, and the mean apparent pressure's the same sides swapped."""
    soft = [*CASE]
    soft[soft.index("--snow-modulus-mpa") + 1] = "20"
    soft[soft.index("--ski") + 1] = "ski-b"
    assert main([*soft, "--json", "--preset", "fast"]) == 0
    b = json.loads(capsys.readouterr().out)["band"]
    w = b["relative_half_width"]["apparent_contact_area"]
    wa = b["relative_half_width_above"]["apparent_contact_area"]
    assert b["grid_above_share"] == 0.0 and wa < w
    assert main([*soft, "--preset", "fast"]) == 0
    lines = capsys.readouterr().out.splitlines()
    (area,) = [x for x in lines if x.strip().startswith("apparent contact area")]
    (pressure,) = [x for x in lines if x.strip().startswith("mean apparent pressure")]
    assert area.endswith(f"−{100 * w:.1f} % / +{100 * wa / (1 - wa):.1f} %")
    assert pressure.endswith(f"−{100 * wa:.1f} % / +{100 * w / (1 - w):.1f} %")


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (("--porosity", "1.5"), "--porosity"),
        (("--ski", "nope"), "unknown ski 'nope'"),
        (("--load-position-mm", "900"), "outside the range"),
    ],
)
def test_user_mistakes_are_one_line_errors(capsys, change, message):
    argv = list(CASE)
    i = argv.index(change[0])
    argv[i + 1] = change[1]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
