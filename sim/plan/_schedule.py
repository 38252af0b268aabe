"""Per-drone timing of one transition, safe by construction (prioritised delay scheduling).

Input: every drone's straight leg A_i -> B_i from CAPT's optimal assignment (spec eq. 11)
and the limits. Output: each drone's departure, profile and arrival, such that every pair
provably keeps ``required_m`` (certified by :mod:`sim.plan._pairs`), or a list of what
could not be made safe.

Reasoning (why this order of means):

1. **Synchronised first.** All drones share one normalised profile β over the minimum time
   of the slowest drone (normalised limits V = min_i v_i/L_i, A = a/max L_i, J = j/max L_i,
   so no drone exceeds its limits). CAPT's guarantee (Turpin, Michael & Kumar 2014)
   holds for *any* shared monotone β: pairs stay >= min(start, goal spacing)/√2. With
   formations drawn at Δ this is Δ/√2, so some pairs may come closer; for those pairs the
   check is exact (one shared s, closed form).
2. **Prioritised delays** (Gravell & Summers 2021, "Centralized collision-free polynomial
   trajectories and goal assignment for aerial swarms"; the prioritised scheduling of
   arXiv 2512.19914). Drones are placed one by one; each takes the smallest departure
   delay from a grid (``DELAY_STEP_S``) at which it keeps the distance from every drone
   placed before it, over the whole window including their rest before departure and after
   arrival. Earlier drones never move again, so every pair is certified once, when its
   second drone is placed. A delayed drone flies its *own* minimum-time profile, slowed
   (time-scaled) to arrive with the synchronised ones when its slack allows: delays then
   cost no show time.
3. **Precedence order.** Delays only push drones later, so order matters: if i's path
   passes within Δ of j's goal, i must pass before j parks there (i placed first); if it
   passes within Δ of j's start, j must leave first (j placed first). Kahn's topological
   order over these edges, ready drones by longest own move first (long movers keep the
   window short; short movers have slack to wait); a cycle is broken at the drone with the
   fewest unplaced predecessors.
4. A drone that no timing makes safe (a cycle, a path through a parked drone) is reported in
   ``unresolved`` with the drone it meets, when, why and a fix, and flown synchronised (never
   silently: the plan says it is unsafe). Drones that found no timing move to the front of the
   order for another round (priority adaptation, a few rounds).
5. **Spreading** (:func:`plan_transition`, :func:`spread`). On formations drawn at exactly Δ
   nearly every drone conflicts under CAPT (measured: all 100 drones of a grid -> filled disc),
   and delays cannot help neighbours that converge on each other's start. Then both formations
   are spread apart so that CAPT between the spread sets keeps Δ (its guarantee needs both
   >= √2·Δ apart; the exact check accepts smaller factors when they suffice), and the drones
   contract into the goal. Each of the three legs is synchronised and provably safe: spreading
   and contracting only ever increase / decrease every distance monotonically towards values
   >= Δ, the middle leg is checked exactly (or given per-drone delays when few drones conflict).
   Flat formations split into layers along their normal (short, fast horizontal moves for
   vertical shapes), 3-D ones scale.
6. **Blending** (:mod:`sim.plan._blend`). Stopping between the three legs costs about two
   spread-leg times per transition (measured: ~2 s each against per-transition bounds of
   3-11 s on the 100-drone dense show). The legs are also tried flown with a share of the
   acceleration and jerk limits (:data:`BLEND_SHARES`), each starting before the previous one
   ends by the longest overlap whose limits and separation are certified; kept when shorter.

Considered and not used by default: min-max (bottleneck) assignment (MacAlpine, Price &
Stone, SCRAM, AAAI 2015) shortens the longest leg but gives up CAPT's Σd² optimality,
whose sub-assignments keep paths from crossing; since the window is set by the slowest
drone's minimum time under per-axis limits, the bottleneck gain on dense shows is small
(see ``benchmarks/bench_dense.py``'s lower bound, which is the bottleneck assignment).
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numba
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from sim.plan._threads import pool

if TYPE_CHECKING:
    from sim.plan._assignment import Assignment
from sim.plan._pairs import close_path_pairs, pair_conflict, point_seg_dists
from sim.plan._timelaw import (
    Profiles,
    double_s_phases,
    double_s_profiles,
    double_s_stretched,
    path_speed_limit,
    quintic_leg_duration,
    quintic_profiles,
)

#: Departure delays are multiples of this, seconds.
DELAY_STEP_S = 0.2
#: Rounds of priority adaptation before the remaining conflicts are reported.
PRIORITY_ROUNDS = 3
#: Candidate timings tried per drone before it is reported unresolved.
MAX_TRIALS = 400
#: Per-drone delays are tried when at most this many drones (or this fraction) conflict when synchronised.
DELAYS_MAX_DRONES = 20
DELAYS_MAX_FRACTION = 0.05
#: Certified separation is required down to min_distance_m·(1 - this): rounding only, half the
#: verifier's relative tolerance (1e-9), so points drawn exactly at min_distance_m pass both.
SEPARATION_SLACK = 5e-10


def required_distance(min_distance_m: float) -> float:
    """The separation the planner certifies, metres."""
    return min_distance_m * (1.0 - SEPARATION_SLACK)
#: Window durations are rounded up to this step, seconds.
WINDOW_STEP_S = 0.1


@dataclass(frozen=True)
class Limits:
    """Scalar limits of one plan: speeds (m/s), acceleration (m/s²), jerk (m/s³), time law."""

    v_xy: float
    v_z: float
    a: float
    j: float
    law: str = "min_time"
    v_down: float | None = None


@dataclass(frozen=True)
class UnresolvedConflict:
    """What could not be made safe: the drones, when (s; local to the window inside the scheduler,
    show time once the plan places it), why, and what would fix it."""

    drones: tuple[int, ...]
    time_s: float
    reason: str
    fix: str


@dataclass(frozen=True)
class Schedule:
    """Per-drone timing of one transition (times local to the window start).

    ``profiles`` rows: 0 is the shared synchronised profile, 1 + i drone i's own
    minimum-time profile; drone i flies row ``prof_row[i]`` slowed by ``scale[i]``,
    departing at ``depart_s[i]`` and arriving at ``arrive_s[i]``.
    """

    a_m: np.ndarray
    b_m: np.ndarray
    depart_s: np.ndarray
    arrive_s: np.ndarray
    prof_row: np.ndarray
    scale: np.ndarray
    profiles: Profiles
    sync_s: float
    window_s: float
    unresolved: tuple[UnresolvedConflict, ...]

    @property
    def stagger_s(self) -> float:
        """Window length added beyond the synchronised minimum, seconds."""
        return max(0.0, self.window_s - self.sync_s)

    @property
    def resolution(self) -> str:
        """'none' (synchronised), 'delays' (some drones wait or fly their own profile), 'unresolved'."""
        if self.unresolved:
            return "unresolved"
        if np.any(self.prof_row != 0) or np.any(self.depart_s != 0):
            return "delays"
        return "none"

    def drone_profiles(self) -> Profiles:
        """(N, 8) breaks and (N, 7, 6) coefficients of each drone's profile, scaled, local to its departure."""
        rows = self.prof_row
        k = self.scale
        powers = k[:, None, None] ** -np.arange(self.profiles.coeffs.shape[-1])[None, None, :]
        return Profiles(self.profiles.breaks_s[rows] * k[:, None], self.profiles.coeffs[rows] * powers)


