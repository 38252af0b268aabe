"""The editor's single flight with errors on, and the export refusals a designer walk found (after issue 20), in
Chromium against a live server on loopback (the helpers of test_editor_browser):

* a flight flies the chosen error preset with the seed in the seed field; the summary shows the preset and seed,
  a non-zero deviation (the job's own figure, read over HTTP), and the flight plays in 3D beside the plan;
* an export refused with a 422 naming ``formations[k]`` marks that formation's timeline card;
* a QGroundControl export without an origin is caught in the editor (no request, no console error), pointing at
  the origin field, whose altitude keeps the show file's range.
"""

from __future__ import annotations

import json

import httpx
import pytest

from tests.live_server import BROWSER_MARKS, server_for, wait_until
from tests.test_api_forced_short import forced_doc
from tests.test_api_jobs import show_doc
from tests.test_editor_browser import Page

pytestmark = BROWSER_MARKS
sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect

server = server_for("single-flight-data", viewer=True)  # viewer on: the flight plays in 3D


def _console_errors(page) -> list[str]:
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    return errors


def _rows(ui: Page) -> dict[str, tuple[str, str]]:
    rows = ui.page.evaluate("""() => [...document.querySelector('#sim-body table').rows].map(
        (r) => [r.cells[0].textContent, r.cells[1].textContent, r.cells[1].className])""")
    return {label: (value, cls) for label, value, cls in rows}


def test_single_flight_flies_the_preset_with_its_seed_and_plays_in_3d(ui: Page):
    page = ui.page
    errors = _console_errors(page)
    ui.open_show(show_doc("Single flight", hold_s=2.0))
    # The default is a realistic preset, not the ideal vehicle; the disturbance is for the ideal vehicle only.
    assert page.locator("#sim-preset").input_value() == "calm-rtk"
    assert page.locator("#sim-disturbance").is_disabled()
    page.select_option("#sim-preset", "ideal")
    assert page.locator("#sim-disturbance").is_enabled()
    page.select_option("#sim-preset", "gusty-rtk")
    # A bad seed is refused in the editor, beside the field.
    page.fill("#sim-seed", "-3")
    page.get_by_role("button", name="Simulate the flight").click()
    expect(page.locator('[data-error-for="sim-seed"]')).to_contain_text("whole number")
    page.fill("#sim-seed", "17")
    with page.expect_response(lambda r: r.url.endswith("/simulate") and r.request.method == "POST") as posted:
        page.get_by_role("button", name="Simulate the flight").click()
    assert posted.value.request.post_data_json == {"preset": "gusty-rtk", "seed": 17, "controller": "ismc",
                                                   "disturbance": "none"}
    job_id = posted.value.json()["id"]
    expect(page.locator("#sim-percent")).to_have_text("100%", timeout=180_000)
    expect(page.locator("#sim-body")).to_contain_text("Deviation from plan")
    job = httpx.get(f"{ui.base}/api/jobs/{job_id}", timeout=60).json()
    flight = job["result"]["flight"]
    assert flight["preset"] == "gusty-rtk" and flight["seed"] == 17 and flight["tracking_max_m"] > 0.01
    rows = _rows(ui)
    assert rows["Error preset"][0] == "gusty-rtk, seed 17"
    shown_max = float(rows["Deviation from plan (max)"][0].split(" m")[0])
    assert shown_max == pytest.approx(flight["tracking_max_m"], abs=5e-4) and shown_max > 0
    assert rows["Flown min separation"][0] == (f"{flight['flown_min_distance_m']:.2f} m (plan "
                                               f"{flight['planned_min_distance_m']:.2f} m, ≥ 3.0)")
    a, b = flight["flown_min_distance_pair"]
    assert rows["Closest flown pair"][0] == f"drones {a} & {b} at {flight['flown_min_distance_time_s']:.1f} s"

    # The flight plays in the 3D preview: this job's flight (its preset and seed), beside the plan.
    with page.expect_response(lambda r: r.url.endswith("/playback") and r.request.method == "POST",
                              timeout=120_000) as played:
        page.locator("#sim-play-flight").click()
    assert played.value.request.post_data_json == {"source": "simulated", "job_id": job_id}
    assert played.value.status == 200 and played.value.json()["source"] == "simulated", played.value.text()
    expect(page.locator("#preview-wrap")).to_be_visible()
    # It starts at the flight's closest pair (the moment that matters), not at takeoff.
    t_pair = flight["flown_min_distance_time_s"]
    wait_until("the preview at the closest pair", lambda: abs((page.evaluate(
        "() => (window.swarmshow.playhead.preview.viewerState() || {time_s: -1e9}).time_s")) - t_pair) < 0.1,
        timeout_s=90)
    # "New seed" draws another valid seed.
    page.get_by_role("button", name="Pick a new seed").click()
    seed = page.locator("#sim-seed").input_value()
    assert seed.isdigit() and 0 <= int(seed) <= 2**31 - 1
    # Preset and seed come back with the page.
    page.reload()
    expect(page.locator("#show-title")).to_have_text("Single flight")
    assert page.locator("#sim-seed").input_value() == seed
    assert page.locator("#sim-preset").input_value() == "gusty-rtk" and page.locator("#sim-disturbance").is_disabled()
    assert not ui.errors and not errors, (ui.errors, errors)
    ui.shot("editor-single-flight")


