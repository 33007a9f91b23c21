"""The web form in a real browser: Playwright driving Debian's Chromium (no downloaded browsers).

The app runs under uvicorn in a background thread on a free 127.0.0.1 port with the test
catalogue. The test fills the form (using a load preset and the snow-density input), submits,
finds the metrics and the plots, opens a ski's page from the form, and saves screenshots to
``docs/screenshots/``. The upload test sends a grind through the upload page (bad inputs first:
errors next to their fields), follows its job to done and computes a contact with it in the
form.
Skipped only when Chromium or Playwright is missing outside CI; on CI (``CI`` set) it must run.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from browser_support import ARGS, CHROMIUM, REPO, SCREENSHOTS, npy_bytes, serve, serve_uploads

if not os.environ.get("CI"):
    if not Path(CHROMIUM).exists():
        pytest.skip(f"{CHROMIUM} is missing (apt-get install chromium)", allow_module_level=True)
    pytest.importorskip("playwright", reason="pip install -e '.[test]' installs playwright")

from playwright.sync_api import expect, sync_playwright


@pytest.fixture(scope="module")
def server(catalogue):
    from skisnow.app.main import create_app
    from skisnow.app.settings import Settings

    with serve(create_app(Settings(), catalogue=catalogue)) as url:
        yield url


@pytest.fixture(scope="module")
def upload_server(catalogue, tmp_path_factory):
    """The app on its own data directory, tables built in seconds (browser_support)."""
    with serve_uploads(catalogue, tmp_path_factory.mktemp("browser-uploads")) as url:
        yield url


@pytest.fixture(scope="module")
def page():
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        context = browser.new_context(viewport={"width": 1280, "height": 900})
        pg = context.new_page()
        pg.set_default_timeout(120_000)  # a solve takes seconds on a busy CI machine
        yield pg
        context.close()
        browser.close()


def test_fill_submit_and_see_results(server, page, tmp_path):
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(server + "/")
    expect(page.locator("h1")).to_contain_text("Ski–snow contact")

    # both skis, the test grind
    page.check("input[name=ski][value=ski-a]")
    page.check("input[name=ski][value=ski-b]")
    page.check("input[name=grind][value=tiny-grind]")
    # preset: half of a 90 kg skier at −80 mm
    page.fill("#body_weight_kg", "90")
    page.get_by_role("button", name="½ body weight at −80 mm").click()
    expect(page.locator("#load_kg")).to_have_value("45")
    expect(page.locator("#load_position_mm")).to_have_value("-80")
    # published case preset, then the snow from its density
    page.get_by_role("button", name="Published case: 40 kg at −160 mm").click()
    expect(page.locator("#load_kg")).to_have_value("40")
    # the snow: a preset fills and locks its numbers; custom numbers are one choice away
    expect(page.locator("#snow")).to_have_value("study")
    expect(page.locator("#snow_modulus_mpa")).to_be_disabled()
    page.select_option("#snow", "icy")
    expect(page.locator("#snow_modulus_mpa")).to_have_value("440")
    page.select_option("#snow", "")
    expect(page.locator("#snow_modulus_mpa")).to_be_enabled()
    page.fill("#snow_modulus_mpa", "200")
    page.check("input[name=snow_input][value=density]")
    expect(page.locator("#porosity")).to_be_disabled()
    page.fill("#snow_density_kg_m3", "458.5")
    expect(page.locator("#porosity-from-density")).to_contain_text("0.5")
    page.screenshot(path=str(tmp_path / "web-form.png"), full_page=True)

    page.click("#submit")
    page.wait_for_url("**/results?**")
    expect(page.locator("h1")).to_have_text("Contact results")
    table = page.locator("#comparison")
    expect(table).to_contain_text("ski-a")
    expect(table).to_contain_text("ski-b")
    expect(table).to_contain_text("Total real contact area [mm²]")
    metric = page.locator('[data-metric="total_real_contact_area_mm2"] .value').first
    assert float(metric.inner_text()) > 0
    for key in ("pressure", "clearance", "real_area", "separation", "reciprocal"):
        svg = page.locator(f"#plot-{key} svg")
        expect(svg).to_be_visible()
        assert svg.bounding_box()["width"] > 300
    assert "porosity n = 0.5" in page.inner_text("main")

    page.screenshot(path=str(tmp_path / "web-results.png"), full_page=True)
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    for name in ("web-form.png", "web-results.png"):
        shutil.copyfile(tmp_path / name, SCREENSHOTS / name)

    # the CSV link downloads one row per combination
    with page.expect_download() as info:
        page.click("#csv")
    download = info.value
    assert download.suggested_filename == "skisnow-contact.csv"
    lines = Path(download.path()).read_text().splitlines()
    assert len(lines) == 3 and lines[0].startswith("ski,grind,load_kg")
    assert errors == []


def test_bad_input_shows_the_field_error(server, page):
    # the browser blocks out-of-range numbers itself; a hand-edited link reaches the server
    page.goto(
        server + "/results?ski=ski-a&grind=tiny-grind&load_kg=400&load_position_mm=-160"
        "&snow_modulus_mpa=200&porosity=0.5"
    )
    expect(page.locator(".alert")).to_contain_text("Equivalent load on the ski")
    expect(page.locator("#load_kg-error")).to_contain_text("at most 150 kg")
    expect(page.locator("#contact-form")).to_be_visible()


def test_ski_page_from_the_form(server, page, tmp_path):
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(server + "/")
    page.get_by_role("link", name="ski page").nth(1).click()  # skis are listed sorted: ski-b
    page.wait_for_url("**/skis/ski-b")
    expect(page.locator("h1")).to_have_text("Ski ski-b")
    expect(page.locator("#profile-model + dl")).to_contain_text("identified_beam")
    for key in ("stiffness", "camber", "misfit"):
        svg = page.locator(f"#plot-{key} svg")
        expect(svg).to_be_visible()
        assert svg.bounding_box()["width"] > 300
    noise = page.locator('[data-number="noise_um"] .value')
    assert float(noise.inner_text()) == pytest.approx(3.0, abs=0.1)
    page.screenshot(path=str(tmp_path / "ski-page.png"), full_page=True)
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(tmp_path / "ski-page.png", SCREENSHOTS / "ski-page.png")
    # an unknown ski: a page that says so and lists the known ones
    response = page.goto(server + "/skis/no-such-ski")
    assert response.status == 404
    expect(page.locator(".alert")).to_contain_text("no-such-ski")
    page.get_by_role("link", name="ski-a").click()
    expect(page.locator("h1")).to_have_text("Ski ski-a")
    assert errors == []


def test_upload_a_grind_then_compute_with_it(upload_server, page, tmp_path):
    import numpy as np
    from skisnow.solvers.texture import self_affine_surface

    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    heights_um = 1e6 * self_affine_surface(
        (64, 64), 1e-6, hurst=0.8, rms_height_m=1e-6, rng=np.random.default_rng(3)
    )
    npy = {"name": "shop7.npy", "mimeType": "application/octet-stream"}

    page.goto(upload_server + "/")
    page.click("#upload-link")
    expect(page.locator("h1")).to_have_text("Upload a ski or a grind")
    form = page.locator("#grind-form")

    # a raw grid without its calibration: both fields say what is missing
    page.set_input_files("#grind-file", files=[{**npy, "buffer": npy_bytes(heights_um)}])
    page.fill("#grind-name", "shop7-fine")
    page.click("#grind-submit")
    for field in ("pixel_size_um", "height_unit"):
        expect(page.locator(f"#grind-{field}-error")).to_contain_text("must be given")
    expect(page.locator("#grind-file-error")).to_be_hidden()
    # bytes that are not what the name says: the error is next to the file
    page.set_input_files("#grind-file", files=[{**npy, "buffer": b"not a numpy file"}])
    page.fill("#grind-pixel_size_um", "1")
    page.select_option("#grind-height_unit", "um")
    page.click("#grind-submit")
    expect(page.locator("#grind-file-error")).to_contain_text("shop7.npy")
    expect(page.locator("#grind-pixel_size_um-error")).to_be_hidden()
    assert "Traceback" not in page.inner_text("main")

    # the real upload with its metadata
    page.set_input_files("#grind-file", files=[{**npy, "buffer": npy_bytes(heights_um)}])
    for field, value in (
        ("shop_code", "S7"),
        ("machine", "Wintersteiger Mono"),
        ("pattern_family", "linear"),
        ("coarseness_grade", "fine"),
        ("temperature_window", "-10 .. -2 C"),
        ("notes", "browser test"),
    ):
        form.locator(f"[name={field}]").fill(value)
    page.click("#grind-submit")
    expect(page.locator("#grind-job")).to_be_visible()
    expect(page.locator("#grind-job .accepted")).to_contain_text("64 × 64 grid")
    # the detrending is said (default for a measured map: the least-squares plane)
    expect(page.locator("#grind-job .accepted")).to_contain_text("least-squares plane removed")
    assert page.locator("#grind-detrend").input_value() == ""  # default: left to the API
    expect(page.locator("#grind-job-state")).to_have_text("done")
    expect(page.locator("#grind-job .percent")).to_have_text("100 %")
    assert page.locator("#grind-progress").evaluate("el => el.value") == 1
    expect(page.locator("#grind-file-error")).to_be_hidden()
    link = page.locator("#grind-done-link")
    expect(link).to_be_visible()
    expect(link).to_contain_text("shop7-fine")
    assert "grind_job=" in page.url  # a reload keeps following the job
    page.screenshot(path=str(tmp_path / "web-upload.png"), full_page=True)
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(tmp_path / "web-upload.png", SCREENSHOTS / "web-upload.png")

    # back in the form with the new grind selected: compute a contact with it
    link.click()
    page.wait_for_url("**/?**")
    expect(page.locator("input[name=grind][value=shop7-fine]")).to_be_checked()
    expect(page.locator("input[name=ski][value=ski-a]")).to_be_checked()
    page.click("#submit")
    page.wait_for_url("**/results?**")
    expect(page.locator("#comparison")).to_contain_text("shop7-fine")
    metric = page.locator('[data-metric="total_real_contact_area_mm2"] .value').first
    assert float(metric.inner_text()) > 0
    assert errors == []


@pytest.fixture(scope="module")
def flex_server(catalogue):
    """The test catalogue plus the flex sheet's design skis of tests/service/test_flex.py."""
    import dataclasses

    from skisnow.app import service
    from skisnow.app.main import create_app
    from skisnow.app.settings import Settings
    from test_flex import DESIGNS

    rec = catalogue.ski("ski-a").record
    cat = service.Catalogue(
        tables_dir=catalogue.tables_dir, skis=dict(catalogue.skis), grinds=catalogue.grinds
    )
    for name, design in DESIGNS.items():
        r = dataclasses.replace(rec, beam=design.build(), identified=None, network=None, cache={})
        cat.skis[name] = service.Ski(name, catalogue.ski("ski-a").path, "0" * 64, r)
    with serve(create_app(Settings(), catalogue=cat)) as url:
        yield url


