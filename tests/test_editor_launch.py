"""The editor's launch-layout panel in Chromium (Playwright) against a live loopback server: launch boxes with
a wave preview, the check's takeoff waves on the timeline, CSV import and its errors."""

from __future__ import annotations

import pytest

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_editor_browser import Page, _check, _create_show

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect


server = server_for("launch-data", viewer=False)


def test_launch_boxes_preview_waves_and_the_check_plans_them(ui: Page):
    page = ui.page
    _create_show(ui, "Boxed", 16)
    page.locator("#launch-panel summary").click()
    page.get_by_label("Drones per launch box").fill("8")
    page.get_by_label("Drone spacing inside a box, metres").fill("0.8")
    page.get_by_label("Distance between box centres, metres").fill("6")
    page.get_by_role("button", name="Use launch boxes").click()
    page.wait_for_function("() => window.swarmshow.state.show.home.boxes?.per_box === 8")
    assert ui.state("s.show.home.boxes.grid.cols * s.show.home.boxes.grid.rows") == 2
    # The preview: 8 waves (a box of 8 at 0.8 m is one clique under the 3 m minimum).
    expect(page.locator("#launch-summary")).to_contain_text("in 8 waves")
    report = _check(ui)
    expect(report.locator(".report-ok")).to_have_text("✓ Safe: every limit holds")
    expect(page.locator(".tl-end").first).to_contain_text("8 waves")
    ui.shot("editor-launch-boxes")
    # Undo goes back to the grid, and everybody climbs at once again.
    page.keyboard.press("Control+z")
    page.wait_for_function("() => !!window.swarmshow.state.show.home.grid")
    expect(page.locator("#launch-summary")).to_contain_text("all at once")


def test_home_csv_import_and_its_error_names_the_line(ui: Page, tmp_path):
    page = ui.page
    _create_show(ui, "CSV homes", 4)
    page.locator("#launch-panel summary").click()
    good = tmp_path / "homes.csv"
    good.write_text("Name,x,y,z\nA,0,0,0\nB,3,0,0\nC,0,3,0\nD,3,3,0\nE,6,0,0\n")
    page.get_by_label("Import home positions from a CSV file (Name,x,y,z or x,y[,z] rows)").set_input_files(str(good))
    page.wait_for_function("() => window.swarmshow.state.show.home.points?.length === 5")
    assert ui.state("s.show.home.points[3]") == [3, 3, 0]
    bad = tmp_path / "bad.csv"
    bad.write_text("1,2\n3,oops\n")
    page.get_by_label("Import home positions from a CSV file (Name,x,y,z or x,y[,z] rows)").set_input_files(str(bad))
    expect(page.locator("#launch-error")).to_contain_text("line 2")
    assert ui.state("s.show.home.points.length") == 5  # nothing lost
