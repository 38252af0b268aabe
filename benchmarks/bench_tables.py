"""The error models' per-chunk tables on one thread and on the table threads (issue 20 item 6).

``pytest -m slow benchmarks/bench_tables.py``. 4,000 drones on circles with "gusty-rtk" (the
setup of ``bench_sim.test_bench_kernel_against_numpy_with_error_models``): the GNSS and wind
tables of a 1,001-step chunk (one second), and whole 1-s ``simulate`` runs, each with the
tables on one thread and on :func:`sim.flight._threads.table_threads` threads, alternating
in one process (the machine is shared: ratios of neighbouring runs, medians and ranges, and
the load average). The two must give the same bits (checked here as well as in
``tests/test_flight_table_threads.py``).
"""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

pytestmark = pytest.mark.slow

DRONES = 4000
PAIRS = 9


def _timed(fn) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - wall, time.process_time() - cpu


def test_bench_error_tables_on_threads(record_result, monkeypatch) -> None:
    import sim.flight.engines._tables as tables_mod
    from sim.flight import QuadrotorParams, TrackingReference, error_preset, simulate
    from sim.flight._threads import table_threads

    rng = np.random.default_rng(0)
    centers = rng.uniform(-200.0, 200.0, (DRONES, 3)) + [0.0, 0.0, 60.0]
    ref = TrackingReference.circle(centers, radius_m=3.0, omega_rad_s=0.5)
    errors = error_preset("gusty-rtk")
    threads = table_threads()

    def tables():
        return tables_mod.ErrorTables(errors, seed=0, drone_ids=np.arange(DRONES), plant=QuadrotorParams(),
                                      dt_s=1e-3, duration_s=1.0)

    one, many = tables().chunk(0, 1001, ref, threads=1), tables().chunk(0, 1001, ref, threads=threads)
    for name in ("gnss", "wind", "wind_grad"):
        assert getattr(one, name).tobytes() == getattr(many, name).tobytes(), name

    load = os.getloadavg()[0]
    chunk: dict[int, list[tuple[float, float]]] = {1: [], threads: []}
    for p in range(PAIRS):
        for th in ((1, threads) if p % 2 == 0 else (threads, 1)):
            t = tables()
            chunk[th].append(_timed(lambda t=t, th=th: t.chunk(0, 1001, ref, threads=th)))

    def fly() -> None:
        simulate(ref, duration_s=1.0, engine="numba", output_every=40, errors=errors)

    fly()  # compile and warm
    flights: dict[int, list[tuple[float, float]]] = {1: [], threads: []}
    for p in range(PAIRS):
        for th in ((1, threads) if p % 2 == 0 else (threads, 1)):
            monkeypatch.setattr(tables_mod, "table_threads", lambda th=th: th)
            flights[th].append(_timed(fly))
    load = max(load, os.getloadavg()[0])

    def ratios(runs: dict[int, list[tuple[float, float]]], k: int) -> list[float]:
        a, b = np.array(runs[1])[:, k], np.array(runs[threads])[:, k]
        r = a / b
        return [float(np.median(r)), float(r.min()), float(r.max())]

    fig = {
        "drones": DRONES, "preset": "gusty-rtk", "table_threads": threads, "load_average_max": load,
        "chunk_wall_s_one_thread_median": float(np.median(np.array(chunk[1])[:, 0])),
        "chunk_cpu_s_one_thread_median": float(np.median(np.array(chunk[1])[:, 1])),
        "chunk_wall_speedup_median_min_max": ratios(chunk, 0),
        "chunk_cpu_ratio_median_min_max": ratios(chunk, 1),
        "simulate_wall_speedup_median_min_max": ratios(flights, 0),
        "simulate_cpu_ratio_median_min_max": ratios(flights, 1),
        "table_share_of_simulate_wall_one_thread": float(
            np.median(np.array(chunk[1])[:, 0]) / np.median(np.array(flights[1])[:, 0])),
    }
    record_result(fig)
    assert fig["chunk_cpu_ratio_median_min_max"][0] > 0.5  # the threads add no large CPU cost


