"""Dense shows (issue 15): formations drawn at exactly min_distance_m, planned safe and short.

``make bench`` or ``pytest -m slow benchmarks/bench_dense.py``; ``swarmshow bench plan --dense`` prints
the same table. Figures per show: violations of the exact check, unresolved conflicts, show length
against the bottleneck lower bound (:mod:`sim.bench._dense`), planning + check time (wall and CPU),
the reference k-d-tree check's CPU time on the same plan, the peak resident memory and what loading the
compiled kernels cost; and, at 1,000 drones, fresh processes with a cold and a warm numba cache.
"""

from __future__ import annotations

import pytest

from sim.bench._dense import DENSE_SIZES, bench_dense, cold_and_warm

pytestmark = pytest.mark.slow


@pytest.mark.timeout(3600)  # 5,000 drones on a shared, loaded 2-core machine outlast the 600 s default
@pytest.mark.parametrize("n", DENSE_SIZES)
def test_bench_dense_show(n: int, record_result) -> None:
    fig = bench_dense(n, formations=6)
    record_result(fig)
    assert fig["unresolved"] == 0
    assert fig["violations"] == 0
    if "sampled_min_distance_m" in fig:
        assert fig["sampled_min_distance_m"] >= 3.0 * (1 - 1e-9)
    assert fig["ratio_to_bound"] <= 1.35
    if n == 5000:
        assert fig["peak_rss_mb"] <= 2048


@pytest.mark.timeout(3600)
def test_bench_dense_cold_and_warm_processes(record_result) -> None:
    """1,000 drones, plan + check in fresh processes: first with an empty numba cache (compiling every
    kernel, once per install), then loading them from the cache that run filled (every later process)."""
    fig = cold_and_warm(1000, formations=6)
    record_result(fig)
    assert fig["same_plan"] is True
    assert fig["cold"]["violations"] == fig["warm"]["violations"] == 0
    warm, cold = fig["warm"], fig["cold"]
    assert warm["plan_cpu_s"] + warm["check_cpu_s"] < cold["plan_cpu_s"] + cold["check_cpu_s"]
