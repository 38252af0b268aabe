"""Exact verification of a planned show: separation, speeds, acceleration, altitude.

The plan's motion is per-drone piecewise polynomials (:class:`sim.plan.Trajectories`):
drones do not share a time law, so nothing here assumes one.

**Separation** is checked continuously in time, window by window (the plan's
show-wide segments, at whose boundaries every drone rests). Within a window:

1. *Exact pair minimum.* For a pair (i, j), cut the window at both drones' piece
   breaks; on each part both drones are on one polynomial piece, so
   d²(t) = |p_j(t) - p_i(t)|² is one polynomial of degree <= 10. Its minimum
   on the part is found by certified Bernstein branch and bound
   (:mod:`sim.verify._poly`): exact to a relative 1e-13, with the time.
2. *Candidate pairs, provably complete.* Each piece is cut into 8 equal parts
   and the largest Bernstein coefficient of |v|² on each part bounds the
   drone's speed there (convex-hull property). Over a grid of cells, V(c) is the
   largest such bound of any drone on any part overlapping cell c. The window
   is cut into time slices [a, b] of width h = b - a made of whole cells, with
   V_s = max V over the slice, greedily so that V_s·h <= R (R the search
   radius). *Claim:* a pair within R of each other at some t in the slice is
   within R + V_s·h of each other at the slice centre c = (a + b)/2.
   *Proof:* |t - c| <= h/2 and every drone's speed on [a, b] is <= V_s, so
   |p_i(t) - p_i(c)| <= V_s·h/2 for each drone; by the triangle inequality
   |p_j(c) - p_i(c)| <= |p_j(t) - p_i(t)| + V_s·h <= R + V_s·h. So a
   ``cKDTree.query_pairs`` at the slice centre with radius R + V_s·h (<= 2R)
   finds every pair that comes within R anywhere in the slice, and the union
   over slices every pair that does so in the window; step 1 then gives each
   candidate's exact minimum over the whole window. Drones at rest contribute
   speed 0 and so widen nothing; a window where nobody moves is one slice.
3. *Radius.* R = max(min_distance_m, the closest-pair distance at either window
   boundary). The window's minimum is <= the latter, so it is always found
   (the exact per-window minimum is reported even when it is safe), and every
   pair closer than the limit is found and reported.

**Peaks** (horizontal and vertical speed, acceleration magnitude, altitude max
and min) are exact per piece: each is the extremum of a polynomial (vx² + vy²,
vz², |a|², z) on the piece, by the same branch and bound, vectorised over all
pieces with numba.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, NamedTuple

import numba
import numpy as np
from pydantic import BaseModel, Field, field_serializer
from scipy.spatial import cKDTree

from formations import ShowFile
from sim.plan._plan import ShowPlan
from sim.plan._threads import pool, workers
from sim.plan._trajectory import Trajectories
from sim.verify import _poly, _sweep
from sim.verify._bounds import check_bounds
from sim.verify._downwash import DOWNWASH_SEGMENTS, scaled_motion
from sim.verify._parked import airborne_span, clearance, restrict
from sim.verify._violation import Violation

#: Relative tolerance on the limits, so that a value equal to its limit passes despite rounding.
_TOL = 1e-9
#: Violations listed in a report (all are counted in ``violations_total``).
MAX_LISTED_VIOLATIONS = 200
#: Violations listed per transition in ``by_transition`` (all are counted there too).
MAX_LISTED_PER_TRANSITION = 50
#: Drones named in one speed / acceleration / altitude violation.
MAX_DRONES_PER_VIOLATION = 10
#: Each piece is cut into this many parts for the speed envelope of the candidate search.
_SPEED_PARTS = 8
#: Cells per slice (at most) of the speed envelope grid, and a cap on cells per window.
_CELLS_PER_SLICE = 4
_MAX_CELLS = 8192
#: Bound on (slice, drone) positions evaluated at once, to bound memory.
_EVAL_BUDGET = 1 << 19


def _no_pair_is_null(value: float) -> float | None:
    """A minimum over no pair (+inf in Python) is ``null`` in JSON, which has no infinity (the -1 once said
    there read as a distance below every limit); the API's schema says number or null."""
    return float(value) if math.isfinite(value) else None


#: The JSON of a distance that is +inf when there is no pair (fewer than two drones, or not searched).
_NULL_WITHOUT_PAIR = " +inf in Python and null in JSON when there is no pair."


