"""Defects found in an exploratory session as a show designer (QA), driven with Playwright against a live
server on loopback: the timeline's labels stay readable after a check (none overflows its item or overlaps
its neighbour), and a refused upload names its field once."""

from __future__ import annotations

import re

import pytest

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_editor_browser import Page, _create_show

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")


server = server_for("qa-data", viewer=True)  # viewer on: the 3D preview plays a run


def _second_formation_checked(ui: Page, title: str, label: str, js_edit: str, wait_text: str):
    """A new show of 4 drones whose second formation ``f`` is edited by the JS ``js_edit``, checked; returns
    the report once it shows ``wait_text``."""
    page = ui.page
    _create_show(ui, title, 4)
    page.get_by_role("button", name="Add a formation").click()
    page.evaluate(f"() => {{ const s = window.swarmshow.state; s.edit('{label}', () => {{"
                  f" const f = s.show.formations[1]; {js_edit} }}); }}")
    page.get_by_role("button", name="Check the show").click()
    report = page.locator("#report-body")
    sync_api.expect(report).to_contain_text(wait_text, timeout=180_000)
    return report


def test_timeline_labels_do_not_overlap_after_a_check(ui: Page):
    """After a check the takeoff item ("↑ takeoff 5.9 s") and the first transition ("→ 23.5 s") were squeezed
    by the flex row until their texts ran into each other (seen at 1366 px with six formations)."""
    page = ui.page
    _create_show(ui, "Timeline labels", 9)
    for _ in range(5):
        page.get_by_role("button", name="Add a formation").click()
    page.get_by_role("button", name="Check the show").click()
    sync_api.expect(page.locator("#report-body")).to_contain_text("Minimum distance", timeout=180_000)
    sync_api.expect(page.locator(".tl-end").first).to_contain_text("takeoff")
    sync_api.expect(page.locator(".tl-transition").first).to_contain_text(" s")
    boxes = page.evaluate("""() => [...document.querySelectorAll('#timeline-list > li')].map((li) => {
        const r = li.getBoundingClientRect();
        return { cls: li.className, text: li.textContent, left: r.left, right: r.right,
                 overflow: li.scrollWidth - li.clientWidth }; })""")
    assert len(boxes) >= 2 * 6 + 2
    for b in boxes:
        assert b["overflow"] <= 1, f"{b['text']!r} overflows its item by {b['overflow']} px"
    for a, b in zip(boxes, boxes[1:], strict=False):
        assert a["right"] <= b["left"] + 0.5, f"{a['text']!r} overlaps {b['text']!r}"


def test_refused_mesh_upload_names_its_field_once(ui: Page):
    """The mesh form showed "file: file: the file holds no vertices" (the message already named its field)."""
    page = ui.page
    _create_show(ui, "Mesh refusal", 4)
    obj = ui.tmp / "empty.obj"
    obj.write_text("garbage\n")
    page.locator("summary", has_text="Mesh / point cloud").click()
    page.set_input_files("#mesh-file", str(obj))
    page.get_by_role("button", name="Replace the formation with points from the mesh or point file").click()
    err = page.locator('[data-error-for="mesh"]')
    sync_api.expect(err).to_contain_text("holds no vertices")
    assert "file: file:" not in err.inner_text()


