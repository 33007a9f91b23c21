"""What an answer's band used to leave out (issue #26 point 4): the flat-base regime, ``auto``
without a beam, and the camber network's band across snow moduli; and the issue's rule that
every answer more than 3 % off lies inside its band or carries a warning."""

from __future__ import annotations

import functools
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from skisnow.app import service
from skisnow.app.presets import PRESETS
from skisnow.app.service import band, band_calibration
from skisnow.solvers.band import flat_stretch
from skisnow.solvers.beam import solve_beam_contact
from skisnow.solvers.errors import InputError
from skisnow.solvers.flexible import prepare_flexible, solve_flexible
from skisnow.solvers.macro import extrude_profile, solve_macro

ROOT = Path(__file__).resolve().parents[2]
TABLES = ROOT / "tables"


@pytest.fixture(scope="module")
def shipped():
    return service.load_catalogue(TABLES)


def _rigid_truth_area_cm2(rec, load_n, xf_m, e_eff_pa, preset="default"):
    """The answer of the ski's true (design) beam's loaded profile, on the answer's grid."""
    pre = PRESETS[preset]
    tr = solve_beam_contact(rec.beam, load_n, xf_m)
    gm = extrude_profile(
        tr.positions_m,
        tr.gap_m,
        rec.outline.width_m,
        width_positions_m=rec.outline.positions_m,
        pixel_along_m=pre.pixel_along_m,
        pixels_across=pre.pixels_across,
    )
    return solve_macro(gm, load_n, xf_m, e_eff_pa).apparent_contact_area_m2 * 1e4


def _area_and_interval(ans):
    a = ans["apparent"]["contact_area_cm2"]
    lo, hi = ans["band"]["intervals"]["contact_area_cm2"]
    return a, lo, hi


# ----------------------------------------------------------------------------- kernel


def test_flat_stretch_finds_the_longest_run_near_the_flat_and_tapers_its_weight():
    x = np.arange(-0.5, 0.5, 1e-3)
    g = np.full(x.size, 50e-6)
    g[(x > -0.3) & (x < -0.25)] = 0.5e-6  # 50 mm within 1 µm
    g[(x > 0.0) & (x < 0.1)] = 0.0  # 100 mm on the flat (contact)
    length, mid, w = flat_stretch(x, g, 1e-6, 0.02)
    assert length == pytest.approx(0.1, abs=2e-3)
    assert mid == pytest.approx(0.05, abs=2e-3)
    assert np.all(w[(x > 0.0) & (x < 0.1)] == 1.0)
    assert np.all(w[(x > -0.3) & (x < -0.25)] == 1.0)
    assert 0 < w[np.argmin(abs(x - 0.11))] < 1  # tapered beside the stretch
    assert w[np.argmin(abs(x - 0.2))] == 0.0  # and zero far from it
    assert flat_stretch(x, np.full(x.size, 1e-3), 1e-6, 0.02)[0] == 0.0
    with pytest.raises(InputError):
        flat_stretch(x, g[:-1], 1e-6, 0.02)


# ----------------------------------------------------------------------------- flat base

FLAT_CASES = [(10.0, 50.0), (12.0, 50.0)]


@pytest.mark.parametrize(("load_kg", "position_mm"), FLAT_CASES)
def test_demo_ski_b_flat_base_truth_is_inside_the_band_and_warned(shipped, load_kg, position_mm):
    """Demo ski-b, rigid, 200 MPa, grind-1 at +50 mm: its identified beam's answer is −14.1 %
    (10 kg) and −6.4 % (12 kg) off the true beam's; the band (±6.5 % and ±4.5 % before) now
    holds the truth, and the answer says it is in the flat-base regime."""
    ans = service.contact(
        shipped,
        service.ContactInputs(
            "ski-b", "grind-1", load_kg, position_mm, 200.0, 0.5, ski_model="rigid"
        ),
    )
    rec = shipped.ski("ski-b").record
    truth = _rigid_truth_area_cm2(
        rec,
        ans["inputs"]["load_n"],
        position_mm * 1e-3,
        ans["inputs"]["effective_modulus_mpa"] * 1e6,
    )
    a, lo, hi = _area_and_interval(ans)
    assert abs(a / truth - 1) > 0.03  # the case the issue measured: the answer is off
    assert lo <= truth <= hi, (lo, truth, hi)
    codes = [w["code"] for w in ans["warnings"]]
    assert "flat_base" in codes
    assert "flat_base" in ans["band"]["components"]
    assert any("flat-base regime" in t for t in ans["band"]["not_covered"])


