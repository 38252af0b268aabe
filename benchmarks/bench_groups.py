"""Subset formations (issue 21 item 3): ``make bench`` or ``pytest -m slow benchmarks/bench_groups.py``.

* The count choice: CAPT with free "stay" goals (exact, dense) against its greedy fallback (the n drones
  nearest the formation, assigned exactly among themselves): travel cost and time ratios on one input.
* A 400-drone show whose middle formation is flown by 200 drones (others hold, park or land): planned and
  checked exactly; planning time against the same show with every drone flying a 400-point formation
  there (ratio, same run).
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from formations import parse_show
from sim import check_plan, plan_show
from sim.plan import _subset

pytestmark = pytest.mark.slow


def _sphere(n: int, r: float, c: tuple[float, float, float]) -> np.ndarray:
    k = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * k / n)
    th = np.pi * (1 + 5**0.5) * k
    return np.column_stack([r * np.cos(th) * np.sin(phi), r * np.sin(th) * np.sin(phi), r * np.cos(phi)]) + c


def test_bench_count_choice_exact_vs_greedy(record_result) -> None:
    rng = np.random.default_rng(0)
    starts = _sphere(1500, 40.0, (0, 0, 60)) + rng.normal(0, 0.3, (1500, 3))
    points = _sphere(600, 25.0, (20, -10, 55))
    t = time.perf_counter()
    d_exact, p_exact = _subset.choose_drones(starts, points, 600)
    exact_s = time.perf_counter() - t
    cells = _subset.DENSE_SELECT_MAX_CELLS
    try:
        _subset.DENSE_SELECT_MAX_CELLS = 0  # force the greedy fallback on the same input
        t = time.perf_counter()
        d_greedy, p_greedy = _subset.choose_drones(starts, points, 600)
        greedy_s = time.perf_counter() - t
    finally:
        _subset.DENSE_SELECT_MAX_CELLS = cells
    exact = float(((starts[d_exact] - points[p_exact]) ** 2).sum())
    greedy = float(((starts[d_greedy] - points[p_greedy]) ** 2).sum())
    record_result({"drones": 1500, "points": 600, "count": 600, "exact_cost_m2": exact, "greedy_cost_m2": greedy,
                   "greedy_over_exact_cost": greedy / exact, "exact_over_greedy_time": exact_s / greedy_s})
    assert exact <= greedy * (1 + 1e-9)


@pytest.mark.parametrize("others", ["hold", "park", "land"])
def test_bench_subset_show_400(others: str, record_result) -> None:
    n = 400
    first = _sphere(n, 30.0, (0, 0, 60)).round(6).tolist()
    half = _sphere(200, 18.0, (0, -30, 50)).round(6).tolist()
    full = _sphere(n, 30.0, (0, -30, 60)).round(6).tolist()

    def doc(middle: dict) -> dict:
        return {"format": "swarmshow/1", "name": "subset bench", "drones": n,
                "home": {"grid": {"rows": 20, "cols": 20, "spacing_m": 4.0}},
                "formations": [{"name": "a", "hold_s": 2.0, "points": first}, middle,
                               {"name": "c", "hold_s": 2.0, "points": first}]}

    subset = parse_show(doc({"name": "b", "hold_s": 2.0, "points": half, "drones": {"count": 200},
                             "others": others}))
    everyone = parse_show(doc({"name": "b", "hold_s": 2.0, "points": full}))
    t = time.perf_counter()
    plan = plan_show(subset)
    subset_s = time.perf_counter() - t
    t = time.perf_counter()
    plan_show(everyone)
    everyone_s = time.perf_counter() - t
    report = check_plan(plan)
    record_result({"drones": n, "flying": 200, "others": others, "ok": report.ok,
                   "min_distance_m": report.min_distance_m, "duration_s": plan.duration_s,
                   "resolutions": [t.resolution for t in plan.transitions],
                   "subset_over_all_plan_time": subset_s / everyone_s})
    assert report.ok, report.violations[:3]
