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


# -- 2. sizes that derive work from a small input are bounded at validation time --------------------


def _point(x: str) -> str:
    return json.dumps(SHOW).replace("[0, 0, 6]", f"[{x}, 0, 6]", 1)


BOUNDED_CASES = [
    ("1 drone on a 20,000 x 20,000 grid",
     json.dumps(doc(drones=1, home={"grid": {"rows": 20_000, "cols": 20_000}},
                    formations=[{"name": "a", "hold_s": 1.0, "points": [[0, 0, 6]]}])),
     "home.grid", "more than 16"),
    ("4 drones on 17 home points",
     json.dumps(doc(home={"points": [[5.0 * i, 0, 0] for i in range(17)]})), "home.points", "at most 16"),
    ("grid reaching outside the area",
     json.dumps(doc(home={"grid": {"rows": 2, "cols": 2, "spacing_m": 4.5, "center_m": [1999, 0]}})),
     "home.grid", "max_horizontal_extent_m"),
    ("x = 1e9", _point("1e9"), "formations[0].points[0][0]", "outside the show area"),
    ("x = 1e308", _point("1e308"), "formations[0].points[0][0]", "outside the show area"),
    ("x = -2001", _point("-2001"), "formations[0].points[0][0]", "+-2000 m"),
    ("hold_s = 1e-320", json.dumps(SHOW).replace('"hold_s": 2.0', '"hold_s": 1e-320'), "formations[0].hold_s",
     "greater than or equal to 0.01"),
    ("transition_s = 5e-324", json.dumps(SHOW).replace('"hold_s": 2.0', '"hold_s": 2.0, "transition_s": 5e-324'),
     "formations[0].transition_s", "greater than or equal to 0.01"),
    ("speed 1e-300", json.dumps(doc(settings={"max_speed_xy_mps": 1e-300})), "settings.max_speed_xy_mps",
     "greater than or equal to 0.1"),
    ("min distance 1e-9", json.dumps(doc(settings={"min_distance_m": 1e-9})), "settings.min_distance_m",
     "greater than or equal to 0.1"),
    ("area asked too large", json.dumps(doc(settings={"max_horizontal_extent_m": 1e9})),
     "settings.max_horizontal_extent_m", "less than or equal"),
]


@pytest.mark.parametrize(("body", "path", "words"), [c[1:] for c in BOUNDED_CASES], ids=[c[0] for c in BOUNDED_CASES])
def test_work_deriving_sizes_refused_at_validation(client, body, path, words):
    r = client.post("/api/shows", content=body, headers={"Content-Type": "application/json"})
    assert r.status_code == 422, r.text
    problems = r.json()["detail"]
    assert problems[0]["path"] == path, problems
    assert words in problems[0]["msg"], problems


def test_a_wider_area_can_be_asked_for(client):
    body = _point("2500").replace('"settings": {', '"settings": {"max_horizontal_extent_m": 3000, ', 1)
    assert client.post("/api/shows", content=body, headers={"Content-Type": "application/json"}).status_code == 201