def round_up(t: float, step: float = WINDOW_STEP_S) -> float:
    """Round up to a multiple of ``step`` (at least one step)."""
    return round(max(1, int(np.ceil(t / step - 1e-9))) * step, 10)


def own_profiles(d_m: np.ndarray, lim: Limits) -> tuple[Profiles, np.ndarray]:
    """Each drone's own minimum-time profile of its leg d (N, 3) and (N,) peak |σ''| (1/s²)."""
    length = np.linalg.norm(d_m, axis=1)
    if lim.law == "quintic":
        dur = quintic_leg_duration(d_m, v_xy=lim.v_xy, v_z=lim.v_z, a=lim.a, v_down=lim.v_down)
        return quintic_profiles(dur), _quintic_peak(dur)
    v = path_speed_limit(d_m, lim.v_xy, lim.v_z, lim.v_down)
    ph = double_s_phases(length, v, lim.a, lim.j)
    peak = np.where(length > 0, ph.jerk * ph.tj / np.where(length > 0, length, 1.0), 0.0)
    return double_s_profiles(ph, length), peak


def _quintic_peak(dur: np.ndarray) -> np.ndarray:
    safe = np.where(dur > 0, dur, 1.0)
    return np.where(dur > 0, 10.0 / np.sqrt(3.0) / safe**2, 0.0)


def sync_min_duration(d_m: np.ndarray, lim: Limits) -> float:
    """Unrounded minimum duration of the shared profile β for legs d (N, 3), seconds."""
    length = np.linalg.norm(d_m, axis=1)
    moving = length > 0
    if not moving.any():
        return 0.0
    if lim.law == "quintic":
        return float(quintic_leg_duration(d_m[moving], v_xy=lim.v_xy, v_z=lim.v_z, a=lim.a,
                                          v_down=lim.v_down).max())
    v = path_speed_limit(d_m[moving], lim.v_xy, lim.v_z, lim.v_down)
    big = float(length.max())
    return float(double_s_phases(1.0, float((v / length[moving]).min()), lim.a / big, lim.j / big).duration_s)


