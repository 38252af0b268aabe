"""Issue 21 item 3 in Chromium: a drone group made from the selection, renamed in the groups panel, flown by a
subset formation whose other drones park behind it; the server's check says it is safe, and the saved show file
carries the group and the formation's selection. Against a live loopback server; every request stays on 127.0.0.1."""

from __future__ import annotations

import httpx
import pytest

from formations import parse_show
from tests.live_server import BROWSER_MARKS, server_for
from tests.test_editor_browser import Page, _check, _type_points

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect


server = server_for("groups-data", viewer=False)


def test_subset_formation_made_in_the_editor_checks_safe(ui: Page) -> None:
    page = ui.page
    page.goto(ui.base + "/")
    page.wait_for_selector("#dlg-shows[open]")
    page.fill("#new-name", "Subset")
    page.fill("#new-drones", "16")
    page.dispatch_event("#new-drones", "input")
    page.fill("#new-rows", "4")
    page.fill("#new-cols", "4")
    page.fill("#new-spacing", "4")
    page.get_by_role("button", name="Create the show").click()
    expect(page.locator("#dlg-shows")).to_be_hidden()
    wall = [(4.0 * c - 6.0, 0.0, 30.0 + 4.0 * r) for r in range(4) for c in range(4)]
    _type_points(ui, wall)

    # A group from the selected points: without a check, drone i flies to point i.
    page.evaluate("() => window.swarmshow.state.setSelection([0, 1, 2, 3])")
    page.get_by_label("New drone group name").fill("front")
    page.get_by_role("button", name="Make a drone group from the selection").click()
    assert ui.state("s.show.groups") == {"front": [0, 1, 2, 3]}
    expect(page.get_by_role("list", name="Drone groups")).to_contain_text("front · 4 drones")

    # Rename it in the panel (the dialog asks for the new name).
    page.get_by_role("button", name="Rename group front").click()
    page.get_by_label("New name").fill("bottom row")
    page.get_by_role("button", name="OK").click()
    expect(page.get_by_role("list", name="Drone groups")).to_contain_text("bottom row · 4 drones")
    assert ui.state("s.show.groups") == {"bottom row": [0, 1, 2, 3]}

    # A second formation flown by that group only, the others parked behind it.
    page.get_by_role("button", name="Add a formation").click()
    page.get_by_label("Drones flying this formation").select_option("group")
    page.get_by_label("Group flying this formation").select_option("bottom row")
    page.get_by_label("What the other drones do").select_option("park")
    line = [(6.0 * c - 9.0, -15.0, 25.0) for c in range(4)]
    _type_points(ui, line)
    k = ui.state("s.current")
    assert ui.state(f"s.show.formations[{k}].drones") == {"group": "bottom row"}
    assert ui.state(f"s.show.formations[{k}].others") == "park"
    # A group a formation flies cannot be deleted.
    page.get_by_role("button", name="Remove group bottom row").click()
    assert ui.state("s.show.groups") == {"bottom row": [0, 1, 2, 3]}

    report = _check(ui)
    expect(report.locator(".report-ok, .report-bad").first).to_have_text("✓ Safe: every limit holds")

    # Saved, the show file carries the group and the formation's selection, and validates on the server's model.
    page.keyboard.press("Control+s")
    expect(page.locator("#dirty-indicator")).to_be_hidden(timeout=30_000)
    show_id = ui.state("s.meta.id")
    doc = httpx.get(f"{ui.base}/api/shows/{show_id}", timeout=30).json()
    doc = doc.get("show", doc)
    show = parse_show(doc)
    assert show.groups == {"bottom row": [0, 1, 2, 3]}
    assert show.formations[k].drones is not None and show.formations[k].others == "park"
    assert not ui.foreign
