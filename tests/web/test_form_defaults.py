"""The form's defaults and labels (issue #28): it pre-checks a shipped item or the last ones
used, never an upload because its name sorts first, and labels uploads with their metadata."""

from __future__ import annotations

import hashlib
import re
import shutil
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from skisnow.app import service
from skisnow.app.main import create_app
from skisnow.app.settings import Settings

REPO = Path(__file__).resolve().parents[2]
CASE = {"load_kg": 40, "load_position_mm": -160, "snow_modulus_mpa": 200, "porosity": 0.5}


def _checked(html: str, kind: str) -> list[str]:
    return re.findall(rf'name="{kind}" value="([^"]+)" checked', html)


@pytest.fixture(scope="module")
def shop(catalogue, tmp_path_factory):
    """The demo catalogue plus a ready upload named ``Grind-1`` (it sorts before every shipped
    grind), with a shop's metadata."""
    data_dir = tmp_path_factory.mktemp("data")
    table = data_dir / "upload-grind-1.h5"
    shutil.copyfile(REPO / "tables" / "grind-1.h5", table)
    cat = service.Catalogue(
        tables_dir=catalogue.tables_dir, skis=dict(catalogue.skis), grinds=dict(catalogue.grinds)
    )
    app = create_app(Settings(data_dir=data_dir, warm_up=False, job_poll_s=3600), catalogue=cat)
    with TestClient(app) as client:
        app.state.uploads.db.add_item(
            "grind",
            "Grind-1",
            state="ready",
            file_path=str(table),
            sha256=hashlib.sha256(table.read_bytes()).hexdigest(),
            metadata={"shop_code": "S7", "machine": "Wintersteiger Micro"},
        )
        app.state.uploads.live.sync()
        assert "Grind-1" in app.state.catalogue.grinds
        yield client


def test_the_form_defaults_to_a_shipped_grind_not_the_first_name(shop):
    shop.cookies.clear()
    html = shop.get("/").text
    assert sorted(shop.app.state.catalogue.grinds)[0] == "Grind-1"  # sorts first
    assert _checked(html, "grind") == ["tiny-grind"] and _checked(html, "ski") == ["ski-a"]


def test_uploads_show_their_metadata(shop):
    html = shop.get("/").text
    row = html[html.index('value="Grind-1"') :].split("</label>")[0]
    assert "uploaded; shop S7; machine Wintersteiger Micro" in row
    shipped = html[html.index('value="tiny-grind"') :].split("</label>")[0]
    assert "uploaded" not in shipped


def test_the_form_defaults_to_the_last_ones_used(shop):
    shop.cookies.clear()
    r = shop.get("/results", params={"ski": "ski-b", "grind": "tiny-grind", **CASE})
    assert r.status_code == 200, r.text[:300]
    html = shop.get("/").text
    assert _checked(html, "ski") == ["ski-b"] and _checked(html, "grind") == ["tiny-grind"]
    # a query still wins over the cookie
    html = shop.get("/", params={"ski": "ski-a"}).text
    assert _checked(html, "ski") == ["ski-a"]
    # a remembered item that is gone falls back to the shipped default
    shop.cookies.set("skisnow_last", "ski%3Dgone-ski")
    assert _checked(shop.get("/").text, "ski") == ["ski-a"]


def test_results_label_the_upload_with_its_metadata(shop):
    html = shop.get("/results", params={"ski": "ski-a", "grind": "Grind-1", **CASE}).text
    assert "grind Grind-1: uploaded; shop S7; machine Wintersteiger Micro" in html
