"""The editor's mesh / point-cloud import control (issue 21), driven with Playwright against a live
server on loopback: a GLB with vertex colours becomes a formation of every drone, in its colours;
a size too small says how many fit and what size fits all."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from tests.live_server import BROWSER_MARKS, running_server
from tests.test_editor_browser import Page, _create_show

pytestmark = BROWSER_MARKS

sync_api = pytest.importorskip("playwright.sync_api")


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    with running_server(tmp_path_factory.mktemp("mesh-data"), viewer=False) as base:
        yield base


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
