"""Issue 18 item 4 in Chromium: the 3D view paints the editor's unsaved effects (its colours, read from the viewer
page's state element, change without a save), an effect bar's end dragged onto a beat, a drone group made from a
selection and targeted, the canvas preview placing drones as the check planned them. Against a live loopback
server; no page error, no request off loopback."""

from __future__ import annotations

import io

import httpx
import numpy as np
import pytest
import soundfile as sf

from tests.live_server import BROWSER_MARKS, server_for, wait_until
from tests.test_editor_browser import Page, _create_show
from tests.test_media_audio import click_track

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect


server = server_for("fx-live-data", viewer=True)


def _viewer(page) -> dict | None:
    """The preview page's state element (token, effect revision, LED colours of the first drones)."""
    return page.evaluate("""() => { const f = document.getElementById('preview-frame');
        const el = f && f.contentDocument && f.contentDocument.getElementById('swarmshow-viewer');
        if (!el || !el.dataset.token) return null;
        return {lights: Number(el.dataset.lights), rgb: (el.dataset.rgb || '').split(' ')}; }""")


def test_unsaved_effects_in_the_3d_view_bars_on_beats_and_groups(ui: Page, tmp_path) -> None:
    page = ui.page
    _create_show(ui, "Live light", 9)
    y, clicks = click_track(120.0, 0.5, duration_s=30.0, sr=22_050)
    buf = io.BytesIO()
    sf.write(buf, y, 22_050, format="WAV")
    (tmp_path / "clicks.wav").write_bytes(buf.getvalue())
    page.set_input_files("#music-file", str(tmp_path / "clicks.wav"))
    expect(page.locator("#music-status")).to_contain_text("BPM", timeout=240_000)
    beats = page.evaluate("() => window.swarmshow.music.analysis.beats_s")

    # A white solid effect over the whole fleet, saved; the canvas preview is approximate before a check.
    page.locator("#effects-panel > summary").click()
    page.get_by_label("Kind of effect to add").select_option("solid")
    page.get_by_role("button", name="Add a light effect").click()
    page.locator("#fx-time").fill("1")
    page.locator("#fx-time").dispatch_event("input")
    expect(page.locator("#fx-approx")).to_be_visible()
    page.keyboard.press("Control+s")
    page.wait_for_function("() => !window.swarmshow.state.dirty")
    page.get_by_role("button", name="Check the show").click()
    expect(page.locator("#report-body")).to_contain_text("Minimum distance", timeout=300_000)
    plan = page.evaluate("() => window.swarmshow.report.result.plan")
    assert len(plan["assignment"]) == 1 and sorted(plan["assignment"][0]) == list(range(9))
    page.locator("#fx-time").fill("1.5")
    page.locator("#fx-time").dispatch_event("input")
    expect(page.locator("#fx-approx")).to_be_hidden()
    # The slider spans the planned show.
    assert float(page.locator("#fx-time").get_attribute("max")) == np.ceil(plan["duration_s"])

    # The 3D view shows the saved white; a colour edit (not saved) turns it red there.
    page.get_by_role("button", name="3D preview").click()
    first = wait_until("the viewer's colours", lambda: (v := _viewer(page)) and len(v["rgb"]) == 9 and v)
    assert first["rgb"] == ["#ffffff"] * 9
    page.locator("input[aria-label='Effect colour']").fill("#ff0000")
    page.locator("input[aria-label='Effect colour']").dispatch_event("change")
    assert ui.state("s.dirty") is True
    wait_until("red in the 3D view", lambda: (v := _viewer(page)) and v["rgb"] == ["#ff0000"] * 9)

    # The effect's bar: drag its end near the beat closest to 7.3 s; it lands on that beat.
    lane = page.locator("#fx-lane").bounding_box()
    bar = page.evaluate("() => window.swarmshow.fxLane.bar(0)")
    target = min(beats, key=lambda b: abs(b - 7.3))
    x1 = page.evaluate(f"() => window.swarmshow.fxLane._x({target})") + 4
    yy = lane["y"] + bar["y"] + bar["h"] / 2
    page.mouse.move(lane["x"] + bar["x1"] - 1, yy)
    page.mouse.down()
    for k in range(1, 11):
        page.mouse.move(lane["x"] + bar["x1"] - 1 + (x1 - bar["x1"] + 1) * k / 10, yy)
    page.mouse.up()
    end = ui.state("s.show.lights.effects[0].end_s")
    assert end == pytest.approx(round(target, 3), abs=1e-9)
    assert np.abs(clicks - end).min() <= 0.02

    # A group of the drones flying to points 0, 4 and 8 (the plan's), made from the selection, targeted by the effect.
    page.evaluate("() => window.swarmshow.state.setSelection([0, 4, 8])")
    page.get_by_label("New drone group name").fill("diagonal")
    page.get_by_role("button", name="Make a drone group from the selection").click()
    want = sorted(d for d, p in enumerate(plan["assignment"][0]) if p in (0, 4, 8))
    assert ui.state("s.show.groups.diagonal") == want
    assert ui.state("s.show.lights.effects[0].target") == {"kind": "group", "group": "diagonal"}
    expect(page.get_by_role("list", name="Drone groups")).to_contain_text("diagonal · 3 drones")
    # In the 3D view only the group's drones stay red (the others show their own white).
    wait_until("the group in the 3D view",
          lambda: (v := _viewer(page)) and [i for i, c in enumerate(v["rgb"]) if c == "#ff0000"] == want)
    # The canvas preview paints the points those drones fly to.
    colors = page.evaluate("() => { const {state, effects} = window.swarmshow; const f = state.formation;"
                           " return effects.colorsFor(f, f.colors); }")
    assert [i for i, c in enumerate(colors) if c == "#ff0000"] == [0, 4, 8]
    assert ui.state("s.dirty") is True
    # The music lane's playhead moves the canvas preview.
    page.evaluate("() => window.swarmshow.music.seek(3.25)")
    assert page.evaluate("() => window.swarmshow.effects.time") == pytest.approx(3.25)
    # The saved show loaded into the viewer again (as another tab's preview does) drops the editor's effects
    # there; the editor sends its own (still unsaved) again.
    rev = _viewer(page)["lights"]
    assert rev > 0
    r = httpx.post(f"{ui.base}/api/shows/{ui.state('s.meta.id')}/playback", json={}, timeout=120)
    assert r.status_code == 200, r.text
    wait_until("the group in the reloaded 3D view", lambda: (v := _viewer(page)) and v["lights"] > rev
          and [i for i, c in enumerate(v["rgb"]) if c == "#ff0000"] == want)
    assert ui.state("s.dirty") is True
    ui.shot("issue18-fx-live")
