"""The README's example answer against the live answer (issue #28: the README quoted a real area
of 49.73 mm² while the service answered 48.38, outside the answer's own band).

The curl request of the README's "REST" block is posted to the service on the shipped tables;
every number of the abridged answer below it must lie inside the live answer's 90 % band (zone
ends within two macro pixels). When a change moves the answer beyond its band, re-measure and
update the README block.
"""

from __future__ import annotations

import copy
import json
import re
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from skisnow.app.main import create_app
from skisnow.app.settings import Settings

README = Path(__file__).resolve().parents[2] / "README.md"


def readme_example() -> tuple[dict, dict]:
    """The request body of the README's curl example and the abridged answer shown below it."""
    text = README.read_text(encoding="utf-8")
    body = re.search(r"curl -s \S+/v1/contact .*?-d '(\{.*?\})'", text, re.S)
    answer = re.search(r"answers \(abridged.*?```json\n(.*?)\n```", text, re.S)
    assert body and answer, "README: the /v1/contact example or its answer block is missing"
    return json.loads(body.group(1)), json.loads(answer.group(1))


def drift(shown: dict, live: dict) -> list[str]:
    """The README numbers outside the live answer's band, each as one line (empty: in band)."""
    out = []
    band = live["band"]["intervals"]
    rel = live["band"]["relative_half_width"]

    def check(where: str, value: float, lo: float, hi: float) -> None:
        if not lo <= value <= hi:
            out.append(f"{where}: README {value:g}, live band [{lo:.4g}, {hi:.4g}]")

    for key, value in shown["metrics"].items():
        check(f"metrics.{key}", value, *band[key])
    for key in ("contact_area_cm2", "mean_pressure_kpa"):
        check(f"apparent.{key}", shown["apparent"][key], *band[key])
    for key in ("load_n", "effective_modulus_mpa"):
        check(
            f"inputs.{key}",
            shown["inputs"][key],
            *(live["inputs"][key] * (1 + d) for d in (-1e-3, 1e-3)),
        )
    zones, live_zones = shown["apparent"]["zones"], live["apparent"]["zones"]
    if [z["name"] for z in zones] != [z["name"] for z in live_zones]:
        out.append(
            f"zones: README {[z['name'] for z in zones]}, live {[z['name'] for z in live_zones]}"
        )
        return out
    pixel_mm = live["provenance"]["preset"]["macro_pixel_size_mm"][0]
    for z, lz in zip(zones, live_zones, strict=True):
        name = z["name"]
        for key in ("start_mm", "end_mm", "length_mm"):
            check(f"zone {name} {key}", z[key], lz[key] - 2 * pixel_mm, lz[key] + 2 * pixel_mm)
        check(f"zone {name} load_n", z["load_n"], *lz["load_band_90_n"])
        w = (lz["load_band_90_n"][1] - lz["load_band_90_n"][0]) / 2
        check(
            f"zone {name} load_share",
            z["load_share"],
            *(lz["load_share"] + s * w / live["inputs"]["load_n"] for s in (-1, 1)),
        )
        a = lz["apparent_area_cm2"]
        check(
            f"zone {name} apparent_area_cm2",
            z["apparent_area_cm2"],
            *(a * (1 + s * rel["apparent_contact_area"]) for s in (-1, 1)),
        )
        r = lz["real_area_mm2"]
        check(
            f"zone {name} real_area_mm2",
            z["real_area_mm2"],
            *(r * (1 + s * rel["total_real_contact_area"]) for s in (-1, 1)),
        )
    return out


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    body, shown = readme_example()
    settings = Settings(data_dir=tmp_path_factory.mktemp("data"), warm_up=False)
    with TestClient(create_app(settings)) as client:
        r = client.post("/v1/contact", json=body)
    assert r.status_code == 200, r.text[:500]
    return body, shown, r.json()


def test_the_readme_example_answer_is_inside_the_live_band(example):
    body, shown, live = example
    assert shown["inputs"]["ski"] == body["ski"] and shown["inputs"]["grind"] == body["grind"]
    assert drift(shown, live) == []


def test_the_check_fails_when_the_readme_drifts_beyond_the_band(example):
    _, shown, live = example
    stale = copy.deepcopy(shown)
    stale["metrics"]["total_real_contact_area_mm2"] = 49.73  # the README's value before #28
    assert any("total_real_contact_area_mm2" in line for line in drift(stale, live))
    moved = copy.deepcopy(shown)
    moved["apparent"]["zones"][0]["start_mm"] += 20.0
    assert any("start_mm" in line for line in drift(moved, live))
    renamed = copy.deepcopy(shown)
    renamed["apparent"]["zones"][0]["name"] = "mid"
    assert drift(renamed, live)