def sync_profile(d_m: np.ndarray, lim: Limits, duration_s: float) -> tuple[Profiles, float]:
    """The shared normalised profile lasting ``duration_s`` and its peak |β''|."""
    length = np.linalg.norm(d_m, axis=1)
    moving = length > 0
    if lim.law == "quintic" or duration_s <= 0 or not moving.any():
        return quintic_profiles([duration_s]), float(_quintic_peak(np.array([duration_s]))[0])
    v = path_speed_limit(d_m[moving], lim.v_xy, lim.v_z, lim.v_down)
    big = float(length.max())
    vn, an, jn = float((v / length[moving]).min()), lim.a / big, lim.j / big
    fast = double_s_phases(1.0, vn, an, jn)
    if duration_s >= float(fast.duration_s):
        ph = double_s_stretched(np.array([1.0]), vn, an, jn, duration_s)
        prof = double_s_profiles(ph, np.array([1.0]))
        return prof, float(ph.jerk[0] * ph.tj[0])
    # Forced shorter than the limits allow (enforce_limits=False): the minimum-time shape, time-compressed.
    prof = double_s_profiles(double_s_phases(np.array([1.0]), vn, an, jn), np.array([1.0]))
    k = duration_s / float(fast.duration_s)
    powers = k ** -np.arange(prof.coeffs.shape[-1])
    return Profiles(prof.breaks_s * k, prof.coeffs * powers), float(jn * fast.tj / k**2)


def precedence_order(a_m: np.ndarray, b_m: np.ndarray, pairs: np.ndarray, own_s: np.ndarray,
                     radius_m: float) -> np.ndarray:
    """Placement order (see the module docstring, point 3)."""
    n = len(a_m)
    if len(pairs) == 0:
        return np.argsort(-own_s, kind="stable")
    i, j = pairs[:, 0], pairs[:, 1]
    # Edge u -> v: u placed before v.
    near_goal_ij = point_seg_dists(b_m, a_m, b_m, j, i) < radius_m  # i's path near j's goal: i first
    near_goal_ji = point_seg_dists(b_m, a_m, b_m, i, j) < radius_m  # j's path near i's goal: j first
    near_start_ij = point_seg_dists(a_m, a_m, b_m, j, i) < radius_m  # i's path near j's start: j first
    near_start_ji = point_seg_dists(a_m, a_m, b_m, i, j) < radius_m  # j's path near i's start: i first
    src = np.concatenate([i[near_goal_ij], j[near_goal_ji], j[near_start_ij], i[near_start_ji]])
    dst = np.concatenate([j[near_goal_ij], i[near_goal_ji], i[near_start_ij], j[near_start_ji]])
    keep = src != dst
    src, dst = src[keep], dst[keep]
    order_edges = np.argsort(src, kind="stable")
    src, dst = src[order_edges], dst[order_edges]
    starts = np.searchsorted(src, np.arange(n + 1))
    indeg = np.bincount(dst, minlength=n).astype(np.int64)
    placed = np.zeros(n, dtype=bool)
    ready = [(-float(own_s[k]), int(k)) for k in np.flatnonzero(indeg == 0)]
    heapq.heapify(ready)
    out: list[int] = []
    while len(out) < n:
        if ready:
            _, u = heapq.heappop(ready)
            if placed[u]:
                continue
        else:
            # A cycle: break it at the unplaced drone with the fewest unplaced predecessors (then longest move).
            key = np.where(placed, np.inf, indeg * 1e6 - own_s)
            u = int(np.argmin(key))
        placed[u] = True
        out.append(u)
        for v in dst[starts[u]:starts[u + 1]]:
            indeg[v] -= 1
            if indeg[v] == 0 and not placed[v]:
                heapq.heappush(ready, (-float(own_s[v]), int(v)))
    return np.array(out, dtype=np.int64)


_F = NDArray[np.float64]
_I = NDArray[np.int64]


@numba.njit(cache=True)
def _try(i: int, indptr: _I, nbrs: _I, placed: NDArray[np.bool_], a_m: _F, d_m: _F, breaks: _F, coeffs: _F,
         row: _I, dep: _F, scale: _F, arr: _F, peak_s2: _F, length: _F, required_m: float, hint: int,
         ) -> tuple[int, float]:  # pragma: no cover - numba
    """(conflicting neighbour or -1, its time); checks the last conflicting neighbour first."""
    if hint >= 0:
        c, t = pair_conflict(i, hint, a_m, d_m, breaks, coeffs, row, dep, scale, arr, peak_s2, length, required_m)
        if c:
            return hint, t
    for q in range(indptr[i], indptr[i + 1]):
        j = nbrs[q]
        if not placed[j] or j == hint:
            continue
        c, t = pair_conflict(i, j, a_m, d_m, breaks, coeffs, row, dep, scale, arr, peak_s2, length, required_m)
        if c:
            return j, t
    return -1, 0.0


