"""Light effects through the REST API (issue 18): a bad effect is a 422 naming its field and the
stored show is untouched; a good one is stored and exported with its colours."""

from __future__ import annotations

import base64
import io
import json
import zipfile

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.server import create_app
from app.settings import AppSettings
from tests.ledctrl_reader import replay
from tests.test_api_shows import show_doc


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("data"), workers=1))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


def _strobe(**kind) -> dict:
    return {"start_s": 2.0, "end_s": 6.0, "effect": {"kind": "strobe", "color": "#ffffff", **kind}}


def test_bad_effect_is_422_with_its_path_and_keeps_the_stored_show(client) -> None:
    doc = show_doc("lights")
    r = client.post("/api/shows", json={**doc, "lights": {"effects": [_strobe()]}})
    assert r.status_code == 201, r.text
    rec = r.json()
    bad = {**doc, "lights": {"effects": [_strobe(frequency_hz=400)]}}
    r = client.put(f"/api/shows/{rec['id']}", json={"show": bad, "revision": rec["revision"]})
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["path"] == "show.lights.effects[0].effect.frequency_hz"
    kept = client.get(f"/api/shows/{rec['id']}").json()["show"]
    assert kept["lights"]["effects"][0]["effect"]["frequency_hz"] == 4.0

    # The stored strobe reaches the .skyc: white flashes at 4 Hz between 2 and 6 s.
    r = client.get(f"/api/shows/{rec['id']}/export/skyc")
    assert r.status_code == 200, r.text
    with zipfile.ZipFile(io.BytesIO(r.content)) as z:
        drones = json.loads(z.read("show.json"))["swarm"]["drones"]
    colors = replay(base64.b64decode(drones[0]["settings"]["lights"]["data"]), 400)
    x = (np.arange(100, 300) / 50.0 - 2.0) * 4.0
    on = (x - np.floor(x)) < 0.5  # the strobe's closed form: on for the first half of each 0.25 s period
    np.testing.assert_array_equal((colors[100:300] == 255).all(axis=1), on)
