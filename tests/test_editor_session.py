"""Issue 17's scripted session: a 300-drone show of four formations (text, image, filled preset,
freehand) built through the editor in Chromium, saved as a draft while half-finished, fixed,
checked, simulated, previewed as flown from the audience camera in two tabs that keep their own
time, and exported (slow). A short variant (drafts, check, export) runs in ``make test``.
Screenshots go to tests/screenshots/session-*.png; every request stays on loopback; page errors
fail it."""

from __future__ import annotations

import re
import time

import pytest

from tests.live_server import BROWSER_MARKS, SHOTS, server_for, wait_until
from tests.test_editor_browser import Page, _create_show
from tests.test_viewer_editor_browser import _preview_panel

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect
DRONES = 300


# The 3D preview flies the 300-drone show inside its request: on a loaded 2-core machine that can
# take longer than the default 60 s interactive budget.
server = server_for("session-data", viewer=True, workers=2, env={"SWARMSHOW_TASK_TIMEOUT_S": "900"})


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


def _expect_draft(ui: Page, *problem_words: str) -> None:
    """The editor shows the stored show as a draft and lists what is wrong in plain words."""
    page = ui.page
    expect(page.locator("#draft-badge")).to_be_visible()
    problems = page.get_by_role("list", name="What is wrong with the draft")
    expect(problems).to_be_visible()
    for words in problem_words:
        expect(problems).to_contain_text(words)


def _expect_refused(ui: Page, action: str, where: str, body_locator: str) -> None:
    """Check / export of a draft say it is a draft and point at the draft panel, which names what is wrong
    (the editor refuses it itself since designwalk2: no request, no 422 in the console; nothing downloaded)."""
    expect(ui.page.locator(body_locator)).to_contain_text(f"Not {action}", timeout=60_000)
    expect(ui.page.locator(body_locator)).to_contain_text("draft panel")
    expect(ui.page.locator("#draft-panel")).to_contain_text(where)


def test_session_draft_fix_check_export(browser, server, tmp_path):
    """The short session: a half-finished formation is saved as a draft (the store keeps it with its
    problems), check and export refuse it saying what is wrong, it survives a reload as a draft, and
    once fixed it checks and exports."""
    import httpx

    ui = Page(browser, server, tmp_path)
    page = ui.page
    try:
        _create_show(ui, "Draft session", 9)
        expect(page.locator("#draft-badge")).to_be_hidden()
        # Half-finished: scaled so far that part of it is underground.
        page.fill("#scale-input", "1500")
        page.get_by_role("button", name="Scale the selection").click()
        below = sum(p[2] < 0 for p in ui.state("s.formation.points"))
        assert below > 0
        page.keyboard.press("Control+s")
        expect(page.locator("#save-status")).to_contain_text("Saved as a draft")
        expect(page.locator("#dirty-indicator")).to_be_hidden()
        where = 'formation 1 "Formation 1", point'
        _expect_draft(ui, where, f"{below} points below 0 m")
        show_id = ui.state("s.meta.id")
        stored = httpx.get(f"{server}/api/shows/{show_id}").json()
        assert stored["draft"] is True and stored["revision"] == 2
        assert stored["show"]["formations"][0]["points"] == ui.state("s.formation.points")
        ui.shot("session-draft-saved")

        # Check and export refuse the draft, saying what is wrong.
        page.get_by_role("button", name="Check the show").click()
        _expect_refused(ui, "checked", where, "#report-body")
        page.select_option("#export-format", "skybrush-csv")
        page.get_by_role("button", name="Export in the chosen format").click()
        _expect_refused(ui, "exported", where, "#export-error")
        ui.shot("session-draft-refused")

        # The draft survives a reload (it is the stored show, not this tab's memory).
        page.reload()
        expect(page.locator("#show-title")).to_have_text("Draft session")
        _expect_draft(ui, where)
        expect(page.locator('.tl-card[data-index="0"] .field-error')).to_contain_text("below the ground")
        # The show list marks it as a draft.
        page.get_by_role("button", name="Shows: open, create, rename, delete, import").click()
        row = page.locator("#shows-tbody tr", has=page.get_by_role("button", name="Open show Draft session"))
        expect(row.locator(".draft-tag")).to_have_text("draft")
        page.locator("#btn-shows-close").click()
        expect(page.locator("#dlg-shows")).to_be_hidden()
        # So does the revision history: revision 2 (the draft), not revision 1.
        page.locator("#history-panel summary").click()
        revisions = page.get_by_role("list", name="Revisions").locator("li")
        expect(revisions).to_have_count(2)
        expect(revisions.nth(0)).to_contain_text("r2")
        expect(revisions.nth(0)).to_contain_text("· draft")
        expect(revisions.nth(1)).not_to_contain_text("draft")
        page.locator("#history-panel summary").click()
        # Clicking a problem takes the user to its formation.
        page.get_by_role("button", name="Add a formation").click()
        assert ui.state("s.current") == 1
        page.get_by_role("list", name="What is wrong with the draft").get_by_role("button").first.click()
        assert ui.state("s.current") == 0

        # Fixed: raise the formation above the floor, save: a show again.
        page.get_by_role("button", name="Undo Add formation").click()
        assert ui.state("s.show.formations.length") == 1
        lowest = min(p[2] for p in ui.state("s.formation.points"))
        page.evaluate(f"""() => {{ const s = window.swarmshow.state;
            s.edit("Raise", () => {{ s.formation.points = s.formation.points.map((p) => [p[0], p[1], p[2] +
              {3.0 - lowest}]); }}); }}""")
        page.keyboard.press("Control+s")
        expect(page.locator("#save-status")).to_contain_text("Saved · revision")
        expect(page.locator("#draft-badge")).to_be_hidden()
        expect(page.locator("#draft-panel")).to_be_hidden()
        assert httpx.get(f"{server}/api/shows/{show_id}").json()["draft"] is False
        page.get_by_role("button", name="Check the show").click()
        expect(page.locator("#report-body")).to_contain_text("Minimum distance", timeout=120_000)
        page.select_option("#export-format", "skybrush-csv")  # the page was reloaded
        with page.expect_download(timeout=120_000) as dl:
            page.get_by_role("button", name="Export in the chosen format").click()
        assert dl.value.suggested_filename.endswith(".zip")
        expect(page.locator("#export-error")).to_be_empty()
        ui.shot("session-draft-fixed")
        print(f"screenshots: {SHOTS}/session-draft-*.png")
    finally:
        ui.close()


