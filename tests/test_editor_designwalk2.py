"""More defects a show designer's walk through the editor found (Chromium against a live server on loopback):

* light-effect and launch-box fields took values the show file refuses (an effect starting at -5 s, a strobe duty
  of 5, 0 drones per box, 0.1 m between the drones of a box) with no mark: only the save said so, turning the
  show into a draft whose panel named them in the API's words; they are now marked at once, as the settings are;
* Check, Simulate and Export on a draft show asked the server anyway (a 422 in the console at each press); the
  editor knows it is a draft, says so and points at the draft panel;
* the first music upload on a server (librosa's beat tracker compiles once per machine, 1-2 min) said only
  "Analysing music.wav…" for minutes; after a short wait it now says why, and the note goes when the answer comes.
"""

from __future__ import annotations

import time
from html.parser import HTMLParser
from pathlib import Path

import pytest
from pydantic import ValidationError

from formations._effects import LightEffect, StrobeKind
from formations._launch import BoxGrid, LaunchBoxes
from formations._show import ShowFile
from tests.live_server import BROWSER_MARKS, server_for
from tests.test_api_jobs import show_doc
from tests.test_editor_browser import Page

pytestmark = BROWSER_MARKS
sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect

server = server_for("designwalk2-data")


def _limit(model: type, field: str, key: str) -> str:
    """The bound the show file's rule puts on a field (its JSON schema), written as the editor writes numbers."""
    return f"{model.model_json_schema()['properties'][field][key]:g}"


def _puts(page) -> list[str]:
    seen: list[str] = []
    page.on("request", lambda r: seen.append(r.url) if r.method == "PUT" else None)
    return seen


def test_effect_and_launch_fields_out_of_range_are_marked_at_once(ui: Page):
    page = ui.page
    ui.open_show(show_doc("Effect limits"))
    saves = _puts(page)
    page.locator("#effects-panel summary").click()
    page.select_option("#fx-kind", "strobe")
    page.get_by_role("button", name="Add a light effect").click()
    start = page.get_by_role("spinbutton", name="Effect start (s)", exact=True)
    duty = page.get_by_role("spinbutton", name="Effect duty", exact=True)
    # Duty's bounds are strict (0 < duty < 1): 1 is refused as 5 is.
    with pytest.raises(ValidationError):
        StrobeKind(kind="strobe", color="#ffffff", duty=1.0)
    for field, typed, said in [(start, "-5", f"at least {_limit(LightEffect, 'start_s', 'minimum')}"),
                               (duty, "5", f"less than {_limit(StrobeKind, 'duty', 'exclusiveMaximum')}"),
                               (duty, "1", f"less than {_limit(StrobeKind, 'duty', 'exclusiveMaximum')}")]:
        field.fill(typed)
        field.dispatch_event("change")
        # The form is drawn again after the edit: the mark is on the new field, next to it.
        expect(field).to_have_class("has-error")
        expect(page.locator("#fx-form .field-error").filter(has_text=said)).to_have_count(1)
    effect = page.evaluate("() => window.swarmshow.state.show.lights.effects[0]")
    assert effect["start_s"] == -5 and effect["effect"]["duty"] == 1
    # Back inside: no mark.
    start.fill("1")
    start.dispatch_event("change")
    expect(start).not_to_have_class("has-error")

    page.locator("#launch-panel summary").click()
    per_box = page.locator("#launch-per-box")
    spacing = page.locator("#launch-box-spacing")
    error = page.locator("#launch-error")
    per_box.fill("0")
    per_box.dispatch_event("change")
    expect(per_box).to_have_class("has-error")
    expect(error).to_have_text(f"Drones per box: at least {_limit(LaunchBoxes, 'per_box', 'minimum')}")
    spacing.fill("0.1")
    spacing.dispatch_event("change")
    expect(spacing).to_have_class("has-error")
    per_box.fill("8")
    per_box.dispatch_event("change")
    expect(per_box).not_to_have_class("has-error")
    expect(error).to_have_text(f"Spacing in box (m): at least {_limit(LaunchBoxes, 'spacing_m', 'minimum')}")
    spacing.fill("0.8")
    spacing.dispatch_event("change")
    expect(error).to_be_empty()
    # Marked before any save (the save would have made a draft to say so).
    assert saves == []


