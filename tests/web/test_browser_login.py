"""Token mode for people in a real browser (issue #27 point 4): log in on ``/login``, upload a
grind from the upload page with no token field, follow its job, open "compute a contact" and
find the team's grind chosen in the form. Chromium as in tests/web/test_browser.py (skipped
where it is missing outside CI)."""

from __future__ import annotations

import numpy as np
import pytest

# test_browser skips (module level) where Chromium or Playwright is missing outside CI
from browser_support import ARGS, CHROMIUM, npy_bytes, serve_uploads
from test_browser import expect, sync_playwright


@pytest.fixture(scope="module")
def token_server(catalogue, tmp_path_factory):
    data_dir = tmp_path_factory.mktemp("browser-login")
    with serve_uploads(catalogue, data_dir, team_tokens={"token-a": "team-a"}) as url:
        yield url


def test_log_in_upload_and_compute_with_the_teams_grind(token_server):
    from skisnow.solvers.texture import self_affine_surface

    heights_um = 1e6 * self_affine_surface(
        (64, 64), 1e-6, hurst=0.8, rms_height_m=1e-6, rng=np.random.default_rng(5)
    )
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        context = browser.new_context(viewport={"width": 1280, "height": 900})
        page = context.new_page()
        page.set_default_timeout(120_000)
        errors: list[str] = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        try:
            page.goto(token_server + "/upload")
            page.click("#nav-login")
            page.fill("#login-token", "token-a")
            page.click("#login-submit")
            page.wait_for_url("**/upload")
            expect(page.locator("#login-team")).to_have_text("team team-a")
            (cookie,) = [c for c in context.cookies() if c["name"] == "skisnow_token"]
            assert cookie["httpOnly"] and cookie["sameSite"] == "Strict"
            assert page.evaluate("document.cookie").find("token-a") < 0  # no script reads it
            assert page.locator("#grind-token").count() == 0  # the cookie carries the token

            npy = {"name": "team.npy", "mimeType": "application/octet-stream"}
            page.set_input_files("#grind-file", files=[{**npy, "buffer": npy_bytes(heights_um)}])
            page.fill("#grind-name", "team-a-fine")
            page.fill("#grind-pixel_size_um", "1")
            page.select_option("#grind-height_unit", "um")
            page.click("#grind-submit")
            expect(page.locator("#grind-job-state")).to_have_text("done")
            link = page.locator("#grind-done-link")
            expect(link).to_contain_text("team-a-fine")
            link.click()
            page.wait_for_url("**/?**")
            assert "unknown grind" not in page.inner_text("main")
            expect(page.locator("input[name=grind][value=team-a-fine]")).to_be_checked()

            page.click("#logout")
            page.wait_for_url(token_server + "/")
            expect(page.locator("#nav-login")).to_be_visible()
            assert page.locator("input[name=grind][value=team-a-fine]").count() == 0
            assert errors == []
        finally:
            context.close()
            browser.close()