def test_export_refusal_marks_the_formation_card(ui: Page):
    page = ui.page
    ui.open_show(forced_doc("Forced export"))
    card = page.locator('.tl-card[data-index="1"]')
    expect(card).not_to_have_class("tl-card has-problem")
    page.select_option("#export-format", "skyc")
    page.get_by_role("button", name="Export in the chosen format").click()
    expect(page.locator("#export-error")).to_contain_text("formations[1].transition_s", timeout=60_000)
    expect(card).to_have_class("tl-card has-problem")
    # The card says its field in the designer's words (the server's where_in_formation).
    expect(card.locator(".field-error")).to_contain_text("transition (s) = 0.2 s is shorter")
    expect(page.locator('.tl-card[data-index="0"]')).not_to_have_class("tl-card has-problem")


def test_qgc_export_without_origin_is_caught_in_the_editor(ui: Page):
    page = ui.page
    errors = _console_errors(page)
    ui.open_show(show_doc("No origin"))
    exports: list[str] = []
    page.on("request", lambda r: exports.append(r.url) if "/export/" in r.url else None)
    for fmt in ("qgc-plan", "qgc-wpl"):
        page.select_option("#export-format", fmt)
        page.get_by_role("button", name="Export in the chosen format").click()
        expect(page.locator('[data-error-for="origin"]')).to_contain_text("Origin")
        expect(page.locator("#export-error")).to_contain_text("origin")
        assert page.evaluate("() => document.getElementById('export-options').open")
        assert page.evaluate("() => document.activeElement.id") == "exp-origin"
    assert exports == [] and errors == [], (exports, errors)
    # The origin's altitude keeps the show file's range (10 km), as the server's export option now does.
    page.fill("#exp-origin", "47.4, 8.5, 20000")
    page.dispatch_event("#exp-origin", "change")
    expect(page.locator('[data-error-for="origin"]')).to_contain_text("10000")
    page.fill("#exp-origin", "47.4, 8.5, 400")
    page.dispatch_event("#exp-origin", "change")
    expect(page.locator('[data-error-for="origin"]')).to_have_text("")
    with page.expect_response(lambda r: "/export/qgc-wpl" in r.url, timeout=60_000) as resp:
        page.get_by_role("button", name="Export in the chosen format").click()
    assert resp.value.status == 200, resp.value.text()
    assert not errors, errors