def test_check_simulate_export_of_a_draft_point_at_the_draft_panel(ui: Page):
    page = ui.page
    doc = show_doc("Draft actions")
    doc["settings"]["max_speed_xy_mps"] = 500.0  # over the show file's 100 m/s
    ui.open_show(doc, draft=True)
    expect(page.locator("#draft-panel")).to_be_visible()
    asked: list[str] = []
    page.on("request", lambda r: asked.append(r.url) if r.method == "POST" or "/export/" in r.url else None)
    page.get_by_role("button", name="Check the show").click()
    expect(page.locator("#report-body")).to_contain_text("draft panel")
    expect(page.locator("#report-body")).to_contain_text("1 problem")
    page.get_by_role("button", name="Simulate the flight").click()
    expect(page.locator("#sim-body")).to_contain_text("draft panel")
    page.get_by_role("button", name="Export in the chosen format").click()
    expect(page.locator("#export-error")).to_contain_text("draft panel")
    page.get_by_role("button", name="3D preview", exact=True).click()
    expect(page.locator('[data-error-for="preview"]')).to_contain_text("draft panel")
    page.wait_for_timeout(300)
    assert [u for u in asked if "/api/" in u] == []
    # Saved valid, Check asks the server again.
    page.evaluate("() => { document.querySelector('#settings-panel').open = true; }")
    page.fill("#set-vxy", "10")
    page.locator("#set-vxy").dispatch_event("change")
    with page.expect_request(lambda r: r.url.endswith("/check")):
        page.get_by_role("button", name="Check the show").click()


def test_a_slow_first_music_analysis_says_why(ui: Page):
    page = ui.page
    show_id = ui.open_show(show_doc("Slow music"))
    held = []
    # The PUT is held here (a cold beat-tracker compile takes minutes) and answered late, in the API's shape.
    page.route(f"**/api/shows/{show_id}/audio?filename=*", lambda route: held.append(route))
    info = {"filename": "music.wav", "duration_s": 3.0, "tempo_bpm": 120.0, "sha256": "0" * 64,
            "sample_rate": 22050, "channels": 1}
    page.route(f"**/api/shows/{show_id}/audio/info", lambda route: route.fulfill(json=info))
    page.route(f"**/api/shows/{show_id}/audio/analysis",
               lambda route: route.fulfill(json={"duration_s": 3.0, "tempo_bpm": 120.0, "beats_s": [0.5, 1.0],
                                                 "onsets_s": [], "peaks": [], "peaks_per_s": 10}))
    status = page.locator("#music-status")
    note = "compiles the beat tracker (1-2 min)"
    t0 = time.monotonic()
    page.set_input_files("#music-file", files=[{"name": "music.wav", "mimeType": "audio/wav", "buffer": b"RIFF"}])
    expect(status).to_have_text("Analysing music.wav…")
    expect(status).to_contain_text(note, timeout=15_000)
    waited_s = time.monotonic() - t0
    assert 7.0 <= waited_s <= 12.0, waited_s
    expect(status).to_contain_text("later uploads take seconds")
    assert len(held) == 1
    held[0].fulfill(json=info)
    expect(status).to_contain_text("music.wav · 3.0 s · 120.0 BPM")
    expect(status).not_to_contain_text(note)


class _Inputs(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.inputs: dict[str, dict[str, str | None]] = {}

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "input" and a.get("id"):
            self.inputs[str(a["id"])] = a


@pytest.mark.parametrize(("input_id", "model", "field"), [
    ("launch-per-box", LaunchBoxes, "per_box"), ("launch-box-spacing", LaunchBoxes, "spacing_m"),
    ("launch-grid-spacing", BoxGrid, "spacing_m"), ("set-drones", ShowFile, "drones"),
])
def test_the_box_and_drone_count_fields_carry_the_show_files_limits(input_id: str, model: type, field: str):
    """The marks use each field's min/max: they are the show file's own bounds (its JSON schema)."""
    parser = _Inputs()
    parser.feed((Path(__file__).resolve().parent.parent / "frontend" / "index.html").read_text(encoding="utf-8"))
    attrs = parser.inputs[input_id]
    bound = model.model_json_schema()["properties"][field]
    assert float(attrs["min"] or "nan") == bound["minimum"]
    assert float(attrs["max"] or "nan") == bound["maximum"]
