"""Assignment benchmarks at scale (``benchmarks/bench_assignment.py``): ours vs scipy's dense LSA.

Each measurement runs in a fresh subprocess so that its peak memory (the
child's ``ru_maxrss``, and tracemalloc's peak of Python/numpy allocations) is
its own; times are wall-clock seconds of one run on this machine, so compare
them as ratios measured in the same run.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from typing import Any

import numpy as np

from sim.bench._shows import BENCH_SPACING_M, grid_to_sphere_input


def random_to_random_input(n: int, *, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Two independent uniform clouds of ``n`` points in one cube, at the formations' density.

    The cube's side is 4.5 m·n^(1/3), so the mean spacing matches the 4.5 m
    benchmark formations. Returns (starts, goals), two (n, 3) arrays, metres.
    """
    rng = np.random.default_rng(seed)
    side = BENCH_SPACING_M * n ** (1 / 3)
    return rng.uniform(0.0, side, (n, 3)), rng.uniform(0.0, side, (n, 3)) + [0.0, 0.0, 20.0]


def transition_input(kind: str, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``kind``: ``"grid_to_sphere"``, ``"random"`` or ``"random_spare"``.

    ``"random_spare"`` has ceil(√n)² goals for n drones, like a landing onto
    the square home grid (M > N: dummy drones take the spare goals).
    """
    if kind == "grid_to_sphere":
        return grid_to_sphere_input(n)
    if kind == "random":
        return random_to_random_input(n)
    if kind == "random_spare":
        side = math.ceil(math.sqrt(n))
        return random_to_random_input(n)[0], random_to_random_input(side * side, seed=1)[1]
    raise ValueError(f"unknown benchmark input {kind!r}")


def _measure(kind: str, n: int, solver: str) -> dict[str, Any]:
    """Run in the child process: time one solve of the instance, report cost, certificate and memory."""
    import resource
    import time
    import tracemalloc

    starts, goals = transition_input(kind, n)
    if solver == "ours":
        from sim.plan._assignment import assign

        assign(*transition_input(kind, 1200))  # load the numba kernels (compiled and cached on disk)
        tracemalloc.start()
        t0 = time.perf_counter()
        a = assign(starts, goals)
        elapsed = time.perf_counter() - t0
        cost, cert = a.cost_m2, a.certificate
        out: dict[str, Any] = {
            "certificate_ok": bool(cert is not None and cert.ok),
            "gap_bound_m2": None if cert is None else cert.gap_bound_m2,
            "relative_gap_bound": None if cert is None else cert.gap_bound_m2 / max(cost, 1e-300),
            "max_violation_m2": None if cert is None else cert.max_violation_m2,
        }
    else:
        from scipy.optimize import linear_sum_assignment
        from scipy.spatial.distance import cdist

        tracemalloc.start()
        t0 = time.perf_counter()
        c = cdist(starts, goals, "sqeuclidean")
        rows, cols = linear_sum_assignment(c)
        elapsed = time.perf_counter() - t0
        cost = float(c[rows, cols].sum())
        out = {}
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    maxrss_kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # Linux: KiB
    return out | {
        "seconds": elapsed,
        "cost_m2": cost,
        "tracemalloc_peak_mb": peak / 2**20,
        "maxrss_mb": maxrss_kib / 1024,
    }


def measure_in_subprocess(kind: str, n: int, solver: str, *, timeout_s: float = 1800.0) -> dict[str, Any]:
    """:func:`_measure` in a fresh interpreter (its own peak memory); ``solver`` is "ours" or "dense"."""
    code = (
        "import json, sys; from sim.bench._assignment import _measure; "
        f"print(json.dumps(_measure({kind!r}, {int(n)}, {solver!r})))"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout_s, check=True
    )
    out: dict[str, Any] = json.loads(proc.stdout.strip().splitlines()[-1])
    return out


def bench_assignment(kind: str, n: int, *, dense_baseline: bool) -> dict[str, Any]:
    """Ours (certified sparse solver via ``assign``) and optionally scipy's dense LSA on one instance."""
    ours = measure_in_subprocess(kind, n, "ours")
    out: dict[str, Any] = {"input": kind, "drones": n} | {f"ours_{k}": v for k, v in ours.items()}
    if dense_baseline:
        dense = measure_in_subprocess(kind, n, "dense")
        out |= {f"dense_{k}": v for k, v in dense.items()}
        out["dense_over_ours"] = dense["seconds"] / ours["seconds"]
        out["cost_equal"] = math.isclose(dense["cost_m2"], ours["cost_m2"], rel_tol=1e-9)
    return out