@numba.njit(cache=True)
def _place_all(order: _I, indptr: _I, nbrs: _I, a_m: _F, d_m: _F, breaks: _F, coeffs: _F, peak_s2: _F,
               length: _F, own_dur: _F, sync_s: float, step: float, max_extra: float, max_trials: int,
               required_m: float,
               ) -> tuple[_F, _I, _F, _F, NDArray[np.bool_], _I, _F]:  # pragma: no cover - numba
    """Place drones in ``order``; each takes the first safe (arrival, departure) candidate.

    Candidates, by increasing arrival: the synchronised profile (depart 0, arrive sync_s);
    its own minimum-time profile departing at 0 (arrives early); then for arrivals
    sync_s + m·step (m = 0..max_extra/step) every departure k·step with room for its
    own profile, slowed to arrive exactly then, and the latest departure (own minimum time).
    """
    n = len(order)
    dep = np.zeros(n)
    row = np.zeros(n, dtype=np.int64)
    scale = np.ones(n)
    arr = np.full(n, sync_s)
    placed = np.zeros(n, dtype=np.bool_)
    failed = np.zeros(n, dtype=np.bool_)
    fail_other = np.full(n, -1, dtype=np.int64)
    fail_time = np.zeros(n)
    m_max = int(max_extra / step + 1e-9)
    for idx in range(n):
        i = order[idx]
        # 1. synchronised.
        dep[i], row[i], scale[i], arr[i] = 0.0, 0, 1.0, sync_s
        hint, t_first = _try(i, indptr, nbrs, placed, a_m, d_m, breaks, coeffs, row, dep, scale, arr, peak_s2,
                             length, required_m, -1)
        ok = hint < 0
        if not ok:
            fail_other[i] = hint
            fail_time[i] = t_first
            # 2. own minimum time, departing at once.
            dep[i], row[i], scale[i], arr[i] = 0.0, 1 + i, 1.0, own_dur[i]
            hint, _ = _try(i, indptr, nbrs, placed, a_m, d_m, breaks, coeffs, row, dep, scale, arr, peak_s2,
                           length, required_m, hint)
            ok = hint < 0
        trials = 0
        m = 0
        while not ok and m <= m_max and trials < max_trials:
            a = sync_s + m * step
            k = 0
            while not ok and trials < max_trials:
                d = k * step
                last = d + own_dur[i] >= a - 1e-12
                if last:
                    d = a - own_dur[i]
                    if d < 0.0:
                        break
                dep[i], row[i], arr[i] = d, 1 + i, a
                scale[i] = (a - d) / own_dur[i] if own_dur[i] > 0.0 else 1.0
                trials += 1
                hint, _ = _try(i, indptr, nbrs, placed, a_m, d_m, breaks, coeffs, row, dep, scale, arr, peak_s2,
                               length, required_m, hint)
                ok = hint < 0
                if last:
                    break
                k += 1
            m += 1
        if not ok:
            failed[i] = True
            dep[i], row[i], scale[i], arr[i] = 0.0, 0, 1.0, sync_s
        placed[i] = True
    return dep, row, scale, arr, failed, fail_other, fail_time


def schedule_transition(a_m: np.ndarray, b_m: np.ndarray, lim: Limits, *, min_distance_m: float,
                        duration_s: float | None = None, max_delay_s: float | None = None,
                        label: str = "") -> Schedule:
    """Per-drone timing of the legs A (N, 3) -> B (N, 3), certified to keep ``min_distance_m``.

    Args:
        a_m, b_m: starts and assigned goals, metres.
        lim: the limits and time law.
        min_distance_m: Δ, metres.
        duration_s: the synchronised duration (>= the minimum; None: the rounded minimum).
        max_delay_s: latest arrival tried beyond the synchronised one (default: half of it + 5 s).
        label: transition name for the fixes suggested in ``unresolved``.
    """
    n = len(a_m)
    d_m = b_m - a_m
    length = np.linalg.norm(d_m, axis=1)
    sync_s = round_up(sync_min_duration(d_m, lim)) if duration_s is None else float(duration_s)
    shared, shared_peak = sync_profile(d_m, lim, sync_s)
    own, own_peak = own_profiles(d_m, lim)
    breaks = np.concatenate([shared.breaks_s, own.breaks_s])
    coeffs = np.concatenate([shared.coeffs, own.coeffs])
    peak = np.concatenate([[shared_peak], own_peak])
    required = required_distance(min_distance_m)
    pairs = close_path_pairs(a_m, b_m, required) if n > 1 else np.zeros((0, 2), dtype=np.int64)
    own_dur = own.breaks_s[:, -1].copy()
    order = precedence_order(a_m, b_m, pairs, own_dur, required)
    # CSR neighbour lists (both directions).
    src = np.concatenate([pairs[:, 0], pairs[:, 1]])
    dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
    o = np.argsort(src, kind="stable")
    nbrs = dst[o].astype(np.int64)
    indptr = np.searchsorted(src[o], np.arange(n + 1)).astype(np.int64)
    max_delay = 0.5 * sync_s + 5.0 if max_delay_s is None else max_delay_s
    # Priority adaptation (Bennewitz, Burgard & Thrun 2002, "Finding and optimizing solvable priority
    # schemes for decoupled path planning"): drones that found no safe timing move to the front of the
    # order and the placement is repeated, a bounded number of rounds.
    best = None
    for _ in range(PRIORITY_ROUNDS):
        dep, row, scale, arr, failed, fail_other, fail_time = _place_all(
            order, indptr, nbrs, a_m, d_m, breaks, coeffs, peak, length, own_dur, sync_s, DELAY_STEP_S,
            max_delay, MAX_TRIALS, required,
        )
        n_failed = int(failed.sum())
        if best is None or n_failed < best[0] or (n_failed == best[0] and arr.max() < best[1][3].max()):
            best = (n_failed, (dep, row, scale, arr, failed, fail_other, fail_time))
        if n_failed == 0:
            break
        first = failed[order]
        order = np.concatenate([order[first], order[~first]])
    assert best is not None
    dep, row, scale, arr, failed, fail_other, fail_time = best[1]
    window = round_up(max(sync_s, float(arr.max()) if n else 0.0))
    unresolved = tuple(
        UnresolvedConflict(
            drones=(int(i), int(fail_other[i])) if fail_other[i] >= 0 else (int(i),),
            time_s=float(fail_time[i]),
            reason=f"drone {int(i)} cannot keep {min_distance_m:g} m from drone {int(fail_other[i])} by waiting "
            f"or arriving up to {max_delay:.0f} s later: their paths cross a parked or waiting position",
            fix=f"space the formations of {label or 'this transition'} wider (>= {min_distance_m * np.sqrt(2):.2f} m "
            f"makes CAPT's straight lines safe) or move the points the two drones meet at",
        )
        for i in np.flatnonzero(failed)
    )
    return Schedule(
        a_m=a_m, b_m=b_m, depart_s=dep, arrive_s=arr, prof_row=row, scale=scale, profiles=Profiles(breaks, coeffs),
        sync_s=sync_s, window_s=window, unresolved=unresolved,
    )


