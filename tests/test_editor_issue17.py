"""Issue 17's editor bugs, each driven through the real UI in Chromium (Playwright) against a live
server on loopback; every request is checked to stay on 127.0.0.1 and page errors fail the test."""

from __future__ import annotations

import pytest

from tests.live_server import BROWSER_MARKS, CHROMIUM, ServerProcess
from tests.test_editor_browser import Page, _create_show

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    """`swarmshow serve` (viewer on) on a free loopback port with an empty store."""
    srv = ServerProcess(tmp_path_factory.mktemp("issue17-data"), viewer=True)
    srv.start()
    try:
        yield srv.base
    finally:
        srv.stop()


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True)
        try:
            yield b
        finally:
            b.close()


@pytest.fixture
def ui(browser, server, tmp_path):
    p = Page(browser, server, tmp_path)
    yield p
    p.close()


def _two_formations(ui: Page, name: str, drones: int = 9) -> None:
    _create_show(ui, name, drones)
    ui.page.get_by_role("button", name="Add a formation").click()
    assert ui.state("s.show.formations.length") == 2


def test_bug1_keyboard_into_timeline_field_replaces_its_value(ui: Page):
    """Shift+Tab into another card's hold time, type: the value is replaced (was appended: 5 -> 57)."""
    page = ui.page
    _two_formations(ui, "Keyboard timeline")
    page.get_by_label("Name of formation 2").click()
    assert ui.state("s.current") == 1
    page.keyboard.press("Shift+Tab")  # the transition into formation 2
    page.keyboard.press("Shift+Tab")  # formation 1's hold time: it becomes the current formation
    expect(page.get_by_label("Hold time of formation 1, seconds")).to_be_focused()
    assert ui.state("s.current") == 0
    page.keyboard.type("7")
    page.keyboard.press("Tab")
    assert ui.state("s.show.formations[0].hold_s") == 7
    page.keyboard.press("Tab")  # formation 2's name, through the transition button
    expect(page.get_by_label("Name of formation 2")).to_be_focused()
    assert ui.state("s.current") == 1
    page.keyboard.type("Hi")
    page.keyboard.press("Tab")
    assert ui.state("s.show.formations[1].name") == "Hi"
    assert ui.state("s.show.formations[0].name") != "Hi"


def test_bug6_undo_forgets_planned_transition_times(ui: Page):
    """Fix a transition, check (it is planned at that length), undo: the stale time goes away."""
    page = ui.page
    _two_formations(ui, "Undo transition")
    page.get_by_role("button", name="Transition into formation 2; set its duration").click()
    page.locator("#confirm-input").fill("40")
    page.get_by_role("button", name="OK").click()
    tr = page.locator(".tl-transition").nth(1)
    expect(tr).to_have_text("→ 40 s fixed")
    page.get_by_role("button", name="Check the show").click()
    expect(page.locator("#report-body")).to_contain_text("Minimum distance", timeout=30_000)
    page.get_by_role("button", name="Undo Transition 40 s").click()
    assert "transition_s" not in ui.state("s.show.formations[1]")
    expect(tr).to_have_text("→")
    page.get_by_role("button", name="Redo Transition 40 s").click()
    expect(tr).to_have_text("→ 40 s fixed")


def test_bug7_clicking_a_cards_problem_selects_that_formation(ui: Page):
    """A refused save marks formation 2 in red; clicking that text makes formation 2 current."""
    page = ui.page
    _two_formations(ui, "Problem click")
    page.evaluate("""() => { const s = window.swarmshow.state;
        s.edit("Stack", () => { s.formation.points[1] = s.formation.points[0].slice(); }); }""")
    page.keyboard.press("Control+s")
    problem = page.locator('.tl-card[data-index="1"] .field-error')
    expect(problem).to_contain_text("closer than")
    page.get_by_label("Formation 1: Formation 1", exact=True).locator(".tl-swatches").click()
    assert ui.state("s.current") == 0
    problem.click()
    assert ui.state("s.current") == 1


def _preview_source(ui: Page) -> str:
    """Open (or reopen) the 3D preview; the source the editor loaded into the viewer."""
    page = ui.page
    with page.expect_response(lambda r: r.url.endswith("/playback") and r.request.method == "POST",
                              timeout=120_000) as resp:
        if page.locator("#preview-wrap").is_hidden():
            page.get_by_role("button", name="3D preview").click()
        else:
            page.get_by_role("button", name="Reload the 3D preview with the saved show").click()
    body = resp.value.json()
    assert resp.value.status == 200, body
    return body["source"]


def test_bug4_preview_plays_the_simulated_flight_after_a_simulation(ui: Page):
    page = ui.page
    _two_formations(ui, "Preview flown", drones=4)
    assert _preview_source(ui) == "planned"
    page.get_by_role("button", name="Close the 3D preview").click()
    page.get_by_role("button", name="Simulate the flight").click()
    expect(page.locator("#sim-percent")).to_have_text("100%", timeout=120_000)
    assert _preview_source(ui) == "simulated"
    # An edit makes the flight stale: the preview goes back to the plan.
    page.get_by_role("button", name="Close the 3D preview").click()
    page.get_by_label("Hold time of formation 1, seconds").fill("6")
    page.keyboard.press("Tab")
    page.wait_for_function("() => window.swarmshow.state.show.formations[0].hold_s === 6")
    assert _preview_source(ui) == "planned"
