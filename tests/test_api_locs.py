"""Every 4xx names the field at fault in ``loc`` and ``path`` (QA round 2): rules across two fields of the show
file blamed the object holding them (``settings`` for a takeoff above the ceiling), and a formation built
outside the limits answered an empty path."""

from __future__ import annotations

import pytest
from fastapi.testclient import TestClient

from app.server import create_app
from app.settings import AppSettings
from tests.test_api_shows import show_doc


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("data"), workers=1, viewer=False))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


def _formation(**fields) -> dict:
    doc = show_doc("locs")
    doc["formations"][0].update(fields)
    return doc


CASES = [
    ("takeoff above the ceiling", show_doc("t", takeoff_altitude_m=50.0, max_altitude_m=40.0),
     ("settings", "takeoff_altitude_m"), "above max_altitude_m"),
    ("floor above the ceiling", show_doc("t", min_altitude_m=45.0, max_altitude_m=40.0),
     ("settings", "min_altitude_m"), "below max_altitude_m"),
    ("geofence empty in x", show_doc("t", geofence={"x_min_m": 5, "x_max_m": -5, "y_min_m": -5, "y_max_m": 5}),
     ("settings", "geofence", "x_max_m"), "x_min_m < x_max_m"),
    ("geofence empty in y", show_doc("t", geofence={"x_min_m": -5, "x_max_m": 5, "y_min_m": 5, "y_max_m": 5}),
     ("settings", "geofence", "y_max_m"), "y_min_m < y_max_m"),
    ("color and colors", _formation(colors=["#ff0000"] * 4), ("formations", 0, "colors"), "not both"),
    ("colors too short", {**_formation(colors=["#ff0000"] * 3), "formations": [
        {k: v for k, v in _formation(colors=["#ff0000"] * 3)["formations"][0].items() if k != "color"}]},
     ("formations", 0, "colors"), "3 entries"),
    ("transition and arrival", _formation(transition_s=5.0, arrive_at_s=9.0), ("formations", 0, "arrive_at_s"),
     "either"),
    ("leave before arrival", _formation(arrive_at_s=9.0, leave_at_s=8.0), ("formations", 0, "leave_at_s"),
     "after arrive_at_s"),
]


def _path(loc: tuple) -> str:
    out = ""
    for p in loc:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out


@pytest.mark.parametrize("doc,loc,words", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_cross_field_rules_name_the_field(client, doc, loc, words):
    r = client.post("/api/shows", json=doc)
    assert r.status_code == 422, r.text
    problem = r.json()["detail"][0]
    assert problem["loc"] == ["body", *loc] and problem["path"] == _path(loc), problem
    assert words in problem["msg"], problem
    # The same through PUT {"revision", "show"}: under "show", and nothing stored.
    rec = client.post("/api/shows", json=show_doc("put target")).json()
    r = client.put(f"/api/shows/{rec['id']}", json={"revision": rec["revision"], "show": doc})
    assert r.status_code == 422, r.text
    problem = r.json()["detail"][0]
    assert problem["loc"] == ["body", "show", *loc] and problem["path"] == "show." + _path(loc), problem
    assert client.get(f"/api/shows/{rec['id']}").json()["revision"] == rec["revision"]


FORMATIONS = [
    ("centre below the ground", "shape", {"kind": "circle", "n": 8, "size_m": 20, "center_m": [0, 0, -30]},
     "center_m"),
    ("centre beyond the show area", "shape", {"kind": "circle", "n": 8, "size_m": 20, "center_m": [2e5, 0, 30]},
     "center_m"),
    ("shape too large for its centre", "shape", {"kind": "circle", "n": 8, "size_m": 5000, "center_m": [0, 0, 30]},
     "size_m"),
    ("letters too tall for their centre", "text", {"text": "A", "n": 20, "height_m": 5000, "center_m": [0, 0, 30]},
     "height_m"),
]


@pytest.mark.parametrize("source,body,field", [c[1:] for c in FORMATIONS], ids=[c[0] for c in FORMATIONS])
def test_a_formation_outside_the_limits_names_the_field(client, source, body, field):
    r = client.post(f"/api/formations/{source}", json=body)
    assert r.status_code == 422, r.text
    problem = r.json()["detail"][0]
    assert problem["loc"] == ["body", field] and problem["path"] == field, problem
    assert "outside" in problem["msg"], problem
