"""Dense benchmark shows (formations drawn at exactly ``min_distance_m``) and a show-length lower bound.

Shared by ``benchmarks/bench_dense.py`` and ``swarmshow bench plan --dense``.

**Shows.** N drones on a home grid at Δ = ``min_distance_m``; formations of different
kinds, each exactly N points on a lattice of spacing Δ (so the closest pair is exactly
Δ): a filled disc (hexagonal lattice), a filled five-pointed star, a filled ball (cubic
lattice), text (hexagonal lattice masked by rendered glyphs), an "image" (a smiley mask)
and a wall (square lattice), plus a random cloud (Poisson-disc dart throwing, spacing
>= Δ). Vertical shapes face the audience in the x-z plane.

**Lower bound.** Σ holds + Σ over the takeoff, every transition, the landing approach
and the landing of the *bottleneck minimum-time assignment*: min over assignments σ of
max_i t(x_i, g_σ(i)), with t the minimum time of one drone under the same limits,
trapezoidal per axis (t = max(t_xy, t_z), t(d; v, a) = 2√(d/a) if d <= v²/a else d/v + v/a).
Each axis component of any feasible motion obeys that axis' speed limit and |a| <= a_max,
so t is a lower bound for each drone, and the bottleneck is a lower bound for the
transition whatever the assignment. Computed by bisection on the threshold τ with
a Hopcroft-Karp matching (:func:`hopcroft_karp`) on the edges t_ij <= τ (a perfect
matching exists iff the bottleneck is <= τ); the reported value is the largest τ found
infeasible, so it stays a lower bound. Formations starting from the previous formation
use its points (all N occupied, since each formation has exactly N points).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypedDict

import numba
import numpy as np
from scipy.sparse import csr_matrix
from scipy.spatial import cKDTree

from formations import ShowFile, parse_show

if TYPE_CHECKING:
    from sim.plan import ShowPlan

#: Formation kinds of the dense suite, in show order.
DENSE_KINDS = ("disc", "star", "ball", "text", "image", "wall", "cloud")
#: Drone counts of the suite.
DENSE_SIZES = (100, 300, 1000, 5000)


def _home_shape(n: int) -> tuple[int, int]:
    rows = int(math.floor(math.sqrt(n)))
    while n % rows:
        rows -= 1
    return rows, n // rows


def _hex_lattice(extent_m: float, spacing_m: float) -> np.ndarray:
    """(K, 2) hexagonal lattice points of spacing ``spacing_m`` covering [-extent, extent]²."""
    rows = int(math.ceil(extent_m / (spacing_m * math.sqrt(3) / 2)))
    cols = int(math.ceil(extent_m / spacing_m)) + 1
    j, i = np.meshgrid(np.arange(-rows, rows + 1), np.arange(-cols, cols + 1), indexing="ij")
    u = (i + 0.5 * (j % 2)) * spacing_m
    v = j * spacing_m * math.sqrt(3) / 2
    return np.column_stack([u.ravel(), v.ravel()])


def _take_central(uv: np.ndarray, n: int, norm: np.ndarray) -> np.ndarray:
    order = np.lexsort((uv[:, 1], uv[:, 0], np.round(norm, 9)))
    return uv[order[:n]]


def _star_norm(uv: np.ndarray, points: int = 5, inner: float = 0.5) -> np.ndarray:
    """A gauge whose unit ball is a five-pointed star (inner radius ratio ``inner``)."""
    r = np.hypot(uv[:, 0], uv[:, 1])
    ang = np.mod(np.arctan2(uv[:, 0], uv[:, 1]), 2 * np.pi / points) / (2 * np.pi / points)
    # Star boundary radius along the angle: linear between tip (1) and notch (inner) in polar terms.
    edge = 1.0 - (1.0 - inner) * (1.0 - np.abs(2.0 * ang - 1.0))
    return np.asarray(r / edge, dtype=np.float64)


def _mask_points(n: int, spacing: float, inside: Callable[[np.ndarray, float], np.ndarray]) -> np.ndarray:
    """N lattice points inside a growing mask ``inside(uv, scale) -> bool``, most central first."""
    scale = spacing * math.sqrt(n) * 0.6
    for _ in range(60):
        uv = _hex_lattice(scale * 1.2, spacing)
        keep = inside(uv, scale)
        if keep.sum() >= n:
            pts = uv[keep]
            return _take_central(pts, n, np.hypot(pts[:, 0], pts[:, 1]))
        scale *= 1.15
    raise RuntimeError("mask too small")


def _smiley(uv: np.ndarray, scale: float) -> np.ndarray:
    r = np.hypot(uv[:, 0], uv[:, 1]) / scale
    ring = (r > 0.78) & (r <= 1.0)
    eyes = (np.hypot(np.abs(uv[:, 0]) / scale - 0.35, uv[:, 1] / scale - 0.3) < 0.15)
    mouth = (r > 0.42) & (r < 0.6) & (uv[:, 1] < -0.1 * scale)
    return np.asarray(ring | eyes | mouth, dtype=np.bool_)


def _text(n: int, spacing: float, text: str = "HELLO") -> np.ndarray:
    from formations._text import text_mask

    height = spacing * math.sqrt(n / (3.0 * len(text))) * 1.6
    for _ in range(60):
        mask, px = text_mask(text, height_m=height, min_spacing_m=spacing)
        h, w = mask.shape
        uv = _hex_lattice(max(h, w) * px, spacing) + np.array([w * px / 2, h * px / 2])
        col = np.floor(uv[:, 0] / px).astype(int)
        row = np.floor(uv[:, 1] / px).astype(int)
        ok = (col >= 0) & (col < w) & (row >= 0) & (row < h)
        ink = np.zeros(len(uv), dtype=bool)
        ink[ok] = mask[h - 1 - row[ok], col[ok]]
        if ink.sum() >= n:
            pts = uv[ink] - np.array([w * px / 2, h * px / 2])
            return _take_central(pts, n, np.abs(pts[:, 0]) + 0.01 * np.abs(pts[:, 1]))
        height *= 1.15
    raise RuntimeError("text too small")


def _ball(n: int, spacing: float) -> np.ndarray:
    k = int(math.ceil((n * 6 / math.pi) ** (1 / 3))) + 2
    g = (np.stack(np.meshgrid(*(np.arange(k) - (k - 1) / 2,) * 3, indexing="ij"), -1).reshape(-1, 3)) * spacing
    d = np.linalg.norm(g, axis=1)
    order = np.lexsort((g[:, 2], g[:, 1], g[:, 0], np.round(d, 9)))
    return g[order[:n]]


def _wall(n: int, spacing: float) -> np.ndarray:
    rows, cols = _home_shape(n)
    j, i = np.divmod(np.arange(n), cols)
    return np.column_stack([(i - (cols - 1) / 2) * spacing, (j - (rows - 1) / 2) * spacing])


def _cloud(n: int, spacing: float, rng: np.random.Generator) -> np.ndarray:
    """Poisson-disc dart throwing in a cube sized for ~35 % packing (spacing >= Δ)."""
    side = (n * spacing**3 / 0.35) ** (1 / 3)
    pts = np.zeros((0, 3))
    while len(pts) < n:
        cand = rng.uniform(-side / 2, side / 2, size=(4 * n, 3))
        accepted: list[np.ndarray] = []
        tree = cKDTree(pts) if len(pts) else None
        for c in cand:
            if tree is not None and tree.query(c)[0] < spacing:
                continue
            if accepted and np.min(np.linalg.norm(np.asarray(accepted) - c, axis=1)) < spacing:
                continue
            accepted.append(c)
            if len(pts) + len(accepted) >= n or len(accepted) >= 256:
                break
        if accepted:
            pts = np.vstack([pts, accepted])
        else:
            side *= 1.1
    return pts[:n]


def dense_points(kind: str, n: int, spacing_m: float, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) points of one dense formation centred on the origin (vertical shapes in x-z), metres."""
    if kind == "ball":
        return _ball(n, spacing_m)
    if kind == "cloud":
        return _cloud(n, spacing_m, rng)
    if kind == "disc":
        uv = _mask_points(n, spacing_m, lambda uv, s: np.hypot(uv[:, 0], uv[:, 1]) <= s)
    elif kind == "star":
        uv = _mask_points(n, spacing_m, lambda uv, s: _star_norm(uv) <= s)
    elif kind == "image":
        uv = _mask_points(n, spacing_m, _smiley)
    elif kind == "text":
        uv = _text(n, spacing_m)
    elif kind == "wall":
        uv = _wall(n, spacing_m)
    else:
        raise ValueError(f"unknown dense kind {kind!r}")
    return np.column_stack([uv[:, 0], np.zeros(len(uv)), uv[:, 1]])