def _audience_camera(frame) -> None:
    """Choose the viewer's audience camera (front view from the audience side)."""
    frame.get_by_role("combobox", name="Camera").click()
    frame.get_by_role("option", name="audience").click()


def test_a_half_finished_show_saved_as_a_copy_after_a_conflict_is_a_draft(browser, server, tmp_path):
    """A stale save of a half-finished show, "Save mine as a copy": the copy keeps the work as a draft
    (it was refused outright before drafts)."""
    import httpx

    ui = Page(browser, server, tmp_path)
    page = ui.page
    try:
        _create_show(ui, "Copy draft", 4)
        show_id = ui.state("s.meta.id")
        page.evaluate("""() => { const s = window.swarmshow.state;
            s.edit("Stack", () => { s.formation.points[1] = s.formation.points[0].slice(); }); }""")
        rec = httpx.get(f"{server}/api/shows/{show_id}").json()
        rec["show"]["formations"][0]["hold_s"] = 9
        assert httpx.put(f"{server}/api/shows/{show_id}", json={"revision": 1, "show": rec["show"]}).status_code == 200
        page.keyboard.press("Control+s")
        page.locator("#dlg-conflict").get_by_role("button", name="Save my version as a new show").click()
        expect(page.locator("#show-title")).to_have_text("Copy draft (copy)")
        expect(page.locator("#draft-badge")).to_be_visible()
        _expect_draft(ui, 'formation 1 "Formation 1", points', "closer than")
        copy = httpx.get(f"{server}/api/shows/{ui.state('s.meta.id')}").json()
        assert copy["draft"] is True and copy["show"]["formations"][0]["points"][1] == \
            copy["show"]["formations"][0]["points"][0]
    finally:
        ui.close()


def _viewer_time(frame) -> float:
    text = frame.get_by_text(re.compile(r"Time\s+[\d.]+\s*/")).first.inner_text()
    return float(re.search(r"Time\s+([\d.]+)", text).group(1))