def test_a_simulation_refused_for_a_formation_marks_its_card(ui: Page):
    """A cue time the planner cannot meet fails the simulation job naming formations[1].arrive_at_s: the failure
    says so and the card of formation 1 is marked, as the check and the exports mark it."""
    page = ui.page
    doc = show_doc("Early cue")
    first = doc["formations"][0]
    doc["formations"].append({**first, "name": "up", "arrive_at_s": 3.0,
                              "points": [[x, y, z + 20] for x, y, z in first["points"]]})
    ui.open_show(doc)
    card = page.locator('.tl-card[data-index="1"]')
    expect(card).not_to_have_class("tl-card has-problem")
    page.get_by_role("button", name="Simulate the flight").click()
    expect(page.locator("#sim-body")).to_contain_text("formations[1].arrive_at_s", timeout=120_000)
    expect(card).to_have_class("tl-card has-problem")
    expect(card.locator(".field-error")).to_contain_text("too early")
    expect(page.locator('.tl-card[data-index="0"]')).not_to_have_class("tl-card has-problem")


def test_drones_blown_off_in_a_single_flight_are_named_with_their_reason(ui: Page):
    """Two drones hovering 700 m up in gusty-rtk's wind are blown off (tests/test_editor_montecarlo.py): the
    flight's summary fails, names both drones under their reason and says on screen what the reason means."""
    from tests.conftest import make_show

    high = {"name": "High", "hold_s": 5.0, "color": "#ffffff", "points": [[0.0, 0.0, 700.0], [6.0, 0.0, 700.0]]}
    show = make_show([high], drones=2, rows=1, cols=2, spacing_m=6.0, max_altitude_m=750.0,
                     max_speed_z_mps=4.0).model_copy(update={"name": "Gale alone"})
    page = ui.page
    ui.open_show(show.model_dump(mode="json", exclude_none=True))
    page.select_option("#sim-preset", "gusty-rtk")
    page.fill("#sim-seed", "3")
    page.get_by_role("button", name="Simulate the flight").click()
    expect(page.locator("#sim-percent")).to_have_text("100%", timeout=300_000)
    expect(page.locator("#sim-body > .report-bad").first).to_contain_text("✗")
    rows = _rows(ui)
    assert rows["Diverged"] == ("2 overpowered (drones 0, 1)", "bad-value"), rows
    expect(page.locator("#sim-body .sim-reasons")).to_contain_text("blown off (wind beyond its authority)")


def test_a_compile_note_of_the_job_shows_beside_the_progress(ui: Page):
    """The server says when a job waits for the flight kernel's compile (a cold numba cache: a minute or
    two with the progress still); the editor shows that note, and drops it when the job moves on. The
    job's answers are routed here (a real cold compile costs minutes), in the shape the API gives."""
    page = ui.page
    ui.open_show(show_doc("Compile note", hold_s=2.0))
    note = "compiling the flight kernel for this machine (first run, a few minutes of CPU; cached afterwards)"
    job = {"id": "jnote", "kind": "simulate", "state": "running", "progress": 0.05, "note": note}
    later = {**job, "progress": 0.4, "note": ""}
    page.route("**/simulate", lambda route: route.fulfill(status=202, json=job))
    # The token-less editor follows the job by server-sent events: one progress event without the note.
    page.route("**/api/jobs/jnote/events", lambda route: route.fulfill(
        status=200, headers={"content-type": "text/event-stream"},
        body=f"event: progress\ndata: {json.dumps(later)}\n\n"))
    page.route("**/api/jobs/jnote", lambda route: route.fulfill(status=200, json=later))
    page.evaluate("() => { window.__seen = []; new MutationObserver(() => window.__seen.push("
                  "document.querySelector('#sim-body').textContent)).observe(document.querySelector('#sim-body'),"
                  " {childList: true, subtree: true, characterData: true}); }")
    page.get_by_role("button", name="Simulate the flight").click()
    expect(page.locator("#sim-body")).to_contain_text("40%")
    seen = page.evaluate("() => window.__seen")
    assert any("5%" in t and note in t for t in seen), seen
    assert note not in page.locator("#sim-body").text_content()
