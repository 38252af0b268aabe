"""The viewer inside the app: lifespan, the /viser/ page, the websocket relay and the playback endpoint."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest
import viser
import zstandard
from fastapi.testclient import TestClient

from app.server import create_app
from app.settings import AppSettings

PROTOCOL = f"viser-v{viser.__version__}"


def decode_viser_message(data: bytes) -> list[dict]:
    """Messages of one viser websocket frame: [raw len][zstd len][zstd msgpack][binary buffers]."""
    raw_len = int.from_bytes(data[:8], "little")
    z_len = int.from_bytes(data[8:16], "little")
    inner = zstandard.ZstdDecompressor().decompress(data[16:16 + z_len], max_output_size=raw_len)
    return list(msgspec.msgpack.decode(inner)["messages"])


@pytest.fixture
def client(tmp_path, small_show):
    app = create_app(AppSettings(data_dir=tmp_path, workers=1))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


@pytest.fixture
def show_id(client, small_show):
    r = client.post("/api/shows", content=small_show.model_dump_json(), headers={"content-type": "application/json"})
    assert r.status_code == 201, r.text
    return r.json()["id"]


def test_viser_page_is_served_locally(client):
    r = client.get("/viser/")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    assert "<canvas" in r.text or "<script" in r.text
    # One self-contained page: no external scripts, styles or fonts.
    assert 'src="http' not in r.text and 'href="http' not in r.text
    r = client.get("/viser", follow_redirects=False)
    assert r.status_code == 307 and r.headers["location"] == "/viser/"
    assert client.get("/viser/../../etc/passwd").status_code == 404


def test_relay_passes_subprotocol_and_messages(client, show_id):
    r = client.post(f"/api/shows/{show_id}/playback", json={"source": "planned"})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["drones"] == 16 and body["viewer_url"] == "/viser/" and body["source"] == "planned"
    viewer = client.app.state.viewer
    assert viewer.current and viewer.current.startswith("test [")
    for path in ("/viser", "/viser/"):
        with client.websocket_connect(f"ws://127.0.0.1{path}", subprotocols=[PROTOCOL]) as ws:
            assert ws.accepted_subprotocol == PROTOCOL
            messages = decode_viser_message(ws.receive_bytes())
            types = {m["type"] for m in messages}
            # The server-wide scene comes through; the drones are each browser's own (viser adds
            # them once the browser reports its camera, which this bare socket never does).
            assert "FrameMessage" in types
            # The share button is off.
            theme = next(m for m in messages if m["type"] == "ThemeConfigurationMessage")
            assert theme["show_share_button"] is False


def test_playback_errors(client, show_id):
    assert client.post("/api/shows/nope/playback", json={}).status_code == 404
    assert client.post(f"/api/shows/{show_id}/playback", json={"source": "bogus"}).status_code == 422
    assert client.post(f"/api/shows/{show_id}/playback").status_code == 200  # no body: planned
    r = client.post(f"/api/shows/{show_id}/playback").json()
    assert r["cached"] is True


def test_simulated_playback(client, show_id):
    r = client.post(f"/api/shows/{show_id}/playback", json={"source": "simulated"})
    assert r.status_code == 200, r.text
    viewer = client.app.state.viewer
    assert viewer.source == "simulated" and viewer._shows[viewer.current].flight is not None
    viewer.seek(30.0)
    frame = viewer.render()
    plan = viewer._shows[viewer.current].plan
    # The flown drones track the plan closely.
    assert np.abs(frame.positions_m - plan.evaluate([30.0]).positions_m[0]).max() < 1.0
    # Switching back to the plan keeps the flight.
    viewer.set_source("planned")
    assert viewer.source == "planned"
    assert client.post(f"/api/shows/{show_id}/playback", json={"source": "simulated"}).json()["cached"] is True


def test_viewer_stops_with_the_app(tmp_path):
    app = create_app(AppSettings(data_dir=tmp_path, workers=1))
    with TestClient(app, base_url="http://127.0.0.1"):
        viewer = app.state.viewer
        assert viewer is not None and viewer.host == "127.0.0.1"
    assert viewer._stop.is_set() and app.state.viewer is None


def test_viser_html_export_via_api(client, show_id):
    r = client.get(f"/api/shows/{show_id}/export/viser-html", params={"fps": 5})
    assert r.status_code == 200, r.text[:300]
    assert r.headers["content-type"].startswith("text/html")
    assert b"__VISER_EMBED_DATA__" in r.content
    assert "attachment" in r.headers.get("content-disposition", "")


def test_live_viewer_websocket_outlives_the_header_timeout(tmp_path):
    """Bug 5's root cause: the slow-loris header timer stayed armed on a connection upgraded to a websocket and
    closed the 3D view's socket ``header_timeout_s`` after it opened; viser's client reconnected as a new client
    whose playback restarted from the default one (another show, t = 0). The socket must stay open (and the viewer
    keep one client), while a connection that never finishes its headers is still closed."""
    import asyncio
    import contextlib
    import socket
    import time
    from concurrent.futures import ThreadPoolExecutor

    import httpx
    from websockets.asyncio.client import connect
    from websockets.exceptions import ConnectionClosed

    from tests.live_server import ServerProcess

    timeout_s = 1.0
    server = ServerProcess(tmp_path, viewer=True, env={"SWARMSHOW_HEADER_TIMEOUT_S": str(timeout_s)})
    server.start()

    async def hold_open() -> tuple[float, int | None]:
        async with connect(f"ws://127.0.0.1:{server.port}/viser", subprotocols=[PROTOCOL],  # type: ignore[list-item]
                           max_size=None, ping_interval=None) as ws:
            t0 = time.monotonic()
            # Read what the viewer sends for 3 header timeouts (it sends the scene and GUI, then frames of
            # nothing); a closed socket ends the loop early.
            with contextlib.suppress(TimeoutError, ConnectionClosed):
                async with asyncio.timeout(3 * timeout_s):
                    async for _ in ws:
                        pass
            return time.monotonic() - t0, ws.close_code

    try:
        slow = socket.create_connection(("127.0.0.1", server.port), timeout=10)
        slow.sendall(b"GET /api/health HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ")
        # In a thread of its own: the session's shared Playwright (tests/live_server.py) keeps its sync API's
        # event loop set on the main thread once a browser module has run, and asyncio.run refuses to nest.
        with ThreadPoolExecutor(max_workers=1) as pool:
            open_s, close_code = pool.submit(asyncio.run, hold_open()).result()
        assert close_code is None and open_s >= 3 * timeout_s - 0.1, (open_s, close_code)
        assert slow.recv(1024) == b""  # the slow-header connection was still closed
        slow.close()
        assert httpx.get(f"{server.base}/api/health").status_code == 200
    finally:
        server.stop()


def test_seek_endpoint_refuses_unknown_pages_and_bad_bodies(client, show_id):
    """``POST /api/viewer/{token}/seek`` moves one browser's playback: an unknown token is 404, a body must name
    exactly one of a time and a formation (422 naming the field). (Moving a real page is the browser test's.)"""
    assert client.post("/api/viewer/nope/seek", json={"time_s": 3.0}).status_code == 404
    r = client.post("/api/viewer/nope/seek", json={"time_s": -1.0})
    assert r.status_code == 422 and "time_s" in r.text
    assert client.post("/api/viewer/nope/seek", json={"at": 1}).status_code == 422
    viewer = client.app.state.viewer
    pb = viewer._main  # stands in for a browser's playback: the endpoint finds playbacks by token
    viewer._clients[999] = pb
    try:
        for body in ({}, {"time_s": 1.0, "formation": 0}):
            r = client.post(f"/api/viewer/{pb.token}/seek", json=body)
            assert r.status_code == 422 and "exactly one" in r.text, r.text
        r = client.post(f"/api/viewer/{pb.token}/seek", json={"formation": 0})
        assert r.status_code == 422 and "formation" in r.text  # nothing on screen yet
        assert client.post(f"/api/shows/{show_id}/playback", json={}).status_code == 200
        plan = viewer._shows[viewer.current].plan
        holds = [seg.start_s for _, seg in plan.formation_segments()]
        r = client.post(f"/api/viewer/{pb.token}/seek", json={"formation": len(holds) - 1})
        assert r.status_code == 200 and r.json()["time_s"] == pytest.approx(holds[-1])
        r = client.post(f"/api/viewer/{pb.token}/seek", json={"time_s": 1e5})
        assert r.status_code == 200 and r.json()["time_s"] == pytest.approx(plan.duration_s)  # clamped
        assert client.post(f"/api/viewer/{pb.token}/seek", json={"formation": len(holds)}).status_code == 422
    finally:
        viewer._clients.pop(999)