#: Drones x slices from which :func:`sync_conflicts` searches its slices on several threads.
PARALLEL_MIN_WORK = 20_000


def sync_conflicts(a_m: np.ndarray, b_m: np.ndarray, required_m: float) -> np.ndarray:
    """(K, 2) pairs i < j that come closer than ``required_m`` when all drones share one profile (exact).

    With one shared s the offset of a pair is a + s·c (a = A_j - A_i, c = D_j - D_i) and its
    minimum over s in [0, 1] is closed form. Candidates come from k-d trees in s-slices, as in
    the verifier: after subtracting the mean motion (which changes no distance) each drone moves
    at most L_max·h/2 from its position at the centre of a slice of width h, so a pair within r
    somewhere in the slice is within r + L_max·h at the centre; with h = 1/ceil(L_max/r) the
    query radius is at most 2r.
    """
    n = len(a_m)
    empty = np.zeros((0, 2), dtype=np.int64)
    if n < 2:
        return empty
    motion = b_m - a_m
    motion = motion - motion.mean(axis=0)
    l_max = float(np.sqrt((motion**2).sum(axis=1).max()))
    slices = max(1, int(np.ceil(l_max / required_m))) if l_max > 1e-12 else 1
    h = 1.0 / slices
    radius = required_m + l_max * h

    def slice_keys(k: int) -> np.ndarray:
        centre = a_m + ((k + 0.5) * h) * motion
        pairs = cKDTree(centre).query_pairs(radius, output_type="ndarray")
        lo, hi = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
        out: np.ndarray = lo.astype(np.int64) * n + hi
        return out

    # The slices are independent and the k-d tree releases the GIL: both cores (the keys are sorted by
    # np.unique below, so the result does not depend on the order the threads finish in).
    if slices > 1 and n * slices >= PARALLEL_MIN_WORK:
        found = [f for f in pool().map(slice_keys, range(slices)) if len(f)]
    else:
        found = [f for f in map(slice_keys, range(slices)) if len(f)]
    if not found:
        return empty
    keys = np.unique(np.concatenate(found))
    i, j = keys // n, keys % n
    a = a_m[j] - a_m[i]
    c = motion[j] - motion[i]
    cc = (c * c).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(cc > 0, np.clip(-(a * c).sum(axis=1) / cc, 0.0, 1.0), 0.0)
    dist = np.linalg.norm(a + s[:, None] * c, axis=1)
    bad = dist < required_m
    return np.stack([i[bad], j[bad]], axis=1)


@dataclass(frozen=True)
class TransitionPlan:
    """How one transition is flown: consecutive legs (each a :class:`Schedule`) and the final assignment.

    ``resolution``: "none" (CAPT's synchronised straight lines are safe), "delays" (per-drone
    departures and profiles), "layers" (expand the start formation, CAPT between the expanded
    formations, contract into the goal) or "unresolved".
    """

    legs: tuple[Schedule, ...]
    goal_index: np.ndarray
    resolution: str
    sync_s: float
    expansion: float = 1.0
    #: Per junction between consecutive legs, how long the next leg starts before the previous ends
    #: (:mod:`sim.plan._blend`), seconds; empty: none.
    overlaps_s: tuple[float, ...] = ()

    @property
    def window_s(self) -> float:
        return float(sum(leg.window_s for leg in self.legs) - sum(self.overlaps_s))

    def leg_offsets_s(self) -> list[float]:
        """Start of each leg within the window, seconds."""
        out = [0.0]
        for k, leg in enumerate(self.legs[:-1]):
            out.append(out[-1] + leg.window_s - (self.overlaps_s[k] if self.overlaps_s else 0.0))
        return out

    @property
    def stagger_s(self) -> float:
        """Window length added beyond the synchronised single-leg minimum, seconds."""
        return max(0.0, self.window_s - self.sync_s)

    @property
    def unresolved(self) -> tuple[UnresolvedConflict, ...]:
        out: list[UnresolvedConflict] = []
        for t0, leg in zip(self.leg_offsets_s(), self.legs, strict=True):
            out += [UnresolvedConflict(u.drones, t0 + u.time_s, u.reason, u.fix) for u in leg.unresolved]
        return tuple(out)

    @property
    def depart_s(self) -> np.ndarray:
        """(N,) departure from the start (window-local), seconds."""
        return self.legs[0].depart_s

    @property
    def arrive_s(self) -> np.ndarray:
        """(N,) arrival at the goal (window-local), seconds."""
        return self.window_s - self.legs[-1].window_s + self.legs[-1].arrive_s


