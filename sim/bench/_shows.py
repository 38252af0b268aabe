"""Planning and verification benchmarks (``swarmshow bench plan|check``, ``benchmarks/bench_plan.py``).

Each returns a JSON-safe dict of wall-clock times (seconds, one run on this
machine) and the ratio against a baseline measured in the same run on the same
input, so figures from different machines are comparable as ratios.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

from formations import ShowFile, parse_show
from formations._shapes import generate_shape
from sim.plan._assignment import assign
from sim.plan._plan import plan_show
from sim.plan._timing import min_transition_duration
from sim.verify._check import check_plan
from sim.verify._segments import segment_close_pairs

#: Formation spacing used by the benchmark inputs, metres (>= 3·√2 so CAPT guarantees 3 m).
BENCH_SPACING_M = 4.5


def _timed(fn: Callable[[], Any]) -> tuple[Any, float]:
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def grid_to_sphere_input(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A square ground grid and a Fibonacci sphere of ``n`` points, both spaced >= 4.5 m.

    Returns:
        (starts, goals): two (n, 3) arrays, metres.
    """
    side = math.ceil(math.sqrt(n))
    ij = np.stack(np.divmod(np.arange(n), side), axis=1).astype(np.float64)
    starts = np.c_[(ij - (side - 1) / 2) * BENCH_SPACING_M, np.zeros(n)]
    # Fibonacci spacing is ~3.1·R/√N; 2.2·√N·s/3.1 keeps a margin over s.
    radius = 0.8 * math.sqrt(n) * BENCH_SPACING_M / 1.6
    goals = generate_shape(
        "sphere", n, size_m=2 * radius, center_m=(0.0, 0.0, radius + 20.0), min_spacing_m=BENCH_SPACING_M
    ).points_m
    return starts, np.asarray(goals)


def bench_transition(n: int, *, min_distance_m: float = 3.0, dense_baseline: bool = True) -> dict[str, Any]:
    """Plan and verify one CAPT transition from a ground grid to a sphere of ``n`` drones.

    Ours: reduced-matrix exact assignment, peak-exact timing and the exact
    continuous-time separation check. Baseline: scipy's dense
    ``linear_sum_assignment`` on the raw squared-distance matrix.
    """
    starts, goals = grid_to_sphere_input(n)
    a, t_assign = _timed(lambda: assign(starts, goals))
    ends = goals[a.goal_index]
    duration, t_timing = _timed(
        lambda: min_transition_duration(starts, ends, max_speed_xy_mps=10.0, max_speed_z_mps=2.0, max_accel_mps2=4.0)
    )
    # A radius of two spacings (not just min_distance_m) also yields the exact minimum when it is safe.
    pairs, t_verify = _timed(lambda: segment_close_pairs(starts, ends, max(min_distance_m, 2 * BENCH_SPACING_M)))
    out: dict[str, Any] = {
        "drones": n,
        "assign_s": t_assign,
        "timing_s": t_timing,
        "verify_s": t_verify,
        "plan_and_verify_s": t_assign + t_timing + t_verify,
        "duration_s": float(duration),
        "assignment_cost_m2": a.cost_m2,
        "min_distance_m": float(pairs.dist.min()) if pairs.dist.size else None,
        "capt_guarantee_m": BENCH_SPACING_M / math.sqrt(2),
    }
    if dense_baseline:
        (rows, cols), t_dense = _timed(lambda: linear_sum_assignment(cdist(starts, goals, "sqeuclidean")))
        dense_cost = float(((starts[rows] - goals[cols]) ** 2).sum())
        out |= {
            "dense_lsa_s": t_dense,
            "dense_over_ours_assign": t_dense / t_assign,
            "cost_equal": math.isclose(dense_cost, a.cost_m2, rel_tol=1e-9),
        }
    return out


def benchmark_show(n: int, *, formations: int = 5) -> ShowFile:
    """A ``n``-drone show with ``formations`` alternating 2-D and 3-D formations, valid by default settings."""
    side = math.ceil(math.sqrt(n))
    half = 0.5 * math.sqrt(n) * BENCH_SPACING_M
    specs: list[tuple[str, dict[str, Any]]] = [
        ("sphere", {"size_m": 2 * 0.8 * math.sqrt(n) * BENCH_SPACING_M / 1.6}),
        ("grid", {"size_m": 2 * half, "plane": "xz"}),
        ("cube", {"size_m": BENCH_SPACING_M * (math.ceil(n ** (1 / 3)) - 1) * 1.05}),
        ("grid", {"size_m": 2 * half, "plane": "xy"}),
        ("sphere", {"size_m": 2.4 * 0.8 * math.sqrt(n) * BENCH_SPACING_M / 1.6}),
    ]
    palette = ["#ff0000", "#00ff00", "#0000ff", "#ffff00", "#ff00ff"]
    forms = []
    for k in range(formations):
        kind, kw = specs[k % len(specs)]
        z = max(kw["size_m"] / 2 + 20.0, 30.0)
        pts = generate_shape(
            kind, n, center_m=(0.0, 0.0, z), min_spacing_m=BENCH_SPACING_M, color=palette[k % 5], **kw
        )
        forms.append(
            {"name": f"{kind}-{k}", "hold_s": 5.0, "points": pts.points_m.tolist(), "colors": pts.hex_colors()}
        )
    return parse_show(
        {
            "format": "swarmshow/1",
            "name": f"bench-{n}",
            "drones": n,
            "home": {"grid": {"rows": side, "cols": side, "spacing_m": BENCH_SPACING_M}},
            "settings": {"max_altitude_m": 1000.0},
            "formations": forms,
        }
    )


def bench_show(n: int = 1000, *, formations: int = 5) -> dict[str, Any]:
    """Plan and verify a whole ``n``-drone, ``formations``-formation show.

    Baseline for the verification: the same plan sampled at 100 Hz with a k-d
    tree pair query per sample (what a sampled check costs, and it still only
    bounds the minimum from above).
    """
    show = benchmark_show(n, formations=formations)
    plan, t_plan = _timed(lambda: plan_show(show))
    report, t_check = _timed(lambda: check_plan(plan))

    def sampled_min() -> float:
        from scipy.spatial import cKDTree

        best = math.inf
        for t in plan.sample_times(100.0)[::10]:  # 10 Hz of the 100 Hz grid keeps the baseline affordable
            p = plan.evaluate(np.array([t])).positions_m[0]
            d, _ = cKDTree(p).query(p, k=2)
            best = min(best, float(d[:, 1].min()))
        return best

    sampled, t_sampled = _timed(sampled_min)
    return {
        "drones": n,
        "formations": formations,
        "show_duration_s": plan.duration_s,
        "plan_s": t_plan,
        "check_s": t_check,
        "exact_min_distance_m": report.min_distance_m,
        "sampled_10hz_min_distance_m": sampled,
        "sampled_10hz_s": t_sampled,
        "sampled_over_exact_check": t_sampled / t_check,
        "violations": report.violations_total,
    }
