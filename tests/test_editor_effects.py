"""The light-effects panel (issue 18) through the real UI in Chromium: add a sweep and a sparkle,
edit them, scrub and play the canvas preview, save (the server validates the stack), and load the
saved show into the 3D viewer; no page error, no request off loopback."""

from __future__ import annotations

import pytest

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_editor_browser import Page, _create_show

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect


server = server_for("effects-data", viewer=True)


def _preview_colors(ui: Page) -> list[str]:
    return ui.page.evaluate("() => { const {state, effects} = window.swarmshow; const f = state.formation;"
                            " return effects.colorsFor(f, f.colors); }")


def test_add_sweep_and_sparkle_preview_save_and_play(ui: Page) -> None:
    page = ui.page
    _create_show(ui, "Effects", 16)
    page.locator("#effects-panel > summary").click()
    page.get_by_label("Kind of effect to add").select_option("sweep")
    page.get_by_role("button", name="Add a light effect").click()
    page.get_by_label("Kind of effect to add").select_option("sparkle")
    page.get_by_role("button", name="Add a light effect").click()
    assert ui.state("s.show.lights.effects.map((e) => e.effect.kind)") == ["sweep", "sparkle"]

    # Kind-specific fields of the selected (sparkle) effect; each change is one undo step.
    page.get_by_label("Effect density").fill("0.9")
    page.get_by_label("Effect density").dispatch_event("change")
    assert ui.state("s.show.lights.effects[1].effect.density") == 0.9
    page.get_by_label("Effect blend").select_option("add")
    assert ui.state("s.show.lights.effects[1].blend") == "add"
    page.get_by_role("button", name="Edit effect 1: sweep · 0–10 s · replace").click()
    page.get_by_label("Effect speed (m/s)").fill("25")
    page.get_by_label("Effect speed (m/s)").dispatch_event("change")
    assert ui.state("s.show.lights.effects[0].effect.speed_mps") == 25

    # Scrub: the canvas colours follow the effects and change with time.
    base = ui.state("s.formation.colors")
    page.locator("#fx-time").fill("2")
    page.locator("#fx-time").dispatch_event("input")
    at2 = _preview_colors(ui)
    assert at2 != base
    page.locator("#fx-time").fill("2.5")
    page.locator("#fx-time").dispatch_event("input")
    assert _preview_colors(ui) != at2

    ui.shot("effects-panel")

    # Play advances the preview time; pause stops it.
    page.get_by_role("button", name="Play the effect preview").click()
    page.wait_for_function("() => window.swarmshow.effects.time > 2.8")
    page.get_by_role("button", name="Pause the effect preview").click()

    # Save: the server accepts the stack and stores it.
    page.keyboard.press("Control+s")
    expect(page.locator("#save-status")).to_contain_text("Saved")
    show_id = ui.state("s.meta.id")
    stored = page.evaluate("async (id) => (await (await fetch(`/api/shows/${id}`)).json()).show", show_id)
    assert [e["effect"]["kind"] for e in stored["lights"]["effects"]] == ["sweep", "sparkle"]

    # The 3D viewer loads it with the effects (and plays without error).
    r = page.evaluate("""async (id) => { const r = await fetch(`/api/shows/${id}/playback`, {method: 'POST',
        headers: {'content-type': 'application/json'}, body: '{"source": "planned"}'}); return r.status; }""",
                      show_id)
    assert r == 200
    page.goto(ui.base + "/viser/")
    page.get_by_text("16 drones").first.wait_for(timeout=60_000)  # the show with its effects is on screen

    # Remove one: undoable.
    page.goto(ui.base + f"/?show={show_id}")
    expect(page.locator("#show-title")).to_have_text("Effects")
    page.locator("#effects-panel > summary").click()
    page.get_by_role("button", name="Remove effect 2").click()
    assert ui.state("s.show.lights.effects.length") == 1
    page.get_by_role("button", name="Undo Remove effect").click()
    assert ui.state("s.show.lights.effects.length") == 2


def test_image_and_video_effects_preview_on_the_canvas(ui: Page) -> None:
    """Upload a PNG and a WebM into image / video effects: the canvas preview paints their pixels."""
    import base64

    import numpy as np

    from tests.test_light_effects import _png_url, _video_url

    page = ui.page
    _create_show(ui, "Projected", 16)
    png = ui.tmp / "red.png"
    png.write_bytes(base64.b64decode(_png_url(np.full((8, 8, 4), (255, 0, 0, 255), dtype=np.uint8)).split(",")[1]))
    webm = ui.tmp / "clip.webm"
    webm.write_bytes(base64.b64decode(_video_url(10, [(0, 255, 0)] * 20, "libvpx", "webm").split(",")[1]))
    centre = ui.state("(() => { const p = s.formation.points;"
                      " return [0, 1, 2].map((a) => p.reduce((m, q) => m + q[a], 0) / p.length).join(', '); })()")

    page.locator("#effects-panel > summary").click()
    for kind, path in (("image", png), ("video", webm)):
        page.get_by_label("Kind of effect to add").select_option(kind)
        page.get_by_role("button", name="Add a light effect").click()
        page.locator("#fx-form input[type=file]").set_input_files(str(path))
        label = "Effect images" if kind == "image" else "Effect video"
        page.wait_for_function(f"() => window.swarmshow.state.undoStack.at(-1)?.label === '{label}'")
        page.get_by_label("Effect centre (m)").fill(centre)
        page.get_by_label("Effect centre (m)").dispatch_event("change")
        page.get_by_label("Effect width (m)").fill("500")
        page.get_by_label("Effect width (m)").dispatch_event("change")
        page.get_by_label("Effect height (m)").fill("500")
        page.get_by_label("Effect height (m)").dispatch_event("change")
        if kind == "image":
            page.locator("#fx-time").fill("1")
            page.locator("#fx-time").dispatch_event("input")
            page.wait_for_function("() => { const {state, effects} = window.swarmshow; const f = state.formation;"
                                   " return effects.colorsFor(f, f.colors).slice(0, 16)"
                                   ".every((c) => c === '#ff0000'); }")
    # The video is on top of the stack: green once its frame is decoded.
    page.locator("#fx-time").fill("1.5")
    page.locator("#fx-time").dispatch_event("input")
    page.wait_for_function("() => { const {state, effects} = window.swarmshow; const f = state.formation;"
                           " const c = effects.colorsFor(f, f.colors)[0];"
                           " return parseInt(c.slice(3, 5), 16) > 200 && parseInt(c.slice(1, 3), 16) < 60; }",
                           timeout=30_000)
    page.keyboard.press("Control+s")
    expect(page.locator("#save-status")).to_contain_text("Saved")


def test_a_refused_effect_shows_its_error_in_the_panel(ui: Page) -> None:
    page = ui.page
    _create_show(ui, "Refused", 9)
    page.locator("#effects-panel > summary").click()
    page.get_by_role("button", name="Add a light effect").click()
    page.get_by_label("Effect end (s)").fill("0")
    page.get_by_label("Effect end (s)").dispatch_event("change")
    page.keyboard.press("Control+s")
    # In the designer's words (CI of 2295181: 'lights, effects, effects 1, end (s)').
    expect(page.locator('#effects-panel [data-error-for="lights"]')).to_contain_text(
        "light effect 1, end (s): must be more than 0")
    page.get_by_role("button", name="Undo Effect end (s)").click()
    assert ui.state("s.show.lights.effects[0].end_s") == 10
    page.keyboard.press("Control+s")
    expect(page.locator("#save-status")).to_contain_text("Saved")
    expect(page.locator('#effects-panel [data-error-for="lights"]')).to_have_text("")
