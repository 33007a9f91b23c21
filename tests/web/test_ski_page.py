"""A ski's page (``/skis/{name}``): the profile model and why, the identified beam's EI(X) and
c(X) with their bands, the misfit per camber case, all equal to ``GET /v1/skis/{name}``; skis
without a beam say why; unknown names are a 404 page; names are escaped."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from html import unescape
from urllib.parse import quote

import numpy as np
import pytest
from fastapi.testclient import TestClient
from markupsafe import escape
from skisnow.app import service
from skisnow.app.main import create_app
from skisnow.app.service.profiles import HELD_OUT_ADDED, HELD_OUT_ERRORS, HELD_OUT_STORED
from skisnow.app.service.reports import _identification_cases
from skisnow.app.service.rounding import finite_list
from skisnow.app.settings import Settings
from skisnow.app.storage.skis import mean_profiles
from skisnow.app.web import form
from skisnow.solvers.band import Z90
from skisnow.solvers.beam import BeamFlexibility, BeamSki, solve_beam_contact

DEMO = ("ski-a", "ski-b")
#: a name that would run as script if it were not escaped (the catalogue accepts any name in
#: memory; uploads are restricted to letters, digits, '.', '_' and '-')
NASTY = '<script>alert("x")</script>'
#: the identification of a ski whose data could not identify a beam (as the upload job stores it)
FAILED = {"attrs": {"ok": False, "reason": "beam not identified: 3 cases are too few"}}


def _variant(base: service.Ski, name: str, **changes) -> service.Ski:
    return service.Ski(name, base.path, base.sha256, dataclasses.replace(base.record, **changes))


def _rejected(base: service.Ski) -> dict:
    """ski-a's identification as if its held-out check had failed (arrays kept, ok False)."""
    group = dict(base.record.identified)
    group["attrs"] = {
        **group["attrs"],
        "ok": False,
        "reason": "held-out cases miss by 9.00 µm RMS, more than 2× the device noise 3.01 µm",
    }
    return group


def _older(base: service.Ski) -> dict:
    """ski-a's identification as a file written before the held-out errors were stored."""
    return {k: v for k, v in base.record.identified.items() if k != HELD_OUT_ERRORS}


def _other_cases(base: service.Ski) -> dict:
    """ski-a's identification whose stored held-out errors name other cases than its held-out
    draw (a damaged or hand-edited file): they must not be shown as these cases' errors."""
    group = dict(base.record.identified)
    errors = dict(group[HELD_OUT_ERRORS])
    errors["case_index"] = np.asarray(errors["case_index"]) + 1
    group[HELD_OUT_ERRORS] = errors
    return group


@pytest.fixture(scope="module")
def client(catalogue, tmp_path_factory):
    a = catalogue.skis["ski-a"]
    skis = dict(catalogue.skis)
    skis["net-only"] = _variant(a, "net-only", identified=FAILED, beam=None)
    skis["design-only"] = _variant(a, "design-only", identified=None, network=None)
    skis["rejected"] = _variant(a, "rejected", identified=_rejected(a), beam=None)
    skis[NASTY] = _variant(a, NASTY, identified=FAILED)
    skis["older-file"] = _variant(a, "older-file", identified=_older(a))
    skis["other-cases"] = _variant(a, "other-cases", identified=_other_cases(a))
    no_alts = {k: v for k, v in a.record.identified.items() if k != "alternatives"}
    skis["no-alternatives"] = _variant(a, "no-alternatives", identified=no_alts)
    m = a.record.measurements
    every_5mm = dataclasses.replace(
        m, positions_m=m.positions_m[::5], profiles_m=m.profiles_m[:, ::5]
    )
    skis["sparse-samples"] = _variant(a, "sparse-samples", measurements=every_5mm)
    # an upload whose file left the tail's first 3 and the tip's last 2 samples unmeasured in
    # some cases: those positions were dropped from every case (app.storage.skis)
    trimmed = dataclasses.replace(
        m, positions_m=m.positions_m[3:-2], profiles_m=m.profiles_m[:, 3:-2]
    )
    dropped = [float(v) for v in np.r_[m.positions_m[:3], m.positions_m[-2:]] * 1e3]
    skis["tips-dropped"] = _variant(
        a,
        "tips-dropped",
        measurements=trimmed,
        metadata={
            **a.record.metadata,
            "unmeasured_samples": "40",
            "positions_dropped_mm": json.dumps(dropped),
        },
    )
    # positions written rounded, read as their grid, and one node absent near the tip
    skis["rounded-grid"] = _variant(
        a,
        "rounded-grid",
        measurements=trimmed,
        metadata={
            **a.record.metadata,
            "unmeasured_samples": "0",
            "positions_dropped_mm": json.dumps(dropped[3:]),
            "positions_absent_mm": json.dumps(dropped[3:4]),
            "position_shift_mm": "0.0049",
            "cases_dropped": json.dumps(["side=mean, load_kg=40, load_position_mm=0 (line 9)"]),
        },
    )
    cat = service.Catalogue(tables_dir=catalogue.tables_dir, skis=skis, grinds=catalogue.grinds)
    settings = Settings(data_dir=tmp_path_factory.mktemp("ski-page"), warm_up=False)
    with TestClient(create_app(settings, catalogue=cat), raise_server_exceptions=False) as c:
        yield c


