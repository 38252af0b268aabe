"""Hardening, round two (issue 16): DNS rebinding, work bounded at validation time, error bodies, fairness.

Every test here failed before its fix; all run on loopback, bounded in count and time.
"""

from __future__ import annotations

import json

import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from app.server import create_app
from app.settings import AppSettings
from tests.test_api_live import SHOW

TOKEN = "correct-horse-battery-staple-42"
LOOPBACK = "http://127.0.0.1"


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("r2"), workers=1, viewer=False))
    with TestClient(app, base_url=LOOPBACK) as c:
        yield c


def doc(**changes) -> dict:
    d = json.loads(json.dumps(SHOW))
    d.update(changes)
    return d


# -- 1. DNS rebinding -------------------------------------------------------------------------------


@pytest.mark.parametrize("host", ["evil.example", "evil.example:8000", "127.0.0.1.evil.example", "0.0.0.0:8000",
                                  "192.168.1.5", "localhost.evil.example", "user@127.0.0.1", "127.0.0.1:x"])
def test_tokenless_server_refuses_foreign_host_names(client, host):
    before = client.get("/api/shows").json()["total"]
    for method, path in (("GET", "/api/shows"), ("GET", "/api/health"), ("GET", "/"), ("GET", "/viser/"),
                         ("POST", "/api/shows"), ("DELETE", "/api/shows/x")):
        body = json.dumps(SHOW) if method == "POST" else None
        r = client.request(method, path, content=body, headers={"Host": host, "Content-Type": "application/json"})
        assert r.status_code == 421, (host, method, path, r.status_code)
        assert "loopback" in r.json()["detail"]
    assert client.get("/api/shows").json()["total"] == before  # nothing created


@pytest.mark.parametrize("host", ["127.0.0.1", "127.0.0.1:8000", "localhost", "localhost:5173", "[::1]",
                                  "[::1]:8000", "LOCALHOST:8000"])
def test_tokenless_server_answers_loopback_host_names(client, host):
    assert client.get("/api/health", headers={"Host": host}).status_code == 200


def test_foreign_origin_refused_even_with_a_loopback_host(client):
    # The rebinding page's Origin is its own name: refused on reads as well as writes.
    r = client.get("/api/shows", headers={"Origin": "http://evil.example:8000"})
    assert r.status_code == 421
    assert client.get("/api/shows", headers={"Origin": "http://localhost:8000"}).status_code == 200


def test_viser_websocket_refuses_foreign_host_and_origin(client):
    # (starlette's test client sends Host from the URL it is given)
    for url, headers in (("ws://evil.example:8000/viser", {}),
                         ("ws://127.0.0.1:8000/viser", {"Origin": "http://evil.example:8000"}),
                         ("ws://evil.example/viser/", {"Origin": "http://evil.example"})):
        with pytest.raises(WebSocketDisconnect) as info, client.websocket_connect(url, headers=headers):
            pass
        assert info.value.code == 1008, url
    # A loopback Host and Origin pass the guard (this server runs no viewer: 1013, not 1008).
    with pytest.raises(WebSocketDisconnect) as info, client.websocket_connect(
            "ws://localhost:8000/viser", headers={"Origin": "http://localhost:8000"}):
        pass
    assert info.value.code == 1013


def test_with_a_token_the_token_rules_apply_whatever_the_host(tmp_path):
    app = create_app(AppSettings(data_dir=tmp_path, workers=1, viewer=False, token=TOKEN))
    with TestClient(app, base_url="http://show.example.org") as c:
        assert c.get("/api/shows").status_code == 401
        assert c.get("/api/shows", headers={"Authorization": f"Bearer {TOKEN}"}).status_code == 200


def test_allowed_hosts_setting_adds_names(tmp_path):
    app = create_app(AppSettings(data_dir=tmp_path, workers=1, viewer=False, allowed_hosts=["studio.lan"]))
    with TestClient(app, base_url="http://studio.lan:8000") as c:
        assert c.get("/api/health").status_code == 200
        assert c.get("/api/health", headers={"Host": "evil.example"}).status_code == 421
