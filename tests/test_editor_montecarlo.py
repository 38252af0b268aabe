"""The editor's Monte-Carlo: Runs selector -> job with progress -> summary, Safety report link, worst run in 3D,
and the drone-runs that diverged (how many, and why) in the summary.

Driven with Playwright against a live server on loopback (the helpers of test_editor_browser).
"""

from __future__ import annotations

import httpx
import pytest

from tests.conftest import make_show
from tests.live_server import BROWSER_MARKS, server_for
from tests.test_editor_browser import Page, _create_show, _draw_stroke

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
expect = sync_api.expect

server = server_for("montecarlo-data", viewer=True)  # viewer on: the worst run plays in 3D


def _two_runs(ui: Page, preset: str) -> None:
    """Two runs keep the tests short (the menu offers 20 and 50), under the error ``preset``."""
    ui.page.evaluate("""() => { const s = document.getElementById('sim-runs');
        s.add(new Option('Monte-Carlo, 2 runs', '2')); s.value = '2'; }""")
    ui.page.select_option("#sim-preset", preset)


def _summary_rows(ui: Page) -> dict[str, tuple[str, str]]:
    """The Monte-Carlo summary's rows: label -> (value, the value cell's class)."""
    rows = ui.page.evaluate("""() => [...document.querySelector('#sim-body table').rows].map(
        (r) => [r.cells[0].textContent, r.cells[1].textContent, r.cells[1].className])""")
    return {label: (value, cls) for label, value, cls in rows}


def _job(ui: Page, href: str) -> dict:
    """The finished job behind the summary's Safety report link, read over HTTP."""
    job_id = href.removeprefix("/api/jobs/").removesuffix("/report.html")
    job = httpx.get(f"{ui.base}/api/jobs/{job_id}", timeout=60).json()
    assert job["state"] == "done" and job["kind"] == "montecarlo", job
    return job


def test_monte_carlo_from_the_editor_links_the_safety_report(ui: Page):
    page = ui.page
    _create_show(ui, "MC editor", 8)
    _draw_stroke(ui)
    _two_runs(ui, "calm-rtk")
    page.get_by_role("button", name="Simulate the flight").click()
    expect(page.locator("#sim-percent")).to_have_text("100%", timeout=120_000)
    body = page.locator("#sim-body")
    expect(body).to_contain_text("P(closer than")
    expect(body).to_contain_text("calm-rtk")
    link = page.locator("#sim-report-link")
    expect(link).to_be_visible()
    href = link.get_attribute("href")
    assert href and href.startswith("/api/jobs/") and href.endswith("/report.html")
    r = httpx.get(ui.base + href, timeout=60)
    assert r.status_code == 200 and "Safety report: MC editor" in r.text and r.text.count("<svg") == 4
    # No drone diverged in calm air (the job says so): the summary has no Diverged row.
    assert _job(ui, href)["result"]["montecarlo"]["diverged_count"] == 0
    rows = _summary_rows(ui)
    assert "Preset" in rows and "Diverged" not in rows, rows
    # The worst run plays in the 3D view (the viewer's simulated source), without an error message. The
    # server flies that run again inside the request: slow on a busy machine.
    with page.expect_response(lambda resp: "/playback" in resp.url, timeout=120_000) as resp:
        page.locator("#sim-play-worst").click()
    assert resp.value.status == 200, resp.value.text()
    assert resp.value.json()["source"] == "simulated"
    expect(body).not_to_contain_text("Cannot play")


#: Formation altitude of the gale test, metres. The presets' mean wind grows with height by the power law
#: (exponent 1/7, sim.flight._errors): gusty-rtk's 7.7 m/s at 10 m is 7.7 · 70^(1/7) ≈ 14.1 m/s up here,
#: beyond the ~13.7 m/s of airspeed the drones can hold against (tests/test_flight_gnss_gate.py), before gusts.
GALE_ALTITUDE_M = 700.0


def test_diverged_drone_runs_are_counted_by_reason_in_the_summary(ui: Page):
    """Two drones hovering 700 m up in the gusty preset are blown off in every run: the summary's Diverged row
    shows the job's count and reasons (the job's JSON read over HTTP), marked bad, and the run fails."""
    page = ui.page
    show = make_show([{"name": "High", "hold_s": 5.0, "color": "#ffffff",
                       "points": [[0.0, 0.0, GALE_ALTITUDE_M], [6.0, 0.0, GALE_ALTITUDE_M]]}],
                     drones=2, rows=1, cols=2, spacing_m=6.0, max_altitude_m=GALE_ALTITUDE_M + 50,
                     max_speed_z_mps=4.0).model_copy(update={"name": "Gale"})
    r = httpx.post(f"{ui.base}/api/shows", content=show.model_dump_json(),
                   headers={"content-type": "application/json"})
    assert r.status_code == 201, r.text
    page.goto(f"{ui.base}/?show={r.json()['id']}")
    expect(page.locator("#show-title")).to_have_text("Gale")
    _two_runs(ui, "gusty-rtk")
    page.get_by_role("button", name="Simulate the flight").click()
    expect(page.locator("#sim-percent")).to_have_text("100%", timeout=300_000)
    link = page.locator("#sim-report-link")
    expect(link).to_be_visible()
    mc = _job(ui, link.get_attribute("href") or "")["result"]["montecarlo"]
    # Really diverged: each drone of each run, held at its limits and blown off.
    assert mc["runs"] == 2 and mc["diverged_count"] == 4, mc["diverged"]
    assert mc["diverged_by_reason"] == {"overpowered": 4}
    assert sum(mc["diverged_by_reason"].values()) == mc["diverged_count"] == len(mc["diverged"])
    rows = _summary_rows(ui)
    reasons = ", ".join(f"{n} {why}" for why, n in mc["diverged_by_reason"].items())
    assert rows["Diverged"] == (f"{mc['diverged_count']} drone-runs ({reasons})", "bad-value"), rows
    expect(page.locator("#sim-body > .report-bad").first).to_contain_text("✗")
    ui.shot("editor-montecarlo-diverged")