def _page(client, name: str) -> str:
    r = client.get(form.ski_url(name))
    assert r.status_code == 200, r.text[:500]
    assert r.headers["content-type"].startswith("text/html")
    return r.text


def _number(html: str, key: str) -> float:
    m = re.search(rf'data-number="{key}">.*?<span class="value">([^<]+)</span>', html)
    assert m, key
    return float(m.group(1))


def _rows(html: str, table_id: str) -> list[list[str]]:
    table = re.search(rf'<table id="{table_id}">(.*?)</table>', html, re.S)
    assert table, table_id
    rows = re.findall(r"<tr[^>]*>(.*?)</tr>", table.group(1), re.S)
    return [[unescape(c) for c in re.findall(r"<td[^>]*>(.*?)</td>", r, re.S)] for r in rows[1:]]


def _pair(cell: str) -> tuple[float, float]:
    lo, hi = cell.split(" … ")
    return float(lo), float(hi)


# ----------------------------------------------------------------------------- demo skis


@pytest.fixture(scope="module", params=DEMO)
def demo(request, client):
    name = request.param
    api = client.get(f"/v1/skis/{name}")
    assert api.status_code == 200, api.text[:300]
    return name, _page(client, name), api.json()


def test_profile_model_and_why_in_the_api_words(demo, client):
    name, html, api = demo
    profile = api["profile_model"]
    assert profile["name"] == "identified_beam"
    assert f"<code>{profile['name']}</code>" in html
    assert f'<span id="profile-reason">{escape(profile["reason"])}</span>' in html
    assert escape(api["beam"]["source"]) in html
    listed = {s["name"]: s for s in client.get("/v1/skis").json()["skis"]}
    assert listed[name]["profile_model"] == profile["name"]
    assert listed[name]["profile_model_reason"] == profile["reason"]


def test_summary_numbers_equal_the_api(demo):
    _, html, api = demo
    ident = api["beam"]["identification"]
    assert ident["ok"] and ident["held_out_cases"] > 0
    for key in ("noise_um", "misfit_um", "misfit_to_noise", "held_out_rms_um", "held_out_to_noise"):
        # shown with 3 decimals
        assert _number(html, key) == pytest.approx(ident[key], abs=5e-4 + 1e-12), key
    # the ratios are the ratios of the figures shown next to them
    assert ident["misfit_to_noise"] == pytest.approx(ident["misfit_um"] / ident["noise_um"], 1e-3)
    assert ident["held_out_to_noise"] == pytest.approx(
        ident["held_out_rms_um"] / ident["noise_um"], 1e-3
    )
    for label in ("Device noise σ", "Held-out error, RMS over 85 cases", "µm"):
        assert label in html
    # the beam's device model is on the samples' 1 mm nodes (a sparser sampling gets 1 mm
    # model nodes of its own: solvers.identify DEFAULT_MODEL_SPACING_M)
    assert ident["model_spacing_mm"] == pytest.approx(1.0, abs=1e-6)
    assert _number(html, "model_spacing_mm") == pytest.approx(1.0)