def test_flex_sheet_pair_ranking(flex_server, page, tmp_path):
    """A technician walks through the flex tab: a ski's flex sheet (with its plot and CSV), the
    pair with its twin of 0.05 mm less pocket height (flagged), and the ranking for the skier
    (skis that do not suit the skier left out: flex-lower stands less than 0.15 mm open at half
    weight, flex-soft is closed there)."""
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(flex_server + "/")
    page.click("#nav-flex")
    expect(page.locator("h1")).to_have_text("Flex sheet")
    page.select_option("#ski", "flex-a")
    page.fill("#body_weight_kg", "75")
    page.fill("#snow_modulus_mpa", "20")
    page.click("#submit")
    page.wait_for_url("**/flex?**")
    expect(page.locator("#pockets")).to_contain_text("0.10 mm")
    closing = page.locator('[data-number="closing_load_kg"] .value')
    assert 37.5 < float(closing.inner_text()) < 75  # open at half weight, closed at full
    svg = page.locator("#plot-flex-profile svg")
    expect(svg).to_be_visible()
    assert svg.bounding_box()["width"] > 300
    page.screenshot(path=str(tmp_path / "flex-sheet.png"), full_page=True)
    with page.expect_download() as info:
        page.click("#csv")
    lines = Path(info.value.path()).read_text().splitlines()
    assert lines[0] == "quantity,value,band" and any("closing_load_kg" in x for x in lines)

    page.get_by_role("link", name="Pair").click()
    expect(page.locator("h1")).to_have_text("Pair matching")
    page.select_option("#left", "flex-a")
    page.select_option("#right", "flex-lower")
    page.click("#submit")
    page.wait_for_url("**/flex/pair?**")
    expect(page.locator("#pair-verdict")).to_contain_text("flagged: ")
    assert page.locator('#pair tr[data-flagged="true"]').count() >= 2
    page.screenshot(path=str(tmp_path / "flex-pair.png"), full_page=True)

    page.get_by_role("link", name="Ranking").click()
    expect(page.locator("h1")).to_have_text("A skier's best ski")
    for ski in ("flex-a", "flex-lower", "flex-soft"):
        page.check(f"input[name=ski][value={ski}]")
    page.check("input[name=grind][value=tiny-grind]")
    page.fill("#snow_modulus_mpa", "20")
    page.fill("#porosity", "0.5")
    page.click("#submit")
    page.wait_for_url("**/flex/ranking?**")
    expect(page.locator("#ranking")).to_contain_text("flex-a")
    assert page.locator("#ranking tr").count() == 2  # header + the one ski that suits
    expect(page.locator("#left-out")).to_contain_text("flex-soft")
    expect(page.locator("#left-out")).to_contain_text("flex-lower: too soft for 75 kg")
    assert errors == []


