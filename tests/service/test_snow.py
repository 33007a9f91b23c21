"""Snow by type and temperature (#28): the presets, and one answer through form, API and CLI."""

from __future__ import annotations

import csv
import io
import json
import math
import re
import typing

import pytest
from fastapi.testclient import TestClient
from skisnow.app.api.models import ContactBody
from skisnow.app.cli import main
from skisnow.app.main import create_app
from skisnow.app.settings import Settings
from skisnow.app.snow import (
    DEFAULT_SNOW,
    ICE_DENSITY_KG_M3,
    SNOW_PRESETS,
    SnowName,
    modulus_scapozza_mpa,
    modulus_sigrist_mpa,
)

CASE = {"ski": "ski-a", "grind": "grind-1", "load_kg": 40, "load_position_mm": -160}


def test_schema_names_are_the_presets():
    assert set(typing.get_args(SnowName)) == set(SNOW_PRESETS)
    assert DEFAULT_SNOW in SNOW_PRESETS


@pytest.mark.parametrize("name", sorted(SNOW_PRESETS))
def test_preset_numbers_follow_their_references(name):
    p = SNOW_PRESETS[name]
    assert p.reference
    assert p.density_range_kg_m3[0] <= p.density_kg_m3 <= p.density_range_kg_m3[1]
    assert p.modulus_range_mpa[0] <= p.snow_modulus_mpa <= p.modulus_range_mpa[1]
    assert p.porosity == pytest.approx(1 - p.density_kg_m3 / ICE_DENSITY_KG_M3, abs=5e-4)
    if name != "study":  # the papers' value is not from a density relation
        assert p.snow_modulus_mpa == pytest.approx(modulus_sigrist_mpa(p.density_kg_m3), rel=0.05)
        assert "Sigrist" in p.reference


def test_density_relations_at_known_points():
    # Sigrist: E = 968 MPa at ice density; Scapozza at 0 kg/m³ is its prefactor
    assert modulus_sigrist_mpa(ICE_DENSITY_KG_M3) == pytest.approx(968.0)
    assert modulus_scapozza_mpa(0.0) == pytest.approx(0.1873)
    # harder snow types are stiffer
    order = ["new-cold", "new-mild", "fine-grained", "coarse-old", "artificial", "icy"]
    moduli = [SNOW_PRESETS[n].snow_modulus_mpa for n in order]
    assert moduli == sorted(moduli) and len(set(moduli)) == len(moduli)


def test_named_snow_fills_only_missing_numbers():
    b = ContactBody(**CASE, snow="icy")
    assert (b.snow_modulus_mpa, b.porosity) == (440.0, SNOW_PRESETS["icy"].porosity)
    b = ContactBody(**CASE, snow="icy", porosity=0.3)
    assert (b.snow_modulus_mpa, b.porosity) == (440.0, 0.3)
    with pytest.raises(ValueError, match="snow_modulus_mpa"):
        ContactBody(**CASE)


@pytest.fixture(scope="module")
def shipped_client():
    with TestClient(create_app(Settings()), raise_server_exceptions=False) as c:
        yield c


def test_unknown_snow_is_a_problem_naming_the_field(shipped_client):
    r = shipped_client.post("/v1/contact", json={**CASE, "snow": "slush"})
    assert r.status_code == 422
    assert r.headers["content-type"].startswith("application/problem+json")
    assert "snow" in r.text and "fine-grained" in r.text


@pytest.mark.parametrize("snow", [[], {}, 3, ["study"]])
def test_a_snow_that_is_not_a_name_is_a_problem(shipped_client, snow):
    """Not a 500 (the fuzz run sent ``"snow": []``: the preset lookup hashed a list)."""
    for path in ("/v1/contact", "/v1/compare"):
        body = {**CASE, "snow": snow}
        if path == "/v1/compare":
            body = {
                **{k: v for k, v in body.items() if k not in ("ski", "grind")},
                "skis": [CASE["ski"]],
                "grinds": [CASE["grind"]],
            }
        r = shipped_client.post(path, json=body)
        assert r.status_code == 422, (path, r.status_code, r.text[:300])
        assert r.headers["content-type"].startswith("application/problem+json")