def test_beam_table_equals_the_api(demo):
    _, html, api = demo
    beam = api["beam"]
    rows = _rows(html, "beam-table")
    assert len(rows) == len(beam["position_mm"]) == 41
    ei_lo, ei_hi = beam["bending_stiffness_band_90_nm2"]
    c_lo, c_hi = beam["camber_band_90_um"]
    share = beam["bending_stiffness_data_share"]
    for i, (x, ei, ei_band, ei_share, c, c_band) in enumerate(rows):
        assert float(x) == beam["position_mm"][i]
        assert float(ei) == beam["bending_stiffness_nm2"][i]
        assert _pair(ei_band) == (ei_lo[i], ei_hi[i])
        assert float(ei_share) == round(100 * share[i])
        assert float(c) == beam["camber_um"][i]
        assert _pair(c_band) == (c_lo[i], c_hi[i])
        # the bands hold the value; c's band is ± Z90 σ (6 significant digits in the API)
        assert ei_lo[i] <= beam["bending_stiffness_nm2"][i] <= ei_hi[i]
        assert c_lo[i] <= beam["camber_um"][i] <= c_hi[i]
        half = 0.5 * (c_hi[i] - c_lo[i])
        # each bound is rounded to 6 significant digits: the half-width is within half a unit
        # in the 6th digit of the larger bound
        digit = 10.0 ** (math.floor(math.log10(max(abs(c_lo[i]), abs(c_hi[i])))) - 5)
        assert abs(half - Z90 * beam["camber_sd_um"][i]) <= 0.5 * digit + 1e-9
    assert "[N·m²]" in html and "c [µm]" in html and "X [mm]" in html
    assert "EI set by the data [%]" in html


def test_stiffness_data_share_marks_where_the_camber_cases_bend_the_ski(demo):
    """The device's loads bend the demo ski between its contact points: the data set EI there
    (share near 1 under the binding), not at the tip and tail, whose EI and band the prior
    sets; the page says where the measured stretch ends, and the EI band is wider outside."""
    _, html, api = demo
    beam = api["beam"]
    x = np.array(beam["position_mm"])
    share = np.array(beam["bending_stiffness_data_share"])
    lo, hi = (np.array(b) for b in beam["bending_stiffness_band_90_nm2"])
    ei = np.array(beam["bending_stiffness_nm2"])
    assert share[np.abs(x) < 150].min() > 0.6
    assert share[(x < -900) | (x > 900)].max() < 0.1
    first, last = beam["bending_stiffness_measured_mm"]
    assert -900 < first < -200 and 200 < last < 900
    rel = (hi - lo) / ei
    assert rel[x > last].min() > 5 * rel[np.abs(x) < 150].max()
    assert f"The camber cases set EI between {first:g} and {last:g} mm" in html


def test_misfit_per_case_equals_the_api_and_is_consistent(demo, catalogue):
    name, html, api = demo
    ident = api["beam"]["identification"]
    rows = _rows(html, "misfit-table")
    fitted = [r for r in rows if r[3] == "identified"]
    held = [r for r in rows if r[3] == "held out"]
    assert [tuple(map(float, r[:3])) for r in fitted] == list(
        zip(ident["case_load_kg"], ident["case_position_mm"], ident["case_misfit_um"], strict=True)
    )
    h = ident["held_out"]
    assert [tuple(map(float, r[:3])) for r in held] == list(
        zip(h["load_kg"], h["position_mm"], h["error_um"], strict=True)
    )
    # every measured case is either identified or held out, each (load, position) once
    data = catalogue.skis[name].record.measurements
    # 425 loaded cases and the unloaded profile (load 0, always fitted, never held out)
    assert len(fitted) + len(held) == data.loads_n.size == 426
    assert ("0", "0") in {(r[0], r[1]) for r in fitted}
    assert len(held) == ident["held_out_cases"]
    cases = {(round(f, 2), round(x, 1)) for f, x, *_ in map(lambda r: map(float, r[:2]), rows)}
    measured = {
        (round(f / 9.82, 2), round(x * 1e3, 1))
        for f, x in zip(data.loads_n, data.load_positions_m, strict=True)
    }
    assert cases == measured
    # the overall figures are the RMS of the per-case ones (same number of nodes per case);
    # per-case values carry 4 significant digits
    fit = np.asarray(ident["case_misfit_um"])
    err = np.asarray(h["error_um"])
    assert math.sqrt(np.mean(fit**2)) == pytest.approx(ident["misfit_um"], rel=1e-3)
    assert math.sqrt(np.mean(err**2)) == pytest.approx(ident["held_out_rms_um"], rel=1e-3)


