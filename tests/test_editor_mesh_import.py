"""The editor's mesh / point-cloud import control (issue 21), driven with Playwright against a live
server on loopback: a GLB with vertex colours becomes a formation of every drone, in its colours;
a size too small says how many fit and what size fits all."""

from __future__ import annotations

import math

import httpx
import numpy as np
import pytest
import trimesh

from tests.live_server import BROWSER_MARKS, server_for
from tests.test_editor_browser import Page, _create_show

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")


server = server_for("mesh-data", viewer=False)


def test_import_glb_surface_with_vertex_colours(ui: Page):
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
    # the file's upper half (+y: glTF is y-up) red, the lower half blue
    mesh.visual.vertex_colors = np.where(mesh.vertices[:, 1:2] > 0, [[255, 0, 0, 255]],
                                         [[0, 0, 255, 255]]).astype(np.uint8)
    path = ui.tmp / "ball.glb"
    path.write_bytes(mesh.export(file_type="glb"))
    page = ui.page
    _create_show(ui, "Mesh import", 24)
    page.locator("summary", has_text="Mesh / point cloud").click()
    page.set_input_files("#mesh-file", str(path))
    page.select_option("#mesh-mode", "surface")
    page.get_by_role("button", name="Replace the formation with points from the mesh or point file").click()
    # (a new show's first formation already has 24 points: wait for the imported ones)
    page.wait_for_function("() => (window.swarmshow.state.formation.source || {}).kind === 'mesh'")
    assert ui.state("s.formation.points.length") == 24
    pts = np.array(ui.state("s.formation.points"))
    colors = np.array(ui.state("s.formation.colors"))
    d = min(np.linalg.norm(pts[i] - pts[j]) for i in range(len(pts)) for j in range(i))
    assert d >= ui.state("s.show.settings.min_distance_m") - 0.01  # the editor rounds to centimetres
    # up in the file is up in the show: well above the middle red, well below blue (faces that
    # straddle the equator mix the two)
    lo, hi = pts[:, 2].min(), pts[:, 2].max()
    h = (pts[:, 2] - (lo + hi) / 2) / ((hi - lo) / 2)
    assert (h > 0.5).sum() >= 3 and (h < -0.5).sum() >= 3
    assert set(colors[h > 0.5]) == {"#ff0000"} and set(colors[h < -0.5]) == {"#0000ff"}
    page.fill("#mesh-size", "2")
    page.get_by_role("button", name="Replace the formation with points from the mesh or point file").click()
    err = page.locator('[data-error-for="mesh"]')
    sync_api.expect(err).to_contain_text("at most")
    sync_api.expect(err).to_contain_text("fits all 24")


def _pinhole(p, *, target, yaw_rad, pitch_rad, distance_m, fov_rad, width, height):
    """Screen pixel and depth of world point ``p`` through an orbit camera, written out from the
    camera's definition (yaw turns the view direction about z from +y toward +x, pitch looks down,
    vertical field of view ``fov_rad``), independently of camera.js."""
    cy, sy, cp, sp = math.cos(yaw_rad), math.sin(yaw_rad), math.cos(pitch_rad), math.sin(pitch_rad)
    forward = np.array([sy * cp, cy * cp, -sp])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    eye = np.asarray(target, dtype=float) - distance_m * forward
    d = np.asarray(p, dtype=float) - eye
    focal = height / 2 / math.tan(fov_rad / 2)
    z = float(d @ forward)
    return width / 2 + float(d @ right) * focal / z, height / 2 - float(d @ up) * focal / z, z