def dense_show(n: int, *, formations: int = 6, spacing_m: float = 3.0, hold_s: float = 5.0,
               seed: int = 0, **settings: Any) -> ShowFile:
    """An n-drone show of ``formations`` dense formations (kinds cycle through :data:`DENSE_KINDS`)."""
    rng = np.random.default_rng(seed)
    rows, cols = _home_shape(n)
    forms = []
    palette = ["#ff0000", "#00ff00", "#0000ff", "#ffff00", "#ff00ff", "#00ffff", "#ffffff"]
    for k in range(formations):
        kind = DENSE_KINDS[k % len(DENSE_KINDS)]
        pts = dense_points(kind, n, spacing_m, rng)
        pts = pts - pts.mean(axis=0)
        pts[:, 2] += -pts[:, 2].min() + 20.0  # lowest point 20 m up
        pts = np.round(pts, 9)
        forms.append({"name": f"{kind}-{k}", "hold_s": hold_s, "points": pts.tolist(), "color": palette[k % 7]})
    return parse_show({
        "format": "swarmshow/1",
        "name": f"dense-{n}",
        "drones": n,
        "home": {"grid": {"rows": rows, "cols": cols, "spacing_m": spacing_m}},
        "settings": {"min_distance_m": spacing_m, "max_altitude_m": 2000.0, **settings},
        "formations": forms,
    })


