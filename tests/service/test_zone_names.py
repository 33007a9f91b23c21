"""Contact zones are named by their position along the ski, whatever the load (issue #28: two
zones were called "front", and the zone under the foot was "mid" at 70 kg but "rear" at 40 kg)."""

from __future__ import annotations

from types import SimpleNamespace

from skisnow.app import service
from skisnow.app.service.answer import resolved_min_separation, zone_names

#: the ends of a 2 m footprint around the balance point [m]
ENDS = (-1.0, 1.0)


def _zones(*spans_mm):
    return [SimpleNamespace(start_m=a / 1e3, end_m=b / 1e3) for a, b in spans_mm]


def test_names_follow_the_position_not_the_load():
    # the foot zone spans a load at -150 mm but its middle lies behind the balance point
    assert zone_names(_zones((-338, -122), (334, 406)), *ENDS) == ["rear", "front"]
    # short tail and tip contacts at a light load do not rename the foot zone
    zones = _zones((-802, -794), (-330, -286), (694, 702))
    assert zone_names(zones, *ENDS) == ["tail", "rear", "tip"]


def test_several_zones_in_one_section_are_numbered_from_the_tail():
    zones = _zones((420, 440), (-300, -200), (100, 160))  # not in order along the ski
    assert zone_names(zones, *ENDS) == ["front 2", "rear", "front 1"]


def _answer(catalogue, load_kg: float) -> dict:
    inp = service.ContactInputs(
        ski="ski-b",
        grind="tiny-grind",
        load_kg=load_kg,
        load_position_mm=-150,
        snow_modulus_mpa=200,
        porosity=0.5,
        ski_model="rigid",
    )
    return service.contact(catalogue, inp)


def test_the_foot_zone_keeps_its_name_from_40_to_70_kg(catalogue):
    names = {}
    for load_kg in (40, 70):
        zones = _answer(catalogue, load_kg)["apparent"]["zones"]
        foot = min(zones, key=lambda z: abs(0.5 * (z["start_mm"] + z["end_mm"]) + 150))
        names[load_kg] = foot["name"]
    assert names[40] == names[70] == "rear"


def test_min_separation_over_the_resolved_zones_names_the_unresolved_one():
    zones = [
        {"name": "tail", "min_average_separation_um": 3.6, "unresolved": "it is 8 mm long"},
        {"name": "rear", "min_average_separation_um": 4.36, "unresolved": None},
        {"name": "tip", "min_average_separation_um": 3.5, "unresolved": "it is 8 mm long"},
        {"name": "front", "min_average_separation_um": 4.42, "unresolved": None},
    ]
    out = resolved_min_separation(zones)
    assert out["value_um"] == 4.36 and out["zone"] == "rear"
    assert [u["zone"] for u in out["unresolved"]] == ["tail", "tip"]
    assert resolved_min_separation(zones[:1])["value_um"] is None


def test_zone_minima_agree_with_the_answers_minimum(catalogue):
    answer = _answer(catalogue, 40)
    zones = answer["apparent"]["zones"]
    per_zone = [z["min_average_separation_um"] for z in zones]
    assert min(per_zone) == answer["metrics"]["min_average_separation_um"]
