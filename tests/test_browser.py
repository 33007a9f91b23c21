"""The web form in a real browser: Playwright driving Debian's Chromium (no downloaded browsers).

The app runs under uvicorn in a background thread on a free 127.0.0.1 port with the test
catalogue. The test fills the form (using a load preset and the snow-density input), submits,
finds the metrics and the plots, and saves screenshots to ``docs/screenshots/``.
Skipped only when Chromium or Playwright is missing outside CI; on CI (``CI`` set) it must run.
"""

from __future__ import annotations

import os
import shutil
import socket
import threading
import time
from pathlib import Path

import pytest

CHROMIUM = "/usr/bin/chromium"
REPO = Path(__file__).resolve().parents[1]
SCREENSHOTS = REPO / "docs" / "screenshots"
ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]

if not os.environ.get("CI"):
    if not Path(CHROMIUM).exists():
        pytest.skip(f"{CHROMIUM} is missing (apt-get install chromium)", allow_module_level=True)
    pytest.importorskip("playwright", reason="pip install -e '.[test]' installs playwright")

from playwright.sync_api import expect, sync_playwright  # noqa: E402


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture(scope="module", autouse=True)
def _numba_threads_env():
    """Keep ``NUMBA_NUM_THREADS`` at numba's live value while this module runs.

    ``create_app`` sets the variable when absent; once numba's thread pool is up, a later JIT
    compile that sees a different value raises RuntimeError (numba re-reads its config). That
    is the app's start-up concern (``skisnow serve`` sets it before numba loads); these tests
    are about the web layer, so they run with a consistent value whatever ran before.
    """
    import numba

    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NUMBA_NUM_THREADS", str(numba.config.NUMBA_NUM_THREADS))
        yield


@pytest.fixture(scope="module")
def server(catalogue):
    import uvicorn

    from app.api import create_app
    from app.settings import Settings

    port = _free_port()
    config = uvicorn.Config(
        create_app(Settings(), catalogue=catalogue),
        host="127.0.0.1",
        port=port,
        log_level="warning",
    )
    srv = uvicorn.Server(config)
    thread = threading.Thread(target=srv.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not srv.started:
        if time.monotonic() > deadline or not thread.is_alive():
            pytest.fail("uvicorn did not start")
        time.sleep(0.05)
    yield f"http://127.0.0.1:{port}"
    srv.should_exit = True
    thread.join(timeout=10)


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
    expect(page.locator("#load_kg-error")).to_contain_text("less than or equal to 150")
    expect(page.locator("#contact-form")).to_be_visible()
