"""Small editor behaviours, driven with Playwright against a live server on loopback: "save as a
copy" keeps the show's music (the copy's stored track is the same file, and the music lane shows
it); the summary tables of the check and the simulation panels (heading, rows, limits marked)."""

from __future__ import annotations

import io

import httpx
import numpy as np
import pytest

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_editor_browser import Page, _create_show

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")
sf = pytest.importorskip("soundfile")


server = server_for("copy-music-data", viewer=False)


def test_save_as_copy_copies_the_music(ui: Page):
    page = ui.page
    _create_show(ui, "With music", 9)
    sr = 22_050
    t = np.arange(4 * sr) / sr
    buf = io.BytesIO()
    sf.write(buf, (0.3 * np.sin(2 * np.pi * 440 * t)).astype(np.float32), sr, format="WAV")
    track = ui.tmp / "tone.wav"
    track.write_bytes(buf.getvalue())
    page.set_input_files("#music-file", str(track))
    page.wait_for_function("() => (window.swarmshow.music.info || {}).filename === 'tone.wav'", timeout=240_000)
    old_id = ui.state("s.meta.id")

    assert page.evaluate("() => window.swarmshow.persist.saveCopy()") is True
    new_id = ui.state("s.meta.id")
    assert new_id != old_id and ui.state("s.show.name") == "With music (copy)"
    got = httpx.get(f"{ui.base}/api/shows/{new_id}/audio")
    assert got.status_code == 200 and got.content == track.read_bytes()
    # the lane reloaded the copy's own track
    page.wait_for_function(f"() => (window.swarmshow.music.info || {{}}).url === '/api/shows/{new_id}/audio'")
    assert ui.state("window.swarmshow.music.info.filename") == "tone.wav"
    # the original keeps its music
    assert httpx.get(f"{ui.base}/api/shows/{old_id}/audio").content == track.read_bytes()


def test_summary_table_builds_the_heading_and_rows(ui: Page):
    """summary.js's one helper for the check report and the flight and Monte-Carlo summaries: the heading's class and
    text, one row per truthy entry (falsy ones left out), breaking values marked bad."""
    page = ui.page
    page.goto(ui.base + "/")
    got = page.evaluate("""async () => {
        const { summaryTable } = await import('/js/summary.js');
        const out = {};
        for (const ok of [true, false]) {
          const [head, table] = summaryTable(ok, ok ? 'fine' : 'broken', 'Some summary',
            [['Speed', '3 m/s'], null, false, ['Gap', '1 m', true], undefined, ['Time', '2 s', false]]);
          out[ok] = { cls: head.className, text: head.textContent, label: table.getAttribute('aria-label'),
            rows: [...table.rows].map((r) => [...r.cells].map((c) => [c.textContent, c.className])) };
        }
        return out; }""")
    rows = [[["Speed", ""], ["3 m/s", ""]], [["Gap", ""], ["1 m", "bad-value"]], [["Time", ""], ["2 s", ""]]]
    assert got["true"] == {"cls": "report-ok", "text": "fine", "label": "Some summary", "rows": rows}
    assert got["false"] == {"cls": "report-bad", "text": "broken", "label": "Some summary", "rows": rows}


def test_flight_and_monte_carlo_summaries_render_through_the_helper(ui: Page):
    """The two call sites with fixed results (no simulation needed): the rows, their values, and the
    limits marked bad where the figures break them."""
    page = ui.page
    page.goto(ui.base + "/")
    got = page.evaluate("""async () => {
        const { SimulatePanel } = await import('/js/simulate.js');
        const dump = (body) => ({ head: [body.firstChild.className, body.firstChild.textContent],
          rows: [...body.querySelector('table').rows].map((r) => [r.cells[0].textContent, r.cells[1].textContent,
                                                                  r.cells[1].className]),
          label: body.querySelector('table').getAttribute('aria-label') });
        const flight = document.createElement('div');
        SimulatePanel.prototype._summary.call({ body: flight }, { flight: { ok: false, tracking_rms_m: 0.0123,
          tracking_max_m: 0.2, min_distance_limit_m: 3, flown_min_distance_m: 2.5, duration_s: 61.25,
          controller: 'pid', engine: 'numba', wall_time_s: 4 } }, true);
        const mc = document.createElement('div');
        SimulatePanel.prototype._monteCarlo.call({ body: mc, state: { meta: null } }, 'job1', { runs: 20,
          min_distance_m: 3, collision_distance_m: 0.5, confidence: 0.95, preset: 'calm-rtk', controller: 'pid',
          seed0: 1, show_min: { p_below_min_distance: { runs_below: 0, p: 0, ci_low: 0, ci_high: 0.14 },
          p_collision: { runs_below: 0, p: 0, ci_low: 0, ci_high: 0.14 },
          flown_min_m: { quantiles: { 0: 3.2, 0.5: 3.6 } },
          extra_spacing: { extra_m: 0.25 } }, deviation: { max_m: 0.3 } }, false);
        return { flight: dump(flight), mc: dump(mc) }; }""")
    assert got["flight"]["head"] == ["report-bad", "✗ The flown show breaks a limit"]
    assert got["flight"]["label"] == "Flight summary"
    assert got["flight"]["rows"] == [
        ["Deviation from plan (RMS)", "0.012 m", ""], ["Deviation from plan (max)", "0.200 m", ""],
        ["Flown min separation", "2.50 m (≥ 3.0)", "bad-value"], ["Duration", "61.3 s", ""],
        ["Controller", "pid, numba", ""], ["Computed in", "4.0 s (cached)", ""]]
    assert got["mc"]["head"] == ["report-ok", "✓ 20 runs: every run kept the minimum distance"]
    assert got["mc"]["label"] == "Monte-Carlo summary"
    assert got["mc"]["rows"] == [
        ["Flown min separation", "worst 3.20 m, median 3.60 m", ""],
        ["P(closer than 3.0 m)", "0.0 % (0.0–14.0 %)", ""], ["P(collision, < 0.5 m)", "0.0 % (0.0–14.0 %)", ""],
        ["Extra spacing at 95 %", "0.25 m", ""], ["Largest deviation", "0.300 m", ""],
        ["Preset", "calm-rtk, pid, seeds 1–20", ""]]