def _trap_time(d: np.ndarray, v: float, a: float) -> np.ndarray:
    return np.where(d <= v * v / a, 2.0 * np.sqrt(d / a), d / v + v / a)


def _trap_reach(t: float, v: float, a: float) -> float:
    """Largest distance coverable in time t (inverse of the trapezoid time)."""
    return a * t * t / 4.0 if t <= 2.0 * v / a else v * (t - v / a)


def leg_time_lower_bound(x: np.ndarray, g: np.ndarray, *, v_xy: float, v_z: float, a: float,
                         v_down: float | None = None) -> np.ndarray:
    """(..., ) per-axis trapezoidal minimum time of moving x -> g (broadcast), seconds."""
    d = g - x
    txy = _trap_time(np.hypot(d[..., 0], d[..., 1]), v_xy, a)
    vz = np.where(d[..., 2] < 0, v_z if v_down is None else v_down, v_z)
    tz = np.where(vz > 0, _trap_time_vec(np.abs(d[..., 2]), vz, a), 0.0)
    return np.asarray(np.maximum(txy, tz), dtype=np.float64)


def _trap_time_vec(d: np.ndarray, v: np.ndarray, a: float) -> np.ndarray:
    return np.where(d <= v * v / a, 2.0 * np.sqrt(d / a), d / v + v / a)


@numba.njit(cache=True)
def hopcroft_karp(indptr: np.ndarray, indices: np.ndarray, n_left: int,
                 n_right: int) -> int:  # pragma: no cover - numba
    """Size of a maximum matching of the bipartite graph (CSR rows = left vertices).

    Hopcroft & Karp, "An n^5/2 algorithm for maximum matchings in bipartite graphs",
    SIAM J. Comput. 2 (1973): BFS layers from the free left vertices, then vertex-disjoint
    augmenting paths by depth-first search along the layers (iterative), O(E·√V).
    (scipy's ``maximum_bipartite_matching`` took minutes on some of these graphs.)
    """
    inf = 1 << 60
    match_l = np.full(n_left, -1, dtype=np.int64)
    match_r = np.full(n_right, -1, dtype=np.int64)
    for u in range(n_left):
        for q in range(indptr[u], indptr[u + 1]):
            v = indices[q]
            if match_r[v] < 0:
                match_l[u] = v
                match_r[v] = u
                break
    dist = np.empty(n_left, dtype=np.int64)
    queue = np.empty(n_left, dtype=np.int64)
    it = np.empty(n_left, dtype=np.int64)
    stack = np.empty(n_left + 1, dtype=np.int64)
    via = np.empty(n_left + 1, dtype=np.int64)
    size = int((match_l >= 0).sum())
    while True:
        head = 0
        tail = 0
        for u in range(n_left):
            if match_l[u] < 0:
                dist[u] = 0
                queue[tail] = u
                tail += 1
            else:
                dist[u] = inf
        limit = inf
        while head < tail:
            u = queue[head]
            head += 1
            if dist[u] >= limit:
                continue
            for q in range(indptr[u], indptr[u + 1]):
                w = match_r[indices[q]]
                if w < 0:
                    if limit == inf:
                        limit = dist[u] + 1
                elif dist[w] == inf:
                    dist[w] = dist[u] + 1
                    queue[tail] = w
                    tail += 1
        if limit == inf:
            return size
        for u in range(n_left):
            it[u] = indptr[u]
        for root in range(n_left):
            if match_l[root] >= 0:
                continue
            top = 0
            stack[0] = root
            while top >= 0:
                x = stack[top]
                if it[x] == indptr[x + 1]:
                    dist[x] = inf
                    top -= 1
                    continue
                v = indices[it[x]]
                it[x] += 1
                w = match_r[v]
                if w < 0:
                    if dist[x] + 1 != limit:
                        continue
                    via[top] = v
                    for k in range(top, -1, -1):
                        y = stack[k]
                        vv = via[k]
                        match_l[y] = vv
                        match_r[vv] = y
                    size += 1
                    break
                if dist[w] == dist[x] + 1:
                    via[top] = v
                    top += 1
                    stack[top] = w


