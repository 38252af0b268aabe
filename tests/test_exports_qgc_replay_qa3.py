"""QGC export of a show with long holds (QA pass): the replay's pair search samples only where something moves.

``close_pairs`` sampled the replay every 0.1 s over the whole show: two drones, three one-day holds took
2.6 M k-d-tree frames in a Python loop (``swarmshow export --format qgc-wpl`` ran for hours on the command
line; the app's 60-s budget cut it). Where neither the replayed missions nor the plan move, every frame is the
same as the last frame before it, so those frames are skipped; the result must equal the dense search.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from app.exports import _wpnav
from app.exports._core import ExportContext, ExportOptions
from app.exports._qgc import timed_mission
from formations import parse_show
from sim import plan_show
from sim.bench._dense import dense_show


def _dense_close_pairs(mission, plan, min_distance_m: float, dt: float):
    """The search over every frame of the grid (the previous implementation, kept as the reference)."""
    from scipy.spatial import cKDTree

    end = float(mission.arrive_s[-1].max())
    found: dict[tuple[int, int], tuple[float, float]] = {}
    for t in np.arange(float(mission.depart_s[0].min()), end + dt / 2, dt):
        pos = mission.positions(float(t))
        pairs = cKDTree(pos).query_pairs(min_distance_m, output_type="ndarray")
        if not len(pairs):
            continue
        ref = plan.evaluate(np.array([min(float(t), plan.duration_s)])).positions_m[0]
        for i, j in pairs:
            d = float(np.linalg.norm(pos[i] - pos[j]))
            if d < min_distance_m - 1e-6 and np.linalg.norm(ref[i] - ref[j]) >= min_distance_m - 1e-6:
                if (i, j) not in found or d < found[(i, j)][0]:
                    found[(i, j)] = (d, float(t))
    return found


def _mission(show):
    plan = plan_show(show)
    ctx = ExportContext(show, ExportOptions(origin=(47.0, 8.0, 400.0)), fmt="qgc-wpl", plan=plan)
    return timed_mission(ctx).mission, plan


def test_skipping_still_frames_finds_what_the_dense_search_finds():
    # A layered show whose replay loses pairs (curved paths flown with stops), with a long hold in it.
    doc = json.loads(dense_show(16, formations=2).model_dump_json(exclude_none=True))
    doc["formations"][0]["hold_s"] = 600.0
    show = parse_show(json.dumps(doc))
    mission, plan = _mission(show)
    got, dt = _wpnav.close_pairs(mission, plan, show.settings.min_distance_m)
    want = _dense_close_pairs(mission, plan, show.settings.min_distance_m, dt)
    assert {(i, j): (round(d, 9), t) for i, j, d, t in got} == {
        k: (round(v[0], 9), pytest.approx(v[1])) for k, v in want.items()}


def test_long_holds_cost_frames_only_where_something_moves(monkeypatch):
    doc = {"format": "swarmshow/1", "name": "days", "drones": 2, "home": {"points": [[0, 0, 0], [3, 0, 0]]},
           "formations": [{"name": f"f{k}", "hold_s": 86400.0, "points": [[0, 0, 20 + 10 * (k % 2)],
                                                                          [3, 0, 20 + 10 * (k % 2)]]}
                          for k in range(3)]}
    show = parse_show(json.dumps(doc))
    frames = [0]
    real = _wpnav.Mission.positions

    def counted(self, t_s):
        frames[0] += 1
        if frames[0] > 50_000:
            raise AssertionError("the replay search samples the holds")
        return real(self, t_s)

    monkeypatch.setattr(_wpnav.Mission, "positions", counted)
    mission, plan = _mission(show)
    moving_s = plan.duration_s - sum(s.duration_s for s in plan.segments if s.kind == "hold")
    # Every 0.1 s while something moves (plus the frames at the edges of the holds), for each tolerance tried.
    assert frames[0] <= 4 * (moving_s / 0.1 + 50)