def test_check_summary_renders_through_the_helper(ui: Page):
    """report.js's check summary with a fixed report (no check needed): the heading, the stale note
    between it and the table, the rows with their limits (≥ for the minimum, ≤ for the maxima), the
    ones breaking a limit marked bad, "—" for a missing figure, and the closest pair only when there is one."""
    page = ui.page
    page.goto(ui.base + "/")
    got = page.evaluate("""async () => {
        const { ReportPanel } = await import('/js/report.js');
        const render = (report, version) => {
          const body = document.createElement('div');
          const self = { body, result: { report, plan: { segments: [] } }, checkedVersion: 1,
            state: { version, show: { formations: [] } },
            parts: { timeline: { setCheck() {}, render() {} } }, _p: ReportPanel.prototype._p };
          ReportPanel.prototype.render.call(self);
          const table = body.querySelector('table');
          return { paras: [...body.querySelectorAll(':scope > p')].map((p) => [p.className, p.textContent, p.hidden]),
            label: table.getAttribute('aria-label'), order: [...body.children].map((e) => e.tagName),
            rows: [...table.rows].map((r) => [r.cells[0].textContent, r.cells[1].textContent, r.cells[1].className]) };
        };
        const limits = { min_distance_m: 3, max_speed_xy_mps: 5, max_accel_mps2: 4, max_altitude_m: 100 };
        return {
          bad: render({ ok: false, violations_total: 2, duration_s: 12.54, limits, min_distance_m: 2.4,
            max_speed_xy_mps: 4, max_speed_z_mps: 1.5, max_accel_mps2: null, max_altitude_m: 100.5,
            min_distance_pair: [3, 7], min_distance_time_s: 8.21 }, 1),
          ok: render({ ok: true, violations_total: 0, duration_s: 3, min_distance_m: 3.5, max_speed_xy_mps: 2,
            max_speed_z_mps: 1, max_accel_mps2: 2, max_altitude_m: 20, min_distance_pair: [] }, 2),
        }; }""")
    bad, ok = got["bad"], got["ok"]
    assert bad["paras"] == [["report-bad", "✗ 2 violations", False],
                            ["muted stale", "The show changed since this check.", True]]
    assert bad["order"] == ["P", "P", "TABLE"] and bad["label"] == "Check summary"
    assert bad["rows"] == [
        ["Duration", "12.5 s", ""], ["Minimum distance", "2.40 m (≥ 3.0)", "bad-value"],
        ["Peak horizontal speed", "4.00 m/s (≤ 5.0)", ""], ["Peak vertical speed", "1.50 m/s", ""],
        ["Peak acceleration", "— (≤ 4.0)", ""], ["Highest altitude", "100.50 m (≤ 100.0)", "bad-value"],
        ["Closest pair", "drones 3 & 7 at 8.2 s", ""]]
    assert ok["paras"] == [["report-ok", "✓ Safe: every limit holds", False],
                           ["muted stale", "The show changed since this check.", False]]
    assert ok["rows"] == [
        ["Duration", "3.0 s", ""], ["Minimum distance", "3.50 m", ""], ["Peak horizontal speed", "2.00 m/s", ""],
        ["Peak vertical speed", "1.00 m/s", ""], ["Peak acceleration", "2.00 m/s²", ""],
        ["Highest altitude", "20.00 m", ""]]