class CaptPremise(BaseModel):
    """CAPT's guarantee beside the exact result for one transition."""

    start_spacing_m: float = Field(description="Closest pair of the start positions, metres;" + _NULL_WITHOUT_PAIR)
    goal_spacing_m: float = Field(description="Closest pair of the goal positions, metres;" + _NULL_WITHOUT_PAIR)
    guaranteed_min_distance_m: float = Field(description="min(start, goal spacing)/√2, metres;" + _NULL_WITHOUT_PAIR)
    exact_min_distance_m: float = Field(description="The exact minimum over the transition, metres;"
                                        + _NULL_WITHOUT_PAIR)
    holds: bool = Field(description="exact >= guaranteed (it must; False would be a planner bug).")

    @field_serializer("start_spacing_m", "goal_spacing_m", "guaranteed_min_distance_m", "exact_min_distance_m",
                      when_used="json")
    def _null_without_pair(self, value: float) -> float | None:
        return _no_pair_is_null(value)


class TransitionReport(BaseModel):
    """A planned CAPT transition."""

    model_config = {"populate_by_name": True}

    from_: str = Field(alias="from")
    to: str
    segment: int
    start_s: float
    duration_s: float
    min_duration_s: float = Field(description="Shortest duration the limits allow, seconds (0.1 s steps).")
    assignment_cost_m2: float = Field(description="Σ squared distance of the optimal assignment, m².")
    stagger_s: float = Field(0.0, description="Time the planner added to keep drones apart (staggering), s.")
    resolution: str = Field("", description="How the planner made the transition safe (empty: not reported).")
    capt: CaptPremise


class FixHint(BaseModel):
    """Something the planner could not resolve, and what would fix it."""

    drones: list[int]
    time_s: float
    reason: str
    fix: str


class TransitionCheck(BaseModel):
    """The check of one show segment that moves (takeoff, a transition, landing), or of a hold that fails."""

    model_config = {"populate_by_name": True}

    segment: int
    kind: str = Field(description="takeoff, transition, landing or hold.")
    from_: str = Field(alias="from")
    to: str
    formation: int = Field(description="Index of the formation it leads into (a hold: its formation); -1: none.")
    start_s: float
    duration_s: float
    stagger_s: float = Field(description="Time the planner added to keep drones apart, s (0 if none or unknown).")
    resolution: str = Field(description="How the planner made it safe (empty: not reported by the planner).")
    ok: bool
    min_distance_m: float = Field(description="Exact minimum distance in the segment, m;" + _NULL_WITHOUT_PAIR)
    min_distance_pair: list[int] = Field(description="The closest pair (i < j); empty when there is none.")
    min_distance_time_s: float
    violations_total: int
    violations: list[Violation] = Field(description="Worst first (smallest distance), at most 50.")
    unresolved: list[FixHint] = Field(description="What the planner could not make safe, and what would fix it.")
    fixes: list[str] = Field(description="Changes to the show that would remove these violations.")
    waves: int = Field(0, description="Takeoff / landing: the drones leave (land) in this many waves, one after "
                       "another (0: all at once).")

    @field_serializer("min_distance_m", when_used="json")
    def _null_without_pair(self, value: float) -> float | None:
        return _no_pair_is_null(value)


class CheckReport(BaseModel):
    """Plan summary and exact verification report (``swarmshow check --json``)."""

    ok: bool
    show: str
    drones: int
    duration_s: float
    min_distance_m: float = Field(description=(
        "Exact minimum distance between any two drones over the show, m; +inf in Python and null in JSON with "
        "fewer than two drones (no pair: no distance, and no limit broken by it)."))
    min_distance_pair: list[int] = Field(description="The closest pair (i < j); empty with fewer than two drones.")
    min_distance_time_s: float
    max_speed_xy_mps: float
    max_speed_z_mps: float
    max_accel_mps2: float
    max_altitude_m: float
    min_altitude_m: float
    limits: dict[str, float]
    transitions: list[TransitionReport]
    by_transition: list[TransitionCheck] = Field(
        description="Per segment that moves (and per failing hold), in show order: its violations worst first."
    )
    violations: list[Violation]
    violations_total: int

    @field_serializer("min_distance_m", when_used="json")
    def _null_without_pair(self, value: float) -> float | None:
        return _no_pair_is_null(value)

    def to_json(self) -> dict[str, Any]:
        """JSON-ready dict with DESIGN.md's key names (``from``, not ``from_``)."""
        return self.model_dump(mode="json", by_alias=True)

    def worst_transitions(self) -> list[TransitionCheck]:
        """``by_transition`` with failing ones first, smallest minimum distance first."""
        def key(g: TransitionCheck) -> tuple[bool, float, int]:
            return (g.ok, g.min_distance_m, g.segment)
        return sorted(self.by_transition, key=key)


