"""The front end in a real browser (Debian's Chromium through Python Playwright): submit a job in the
page, watch its progress reach 100 %, open the results and check that the 3D view draws something.

Skipped when /usr/bin/chromium is missing, unless FUSIONCUT_REQUIRE_BROWSER=1 (CI), which makes a
missing browser a failure.
"""
from __future__ import annotations

import os
from pathlib import Path

import pytest
from service_helpers import KEY_A, TINY_GCODE

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
        "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run"]
BACKGROUND = (0xF4, 0xF6, 0xF8)  # the 3D view's clear colour (frontend/src/view3d.js)


@pytest.fixture(scope="module")
def browser():
    if not Path(CHROMIUM).exists():
        if os.environ.get("FUSIONCUT_REQUIRE_BROWSER") == "1":
            pytest.fail(f"{CHROMIUM} is missing and FUSIONCUT_REQUIRE_BROWSER=1")
        pytest.skip(f"{CHROMIUM} is missing")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        yield b
        b.close()


def _open(browser, web):
    page = browser.new_page(viewport={"width": 1280, "height": 1000})
    problems: list[str] = []
    page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
    page.on("console", lambda m: problems.append(f"console {m.type}: {m.text}") if m.type == "error" else None)
    page.goto(web.url + "/")
    page.fill("#api-key", KEY_A)
    page.click("#key-save")
    page.wait_for_selector("#key-state.ok")
    return page, problems


def _non_background_fraction(png: bytes) -> float:
    from io import BytesIO

    from PIL import Image

    import numpy as np

    px = np.asarray(Image.open(BytesIO(png)).convert("RGB"), dtype=int)
    off = (np.abs(px - np.array(BACKGROUND)).max(axis=2) > 12).sum()
    return float(off) / (px.shape[0] * px.shape[1])


def _row(page, name: str):
    """The job list's row of the (newest) job called exactly ``name``."""
    return page.locator("tr.job").filter(has=page.get_by_role("link", name=name, exact=True)).first


def _wait_done_in_list(page, name: str, timeout_ms: int) -> None:
    row = _row(page, name)
    row.locator(".bar .label", has_text="100%").wait_for(timeout=timeout_ms)
    assert row.get_attribute("data-state") == "done"  # 100 % is shown only once the job is done
    assert row.locator(".bar").get_attribute("aria-valuenow") == "100"


def _check_3d_view(page, shot: Path) -> None:
    page.wait_for_selector("canvas#view3d[data-ready='1']", timeout=60_000)
    page.wait_for_selector("#summary-table tbody tr")
    canvas = page.locator("canvas#view3d")
    canvas.scroll_into_view_if_needed()
    png = canvas.screenshot(path=str(shot))
    frac = _non_background_fraction(png)
    assert frac > 0.03, f"the 3D view is (nearly) blank: {frac:.1%} non-background pixels, see {shot}"
    # the slider moves the tool: another CL gets drawn
    first = canvas.get_attribute("data-cl")
    page.locator("#cl-slider").fill("0")
    page.wait_for_function(f"document.querySelector('canvas#view3d').dataset.cl !== '{first}'", timeout=20_000)


def test_upload_a_job_watch_it_and_see_it_in_3d(browser, service, tmp_path):
    page, problems = _open(browser, service)
    page.goto(service.url + "/#/new")
    page.set_input_files("input[name=toolpath]",
                         files=[{"name": "slot.nc", "mimeType": "text/plain", "buffer": TINY_GCODE.encode()}])
    page.fill("input[name=name]", "browser job")
    row = page.locator(".tool-row").first
    row.locator("[name=t_number]").fill("1")
    row.locator("[name=t_diameter]").fill("6")
    row.locator("[name=t_flute]").fill("12")
    page.select_option("select[name=stock_kind]", "box")
    for name, v in zip(("x0", "y0", "z0", "x1", "y1", "z1"), (0, 0, -5, 30, 20, 0)):
        page.fill(f"input[name={name}]", str(v))
    page.fill("input[name=max_segment_length]", "5")
    page.click("#submit-button")
    page.wait_for_url("**/#/jobs*")
    _wait_done_in_list(page, "browser job", 120_000)
    _row(page, "browser job").locator("a.button", has_text="Open").click()
    _check_3d_view(page, tmp_path / "view3d-upload.png")
    ops = page.locator("#summary-table tbody tr td:first-child").all_inner_texts()
    assert ops == ["Slot", "Side"]
    page.wait_for_function("document.querySelector('#plot-program') && document.querySelector('#plot-program').naturalWidth > 0")
    assert not problems, problems


def test_bad_upload_shows_the_services_message(browser, service):
    page, problems = _open(browser, service)
    page.goto(service.url + "/#/new")
    bad = "G21\nT1 M6\nG1 X10 F100\nG1 X20 Q#<\n"
    page.set_input_files("input[name=toolpath]", files=[{"name": "bad.nc", "mimeType": "text/plain",
                                                          "buffer": bad.encode()}])
    page.locator(".tool-row [name=t_diameter]").first.fill("6")
    page.click("#submit-button")
    err = page.locator("#submit-error")
    err.wait_for(state="visible")
    assert "bad.nc:4" in err.inner_text()
    assert page.url.endswith("#/new")
    assert not [p for p in problems if "page error" in p], problems


@pytest.mark.slow
def test_demo_job_in_the_browser(browser, service, tmp_path):
    page, problems = _open(browser, service)
    page.goto(service.url + "/#/new")
    page.click("#demo-button")
    page.wait_for_url("**/#/jobs*")
    _wait_done_in_list(page, "demo", 600_000)
    _row(page, "demo").locator("a.button", has_text="Open").click()
    _check_3d_view(page, tmp_path / "view3d-demo.png")
    assert len(page.locator("#summary-table tbody tr").all()) == 5
    assert not problems, problems