def test_technician_walk_with_the_shipped_ski_at_70_kg(server, page, tmp_path):
    """#28 acceptance: form → results → flex sheet → pair → ranking → upload with the shipped
    ski for a 60–80 kg skier (ski-c) at 70 kg: the sheet shows non-zero pockets, a verdict and a
    pocket height, and the ranking is not empty. Writes the flex screenshots."""
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(server + "/")
    page.check("input[name=ski][value=ski-c]")
    page.uncheck("input[name=ski][value=ski-a]")
    page.check("input[name=grind][value=tiny-grind]")
    page.fill("#body_weight_kg", "70")
    page.get_by_role("button", name="Full body weight at −150 mm").click()
    expect(page.locator("#load_kg")).to_have_value("70")
    page.select_option("#snow", "fine-grained")
    expect(page.locator("#snow_modulus_mpa")).to_have_value("120")
    page.click("#submit")
    page.wait_for_url("**/results?**")
    expect(page.locator("#comparison")).to_contain_text("ski-c")
    metric = page.locator('[data-metric="total_real_contact_area_mm2"] .value').first
    assert float(metric.inner_text()) > 0

    # flex sheet
    page.goto(server + "/")
    page.click("#nav-flex")
    page.select_option("#ski", "ski-c")
    page.fill("#body_weight_kg", "70")
    expect(page.locator("#snow")).to_have_value("study")  # the form's default snow
    page.click("#submit")
    page.wait_for_url("**/flex?**")
    expect(page.locator("#verdict")).to_contain_text("suits 70 kg: closes at")
    height = page.locator('[data-number="pocket_height"] .value')
    assert float(height.inner_text().split()[0]) > 0.1  # mm, at half weight
    pockets = page.locator("#pockets td.value")
    assert float(pockets.first.inner_text().split()[0]) > 100  # 0.10 mm pocket at half weight [mm]
    expect(page.locator('[data-number="kick_snow"]')).to_contain_text("shops aim for 33–50 %")
    page.screenshot(path=str(tmp_path / "flex-sheet.png"), full_page=True)

    # pair: ski-c against ski-a, labels and the overlay plot
    page.get_by_role("link", name="Pair").click()
    page.select_option("#left", "ski-c")
    page.select_option("#right", "ski-a")
    page.fill("#body_weight_kg", "70")
    page.click("#submit")
    page.wait_for_url("**/flex/pair?**")
    expect(page.locator("#pair")).to_contain_text("Closing load (0.10 mm under the foot) [kg]")
    expect(page.locator("#pair-verdicts")).to_contain_text("ski-a: too soft for 70 kg")
    svg = page.locator("#plot-flex-pair svg")
    expect(svg).to_be_visible()
    assert svg.bounding_box()["width"] > 300
    page.screenshot(path=str(tmp_path / "flex-pair.png"), full_page=True)

    # ranking: the shipped skis for a 70 kg skier; ski-c ranks, the demo skis are left out
    page.get_by_role("link", name="Ranking").click()
    for ski in ("ski-a", "ski-b", "ski-c"):
        page.check(f"input[name=ski][value={ski}]")
    page.check("input[name=grind][value=tiny-grind]")
    page.fill("#body_weight_kg", "70")
    page.click("#submit")
    page.wait_for_url("**/flex/ranking?**")
    expect(page.locator("#ranking")).to_contain_text("ski-c")
    assert page.locator("#ranking tr").count() >= 2
    expect(page.locator("#left-out")).to_contain_text("ski-a: too soft for 70 kg")
    page.screenshot(path=str(tmp_path / "flex-ranking.png"), full_page=True)
    # with only the demo skis: no ski qualifies, and the page says why
    page.uncheck("input[name=ski][value=ski-c]")
    page.click("#submit")
    page.wait_for_url("**/flex/ranking?**")
    expect(page.locator("#no-ski")).to_have_text("No ski qualifies")
    expect(page.locator("#no-ski-message")).to_contain_text("ski-b")

    # upload: the page is one click away
    page.goto(server + "/")
    page.click("#upload-link")
    expect(page.locator("h1")).to_have_text("Upload a ski or a grind")
    SCREENSHOTS.mkdir(parents=True, exist_ok=True)
    for name in ("flex-sheet.png", "flex-pair.png", "flex-ranking.png"):
        shutil.copyfile(tmp_path / name, SCREENSHOTS / name)
    assert errors == []