class ClosePairs(NamedTuple):
    """Pairs (i < j) whose exact minimum distance in a time window is <= the search radius."""

    i: np.ndarray
    j: np.ndarray
    dist_m: np.ndarray
    time_s: np.ndarray


class PieceExtrema(NamedTuple):
    """Exact per-piece extrema: (N, P) values and times (s) of each quantity."""

    speed_xy_mps: np.ndarray
    speed_xy_t: np.ndarray
    speed_z_mps: np.ndarray
    speed_z_t: np.ndarray
    accel_mps2: np.ndarray
    accel_t: np.ndarray
    z_max_m: np.ndarray
    z_max_t: np.ndarray
    z_min_m: np.ndarray
    z_min_t: np.ndarray


def piece_extrema(motion: Trajectories, limits: tuple[float, float, float, float, float] | None = None
                  ) -> PieceExtrema:
    """Per-piece peaks of horizontal / vertical speed, acceleration and altitude (max, min).

    Without ``limits`` every value is exact. With ``limits`` (max speed xy, max speed z,
    max acceleration, max altitude, min altitude) a piece is refined only as far as needed
    (:func:`sim.verify._poly.piece_extrema`): values past a limit and each drone's peaks are
    exact, the others may be lower attained values (much less work on long shows).
    """
    n, p = motion.drone_count, motion.piece_count
    v = np.empty((n, p, 5))
    t = np.empty((n, p, 5))
    if limits is None:
        lim = np.full(5, np.nan)
    else:
        lim = np.array([limits[0] ** 2, limits[1] ** 2, limits[2] ** 2, limits[3], limits[4]], dtype=np.float64)
    _poly.piece_extrema(motion.breaks_s, motion.coeffs_m, _poly.W, v, t, lim)
    root = np.sqrt(np.maximum(v[..., :3], 0.0))
    return PieceExtrema(root[..., 0], t[..., 0], root[..., 1], t[..., 1], root[..., 2], t[..., 2],
                        v[..., 3], t[..., 3], v[..., 4], t[..., 4])


def speed_bounds(motion: Trajectories) -> np.ndarray:
    """(N, P, 8) upper bounds of each drone's speed on 8 equal parts of each piece, m/s."""
    out = np.empty((motion.drone_count, motion.piece_count, _SPEED_PARTS))
    _poly.speed_bounds(motion.breaks_s, motion.coeffs_m, _poly.W, _SPEED_PARTS, out)
    return out


