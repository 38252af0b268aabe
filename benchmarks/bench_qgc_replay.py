"""QGC missions flown as exported: ``pytest -m slow benchmarks/bench_qgc_replay.py``.

For the demo show and benchmark shows of 25, 64 and 100 drones: the pairs the export's replay
(the missions at the WPNAV parameters of ``wpnav.parm``) brings under ``min_distance_m`` where the
plan keeps them apart, and the closest airborne pair of the replay sampled every 0.02 s. Before the
missions followed each drone's own motion the demo lost 30 pairs, the closest 0.52 m apart.
"""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
from scipy.spatial import cKDTree

from app.exports import export_show
from app.exports._qgc import _wpnav_of_parameters, show_wpnav, wpnav_parameters
from app.exports._wpnav import plan_legs, time_mission
from formations._demo import load_demo_show
from sim import plan_show
from sim.bench._shows import benchmark_show

pytestmark = pytest.mark.slow


def _closest_airborne(mission, dt_s: float = 0.02) -> float:
    """Closest pair of drones off the ground (parked ones sit on the plan's own home grid)."""
    best = np.inf
    for t in np.arange(0.0, float(mission.arrive_s[-1].max()), dt_s):
        p = mission.positions(float(t))
        d, _ = cKDTree(p).query(p, k=2)
        air = p[:, 2] > 0.5
        if air.any():
            best = min(best, float(d[air, 1].min()))
    return best


@pytest.mark.parametrize("name", ["demo", "bench-25", "bench-64", "bench-100"])
def test_qgc_replay_closest_pair(name, record_result):
    show = load_demo_show() if name == "demo" else benchmark_show(int(name.split("-")[1]))
    plan = plan_show(show)
    result = export_show(show, "qgc-wpl", plan=plan, origin=(47.4, 8.5, 400.0))
    replay = json.loads(zipfile.ZipFile(io.BytesIO(result.content)).read("manifest.json"))["replay"]
    s = show.settings
    w = _wpnav_of_parameters(wpnav_parameters(show_wpnav(s)))
    mission = time_mission(plan_legs(plan, replay["path_tolerance_m"]), w.speed_mps, w.speed_up_mps,
                           w.speed_dn_mps, w)
    closest = _closest_airborne(mission)
    record_result({"drones": show.drones, "pairs_lost": replay["close_pair_count"],
                   "closest_airborne_pair_m": round(closest, 3), "min_distance_m": s.min_distance_m,
                   "worst_arrival_late_s": replay["worst_arrival_late_s"], "max_items": replay["max_items"]})
    assert replay["close_pair_count"] == 0 and closest >= s.min_distance_m