def test_plots_and_units(demo):
    _, html, _ = demo
    for key in ("stiffness", "camber", "misfit"):
        fig = re.search(rf'<figure class="plot" id="plot-{key}">(.*?)</figure>', html, re.S)
        assert fig and "<svg" in fig.group(1), key
    for text in (
        "Bending stiffness EI(X) [N·m²] with its 90 % band",
        "Unloaded camber c(X) [mm] with its 90 % band",
        "RMS misfit per camber case [µm] against load [kg] and load position [mm]",
        "device noise σ",
    ):
        assert text in html
    assert not re.search(r'(src|href)="(https?:)?//', html)


def test_alternative_beams_in_the_api_the_text_and_the_plots(demo, catalogue):
    """The identification's alternative beams: the API gives each at the report's points and
    how far it lies from the served beam over the middle half of the ski (recomputed here from
    the stored beams); the page names how many and the largest distances, and draws them
    dashed in both plots."""
    from skisnow.app.storage.skis import identified_alternatives
    from skisnow.solvers.identify import middle_distance

    name, html, api = demo
    rec = catalogue.skis[name].record
    stored = identified_alternatives(rec.identified)
    alt = api["beam"]["alternatives"]
    assert alt["count"] == len(stored) >= 1
    served, _ = catalogue.skis[name].beam()
    idx = [int(np.argmin(np.abs(served.positions_m * 1e3 - x))) for x in api["beam"]["position_mm"]]
    for i, b in enumerate(stored):
        dc, dl = middle_distance(b, served)
        assert alt["max_camber_difference_middle_um"][i] == pytest.approx(dc * 1e6, abs=1e-3)
        assert alt["max_stiffness_ratio_middle"][i] == pytest.approx(math.exp(dl), abs=1e-4)
        np.testing.assert_allclose(
            alt["bending_stiffness_nm2"][i], b.bending_stiffness_nm2[idx], rtol=1e-4
        )
    text = unescape(
        re.sub(r"<[^>]+>", "", re.search(r'id="alternative-beams">(.*?)</p>', html, re.S)[1])
    )
    text = " ".join(text.split())
    many = "s fit" if len(stored) > 1 else " fits"
    assert text.startswith(f"{len(stored)} other beam{many} the camber cases almost as well")
    assert f"{max(alt['max_camber_difference_middle_um']):.2f} µm in camber" in text
    assert f"a factor {max(alt['max_stiffness_ratio_middle']):.2f} in EI" in text
    for key in ("stiffness", "camber"):
        fig = re.search(rf'<figure class="plot" id="plot-{key}">(.*?)</figure>', html, re.S)[1]
        assert f"other beams that fit ({len(stored)})" in fig


def test_a_beam_without_alternatives_shows_none(client):
    """A ski whose identification stores no alternative beams (a file from before them): no
    alternatives in the API, no sentence on the page, none drawn."""
    api = client.get("/v1/skis/no-alternatives").json()
    assert api["beam"]["available"] and "alternatives" not in api["beam"]
    html = _page(client, "no-alternatives")
    assert 'id="alternative-beams"' not in html and "other beams that fit" not in html


@pytest.mark.parametrize("name", DEMO)
def test_stored_held_out_errors_equal_a_recomputation_from_the_beam(catalogue, name):
    """The demo skis store each held-out case's error with their identification; it is the
    identified beam's prediction minus the measured (left/right mean) profile, RMS over X,
    recomputed here case by case from the stored beam: rounding only."""
    rec = catalogue.skis[name].record
    ident = rec.identified
    stored = ident[HELD_OUT_ERRORS]
    loads_n, positions_m, profiles_m, _ = mean_profiles(rec.measurements)
    held = np.sort(np.asarray(ident["held_out_index"], dtype=int))
    assert held.size == ident["attrs"]["held_out_cases"] == 85
    assert np.array_equal(stored["case_index"], held)
    beam = BeamSki(ident["positions_m"], ident["bending_stiffness_nm2"], ident["unloaded_gap_m"])
    flex = BeamFlexibility(beam)
    gaps = np.stack(
        [solve_beam_contact(beam, loads_n[k], positions_m[k], flexibility=flex).gap_m for k in held]
    )
    expected = np.sqrt(np.mean((gaps - profiles_m[held]) ** 2, axis=1))
    assert np.all(expected > 0)
    # stored by another machine: its LAPACK rounds the beam solve differently (2e-11 relative
    # measured on 2026-11-26), far below the µm the errors are read in
    np.testing.assert_allclose(stored["rms_error_m"], expected, rtol=1e-9, atol=0)
    # the overall held-out RMS of the identification's check is their RMS (same nodes per case)
    overall = math.sqrt(np.mean(np.asarray(stored["rms_error_m"]) ** 2))
    assert overall == pytest.approx(ident["attrs"]["held_out_rms_m"], rel=1e-12)
    # provenance: units, how they were stored (the demo skis: added to their identification
    # without re-identifying, or stored by a later identify-ski --store), when and by what
    a = stored["attrs"]
    assert a["units"] == "m"
    assert a["source"] in (HELD_OUT_STORED, HELD_OUT_ADDED)
    for key in ("created_utc", "command_line", "code_version", "git_commit"):
        assert a[key], key


