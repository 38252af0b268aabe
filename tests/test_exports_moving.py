"""Exports and lights of a show whose formations move during their holds (issue 21, item 5).

The moving holds are per-drone quintic pieces like any other motion, so the exports read
back through Skybrush's own readers (tests/skybrush_readers.py) must stay within the same
tolerances as for still holds; waypoint missions, which can only hold still, refuse them.
Position-reading light effects follow the moving points.
"""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

from app.exports import ExportError, export_show
from formations.sources import generate_shape
from sim import plan_show
from sim.light import show_colors
from tests.conftest import make_show
from tests.skybrush_readers import (
    LibskybrushPlayer,
    server_binary_trajectory,
    show_format_positions,
    studio_csv_import,
)


def _moving_show(**extra):
    """A star spinning a quarter turn about the vertical through its centre, then a ring drifting and growing."""
    star = generate_shape("star", 40, size_m=60.0, center_m=(0.0, 0.0, 45.0), plane="xz", min_spacing_m=3.0).points_m
    ring = generate_shape("circle", 40, size_m=50.0, center_m=(0.0, 10.0, 40.0), plane="xz",
                          min_spacing_m=3.0).points_m
    return make_show(
        [
            {"name": "star", "hold_s": 16.0, "points": star, "color": "#ffcc00",
             "motion": {"keys": [{"t_s": 0.0}, {"t_s": 16.0, "rotate_deg": [0.0, 0.0, 90.0]}]}},
            {"name": "ring", "hold_s": 24.0, "points": ring, "color": "#2040ff",
             "motion": {"keys": [{"t_s": 1.0}, {"t_s": 12.0, "translate_m": [8.0, 0.0, 3.0], "scale": 1.1,
                                                 "easing": "linear"},
                                 {"t_s": 23.0, "translate_m": [4.0, 5.0, 2.0], "rotate_deg": [0.0, 0.0, 20.0]}]}},
        ],
        drones=40, rows=5, cols=8, spacing_m=4.5, **extra,
    )


@pytest.fixture(scope="module")
def moving():
    show = _moving_show()
    return show, plan_show(show)


def _times(plan, n: int = 3000) -> np.ndarray:
    rng = np.random.default_rng(2)
    holds = [s for s in plan.segments if s.kind == "hold"]
    dense = np.concatenate([np.linspace(s.start_s, s.end_s, n) for s in holds])
    return np.sort(np.r_[dense, rng.uniform(0, plan.duration_s, n)])


def test_the_plan_moves_during_the_holds(moving):
    _, plan = moving
    for seg in (s for s in plan.segments if s.kind == "hold"):
        start, end = plan.knot_positions_m[seg.index], plan.knot_positions_m[seg.index + 1]
        assert np.linalg.norm(end - start, axis=1).max() > 5.0


def test_skyc_of_a_moving_show_through_server_and_libskybrush_within_7_mm(moving):
    show, plan = moving
    with zipfile.ZipFile(io.BytesIO(export_show(show, "skyc", plan=plan).content)) as z:
        doc = json.loads(z.read("show.json"))
    t = _times(plan)
    ref = plan.evaluate(t).positions_m
    worst_player, worst_loader = 0.0, 0.0
    for i, d in enumerate(doc["swarm"]["drones"]):
        points = d["settings"]["trajectory"]["points"]
        player = LibskybrushPlayer(server_binary_trajectory(points))
        assert player.total_ms == round(plan.duration_s * 1000)
        worst_player = max(worst_player, float(np.linalg.norm(player.positions(t) - ref[:, i], axis=1).max()))
        got = show_format_positions(points, t)
        worst_loader = max(worst_loader, float(np.linalg.norm(got - ref[:, i], axis=1).max()))
    assert worst_player <= 0.007, f"{worst_player * 1000:.2f} mm"
    assert worst_loader <= 0.002, f"{worst_loader * 1000:.2f} mm"


def test_skybrush_csv_of_a_moving_show_imports_into_studio_within_5_mm(moving):
    show, plan = moving
    imported = studio_csv_import(export_show(show, "skybrush-csv", plan=plan).content, fps=25)
    worst = 0.0
    for i, (_, (times, pos, _)) in enumerate(imported.items()):
        ref = plan.evaluate(times, drones=np.array([i])).positions_m[:, 0]
        worst = max(worst, float(np.linalg.norm(pos - ref, axis=1).max()))
    assert worst <= 0.005, f"{worst * 1000:.2f} mm"


def test_waypoints_csv_of_a_moving_show_samples_the_motion(moving):
    show, plan = moving
    result = export_show(show, "waypoints-csv", plan=plan, fps=10.0)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        name = sorted(n for n in z.namelist() if n.endswith(".csv"))[0]
        rows = np.loadtxt(io.StringIO(z.read(name).decode()), delimiter=",", skiprows=1)
    drone = 0
    ref = plan.evaluate(rows[:, 0], drones=np.array([drone])).positions_m[:, 0]
    assert np.abs(rows[:, 1:4] - ref).max() <= 0.0005 + 1e-9


@pytest.mark.parametrize("fmt", ["qgc-plan", "qgc-wpl"])
def test_waypoint_missions_refuse_a_moving_hold_naming_the_field(moving, fmt):
    show, plan = moving
    with pytest.raises(ExportError, match=r"formations\[0\]\.motion"):
        export_show(show, fmt, plan=plan)


def test_a_box_light_follows_the_moving_points():
    """A box target on the right half: after the quarter turn the drones in it are others."""
    effect = {"start_s": 0.0, "end_s": 10_000.0, "effect": {"kind": "solid", "color": "#ff0000"},
              "target": {"kind": "box", "min_m": [5.0, -100.0, 0.0], "max_m": [100.0, 100.0, 200.0]}}
    show = _moving_show()
    show = show.model_validate({**show.model_dump(exclude_none=True), "lights": {"effects": [effect]}})
    plan = plan_show(show)
    seg = next(s for s in plan.segments if s.kind == "hold")
    t = np.array([seg.start_s + 0.01, seg.end_s - 0.01])
    pos = plan.evaluate(t).positions_m
    red = show_colors(show, plan, t)[..., 1] < 0.01  # (2, N): the star is #ffcc00, the effect #ff0000
    inside = pos[..., 0] >= 5.0
    np.testing.assert_array_equal(red, inside)
    assert (red[0] != red[1]).sum() >= 10


def test_crazyswarm_of_a_moving_show_through_crazyswarms_reader_cut_only_where_drones_rest(moving):
    """The moving holds' pieces need more than a Crazyflie holds: the parts are cut where every drone rests."""
    from tests.test_exports_crazyswarm import _drone_positions

    show, plan = moving
    result = export_show(show, "crazyswarm", plan=plan)
    t = np.linspace(0.0, plan.duration_s, 2001)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        manifest = json.loads(z.read("manifest.json"))
        cuts = [p["start_s"] for p in manifest["parts"][1:]]
        assert cuts, "the moving show needs parts"
        v = plan.evaluate(np.array(cuts)).velocities_mps
        assert np.abs(v).max() < 1e-9  # every drone at rest at every cut
        for i in (0, 17, 39):
            got, _ = _drone_positions(z, manifest["parts"], i, t)
            want = plan.evaluate(t, drones=np.array([i])).positions_m[:, 0]
            assert np.abs(got - want).max() <= 1e-6
