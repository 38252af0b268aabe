"""Monte-Carlo benchmark (issue 20): a 1,000-drone, 10-minute show flown 20 times, target <= 15 minutes.

``make bench`` or ``pytest -m slow benchmarks/bench_montecarlo.py``. The show is the benchmark
show of ``sim.bench`` (five formations) with its holds stretched to 10 minutes. On a shared
machine the full 20 runs are not measured by default: ``MC_BENCH_RUNS`` runs (default 2) are
flown with ``sim.flight.monte_carlo`` and the 20-run time is extrapolated from the time per run
(the runs are independent and identical in cost: the extrapolation is linear), and the figures
say so (``extrapolated``) with the load average at the time. ``MC_BENCH_RUNS=20`` measures all;
``MC_BENCH_DRONES=250`` flies a smaller fleet on the same 10-minute show and scales the time
linearly to 1,000 drones (the kernel and the per-frame closest pair are both linear in drones).

Figures, all from one run of the benchmark: seconds per Monte-Carlo run, the same run flown
alone by ``fly_show`` (the flight without the Monte-Carlo reduction), their ratio (the
reduction's overhead), drone-steps per second, and the 20-run estimate against the target.
"""

from __future__ import annotations

import os
import time

import pytest

pytestmark = pytest.mark.slow

#: Target of issue 20 on the 2-core reference machine (s).
TARGET_S = 15 * 60.0
DRONES = 1000
SHOW_S = 600.0
TARGET_RUNS = 20


def _ten_minute_show(n: int, seconds: float):
    """The benchmark show with every hold lengthened so that the plan lasts ``seconds``."""
    from sim import plan_show
    from sim.bench._shows import benchmark_show

    show = benchmark_show(n)
    plan = plan_show(show)
    extra = max(seconds - plan.duration_s, 0.0) / len(show.formations)
    stretched = show.model_copy(update={"formations": [
        f.model_copy(update={"hold_s": f.hold_s + extra}) for f in show.formations]})
    return plan_show(stretched)


def test_bench_montecarlo_1000_drones_10_minutes(record_result) -> None:
    from sim.flight import FlightOptions, fly_show, monte_carlo, options_for_preset

    runs = int(os.environ.get("MC_BENCH_RUNS", "2"))
    drones = int(os.environ.get("MC_BENCH_DRONES", str(DRONES)))
    plan = _ten_minute_show(drones, SHOW_S)
    options = options_for_preset("gusty-rtk", FlightOptions())
    load_before = os.getloadavg()[0]

    start = time.perf_counter()
    mc = monte_carlo(plan, options, runs=runs, seed0=0)
    mc_s = time.perf_counter() - start
    # The first run's flight alone, in the same benchmark run: what the reduction adds.
    start = time.perf_counter()
    single = fly_show(plan, options.with_(seed=0, flown_distance=False))
    single_s = time.perf_counter() - start
    load_after = os.getloadavg()[0]

    per_run_s = mc_s / runs
    # Flight and reduction are linear in the drones (kernel per drone, O(N) closest pair per frame).
    scale = DRONES / plan.drone_count
    estimate_s = per_run_s * TARGET_RUNS * scale
    steps = (round(plan.duration_s / 1e-3) + 1) * plan.drone_count
    j = mc.to_json()
    record_result({
        "drones": plan.drone_count,
        "show_s": plan.duration_s,
        "runs_measured": runs,
        "extrapolated": runs < TARGET_RUNS or plan.drone_count != DRONES,
        "drones_scale_to_1000": scale,
        "monte_carlo_s": mc_s,
        "per_run_s": per_run_s,
        "single_flight_s": single_s,
        "per_run_over_single_flight": per_run_s / single_s,
        "drone_steps_per_s": steps * runs / mc_s,
        "estimate_20_runs_s": estimate_s,
        "target_s": TARGET_S,
        "estimate_over_target": estimate_s / TARGET_S,
        "load_average_1min": [load_before, load_after],
        "cpus": os.cpu_count(),
        "flown_min_m": j["show_min"]["flown_min_m"]["quantiles"]["0"],
        "diverged": j["diverged_count"],
    })
    assert j["diverged_count"] == 0 and not single.diverged
    assert [r["seed"] for r in j["run_list"]] == list(range(runs))
    # The reduction (closest pair per frame, speeds, folds) costs little next to the flight.
    assert per_run_s / single_s < 1.5
