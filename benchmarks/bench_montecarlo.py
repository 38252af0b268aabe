"""Monte-Carlo benchmark (issue 20): a 1,000-drone, 10-minute show flown 20 times, target <= 15 minutes.

``make bench`` or ``pytest -m slow benchmarks/bench_montecarlo.py``. The show is the benchmark
show of ``sim.bench`` (five formations) with its holds stretched to ``MC_BENCH_SHOW_S`` seconds
(default 600). On a shared machine the full 20 runs are not flown by default: ``MC_BENCH_RUNS``
runs (default 2) are flown with ``sim.flight.monte_carlo`` and the 20-run time is an
**extrapolation**, stated as such in the figures (``extrapolated``), with the load average at
the time. ``MC_BENCH_RUNS=20`` (and the default drones and length) measures the target case.

The extrapolation (all terms measured in this benchmark run, each run's timings from
``RunStats``)::

    T_20 = 20 · S_target / R  +  (P + 20 · O) · (N_target · F_target) / (N · F)

* ``S_target = 1,000 · (600 s / 1 ms + 1)`` drone-steps of one target run;
* ``R`` = drone-steps per second of the engine loop (the kernel and its per-chunk GNSS and
  wind tables: ``flight_wall_time_s`` of the runs), measured on ``N`` drones;
* ``O`` = the rest of a run (setup, closest pair of every frame, speeds, folds: ``wall_time_s -
  flight_wall_time_s``), linear in drones times frames ``F`` (the closest pair is O(N) per frame);
* ``P`` = the per-show work done once (the plan's own minimum at every frame, in ``monte_carlo``:
  the wall time of the whole call less the runs' own), also linear in drones times frames.

The plan itself is made once before ``monte_carlo`` (``plan_s``, reported, not in T_20: the
designer has it already). Kernel speed-ups (a SIMD kernel) change ``R`` only; the figures
give the split ``per_run_engine_fraction`` so both parts can be followed.
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


def _stretched_show(n: int, seconds: float):
    """The benchmark show with every hold lengthened so that the plan lasts ``seconds``."""
    from sim import plan_show
    from sim.bench._shows import benchmark_show

    show = benchmark_show(n)
    plan = plan_show(show)
    extra = max(seconds - plan.duration_s, 0.0) / len(show.formations)
    stretched = show.model_copy(update={"formations": [
        f.model_copy(update={"hold_s": f.hold_s + extra}) for f in show.formations]})
    return plan_show(stretched)


# The full 20 runs on a loaded shared machine outlast pytest's 600 s default (a run at load ~8 was cut at 600 s).
@pytest.mark.timeout(3600)
def test_bench_montecarlo_1000_drones_10_minutes(record_result) -> None:
    from sim.flight import FlightOptions, monte_carlo, options_for_preset
    from sim.flight.engines import warm_up

    runs = int(os.environ.get("MC_BENCH_RUNS", "2"))
    drones = int(os.environ.get("MC_BENCH_DRONES", str(DRONES)))
    show_s = float(os.environ.get("MC_BENCH_SHOW_S", str(SHOW_S)))
    start = time.perf_counter()
    plan = _stretched_show(drones, show_s)
    plan_s = time.perf_counter() - start
    options = options_for_preset("gusty-rtk", FlightOptions())
    warm_up()  # compile time is not a run's
    load_before = os.getloadavg()[0]

    start = time.perf_counter()
    mc = monte_carlo(plan, options, runs=runs, seed0=0)
    mc_s = time.perf_counter() - start
    load_after = os.getloadavg()[0]

    j = mc.to_json()
    rows = j["run_list"]
    engine_s = sum(r["flight_wall_time_s"] for r in rows)
    runs_s = sum(r["wall_time_s"] for r in rows)
    once_s = max(mc_s - runs_s, 0.0)
    steps = round(plan.duration_s / 1e-3) + 1
    every = max(round(1.0 / (options.output_hz * 1e-3)), 1)
    frames = (steps - 1) // every + 1
    drone_steps = plan.drone_count * steps
    rate = drone_steps * runs / engine_s
    rest_per_run = (runs_s - engine_s) / runs
    target_steps = DRONES * (round(SHOW_S / 1e-3) + 1)
    target_frames = round(SHOW_S / 1e-3) // every + 1
    scale_nf = (DRONES * target_frames) / (plan.drone_count * frames)
    estimate_s = TARGET_RUNS * target_steps / rate + (once_s + TARGET_RUNS * rest_per_run) * scale_nf
    measured_target = runs >= TARGET_RUNS and plan.drone_count == DRONES and abs(plan.duration_s - SHOW_S) < 1.0
    record_result({
        "drones": plan.drone_count,
        "show_s": plan.duration_s,
        "plan_s": plan_s,
        "runs_measured": runs,
        "extrapolated": not measured_target,
        "formula": "T_20 = 20 * S_target / R + (P + 20 * O) * (N_target*F_target) / (N*F)",
        "drones_frames_scale": scale_nf,
        "monte_carlo_s": mc_s,
        "per_run_s": runs_s / runs,
        "per_run_engine_s": engine_s / runs,
        "per_run_engine_fraction": engine_s / runs_s,
        "R_engine_drone_steps_per_s": rate,
        "O_rest_per_run_s": rest_per_run,
        "P_once_s": once_s,
        "S_target_drone_steps": target_steps,
        "estimate_20_runs_s": mc_s if measured_target else estimate_s,
        "target_s": TARGET_S,
        "estimate_over_target": (mc_s if measured_target else estimate_s) / TARGET_S,
        "load_average_1min": [load_before, load_after],
        "cpus": os.cpu_count(),
        "flown_min_m": j["show_min"]["flown_min_m"]["quantiles"]["0"],
        "diverged": j["diverged_count"],
        "diverged_by_reason": j.get("diverged_by_reason", {}),
    })
    # Not asserted zero: at 1,000 drones the benchmark show's spheres reach 182 m, where gusty-rtk's wind
    # (7.7 m/s at 10 m, power law 1/7: 11.6 m/s mean, sigma 1.3 m/s) exceeds what a 0.5 kg drone with a 0.6 rad
    # tilt limit can hold (m*g*tan(0.6) = 3.3 N of drag, i.e. 13.5 m/s of airspeed at c = 0.018 kg/m): drones
    # are blown off their track during the descents, a real finding the report names (about 19 % of
    # drones per run; none at 250 drones, whose formations stay below 110 m). The engines name that
    # reason "overpowered" (held at the tilt limit, pushing back, attitude following), not "runaway"
    # (unstable control or a tumble); "diverged_by_reason" records the split.
    assert 0 <= j["diverged_count"] <= plan.drone_count * runs
    assert [r["seed"] for r in rows] == list(range(runs))
    # The reduction (closest pair per frame, speeds, folds) costs little next to the flight.
    assert engine_s / runs_s > 0.8
