"""Issue 21 item 5, formations that move during a hold, driven through the real editor in Chromium
(Playwright) against a live server on loopback: the Motion section adds a 90° turn about z over the
hold, the keys are listed and editable, the canvas plays the motion (the drawn points follow the
closed-form rotation), and the show checks ✓ Safe. The saved show is read back over the API."""

from __future__ import annotations

import math

import httpx
import pytest

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_editor_browser import Page, _check, _create_show, _type_points

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect

# A 3 x 3 grid in the front (x-z) plane at y = 0, 5 m apart (centre (0, 0, 40)).
GRID = [(x, 0.0, z) for z in (35.0, 40.0, 45.0) for x in (-5.0, 0.0, 5.0)]


server = server_for("motion-data")


def test_add_a_rotation_edit_its_keys_play_it_and_check_safe(ui: Page):
    page = ui.page
    _create_show(ui, "Spin", len(GRID))
    _type_points(ui, GRID)
    hold = page.get_by_label("Hold time of formation 1, seconds")
    hold.fill("12")
    hold.press("Tab")
    page.wait_for_function("() => window.swarmshow.state.formation.hold_s === 12")

    panel = page.locator("#motion-panel")
    if not panel.evaluate("el => el.open"):
        page.locator("summary", has_text="Motion during the hold").click()
    expect(page.locator("#motion-info")).to_have_text("holds still")
    page.fill("#motion-rotate", "90")
    page.select_option("#motion-axis", "2")
    page.get_by_role("button", name="Move the formation over its hold").click()
    keys = ui.state("s.formation.motion.keys")
    assert keys == [{"t_s": 0}, {"t_s": 12, "rotate_deg": [0, 0, 90], "translate_m": [0, 0, 0], "scale": 1}]
    table = page.locator("#motion-keys")
    expect(table.locator("tbody")).to_have_count(2)  # one block per key

    # The keys are editable: the last key turns 80° instead, then back with undo.
    last = page.get_by_label("Key 2 rotate about z, degrees")
    last.fill("80")
    last.press("Tab")
    page.wait_for_function("() => window.swarmshow.state.formation.motion.keys[1].rotate_deg[2] === 80")
    page.keyboard.press("Control+z")
    page.wait_for_function("() => window.swarmshow.state.formation.motion.keys[1].rotate_deg[2] === 90")
    # A key added halfway keeps the path: at 6 s the smooth quarter turn is at 45°.
    page.get_by_role("button", name="Add a motion key").click()
    mid = ui.state("s.formation.motion.keys[1]")
    assert mid["t_s"] == 6 and abs(mid["rotate_deg"][2] - 45.0) < 1e-3 and mid["easing"] == "linear"
    expect(table.locator("tbody")).to_have_count(3)
    page.get_by_role("button", name="Delete motion key 2").click()
    expect(table.locator("tbody")).to_have_count(2)

    # Playback draws the formation moved; at its end the points are the grid turned 90° about z.
    play = page.get_by_role("button", name="Play the motion on the canvas")
    play.click()
    expect(play).to_have_text("■ Stop")
    expect(page.locator("#motion-info")).to_contain_text("t = 12.0 s of the hold", timeout=60_000)
    # "12.0" shows from 11.95 s on; the playback has drawn its last frame (at the end) once its button says
    # Play again.
    expect(play).to_have_text("▶ Play")
    drawn = page.evaluate(
        "() => { const v = window.swarmshow.view; const f = window.swarmshow.state.formation;"
        " return v.moved ? v.moved(f).points : null; }"
    )
    assert drawn is not None
    for (x, y, z), p in zip(GRID, drawn, strict=True):
        want = (-y, x, z)  # a quarter turn about the vertical through the centre (0, 0, 40)
        assert math.dist(want, p) < 1e-6, (want, p)

    # The exact check plans the moving hold and finds it safe.
    report = _check(ui)
    expect(report.locator(".report-ok, .report-bad").first).to_have_text("✓ Safe: every limit holds")
    ui.shot("editor-motion")

    # Saved with the show.
    page.locator("#canvas").focus()
    page.keyboard.press("Control+s")
    expect(page.locator("#dirty-indicator")).to_be_hidden()
    saved = httpx.get(f"{ui.base}/api/shows/{ui.state('s.meta.id')}").json()["show"]["formations"][0]
    assert saved["motion"]["keys"][-1]["rotate_deg"] == [0.0, 0.0, 90.0]


def test_a_too_fast_motion_is_refused_with_the_field_named(ui: Page):
    page = ui.page
    _create_show(ui, "Too fast", len(GRID))
    _type_points(ui, GRID)
    page.locator("summary", has_text="Motion during the hold").click()
    page.fill("#motion-rotate", "720")
    page.get_by_role("button", name="Move the formation over its hold").click()
    page.locator("#canvas").focus()
    page.keyboard.press("Control+s")
    # The save is refused (or kept as a draft) with the server's reason on the formation's card.
    expect(page.locator(".tl-card .field-error").first).to_contain_text("too fast", timeout=30_000)
