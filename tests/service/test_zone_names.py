"""Contact zones are named by their position along the ski, whatever the load (issue #28: two
zones were called "front", and the zone under the foot was "mid" at 70 kg but "rear" at 40 kg)."""

from __future__ import annotations

from types import SimpleNamespace

from skisnow.app.service.answer import zone_names


def _zones(*spans_mm):
    return [SimpleNamespace(start_m=a / 1e3, end_m=b / 1e3) for a, b in spans_mm]


def test_names_follow_the_balance_point_not_the_load():
    # the foot zone spans a load at -150 mm but its middle lies behind the balance point
    assert zone_names(_zones((-338, -122), (334, 406))) == ["rear", "front"]


def test_several_zones_on_one_side_are_numbered_from_the_tail():
    zones = _zones((700, 720), (-300, -200), (380, 430))  # not in order along the ski
    assert zone_names(zones) == ["front 2", "rear", "front 1"]
    assert len(set(zone_names(zones))) == len(zones)


def test_the_foot_zone_keeps_its_name_from_40_to_70_kg(catalogue):
    from skisnow.app import service

    names = {}
    for load_kg in (40, 70):
        inp = service.ContactInputs(
            ski="ski-b",
            grind="tiny-grind",
            load_kg=load_kg,
            load_position_mm=-150,
            snow_modulus_mpa=200,
            porosity=0.5,
            ski_model="rigid",
        )
        answer = service.contact(catalogue, inp)
        zones = answer["apparent"]["zones"]
        foot = min(zones, key=lambda z: abs(0.5 * (z["start_mm"] + z["end_mm"]) + 150))
        names[load_kg] = foot["name"]
    assert names[40] == names[70] == "rear"
