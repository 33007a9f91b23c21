"""Named accuracy presets of /v1/contact: validation, provenance, documented agreement."""

from __future__ import annotations

import typing
from dataclasses import replace
from pathlib import Path

import pytest
from conftest import CONTACT_BODY
from fastapi.testclient import TestClient
from skisnow.app import service
from skisnow.app.bounds import PresetName
from skisnow.app.main import create_app
from skisnow.app.presets import DEFAULT_PRESET, PRESETS, get_preset
from skisnow.app.settings import Settings
from skisnow.solvers.errors import InputError
from skisnow.solvers.macro import DEFAULT_PIXEL_ACROSS, DEFAULT_PIXEL_ALONG_M

BODY = CONTACT_BODY
#: the metrics the presets' documented errors cover (the minimum average separation does not
#: converge with the macro grid where it sits at a short tip/tail contact: docs/benchmarks.md)
METRICS = (
    ("apparent", "contact_area_cm2"),
    ("metrics", "total_real_contact_area_mm2"),
    ("metrics", "average_real_contact_pressure_mpa"),
    ("metrics", "total_reciprocal_separation_m"),
)


@pytest.fixture(scope="module")
def client(catalogue):
    app = create_app(Settings(), catalogue=catalogue)
    with TestClient(app, raise_server_exceptions=False) as c:
        yield c


def test_schema_names_are_the_presets():
    assert set(typing.get_args(PresetName)) == set(PRESETS)
    assert DEFAULT_PRESET in PRESETS
    for name, p in PRESETS.items():
        assert p.name == name and p.pixel_along_m > 0 and p.pixels_across >= 1


def test_default_preset_is_the_solver_default_grid():
    """The default preset keeps the answers of requests that name no preset."""
    p = PRESETS[DEFAULT_PRESET]
    assert (p.pixel_along_m, p.pixels_across) == (DEFAULT_PIXEL_ALONG_M, DEFAULT_PIXEL_ACROSS)


@pytest.mark.parametrize("path", ["/v1/contact", "/v1/compare"])
def test_unknown_preset_is_422_naming_the_field(client, path):
    body = dict(BODY, preset="ultra")
    if path == "/v1/compare":
        body = dict(body, skis=["ski-a"], grinds=["tiny-grind"])
        del body["ski"], body["grind"]
    r = client.post(path, json=body)
    assert r.status_code == 422, r.text
    problem = r.json()
    assert [e["field"] for e in problem["errors"]] == ["preset"]
    assert "fast" in problem["detail"] and "fine" in problem["detail"]


def test_unknown_preset_in_the_service_names_the_field(catalogue):
    inp = service.ContactInputs("ski-a", "tiny-grind", 40, -160, 200, 0.5, preset="ultra")
    with pytest.raises(InputError, match="preset must be one of fast, default, fine"):
        service.contact(catalogue, inp)
    with pytest.raises(InputError, match="preset"):
        get_preset(None)  # type: ignore[arg-type]


@pytest.mark.parametrize("name", list(PRESETS))
def test_provenance_reports_preset_and_pixel_sizes(client, name):
    r = client.post("/v1/contact", json=dict(BODY, preset=name))
    assert r.status_code == 200, r.text
    ans = r.json()
    prov = ans["provenance"]["preset"]
    p = PRESETS[name]
    assert ans["inputs"]["preset"] == name
    assert prov["name"] == name
    assert prov["macro_pixel_along_mm"] == pytest.approx(p.pixel_along_m * 1e3)
    assert prov["macro_pixels_across"] == p.pixels_across
    assert prov["macro_pixel_size_mm"][0] == pytest.approx(p.pixel_along_m * 1e3)
    assert prov["macro_pixel_size_mm"] == ans["provenance"]["macro"]["pixel_size_mm"]
    width_mm = max(client.get("/v1/skis").json()["skis"][0]["width_mm"])
    assert prov["macro_pixel_size_mm"][1] == pytest.approx(width_mm / p.pixels_across)
    assert prov["texture_pixel_size_um"] == pytest.approx(1.0)  # the fixture table: 1 µm
    assert prov["grid_band_90"] == p.grid_band


def test_no_preset_means_default(client):
    a = client.post("/v1/contact", json=BODY).json()
    b = client.post("/v1/contact", json=dict(BODY, preset="default")).json()
    assert a["metrics"] == b["metrics"] and a["provenance"]["preset"]["name"] == "default"


@pytest.fixture(scope="module")
def shipped_catalogue(catalogue):
    """The fixture skis with the shipped grind-1 table (the documented errors are for it)."""
    from skisnow.app.storage.tables import read_table

    path = Path(catalogue.tables_dir) / "grind-1.h5"
    cat = replace(catalogue, grinds=dict(catalogue.grinds))
    cat.grinds["grind-1"] = service.Grind("grind-1", path, "0" * 64, read_table(path))
    return cat


@pytest.mark.parametrize("ski", ["ski-a", "ski-b"])
@pytest.mark.parametrize("coarse", ["default", "fast"])
def test_presets_agree_with_fine_within_documented_error(shipped_catalogue, ski, coarse):
    """Each preset is within its documented error of the reference; so two presets differ by
    at most the sum of their documented errors (papers' case, shipped table)."""
    inp = service.ContactInputs(ski, "grind-1", 40, -160, 200, 0.5)
    fine = service.contact(shipped_catalogue, replace(inp, preset="fine"))
    other = service.contact(shipped_catalogue, replace(inp, preset=coarse))
    bound = PRESETS[coarse].max_rel_error + PRESETS["fine"].max_rel_error
    for group, key in METRICS:
        rel = other[group][key] / fine[group][key] - 1
        assert abs(rel) <= bound, (key, rel, bound)
