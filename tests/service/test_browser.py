"""The front end in a real browser (Debian's Chromium through Python Playwright): submit a job in the
page, watch its progress reach 100 %, open the results and check that the 3D view draws something;
move the CL slider from an early CL to the last and see the workpiece change inside the part.

Skipped when /usr/bin/chromium or the front end's npm packages are missing, unless
FUSIONCUT_REQUIRE_BROWSER=1 (CI), which makes either a failure.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from service_helpers import KEY_A, TINY_GCODE, medium_submission, tiny_submission, tiny_total, wait_for

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--disable-gpu", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
        "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run"]
BACKGROUND = (0xF4, 0xF6, 0xF8)  # the 3D view's clear colour (frontend/src/view3d.js)

pytestmark = pytest.mark.usefixtures("frontend_packages")  # the page loads three.js from them


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
    px = _pixels(png)
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
    # the workpiece after the CL shown (the last) has arrived: a worker replayed the job to it
    page.wait_for_function("(c => c.dataset.mesh === c.dataset.cl)(document.querySelector('canvas#view3d'))",
                           timeout=120_000)
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
    # the view's legend names the toolpath's colours
    legend = page.locator("#view-legend").inner_text()
    assert all(status in legend for status in ("engaged", "air", "rapid", "failed")), legend


def _pixels(png: bytes) -> np.ndarray:
    from io import BytesIO

    from PIL import Image

    return np.asarray(Image.open(BytesIO(png)).convert("RGB"), dtype=int)


def _show_workpiece_at(page, canvas, index: int, cl: int) -> bytes:
    page.locator("#cl-slider").fill(str(index))
    # data-mesh: the CL whose workpiece (the GLB from /scene?cl=) is drawn
    page.wait_for_function(f"document.querySelector('canvas#view3d').dataset.mesh === '{cl}'", timeout=120_000)
    return canvas.screenshot()


def test_the_cl_slider_shows_the_workpiece_after_each_cl(browser, service, tmp_path):
    with service.client() as c:
        r = c.post("/api/jobs", json=tiny_submission("slider"))
        assert r.status_code == 201, r.text
        job = wait_for(c, r.json()["id"])
    assert job["state"] == "done", job
    last = tiny_total() - 1
    page, problems = _open(browser, service)
    page.goto(f"{service.url}/#/jobs/{job['id']}")
    canvas = page.locator("canvas#view3d")
    page.wait_for_selector(f"canvas#view3d[data-mesh='{last}']", timeout=120_000)  # it opens at the last CL
    canvas.scroll_into_view_if_needed()
    page.screenshot(path=str(tmp_path / "page-last.png"), full_page=True)
    # only the workpiece: the tool, arcs, lines and toolpath move with the slider too
    for layer in ("tool", "contact_faces", "arcs", "lines", "toolpath", "axes"):
        page.locator(f"#view-legend input[data-layer='{layer}']").uncheck()
    early = _show_workpiece_at(page, canvas, 1, 1)  # CL 1: before the slot
    (tmp_path / "workpiece-early.png").write_bytes(early)
    v_early = float(canvas.get_attribute("data-volume"))
    final = _show_workpiece_at(page, canvas, last, last)
    (tmp_path / "workpiece-last.png").write_bytes(final)
    v_last = float(canvas.get_attribute("data-volume"))
    assert v_early > v_last + 10.0  # mm³: the slot and the side pass

    x0, y0, x1, y1 = (int(v) for v in canvas.get_attribute("data-part-box").split(","))
    a, b = _pixels(early), _pixels(final)
    assert a.shape == b.shape and 0 <= x0 < x1 <= a.shape[1] and 0 <= y0 < y1 <= a.shape[0]
    changed = np.abs(a - b).max(axis=2) > 24
    inside = np.zeros_like(changed)
    inside[y0:y1, x0:x1] = True
    in_part = changed[inside].mean()
    outside = changed[~inside].mean()
    assert in_part > 0.01, f"the workpiece did not change: {in_part:.2%} of the part's pixels, see {tmp_path}"
    assert outside < 0.001, f"{outside:.2%} of the pixels outside the part changed, see {tmp_path}"
    # the part fills the view: its box is most of the canvas's width or height
    assert max((x1 - x0) / a.shape[1], (y1 - y0) / a.shape[0]) > 0.5
    assert not problems, problems


def test_upload_a_job_watch_it_and_see_it_in_3d(browser, service, tmp_path):
    page, problems = _open(browser, service)
    page.goto(service.url + "/#/new")
    page.set_input_files("input[name=toolpath]",
                         files=[{"name": "résumé.nc", "mimeType": "text/plain", "buffer": TINY_GCODE.encode()}])
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


def test_a_running_job_shows_its_latest_cl_and_plots_so_far(browser, service, tmp_path):
    with service.client() as c:
        # a ball end mill on CLs of 0.06 mm: about 1,800 CLs (the test service takes 2,000), long enough
        # to be watched while it runs and cancelled before it ends
        r = c.post("/api/jobs", json=medium_submission("running", segment=0.06, checkpoint_every=1000))
        assert r.status_code == 201, r.text
        job_id = r.json()["id"]
        page, problems = _open(browser, service)
        page.goto(f"{service.url}/#/jobs/{job_id}")
        page.wait_for_selector("#job-state:text-is('running')", timeout=60_000)
        # the CL shown is read in the same evaluation that finds it drawn: the page re-renders the job
        # view (a new canvas, without data-cl until its CL is drawn) while the job runs
        shown = page.wait_for_function(
            "() => { const v = document.querySelector('canvas#view3d'), p = document.querySelector('#plot-program');"
            " return v && v.dataset.cl !== undefined && p && p.naturalWidth > 0 ? {cl: Number(v.dataset.cl)} : null; }",
            timeout=60_000).json_value()["cl"]
        state = c.get(f"/api/jobs/{job_id}").json()
        page.screenshot(path=str(tmp_path / "running.png"), full_page=True)
        # the view follows the job: a later CL is drawn as more are finished
        page.wait_for_function(f"Number(document.querySelector('canvas#view3d').dataset.cl) > {shown}",
                               timeout=60_000)
        running = page.locator("#job-state").inner_text() == "running"
        cancel = page.locator("#cancel-button")
        assert cancel.get_attribute("class") == "danger"  # stopping a job for good looks destructive
        if running:
            cancel.click()
        final = wait_for(c, job_id)
    assert state["state"] == "running" and shown < state["progress"]["total"] - 1, (shown, state)
    assert running, "the job ended before the view followed it: make it longer"
    assert final["state"] == "cancelled"
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
    page.wait_for_url("**/#/jobs/*")  # the demo opens its own page
    assert page.locator("#cancel-button").get_attribute("class") == "danger"  # cancel looks destructive
    page.wait_for_selector("#job-state:text-is('done')", timeout=600_000)
    _check_3d_view(page, tmp_path / "view3d-demo.png")
    assert len(page.locator("#summary-table tbody tr").all()) == 5
    assert not problems, problems
