"""The editor's export request, in Chromium against a live server on loopback: the flown trajectories carry the
simulation panel's preset, seed, controller and (preset "ideal") disturbance (the file holds the flight the
designer chose), and scale / offset go only to
the format that applies them (the server refuses them elsewhere with 422)."""

from __future__ import annotations

from urllib.parse import parse_qs, urlparse

import httpx
import pytest

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_api_jobs import show_doc
from tests.test_editor_browser import Page

pytestmark = BROWSER_MARKS
sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect

server = server_for("export-query-data")


def _export(page, fmt: str) -> tuple[dict[str, list[str]], int]:
    page.select_option("#export-format", fmt)
    with page.expect_response(lambda r: f"/export/{fmt}" in r.url, timeout=120_000) as resp:
        page.get_by_role("button", name="Export in the chosen format").click()
    return parse_qs(urlparse(resp.value.url).query), resp.value.status


def test_export_sends_the_flight_and_the_scaling_where_they_apply(ui: Page):
    """Failed before: the flown export asked for neither preset nor seed (the server flew the ideal vehicle), and
    a scale typed for Crazyswarm went to every format (refused there now)."""
    page = ui.page
    r = httpx.post(f"{ui.base}/api/shows", json=show_doc("Export query"))
    assert r.status_code == 201, r.text
    page.goto(f"{ui.base}/?show={r.json()['id']}")
    expect(page.locator("#show-title")).to_have_text("Export query")
    page.select_option("#sim-preset", "gusty-rtk")
    page.fill("#sim-seed", "17")
    page.select_option("#sim-controller", "baseline")  # failed before: the export flew ISMC
    page.evaluate("() => { document.getElementById('export-options').open = true; }")
    page.select_option("#exp-source", "simulated")
    page.fill("#exp-scale", "0.5")
    page.fill("#exp-offset", "1, 2, 0")

    query, status = _export(page, "waypoints-csv")
    assert status == 200, page.locator("#export-error").text_content()
    assert query == {"source": ["simulated"], "preset": ["gusty-rtk"], "seed": ["17"],
                     "controller": ["baseline"]}, query
    # The fleet-wide disturbance goes with preset "ideal" only (the others bring their own wind).
    page.select_option("#sim-preset", "ideal")
    page.select_option("#sim-disturbance", "wind")
    query, status = _export(page, "waypoints-csv")
    assert status == 200, page.locator("#export-error").text_content()
    assert query["preset"] == ["ideal"] and query["disturbance"] == ["wind"], query

    page.select_option("#exp-source", "planned")
    query, status = _export(page, "crazyswarm")
    assert status == 200, page.locator("#export-error").text_content()
    assert query == {"scale": ["0.5"], "offset": ["1,2,0"]}, query
    expect(page.locator("#export-error")).to_have_text("")


def test_simulated_trajectories_with_a_format_of_the_plan_are_caught_in_the_editor(ui: Page):
    """Failed before: the editor asked the server, which refused with 422 (an error in the browser console)."""
    page = ui.page
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    r = httpx.post(f"{ui.base}/api/shows", json=show_doc("Export plan only"))
    assert r.status_code == 201, r.text
    page.goto(f"{ui.base}/?show={r.json()['id']}")
    expect(page.locator("#show-title")).to_have_text("Export plan only")
    page.evaluate("() => { document.getElementById('export-options').open = true; }")
    page.select_option("#exp-source", "simulated")
    exports: list[str] = []
    page.on("request", lambda req: exports.append(req.url) if "/export/" in req.url else None)
    page.select_option("#export-format", "skyc")
    page.get_by_role("button", name="Export in the chosen format").click()
    expect(page.locator("#export-error")).to_contain_text("exact plan")
    assert page.evaluate("() => document.activeElement.id") == "exp-source"
    assert exports == [] and errors == [], (exports, errors)
