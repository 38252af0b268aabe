"""Moving-hold benchmarks (issue 21, item 5): ``pytest -m slow benchmarks/bench_motion.py``.

A 1,000-drone show of two spheres; the same show with each sphere turning (a quarter turn about
the vertical, then a half turn with a rise and a scale through a linear key) is planned and
checked exactly. Figures: plan and check time of the moving show over the still one (ratios
in one run), pieces per drone, and the largest fit error against the exact transform (dense
sampling of every drone over each hold).
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from formations._motion import apply, pivot_of, pose
from sim.plan import FIT_TOLERANCE_M, plan_show
from sim.verify import check_plan
from tests.conftest import fibonacci_sphere, make_show

pytestmark = pytest.mark.slow

DRONES = 1000
MOTIONS = [
    {"keys": [{"t_s": 0.0}, {"t_s": 30.0, "rotate_deg": [0.0, 0.0, 90.0]}]},
    {"keys": [{"t_s": 0.0}, {"t_s": 20.0, "rotate_deg": [0.0, 0.0, 90.0], "translate_m": [0.0, 0.0, 5.0],
                             "scale": 1.1, "easing": "linear"},
              {"t_s": 40.0, "rotate_deg": [0.0, 0.0, 180.0], "translate_m": [0.0, 0.0, 8.0]}]},
]


def _show(moving: bool):
    spheres = [fibonacci_sphere(DRONES, 60.0, center=(0.0, 0.0, 80.0)),
               fibonacci_sphere(DRONES, 66.0, center=(10.0, 20.0, 85.0))]
    fs = []
    for k, pts in enumerate(spheres):
        f = {"name": f"sphere{k}", "hold_s": 45.0, "points": pts, "color": "#ffffff"}
        if moving:
            f["motion"] = MOTIONS[k]
        fs.append(f)
    return make_show(fs, drones=DRONES, rows=25, cols=40, spacing_m=4.0, max_speed_z_mps=3.0, max_altitude_m=200.0)


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def test_moving_holds_plan_and_check(record_result):
    still, moving = _show(False), _show(True)
    check_plan(plan_show(still))  # warm up (compiled kernels, caches) before anything is timed
    plan_still, t_plan_still = _timed(lambda: plan_show(still))
    plan_moving, t_plan_moving = _timed(lambda: plan_show(moving))
    report_still, t_check_still = _timed(lambda: check_plan(plan_still))
    report_moving, t_check_moving = _timed(lambda: check_plan(plan_moving))
    assert report_still.ok and report_moving.ok, [v.message for v in report_moving.violations[:5]]
    worst = 0.0
    holds = [s for s in plan_moving.segments if s.kind == "hold"]
    for k, seg in enumerate(holds):
        f = moving.formations[k]
        p = f.points_m[plan_moving.transitions[k].goal_index]
        t = np.linspace(seg.start_s, seg.end_s, 1501)
        want = apply(pose(f.motion, t - seg.start_s), pivot_of(f.motion, f.points_m), p)[0]
        got = plan_moving.motion.evaluate(t, derivatives=0).positions_m
        worst = max(worst, float(np.linalg.norm(got - want, axis=-1).max()))
    assert worst < FIT_TOLERANCE_M
    record_result({
        "drones": DRONES,
        "pieces_per_drone_still": plan_still.motion.piece_count,
        "pieces_per_drone_moving": plan_moving.motion.piece_count,
        "plan_time_ratio_moving_over_still": round(t_plan_moving / t_plan_still, 3),
        "check_time_ratio_moving_over_still": round(t_check_moving / t_check_still, 3),
        "max_fit_error_mm": round(worst * 1000, 4),
        "fit_tolerance_mm": FIT_TOLERANCE_M * 1000,
        "min_distance_moving_m": round(report_moving.min_distance_m, 3),
    })