def _slices(motion: Trajectories, bounds: np.ndarray, t0: float, t1: float, radius_m: float
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Slice centres, widths and query radii (S,) covering [t0, t1] (see the module docstring, step 2)."""
    length = t1 - t0
    b = motion.breaks_s
    overlap = (b[:, :-1] <= t1) & (b[:, 1:] >= t0)
    v_w = float(np.max(bounds.max(axis=2), where=overlap, initial=0.0))
    if length <= 0 or v_w * length <= 0:
        return np.array([0.5 * (t0 + t1)]), np.array([max(length, 0.0)]), np.array([radius_m])
    cells = int(min(_MAX_CELLS, max(1, math.ceil(_CELLS_PER_SLICE * v_w * length / radius_m))))
    cell_s = length / cells
    env = np.empty(cells)
    _poly.envelope_cells(b, bounds, t0, cell_s, cells, env)
    centres, widths, radii = [], [], []
    s = 0
    while s < cells:
        vmax, e = env[s], s + 1
        while e < cells and max(vmax, env[e]) * (e + 1 - s) * cell_s <= radius_m:
            vmax = max(vmax, env[e])
            e += 1
        h = (e - s) * cell_s
        centres.append(t0 + (s + e) * 0.5 * cell_s)
        widths.append(h)
        radii.append(radius_m + vmax * h)
        s = e
    return np.array(centres), np.array(widths), np.array(radii)


def window_close_pairs(
    motion: Trajectories, t0_s: float, t1_s: float, radius_m: float, *, bounds: np.ndarray | None = None,
    method: str = "sweep",
) -> ClosePairs:
    """Every pair whose exact minimum distance during [t0_s, t1_s] is <= ``radius_m``, with where it occurs.

    Args:
        motion: the per-drone trajectories.
        t0_s, t1_s: the time window, seconds.
        radius_m: search radius, metres (> 0).
        bounds: :func:`speed_bounds` of ``motion`` (computed if not given).
        method: ``"sweep"`` (swept balls on a numba grid, :mod:`sim.verify._sweep`) or
            ``"kdtree"`` (a k-d tree per time slice, step 2 of the module docstring; the reference).

    Returns:
        The pairs (i < j), their exact minimum distance (m) and its time (s).
    """
    n = motion.drone_count
    empty = ClosePairs(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0))
    if n < 2:
        return empty
    if bounds is None:
        bounds = speed_bounds(motion)
    if method == "sweep":
        sa, sb = _sweep.window_slices(motion.breaks_s, bounds, float(t0_s), float(t1_s), radius_m)
        i, j, first, last = _sweep.slice_candidates(motion.breaks_s, motion.coeffs_m, bounds, sa, sb, radius_m)
        lo, hi = sa[first], sb[last]
    elif method == "kdtree":
        i, j = _kdtree_candidates(motion, t0_s, t1_s, radius_m, bounds)
        lo, hi = np.full(len(i), float(t0_s)), np.full(len(i), float(t1_s))
    else:
        raise ValueError(f"unknown candidate search {method!r}")
    m = len(i)
    if m == 0:
        return empty
    d2 = np.empty(m)
    tm = np.empty(m)
    _poly.pair_minima(i, j, lo, hi, np.full(m, radius_m**2), motion.breaks_s, motion.coeffs_m, _poly.W, d2, tm)
    keep = d2 <= radius_m**2
    return ClosePairs(i[keep], j[keep], np.sqrt(np.maximum(d2[keep], 0.0)), tm[keep])


def _kdtree_candidates(motion: Trajectories, t0_s: float, t1_s: float, radius_m: float, bounds: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Candidate pairs from a k-d tree at each slice centre (step 2 of the module docstring)."""
    n = motion.drone_count
    centres, _, radii = _slices(motion, bounds, t0_s, t1_s, radius_m)
    keys: list[np.ndarray] = []
    step = max(1, _EVAL_BUDGET // n)
    for a in range(0, len(centres), step):
        pos = motion.evaluate(centres[a:a + step], derivatives=0).positions_m
        for s in range(len(pos)):
            tree = cKDTree(pos[s], balanced_tree=False, compact_nodes=False)  # faster to build, as exact
            pairs = tree.query_pairs(float(radii[a + s]), output_type="ndarray")
            if len(pairs):
                keys.append(pairs[:, 0].astype(np.int64) * n + pairs[:, 1])
        if len(keys) > 64:
            keys = [np.unique(np.concatenate(keys))]
    if not keys:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    k = np.unique(np.concatenate(keys))
    return k // n, k % n


def _closest_pair_distance(points: np.ndarray) -> float:
    if len(points) < 2:
        return math.inf
    d, _ = cKDTree(points).query(points, k=2)
    return float(d[:, 1].min())


def _get(rec: Any, name: str, default: Any) -> Any:
    """A field of a planner record that may be an object or a mapping."""
    if isinstance(rec, dict):
        return rec.get(name, default)
    return getattr(rec, name, default)


def _stagger(tr: Any) -> float:
    s = _get(tr, "stagger_s", None)
    if s is not None:
        return float(s)
    return 0.0


def _limit_violations(
    plan: ShowPlan, ext: PieceExtrema, ground_m: float
) -> tuple[list[Violation], dict[str, float]]:
    """Speed / acceleration / altitude violations, one per (segment, kind), and the peaks."""
    s = plan.settings
    n, p = ext.speed_xy_mps.shape
    drone = np.broadcast_to(np.arange(n)[:, None], (n, p)).ravel()
    out: list[Violation] = []
    peaks: dict[str, float] = {}
    checks = (
        ("speed_xy", ext.speed_xy_mps, ext.speed_xy_t, s.max_speed_xy_mps, 1.0, "m/s", "exceed"),
        ("speed_z", ext.speed_z_mps, ext.speed_z_t, s.max_speed_z_mps, 1.0, "m/s", "exceed"),
        ("acceleration", ext.accel_mps2, ext.accel_t, s.max_accel_mps2, 1.0, "m/s²", "exceed"),
        ("altitude", ext.z_max_m, ext.z_max_t, s.max_altitude_m, 1.0, "m", "rise above"),
        ("altitude", ext.z_min_m, ext.z_min_t, ground_m, -1.0, "m", "sink below"),
    )
    for kind, values, times, limit, sense, unit, verb in checks:
        vals = values.ravel() * sense  # "larger is worse" in both senses
        lim = limit * sense
        key = "min_altitude_m" if sense < 0 else {"altitude": "max_altitude_m"}.get(kind, f"max_{kind}")
        peaks[key] = float(vals.max() * sense) if len(vals) else 0.0
        over = np.flatnonzero(vals > lim + abs(limit) * _TOL + (1e-9 if sense < 0 else 0.0))
        if not len(over):
            continue
        seg = plan.segment_index(times.ravel()[over])
        order = np.lexsort((-vals[over], seg))
        over, seg = over[order], seg[order]
        for k in np.unique(seg):
            rows = over[seg == k]  # worst first within the segment
            _, first = np.unique(drone[rows], return_index=True)
            worst = rows[np.sort(first)]
            top = worst[0]
            d0, t_v, value = int(drone[top]), float(times.ravel()[top]), float(vals[top] * sense)
            sg = plan.segments[int(k)]
            names = [int(drone[q]) for q in worst[:MAX_DRONES_PER_VIOLATION]]
            out.append(Violation(
                kind=kind, drones=names, time_s=t_v, value=value, limit=limit, segment=int(k),
                message=f"{len(worst)} drone(s) {verb} {kind} {limit} {unit} in {sg.kind} {sg.label!r}: "
                f"drone {d0} reaches {value:.3f} {unit} at t = {t_v:.2f} s",
            ))
    return out, peaks


#: Drones from which :func:`check_plan` searches the segments on threads.
PARALLEL_MIN_DRONES = 200


def _threads_ok(n: int) -> bool:
    """Segments on threads: enough drones, and numba's threading layer safe for concurrent parallel kernels
    (OpenMP or TBB; the fallback work queue is not)."""
    if n < PARALLEL_MIN_DRONES or workers() < 2:
        return False
    try:
        return numba.threading_layer() in ("omp", "tbb")
    except ValueError:  # no parallel kernel has run yet
        return False


def check_plan(plan: ShowPlan, *, progress: Callable[[float], None] | None = None,
               candidates: str = "sweep") -> CheckReport:
    """Verify a plan exactly against its show's limits.

    Args:
        plan: the planned show.
        progress: optional callback receiving the fraction done in [0, 1].
        candidates: the pair candidate search of :func:`window_close_pairs` (``"sweep"`` or the
            reference ``"kdtree"``; both exact, benchmarks compare them).
    """
    s = plan.settings
    limit_d = s.min_distance_m
    motion = plan.motion
    P = plan.knot_positions_m
    violations: list[Violation] = []

    ground = min(0.0, float(P[0][:, 2].min()))
    ext = piece_extrema(motion, (s.max_speed_xy_mps, s.max_speed_z_mps, s.max_accel_mps2, s.max_altitude_m, ground))
    bounds = speed_bounds(motion)
    limit_v, peaks = _limit_violations(plan, ext, ground)
    violations += limit_v
    if progress:
        progress(0.05)

    best = (math.inf, (0, 0), 0.0)
    seg_min: dict[int, tuple[float, tuple[int, int], float]] = {}
    closest = [_closest_pair_distance(P[0])]
    radii = []
    for k, seg in enumerate(plan.segments):
        moving = not np.array_equal(P[k], P[k + 1]) or seg.kind != "hold"
        closest.append(_closest_pair_distance(P[k + 1]) if moving else closest[-1])
        upper = min(closest[-2], closest[-1])
        # (a hair over, so that the pair at a boundary's exact closest distance survives rounding)
        radii.append((max(limit_d, upper) if math.isfinite(upper) else limit_d) * (1 + 1e-9))

    def search(k: int) -> ClosePairs:
        seg = plan.segments[k]
        return window_close_pairs(motion, seg.start_s, seg.end_s, radii[k], bounds=bounds, method=candidates)

    # The segments' searches are independent: on threads when the kernels may run concurrently (results are
    # consumed in segment order, so the report does not depend on which thread finishes first).
    searches = (pool().map(search, range(len(plan.segments))) if _threads_ok(motion.drone_count)
                else map(search, range(len(plan.segments))))
    for k, (seg, pairs) in enumerate(zip(plan.segments, searches, strict=True)):
        span = airborne_span(plan, seg)
        if span is not None and len(pairs.dist_m):
            # Launch boxes: a pair of one box keeps its distance only while both fly (sim.verify._parked).
            d_r, t_r = restrict(motion, span, pairs.i, pairs.j, pairs.dist_m, pairs.time_s, radii[k])
            keep = d_r <= radii[k]
            pairs = ClosePairs(pairs.i[keep], pairs.j[keep], d_r[keep], t_r[keep])
        if len(pairs.dist_m):
            m = int(np.argmin(pairs.dist_m))
            seg_min[k] = (float(pairs.dist_m[m]), (int(pairs.i[m]), int(pairs.j[m])), float(pairs.time_s[m]))
            if seg_min[k][0] < best[0]:
                best = seg_min[k]
            bad = np.flatnonzero(pairs.dist_m < limit_d * (1 - _TOL))
            bad = bad[np.argsort(pairs.dist_m[bad], kind="stable")]
            for q in bad:
                i, j, d, t_q = int(pairs.i[q]), int(pairs.j[q]), float(pairs.dist_m[q]), float(pairs.time_s[q])
                violations.append(Violation(
                    kind="min_distance", drones=[i, j], time_s=t_q, value=d, limit=limit_d, segment=k,
                    message=f"drones {i} and {j} come {d:.3f} m apart at t = {t_q:.2f} s "
                    f"({seg.kind} {seg.label!r}); the minimum is {limit_d} m",
                ))
        if progress:
            progress(0.05 + 0.95 * (k + 1) / len(plan.segments))

    transitions = []
    for tr in plan.transitions:
        exact = seg_min.get(tr.segment, (math.inf,))[0]
        guaranteed = tr.guaranteed_separation_m
        transitions.append(TransitionReport(
            **{"from": tr.from_name},
            to=tr.to_name, segment=tr.segment, start_s=tr.start_s, duration_s=tr.duration_s,
            min_duration_s=tr.min_duration_s, assignment_cost_m2=tr.assignment_cost_m2,
            stagger_s=_stagger(tr), resolution=str(_get(tr, "resolution", "") or ""),
            capt=CaptPremise(
                start_spacing_m=_inf_if_none(tr.start_spacing_m), goal_spacing_m=_inf_if_none(tr.goal_spacing_m),
                guaranteed_min_distance_m=_inf_if_none(guaranteed), exact_min_distance_m=_inf_if_none(exact),
                holds=bool(exact >= guaranteed - 1e-9),
            ),
        ))
        if tr.duration_s < tr.min_duration_s - 1e-9:
            violations.append(Violation(
                kind="transition_duration", drones=[], time_s=tr.start_s, value=tr.duration_s,
                limit=tr.min_duration_s, segment=tr.segment,
                message=f"transition {tr.from_name!r} -> {tr.to_name!r} lasts {tr.duration_s} s; "
                f"the limits need at least {tr.min_duration_s:.1f} s",
            ))

    # The altitude floor (outside takeoff and landing) and the geofence, exact per piece.
    violations.extend(check_bounds(plan, plan.settings))
    # Downwash during takeoff and landing: the same exact pair search in ellipsoid units.
    violations.extend(downwash_violations(plan, max_listed=1 << 62)[0])
    violations.sort(key=lambda v: (v.time_s, v.kind))
    groups = _by_transition(plan, violations, seg_min)
    min_d, pair, t_min = best
    return CheckReport(
        ok=not violations,
        show=plan.show_name,
        drones=plan.drone_count,
        duration_s=plan.duration_s,
        min_distance_m=float(min_d),  # +inf: fewer than two drones, no pair (null in JSON)
        min_distance_pair=list(pair) if math.isfinite(min_d) else [],
        min_distance_time_s=t_min,
        max_speed_xy_mps=peaks["max_speed_xy"],
        max_speed_z_mps=peaks["max_speed_z"],
        max_accel_mps2=peaks["max_acceleration"],
        max_altitude_m=peaks["max_altitude_m"],
        min_altitude_m=peaks["min_altitude_m"],
        limits={
            "min_distance_m": s.min_distance_m,
            "max_speed_xy_mps": s.max_speed_xy_mps,
            "max_speed_z_mps": s.max_speed_z_mps,
            "max_accel_mps2": s.max_accel_mps2,
            "max_altitude_m": s.max_altitude_m,
        },
        transitions=transitions,
        by_transition=groups,
        violations=violations[:MAX_LISTED_VIOLATIONS],
        violations_total=len(violations),
    )


def downwash_violations(plan: ShowPlan, *, max_listed: int = 200) -> tuple[list[Violation], int]:
    """Every pair inside each other's downwash ellipsoid during takeoff or landing (and, for drones
    landed mid-show, from their descent to their climb), exact (:mod:`sim.verify._downwash`).

    Returns:
        (violations: one per pair and segment, deepest first within a segment, at most
        ``max_listed``; the total count). ``value`` is the scaled distance (< 1 inside),
        ``limit`` 1.
    """
    r, c = plan.settings.downwash_axes_m
    motion = scaled_motion(plan.motion, r, c)
    # (start, end, segment, what, drones): takeoff and landing for every pair; drones landed mid-show
    # (issue 21, a subset formation's others) from their descent to their climb, pairs with one of them.
    windows: list[tuple[float, float, int, str, np.ndarray | None]] = [
        (s.start_s, s.end_s, s.index, s.kind, None) for s in plan.segments if s.kind in DOWNWASH_SEGMENTS]
    windows += [(g0, g1, -1, "a mid-show landing", g) for g0, g1, g in getattr(plan, "grounded", ())]
    if plan.drone_count < 2 or not windows:
        return [], 0
    bounds = speed_bounds(motion)
    out: list[Violation] = []
    total = 0
    clear_r = plan.launch.box_clearance_m if plan.launch is not None else 0.0
    clear_motion = scaled_motion(plan.motion, clear_r, c) if clear_r > 0 else None
    for w0, w1, index, what, down in windows:
        pairs = window_close_pairs(motion, w0, w1, 1.0, bounds=bounds)
        value = pairs.dist_m
        times = pairs.time_s
        rule = np.zeros(len(value), dtype=np.int64)  # 0: downwash, 1: clearance over a parked box mate
        span = airborne_span(plan, plan.segments[index]) if index >= 0 else None
        if span is not None and len(value):
            # Launch boxes: pairs with a parked drone follow sim.verify._parked.
            seg = plan.segments[index]
            value, times = restrict(motion, span, pairs.i, pairs.j, value, times, 1.0)
            if clear_motion is not None:
                cv, ct = clearance(clear_motion, span, seg, pairs.i, pairs.j)
                worse = cv < value
                value, times, rule = np.where(worse, cv, value), np.where(worse, ct, times), worse.astype(np.int64)
        inside = value < 1.0 - _TOL
        if down is not None:
            inside &= np.isin(pairs.i, down) | np.isin(pairs.j, down)
        bad = np.flatnonzero(inside)
        total += len(bad)
        bad = bad[np.argsort(value[bad], kind="stable")]
        for q in bad[: max(0, max_listed - len(out))]:
            i, j, t = int(pairs.i[q]), int(pairs.j[q]), float(times[q])
            p = plan.motion.evaluate([t], derivatives=0).positions_m[0]
            upper, lower = (i, j) if p[i, 2] >= p[j, 2] else (j, i)
            dz = float(p[upper, 2] - p[lower, 2])
            dxy = float(np.hypot(*(p[upper, :2] - p[lower, :2])))
            who = (f"drone {lower} is in drone {upper}'s downwash" if not rule[q] else
                   f"drone {upper} passes over its parked box mate {lower} (clearance {clear_r:g} m)")
            out.append(Violation(
                kind="downwash", drones=[upper, lower], time_s=t, value=float(value[q]), limit=1.0,
                segment=index if index >= 0 else int(plan.segment_index(t)),
                message=f"{who} during {what} at t = {t:.2f} s: "
                f"{dz:.2f} m below it and {dxy:.2f} m to the side (ellipsoid {r:g} m wide, {c:g} m high)",
            ))
    return out, total



def _worst_first(v: Violation) -> tuple[int, float, float]:
    """Distance violations first, smallest distance first; then the others by how far over the limit."""
    if v.kind == "min_distance":
        return (0, v.value, v.time_s)
    over = abs(v.value - v.limit) / max(abs(v.limit), 1e-9)
    return (1, -over, v.time_s)


def _by_transition(plan: ShowPlan, violations: list[Violation],
                   seg_min: dict[int, tuple[float, tuple[int, int], float]]) -> list[TransitionCheck]:
    """One :class:`TransitionCheck` per segment that moves (and per hold with a violation), in show order."""
    s = plan.settings
    per_seg: dict[int, list[Violation]] = {}
    for v in violations:
        per_seg.setdefault(v.segment, []).append(v)
    info = {tr.segment: tr for tr in plan.transitions}
    segs = plan.segments
    out: list[TransitionCheck] = []
    holds_before = 0
    for k, seg in enumerate(segs):
        vs = sorted(per_seg.get(k, []), key=_worst_first)
        if seg.kind == "hold":
            formation = holds_before
            holds_before += 1
            if not vs:
                continue
        else:
            nxt = segs[k + 1] if k + 1 < len(segs) else None
            formation = holds_before if (seg.kind == "transition" and nxt is not None and nxt.kind == "hold") else -1
        tr = info.get(k)
        if tr is not None:
            src, dst = tr.from_name, tr.to_name
        elif seg.kind == "takeoff":
            src, dst = "home", "takeoff"
        elif seg.kind == "landing":
            src, dst = "landing", "home"
        else:
            src = dst = seg.label
        unresolved = [
            FixHint(drones=[int(d) for d in _get(u, "drones", ())], time_s=float(_get(u, "time_s", seg.start_s)),
                    reason=str(_get(u, "reason", "")), fix=str(_get(u, "fix", "")))
            for u in (_get(tr, "unresolved", ()) if tr is not None else ())
        ]
        resolution = str(_get(tr, "resolution", "") or "") if tr is not None else ""
        dmin = seg_min.get(k)
        out.append(TransitionCheck(
            segment=k, kind=seg.kind, **{"from": src}, to=dst, formation=formation, start_s=seg.start_s,
            duration_s=seg.duration_s, stagger_s=_stagger(tr) if tr is not None else 0.0, resolution=resolution,
            ok=not vs, min_distance_m=float(dmin[0]) if dmin else math.inf,
            min_distance_pair=list(dmin[1]) if dmin and math.isfinite(dmin[0]) else [],
            min_distance_time_s=dmin[2] if dmin else seg.start_s,
            violations_total=len(vs), violations=vs[:MAX_LISTED_PER_TRANSITION], unresolved=unresolved,
            fixes=_fixes(seg.kind, formation, src, dst, vs, tr, unresolved, s.min_distance_m),
            waves=_waves(plan, seg.kind),
        ))
    return out


def _waves(plan: ShowPlan, kind: str) -> int:
    """Number of takeoff / landing waves of the plan (0: everybody at once, or not such a segment)."""
    launch = plan.launch
    w = None if launch is None else launch.takeoff if kind == "takeoff" else launch.landing if kind == "landing" \
        else None
    return 0 if w is None else int(w.count)


def _fixes(kind: str, formation: int, src: str, dst: str, vs: list[Violation], tr: Any,
           unresolved: list[FixHint], limit_m: float) -> list[str]:
    """What would remove these violations: the planner's own fixes first, then ones that provably work.

    Only changes that change the outcome are named: a longer transition does not move
    CAPT's straight lines apart (the geometry is the same at any duration), so it is
    offered for speed, acceleration and duration violations only.
    """
    fixes: list[str] = []
    for u in unresolved:
        if u.fix and u.fix not in fixes:
            fixes.append(u.fix)
    kinds = {v.kind for v in vs}
    # A duration the designer forced (the planner would have chosen min_duration_s): freeing it
    # lets the planner fit the limits again.
    forced = tr is not None and abs(tr.duration_s - tr.min_duration_s) > 1e-9
    too_fast = "transition_duration" in kinds or (forced and kinds & {"speed_xy", "speed_z", "acceleration"})
    if too_fast and formation >= 0:
        fixes.append(f"let the planner choose the duration of the transition into {dst!r} "
                     f"(remove formations[{formation}].transition_s)")
    if "downwash" in kinds:
        w = max((v for v in vs if v.kind == "downwash"), key=lambda v: -v.value)
        fixes.append(f"space the home positions wider (drone {w.drones[1]} is in drone {w.drones[0]}'s downwash): "
                     f"at least the downwash radius (settings.downwash_radius_m) apart")
    if "min_distance" in kinds and not unresolved:
        if kind == "hold":
            fixes.append(f"repair the spacing of formation {dst!r}: points closer than {limit_m} m "
                         "(if it moves during its hold: keep its motion's scale up)")
        elif kind in ("takeoff", "landing"):
            fixes.append(f"space the home positions at least {limit_m} m apart")
        else:
            # CAPT's guarantee (Turpin et al. 2014): min(start, goal spacing)/√2. It holds whatever
            # timing the planner chose, since with that spacing synchronised lines are already safe.
            a = "the home grid" if src == "takeoff" else f"formation {src!r}"
            b = "the home grid" if dst == "landing" else f"formation {dst!r}"
            fixes.append(f"space the points of {a} and {b} at least {limit_m * math.sqrt(2):.2f} m apart "
                         f"(synchronised straight lines keep only spacing/√2)")
    return fixes


def _inf_if_none(x: float) -> float:
    """A distance over no pair: +inf (NaN or a negative 'none' from older plans too); null in the JSON."""
    x = float(x)
    return x if x >= 0 else math.inf


def check_show(show: ShowFile, *, progress: Callable[[float], None] | None = None) -> CheckReport:
    """Plan ``show`` (forced durations flown as asked) and verify it exactly.

    Args:
        show: a validated :class:`formations.ShowFile`.
        progress: optional callback receiving the fraction done in [0, 1]
            (planning is the first half, verification the second).
    """
    from sim.plan._plan import plan_show

    half = (lambda f: progress(0.5 * f)) if progress else None
    plan = plan_show(show, enforce_limits=False, progress=half)
    return check_plan(plan, progress=(lambda f: progress(0.5 + 0.5 * f)) if progress else None)