def bottleneck_time(x: np.ndarray, g: np.ndarray, *, tol_s: float = 0.05, **lim: Any) -> float:
    """Lower bound (s) on min over assignments of the longest leg time x_i -> g_σ(i) (module docstring).

    The N x M matrix of leg times is built in float32 (N·M·4 bytes; 100 MB at 5,000 drones);
    bisection between max_i min_j t_ij (every drone must go somewhere) and the largest leg of
    a greedy perfect matching, down to ``tol_s``. Returns the largest threshold proven infeasible
    (or the lower bracket when that is already feasible).
    """
    n, m = len(x), len(g)
    t = np.empty((n, m), dtype=np.float32)
    step = max(1, 2_000_000 // max(m, 1))
    for a in range(0, n, step):
        t[a:a + step] = leg_time_lower_bound(x[a:a + step, None, :], g[None, :, :], **lim)

    def feasible(tau: float) -> bool:
        graph = csr_matrix(t <= tau)
        return bool(hopcroft_karp(graph.indptr.astype(np.int64), graph.indices.astype(np.int64), n, m) == n)

    lo = float(max(t.min(axis=1).max(), t.min(axis=0).max() if m == n else 0.0)) - 1e-4
    if feasible(lo):
        return lo
    hi = float(t.max())
    while hi - lo > tol_s:
        mid = 0.5 * (lo + hi)
        if feasible(mid):
            hi = mid
        else:
            lo = mid
    return lo


class _Limits(TypedDict):
    """Keyword arguments of :func:`leg_time_lower_bound` taken from a show's settings."""

    v_xy: float
    v_z: float
    a: float
    v_down: float | None


def show_lower_bound(show: ShowFile) -> dict[str, Any]:
    """The show-length lower bound of the module docstring, seconds, with its terms."""
    s = show.settings
    lim: _Limits = {"v_xy": s.max_speed_xy_mps, "v_z": s.max_speed_z_mps, "a": s.max_accel_mps2,
           "v_down": s.max_descent_speed_mps}
    lift = np.array([0.0, 0.0, s.takeoff_altitude_m])
    home = np.asarray(show.home_positions_m)
    terms = []
    up_t = float(leg_time_lower_bound(home[:1], home[:1] + lift, **lim)[0])
    down_t = float(leg_time_lower_bound(home[:1] + lift, home[:1], **lim)[0])
    terms.append(up_t)
    prev = home + lift
    holds = 0.0
    for f in show.formations:
        terms.append(bottleneck_time(prev, f.points_m, **lim))
        holds += f.hold_s
        prev = f.points_m if len(f.points_m) == len(home) else f.points_m  # all points occupied when M = N
    homes_up = np.asarray(show.all_home_positions_m) + lift
    terms.append(bottleneck_time(prev, homes_up, **lim))
    terms.append(down_t)
    return {"lower_bound_s": holds + sum(terms), "holds_s": holds, "transition_bounds_s": terms}


def _warm_up() -> dict[str, float]:
    """Plan and check a tiny dense show once per process, both candidate searches, so that loading the
    compiled (numba) kernels is not timed as part of the first show. Returns what that cost in this
    process (wall and CPU seconds; zero after the first call): loading the kernels from numba's
    on-disk cache, or compiling them when the cache is cold."""
    global _WARM
    if _WARM:
        return {"kernel_load_s": 0.0, "kernel_load_cpu_s": 0.0}
    from sim.plan import plan_show
    from sim.verify import check_plan

    c0, t0 = time.process_time(), time.perf_counter()
    plan = plan_show(dense_show(12, formations=2))
    check_plan(plan)
    check_plan(plan, candidates="kdtree")
    _WARM = True
    return {"kernel_load_s": time.perf_counter() - t0, "kernel_load_cpu_s": time.process_time() - c0}


_WARM = False

_FIRST_RUN = """
import json, resource, sys, time
from sim.bench._dense import dense_show
show = dense_show({n}, formations={formations})
from sim.plan import plan_show
from sim.verify import check_plan
c0, t0 = time.process_time(), time.perf_counter()
plan = plan_show(show)
c1, t1 = time.process_time(), time.perf_counter()
report = check_plan(plan)
c2, t2 = time.process_time(), time.perf_counter()
try:  # this process's own peak (ru_maxrss would include the parent's, inherited across fork and exec)
    peak = int(next(x for x in open("/proc/self/status") if x.startswith("VmHWM")).split()[1]) / 1024.0
except (OSError, StopIteration):
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
json.dump({{"plan_s": t1 - t0, "plan_cpu_s": c1 - c0, "check_s": t2 - t1, "check_cpu_s": c2 - c1,
           "violations": report.violations_total, "duration_s": plan.duration_s,
           "peak_rss_mb": peak}}, sys.stdout)
"""


def cold_and_warm(n: int, *, formations: int = 6) -> dict[str, Any]:
    """Plan + check one dense show as a command-line user does: in a fresh process, first with an empty
    numba cache (every kernel compiled: once per install), then again with the cache that run filled
    (kernels loaded from disk: every later process). Times include that compiling or loading, not the
    show's construction. Both runs must give the same plan (same length, same violations)."""
    import json
    import os
    import subprocess
    import sys
    import tempfile

    out: dict[str, Any] = {"drones": n, "formations": formations}
    with tempfile.TemporaryDirectory(prefix="swarmshow-numba-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        for label in ("cold", "warm"):
            proc = subprocess.run([sys.executable, "-c", _FIRST_RUN.format(n=n, formations=formations)], env=env,
                                  capture_output=True, text=True, check=True)
            out[label] = json.loads(proc.stdout)
    out["load_avg_1m"] = _load_average()
    out["same_plan"] = (out["cold"]["duration_s"] == out["warm"]["duration_s"]
                        and out["cold"]["violations"] == out["warm"]["violations"])
    return out


def _load_average() -> float:
    """The machine's 1-minute load average (times on a shared machine mean little without it)."""
    import os

    return float(os.getloadavg()[0])


def _peak_rss_mb() -> float:
    """Peak resident memory of this process so far (interpreter, libraries and earlier work included), MB."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def bench_dense(n: int, *, formations: int = 6, sampled_check: bool | None = None, compare_kdtree: bool | None = None,
                **settings: Any) -> dict[str, Any]:
    """Plan + check one dense show: violations, show length vs the lower bound, time and peak memory.

    Times are wall clock and process CPU (the CPU time is what to compare on a shared machine), with the
    compiled kernels already loaded (``kernel_load_s``: what loading them cost this process, if it was the
    first show; :func:`cold_and_warm` measures fresh processes).
    Memory is the process's peak resident set (``ru_maxrss``), an upper bound on what the show
    needed; no tracemalloc, which slowed the numpy-heavy check 2-3x. ``compare_kdtree`` (default:
    up to 1,000 drones) re-runs the check with the reference k-d-tree candidate search, same input,
    for the speed ratio.
    """
    from sim.plan import plan_show
    from sim.verify import check_plan

    show = dense_show(n, formations=formations, **settings)
    load = _warm_up()
    c0, t0 = time.process_time(), time.perf_counter()
    plan = plan_show(show)
    c1, t1 = time.process_time(), time.perf_counter()
    report = check_plan(plan)
    c2, t2 = time.process_time(), time.perf_counter()
    peak = _peak_rss_mb()
    bound = show_lower_bound(show)
    unresolved = sum(len(tr.unresolved) for tr in plan.transitions)
    out = {
        "drones": n,
        "formations": formations,
        "kinds": [f.name for f in show.formations],
        "time_law": show.settings.time_law,
        "show_duration_s": plan.duration_s,
        "lower_bound_s": bound["lower_bound_s"],
        "ratio_to_bound": plan.duration_s / bound["lower_bound_s"],
        "transitions": [
            {"to": tr.to_name, "duration_s": tr.duration_s, "bound_s": b, "resolution": tr.resolution,
             "stagger_s": tr.stagger_s}
            for tr, b in zip(plan.transitions, bound["transition_bounds_s"][1:-1], strict=True)
        ],
        "stagger_s": sum(tr.stagger_s for tr in plan.transitions),
        "unresolved": unresolved,
        "violations": report.violations_total,
        "violation_kinds": sorted({v.kind for v in report.violations}),
        "check_min_distance_m": report.min_distance_m,
        "plan_s": t1 - t0,
        "check_s": t2 - t1,
        "plan_and_check_s": t2 - t0,
        "plan_cpu_s": c1 - c0,
        "check_cpu_s": c2 - c1,
        "plan_and_check_cpu_s": c2 - c0,
        "peak_rss_mb": peak,
        "load_avg_1m": _load_average(),
        **load,
    }
    if compare_kdtree if compare_kdtree is not None else n <= 1000:
        c3, t3 = time.process_time(), time.perf_counter()
        ref = check_plan(plan, candidates="kdtree")
        c4, t4 = time.process_time(), time.perf_counter()
        out |= {"check_kdtree_s": t4 - t3, "check_kdtree_cpu_s": c4 - c3,
                "kdtree_over_sweep_cpu": (c4 - c3) / max(c2 - c1, 1e-9),
                "kdtree_same_result": ref.violations_total == report.violations_total
                and ref.min_distance_m == report.min_distance_m}
    if sampled_check if sampled_check is not None else n <= 1000:
        out |= sampled_separation(plan)
    return out


def sampled_separation(plan: ShowPlan, *, dt_s: float = 0.05) -> dict[str, Any]:
    """Independent dense-sampling check of the plan's motion: sampled minimum and a certified lower bound.

    Between samples h apart, |r(t)| >= (|r(t0)| + |r(t1)|)/2 - v_rel·h/2 (Lipschitz), with
    v_rel <= the largest speed sum of two drones at the two samples plus a_max·h (speeds can
    grow by at most a_max·h in between).
    """
    t = np.arange(0.0, plan.duration_s + dt_s, dt_s)
    limit = plan.settings.min_distance_m
    best_sampled = math.inf
    best_certified = math.inf
    a_max = plan.settings.max_accel_mps2 * 1.001
    prev = None
    for t_chunk in np.array_split(t, max(1, len(t) // 64)):
        smp = plan.motion.evaluate(t_chunk, derivatives=1)
        for k in range(len(t_chunk)):
            p = smp.positions_m[k]
            speed = np.linalg.norm(smp.velocities_mps[k], axis=1)
            tree = cKDTree(p)
            pairs = tree.query_pairs(limit + 2.0, output_type="ndarray")
            d = np.linalg.norm(p[pairs[:, 0]] - p[pairs[:, 1]], axis=1) if len(pairs) else np.zeros(0)
            if len(d):
                best_sampled = min(best_sampled, float(d.min()))
            if prev is not None and len(pairs):
                p0, s0 = prev
                d0 = np.linalg.norm(p0[pairs[:, 0]] - p0[pairs[:, 1]], axis=1)
                v_rel = np.maximum(s0[pairs[:, 0]] + s0[pairs[:, 1]], speed[pairs[:, 0]] + speed[pairs[:, 1]])
                lb = 0.5 * (d0 + d) - (v_rel + 2 * a_max * dt_s) * dt_s / 2
                best_certified = min(best_certified, float(lb.min()))
            prev = (p, speed)
    return {"sampled_min_distance_m": best_sampled, "sampled_lipschitz_lower_bound_m": best_certified,
            "sampled_dt_s": dt_s}
