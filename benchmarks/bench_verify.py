"""The exact check of per-drone piecewise polynomials against the shared-β closed form (issue 15).

``pytest -m slow benchmarks/bench_verify.py -s``. Same quintic, unstaggered plan for both:
ours is ``check_plan`` (separation by Bernstein branch and bound over every piece, plus
exact speed / acceleration / altitude peaks); the baseline is CAPT's closed form over the
shared β (``segment_close_pairs``, separation only, valid only while drones share one
time law). Figures are ratios measured in one run. Targets: 1,000 drones x 6 formations
well under 2 s, 5,000 drones a few tens of seconds.
"""

from __future__ import annotations

import math
import os
import time

import numpy as np
import pytest

from sim import check_plan, plan_show
from sim.bench._shows import benchmark_show
from sim.verify import segment_close_pairs

pytestmark = pytest.mark.slow


def _closed_form_separation(plan) -> float:
    """Minimum distance over the show by the shared-β closed form, with the check's search radii."""
    P = plan.knot_positions_m
    best = math.inf
    for k, seg in enumerate(plan.segments):
        if seg.kind == "hold":
            continue
        pairs = segment_close_pairs(P[k], P[k + 1], 2 * plan.settings.min_distance_m)
        if len(pairs.dist):
            best = min(best, float(pairs.dist.min()))
    return best


@pytest.mark.parametrize("n", [1000, 5000])
def test_exact_check_speed(n: int, record_result) -> None:
    check_plan(plan_show(benchmark_show(50, formations=2)))  # compile the numba kernels first
    plan = plan_show(benchmark_show(n, formations=6))
    t0 = time.perf_counter()
    baseline_min = _closed_form_separation(plan)
    baseline_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    report = check_plan(plan)
    check_s = time.perf_counter() - t0
    fig = {
        "drones": n,
        "formations": 6,
        "check_s": check_s,
        "closed_form_separation_s": baseline_s,
        "check_over_closed_form": check_s / baseline_s,
        "min_distance_m": report.min_distance_m,
        "closed_form_min_distance_m": baseline_min,
        "load_average_1min": os.getloadavg()[0],
    }
    record_result(fig)
    assert report.violations_total == 0
    np.testing.assert_allclose(report.min_distance_m, baseline_min, atol=1e-8)