#: Shares of the acceleration and jerk limits with which blended legs are tried (:mod:`sim.plan._blend`).
BLEND_SHARES = ((0.7, 0.7), (0.5, 0.5), (0.5, 0.7))
#: Expansion factors tried by the "layers" fallback (√2 makes CAPT's guarantee reach Δ).
EXPANSIONS = (1.28, float(np.sqrt(2.0)))


def _greedy_colours(points: np.ndarray, radius_m: float) -> np.ndarray:
    """(n,) colours such that points closer than ``radius_m`` differ (DSatur, :func:`_dsatur`)."""
    from scipy.spatial import cKDTree

    n = len(points)
    pairs = cKDTree(points).query_pairs(radius_m, output_type="ndarray").astype(np.int64)
    src = np.concatenate([pairs[:, 0], pairs[:, 1]])
    dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
    o = np.argsort(src, kind="stable")
    nbrs, starts = dst[o].astype(np.int64), np.searchsorted(src[o], np.arange(n + 1)).astype(np.int64)
    return np.asarray(_dsatur(starts, nbrs, n), dtype=np.int64)


@numba.njit(cache=True)
def _dsatur(starts: _I, nbrs: _I, n: int) -> _I:  # pragma: no cover - numba
    """Brélaz's DSatur colouring (Brélaz 1979, "New methods to color the vertices of a graph", CACM 22(4)):
    colour next the uncoloured vertex with the most distinct neighbour colours (ties: most neighbours,
    then lowest index), with the smallest colour its neighbours do not use. Fewer colours than plain
    greedy on lattices (3 instead of 4 on the hexagonal ones), so the layers of :func:`spread` are
    thinner and the spread legs shorter. O(n² + E·C)."""
    colour = np.full(n, -1, dtype=np.int64)
    sat = np.zeros(n, dtype=np.int64)
    deg = starts[1:] - starts[:-1]
    used = np.zeros(n + 1, dtype=np.bool_)
    for _ in range(n):
        best = -1
        for v in range(n):
            if colour[v] < 0 and (best < 0 or sat[v] > sat[best] or (sat[v] == sat[best] and deg[v] > deg[best])):
                best = v
        for q in range(starts[best], starts[best + 1]):
            c = colour[nbrs[q]]
            if c >= 0:
                used[c] = True
        c = 0
        while used[c]:
            c += 1
        colour[best] = c
        for q in range(starts[best], starts[best + 1]):
            cu = colour[nbrs[q]]
            if cu >= 0:
                used[cu] = False
        # Saturation of the uncoloured neighbours: count distinct colours around each.
        for q in range(starts[best], starts[best + 1]):
            u = nbrs[q]
            if colour[u] >= 0:
                continue
            seen = False
            for r in range(starts[u], starts[u + 1]):
                w = nbrs[r]
                if w != best and colour[w] == c:
                    seen = True
                    break
            if not seen:
                sat[u] += 1
    return colour