def test_the_api_and_page_show_the_stored_held_out_errors(demo, catalogue):
    name, html, api = demo
    held = api["beam"]["identification"]["held_out"]
    stored = catalogue.skis[name].record.identified[HELD_OUT_ERRORS]
    assert held["error_um"] == finite_list(np.asarray(stored["rms_error_m"]), 1e6, 4)
    origin = held["provenance"]
    assert origin["source"] == stored["attrs"]["source"]
    assert origin["created_utc"] == stored["attrs"]["created_utc"]
    shown = re.search(r'<span id="held-out-source">([^<]*)</span>', html).group(1)
    assert unescape(shown).startswith(origin["source"])


@pytest.mark.parametrize("name", ["older-file", "other-cases"])
def test_an_older_file_computes_the_held_out_errors_on_read(client, catalogue, name):
    """A file without stored held-out errors (or with errors of other cases) still shows every
    held-out case's error: predicted from the stored beam on reading, and said so."""
    base = catalogue.skis["ski-a"].record.identified[HELD_OUT_ERRORS]
    ski = client.app.state.catalogue.skis[name]
    *_, held, error_m, origin = _identification_cases(ski)
    assert origin == {"source": service.HELD_OUT_COMPUTED}
    assert np.array_equal(held, base["case_index"])
    # recomputed here against errors stored by another machine (rounding of its LAPACK)
    np.testing.assert_allclose(error_m, base["rms_error_m"], rtol=1e-9, atol=0)
    api = client.get(f"/v1/skis/{name}").json()["beam"]["identification"]["held_out"]
    demo = client.get("/v1/skis/ski-a").json()["beam"]["identification"]["held_out"]
    assert api["provenance"] == {"source": service.HELD_OUT_COMPUTED}
    assert demo["provenance"]["source"] != service.HELD_OUT_COMPUTED
    for key in ("load_kg", "position_mm", "error_um"):
        assert api[key] == demo[key], key
    html = _page(client, name)
    assert "computed on read" in re.search(r'<span id="held-out-source">([^<]*)</span>', html)[1]
    assert len(re.findall(r'<tr class="held-out">', html)) == 85


def test_page_figures_are_kept_on_disk_per_ski_file(catalogue, tmp_path, monkeypatch):
    """The page's figures are drawn once per ski file and read back by another process (a
    fresh record); other numbers, or a damaged cache file, draw anew."""
    from skisnow.app.service import ski_figures as sf

    a = catalogue.skis["ski-a"]
    drawn = []
    draw = sf._draw
    monkeypatch.setattr(sf, "_draw", lambda *args: drawn.append(1) or draw(*args))

    def fresh() -> service.Ski:  # as read by another process: nothing in memory
        return service.Ski("ski-a", a.path, a.sha256, dataclasses.replace(a.record, cache={}))

    cache = tmp_path / "cache" / "ski-a.json"
    first = sf.ski_figures(fresh(), cache)
    assert set(first) == {"stiffness", "camber", "misfit"} and len(drawn) == 1
    assert all(svg.startswith("<svg") for svg in first.values())
    again = fresh()
    assert sf.ski_figures(again, cache) == first and len(drawn) == 1  # read, not drawn
    assert sf.ski_figures(again, cache) is sf.ski_figures(again, cache)  # then kept in memory
    # a ski with other numbers (its design beam, no identification) draws its own figures
    design = service.Ski(
        "ski-a", a.path, a.sha256, dataclasses.replace(a.record, identified=None, cache={})
    )
    other = sf.ski_figures(design, cache)
    assert set(other) == {"stiffness", "camber"} and len(drawn) == 2
    # the entry was replaced: ski-a's figures are drawn anew (matplotlib's SVG ids differ from
    # one drawing to the next), then read back
    redrawn = sf.ski_figures(fresh(), cache)
    assert set(redrawn) == set(first) and len(drawn) == 3
    assert sf.ski_figures(fresh(), cache) == redrawn and len(drawn) == 3
    cache.write_text("{not json")
    redrawn = sf.ski_figures(fresh(), cache)
    assert set(redrawn) == set(first) and len(drawn) == 4
    assert sf.ski_figures(fresh(), cache) == redrawn and len(drawn) == 4  # rewritten