def test_ordinary_answer_has_no_flat_base_part(shipped):
    """The papers' case of ski-a: its loaded base leaves the flat within ~12 mm, so no extra
    solves and no flat-base part; ski-b at 40 kg at +50 mm has the stretch, but the load
    presses through it (a 0.5 µm change moves the area by < 3 %): no warning either."""
    for name, kg, mm in (("ski-a", 40.0, -160.0), ("ski-b", 40.0, 50.0)):
        ans = service.contact(
            shipped, service.ContactInputs(name, "grind-1", kg, mm, 200, 0.5, ski_model="rigid")
        )
        assert "flat_base" not in ans["band"]["components"], name
        assert "flat_base" not in [w["code"] for w in ans["warnings"]], name


# ----------------------------------------------------------------------------- auto, no beam


def _network_only(cat, name):
    """The catalogue with ``name`` served by its camber network and no beam at all (an upload
    whose identification failed)."""
    ski = cat.ski(name)
    rec = replace(ski.record, identified=None, beam=None, cache={})
    return replace(cat, skis={**cat.skis, name: replace(ski, record=rec, _flexible={})})


@pytest.mark.parametrize("e_mpa", [20.0, 200.0, 2000.0])
@pytest.mark.parametrize("name", ["ski-a", "ski-b"])
def test_auto_without_a_beam_says_the_bending_is_ignored_and_its_band_holds_it(
    shipped, name, e_mpa
):
    """``auto`` for a ski without a beam answers with the rigid shape; its band holds the true
    bending ski (the demo ski's design beam bending on the snow, default grid) and says in
    not_covered and in a warning that the bending is ignored."""
    cat = _network_only(shipped, name)
    ans = service.contact(cat, service.ContactInputs(name, "grind-1", 40, -160, e_mpa, 0.5))
    assert ans["provenance"]["ski_model"]["used"] == "rigid"
    b = ans["band"]
    assert "ski_model" in b["components"]
    assert any(t.startswith("the ski's bending on the snow") for t in b["not_covered"])
    warn = {w["code"]: w["detail"] for w in ans["warnings"]}
    assert "ignores how the ski bends" in warn["flexible_unavailable"]
    rec = shipped.ski(name).record
    pre = PRESETS["default"]
    o = rec.outline
    model = prepare_flexible(
        rec.beam,
        o.width_m,
        pixel_along_m=pre.pixel_along_m,
        pixels_across=pre.pixels_across,
        width_positions_m=o.positions_m,
    )
    e = ans["inputs"]["effective_modulus_mpa"] * 1e6
    flex = solve_flexible(model, ans["inputs"]["load_n"], -0.16, e)
    truth = flex.apparent_contact_area_m2 * 1e4
    _a, lo, hi = _area_and_interval(ans)
    assert lo <= truth <= hi, (lo, truth, hi)


def test_auto_with_a_beam_is_unchanged(shipped):
    """With a beam ``auto`` compares and carries no bending-ignored part or words."""
    ans = service.contact(shipped, service.ContactInputs("ski-a", "grind-1", 40, -160, 200, 0.5))
    assert not any(t.startswith("the ski's bending") for t in ans["band"]["not_covered"])
    assert "flexible_unavailable" not in [w["code"] for w in ans["warnings"]]


def test_bending_ignored_width_follows_the_study_and_is_held_at_the_ends():
    from skisnow.solvers.elastic import effective_modulus

    w = band_calibration.BENDING_IGNORED_WIDTH["apparent_contact_area"]
    for e_mpa, expect in zip(band_calibration.BENDING_IGNORED_E_SNOW_MPA, w, strict=True):
        got = band_calibration.bending_ignored_widths(effective_modulus(e_mpa * 1e6, 700e6, 0.3))
        assert got["apparent_contact_area"] == pytest.approx(expect)
    low = band_calibration.bending_ignored_widths(effective_modulus(0.5e6, 700e6, 0.3))
    assert low["apparent_contact_area"] == pytest.approx(w[0])