def test_limit_violations_show_their_units(ui: Page):
    """The check listed "Acceleration: 126.81 (limit 4.00) at 24.9 s, drones 1, 7, 3, 5, 4" for nine drones:
    no unit, and five drones with nothing saying there were more. Each line now carries the value's unit and
    an ellipsis when the list is cut."""
    page = ui.page
    page.goto(ui.base + "/")
    got = page.evaluate("""async () => {
        const { violationText } = await import('/js/report.js');
        const v = (kind, n) => violationText({ kind, value: 12.5, limit: 4, time_s: 3, drones: [...Array(n).keys()] });
        return { acc: v('acceleration', 9), vz: v('speed_z', 2), vxy: v('speed_xy', 1), alt: v('altitude', 1),
                 floor: v('min_altitude', 1), fence: v('geofence', 1), wash: v('downwash', 2) }; }""")
    assert got["acc"] == "Acceleration: 12.50 m/s² (limit 4.00 m/s²) at 3.0 s, drones 0, 1, 2, 3, 4, …"
    assert got["vz"] == "Vertical speed: 12.50 m/s (limit 4.00 m/s) at 3.0 s, drones 0, 1"
    assert got["vxy"] == "Horizontal speed: 12.50 m/s (limit 4.00 m/s) at 3.0 s, drone 0"
    assert "12.50 m (limit 4.00 m)" in got["alt"] and "12.50 m (limit 4.00 m)" in got["floor"]
    assert "12.50 m (limit 4.00 m)" in got["fence"]
    assert got["wash"].startswith("In downwash (ellipsoid units")

    # And in a real report: a forced one-second transition breaks the acceleration and vertical speed limits.
    report = _second_formation_checked(ui, "Forced transition", "force",
                                       "f.points = f.points.map(([x, y, z]) => [x, y, z + 15]); f.transition_s = 1;",
                                       "Minimum distance")
    sync_api.expect(report.locator("button", has_text="Acceleration:").first).to_contain_text("m/s² (limit 4.00 m/s²)")
    sync_api.expect(report.locator("button", has_text="Vertical speed:").first).to_contain_text("m/s (limit 2.00 m/s)")
    # The too-short transition names no drones: its button's name does not say "drones :".
    short = report.locator("button", has_text="Too short")
    name = re.compile(r'^Transition too short at [\d.]+ s: select "Formation 2"$')
    sync_api.expect(short).to_have_attribute("aria-label", name)


def test_a_formation_card_with_a_problem_keeps_its_name_and_message(ui: Page):
    """A cue that cannot be met marks the formation's card; the card's flex column then squeezed its name to
    0.4 px and the message itself to 2.5 px (seen with a pinned formation): the card said neither which
    formation nor what was wrong. Nothing in a card shrinks now; a tall card scrolls."""
    page = ui.page
    _second_formation_checked(ui, "Cue problem", "cue", "f.arrive_at_s = 20; f.leave_at_s = 30;"
                              " f.points = f.points.map(([x, y, z]) => [x + 60, y, z]);", "earliest feasible")
    card = page.locator(".tl-card").nth(1)
    sync_api.expect(card).to_have_class(re.compile("has-problem"))
    sizes = card.evaluate("""(li) => {
        const h = (sel) => li.querySelector(sel).getBoundingClientRect().height;
        return { name: h('.tl-name'), meta: h('.tl-meta'), swatches: h('.tl-swatches'),
                 error: h('.field-error'), errorText: li.querySelector('.field-error').textContent,
                 scrolls: li.scrollHeight <= li.clientHeight || getComputedStyle(li).overflowY === 'auto' }; }""")
    assert sizes["name"] >= 14, sizes
    assert sizes["swatches"] >= 5.5, sizes
    assert sizes["error"] >= 12 and "earliest feasible" in sizes["errorText"], sizes
    assert sizes["scrolls"], sizes
    sync_api.expect(card.locator(".tl-name")).to_have_value("Formation 2")
    # The message names its field once, in the designer's words from the server's 'where_in_formation'
    # (it read "arrive_at_s: formations[1].arrive_at_s = 20 s is too early", then the raw path once).
    assert sizes["errorText"].startswith("arrive at (s) = 20 s is too early"), sizes["errorText"]
    report = page.locator("#report-body").inner_text()
    assert "Not checked: formations[1].arrive_at_s = 20" in report, report


def test_play_worst_run_opens_the_preview_with_that_run(ui: Page):
    """"Play worst run (seed k) in 3D" under a Monte-Carlo summary loaded the run into the viewer but, with the
    3D preview closed (as it is after a check), nothing on screen changed: a button that seemed to do nothing.
    It now opens the preview on that run."""
    page = ui.page
    _create_show(ui, "Worst run", 4)
    page.select_option("#sim-runs", index=1)  # Monte-Carlo, 20 runs
    page.get_by_role("button", name="Simulate the flight").click()
    play = page.locator("#sim-body button", has_text="Play worst run")
    sync_api.expect(play).to_be_visible(timeout=300_000)
    assert page.locator("#preview-wrap").is_hidden()
    job = page.evaluate("() => [...document.querySelectorAll('#sim-body a')].map((a) => a.href)"
                        ".find((h) => h.includes('/report.html'))").split("/api/jobs/")[1].split("/")[0]
    with page.expect_request(lambda r: r.url.endswith("/playback") and r.method == "POST") as req:
        play.click()
    body = req.value.post_data_json
    assert body["source"] == "simulated" and body["job_id"] == job and isinstance(body["run"], int), body
    sync_api.expect(page.locator("#preview-wrap")).to_be_visible()
    page.wait_for_function("() => window.swarmshow.playhead.preview.viewerState() !== null", timeout=120_000)


