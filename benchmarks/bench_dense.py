"""Dense shows (issue 15): formations drawn at exactly min_distance_m, planned safe and short.

``make bench`` or ``pytest -m slow benchmarks/bench_dense.py``; ``swarmshow bench plan --dense`` prints
the same table. Figures per show: violations of the exact check, unresolved conflicts, show length
against the bottleneck lower bound (:mod:`sim.bench._dense`), planning + check time (wall and CPU),
the reference k-d-tree check's CPU time on the same plan, and the peak resident memory.
"""

from __future__ import annotations

import pytest

from sim.bench._dense import DENSE_SIZES, bench_dense

pytestmark = pytest.mark.slow


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
