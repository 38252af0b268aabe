"""Exposure: loopback by default, a token off loopback, 401 without it (HTTP and websocket), the session
cookie, no CORS, cross-site writes refused, security headers, body limits before parsing."""

from __future__ import annotations

import subprocess

import httpx
import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from app.server import create_app
from app.server._auth import COOKIE, session_ok, session_value
from app.server._exposure import is_loopback
from app.settings import AppSettings
from tests.live_server import ServerProcess, swarmshow_command
from tests.test_api_live import SHOW

TOKEN = "correct-horse-battery-staple-42"


@pytest.fixture(scope="module")
def open_client(tmp_path_factory):
    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("open"), workers=1, viewer=False))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


@pytest.fixture(scope="module")
def locked(tmp_path_factory):
    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("locked"), workers=1, token=TOKEN))
    with TestClient(app) as c:  # with a token any Host name is answered (the token rules apply)
        yield c


def test_default_host_is_loopback_and_other_hosts_need_a_token(tmp_path):
    assert AppSettings().host == "127.0.0.1"
    assert all(map(is_loopback, ("127.0.0.1", "127.8.9.1", "::1", "[::1]", "localhost")))
    assert not any(map(is_loopback, ("0.0.0.0", "::", "192.168.1.5", "example.com", "")))
    for host in ("0.0.0.0", "::", "10.0.0.7"):
        r = subprocess.run([*swarmshow_command(), "serve", "--host", host, "--port", "0", "--data-dir",
                            str(tmp_path)], capture_output=True, text=True, timeout=60,
                           env={**_no_token_env(), "SWARMSHOW_TOKEN": ""})
        assert r.returncode == 2, r.stderr
        assert "SWARMSHOW_TOKEN" in r.stderr and f"refusing to listen on {host}" in r.stderr
    weak = subprocess.run([*swarmshow_command(), "serve", "--host", "0.0.0.0", "--data-dir", str(tmp_path)],
                          capture_output=True, text=True, timeout=60, env={**_no_token_env(), "SWARMSHOW_TOKEN": "x"})
    assert weak.returncode == 2 and "SWARMSHOW_TOKEN" in weak.stderr


def _no_token_env() -> dict[str, str]:
    import os

    return {k: v for k, v in os.environ.items() if k != "SWARMSHOW_TOKEN"}


@pytest.mark.parametrize("headers", [
    {}, {"Authorization": "Bearer wrong"}, {"Authorization": f"Basic {TOKEN}"}, {"Authorization": "Bearer"},
    {"Authorization": f"Bearer {TOKEN}x"}, {"Cookie": f"{COOKIE}=1.abc"},
])
@pytest.mark.parametrize("method,path", [
    ("GET", "/api/health"), ("GET", "/api/shows"), ("POST", "/api/shows"), ("GET", "/api/openapi.json"),
    ("GET", "/viser/"), ("DELETE", "/api/shows/x"), ("GET", "/api/jobs/x/events"),
])
def test_wrong_or_missing_token_gets_the_same_bare_401(locked, headers, method, path):
    r = locked.request(method, path, headers=headers, content=b"{}" if method == "POST" else None)
    assert r.status_code == 401
    assert r.json() == {"detail": "unauthorized"}  # the same whatever was wrong: nothing to learn from it
    assert r.headers["www-authenticate"].startswith("Bearer")


def test_bearer_token_opens_api_and_viewer(locked):
    auth = {"Authorization": f"Bearer {TOKEN}"}
    assert locked.get("/api/health", headers=auth).status_code == 200
    r = locked.post("/api/shows", json=SHOW, headers=auth)
    assert r.status_code == 201
    assert locked.get("/viser/", headers=auth).status_code == 200
    assert locked.get("/").status_code == 200  # the editor's files are public: it asks for the token


def test_session_cookie_for_iframe_eventsource_and_websocket(locked):
    assert locked.post("/api/session", json={"token": "nope"}).status_code == 401
    assert COOKIE not in locked.cookies
    r = locked.post("/api/session", json={"token": TOKEN})
    assert r.status_code == 204
    cookie = r.headers["set-cookie"]
    assert "HttpOnly" in cookie and "SameSite=strict" in cookie.replace("Strict", "strict") and "Max-Age=3600" in cookie
    try:
        assert locked.get("/api/shows").status_code == 200  # the cookie alone
        assert locked.get("/viser/").status_code == 200
        with locked.websocket_connect("/viser", subprotocols=["viser-v1"]) as ws:
            assert ws is not None
    finally:
        locked.cookies.clear()
    with pytest.raises(WebSocketDisconnect), locked.websocket_connect("/viser"):
        pass


