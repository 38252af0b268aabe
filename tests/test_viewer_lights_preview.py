"""``POST /api/viewer/{token}/lights`` (issue 18 item 4): the editor's unsaved effect stack painted in one
browser's 3D playback, checked against the plan on screen (422 naming the field), dropped when the show reloads."""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.server import create_app
from app.settings import AppSettings


@pytest.fixture
def client(tmp_path):
    app = create_app(AppSettings(data_dir=tmp_path, workers=1))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


@pytest.fixture
def page(client, small_show):
    """(show id, a playback found by token: the headless main playback stands in for a browser's)."""
    r = client.post("/api/shows", content=small_show.model_dump_json(), headers={"content-type": "application/json"})
    assert r.status_code == 201, r.text
    viewer = client.app.state.viewer
    pb = viewer._main
    viewer._clients[999] = pb
    yield r.json()["id"], pb
    viewer._clients.pop(999, None)


def _fx(target: dict, color: str = "#0000ff") -> dict:
    return {"start_s": 0.0, "end_s": 1000.0, "target": target, "effect": {"kind": "solid", "color": color}}


def _ring_hold_colors(pb) -> np.ndarray:
    """(16, 3) colours the playback renders in the middle of the red ring's hold."""
    plan = pb.plan()
    (_, hold), = [(n, s) for n, s in plan.formation_segments() if n == "ring"]
    pb.seek(hold.start_s + hold.duration_s / 2)
    return np.asarray(pb.render().colors_rgb)


def test_unsaved_effects_paint_this_playback_until_the_show_reloads(client, page):
    show_id, pb = page
    assert client.post(f"/api/viewer/{pb.token}/lights", json={"lights": None}).status_code == 422  # nothing on screen
    assert client.post(f"/api/shows/{show_id}/playback", json={}).status_code == 200
    red = np.array([1.0, 0.0, 0.0])
    assert np.allclose(_ring_hold_colors(pb), red, atol=1e-6)  # the saved show has no effects

    lights = {"groups": {"pair": [0, 2]}, "effects": [_fx({"kind": "group", "group": "pair"})]}
    r = client.post(f"/api/viewer/{pb.token}/lights", json={"lights": lights})
    assert r.status_code == 200, r.text
    assert r.json()["effects"] == 1 and r.json()["revision"] == 1
    got = _ring_hold_colors(pb)
    # Independently: the group's drones take the solid colour (replace, full opacity), the rest keep the ring's red.
    want = np.tile(red, (16, 1))
    want[[0, 2]] = [0.0, 0.0, 1.0]
    assert np.allclose(got, want, atol=1e-6)
    assert 'data-lights="1"' in pb._link_html(got) and "#0000ff" in pb._link_html(got)

    # An empty design clears the preview; a reload of the show brings back the saved effects (none).
    r = client.post(f"/api/viewer/{pb.token}/lights", json={"lights": {"effects": [_fx({"kind": "all"})]}})
    assert r.status_code == 200 and np.allclose(_ring_hold_colors(pb), [0, 0, 1], atol=1e-6)
    assert client.post(f"/api/viewer/{pb.token}/lights", json={}).json()["effects"] == 0
    assert np.allclose(_ring_hold_colors(pb), red, atol=1e-6)
    client.post(f"/api/viewer/{pb.token}/lights", json={"lights": {"effects": [_fx({"kind": "all"})]}})
    assert client.post(f"/api/shows/{show_id}/playback", json={}).status_code == 200
    assert np.allclose(_ring_hold_colors(pb), red, atol=1e-6)


@pytest.mark.parametrize(("lights", "field"), [
    ({"effects": [_fx({"kind": "group", "group": "nope"})]}, "lights.effects[0].target.group"),
    ({"groups": {"g": [99]}, "effects": []}, "lights.groups.g"),
    ({"effects": [_fx({"kind": "drones", "indices": [16]})]}, "lights.effects[0].target.indices"),
    ({"effects": [_fx({"kind": "formation", "formation": "cube"})]}, "lights.effects[0].target.formation"),
    ({"effects": [{"start_s": 5.0, "end_s": 1.0, "effect": {"kind": "solid", "color": "#ffffff"}}]}, "end_s"),
    ({"effects": [_fx({"kind": "all"})] * 201}, "effects"),
])
def test_bad_designs_are_422_naming_the_field_and_change_nothing(client, page, lights, field):
    show_id, pb = page
    assert client.post(f"/api/shows/{show_id}/playback", json={}).status_code == 200
    r = client.post(f"/api/viewer/{pb.token}/lights", json={"lights": lights})
    assert r.status_code == 422 and field in r.text, r.text
    assert pb.lights_rev == 0 and np.allclose(_ring_hold_colors(pb), [1, 0, 0], atol=1e-6)


def test_unknown_page_is_404(client):
    assert client.post("/api/viewer/nope/lights", json={"lights": None}).status_code == 404


def test_a_design_is_bounded_like_a_show_file(tmp_path, small_show):
    """The body may be a show's worth (images and videos are large), not more: 413 naming the limit."""
    app = create_app(AppSettings(data_dir=tmp_path, workers=1, max_show_bytes=3_000_000))
    with TestClient(app, base_url="http://127.0.0.1") as client:
        r = client.post("/api/shows", content=small_show.model_dump_json(),
                        headers={"content-type": "application/json"})
        show_id = r.json()["id"]
        viewer = client.app.state.viewer
        pb = viewer._main
        viewer._clients[999] = pb
        assert client.post(f"/api/shows/{show_id}/playback", json={}).status_code == 200
        # 1.9 MB of groups (more than the 1 MB default of other requests): taken.
        groups = {f"g{k}": [k % 16] * 19_000 for k in range(50)}
        r = client.post(f"/api/viewer/{pb.token}/lights", json={"lights": {"groups": groups, "effects": [
            _fx({"kind": "group", "group": "g1"})]}})
        assert r.status_code == 200, r.text[:300]
        assert np.allclose(_ring_hold_colors(pb)[1], [0, 0, 1]) and np.allclose(_ring_hold_colors(pb)[0], [1, 0, 0])
        groups = {f"g{k}": [k % 16] * 19_000 for k in range(90)}
        r = client.post(f"/api/viewer/{pb.token}/lights", json={"lights": {"groups": groups, "effects": []}})
        assert r.status_code == 413 and "lights" in r.text
