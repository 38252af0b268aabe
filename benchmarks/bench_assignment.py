"""Assignment and verification at scale (issue 9): ``make bench`` or ``pytest -m slow benchmarks/bench_assignment.py``.

Ours is ``sim.assign`` (the certified sparse auction above 1,000 drones), each
run in a fresh subprocess for its own peak memory; the baseline is scipy's
dense ``linear_sum_assignment`` on the full ``cdist`` matrix, measured at 5,000
drones only (above that it needs 800 MB+ and minutes).
"""

from __future__ import annotations

import os
import time

import pytest

from sim.bench._assignment import bench_assignment
from sim.bench._shows import bench_show

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("n", [5000, 10000, 16000])
@pytest.mark.parametrize("kind", ["grid_to_sphere", "random"])
def test_bench_assignment(kind: str, n: int, record_result) -> None:
    """Certified exact assignment: time, peak memory, certificate; dense scipy ratio at 5k."""
    fig = bench_assignment(kind, n, dense_baseline=n == 5000)
    record_result(fig)
    assert fig["ours_certificate_ok"]
    assert fig["ours_relative_gap_bound"] <= 1e-9
    assert fig["ours_maxrss_mb"] <= 4096
    if n == 5000:
        assert fig["cost_equal"]
        if kind == "grid_to_sphere":
            assert fig["dense_over_ours"] >= 20
    if n == 16000:
        assert fig["ours_seconds"] <= 5.0


def test_bench_assignment_spare_goals_16k(record_result) -> None:
    """16,000 drones onto 16,129 goals (a landing onto the square home grid): M > N."""
    fig = bench_assignment("random_spare", 16000, dense_baseline=False)
    record_result(fig)
    assert fig["ours_certificate_ok"]
    assert fig["ours_seconds"] <= 5.0


#: Drones of the whole-show check (``BENCH_CHECK_DRONES=300`` runs the same assertions on a small show).
CHECK_DRONES = int(os.environ.get("BENCH_CHECK_DRONES", "10000"))
#: The exact check must beat a 10 Hz sampled check of the same plan, timed in the same run, by this factor
#: (README: 12.8-16.3x measured for 10,000 drones, 2 formations; an absolute 5 s bound failed under load).
MIN_SAMPLED_OVER_EXACT = 10.0


@pytest.mark.parametrize("formations", [2, 5])
def test_bench_check_10k_show(formations: int, record_result) -> None:
    """``check_plan`` on a 10,000-drone show (minimum-time law: 2 formations plan an 8.7-minute show, 5 longer),
    against a 10 Hz sampled check of the same plan in the same process (``sim.bench._shows.bench_show``, what
    ``swarmshow bench check`` reports): speed as a ratio, never absolute seconds (the CPU is shared)."""
    fig = bench_show(CHECK_DRONES, formations=formations)
    record_result(fig)
    assert fig["violations"] == 0
    # The sampled minimum only bounds the exact one from above (it misses the instants between samples).
    assert fig["sampled_10hz_min_distance_m"] >= fig["exact_min_distance_m"] - 1e-9
    if CHECK_DRONES == 10000:
        assert fig["show_duration_s"] >= 500  # 519 s for 2 formations (it was >= 600 under the quintic law)
        # The README's figure is for 2 formations; 5 (unmeasured as a ratio yet) must at least beat sampling.
        assert fig["sampled_over_exact_check"] >= (MIN_SAMPLED_OVER_EXACT if formations == 2 else 1.0), fig
    # A small show (BENCH_CHECK_DRONES) checks the code above runs; a 10 Hz sampled check of 400 drones costs
    # about what the exact one does (1.02x measured), so no speed ratio is asserted there.


@pytest.mark.parametrize("n", [1000, 5000])
def test_bench_warm_started_reassignment(n: int, record_result) -> None:
    """The re-assignments between spread formations of the dense show (sim.bench._dense), warm-started from
    the transition's assignment vs solved cold, same inputs, same process: CPU ratio and equal cost."""
    import numpy as np

    from sim.bench._dense import dense_show
    from sim.plan import assign
    from sim.plan._schedule import EXPANSIONS, spread

    show = dense_show(n, formations=6)
    sets = [np.asarray(show.home_positions_m) + [0.0, 0.0, show.settings.takeoff_altitude_m]]
    sets += [np.asarray(f.points_m) for f in show.formations]
    cold = warm = 0.0
    equal = True
    for a, g in zip(sets[:-1], sets[1:], strict=True):
        base = assign(a, g, method="sparse")
        for k in EXPANSIONS:
            sa, sg = spread(a, k, 3.0, 1e4), spread(g, k, 3.0, 1e4)
            if sa is None or sg is None:
                continue
            c0 = time.process_time()
            r_cold = assign(sa, sg, method="sparse")
            c1 = time.process_time()
            r_warm = assign(sa, sg, method="sparse", warm=base)
            c2 = time.process_time()
            cold, warm = cold + c1 - c0, warm + c2 - c1
            equal &= abs(r_cold.cost_m2 - r_warm.cost_m2) <= 1e-9 * r_cold.cost_m2
    record_result({"drones": n, "reassign_cold_cpu_s": cold, "reassign_warm_cpu_s": warm,
                   "warm_over_cold_cpu": warm / cold, "cost_equal": bool(equal)})
    assert equal
