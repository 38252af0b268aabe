"""The 3D viewer in headless Chromium (Debian's /usr/bin/chromium): through the app's port, and the HTML export.

Everything must stay on loopback (or ``file:``/``data:``/``blob:`` for the export).
"""

from __future__ import annotations

import re
import threading
import time
from urllib.parse import urlsplit

import numpy as np
import pytest

from sim import plan_show
from tests.live_server import BROWSER_MARKS, SHOTS, chromium_browser, free_port, wait_until

pytestmark = BROWSER_MARKS
sync_api = pytest.importorskip("playwright.sync_api")


@pytest.fixture(scope="module")
def live_app(tmp_path_factory):
    """The app under uvicorn on a free loopback port (in this process, so the viewer can be inspected)."""
    import uvicorn

    from app.server import create_app
    from app.settings import AppSettings

    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("viewer-data"), workers=1))
    port = free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 60
    while not server.started or getattr(app.state, "viewer", None) is None:
        assert time.monotonic() < deadline and thread.is_alive(), "server did not start"
        time.sleep(0.05)
    try:
        yield app, f"http://127.0.0.1:{port}"
    finally:
        server.should_exit = True
        thread.join(timeout=20)


@pytest.fixture(scope="module")
def browser():
    with chromium_browser("--enable-unsafe-swiftshader") as b:
        yield b


def _guarded_page(browser, foreign: list[str]):
    ctx = browser.new_context(viewport={"width": 1280, "height": 800})

    def route(r) -> None:
        url = urlsplit(r.request.url)
        if url.scheme in ("http", "https") and url.hostname != "127.0.0.1":
            foreign.append(r.request.url)
            r.abort()
        else:
            r.continue_()

    ctx.route("**/*", route)
    page = ctx.new_page()
    page.on("websocket", lambda ws: urlsplit(ws.url).hostname == "127.0.0.1" or foreign.append(ws.url))
    return ctx, page


def _readout_time(page) -> float:
    text = page.get_by_text(re.compile(r"Time\s+[\d.]+\s*/")).first.inner_text()
    return float(re.search(r"Time\s+([\d.]+)", text).group(1))


def _lit_pixels(png: bytes, rgb: tuple[int, int, int]) -> int:
    import io

    from PIL import Image

    img = np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(int)
    return int((np.abs(img - np.array(rgb)).sum(axis=-1) < 90).sum())


def test_viewer_through_the_app_port(live_app, browser, small_show):
    app, base = live_app
    import httpx

    r = httpx.post(f"{base}/api/shows", content=small_show.model_dump_json(),
                   headers={"content-type": "application/json"})
    assert r.status_code == 201, r.text
    show_id = r.json()["id"]
    assert httpx.post(f"{base}/api/shows/{show_id}/playback", json={"source": "planned"}, timeout=60).status_code == 200
    viewer = app.state.viewer
    # Park the show in the ring formation (red LEDs) so the screenshot has something to find.
    ring = next(s for s in viewer._shows[viewer.current].plan.segments if s.kind == "hold")
    viewer.seek(ring.start_s + 0.5)

    foreign: list[str] = []
    ctx, page = _guarded_page(browser, foreign)
    sockets = []
    page.on("websocket", lambda ws: sockets.append(ws.url))
    try:
        page.goto(f"{base}/viser/")
        page.wait_for_selector("canvas", timeout=60_000)
        # The websocket went through the relay, on the app's port, and viser sees the client.
        wait_until("a client connected through the relay", viewer.server.get_clients)
        assert sockets and all(u == f"ws{base[4:]}/viser" for u in sockets)
        page.get_by_text("16 drones").first.wait_for(timeout=60_000)
        # No share button (it would open a public tunnel).
        assert page.get_by_text(re.compile("share", re.I)).count() == 0

        # The page first draws the show at 0 s, then the time it joined at (the parked one): start from
        # that, or the jump to it would pass for the clock running.
        parked = ring.start_s + 0.5
        t0 = wait_until("the joined time", lambda: (t := _readout_time(page)) > 0 and abs(t - parked) < 0.06 and t)
        page.get_by_role("button", name="Play").click()
        # Conditions, not fixed sleeps: a loaded machine renders late, never wrong.
        wait_until("the clock to run", lambda: _readout_time(page) > t0 + 0.5)
        assert viewer.playing
        page.get_by_role("button", name="Pause").click()
        page.get_by_role("button", name="Play").wait_for()
        viewer.seek(parked)
        wait_until("the parked frame", lambda: abs(_readout_time(page) - parked) < 0.06)

        SHOTS.mkdir(exist_ok=True)
        # Non-blank 3D view: the ring's red LEDs are drawn (once the browser has drawn the frame it was sent).
        wait_until("the ring's red LEDs on screen", lambda: _lit_pixels(
            page.screenshot(path=str(SHOTS / "viewer_app.png")), (255, 0, 0)) > 20)
    finally:
        ctx.close()
    assert not foreign, f"requests left loopback: {foreign}"


def test_viser_html_export_plays_from_file(browser, small_show, tmp_path):
    from app.viewer import export_viser_html

    path = tmp_path / "show.html"
    path.write_bytes(export_viser_html(plan_show(small_show), fps=10.0))
    foreign: list[str] = []
    ctx, page = _guarded_page(browser, foreign)
    try:
        page.goto(path.as_uri())
        page.wait_for_selector("canvas", timeout=60_000)
        time_input = page.locator("input").first
        time_input.wait_for(timeout=60_000)
        v0 = float(time_input.input_value())
        # It plays by itself: wait for a second of show time to pass (however slowly the machine draws).
        wait_until("the file to play", lambda: float(time_input.input_value()) > v0 + 1.0)
        SHOTS.mkdir(exist_ok=True)
        page.screenshot(path=str(SHOTS / "viewer_export.png"))
    finally:
        ctx.close()
    assert not foreign, f"requests left the file: {foreign}"