def spread(points: np.ndarray, k: float, min_distance_m: float, ceiling_m: float,
           similar: bool = False, floor_m: float = 0.0) -> np.ndarray | None:
    """The points moved apart so that every pair ends >= k·(its spacing) and no pair ever comes closer.

    Three ways, by the shape of the set (each moves all points along straight lines with one
    shared profile, and each pair's distance is nondecreasing along the way):

    * **flat and horizontal** (e.g. the lifted home grid): scaled by k about the centroid within
      its plane (a similarity of the set: every distance grows by the factor 1 + s(k - 1));
    * **flat and tilted/vertical** (text, walls, discs drawn in x-z): split into *layers*
      offset along the plane's normal n: points closer than k·Δ get different colours (DSatur,
      few colours so thin layers: 3 on hexagonal lattices, 2 on square ones),
      colour c moves by (c - (C-1)/2)·λΔ·n with λ = √(k² - 1). Offsets are along n and every
      in-plane offset d is ⟂ n, so |d + s·Δo·n|² = |d|² + s²Δo² grows, and pairs in different
      layers end >= Δ·√(1 + λ²) = kΔ apart while same-colour pairs already were >= kΔ apart (up to
      a relative 1e-9, so that lattice diagonals at exactly kΔ may share a layer; the middle leg is
      checked exactly in any case);
    * **3-D** (or ``similar``): scaled by k about (centroid x, centroid y, anchor z), the anchor as
      near the centroid's z as keeps the set within [min(floor, its lowest point), ceiling] (None if
      it cannot). About the centroid every point moves least vertically, which matters since the
      vertical speed limit is the tight one (2 m/s against 10 m/s by default). Scaling both sets
      of a transition by the same k keeps CAPT's assignment optimal when every goal is used (Σ|kx - kg|² = k²Σ|x - g|²
      up to a translation, which shifts every complete assignment's cost equally).
    """
    c = points.mean(axis=0)
    centred = points - c
    if len(points) >= 3:
        _, sv, vt = np.linalg.svd(centred, full_matrices=False)
        normal = vt[-1]
        flat = sv[-1] <= 1e-9 * max(float(sv[0]), 1.0)
    else:
        normal, flat = np.array([0.0, 0.0, 1.0]), True
    if flat and abs(normal[2]) > 0.9 and not similar:
        proj = centred - np.outer(centred @ normal, normal)
        return np.asarray(points + (k - 1.0) * proj, dtype=np.float64)
    if flat and not similar:
        lam = float(np.sqrt(max(k * k - 1.0, 0.0)))
        colour = _greedy_colours(points, k * min_distance_m * (1.0 - 1e-9))
        offset = (colour - 0.5 * colour.max()) * lam * min_distance_m
        out = points + offset[:, None] * normal[None, :]
        if out[:, 2].min() < 0 or out[:, 2].max() > ceiling_m:
            return None
        return np.asarray(out, dtype=np.float64)
    lo_z, hi_z = float(points[:, 2].min()), float(points[:, 2].max())
    # anchor a keeps lo' = a + k(lo - a) >= min(floor, lo) (never below 0) and hi' = a + k(hi - a) <= ceiling.
    bottom = max(min(floor_m, lo_z), 0.0)
    a_min = (k * hi_z - ceiling_m) / (k - 1.0)
    a_max = (k * lo_z - bottom) / (k - 1.0)
    if a_min > a_max + 1e-9:
        return None
    anchor = np.array([c[0], c[1], min(max(float(c[2]), a_min), a_max)])
    return np.asarray(anchor + k * (points - anchor), dtype=np.float64)


