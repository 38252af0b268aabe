"""Launch boxes (issue 21 item 4): takeoff / landing in waves against the same show on a sparse home grid.

Figures are ratios measured in one run (boxed over grid): the show length, the takeoff window, plan and
exact-check time; plus the wave count against its lower bound (drones per box: a box is a clique).
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from formations import parse_show
from sim import check_plan, plan_show
from tests.conftest import fibonacci_sphere

pytestmark = pytest.mark.slow


def _show(n: int, home: dict) -> object:
    return parse_show({
        "format": "swarmshow/1", "name": "launch bench", "drones": n, "home": home,
        "formations": [
            {"name": "ball", "hold_s": 3.0, "points": np.round(fibonacci_sphere(n, max(15.0, 1.1 * np.sqrt(n)),
                                                                               center=(0.0, 0.0, 60.0)), 6).tolist()},
            {"name": "big ball", "hold_s": 3.0, "points": np.round(fibonacci_sphere(
                n, 1.3 * max(15.0, 1.1 * np.sqrt(n)), center=(5.0, 5.0, 70.0)), 6).tolist()},
        ],
    })


def _timed(show):
    t0 = time.perf_counter()
    plan = plan_show(show)
    t1 = time.perf_counter()
    report = check_plan(plan)
    return plan, report, t1 - t0, time.perf_counter() - t1


@pytest.mark.parametrize("boxes", [6, 60])
def test_bench_launch_boxes_against_a_grid(boxes, record_result):
    per_box = 8
    n = boxes * per_box
    cols = int(np.ceil(np.sqrt(boxes)))
    boxed = _show(n, {"boxes": {"per_box": per_box, "cols": 4, "spacing_m": 0.8,
                                "grid": {"rows": int(np.ceil(boxes / cols)), "cols": cols, "spacing_m": 6.0}}})
    gcols = int(np.ceil(np.sqrt(n)))
    grid = _show(n, {"grid": {"rows": int(np.ceil(n / gcols)), "cols": gcols, "spacing_m": 3.0}})
    _timed(grid)  # warm the numba caches
    pg, rg, plan_g, check_g = _timed(grid)
    pb, rb, plan_b, check_b = _timed(boxed)
    assert rb.violations_total == 0 and rg.violations_total == 0
    waves = pb.launch.takeoff.count
    record_result({
        "drones": n, "boxes": boxes, "per_box": per_box, "box_spacing_m": 0.8,
        "takeoff_waves": waves, "waves_lower_bound": per_box,
        "landing_waves": pb.launch.landing.count,
        "violations": rb.violations_total,
        "takeoff_window_ratio_boxed_over_grid": pb.segments[0].duration_s / pg.segments[0].duration_s,
        "show_length_ratio_boxed_over_grid": pb.duration_s / pg.duration_s,
        "plan_time_ratio_boxed_over_grid": plan_b / plan_g,
        "check_time_ratio_boxed_over_grid": check_b / check_g,
    })
