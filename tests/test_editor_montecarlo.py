"""The editor's Monte-Carlo: Runs selector -> job with progress -> summary, Safety report link, worst run in 3D.

Driven with Playwright against a live server on loopback (the helpers of test_editor_browser).
"""

from __future__ import annotations

import httpx
import pytest

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_editor_browser import _create_show, _draw_stroke

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")

server = server_for("montecarlo-data", viewer=True)  # viewer on: the worst run plays in 3D


def test_monte_carlo_from_the_editor_links_the_safety_report(ui):
    page = ui.page
    _create_show(ui, "MC editor", 8)
    _draw_stroke(ui)
    # Two runs keep the test short (the menu offers 20 and 50).
    page.evaluate("""() => { const s = document.getElementById('sim-runs');
        s.add(new Option('Monte-Carlo, 2 runs', '2')); s.value = '2'; }""")
    page.select_option("#sim-preset", "calm-rtk")
    page.get_by_role("button", name="Simulate the flight").click()
    sync_api.expect(page.locator("#sim-percent")).to_have_text("100%", timeout=120_000)
    body = page.locator("#sim-body")
    sync_api.expect(body).to_contain_text("P(closer than")
    sync_api.expect(body).to_contain_text("calm-rtk")
    link = page.locator("#sim-report-link")
    sync_api.expect(link).to_be_visible()
    href = link.get_attribute("href")
    assert href and href.startswith("/api/jobs/") and href.endswith("/report.html")
    r = httpx.get(ui.base + href, timeout=60)
    assert r.status_code == 200 and "Safety report: MC editor" in r.text and r.text.count("<svg") == 4
    # The worst run plays in the 3D view (the viewer's simulated source), without an error message.
    with page.expect_response(lambda resp: "/playback" in resp.url) as resp:
        page.locator("#sim-play-worst").click()
    assert resp.value.status == 200, resp.value.text()
    assert resp.value.json()["source"] == "simulated"
    sync_api.expect(body).not_to_contain_text("Cannot play")