def test_session_by_header_and_expiry():
    value = session_value(token=TOKEN, ttl_s=60, now=1000.0)
    assert session_ok(value, token=TOKEN, now=1059.0)
    assert not session_ok(value, token=TOKEN, now=1061.0)  # expired
    assert not session_ok(value, token=TOKEN + "2", now=1000.0)  # a new token revokes old cookies
    assert not session_ok(value.replace(".", ".0", 1), token=TOKEN, now=1000.0)


def test_live_server_websocket_without_token_is_refused(tmp_path):
    websockets = pytest.importorskip("websockets.sync.client")
    server = ServerProcess(tmp_path, env={"SWARMSHOW_TOKEN": TOKEN})
    server.start(wait=False)
    try:
        server.wait_ready()
        with pytest.raises(Exception) as info:
            websockets.connect(f"ws://127.0.0.1:{server.port}/viser", open_timeout=10).close()
        assert "401" in str(info.value) or "403" in str(info.value)
        r = httpx.post(f"{server.base}/api/session", json={"token": TOKEN})
        assert r.status_code == 204
        cookie = r.headers["set-cookie"].split(";")[0]
        assert httpx.get(f"{server.base}/api/shows", headers={"Cookie": cookie}).status_code == 200
    finally:
        server.stop()


def test_no_cors_and_cross_site_writes_refused(open_client):
    r = open_client.get("/api/shows", headers={"Origin": "https://evil.example"})
    # A foreign Origin is refused outright by the tokenless server (DNS-rebinding guard), never with CORS.
    assert r.status_code == 421 and not any(h.startswith("access-control-") for h in r.headers)
    pre = open_client.options("/api/shows", headers={
        "Origin": "https://evil.example", "Access-Control-Request-Method": "PUT"})
    assert "access-control-allow-origin" not in pre.headers
    before = open_client.get("/api/shows").json()["total"]
    for headers in ({"Origin": "https://evil.example"}, {"Origin": "null"}, {"Sec-Fetch-Site": "cross-site"}):
        r = open_client.post("/api/shows", content=_json(SHOW), headers={"Content-Type": "text/plain", **headers})
        assert r.status_code == 403, headers
    assert open_client.get("/api/shows").json()["total"] == before
    same = open_client.post("/api/shows", json=SHOW, headers={"Origin": "http://127.0.0.1"})
    assert same.status_code == 201


def _json(doc: dict) -> bytes:
    import json

    return json.dumps(doc).encode()


def test_security_headers(open_client):
    editor = open_client.get("/")
    csp = editor.headers["content-security-policy"]
    assert "default-src 'self'" in csp and "'unsafe-inline'" not in csp and "frame-ancestors 'self'" in csp
    assert "script-src 'self';" in csp
    for r in (editor, open_client.get("/api/health"), open_client.get("/api/shows/none"),
              open_client.get("/viser/")):
        assert r.headers["x-content-type-options"] == "nosniff"
        assert r.headers["referrer-policy"] == "no-referrer"
    viewer = open_client.get("/viser/").headers["content-security-policy"]
    assert "frame-ancestors 'self'" in viewer and "'wasm-unsafe-eval'" in viewer
    assert open_client.get("/api/health").headers["content-security-policy"].startswith("default-src 'none'")


def test_body_limit_is_enforced_before_the_body_is_read(open_client):
    app = open_client.app
    limit = app.state.settings.max_show_bytes
    # A declared length over the limit is refused before a byte of the body is taken.
    pulled = []

    def body():
        for _ in range(1024):
            pulled.append(1)
            yield b"x" * (1 << 20)

    r = open_client.post("/api/shows", content=body(), headers={"Content-Length": str(1 << 30)})
    assert r.status_code == 413 and "20 MB" in r.json()["detail"]
    assert len(pulled) <= 2
    assert limit < 1 << 30