def test_beam_scale_follows_its_nodes_and_is_held_at_the_ends():
    """The bending-ski answer's beam-draw factor: the calibrated node values at their snow
    moduli, between them linear in log E', beyond them the end values."""
    from skisnow.solvers.elastic import effective_modulus

    nodes = band_calibration.BEAM_SCALE_NODES
    e_nodes = band_calibration.BEAM_SCALE_E_SNOW_MPA
    for e_mpa, expect in zip(e_nodes, nodes, strict=True):
        got = band_calibration.beam_scale_at(effective_modulus(e_mpa * 1e6, 700e6, 0.3))
        assert got == pytest.approx(expect)
    assert band_calibration.beam_scale_at(effective_modulus(2e6, 700e6, 0.3)) == nodes[0]
    assert band_calibration.beam_scale_at(effective_modulus(20e9, 700e6, 0.3)) == nodes[-1]
    lo, hi = (effective_modulus(e * 1e6, 700e6, 0.3) for e in e_nodes[:2])
    mid = band_calibration.beam_scale_at(float(np.sqrt(lo * hi)))
    assert mid == pytest.approx(0.5 * (nodes[0] + nodes[1]))


@pytest.mark.parametrize("table", ["BEAM_SCALE_GRID_NODES", "IDENTIFIED_SIGMA_GRID_NODES"])
def test_per_grid_factors_follow_the_measurement_grid(table):
    """The identified beam's band factors per measurement grid: each grid's row at its number
    of loaded cases, between the grids linear in log(cases), beyond them held, and the larger
    row when the ski's cases are not known."""
    from skisnow.solvers.elastic import effective_modulus

    rows = getattr(band_calibration, table)
    e_nodes = (
        band_calibration.BEAM_SCALE_E_SNOW_MPA
        if table.startswith("BEAM")
        else band_calibration.IDENTIFIED_SIGMA_E_SNOW_MPA
    )
    at = (
        band_calibration.beam_scale_at
        if table.startswith("BEAM")
        else band_calibration.identified_sigma_scale_at
    )
    n_coarse, n_dense = band_calibration.GRID_CASES
    for j, e_mpa in enumerate(e_nodes):
        e = effective_modulus(e_mpa * 1e6, 700e6, 0.3)
        coarse, dense = rows[0][j], rows[1][j]
        assert at(e, n_coarse) == pytest.approx(coarse)
        assert at(e, n_dense) == pytest.approx(dense)
        assert at(e, 20) == pytest.approx(coarse) and at(e, 425) == pytest.approx(dense)
        mid = at(e, round(float(np.sqrt(n_coarse * n_dense))))
        assert min(coarse, dense) - 0.05 <= mid <= max(coarse, dense) + 0.05
        assert at(e) == pytest.approx(max(coarse, dense))
    # the envelope the flex sheet and skis of unknown grid take
    envelope = (
        band_calibration.BEAM_SCALE_NODES
        if table.startswith("BEAM")
        else band_calibration.IDENTIFIED_SIGMA_NODES
    )
    assert list(envelope) == [max(a, b) for a, b in zip(*rows, strict=True)]


def test_loaded_cases_counts_the_loaded_profiles_only():
    """The grid's size is the loaded cases: the unloaded profile is not a case of the grid."""
    from types import SimpleNamespace

    meas = SimpleNamespace(loads_n=np.array([0.0, 98.1, 98.1, 196.2]))
    assert band_calibration.loaded_cases(SimpleNamespace(measurements=meas)) == 3
    assert band_calibration.loaded_cases(SimpleNamespace(measurements=None)) is None


