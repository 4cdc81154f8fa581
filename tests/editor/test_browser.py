"""The editor's page end to end in headless Chromium (Playwright driving Debian's ``chromium``): load the page, move a
slider, wait for the new render, keep a screenshot in ``out/test-artifacts/`` (not committed).

``make test`` installs both (the ``playwright`` package among the dev dependencies, Debian's ``chromium`` by
``scripts/setup.sh --browser``; no browser is downloaded). Elsewhere the test is skipped when either is missing; in
CI (``CI`` set) it fails instead, so that the page is driven in a real browser on every CI run.
"""

import os
import shutil
from pathlib import Path

import pytest

if os.environ.get("CI"):  # CI must drive the page: a missing browser is a failure there, not a skip
    import playwright.sync_api as _sync_api

    playwright = _sync_api
else:
    playwright = pytest.importorskip("playwright.sync_api", reason="the playwright package is not installed "
                                                                     "(pip install playwright)")
CHROMIUM = os.environ.get("CONVSSS_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
pytestmark = pytest.mark.skipif(CHROMIUM is None and not os.environ.get("CI"),
                                reason="no chromium binary (apt-get install chromium, or set CONVSSS_CHROMIUM)")
ARTIFACTS = Path(__file__).parents[2] / "out" / "test-artifacts"


def test_moving_a_slider_renders_a_new_image(editor_server, tmp_path):
    with playwright.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=["--no-sandbox"])
        try:
            page = browser.new_page(viewport={"width": 1100, "height": 800})
            errors = []
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto(editor_server.url)
            page.wait_for_function("document.body.dataset.version === '1'")
            page.wait_for_function("document.getElementById('render').complete "
                                   "&& document.getElementById('render').naturalWidth === 32")
            # Passes refine the preview while idle (to the fixture's 4 spp), each shown; the toggle shows the raw one.
            page.wait_for_function("document.body.dataset.spp === '4'", timeout=120_000)
            assert "4 of 4 spp, noise" in page.locator("#passes").inner_text()
            assert page.locator("#render").get_attribute("data-denoised") == "1"
            page.wait_for_function("document.getElementById('render').complete")
            denoised = page.locator("#render").screenshot()
            page.locator("#denoise").uncheck()
            page.wait_for_function("document.getElementById('render').dataset.denoised === '0' "
                                   "&& document.getElementById('render').complete")
            assert page.locator("#render").screenshot() != denoised
            before = page.locator("#render").screenshot()
            assert page.locator("#eta").is_enabled()  # a dielectric boundary
            assert page.locator("#preset option").count() == 48  # the 47 presets and the prompt
            # Move sigma_a (red) by keyboard: a real input event, as a user's drag gives.
            page.locator("#sigma_a-0").focus()
            for _ in range(40):
                page.keyboard.press("ArrowRight")
            page.wait_for_function("+document.body.dataset.version >= 2 && document.getElementById('busy')"
                                   ".textContent === ''", timeout=120_000)
            page.wait_for_function("document.getElementById('render').complete")
            after = page.locator("#render").screenshot()
            assert after != before
            assert "transport" in page.locator("#timings").inner_text()
            assert page.locator("#error").inner_text() == ""
            # Another profile model: a new render and a new profile plot.
            page.select_option("#model", "better-dipole")
            page.wait_for_function("+document.body.dataset.version >= 3 && document.getElementById('busy')"
                                   ".textContent === '' && document.getElementById('profile').complete",
                                   timeout=120_000)
            assert not errors
            ARTIFACTS.mkdir(parents=True, exist_ok=True)
            for folder in (tmp_path, ARTIFACTS):
                page.screenshot(path=str(folder / "editor.png"), full_page=True)
        finally:
            browser.close()
    assert (ARTIFACTS / "editor.png").stat().st_size > 1000
