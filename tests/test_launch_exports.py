"""Every export of a boxed show (drones taking off and landing in waves, at different times) stays within
its tolerance of the plan: the export tests of tests/test_exports_*.py run again here on a boxed plan,
plus Skybrush's own readers (tests/skybrush_readers.py)."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

from app.exports import export_show
from sim import plan_show
from tests.skybrush_readers import LibskybrushPlayer, server_binary_trajectory, show_format_positions

# The export tests themselves, collected again in this module with its `show` and `plan` fixtures.
from tests.test_exports_qgc import (
    test_plan_json_structure,  # noqa: F401
    test_wpl_loads_in_pymavlink_with_the_right_count_and_coordinates,  # noqa: F401
    test_wpl_replay_keeps_min_distance_or_names_the_pairs,  # noqa: F401
)
from tests.test_exports_sampled import (
    test_skybrush_csv_resampled_at_high_fps_matches_the_plan_within_1mm,  # noqa: F401
    test_skybrush_csv_rows_are_the_plan,  # noqa: F401
    test_skybrush_studio_importer_accepts_the_archive,  # noqa: F401
    test_waypoints_csv_planned,  # noqa: F401
)
from tests.test_exports_trajectories import (
    test_crazyswarm_pieces_are_the_plan,  # noqa: F401
    test_skyc_lights_replay_the_plan_colours,  # noqa: F401
    test_skyc_passes_the_rules_and_evaluates_to_the_plan,  # noqa: F401
)
from tests.test_launch import boxes_show


@pytest.fixture(scope="module")
def show():
    return boxes_show(drones=16, rows=1, cols=2)


@pytest.fixture(scope="module")
def plan(show):
    p = plan_show(show)
    assert p.launch is not None and p.launch.takeoff is not None and p.launch.takeoff.count == 8
    return p


def test_qgc_missions_take_off_and_land_in_waves_and_keep_min_distance(show, plan, tmp_path):
    """Each wave's missions wait (NAV_DELAY before NAV_TAKEOFF) until the plan's takeoff of that wave;
    flown by the independent replay, no pair comes closer than the plan keeps it (brute force)."""
    from tests.test_exports_qgc_safety import check_show

    out = check_show(show, tmp_path, plan=plan)
    first = np.array([items[1][1] if items[1][0] == 93 else 0.0 for items in out["items"]])
    # the plan's own takeoff departures (the first time each drone moves)
    t = np.arange(0.0, plan.segments[0].end_s, 0.01)
    z = plan.evaluate(t).positions_m[..., 2]
    leaves = t[np.argmax(z > z[0] + 1e-6, axis=0) - 1]
    assert len(np.unique(np.round(leaves, 1))) > 1  # waves
    assert np.abs(first - leaves).max() <= 0.02


def test_skyc_through_skybrush_readers_keeps_the_waves(show, plan):
    with zipfile.ZipFile(io.BytesIO(export_show(show, "skyc", plan=plan).content)) as z:
        doc = json.loads(z.read("show.json"))
    rng = np.random.default_rng(2)
    t = np.sort(np.r_[np.linspace(0.0, plan.duration_s, 4000), rng.uniform(0, plan.duration_s, 2000)])
    ref = plan.evaluate(t).positions_m
    worst_drone = worst_loader = 0.0
    for i, d in enumerate(doc["swarm"]["drones"]):
        points = d["settings"]["trajectory"]["points"]
        player = LibskybrushPlayer(server_binary_trajectory(points))
        worst_drone = max(worst_drone, float(np.linalg.norm(player.positions(t) - ref[:, i], axis=1).max()))
        worst_loader = max(worst_loader, float(np.linalg.norm(show_format_positions(points, t) - ref[:, i],
                                                              axis=1).max()))
    assert worst_drone <= 0.007 and worst_loader <= 0.002