@pytest.mark.slow
@pytest.mark.timeout(2400)
def test_scripted_session_300_drones(browser, server, tmp_path):
    import httpx
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
        # 4. Freehand. A first, short stroke cannot hold 300 drones 3 m apart: the half-finished
        #    show is saved as a draft, check refuses it saying what is wrong, and a zigzag long
        #    enough for 300 drones fixes it.
        page.get_by_role("button", name="Add a formation").click()
        page.get_by_role("radio", name="Freehand stroke (D)").click()
        page.evaluate("() => { const v = window.swarmshow.view; v.scale = 2; v.center = [0, 75]; v.redraw(); }")
        box = page.locator("#canvas").bounding_box()
        cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        page.mouse.move(cx - 60, cy + 20)
        page.mouse.down()
        for k in range(1, 13):
            page.mouse.move(cx - 60 + 10 * k, cy + 20 - 3 * k)
        page.mouse.up()
        assert ui.state("s.formation.points.length") == DRONES
        expect(page.locator("#st-spacing")).to_contain_text("closer than")
        page.keyboard.press("Control+s")
        expect(page.locator("#save-status")).to_contain_text("Saved as a draft", timeout=60_000)
        _expect_draft(ui, 'formation 4 "Formation 4", points', "closer than min_distance_m")
        assert httpx.get(f"{server}/api/shows/{ui.state('s.meta.id')}").json()["draft"] is True
        page.get_by_role("button", name="Check the show").click()
        _expect_refused(ui, "checked", 'formation 4 "Formation 4", points', "#report-body")
        ui.shot("session-4-draft")
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

        # Save (a show again, not a draft), check, simulate.
        page.keyboard.press("Control+s")
        expect(page.locator("#dirty-indicator")).to_be_hidden(timeout=60_000)
        expect(page.locator("#save-status")).to_contain_text("Saved · revision")
        expect(page.locator("#draft-badge")).to_be_hidden()
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
        assert resp.value.status == 200, resp.value.text
        assert resp.value.json()["source"] == "simulated"
        frame = _preview_panel(page)  # its panel unfolded (the editor folds viser's bottom sheet)
        frame.get_by_text(f"{DRONES} drones").first.wait_for(timeout=120_000)
        _audience_camera(frame)
        expect(frame.get_by_role("combobox", name="Source")).to_have_value("simulated")
        frame.get_by_role("button", name="Play").click()
        # Waits are on the clocks (a loaded machine plays late, never wrong), not on fixed sleeps.
        wait_until("tab 1 to play", lambda: _viewer_time(frame) > 2.0, timeout_s=120)
        # A second tab opens the viewer on the same show; each tab keeps its own clock.
        other = Page(browser, server, tmp_path)
        try:
            tab2 = other.page
            tab2.goto(f"{server}/viser/")
            tab2.get_by_text(f"{DRONES} drones").first.wait_for(timeout=120_000)
            _audience_camera(tab2)
            expect(tab2.get_by_role("combobox", name="Source")).to_have_value("simulated")
            t2 = _viewer_time(tab2)
            # Tab 1 plays on while tab 2, paused, stays where it is.
            t1_now = _viewer_time(frame)
            t1 = wait_until("tab 1's clock to run on", lambda: (t := _viewer_time(frame)) > t1_now + 1.5 and t,
                            timeout_s=120)
            assert _viewer_time(tab2) == t2 and t1 > t2 + 1.0, (t1, t2)
            # Tab 2 plays and pauses on its own; tab 1 pauses: both clocks stay apart and still.
            tab2.get_by_role("button", name="Play").click()
            wait_until("tab 2 to play", lambda: _viewer_time(tab2) > t2 + 1.0, timeout_s=120)
            tab2.get_by_role("button", name="Pause").click()
            frame.get_by_role("button", name="Pause").click()
            for tab in (frame, tab2):  # paused: the button says Play again
                tab.get_by_role("button", name="Play").wait_for()
            t1, t2 = _viewer_time(frame), _viewer_time(tab2)
            time.sleep(1.0)  # still a second later
            assert (_viewer_time(frame), _viewer_time(tab2)) == (t1, t2)
            assert t2 > 0.5 and abs(t1 - t2) > 0.5, (t1, t2)
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
        print(f"screenshots: {SHOTS}/session-*.png")
    finally:
        ui.close()
