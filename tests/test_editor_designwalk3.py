"""A demanding show designer's third walk through the editor (Chromium against a live server on loopback):

* the 3D preview pane (265-400 px wide beside the canvas) is narrower than viser's mobile breakpoint (576 px), so
  viser laid its control panel out as a bottom sheet over 60% of the scene (the sheet ignores
  ``main_panel.minimize()``); the editor now folds that sheet to its handle strip (preview.js, foldSheet).
"""

from __future__ import annotations

import pytest

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_api_jobs import show_doc
from tests.test_editor_browser import Page

pytestmark = BROWSER_MARKS
sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect

server = server_for("designwalk3-data", viewer=True)


@pytest.mark.parametrize("viewport_w", [1366, 1024])
def test_the_preview_pane_shows_the_scene_not_viser_s_mobile_panel(ui: Page, viewport_w: int):
    page = ui.page
    page.set_viewport_size({"width": viewport_w, "height": 768})
    ui.open_show(show_doc(name="Narrow pane"))
    page.locator("#btn-preview").click()
    pane = page.locator("#preview-wrap").bounding_box()
    assert pane is not None and pane["width"] < 576, f"the pane is wide enough for viser's desktop layout: {pane}"
    frame = page.frame_locator("#preview-frame")
    canvas = frame.locator("canvas[data-engine^='three.js']")
    canvas.wait_for(timeout=60_000)
    # Once the viewer page has connected (its playback reported), viser's panel is in its final layout.
    page.wait_for_function("() => window.swarmshow.playhead.preview.viewerState() !== null", timeout=60_000)
    page.wait_for_timeout(500)
    ui.shot(f"designwalk3-preview-{viewport_w}")
    # What the designer sees at the middle of the scene (and at its lower third, where a bottom sheet sits) is the
    # scene's canvas, not a panel: elementFromPoint inside the preview's own page.
    hits = frame.locator("body").evaluate("""() => {
        const c = document.querySelector("canvas[data-engine^='three.js']");
        const r = c.getBoundingClientRect();
        return [0.5, 0.7].map((f) => {
          const e = document.elementFromPoint(r.left + r.width / 2, r.top + r.height * f);
          return e === c ? 'canvas' : (e ? e.outerHTML.slice(0, 120) : 'nothing');
        });
    }""")
    assert hits == ["canvas", "canvas"], hits
    # The folded panel still carries the playback's link: the editor's shared playhead reads it.
    assert page.evaluate("() => window.swarmshow.playhead.preview.viewerState()") is not None
    # And the page fits the pane: the frame's box on screen is inside the pane.
    box = page.locator("#preview-frame").bounding_box()
    assert box is not None
    assert box["x"] >= pane["x"] - 1 and box["x"] + box["width"] <= pane["x"] + pane["width"] + 1, (box, pane)
    assert box["y"] + box["height"] <= pane["y"] + pane["height"] + 1, (box, pane)


def test_a_submit_the_browser_blocks_replaces_the_last_answer_s_error(ui: Page):
    page = ui.page
    ui.open_show(show_doc(name="Stale error"))
    err = page.locator('[data-error-for="shape"]')
    size = page.locator("#shape-size")
    # An answer from the server: 4 drones do not fit on a 1 m circle at the show's minimum distance.
    size.fill("1")
    page.get_by_role("button", name="Replace the formation with this shape").click()
    expect(err).to_contain_text("do not fit")
    # Below the field's own minimum the browser blocks the submit (no request): the message is about that value.
    minimum = size.get_attribute("min")
    size.fill("0")
    page.get_by_role("button", name="Replace the formation with this shape").click()
    expect(err).not_to_contain_text("do not fit")
    expect(err).to_contain_text("Size (m)")
    assert page.evaluate("() => document.getElementById('shape-size').validity.rangeUnderflow")
    assert minimum is not None and minimum in err.inner_text(), (minimum, err.inner_text())