def test_an_uploads_figure_cache_goes_with_it(tmp_path):
    from skisnow.app.storage.layout import Layout

    layout = Layout(tmp_path)
    path = layout.ski_figures("item-1")
    path.parent.mkdir(parents=True)
    path.write_text("{}")
    layout.remove_item_files("item-1")
    assert not path.exists()


# ----------------------------------------------------------------------------- no beam


@pytest.mark.parametrize(
    ("name", "model", "why"),
    [
        ("net-only", "network", "beam not identified: 3 cases are too few"),
        ("rejected", "network", "held-out cases miss by 9.00 µm RMS"),
        ("design-only", "design_beam", "no identification was run"),
    ],
)
def test_ski_without_an_identified_beam_says_why(client, name, model, why):
    html = _page(client, name)
    api = client.get(f"/v1/skis/{name}").json()
    assert api["profile_model"]["name"] == model
    assert why in api["profile_model"]["reason"]
    assert f"<code>{model}</code>" in html
    assert escape(api["profile_model"]["reason"]) in html
    assert escape(why) in html
    beam = api["beam"]
    if model == "network":
        # no beam at all: said at the top, no EI or camber plot, no beam table
        assert not beam["available"]
        assert 'id="no-beam"' in html and "This ski has no beam." in html
        assert escape(beam["source"]) in html
        assert "plot-stiffness" not in html and "beam-table" not in html
        assert 'id="identification-failed"' in html
    else:
        # the design beam: drawn, without a band, and said to be unidentified
        assert beam["available"] and "bending_stiffness_band_90_nm2" not in beam
        assert "identification" not in beam and 'id="identification"' not in html
        assert "not identified, no band" in html
        rows = _rows(html, "beam-table")
        assert [float(r[1]) for r in rows] == beam["bending_stiffness_nm2"]
        assert [float(r[2]) for r in rows] == beam["camber_um"]
    if name == "rejected":
        # a fit that failed its held-out check still shows its misfit per case
        assert "plot-misfit" in html
        assert len(_rows(html, "misfit-table")) == 426  # 425 loaded cases + the unloaded
    if name == "net-only":
        assert "plot-misfit" not in html and "misfit-table" not in html
        assert 'data-number="misfit_um"' not in html  # nothing to show, no empty cards


# ----------------------------------------------------------------------------- errors


def test_unknown_ski_is_a_404_page(client):
    r = client.get("/skis/no-such-ski")
    assert r.status_code == 404
    assert r.headers["content-type"].startswith("text/html")
    assert "Unknown ski" in r.text and "no-such-ski" in r.text
    assert "Traceback" not in r.text
    for name in DEMO:
        assert f'href="/skis/{name}"' in r.text


def test_pending_upload_says_so(client):
    client.app.state.uploads.db.add_item("ski", "still-training", state="pending")
    r = client.get("/skis/still-training")
    assert r.status_code == 404
    assert "upload that is pending" in r.text


def test_names_are_escaped(client):
    page, form = _page(client, NASTY), client.get("/").text
    for html in (page, form):
        assert NASTY not in html
        assert escape(NASTY) in html
    # links carry the name percent-encoded as one path segment
    assert f'href="/skis/{quote(NASTY, safe="")}"' in form
    assert f'href="/v1/skis/{quote(NASTY, safe="")}"' in page
    assert f'<span id="ski-name">{escape(NASTY)}</span>' in page
    r = client.get("/skis/" + quote("<b>x</b>", safe=""))
    assert r.status_code == 404
    assert "<b>x</b>" not in r.text and escape("<b>x</b>") in r.text