def test_bench_wind_mode_sum_against_the_taylor_form(record_result) -> None:
    """The wind mode sum (Cephes polynomials on a quadrant reduction, FMA contraction) against its previous
    Taylor form, 44,000 points (4,000 drones x 11 rows of the 10 Hz grid) x 128 modes, one thread,
    alternating in one process, CPU time (issue 20 item 6)."""
    from benchmarks._windsum_taylor import _sum_and_jacobian_blocks as taylor
    from sim.flight._disturbance import WindField
    from sim.flight._windsum import _BLOCK, turbulence_sum_and_jacobian

    rng = np.random.default_rng(0)
    n = DRONES * 11
    f = WindField.dryden(mean_mps=7.7, direction_rad=0.4, sigma_mps=1.3, length_m=152.0, vertical_factor=0.6,
                         modes=128, seed=3)
    pts = rng.uniform(-200.0, 200.0, (n, 3))
    pts[:, 2] = rng.uniform(2.0, 120.0, n)
    _, t, x, y, z = f._advected(pts, rng.uniform(0.0, 1.0, n))
    modes = f._modes()

    def now() -> tuple[np.ndarray, np.ndarray]:
        out, jac = np.zeros((n, 3)), np.zeros((n, 11))
        turbulence_sum_and_jacobian(out, jac, x, y, z, t, *modes, threads=1)
        return out, jac

    def before() -> tuple[np.ndarray, np.ndarray]:
        out, jac = np.zeros((n, 3)), np.zeros((n, 11))
        taylor(out, jac, x, y, z, t, *modes, 0, (n + _BLOCK - 1) // _BLOCK)
        return out, jac

    a, b = now(), before()  # compile, and the two agree far below anything the flight resolves
    diff = max(float(np.abs(a[0] - b[0]).max()), float(np.abs(a[1] - b[1]).max()))
    assert diff < 1e-12
    load = os.getloadavg()[0]
    cpu: dict[str, list[float]] = {"now": [], "before": []}
    for p in range(PAIRS):
        for name, fn in ((("now", now), ("before", before)) if p % 2 == 0 else (("before", before), ("now", now))):
            cpu[name].append(_timed(fn)[1])
    r = np.array(cpu["before"]) / np.array(cpu["now"])
    fig = {"points": n, "modes": 128, "threads": 1, "max_abs_difference": diff,
           "cpu_s_now_median": float(np.median(cpu["now"])), "cpu_s_before_median": float(np.median(cpu["before"])),
           "point_modes_per_cpu_s_now": n * 128 / float(np.median(cpu["now"])),
           "speedup_cpu_median_min_max": [float(np.median(r)), float(r.min()), float(r.max())],
           "load_average_max": max(load, os.getloadavg()[0])}
    record_result(fig)
    assert fig["speedup_cpu_median_min_max"][0] > 1.0


@pytest.mark.parametrize("precision", ["float64", "float32"])
def test_bench_simulate_with_the_previous_wind_sum(record_result, monkeypatch, precision) -> None:
    """Whole 1-s ``simulate`` (4,000 drones, gusty-rtk, default gains) with the current wind mode sum and with
    its previous Taylor form swapped in, alternating in one process (issue 20 item 6: the tables' share)."""
    import sim.flight._windsum as windsum
    from benchmarks._windsum_taylor import _sum_and_jacobian_blocks as taylor
    from sim.flight import TrackingReference, error_preset, simulate
    from sim.flight._threads import share_blocks

    def taylor_sum(out, jac, x, y, z, t, k, amp, omega, phase, *, threads=1):  # type: ignore[no-untyped-def]
        blocks = (x.shape[0] + windsum._BLOCK - 1) // windsum._BLOCK
        args = (out, jac, x, y, z, t, k, amp, omega, phase)
        if threads <= 1 or blocks < 2:
            taylor(*args, 0, blocks)
        else:
            share_blocks(blocks, lambda b: taylor(*args, b, b + 1), threads=threads)

    rng = np.random.default_rng(0)
    ref = TrackingReference.circle(rng.uniform(-200.0, 200.0, (DRONES, 3)) + [0.0, 0.0, 60.0], radius_m=3.0,
                                   omega_rad_s=0.5)
    errors = error_preset("gusty-rtk")
    sums = {"now": windsum.turbulence_sum_and_jacobian, "before": taylor_sum}

    def fly(name: str) -> None:
        monkeypatch.setattr(windsum, "turbulence_sum_and_jacobian", sums[name])
        simulate(ref, duration_s=1.0, engine="numba", output_every=40, errors=errors, precision=precision)

    for name in sums:
        fly(name)  # compile and warm
    load = os.getloadavg()[0]
    runs: dict[str, list[tuple[float, float]]] = {"now": [], "before": []}
    for p in range(PAIRS):
        for name in (("now", "before") if p % 2 == 0 else ("before", "now")):
            runs[name].append(_timed(lambda name=name: fly(name)))
    r = np.array(runs["before"]) / np.array(runs["now"])
    steps = DRONES * 1001
    fig = {"drones": DRONES, "preset": "gusty-rtk", "precision": precision,
           "drone_steps_per_wall_s_now_best": steps / float(np.array(runs["now"])[:, 0].min()),
           "drone_steps_per_wall_s_before_best": steps / float(np.array(runs["before"])[:, 0].min()),
           "speedup_wall_median_min_max": [float(np.median(r[:, 0])), float(r[:, 0].min()), float(r[:, 0].max())],
           "speedup_cpu_median_min_max": [float(np.median(r[:, 1])), float(r[:, 1].min()), float(r[:, 1].max())],
           "load_average_max": max(load, os.getloadavg()[0])}
    record_result(fig)
    assert fig["speedup_cpu_median_min_max"][0] > 0.9
