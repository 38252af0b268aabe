"""Planning and verification benchmarks (issue 3): ``make bench`` or ``pytest -m slow benchmarks/bench_plan.py``."""

from __future__ import annotations

import pytest

from sim.bench._shows import bench_show, bench_transition

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("n", [1000, 2000, 5000])
def test_bench_transition_grid_to_sphere(n: int, record_result) -> None:
    """One ground-grid -> sphere transition: ours vs scipy's dense LSA on the same input."""
    fig = bench_transition(n)
    record_result(fig)
    assert fig["cost_equal"]
    assert fig["min_distance_m"] >= fig["capt_guarantee_m"] - 1e-9
    if n == 2000:
        assert fig["plan_and_verify_s"] <= 2.0


def test_bench_whole_show_1000_drones_5_formations(record_result) -> None:
    """A 1000-drone, 5-formation show: exact check vs a 10 Hz sampled check."""
    fig = bench_show(1000, formations=5)
    record_result(fig)
    assert fig["violations"] == 0
    assert fig["check_s"] <= 1.0
    # The sampled minimum can only be >= the exact one (sampling misses the true minimum).
    assert fig["sampled_10hz_min_distance_m"] >= fig["exact_min_distance_m"] - 1e-9