def test_delete_buttons_delete_from_the_upload_and_ski_pages(catalogue, page, tmp_path):
    """A failed upload on /upload and a ready uploaded ski on its page: each Delete button asks
    to confirm, sends DELETE from the page (the same-origin check lets it through) and the item
    is gone; the failed item's reason is shown."""
    from skisnow.app import service
    from skisnow.app.main import create_app
    from skisnow.app.settings import Settings
    from skisnow.app.storage.common import sha256_file

    cat = service.Catalogue(
        tables_dir=catalogue.tables_dir, skis=dict(catalogue.skis), grinds=dict(catalogue.grinds)
    )
    app = create_app(Settings(data_dir=tmp_path / "data", warm_up=False), catalogue=cat)
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.on("dialog", lambda dialog: dialog.accept())
    with serve(app) as url:
        state = app.state.uploads
        state.runner.stop()  # the jobs below are set by hand
        broken = state.db.add_item("ski", "broken", metadata={})
        job = state.db.add_job("ski-network", broken.id)
        state.db.update_job(job.id, state="failed", error="beam test failure: 5 loads")
        state.db.update_item(broken.id, state="failed")
        mine = state.db.add_item("ski", "mine", metadata={})
        path = state.layout.ski_file(mine.id)
        path.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(REPO / "tables" / "skis" / "ski-a.h5", path)
        state.db.update_item(mine.id, state="ready", file_path=str(path), sha256=sha256_file(path))
        state.live.sync()

        page.goto(url + "/upload")
        row = page.locator('li[data-item="ski:broken"]')
        expect(row).to_contain_text("beam test failure: 5 loads")
        row.locator("button[data-delete]").click()
        expect(row.locator(".delete-result")).to_contain_text("ski broken deleted")
        assert state.db.item_by_name("ski", "broken") is None

        page.goto(url + "/skis/mine")
        page.click("#delete-ski")
        expect(page.locator(".delete-result")).to_contain_text("ski mine deleted")
        assert state.db.item_by_name("ski", "mine") is None and not path.exists()
    assert errors == []


