"""The editor as a demanding designer uses it (QA round 2), in Chromium against a live ``swarmshow serve``: a show
the check finds unflyable still plays in the 3D preview and simulates, with its problems shown, while the exports
refuse it naming the field. Waits are on conditions, not fixed sleeps."""

from __future__ import annotations

import re

import httpx
import pytest

from tests.live_server import BROWSER_MARKS, server_for, wait_until
from tests.test_api_forced_short import forced_doc
from tests.test_api_shows import show_doc

pytestmark = BROWSER_MARKS
sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect

server = server_for("designer-data", viewer=True)


def _store(base: str, doc: dict) -> str:
    r = httpx.post(f"{base}/api/shows", json=doc)
    assert r.status_code == 201, r.text
    return r.json()["id"]


def test_forced_short_transition_previews_and_simulates_but_does_not_export(ui):
    """QA: the check listed the violations of a transition forced too short, but the 3D preview answered "Cannot
    load the show into the 3D view" and simulate failed, so the designer could not watch what was wrong."""
    page = ui.page
    show_id = _store(ui.base, forced_doc("Forced"))
    page.goto(f"{ui.base}/?show={show_id}")
    expect(page.locator("#show-title")).to_have_text("Forced")

    page.locator("#btn-preview").click()
    note = page.locator('[data-error-for="preview"]')
    expect(note).to_contain_text("Plays as designed, but cannot be flown: formations[1].transition_s = 0.2 s",
                                 timeout=90_000)
    wait_until("the preview's viewer", lambda: page.evaluate(
        "() => window.swarmshow.playhead.preview.viewerState()"), timeout_s=90)
    # The viewer draws the check's violations (computed in a worker once the show is on screen).
    from tests.test_viewer_editor_browser import _preview_panel

    frame = _preview_panel(page)
    expect(frame.get_by_text(re.compile(r"Problems\s+\d+ in the check"))).to_be_visible(timeout=60_000)
    expect(frame.get_by_role("button", name="Next problem")).to_be_enabled()

    page.get_by_role("button", name="Simulate the flight").click()
    body = page.locator("#sim-body")
    expect(body).to_contain_text("Flown as designed, but the design breaks the limits", timeout=120_000)
    expect(body.locator(".sim-problem")).to_contain_text("formations[1].transition_s = 0.2 s is shorter")

    page.select_option("#export-format", "skyc")
    page.get_by_role("button", name="Export in the chosen format").click()
    expect(page.locator("#export-error")).to_contain_text("formations[1].transition_s = 0.2 s is shorter",
                                                          timeout=30_000)


def _console_errors(page) -> list[str]:
    """Every console error of ``page`` from now on (Chromium logs a failed request's status there)."""
    errors: list[str] = []
    page.on("console", lambda m: errors.append(f"{m.text} ({m.location.get('url', '')})") if m.type == "error"
            else None)
    return errors


def test_a_show_without_music_opens_without_console_errors(ui):
    """QA: opening a show without music logged "Failed to load resource: ... 404" for /audio/info: the editor
    asked for music it could know was not there (the show says ``has_audio``)."""
    page = ui.page
    errors = _console_errors(page)
    show_id = _store(ui.base, forced_doc("No music"))
    page.goto(f"{ui.base}/?show={show_id}")
    expect(page.locator("#show-title")).to_have_text("No music")
    page.get_by_role("button", name="Check the show").click()
    expect(page.locator("#tl-problems .tl-problem").first).to_be_visible(timeout=60_000)
    # Another show, opened from the list (the editor reloads the music lane on every load).
    other = _store(ui.base, forced_doc("No music either"))
    page.goto(f"{ui.base}/?show={other}")
    expect(page.locator("#show-title")).to_have_text("No music either")
    page.wait_for_load_state("networkidle")
    assert errors == [], errors


def test_export_options_refuse_a_heading_beyond_a_turn_and_drop_stale_errors(ui):
    """QA (a designer's session): the heading field took 400 and stored 40 (the API and the CLI refuse |heading| >
    360), and the origin error of a refused QGroundControl export stayed on screen after another format had
    downloaded."""
    page = ui.page
    show_id = _store(ui.base, show_doc("Export options"))
    page.goto(f"{ui.base}/?show={show_id}")
    expect(page.locator("#show-title")).to_have_text("Export options")
    page.locator("#export-options").evaluate("(d) => { d.open = true; }")
    origin_error = page.locator('[data-error-for="origin"]')
    # No place on Earth: the QGroundControl export is refused and says where to give it.
    page.select_option("#export-format", "qgc-wpl")
    page.get_by_role("button", name="Export in the chosen format").click()
    expect(origin_error).to_contain_text("place on Earth")
    # Another format downloads: the stale origin error goes.
    page.select_option("#export-format", "show")
    with page.expect_download():
        page.get_by_role("button", name="Export in the chosen format").click()
    expect(origin_error).to_have_text("")
    # A heading beyond a full turn is refused, not wrapped to 40: the stored heading stays as it was.
    page.fill("#exp-origin", "47.1, 8.2")
    page.dispatch_event("#exp-origin", "change")
    assert ui.state("s.show.settings.geo.heading_deg") == 0
    page.fill("#exp-heading", "400")
    page.dispatch_event("#exp-heading", "change")
    expect(origin_error).to_contain_text("Heading")
    assert ui.state("s.show.settings.geo.heading_deg") == 0
    page.fill("#exp-heading", "-90")
    page.dispatch_event("#exp-heading", "change")
    expect(origin_error).to_have_text("")
    assert ui.state("s.show.settings.geo") == {"origin_lat_deg": 47.1, "origin_lon_deg": 8.2, "origin_alt_m": 0,
                                               "heading_deg": 270}


