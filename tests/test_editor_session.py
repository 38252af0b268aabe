"""Issue 17's scripted session: a 300-drone show of four formations (text, image, filled preset,
freehand) built through the editor in Chromium, checked, simulated, previewed as flown from the
audience camera in two tabs that keep their own time, and exported. Screenshots go to
tests/screenshots/session-*.png; every request stays on loopback; page errors fail it."""

from __future__ import annotations

import re
import time

import pytest

from tests.live_server import BROWSER_MARKS, chromium_browser, running_server
from tests.test_editor_browser import Page, _create_show

pytestmark = [*BROWSER_MARKS, pytest.mark.slow]

sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect
DRONES = 300


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with running_server(tmp_path_factory.mktemp("session-data"), viewer=True, workers=2) as base:
        yield base


@pytest.fixture(scope="module")
def browser():
    with chromium_browser() as b:
        yield b


def _open(ui: Page, summary: str) -> None:
    """Open a sidebar panel (a click on an open one would close it)."""
    details = ui.page.locator("details", has=ui.page.locator("summary", has_text=summary))
    if details.get_attribute("open") is None:
        ui.page.locator("summary", has_text=summary).click()
    expect(details).to_have_attribute("open", "")


def _apply(ui: Page, form: str, summary: str, label: str, fit_label: str) -> None:
    """Open a source panel, size it to fit all drones, apply it; the formation has every drone."""
    page = ui.page
    _open(ui, summary)
    before = ui.state("s.undoStack.length")
    page.get_by_role("button", name=fit_label).click()
    expect(page.locator(".toast, #toast").first).to_contain_text(f"fits {DRONES} drones", timeout=60_000)
    page.get_by_role("button", name=label).click()
    page.wait_for_function(f"() => window.swarmshow.state.undoStack.length > {before}", timeout=60_000)
    assert ui.state("s.formation.points.length") == DRONES, form
    expect(page.locator(f'[data-error-for="{form}"]')).to_be_empty()


def _viewer_time(frame) -> float:
    text = frame.get_by_text(re.compile(r"Time\s+[\d.]+\s*/")).first.inner_text()
    return float(re.search(r"Time\s+([\d.]+)", text).group(1))


@pytest.mark.timeout(2400)
def test_scripted_session_300_drones(browser, server, tmp_path):
    from PIL import Image, ImageDraw

    ui = Page(browser, server, tmp_path)
    page = ui.page
    try:
        _create_show(ui, "Session", DRONES)
        # 1. Text.
        _open(ui, "Text")
        page.fill("#text-input", "HI")
        _apply(ui, "text", "Text", "Replace the formation with this text",
               "Size the text to fit all drones at the minimum distance")
        ui.shot("session-1-text")
        # 2. An image (a filled ring drawn here).
        page.get_by_role("button", name="Add a formation").click()
        img = Image.new("RGBA", (96, 96), (0, 0, 0, 0))
        ImageDraw.Draw(img).ellipse((8, 8, 88, 88), fill=(255, 80, 0, 255))
        ImageDraw.Draw(img).ellipse((34, 34, 62, 62), fill=(0, 0, 0, 0))
        path = tmp_path / "ring.png"
        img.save(path)
        _open(ui, "Image / SVG")
        page.set_input_files("#upload-file", str(path))
        _apply(ui, "upload", "Image / SVG", "Replace the formation with the uploaded drawing",
               "Size the drawing to fit all drones at the minimum distance")
        ui.shot("session-2-image")
        # 3. A filled preset.
        page.get_by_role("button", name="Add a formation").click()
        _open(ui, "Shape preset")
        page.select_option("#shape-kind", "filled_heart")
        _apply(ui, "shape", "Shape preset", "Replace the formation with this shape",
               "Size the shape to fit all drones at the minimum distance")
        ui.shot("session-3-heart")
        # 4. Freehand: a zigzag long enough for 300 drones 3 m apart.
        page.get_by_role("button", name="Add a formation").click()
        page.get_by_role("radio", name="Freehand stroke (D)").click()
        page.evaluate("() => { const v = window.swarmshow.view; v.scale = 2; v.center = [0, 75]; v.redraw(); }")
        box = page.locator("#canvas").bounding_box()
        cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        page.mouse.move(cx - 280, cy + 100)
        page.mouse.down()
        for row in range(6):
            y = cy + 100 - row * 40
            x0, x1 = (cx - 280, cx + 280) if row % 2 == 0 else (cx + 280, cx - 280)
            for k in range(1, 29):
                page.mouse.move(x0 + (x1 - x0) * k / 28, y)
            if row < 5:
                for k in range(1, 5):
                    page.mouse.move(x1, y - 40 * k / 4)
        page.mouse.up()
        assert ui.state("s.formation.points.length") == DRONES
        expect(page.locator("#st-spacing")).to_contain_text("✓")
        ui.shot("session-4-freehand")
        assert ui.state("s.show.formations.length") == 4
        kinds = [f.get("source", {}).get("kind") for f in ui.state("s.show.formations")]
        assert kinds[:3] == ["text", "image", "shape"]

        # Save, check, simulate.
        page.keyboard.press("Control+s")
        expect(page.locator("#dirty-indicator")).to_be_hidden(timeout=60_000)
        page.get_by_role("button", name="Check the show").click()
        expect(page.locator("#report-body")).to_contain_text("Minimum distance", timeout=300_000)
        ui.shot("session-5-check")
        page.get_by_role("button", name="Simulate the flight").click()
        expect(page.locator("#sim-percent")).to_have_text("100%", timeout=900_000)
        expect(page.locator("#sim-body")).to_contain_text("Flown min separation", timeout=120_000)
        ui.shot("session-6-simulated")

        # The flown show in the 3D preview, from the audience camera.
        with page.expect_response(lambda r: r.url.endswith("/playback"), timeout=900_000) as resp:
            page.get_by_role("button", name="3D preview").click()
        assert resp.value.json()["source"] == "simulated"
        frame = page.frame_locator("#preview-frame")
        frame.get_by_text(f"{DRONES} drones").first.wait_for(timeout=120_000)
        frame.get_by_role("combobox", name="Camera").click()
        frame.get_by_role("option", name="audience").click()
        frame.get_by_role("button", name="Play").click()
        time.sleep(2.0)
        # A second tab opens the viewer on the same show and keeps its own clock.
        other = Page(browser, server, tmp_path)
        try:
            tab2 = other.page
            tab2.goto(f"{server}/viser/")
            tab2.get_by_text(f"{DRONES} drones").first.wait_for(timeout=120_000)
            t2 = _viewer_time(tab2)
            time.sleep(1.5)
            t1 = _viewer_time(frame)
            assert _viewer_time(tab2) == t2 and t1 > t2 + 1.0
            other.shot("session-7-tab2")
        finally:
            other.close()
        ui.shot("session-7-preview")
        page.get_by_role("button", name="Close the 3D preview").click()

        # Export.
        page.select_option("#export-format", "skybrush-csv")
        with page.expect_download(timeout=300_000) as dl:
            page.get_by_role("button", name="Export in the chosen format").click()
        assert dl.value.suggested_filename.endswith(".zip")
    finally:
        ui.close()
