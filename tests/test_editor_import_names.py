"""The editor names an imported formation after its source (file stem, text), never over a name the
designer typed; driven with Playwright against a live server on loopback."""

from __future__ import annotations

import pytest

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_editor_browser import Page, _create_show

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect

server = server_for("names-data", viewer=False)

SVG = """<svg xmlns="http://www.w3.org/2000/svg" width="100" height="100" viewBox="0 0 100 100">
<circle cx="50" cy="50" r="40" fill="none" stroke="#ff0000"/></svg>"""


def _open(ui: Page, summary: str) -> None:
    details = ui.page.locator("details", has=ui.page.locator("summary", has_text=summary))
    if details.get_attribute("open") is None:
        ui.page.locator("summary", has_text=summary).click()
    expect(details).to_have_attribute("open", "")


def _upload(ui: Page, filename: str) -> None:
    path = ui.tmp / filename
    path.write_text(SVG)
    _open(ui, "Image / SVG")
    ui.page.set_input_files("#upload-file", str(path))
    before = ui.state("s.undoStack.length")
    ui.page.get_by_role("button", name="Replace the formation with the uploaded drawing").click()
    ui.page.wait_for_function(f"() => window.swarmshow.state.undoStack.length > {before}", timeout=60_000)


def _name(ui: Page, k: int):
    return ui.page.get_by_label(f"Name of formation {k + 1}", exact=True)


def test_imports_name_the_formation_unless_the_designer_did(ui: Page):
    page = ui.page
    _create_show(ui, "Import names", 12)
    expect(_name(ui, 0)).to_have_value("Formation 1")
    # A default name gives way to the file's stem, and to the next file's (the name was the import's).
    _upload(ui, "Company Logo.svg")
    expect(_name(ui, 0)).to_have_value("Company Logo")
    _upload(ui, "star.svg")
    expect(_name(ui, 0)).to_have_value("star")
    # A typed name stays.
    _name(ui, 0).fill("Finale")
    _name(ui, 0).press("Tab")
    page.wait_for_function("() => window.swarmshow.state.show.formations[0].name === 'Finale'")
    _upload(ui, "other.svg")
    assert ui.state("s.show.formations[0].name") == "Finale"
    assert ui.state("s.formation.source.file") == "other.svg"
    # A text names a new formation after itself, never taking another's name; one undo restores both.
    page.get_by_role("button", name="Add a formation").click()
    expect(_name(ui, 1)).to_have_value("Formation 2")
    _upload(ui, "Finale.svg")
    expect(_name(ui, 1)).to_have_value("Finale 2")
    _open(ui, "Text")
    page.fill("#text-input", "HI")
    before = ui.state("s.undoStack.length")
    page.get_by_role("button", name="Replace the formation with this text").click()
    page.wait_for_function(f"() => window.swarmshow.state.undoStack.length > {before}", timeout=60_000)
    expect(_name(ui, 1)).to_have_value("HI")
    page.keyboard.press("Control+z")
    expect(_name(ui, 1)).to_have_value("Finale 2")
    assert ui.state("s.formation.source.kind") == "svg"
    assert not ui.errors