# ----------------------------------------------------------------------------- links


def test_form_names_the_profile_model_and_links_the_ski_pages(client):
    html = client.get("/").text
    assert "camber model:" not in html
    for name, model in (
        ("ski-a", "identified_beam"),
        ("net-only", "network"),
        ("design-only", "design_beam"),
    ):
        entry = re.search(rf'value="{name}".*?</label>', html, re.S).group(0)
        assert f"profile model: {model}" in entry
        assert f'href="/skis/{name}"' in entry


def test_upload_page_lists_the_ski_pages(client):
    html = client.get("/upload").text
    pages = re.search(r'<p class="hint" id="ski-pages">(.*?)</p>', html, re.S).group(1)
    for name in DEMO:
        assert f'href="/skis/{name}"' in pages
    assert 'id="ski-item-link"' in html and 'id="grind-item-link"' not in html


def test_a_ski_sampled_every_5_mm_says_what_it_costs(client):
    """The ski page repeats the upload's sampling note for a file sampled coarser than 1 mm
    (here ski-a's measurements every 5th sample, its beam on the 1 mm nodes, as a 5 mm upload's
    is identified); the 1 mm demo ski has none."""
    html = _page(client, "sparse-samples")
    assert "samples every 5 mm" in html and 'id="sampling-note"' in html
    assert "Measure every 1 mm for the most accurate answers" in html
    assert 'id="sampling-note"' not in _page(client, "ski-a")


def test_a_ski_whose_file_had_unmeasured_samples_says_which_positions_went(client):
    """The ski page repeats the upload's note on the positions dropped for unmeasured samples,
    as runs of positions; the sample step stays the device's (the median step)."""
    html = _page(client, "tips-dropped")
    note = re.search(r'<p class="hint" id="unmeasured-note">([^<]*)</p>', html)
    assert note, html[:2000]
    assert "40 samples of the file had no gap: the 5 positions" in note.group(1)
    x_mm = catalogue_positions_mm(client)
    assert f"({x_mm[0]:g} … {x_mm[2]:g} mm, {x_mm[-2]:g} … {x_mm[-1]:g} mm)" in unescape(
        note.group(1)
    )
    assert 'id="sampling-note"' not in html  # still every 1 mm
    assert 'id="unmeasured-note"' not in _page(client, "ski-a")
    html = unescape(_page(client, "rounded-grid"))
    note = re.search(r'<p class="hint" id="unmeasured-note">([^<]*)</p>', html)
    assert note, html[:2000]
    assert f"1 position of the grid ({x_mm[-2]:g} mm) none" in note.group(1)
    assert (
        "written rounded, were read as the uniform grid they round (largest shift 0.0049 mm)"
        in (note.group(1))
    )
    assert (
        "the case with an unmeasured sample inside it was left out (side=mean, load_kg=40, "
        "load_position_mm=0 (line 9))" in note.group(1)
    )


def catalogue_positions_mm(client) -> np.ndarray:
    """Demo ski A's measured positions [mm] (the catalogue the client serves)."""
    ski = client.app.state.catalogue.skis["ski-a"]
    return ski.record.measurements.positions_m * 1e3


def test_the_ski_page_s_note_counts_rows_a_case_left_out():
    """Rows a case left out of the grid the others list are unmeasured samples: the ski page's
    note says how many beside those without a gap (app.storage.skis, omitted_samples)."""
    from skisnow.app.web.ski_page import _unmeasured_note

    metadata = {
        "unmeasured_samples": "0",
        "omitted_samples": "14",
        "positions_dropped_mm": "[-970.0, -965.0]",
    }
    note = _unmeasured_note(metadata)
    assert note.startswith("14 samples of the grid were not listed by their case: the 2 ")
    assert "the 2 positions outside the stretch kept (-970 … -965 mm) were dropped" in note
    both = _unmeasured_note({**metadata, "unmeasured_samples": "3"})
    assert both.startswith("3 samples of the file had no gap, 14 samples of the grid were not")
    assert "were not listed" not in _unmeasured_note({**metadata, "omitted_samples": "0"})