def test_a_ski_upload_shows_how_its_file_was_read_and_what_its_sampling_costs(
    catalogue, page, tmp_path, upload_csv
):
    """The upload answer's notes (app.jobs.uploads._upload_notes) are shown after "Checked":
    a spreadsheet's `Load (kgf)` without ski_id and side, sampled every 5 mm."""
    from skisnow.app import service
    from skisnow.app.main import create_app
    from skisnow.app.settings import Settings

    lines = upload_csv.decode().splitlines()
    rows = [";".join(line.split(",")[2:]).replace(".", ",") for line in lines[1:]]
    sheet = "\r\n".join(["Load (kgf);Load position (mm);Position (mm);Gap (mm)", *rows])
    cat = service.Catalogue(
        tables_dir=catalogue.tables_dir, skis=dict(catalogue.skis), grinds=dict(catalogue.grinds)
    )
    app = create_app(Settings(data_dir=tmp_path / "data", warm_up=False), catalogue=cat)
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    with serve(app) as url:
        app.state.uploads.runner.stop()  # the job is not the point here
        page.goto(url + "/upload")
        csv = {"name": "shop.csv", "mimeType": "text/csv", "buffer": sheet.encode()}
        page.set_input_files("#ski-file", files=[csv])
        page.fill("#ski-name", "shop-ski")
        page.fill("#ski-length_mm", "2000")
        page.fill("#ski-width_mm", "44")
        page.click("#ski-submit")
        accepted = page.locator("#ski-job .accepted")
        expect(accepted).to_contain_text("Checked: 45 load cases")
        expect(accepted).to_contain_text("Note: loads read in kgf as kg")
        expect(accepted).to_contain_text("Note: no ski_id column: ski_id shop-ski.")
        expect(accepted).to_contain_text("Note: samples every 5 mm")
        expect(accepted).to_contain_text("Measure every 1 mm for the most accurate answers.")
    assert errors == []
