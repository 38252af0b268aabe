"""The editor and the 3D viewer in Chromium behind a token and under the Content-Security-Policy.

The editor asks for the token once, trades it for the HttpOnly session cookie, and
the viewer page and its websocket then work on that cookie alone; neither page logs
a CSP violation or an uncaught error.
"""

from __future__ import annotations

import time

import httpx
import pytest

from tests.live_server import BROWSER_MARKS, ServerProcess, chromium_browser, wait_until
from tests.test_api_live import SHOW

TOKEN = "browser-token-0123456789abcdef"

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    srv = ServerProcess(tmp_path_factory.mktemp("browser"), viewer=True, env={"SWARMSHOW_TOKEN": TOKEN})
    srv.start()
    try:
        yield srv
    finally:
        srv.stop()


def _watch(page, problems: list[str]) -> None:
    page.on("pageerror", lambda e: problems.append(f"error: {e}"))
    page.on("console", lambda m: ("Content Security Policy" in m.text or "Refused to" in m.text)
            and problems.append(f"csp: {m.text}"))


def test_editor_token_prompt_session_cookie_and_viewer_under_csp(server):
    auth = {"Authorization": f"Bearer {TOKEN}"}
    sid = httpx.post(f"{server.base}/api/shows", json=SHOW, headers=auth).json()["id"]
    r = httpx.post(f"{server.base}/api/shows/{sid}/playback", json={"source": "planned"}, headers=auth, timeout=60)
    assert r.status_code == 200, r.text

    problems: list[str] = []
    with chromium_browser("--enable-unsafe-swiftshader") as browser:
        ctx = browser.new_context(viewport={"width": 1280, "height": 800})
        editor = ctx.new_page()
        _watch(editor, problems)
        editor.set_default_timeout(20_000)
        editor.goto(f"{server.base}/")
        editor.wait_for_selector("#dlg-token", state="visible")  # the API said 401: the editor asks
        editor.fill("#token-input", TOKEN)
        editor.press("#token-input", "Enter")
        cookie = wait_until("the session cookie", lambda: next(
            (c for c in ctx.cookies() if c["name"] == "swarmshow_session"), None), timeout_s=20)
        assert cookie["httpOnly"] and cookie["sameSite"] == "Strict"
        assert "swarmshow_session" not in editor.evaluate("document.cookie")  # scripts cannot read it
        editor.wait_for_function("() => !document.getElementById('dlg-token').open")

        viewer = ctx.new_page()  # no Authorization header: the cookie alone
        _watch(viewer, problems)
        sockets: list = []
        viewer.on("websocket", lambda ws: sockets.append(ws))
        viewer.goto(f"{server.base}/viser/")
        viewer.wait_for_selector("canvas", timeout=60_000)
        viewer.get_by_text("4 drones").first.wait_for(timeout=60_000)  # the scene arrived over the websocket
        assert sockets and not sockets[0].is_closed()
        time.sleep(1.0)  # let late violations surface
        ctx.close()

        stranger = browser.new_context()
        page = stranger.new_page()
        assert page.goto(f"{server.base}/viser/").status == 401
        stranger.close()
    assert problems == []