def test_glb_import_view_in_3d_and_move_one_point(ui: Page):
    """Issue 21's done-when: a GLB imported through the mesh panel, viewed in the free 3D view, one
    point picked with the mouse and dragged along x (axis-constrained) by a set distance; exactly that
    point moves, by that vector in 3D, and the show saves with it."""
    mesh = trimesh.creation.box(extents=(2.0, 2.0, 2.0))
    path = ui.tmp / "cube.glb"
    path.write_bytes(mesh.export(file_type="glb"))
    page = ui.page
    n = 20
    _create_show(ui, "GLB in 3D", n)
    page.locator("summary", has_text="Mesh / point cloud").click()
    page.set_input_files("#mesh-file", str(path))
    page.select_option("#mesh-mode", "surface")
    page.get_by_role("button", name="Replace the formation with points from the mesh or point file").click()
    page.wait_for_function("() => (window.swarmshow.state.formation.source || {}).kind === 'mesh'")
    before = np.array(ui.state("s.formation.points"))
    assert before.shape == (n, 3)
    # A cube's surface: every point on one of the six faces of an axis-aligned box.
    lo, hi = before.min(axis=0), before.max(axis=0)
    on_face = (np.abs(before - lo) < 0.02) | (np.abs(before - hi) < 0.02)
    assert on_face.any(axis=1).all(), before

    # ---- the free 3D view, an oblique camera on the formation's centre.
    page.select_option("#view-select", "3d")
    assert ui.state("window.swarmshow.view.view") == "3d"
    centre = ((lo + hi) / 2).tolist()
    cam = dict(target=centre, yaw_rad=-0.6, pitch_rad=0.35, distance_m=float(6 * (hi - lo).max()))
    page.evaluate(f"""() => {{ const c = window.swarmshow.view.camera;
        c.target = {centre}; c.yaw_rad = {cam['yaw_rad']}; c.pitch_rad = {cam['pitch_rad']};
        c.distance_m = {cam['distance_m']}; window.swarmshow.view._draw(); }}""")
    view = ui.state("[window.swarmshow.view.width, window.swarmshow.view.height, "
                    "window.swarmshow.view.camera.fov_rad]")
    cam.update(width=view[0], height=view[1], fov_rad=view[2])
    screen = np.array([_pinhole(p, **cam) for p in before])
    # camera.js agrees with the closed form on every point
    js = np.array(page.evaluate(f"() => {before.tolist()}.map((p) => window.swarmshow.view.camera.project(p))"))
    assert np.allclose(js, screen, atol=1e-6)
    ui.shot("editor-glb-3d-view")

    # The point nearest the camera: the hit test prefers it, so a click on it selects it alone.
    k = int(np.argmin(screen[:, 2]))
    box = page.locator("#canvas").bounding_box()
    _key(ui, "Escape")
    page.mouse.click(box["x"] + screen[k, 0], box["y"] + screen[k, 1])
    assert ui.state("[...s.selection]") == [k]

    # ---- drag it along x: from its pixel to the pixel of the point 0.8 m further along x.
    page.select_option("#move-axis", "x")
    shift = np.array([0.8, 0.0, 0.0])
    tx, ty, _ = _pinhole(before[k] + shift, **cam)
    m = page.mouse
    m.move(box["x"] + screen[k, 0], box["y"] + screen[k, 1])
    m.down()
    m.move(box["x"] + tx, box["y"] + ty, steps=8)
    m.up()
    after = np.array(ui.state("s.formation.points"))
    assert ui.state("s.undoStack.at(-1).label") == "Move point"
    others = np.arange(n) != k
    assert np.array_equal(after[others], before[others])
    # sub-pixel mouse positions: a pixel is distance / focal ≈ 2 cm here
    assert np.allclose(after[k] - before[k], shift, atol=0.03), after[k] - before[k]
    assert after[k][1] == before[k][1] and after[k][2] == before[k][2]  # the axis constraint is exact

    # ---- it saves: the server's copy has exactly that move.
    page.locator("#canvas").focus()
    page.keyboard.press("Control+s")
    sync_api.expect(page.locator("#dirty-indicator")).to_be_hidden()
    show_id = ui.state("s.meta.id")
    saved = np.array(httpx.get(f"{ui.base}/api/shows/{show_id}").json()["show"]["formations"][0]["points"])
    assert np.allclose(saved, after, atol=1e-6)
    assert np.allclose(saved[k] - before[k], shift, atol=0.03)
    assert np.array_equal(saved[others], before[others])


def _key(ui: Page, key: str) -> None:
    ui.page.locator("#canvas").focus()
    ui.page.keyboard.press(key)