def test_hold_arrow_keys_step_by_half_seconds(ui: Page):
    """The card's hold field had min 0.1 and step 0.5, so its steps were 0.1 + k·0.5: ArrowDown on the default
    5 s hold gave 4.6 s, then 4.1 s (and 5 s itself was a 'step mismatch'). Steps are whole half seconds now."""
    page = ui.page
    _create_show(ui, "Hold steps", 4)
    hold = page.get_by_role("spinbutton", name="Hold time of formation 1, seconds")
    assert ui.state("s.show.formations[0].hold_s") == 5
    assert hold.evaluate("(el) => el.validity.valid"), "the default hold is a valid value of its own field"
    hold.focus()
    page.keyboard.press("ArrowDown")
    page.wait_for_function("() => window.swarmshow.state.show.formations[0].hold_s !== 5")
    assert ui.state("s.show.formations[0].hold_s") == 4.5
    page.keyboard.press("ArrowUp")
    page.keyboard.press("ArrowUp")
    page.wait_for_function("() => window.swarmshow.state.show.formations[0].hold_s === 5.5")
    # A typed value between the steps is kept as typed.
    hold.fill("2.3")
    hold.press("Tab")
    page.wait_for_function("() => window.swarmshow.state.show.formations[0].hold_s === 2.3")


def test_takeoff_and_landing_lines_of_the_check_read_once(ui: Page):
    """The check listed "✓ · Landing landing → home · 5.9 s" and "✓ · Takeoff home → takeoff · 5.9 s"."""
    page = ui.page
    page.goto(ui.base + "/")
    got = page.evaluate("""async () => {
        const { groupTitle } = await import('/js/report.js');
        const g = (kind, from, to) => groupTitle({ kind, from, to, duration_s: 5.9, stagger_s: 0, ok: true,
                                                    min_distance_m: 4.5, violations_total: 0 });
        return [g('takeoff', 'home', 'takeoff'), g('landing', 'landing', 'home'), g('transition', 'A', 'B')]; }""")
    assert got == ["✓ · Takeoff from the homes · 5.9 s, closest 4.50 m",
                   "✓ · Landing onto the homes · 5.9 s, closest 4.50 m",
                   "✓ · Transition A → B · 5.9 s, closest 4.50 m"]


def test_fit_them_leaves_a_group_formation_that_has_enough_points(ui: Page):
    """After raising the drone count, the prompt counted the formations short of the drones that fly them
    ("5 formations have fewer than 12 points"), but "Fit them" refitted every formation with fewer points than
    the whole fleet: a text flown by a 4-drone group was made again at 12 points. It fits what it counted."""
    page = ui.page
    _create_show(ui, "Fit groups", 4)
    page.get_by_role("button", name="Add a formation").click()
    page.evaluate("() => { const s = window.swarmshow.state; s.edit('group', () => {"
                  " s.show.groups = { pair: [0, 1] };"
                  " const f = s.show.formations[1]; f.points = [[-5, 0, 30], [5, 0, 30]];"
                  " f.colors = ['#ff0000', '#00ff00'];"
                  " f.drones = { group: 'pair' }; }); }")
    page.locator("summary", has_text="Show settings").click()
    page.fill("#set-drones", "6")
    page.dispatch_event("#set-drones", "change")
    dialog = page.locator("#dlg-confirm")
    sync_api.expect(dialog).to_contain_text("1 formation has fewer than 6 points")
    dialog.get_by_role("button", name="Fit them").click()
    page.wait_for_function("() => window.swarmshow.state.show.formations[0].points.length === 6")
    assert ui.state("s.show.formations[1].points") == [[-5, 0, 30], [5, 0, 30]]
