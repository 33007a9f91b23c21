"""``skisnow report paper-case``: files written, numbers equal to the service's answers."""

from __future__ import annotations

import json
import math

import pytest
from skisnow.app.cli import build_parser
from skisnow.app.commands import report as report_command
from skisnow.app.evidence import paper_case as report
from skisnow.app.evidence.paper_case_write import write_paper_case
from skisnow.app.service import ContactInputs, contact, load_catalogue
from skisnow.app.settings import Settings
from skisnow.solvers.errors import InputError, NotConvergedError

SWEEP = (100.0, 200.0)  # reduced E_snow sweep [MPa]
LOADS = (20.0, 40.0)  # reduced load checks [kg]


@pytest.fixture(scope="module")
def cat():
    return load_catalogue(Settings().tables_dir)


@pytest.fixture(scope="module")
def written(cat, tmp_path_factory):
    out = tmp_path_factory.mktemp("docs")
    md = write_paper_case(cat, out, progress=False, snow_moduli_mpa=SWEEP, load_check_kg=LOADS)
    return out, md


def _metric_table(text: str, title: str, unit: str) -> dict[str, list[str]]:
    """Rows ``{ski: [cell per grind]}`` of the 2 × 2 table under ``**title [unit]**``."""
    block = text.split(f"**{title} [{unit}]**", 1)[1].strip().splitlines()
    rows = {}
    for line in block[2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows[cells[0]] = cells[1:]
    return rows


def test_writes_markdown_figures_and_json(written):
    out, md = written
    assert md == out / "paper-case.md"
    text = md.read_text(encoding="utf-8")
    fig_dir = out / "paper-case"
    figures = sorted(p.name for p in fig_dir.glob("*.svg"))
    assert figures == sorted(
        [
            "band.svg",
            "pressure.svg",
            "clearance.svg",
            "real-area.svg",
            "separation.svg",
            "reciprocal.svg",
            "zone-pressure-vs-modulus.svg",
            "real-area-vs-pressure.svg",
        ]
    )
    for name in figures:
        svg = (fig_dir / name).read_text(encoding="utf-8")
        assert svg.startswith("<?xml") and "<svg" in svg and svg.rstrip().endswith("</svg>")
        assert f"](paper-case/{name})" in text, f"{name} not linked from the report"
    data = json.loads((fig_dir / "paper-case.json").read_text(encoding="utf-8"))
    assert data["schema"] == "skisnow.paper-case/1"
    assert {r["snow_modulus_mpa"] for r in data["zone_pressure_sweep"]} == set(SWEEP)
    # no temporary files left behind by the atomic writes
    assert not list(out.rglob("*.part"))


def test_markdown_states_inputs_choices_published_and_provenance(written, cat):
    _out, md = written
    text = md.read_text(encoding="utf-8")
    for needle in (
        "| snow porosity n | 0.5 (−) | **our choice**",
        "Synthetic stand-ins",
        "| ski-a | 63.98 |",  # published apparent area, docs/physics.md §4
        "| 61.4 |",  # published mean apparent pressure of ski-a
        "| ski-b | 121.84 |",
        "## Findings of docs/physics.md §8, measured",
        "git commit",
    ):
        assert needle in text, needle
    for g in report.GRINDS:
        assert cat.grind(g).sha256 in text
    for s in report.SKIS:
        assert cat.ski(s).sha256 in text


def test_two_by_two_tables_equal_the_service_answers(written, cat):
    out, md = written
    text = md.read_text(encoding="utf-8")
    data = json.loads((out / "paper-case" / "paper-case.json").read_text(encoding="utf-8"))
    stored = {(r["inputs"]["ski"], r["inputs"]["grind"]): r["metrics"] for r in data["results"]}
    for key, title, unit in report.METRICS:
        table = _metric_table(text, title, unit)
        assert sorted(table) == sorted(report.SKIS)
        for s in report.SKIS:
            for j, g in enumerate(report.GRINDS):
                inp = ContactInputs(s, g, 40.0, -160.0, 200.0, 0.5, ski_model="rigid")
                expected = contact(cat, inp)["metrics"][key]
                assert table[s][j] == f"{report.fmt(expected)} {unit}", (s, g, key)
                assert stored[(s, g)][key] == pytest.approx(expected, rel=1e-9)


def test_findings_are_measured_verdicts(written):
    out, md = written
    data = json.loads((out / "paper-case" / "paper-case.json").read_text(encoding="utf-8"))
    findings = data["findings"]
    assert len(findings) == 5
    text = md.read_text(encoding="utf-8")
    for f in findings:
        assert isinstance(f["holds"], bool)
        assert f["test"] and any(ch.isdigit() for ch in f["evidence"])  # measured numbers
        assert f["evidence"] in text


def test_load_checks_need_two_loads(cat):
    with pytest.raises(InputError, match="load_check_kg"):
        report.compute_paper_case(cat, snow_moduli_mpa=(200.0,), load_check_kg=(40.0,))


def test_zone_pressures_split_at_the_balance_point():
    result = {
        "apparent": {
            "zones": [
                {"start_mm": -800, "end_mm": -780, "length_mm": 20, "load_n": 10.0,
                 "load_share": 0.1, "apparent_area_cm2": 2.0},
                {"start_mm": -300, "end_mm": -100, "length_mm": 200, "load_n": 70.0,
                 "load_share": 0.7, "apparent_area_cm2": 18.0},
                {"start_mm": 300, "end_mm": 400, "length_mm": 100, "load_n": 20.0,
                 "load_share": 0.2, "apparent_area_cm2": 8.0},
            ]
        }
    }  # fmt: skip
    zp = report.zone_pressures(result)
    assert zp["rear"]["pieces"] == 2 and zp["front"]["pieces"] == 1
    assert zp["rear"]["load_n"] == pytest.approx(80.0)
    assert zp["rear"]["length_mm"] == pytest.approx(220.0)
    # 80 N over 20 cm² = 40 kPa; 20 N over 8 cm² = 25 kPa
    assert zp["rear"]["mean_pressure_kpa"] == pytest.approx(40.0)
    assert zp["front"]["mean_pressure_kpa"] == pytest.approx(25.0)
    assert zp["rear"]["load_share"] + zp["front"]["load_share"] == pytest.approx(1.0)
    # no front contact: NaN pressure, not a division error
    empty = report.zone_pressures({"apparent": {"zones": result["apparent"]["zones"][:2]}})
    assert empty["front"]["pieces"] == 0 and math.isnan(empty["front"]["mean_pressure_kpa"])


def test_a_failed_sweep_solve_is_reported_not_fatal(cat, tmp_path, monkeypatch):
    def flaky(c, inp):
        if inp.snow_modulus_mpa == 100.0:
            raise NotConvergedError("synthetic failure for the test")
        return contact(c, inp)

    monkeypatch.setattr(report, "contact", flaky)
    md = write_paper_case(cat, tmp_path, progress=False, snow_moduli_mpa=SWEEP, load_check_kg=LOADS)
    text = md.read_text(encoding="utf-8")
    assert "Failed solves" in text and "synthetic failure for the test" in text
    data = json.loads((tmp_path / "paper-case" / "paper-case.json").read_text(encoding="utf-8"))
    errors = [r for r in data["zone_pressure_sweep"] if r["error"]]
    assert {r["snow_modulus_mpa"] for r in errors} == {100.0}


def test_cli_registers_report_paper_case(tmp_path):
    args = build_parser().parse_args(
        ["report", "paper-case", "--out-dir", str(tmp_path), "--tables-dir", "tables"]
    )
    assert args.func is report_command.run
    assert str(args.out_dir) == str(tmp_path)
    defaults = build_parser().parse_args(["report", "paper-case"])
    assert defaults.out_dir.name == "docs" and defaults.tables_dir is None