def test_flexible_area_grid_factor_follows_its_nodes_and_is_held_at_the_ends():
    """The bending-ski answer's apparent-area grid factor: the calibrated node values at their
    snow moduli, between them linear in log E', beyond them the end values."""
    from skisnow.solvers.elastic import effective_modulus

    nodes = band_calibration.FLEXIBLE_AREA_GRID_NODES
    e_nodes = band_calibration.FLEXIBLE_AREA_GRID_E_SNOW_MPA
    at = band_calibration.flexible_area_grid_factor_at
    for e_mpa, expect in zip(e_nodes, nodes, strict=True):
        assert at(effective_modulus(e_mpa * 1e6, 700e6, 0.3)) == pytest.approx(expect)
    assert at(effective_modulus(0.5e6, 700e6, 0.3)) == nodes[0]
    assert at(effective_modulus(20e9, 700e6, 0.3)) == nodes[-1]
    lo, hi = (effective_modulus(e * 1e6, 700e6, 0.3) for e in e_nodes[1:3])
    assert at(float(np.sqrt(lo * hi))) == pytest.approx(0.5 * (nodes[1] + nodes[2]))


@pytest.mark.parametrize("e_mpa", [5.0, 200.0])
def test_answers_report_their_grid_factors_and_use_them(shipped, e_mpa):
    """A bending-ski answer's band names its factors on the grid part (the apparent area's at
    its snow modulus) and its apparent-area grid part is that factor × K_END_PIXELS × its
    end-pixel share; a rigid answer's the same with the rigid factor at its snow modulus, its
    other quantities' grid parts not scaled."""
    from skisnow.solvers.band import end_pixel_share

    out = {}
    for model in ("flexible", "rigid"):
        req = service.ContactInputs("ski-a", "grind-1", 40, -160, e_mpa, 0.5, ski_model=model)
        ans = service.contact(shipped, req)
        e_eff = ans["inputs"]["effective_modulus_mpa"] * 1e6
        dx = ans["provenance"]["preset"]["macro_pixel_size_mm"][0] * 1e-3
        share = end_pixel_share([z["length_mm"] * 1e-3 for z in ans["apparent"]["zones"]], dx)
        out[model] = (ans["band"], share, e_eff)
    b, share, e_eff = out["flexible"]
    k = band_calibration.flexible_area_grid_factor_at(e_eff)
    assert b["macro_grid_factor"]["apparent_contact_area"] == pytest.approx(k, rel=1e-3)
    grid = b["components"]["macro_grid"]["apparent_contact_area"]
    assert grid == pytest.approx(k * band.K_END_PIXELS * share, rel=1e-3)
    b, share, e_eff = out["rigid"]
    k = band_calibration.rigid_area_grid_factor_at(e_eff)
    assert b["macro_grid_factor"] == {"apparent_contact_area": pytest.approx(k, rel=1e-3)}
    grid = b["components"]["macro_grid"]["apparent_contact_area"]
    assert grid == pytest.approx(k * band.K_END_PIXELS * share, rel=1e-3)
    assert (
        out["flexible"][0]["components"]["macro_grid"]["total_real_contact_area"]
        != (b["components"]["macro_grid"]["total_real_contact_area"])
    )  # the bending ski's real-area factor applies to it alone


def test_flexible_band_widens_its_beam_draws_with_the_snow_modulus(shipped):
    """The factor enters the answer: its band reports the factor at its modulus, and the same
    answer with the draws forced to another factor gets another camber part."""
    from functools import partial

    from skisnow.app.service import answer as answer_mod

    req = service.ContactInputs("ski-a", "grind-1", 40, -160, 2000, 0.5, ski_model="flexible")
    ans = service.contact(shipped, req)
    e_eff = ans["inputs"]["effective_modulus_mpa"] * 1e6
    got = ans["band"]["camber_model"]["beam_deviation_scale"]
    cases = band_calibration.loaded_cases(shipped.skis["ski-a"].record)
    assert got == pytest.approx(band_calibration.beam_scale_at(e_eff, cases))
    original = answer_mod.answer_band
    try:
        answer_mod.answer_band = partial(original, beam_scale=2 * got)
        wider = service.contact(shipped, req)["band"]
    finally:
        answer_mod.answer_band = original
    assert wider["camber_model"]["beam_deviation_scale"] == pytest.approx(2 * got)
    assert (
        wider["components"]["camber_model"]["apparent_contact_area"]
        > ans["band"]["components"]["camber_model"]["apparent_contact_area"]
    )