def test_one_answer_through_form_api_and_cli(shipped_client, capsys):
    """A snow preset gives the same answer through the form, the API and the CLI (#28)."""
    snow = "new-cold"
    p = SNOW_PRESETS[snow]
    api = shipped_client.post("/v1/contact", json={**CASE, "snow": snow, "preset": "fast"})
    assert api.status_code == 200, api.text
    a = api.json()
    assert a["inputs"]["snow_modulus_mpa"] == p.snow_modulus_mpa
    assert a["inputs"]["porosity"] == p.porosity
    assert a["inputs"]["snow"]["name"] == snow
    assert a["inputs"]["snow"]["numbers_given_instead_of_the_preset"] == {}

    assert main(["solve", *_cli_case(), "--snow", snow, "--preset", "fast", "--json"]) == 0
    cli = json.loads(capsys.readouterr().out)
    assert cli["metrics"] == a["metrics"]
    assert cli["inputs"]["snow"] == a["inputs"]["snow"]

    # the form: the snow select only (its number fields are disabled, so not sent)
    q = {**CASE, "snow": snow, "preset": "fast"}
    page = shipped_client.get("/results", params=q)
    assert page.status_code == 200, page.text[:2000]
    table = shipped_client.get("/results.csv", params=q)
    assert table.status_code == 200, table.text[:2000]
    rows = list(csv.DictReader(io.StringIO(table.text.lstrip("\ufeff"))))
    assert len(rows) == 1
    area = a["metrics"]["total_real_contact_area_mm2"]
    # the CSV writes 7 significant digits
    assert float(rows[0]["total_real_contact_area_mm2"]) == pytest.approx(area, rel=1e-6)
    assert float(rows[0]["snow_modulus_mpa"]) == p.snow_modulus_mpa
    assert rows[0]["snow"] == snow
    assert p.label in page.text  # the results page names the snow
    # a different snow gives a different answer (the test can fail)
    other = shipped_client.post("/v1/contact", json={**CASE, "snow": "icy", "preset": "fast"})
    assert not math.isclose(other.json()["metrics"]["total_real_contact_area_mm2"], area)


def _cli_case() -> list[str]:
    out = []
    for k, v in CASE.items():
        out += [f"--{k.replace('_', '-')}", str(v)]
    return out


def test_form_defaults_to_the_default_snow(shipped_client):
    page = shipped_client.get("/").text
    m = re.search(r'<option value="([^"]*)"[^>]*selected[^>]*>', page[page.index('id="snow"') :])
    assert m and m.group(1) == DEFAULT_SNOW
    # an old link with numbers and no snow stays custom: the numbers are used as given
    r = shipped_client.get(
        "/results",
        params={**CASE, "snow_modulus_mpa": 150, "porosity": 0.4, "preset": "fast"},
    )
    assert r.status_code == 200


def test_answers_with_a_snow_match_their_response_models(shipped_client):
    from skisnow.app.api.responses import ContactAnswer, FlexSheet

    a = shipped_client.post("/v1/contact", json={**CASE, "snow": "icy", "porosity": 0.3}).json()
    ContactAnswer.model_validate(a)
    assert a["inputs"]["snow"]["numbers_given_instead_of_the_preset"] == {"porosity": 0.3}
    assert a["inputs"]["snow_modulus_mpa"] == 440.0 and a["inputs"]["porosity"] == 0.3
    r = shipped_client.get("/v1/skis/ski-c/flex", params={"body_weight_kg": 70, "snow": "icy"})
    assert r.status_code == 200, r.text[:500]
    sheet = r.json()
    FlexSheet.model_validate(sheet)
    assert sheet["inputs"]["snow_modulus_mpa"] == 440.0
    assert sheet["kick_zone"]["snow"]["snow_modulus_mpa"] == 440.0
    assert sheet["kick_zone"]["snow"]["target_full_weight_percent"] == [33, 50]


def test_every_page_defaults_to_the_same_snow(shipped_client):
    for url in ("/", "/flex", "/flex/pair", "/flex/ranking"):
        page = shipped_client.get(url).text
        select = page[page.index('id="snow"') :]
        select = select[: select.index("</select>")]
        m = re.search(r'<option value="([^"]*)"[^>]*selected', select)
        assert m and m.group(1) == DEFAULT_SNOW, url