def test_a_shape_lands_on_the_formation_it_was_made_for(ui):
    """QA (a designer's session): "Apply shape" then, before the server answered, "Add a formation": the shape replaced
    the new formation instead of the one it was made for (the answer went to whichever formation was current)."""
    page = ui.page
    show_id = _store(ui.base, show_doc("Quick hands"))
    page.goto(f"{ui.base}/?show={show_id}")
    expect(page.locator("#show-title")).to_have_text("Quick hands")
    held = []
    page.route("**/api/formations/shape", lambda route: held.append(route))
    page.select_option("#shape-kind", "circle")
    page.fill("#shape-size", "40")
    page.fill("#shape-z", "40")
    page.get_by_role("button", name="Replace the formation with this shape").click()
    wait_until("the shape request", lambda: held, sleep=lambda s: page.wait_for_timeout(1000 * s))
    page.get_by_role("button", name="Add a formation").click()
    expect(page.locator(".tl-card")).to_have_count(2)
    added = ui.state("s.show.formations[1].points")
    before = ui.state("s.show.formations[0].points")
    held[0].continue_()
    wait_until("the shape applied", lambda: ui.state("s.show.formations[0].points") != before,
               sleep=lambda s: page.wait_for_timeout(1000 * s))
    circle = ui.state("s.show.formations[0].points")
    cx = sum(p[0] for p in circle) / len(circle)  # the editor centres a shape on the view
    radii = [(((x - cx) ** 2 + (z - 40) ** 2) ** 0.5) for x, _, z in circle]
    assert len(circle) == 4 and max(radii) - min(radii) < 0.01 and abs(radii[0] - 20) < 0.01, circle
    assert ui.state("s.show.formations[1].points") == added  # the formation added meanwhile is untouched
    assert ui.state("s.current") == 1
    # Undone while in flight: the formation it was made for is gone; nothing is replaced, the designer is told.
    held.clear()
    page.get_by_role("button", name="Replace the formation with this shape").click()
    wait_until("the second shape request", lambda: held, sleep=lambda s: page.wait_for_timeout(1000 * s))
    page.keyboard.press("Control+z")
    page.keyboard.press("Control+z")
    shows = ui.state("JSON.stringify(s.show.formations)")
    held[0].continue_()
    expect(page.locator('[data-error-for="shape"]')).to_contain_text("apply it again")
    assert ui.state("JSON.stringify(s.show.formations)") == shows


def test_a_hold_the_show_file_refuses_is_refused_with_its_reason(ui):
    """QA (a designer's session): typing 0 in a hold was put back silently, and 1e9 was taken, making the show a draft
    that the check then refused ("hold s: Input should be less than or equal to 86400")."""
    from formations._show import MAX_SHOW_TIME_S, MIN_DURATION_S

    page = ui.page
    show_id = _store(ui.base, show_doc("Holds"))
    page.goto(f"{ui.base}/?show={show_id}")
    expect(page.locator("#show-title")).to_have_text("Holds")
    hold = page.get_by_label("Hold time of formation 1, seconds")
    toast = page.locator("#toast")
    for typed, words in (("0", f"at least {MIN_DURATION_S:g} s"), ("1e9", f"at most {MAX_SHOW_TIME_S:g} s"),
                         (str(MIN_DURATION_S / 2), "at least")):
        hold.fill(typed)
        hold.press("Enter")
        expect(toast).to_contain_text(f'Hold of "square" must be {words}')
        expect(hold).to_have_value("1")
        assert ui.state("s.show.formations[0].hold_s") == 1
    hold.fill(str(MAX_SHOW_TIME_S))
    hold.press("Enter")
    page.wait_for_function(f"() => window.swarmshow.state.show.formations[0].hold_s === {MAX_SHOW_TIME_S:g}")


def test_the_preview_opens_at_the_selected_formation(ui):
    """QA (a designer's session): with the third formation selected (just drawn), "3D preview" opened at 0 s on the
    ground; the timeline and the preview share one playhead, so it opens at that formation's hold (the first
    formation: from the start, takeoff included)."""
    from tests.test_viewer_editor_browser import _hold_starts
    from tests.test_viewer_editor_browser import _store as store_three

    page = ui.page
    show_id = store_three(ui.base, "Three")
    page.goto(f"{ui.base}/?show={show_id}")
    expect(page.locator("#show-title")).to_have_text("Three")
    page.get_by_label("Name of formation 3").click()
    page.wait_for_function("() => window.swarmshow.state.current === 2")
    page.locator("#btn-preview").click()
    hold = _hold_starts(ui.base, show_id)[2]
    state = "() => window.swarmshow.playhead.preview.viewerState()"
    wait_until("the preview at formation 3's hold",
               lambda: (s := page.evaluate(state)) and abs(s["time_s"] - hold) < 0.06, timeout_s=90)
    # Closed and opened again on the first formation, it starts at 0 s.
    page.get_by_label("Name of formation 1").click()
    page.locator("#btn-preview-close").click()
    page.locator("#btn-preview").click()
    wait_until("the preview from the start", lambda: (s := page.evaluate(state)) and s["time_s"] == 0, timeout_s=90)
