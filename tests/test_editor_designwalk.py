"""Defects a show designer's walk through the editor found (Chromium against a live server on loopback):

* in a narrow window (a split screen, a small laptop) the top bar ran off the right edge: Export, its format
  and the shortcuts button could not be reached with the mouse;
* a mesh imported at the smallest size that fits (its closest points exactly the minimum distance apart) was
  rounded to millimetres in the editor, which brought pairs closer than the minimum distance: the save became a
  draft that check, simulate and export refuse; so did turning or nudging such a formation (each edit rounds the
  points it moves); and a refused vertices import said "at undefined m";
* a source with nothing to place drones on (blank text, an all-black image, an SVG without paths) was answered
  "at most 0 fit. Use fewer drones or a smaller minimum distance", hiding the server's reason;
* a drone count over the show file's limit (30000 for 300) offered "Fit them", which froze the tab fitting 30000
  points into every formation; the count is marked at once instead;
* a number field of a formation source left empty was sent as 0 and answered in the API's words
  ("size_m: Input should be greater than or equal to 0.01", "points must be an integer in [2, 1000], got 0");
* a transition duration typed wrong ("abc", -1) closed its dialog with a passing toast: the designer had to find
  the transition and open it again; the dialog now stays open saying what is wrong;
* a new show with its home grid closer than the 3 m default lowered the show's minimum distance to that spacing
  without a word (a typo of 1 for 10 halves the safety margin): the editor now says so when it creates the show;
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

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


def test_narrow_window_keeps_every_top_bar_control_on_screen(ui: Page):
    page = ui.page
    ui.open_show(show_doc("Narrow window"))
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


#: A unit cube: 8 vertices, 6 quadrilateral faces.
CUBE_OBJ = "\n".join(f"v {x} {y} {z}" for x in (0, 1) for y in (0, 1) for z in (0, 1)) + (
    "\nf 1 2 4 3\nf 5 6 8 7\nf 1 2 6 5\nf 3 4 8 7\nf 1 3 7 5\nf 2 4 8 6\n")
TRIANGLE_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def _eight_drones(name: str) -> dict:
    return {"format": "swarmshow/1", "name": name, "drones": 8,
            "home": {"grid": {"rows": 3, "cols": 3, "spacing_m": 4.5}},
            "formations": [{"name": "square", "hold_s": 2.0, "color": "#00ff00",
                            "points": [[x, 0.0, z] for x in (0.0, 5.0, 10.0, 15.0) for z in (10.0, 15.0)]}]}


def _closest_m(points: list[list[float]]) -> float:
    """Brute force over all pairs."""
    return min(math.dist(a, b) for a, b in itertools.combinations(points, 2))


def test_mesh_at_its_fitting_size_saves_valid(ui: Page, tmp_path: Path):
    page = ui.page
    show_id = ui.open_show(_eight_drones("Mesh import"))
    (tmp_path / "cube.obj").write_text(CUBE_OBJ)
    (tmp_path / "triangle.obj").write_text(TRIANGLE_OBJ)
    page.locator("summary", has_text="Mesh / point cloud").click()
    import_button = page.get_by_role("button", name="Replace the formation with points from the mesh or point file")
    # Eight drones on a triangle's three vertices: refused, saying so without an undefined size.
    page.set_input_files("#mesh-file", str(tmp_path / "triangle.obj"))
    page.select_option("#mesh-mode", "vertices")
    import_button.click()
    error = page.locator('[data-error-for="mesh"]')
    expect(error).to_contain_text("at most 3 fit")
    assert "undefined" not in error.text_content()
    # The cube's volume at the smallest size that fits (the size left empty): the server spaces the closest
    # points the minimum distance apart, exactly.
    page.set_input_files("#mesh-file", str(tmp_path / "cube.obj"))
    page.select_option("#mesh-mode", "volume")
    with page.expect_response(lambda r: r.url.endswith("/api/formations/mesh")) as made:
        import_button.click()
    served = made.value.json()["points"]
    assert _closest_m(served) == pytest.approx(3.0, abs=1e-5)
    expect(page.locator("#toast")).to_contain_text("From cube.obj")
    expect(page.locator("#st-spacing")).to_contain_text("spacing ≥ 3 m")
    page.get_by_role("button", name="Save").click()
    expect(page.locator("#save-status")).to_contain_text("Saved")
    stored = httpx.get(f"{ui.base}/api/shows/{show_id}").json()
    assert not stored["draft"] and not stored["problems"], stored["problems"]
    points = stored["show"]["formations"][0]["points"]
    assert len(points) == 8 and _closest_m(points) >= 3.0 - 1e-9
    # Turned (the Transform panel, then the keys) and nudged: still exactly as far apart, so still valid.
    page.fill("#rotate-input", "15")
    page.get_by_role("button", name="Rotate the selection").click()
    page.locator("#canvas").focus()
    page.keyboard.press("[")
    page.keyboard.press("Control+a")
    page.keyboard.press("ArrowUp")
    expect(page.get_by_role("button", name="Undo")).to_have_attribute("title", "Undo Nudge 8 points (Ctrl+Z)")
    page.get_by_role("button", name="Save").click()
    expect(page.locator("#save-status")).to_contain_text("revision 3")
    stored = httpx.get(f"{ui.base}/api/shows/{show_id}").json()
    assert not stored["draft"] and not stored["problems"], stored["problems"]
    turned = stored["show"]["formations"][0]["points"]
    assert turned != points and _closest_m(turned) >= 3.0 - 1e-9


def test_a_source_with_nothing_to_draw_says_why(ui: Page, tmp_path: Path):
    from PIL import Image

    page = ui.page
    ui.open_show(_eight_drones("Nothing to draw"))
    Image.new("RGB", (40, 20), "black").save(tmp_path / "black.png")
    (tmp_path / "empty.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 10 10">'
                                        "<text>hi</text></svg>")
    page.locator("summary", has_text="Text").first.click()
    page.fill("#text-input", "   ")
    page.get_by_role("button", name="Replace the formation with this text").click()
    text_error = page.locator('[data-error-for="text"]')
    expect(text_error).to_contain_text("empty")
    assert "fewer drones" not in text_error.text_content()
    page.evaluate("() => { document.querySelector('[data-error-for=\"text\"]').textContent = ''; }")
    page.get_by_role("button", name="Size the text to fit all drones at the minimum distance").click()
    expect(text_error).to_contain_text("empty")
    assert "64 times" not in text_error.text_content()
    page.locator("summary", has_text="Image / SVG").click()
    upload_error = page.locator('[data-error-for="upload"]')
    for name, reason in [("black.png", "no bright or opaque pixels"), ("empty.svg", "no paths or shapes")]:
        page.set_input_files("#upload-file", str(tmp_path / name))
        page.get_by_role("button", name="Replace the formation with the uploaded drawing").click()
        expect(upload_error).to_contain_text(reason)
        assert "fewer drones" not in upload_error.text_content()


def test_a_drone_count_over_the_limit_is_marked_not_fitted(ui: Page):
    page = ui.page
    ui.open_show(_eight_drones("Too many drones"))
    page.locator("#settings-panel summary").click()
    page.fill("#set-drones", "30000")
    page.locator("#set-drones").dispatch_event("change")
    expect(page.locator('[data-error-for="drones"]')).to_contain_text("20000")
    # No offer to fit the formations to a count the show file refuses; the page answers at once.
    page.wait_for_timeout(300)
    assert not page.locator("#dlg-confirm").is_visible()
    assert page.evaluate("() => window.swarmshow.state.show.drones") == 30000
    # Back to a count within the limit: the mark goes, the formations are offered a fit as before.
    page.fill("#set-drones", "12")
    page.locator("#set-drones").dispatch_event("change")
    expect(page.locator("#dlg-confirm")).to_be_visible()
    expect(page.locator('[data-error-for="drones"]')).to_be_hidden()


def test_an_empty_source_field_is_named_before_asking_the_server(ui: Page):
    page = ui.page
    ui.open_show(_eight_drones("Empty fields"))
    asked: list[str] = []
    page.on("request", lambda r: asked.append(r.url) if "/api/formations/" in r.url else None)
    error = page.locator('[data-error-for="shape"]')
    apply = page.get_by_role("button", name="Replace the formation with this shape")
    page.fill("#shape-size", "")
    apply.click()
    expect(error).to_have_text("Size (m): enter a number.")
    page.get_by_role("button", name="Size the shape to fit all drones at the minimum distance").click()
    expect(error).to_have_text("Size (m): enter a number.")
    page.fill("#shape-size", "40")
    page.select_option("#shape-kind", "star")
    page.fill("#shape-param", "")
    apply.click()
    expect(error).to_have_text("Tips: enter a number.")
    page.locator("summary", has_text="Mesh / point cloud").click()
    page.fill("#mesh-z", "")
    page.set_input_files("#mesh-file", files=[{"name": "p.xyz", "mimeType": "text/plain", "buffer": b"0 0 0\n"}])
    page.get_by_role("button", name="Replace the formation with points from the mesh or point file").click()
    expect(page.locator('[data-error-for="mesh"]')).to_have_text("Centre height (m): enter a number.")
    assert asked == []
    # Filled in again, the shape is made.
    page.locator("summary", has_text="Shape preset").click()
    page.fill("#shape-param", "5")
    page.fill("#shape-size", "30")
    apply.click()
    expect(page.locator("#toast")).to_contain_text("Shape: star")


def test_a_wrong_transition_duration_keeps_its_dialog_open(ui: Page):
    page = ui.page
    show_id = ui.open_show(_eight_drones("Transition duration"))
    page.get_by_role("button", name="Add a formation").click()
    page.locator("#timeline-list li.tl-transition").nth(1).click()
    dialog = page.locator("#dlg-confirm")
    expect(dialog).to_be_visible()
    field = page.locator("#confirm-input")
    for typed, said in [("abc", "must be a number of seconds"), ("-1", "must be at least 0.01 s")]:
        field.fill(typed)
        page.get_by_role("button", name="OK").click()
        expect(dialog).to_be_visible()
        expect(dialog.get_by_role("alert")).to_contain_text(said)
    field.fill("9")
    field.press("Enter")
    expect(dialog).to_be_hidden()
    expect(page.locator("#timeline-list li.tl-transition").nth(1)).to_contain_text("9 s fixed")
    page.get_by_role("button", name="Save").click()
    expect(page.locator("#save-status")).to_contain_text("Saved")
    stored = httpx.get(f"{ui.base}/api/shows/{show_id}").json()["show"]
    assert stored["formations"][1]["transition_s"] == 9
    # Asked again, the dialog opens without the last message.
    page.locator("#timeline-list li.tl-transition").nth(1).click()
    expect(dialog).to_be_visible()
    expect(dialog.get_by_role("alert")).to_be_hidden()
    page.get_by_role("button", name="Cancel").click()


def test_a_new_show_says_when_its_spacing_lowers_the_minimum_distance(ui: Page):
    page = ui.page
    page.goto(ui.base + "/")
    expect(page.locator("#dlg-shows")).to_be_visible()
    page.fill("#new-name", "Tight home grid")
    page.fill("#new-drones", "6")
    page.dispatch_event("#new-drones", "input")
    page.fill("#new-spacing", "1.5")
    page.get_by_role("button", name="Create the show").click()
    expect(page.locator("#show-title")).to_have_text("Tight home grid")
    expect(page.locator("#toast")).to_contain_text("minimum distance 1.5 m")
    assert page.evaluate("() => window.swarmshow.state.show.settings.min_distance_m") == 1.5