# ----------------------------------------------------------------------------- the rule

#: the rule's cases: (ski, served by, load kg, position mm) at each of RULE_MODULI_MPA
RULE_CASES = [
    # the camber network's fallback (the ski's identification left out), light to heavy
    *(
        (name, "network", kg, mm)
        for name in ("ski-a", "ski-b")
        for kg, mm in ((13.3, -25.0), (16.7, -25.0), (36.7, -250.0), (46.7, 25.0), (63.4, -50.0))
    ),
    # the identified beam at ski-b's light loads ahead of the balance point
    *(("ski-b", "identified", kg, 50.0) for kg in (10.0, 12.0, 15.0, 20.0)),
]
RULE_MODULI_MPA = (20.0, 200.0, 2000.0)


def _rule_catalogue(shipped, name, served):
    if served == "identified":
        return shipped
    ski = shipped.ski(name)
    rec = replace(ski.record, identified=None, cache={})
    return replace(shipped, skis={**shipped.skis, name: replace(ski, record=rec, _flexible={})})


@functools.cache
def _shipped():
    return service.load_catalogue(TABLES)


def _rule_rows(name, served, kg, mm) -> list[dict]:
    shipped = _shipped()
    cat = _rule_catalogue(shipped, name, served)
    rows = []
    for e_mpa in RULE_MODULI_MPA:
        ans = service.contact(
            cat, service.ContactInputs(name, "grind-1", kg, mm, e_mpa, 0.5, ski_model="rigid")
        )
        assert ans["provenance"]["ski"]["profile_model"] == (
            "network" if served == "network" else "identified_beam"
        )
        truth = _rigid_truth_area_cm2(
            cat.ski(name).record,
            ans["inputs"]["load_n"],
            mm * 1e-3,
            ans["inputs"]["effective_modulus_mpa"] * 1e6,
        )
        a, lo, hi = _area_and_interval(ans)
        rows.append(
            {
                "case": (name, served, kg, mm, e_mpa),
                "error": a / truth - 1,
                "inside": lo <= truth <= hi,
                "warnings": [w["code"] for w in ans["warnings"]],
            }
        )
    return rows


#: the one case of RULE_CASES that breaks the rule (strict xfail)
RULE_KNOWN_FAILURE = ("ski-b", "network", 13.3, -25.0)


@pytest.mark.slow
@pytest.mark.parametrize(
    "case",
    [
        pytest.param(
            c,
            marks=pytest.mark.xfail(
                strict=True,
                reason="NETWORK-SOFT-SNOW: ski-b's camber network at 13.3 kg, -25 mm, 20 MPa is "
                "-4.4 % off against a ±3.1 % band with no warning (camber part 2.7 % at σ × 1.5, "
                "grid 1.5 %; its 159 mm flat stretch moves the area by less than ±3 % on soft "
                "snow: no flat-base part; at 1 µm it would be ±2.2 %, still short). A network "
                "error the held-out σ does not show; × 3 would cover it at 3.4× the RMS error "
                "(docs/limits.md, the camber network across snow moduli)",
            ),
        )
        if c == RULE_KNOWN_FAILURE
        else c
        for c in RULE_CASES
    ],
    ids=lambda c: f"{c[0]}-{c[1]}-{c[2]:g}kg-{c[3]:g}mm",
)
def test_every_answer_more_than_3_percent_off_is_inside_its_band_or_warned(case):
    """Issue #26's rule on the rigid answers of the network fallback and of ski-b's identified
    beam at light loads, each at 20, 200 and 2000 MPa, against the true beam's profile on the
    answer's grid: an answer more than 3 % off lies inside its band or carries a warning."""
    rows = _rule_rows(*case)
    broken = [r for r in rows if abs(r["error"]) > 0.03 and not r["inside"] and not r["warnings"]]
    assert not broken, broken


@pytest.mark.slow
def test_the_rule_is_exercised():
    """The rule's cases include answers far off (else the rule asserts nothing): ski-b's
    identified beam at 10 kg, +50 mm is −14 % off at 200 MPa."""
    rows = _rule_rows("ski-b", "identified", 10.0, 50.0)
    assert max(abs(r["error"]) for r in rows) > 0.1