def plan_transition(a_m: np.ndarray, goals_m: np.ndarray, goal_index: np.ndarray, lim: Limits, *,
                    min_distance_m: float, ceiling_m: float, floor_m: float = 0.0, duration_s: float | None = None,
                    label: str = "", allow_layers: bool = True, fixed_assignment: bool = False,
                    warm: Assignment | None = None) -> TransitionPlan:
    """Fly starts A (N, 3) to ``goals_m[goal_index]`` safely, or report what is unsafe.

    In order: CAPT's synchronised straight lines if the exact pair check passes ("none");
    else the cheapest safe way among per-drone delays ("delays", tried when few drones
    conflict) and spreading the start and/or the goal formation apart (:func:`spread`) with
    CAPT between the spread sets ("layers": safe by CAPT's guarantee once both sets are
    >= √2·Δ apart, and often already at smaller factors, which the exact check decides);
    else the delays' result with its unresolved conflicts.

    Args:
        a_m: (N, 3) starts, metres.
        goals_m: (M, 3) all goal points; ``goal_index`` (N,) CAPT's assignment into them.
        lim: limits and time law.
        min_distance_m: Δ, metres.
        ceiling_m: highest altitude the spread formations may use, metres.
        floor_m: lowest altitude they may use (a formation already lower is not pushed lower), metres.
        duration_s: forced synchronised duration (None: the minimum). A forced duration is
            flown as one leg (the designer asked for that transition time).
        label: transition name for messages.
        allow_layers: try spreading when the synchronised lines conflict.
        fixed_assignment: the assignment must stay (e.g. landing on one's own home): no re-assignment.
        warm: the assignment that gave ``goal_index``, if at hand: its prices warm-start the re-assignments
            between the spread sets (same optimum, less work), each of which then warms the next.
    """
    from sim.plan._assignment import assign
    from sim.plan._blend import blend_overlaps

    b_m = goals_m[goal_index]
    n = len(a_m)
    required = required_distance(min_distance_m)
    sync_s = round_up(sync_min_duration(b_m - a_m, lim)) if duration_s is None else float(duration_s)
    conflicts = sync_conflicts(a_m, b_m, required)
    if len(conflicts) == 0:
        return TransitionPlan((synchronised(a_m, b_m, lim, sync_s),), goal_index, "none", sync_s)
    involved = len(np.unique(conflicts))
    direct = None
    few = involved <= max(DELAYS_MAX_DRONES, DELAYS_MAX_FRACTION * n)
    if duration_s is not None or not allow_layers or few or fixed_assignment:
        direct = schedule_transition(a_m, b_m, lim, min_distance_m=min_distance_m, duration_s=sync_s, label=label)
        if duration_s is not None or not allow_layers:
            return TransitionPlan((direct,), goal_index, direct.resolution, sync_s)
    best: TransitionPlan | None = None
    if direct is not None and not direct.unresolved:
        best = TransitionPlan((direct,), goal_index, "delays", sync_s)
    # Spread both formations (see :func:`spread`); the exact check decides which variant is safe.
    # Smallest factor first (shorter spread and contract legs): layers with CAPT's assignment as it is,
    # then re-assigned between the spread sets (one more assignment); a middle leg with few conflicting
    # drones gets per-drone delays (its waiting drones have k·Δ of room). The first variant whose middle
    # leg is safe synchronised ends the search; then similarities by √2 (CAPT's guarantee when all
    # goals are used). The shortest window found wins.
    root2 = float(np.sqrt(2.0))
    tries = [(k, False, r) for k in EXPANSIONS for r in (False, True)] + [(root2, True, False)]
    if fixed_assignment:
        tries = [t for t in tries if not t[2]]
    few_middle = max(DELAYS_MAX_DRONES, DELAYS_MAX_FRACTION * n)
    for k, similar, reassign in tries:
        sa = spread(a_m, k, min_distance_m, ceiling_m, similar=similar, floor_m=floor_m)
        sg = spread(goals_m, k, min_distance_m, ceiling_m, similar=similar, floor_m=floor_m)
        if sa is None or sg is None:
            continue
        if reassign:
            warm = assign(sa, sg, warm=warm)
            mid = warm.goal_index
        else:
            mid = goal_index
        middle: Schedule | None = None
        clashes = sync_conflicts(sa, sg[mid], required)
        if len(clashes):
            if not fixed_assignment and len(np.unique(clashes)) > few_middle:
                continue
            # Per-drone delays between the spread sets (a prescribed assignment, e.g. own homes, has
            # no CAPT guarantee at all).
            middle = schedule_transition(sa, sg[mid], lim, min_distance_m=min_distance_m, label=label)
            if middle.unresolved:
                continue
        legs = []
        inner = []  # which legs are the middle one
        for start, end in ((a_m, sa), (sa, sg[mid]), (sg[mid], goals_m[mid])):
            if middle is not None and start is sa:
                legs.append(middle)
            elif np.any(start != end):
                legs.append(synchronised(start, end, lim, round_up(sync_min_duration(end - start, lim))))
            else:
                continue
            inner.append(start is sa)
        cand = TransitionPlan(tuple(legs), mid, "layers", sync_s, expansion=k)
        if middle is None:
            # Blended legs (sim.plan._blend): flown with a share of the acceleration and jerk limits, each
            # leg starts before the previous one ends, as far as certified; kept when it is shorter.
            for shares in BLEND_SHARES:
                slow = tuple(
                    synchronised(leg.a_m, leg.b_m, part, round_up(sync_min_duration(leg.b_m - leg.a_m, part)))
                    for leg, is_inner in zip(legs, inner, strict=True)
                    for share in [shares[1] if is_inner else shares[0]]
                    for part in [replace(lim, a=lim.a * share, j=lim.j * share)]
                )
                # No overlap exceeds either of its legs: a share that cannot beat the best so far even with
                # the longest overlaps is skipped unexamined (the certificates are the costly part).
                reach = sum(min(u.window_s, v.window_s) for u, v in zip(slow[:-1], slow[1:], strict=True))
                if sum(leg.window_s for leg in slow) - reach >= cand.window_s - 1e-9:
                    continue
                blended = replace(cand, legs=slow, overlaps_s=blend_overlaps(slow, lim, required, WINDOW_STEP_S))
                if blended.window_s < cand.window_s - 1e-9:
                    cand = blended
        if best is None or cand.window_s < best.window_s:
            best = cand
        if middle is None:
            break
    if best is not None:
        return best
    if direct is None:
        direct = schedule_transition(a_m, b_m, lim, min_distance_m=min_distance_m, duration_s=sync_s, label=label)
    return TransitionPlan((direct,), goal_index, direct.resolution, sync_s)


def synchronised(a_m: np.ndarray, b_m: np.ndarray, lim: Limits, duration_s: float) -> Schedule:
    """Every drone on the shared profile, departing at once (a leg already known to be safe)."""
    n = len(a_m)
    shared, _ = sync_profile(b_m - a_m, lim, duration_s)
    return Schedule(
        a_m=a_m, b_m=b_m, depart_s=np.zeros(n), arrive_s=np.full(n, duration_s), prof_row=np.zeros(n, dtype=np.int64),
        scale=np.ones(n), profiles=shared, sync_s=duration_s, window_s=duration_s, unresolved=(),
    )


__all__ = [
    "EXPANSIONS",
    "Limits",
    "Schedule",
    "TransitionPlan",
    "UnresolvedConflict",
    "plan_transition",
    "schedule_transition",
    "sync_conflicts",
    "sync_min_duration",
    "synchronised",
]
