"""Issue 17's sizing, through the editor in Chromium: "Size to fit" on the text and image sources
tells the size that fits all drones at the minimum distance, and that size is checked against the
server's own formation builder (it fits; 10 % smaller does not)."""

from __future__ import annotations

import math

import httpx
import pytest

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_editor_browser import Page, _create_show

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect
DRONES = 80


server = server_for("sizing-data")


def _min_distance(points: list[list[float]]) -> float:
    """Brute force over all pairs (80 points)."""
    return min(math.dist(a, b) for i, a in enumerate(points) for b in points[i + 1:])


def _size_to_fit(ui: Page, summary: str, what: str, size_input: str) -> float:
    """Open a source panel, press its "Size to fit"; the size it tells (toast and field agree)."""
    page = ui.page
    page.locator("summary", has_text=summary).click()
    page.get_by_role("button", name=f"Size the {what} to fit all drones at the minimum distance").click()
    toast = page.locator("#toast")
    expect(toast).to_contain_text(f"fits {DRONES} drones at 3 m", timeout=60_000)
    size = float(page.input_value(size_input))
    assert toast.inner_text().startswith(f"{page.input_value(size_input)} m fits")
    return size


def test_text_size_to_fit_tells_a_size_that_fits_and_no_smaller_one_does(ui: Page):
    page = ui.page
    _create_show(ui, "Sizing text", DRONES)
    page.locator("summary", has_text="Text").click()
    page.fill("#text-input", "OK")
    page.fill("#text-height", "5")
    page.locator("summary", has_text="Text").click()  # closed again: _size_to_fit opens it
    size = _size_to_fit(ui, "Text", "text", "#text-height")
    assert size > 5
    params = {"text": "OK", "center_m": [0, 0, float(page.input_value("#text-z"))], "n": DRONES,
              "min_spacing_m": 3.0}
    fits = httpx.post(f"{ui.base}/api/formations/text", json={**params, "height_m": size}, timeout=60)
    assert fits.status_code == 200, fits.text
    assert len(fits.json()["points"]) == DRONES and _min_distance(fits.json()["points"]) >= 3.0 - 1e-6
    smaller = httpx.post(f"{ui.base}/api/formations/text", json={**params, "height_m": size * 0.9}, timeout=60)
    assert smaller.status_code == 422 and smaller.json()["detail"][0]["max_n"] < DRONES
    # Applied at that size, the formation has every drone, spaced, above the floor.
    page.get_by_role("button", name="Replace the formation with this text").click()
    page.wait_for_function("() => window.swarmshow.state.undoStack.at(-1)?.label.startsWith('Text')")
    pts = ui.state("s.formation.points")
    assert len(pts) == DRONES and _min_distance(pts) >= 3.0 - 2e-3
    expect(page.locator("#st-spacing")).to_contain_text("✓")


def test_image_size_to_fit_tells_a_size_that_fits(ui: Page, tmp_path):
    from PIL import Image, ImageDraw

    page = ui.page
    _create_show(ui, "Sizing image", DRONES)
    img = Image.new("RGBA", (64, 64), (0, 0, 0, 0))
    ImageDraw.Draw(img).rectangle((8, 8, 56, 56), fill=(0, 120, 255, 255))
    path = tmp_path / "square.png"
    img.save(path)
    page.locator("summary", has_text="Image / SVG").click()
    page.set_input_files("#upload-file", str(path))
    page.fill("#upload-width", "4")
    page.locator("summary", has_text="Image / SVG").click()
    size = _size_to_fit(ui, "Image / SVG", "drawing", "#upload-width")
    assert size > 4
    data = {"width_m": str(size), "center_m": f"0,0,{page.input_value('#upload-z')}", "n": str(DRONES),
            "min_spacing_m": "3"}
    fits = httpx.post(f"{ui.base}/api/formations/image", data=data,
                      files={"file": ("square.png", path.read_bytes(), "image/png")}, timeout=60)
    assert fits.status_code == 200, fits.text
    assert len(fits.json()["points"]) == DRONES and _min_distance(fits.json()["points"]) >= 3.0 - 1e-6
    page.get_by_role("button", name="Replace the formation with the uploaded drawing").click()
    page.wait_for_function("() => window.swarmshow.state.undoStack.at(-1)?.label.startsWith('From')")
    assert len(ui.state("s.formation.points")) == DRONES