# ----------------------------------------------------------------------------- network band


def _study():
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        "network_band_study", ROOT / "scripts" / "network_band_study.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@functools.cache
def _network_rows() -> list[dict]:
    """The study's ``test`` cases (held-out loads its factor was not fitted on) at the service's
    NETWORK_SIGMA_SCALE."""
    study = _study()
    cat = service.load_catalogue(TABLES)
    table = cat.grind("grind-1").table
    scale = band_calibration.NETWORK_SIGMA_SCALE
    rows = []
    try:
        for name in ("ski-a", "ski-b"):
            rec = study.network_record(cat.ski(name).record)
            for f, xf in study.pick_cases(rec)["test"]:
                for e in study.E_SNOW_MPA:
                    rows += study.case_rows(name, rec, table, f, xf, e, [scale])
    finally:
        band_calibration.NETWORK_SIGMA_SCALE = scale
    return rows


@pytest.mark.slow
def test_network_band_covers_its_truth_at_every_snow_modulus():
    """Skis served by their camber network: the apparent area's truth (design beam, fine grid)
    inside the band in ≥ 90 % of the held-out cases at each of 20, 200 and 2000 MPa, with a mean
    half-width ≤ 2.5 × the RMS error (measured: 100 / 100 / 95 %, 1.73 ×; before the factor
    95 / 100 / 80 %)."""
    rows = _network_rows()
    q = "apparent_contact_area"
    for e in (20.0, 200.0, 2000.0):
        sel = [r for r in rows if r["e_snow_mpa"] == e]
        assert len(sel) == 20
        inside = np.mean([abs(r["error"][q]) <= r["width"][q] for r in sel])
        assert inside >= 0.9, (e, inside)
    err = np.array([r["error"][q] for r in rows])
    width = np.array([r["width"][q] for r in rows])
    assert width.mean() <= 2.5 * np.sqrt(np.mean(err**2))


def test_an_identified_beams_band_names_the_shape_error_the_data_cannot_show(shipped):
    """Every answer from an identified beam (rigid and bending) lists the beam model's shape
    error among what its band does not cover; an answer from the camber network does not."""
    for model in ("rigid", "flexible"):
        req = service.ContactInputs("ski-a", "grind-1", 40, -160, 200, 0.5, ski_model=model)
        ans = service.contact(shipped, req)
        assert ans["provenance"]["ski"]["profile_model"] == "identified_beam"
        assert band.IDENTIFIED_STRUCTURE_NOT_COVERED in ans["band"]["not_covered"], model
    net = _network_only(shipped, "ski-a")
    req = service.ContactInputs("ski-a", "grind-1", 40, -160, 200, 0.5, ski_model="rigid")
    ans = service.contact(net, req)
    assert ans["provenance"]["ski"]["profile_model"] != "identified_beam"
    assert band.IDENTIFIED_STRUCTURE_NOT_COVERED not in ans["band"]["not_covered"]


def test_bending_ignored_width_is_the_study_s_fit_and_covers_fresh_random_designs():
    """The served table is the study's ``fitted_width`` (the largest over its calibration
    designs, rounded up), and it covers ≥ 95 % of the held-out random designs' differences and
    all of the demo skis' (docs/studies/auto-without-beam.json)."""
    import json

    study = json.loads((ROOT / "docs" / "studies" / "auto-without-beam.json").read_text())
    params = json.loads(study["provenance"]["parameters_json"])
    assert params["calib_randoms"] >= 24 and params["randoms"] >= 24
    for q, widths in band_calibration.BENDING_IGNORED_WIDTH.items():
        cells = study["summary"][q]
        for e_mpa, w in zip(band_calibration.BENDING_IGNORED_E_SNOW_MPA, widths, strict=True):
            cell = cells[str(e_mpa)]
            assert cell["fitted_width"] == w == cell["served_width"], (q, e_mpa)
            assert cell["served_inside"]["random"] >= 0.95, (q, e_mpa)
            assert cell["served_inside"]["test"] == 1.0, (q, e_mpa)
