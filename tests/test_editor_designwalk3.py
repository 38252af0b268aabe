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


#: Records every interval timer the editor's own scripts start and stop (with where it was started), so that a test
#: can see which still run.
_INTERVALS = """(() => {
  const set = window.setInterval.bind(window), clear = window.clearInterval.bind(window);
  window.__intervals = new Map();
  window.setInterval = (fn, ms, ...args) => {
    const id = set(fn, ms, ...args);
    window.__intervals.set(id, { ms, stack: new Error().stack || "" });
    return id;
  };
  window.clearInterval = (id) => { window.__intervals.delete(id); clear(id); };
})();"""


def test_the_sheet_is_folded_by_watching_the_viewer_page_not_by_polling(ui: Page):
    """Review: the preview polled the viewer's frame every 250 ms for as long as it was open. It now watches the
    viewer page for changes (a MutationObserver on its body): the sheet is folded once viser renders it, and no
    interval timer of the preview runs. Failed before: a 250 ms interval started in preview.js was running."""
    page = ui.page
    page.add_init_script(_INTERVALS)
    page.set_viewport_size({"width": 1024, "height": 768})
    ui.open_show(show_doc(name="No polling"))
    page.locator("#btn-preview").click()
    frame = page.frame_locator("#preview-frame")
    # viser renders its bottom sheet after the page has loaded; the editor folds it once the viewer's link is in.
    expect(frame.locator("[data-swarmshow-folded]")).to_have_count(1, timeout=90_000)
    page.wait_for_function("() => window.swarmshow.playhead.preview.viewerState() !== null", timeout=60_000)
    running = page.evaluate("() => [...window.__intervals.values()].filter((t) => /preview\\.js/.test(t.stack))")
    assert running == [], running
    # The watch is the observer, and it ends with the preview.
    assert page.evaluate("() => window.swarmshow.playhead.preview.sheetWatch instanceof MutationObserver")
    page.locator("#btn-preview-close").click()
    assert page.evaluate("() => window.swarmshow.playhead.preview.sheetWatch === null")


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


#: The canvas' axis legend's words (canvas.js draws "x (east) →  z (up) ↑" in the front view).
AXIS_WORDS = {"x": "x (east)", "y": "y (north)", "z": "z (up)"}


def test_the_depth_field_names_the_hidden_axis_as_the_canvas_does_and_is_gone_in_3d(ui: Page):
    page = ui.page
    ui.open_show(show_doc(name="Depth label"))
    label = page.locator("#depth-label")
    for view in ("front", "top", "side"):
        page.select_option("#view-select", view)
        # The axis the view does not show: the one its menu entry ("Front (x–z, audience)") does not name.
        shown = page.locator(f"#view-select option[value='{view}']").inner_text().split("(")[1][:3]
        (hidden,) = set("xyz") - set(shown)
        expect(label).to_be_visible()
        expect(label).to_contain_text(AXIS_WORDS[hidden])
        expect(label).to_contain_text("Altitude" if hidden == "z" else "Depth")
    # The 3D view has no drawing plane (Draw and Place are refused there): no depth for new points either.
    page.select_option("#view-select", "3d")
    expect(page.locator("#depth-input")).to_be_hidden()


def test_draft_problems_are_named_as_the_designer_sees_them(ui: Page):
    from formations._show import Formation, Settings

    page = ui.page
    doc = show_doc(name="Plain words")
    doc["formations"].append(dict(doc["formations"][0], name="Heart", hold_s=-1))
    doc["settings"]["max_speed_z_mps"] = 1e6
    ui.open_show(doc, draft=True)
    hold_min = Formation.model_json_schema()["properties"]["hold_s"]["minimum"]
    vz_max = Settings.model_json_schema()["properties"]["max_speed_z_mps"]["maximum"]
    items = page.locator("#draft-problems button")
    expect(items).to_have_count(2)
    texts = sorted(items.all_inner_texts(), key=lambda t: not t.startswith("formation"))
    vz_label = page.locator("label[for='set-vz']").inner_text()
    # The field by its label in the settings form, the formation by number and name; the rule in words.
    assert texts[0] == f'formation 2 "Heart", hold (s): must be at least {hold_min:g}', texts
    assert texts[1] == f"{vz_label}: must be at most {vz_max:g}", texts
    # The server's own words stay at hand for an operator (the tooltip).
    raws = {b.get_attribute("title") for b in items.all()}
    assert f"formations[1].hold_s: Input should be greater than or equal to {hold_min:g}" in raws, raws
    # Beside the field and on the formation's card, the same words, not the API's.
    expect(page.locator('[data-error-for="settings.max_speed_z_mps"]')).to_have_text(f"must be at most {vz_max:g}")
    card = page.locator(".tl-card[data-index='1']")
    expect(card).to_contain_text(f"hold (s): must be at least {hold_min:g}")
    assert "Input should" not in page.locator("body").inner_text()


def test_after_simulate_the_timeline_has_the_planned_durations_and_the_result_is_in_view(ui: Page):
    """The simulation's answer is the server's job as it comes when done (``simulate_task``: the plan summary and
    the flight summary); the flight itself is stood in for, so that the test does not compile and fly the kernel
    (the plan is the server's own, ``plan_summary`` of ``plan_show``)."""
    import json

    from app.tasks import plan_summary
    from formations._show import parse_show
    from sim import plan_show

    page = ui.page
    doc = show_doc(name="Simulated timing")
    doc["formations"].append(dict(doc["formations"][0], name="Up", points=[[x, y, z + 6] for x, y, z in
                                                                               doc["formations"][0]["points"]]))
    ui.open_show(doc)
    plan = plan_show(parse_show(doc))
    job = {"id": "sim-stand-in", "kind": "simulate", "state": "done", "progress": 1.0, "cached": False,
           "result": {"plan": plan_summary(plan), "problems": [],
                      "flight": {"ok": True, "drones": 4, "min_separation_m": 3.5, "max_deviation_m": 0.1}}}
    page.route("**/api/shows/*/simulate", lambda route: route.fulfill(
        status=202, content_type="application/json", body=json.dumps(job)))
    page.get_by_role("button", name="Simulate the flight").click()
    expect(page.locator("#sim-percent")).to_have_text("100%")
    # The planner's durations: the transition before each formation's hold.
    segs = plan.segments
    holds = [i for i, s in enumerate(segs) if s.kind == "hold"]
    checked = 0
    for k, i in enumerate(holds):
        if segs[i - 1].kind != "transition":
            continue
        expect(page.locator(".tl-transition button").nth(k)).to_have_text(f"→ {segs[i - 1].duration_s:.1f} s")
        checked += 1
    assert checked >= 1
    # The result the designer asked for is on screen, not below the fold of its panel.
    expect(page.locator("#sim-body")).to_be_in_viewport()


def test_a_speed_limit_beyond_the_show_file_s_is_marked_before_any_request(ui: Page):
    from formations._show import Settings

    page = ui.page
    ui.open_show(show_doc(name="Limits"))
    page.locator("#settings-panel summary").click()
    top = Settings.model_json_schema()["properties"]["max_speed_xy_mps"]["maximum"]
    page.fill("#set-vxy", f"{top * 10:g}")
    assert page.evaluate("() => document.getElementById('set-vxy').validity.rangeOverflow")
    page.locator("#set-vxy").dispatch_event("change")
    expect(page.locator('[data-error-for="settings.max_speed_xy_mps"]')).to_have_text(f"at most {top:g}")
    expect(page.locator("#set-vxy")).to_have_class("has-error")
