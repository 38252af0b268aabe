"""Defects a show designer's walk through the editor found (Chromium against a live server on loopback):

* in a narrow window (a split screen, a small laptop) the top bar ran off the right edge: Export, its format
  and the shortcuts button could not be reached with the mouse;
"""

from __future__ import annotations

import httpx
import pytest

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_api_jobs import show_doc
from tests.test_editor_browser import Page

pytestmark = BROWSER_MARKS
sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect

server = server_for("designwalk-data")

#: Every control of the top bar a designer clicks.
TOP_CONTROLS = ["#btn-shows", "#btn-undo", "#btn-redo", "#btn-save", "#chk-autosave", "#btn-check", "#btn-simulate",
                "#btn-preview", "#export-format", "#btn-export", "#btn-help"]


def _open(ui: Page, doc: dict) -> str:
    r = httpx.post(f"{ui.base}/api/shows", json=doc)
    assert r.status_code == 201, r.text
    show_id = r.json()["id"]
    ui.page.goto(f"{ui.base}/?show={show_id}")
    expect(ui.page.locator("#show-title")).to_have_text(doc["name"])
    return show_id


def test_narrow_window_keeps_every_top_bar_control_on_screen(ui: Page):
    page = ui.page
    _open(ui, show_doc("Narrow window"))
    for width, height in [(1366, 768), (1024, 768), (900, 700), (760, 800)]:
        page.set_viewport_size({"width": width, "height": height})
        ui.settle()
        # Each control wholly inside the window and the topmost element at its centre (not clipped, not covered).
        where = page.evaluate("""(sels) => sels.map((s) => {
            const el = document.querySelector(s);
            const r = el.getBoundingClientRect();
            const hit = document.elementFromPoint(r.left + r.width / 2, r.top + r.height / 2);
            return [s, r.left, r.right, r.top, r.bottom, !!hit && (hit === el || el.contains(hit) || hit.contains(el))];
        })""", TOP_CONTROLS)
        for sel, left, right, top, bottom, on_top in where:
            assert 0 <= left and right <= width and 0 <= top and bottom <= height, \
                f"{width} px: {sel} at x {left:.0f}..{right:.0f}, y {top:.0f}..{bottom:.0f} is off screen"
            assert on_top, f"{width} px: {sel} is covered"
        # The canvas and the timeline still fit under the bar.
        canvas = page.locator("#canvas").bounding_box()
        timeline = page.locator("footer.timeline").bounding_box()
        bar = page.locator("header.topbar").bounding_box()
        assert canvas["y"] >= bar["y"] + bar["height"] - 1, f"{width} px: the canvas is under the top bar"
        assert canvas["height"] > 150 and timeline["y"] + timeline["height"] <= height + 1, \
            f"{width} px: canvas {canvas}, timeline {timeline}"
    page.get_by_role("button", name="Keyboard shortcuts").click()
    expect(page.locator("#dlg-help")).to_be_visible()
