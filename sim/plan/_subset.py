"""Subset formations (issue 21): which drones fly a formation and where the others wait.

A formation may be flown by a named group or by a count of drones smaller than the fleet.
The others stay dark and either hold where they are or park in a vertical layer behind the
formation (+y, away from the audience). The transition into such a formation is then one CAPT
problem over *every* drone: the flying drones go to their points, the holding ones have their
start as goal (stationary, so :func:`sim.plan._schedule.schedule_transition` treats them as fixed
obstacles it keeps clear of) and the parking ones go to their slots.

Choosing *which* n of N drones fly (``{"count": n}``) is CAPT's unlabelled assignment (Turpin,
Michael & Kumar 2014, eq. 11) with the non-flying drones as N - n free "stay" goals: drone i
either takes a formation point at cost ||x_i - g_j||² or stays at cost 0, and the minimum of the
sum picks the n drones (and their points) that move least. Dense on small fleets; beyond
:data:`DENSE_SELECT_MAX_CELLS` matrix cells the n drones nearest to any formation point are taken
and assigned by CAPT among themselves (exact assignment, greedy choice of the set).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist

from sim.plan._assignment import assign
from sim.plan._schedule import Limits, Schedule, TransitionPlan, plan_transition, schedule_transition

#: Largest drones x (points + staying) cost matrix built for an exact count selection (32 MB of float64).
DENSE_SELECT_MAX_CELLS = 4_000_000
#: The park layer lies this many min_distance_m behind the formation's deepest point (+y).
PARK_OFFSET_FACTOR = 2.0
#: Park slots are this many min_distance_m apart (a margin above the minimum for the flights in and out).
PARK_SPACING_FACTOR = 1.5


def choose_drones(starts_m: np.ndarray, points_m: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``count`` drones that fly to ``points_m`` and their points (module docstring).

    Args:
        starts_m: (N, 3) drone positions, metres.
        points_m: (M, 3) formation points, M >= count.
        count: how many drones fly, 1 <= count <= N.

    Returns:
        (drones, point_index): (count,) sorted drone indices and (count,) the point each flies to.
    """
    n, m = len(starts_m), len(points_m)
    stay = n - count
    if n * (m + stay) <= DENSE_SELECT_MAX_CELLS:
        cost = np.empty((n, m + stay))
        cost[:, :m] = cdist(starts_m, points_m, "sqeuclidean")
        # Staying costs a constant below any flight (-1 m² instead of 0): the optimum then uses every stay
        # column, so exactly `count` drones fly, and among those choices it is the one of least flight cost.
        cost[:, m:] = -1.0
        rows, cols = linear_sum_assignment(cost)
        fly = cols < m
        return rows[fly].astype(np.int64), cols[fly].astype(np.int64)
    near, _ = cKDTree(points_m).query(starts_m)
    drones = np.sort(np.argsort(near, kind="stable")[:count]).astype(np.int64)
    return drones, assign(starts_m[drones], points_m).goal_index.astype(np.int64)


def park_slots(points_m: np.ndarray, count: int, *, min_distance_m: float, floor_m: float,
               ceiling_m: float) -> np.ndarray:
    """``count`` parking slots in a vertical x-z layer behind the formation ``points_m`` (M, 3), (count, 3) metres.

    The layer lies ``PARK_OFFSET_FACTOR`` x min_distance_m beyond the formation's largest y (away from
    the audience), centred on its x and z; slots are ``PARK_SPACING_FACTOR`` x min_distance_m apart,
    between ``floor_m`` and ``ceiling_m`` (a wider layer when the height does not fit a square one).
    """
    if count == 0:
        return np.zeros((0, 3))
    gap = PARK_SPACING_FACTOR * min_distance_m
    y = float(points_m[:, 1].max()) + PARK_OFFSET_FACTOR * min_distance_m
    z_lo, z_hi = floor_m + gap, ceiling_m - gap
    rows_fit = max(1, int(math.floor((z_hi - z_lo) / gap)) + 1) if z_hi > z_lo else 1
    rows = min(rows_fit, max(1, math.ceil(math.sqrt(count))))
    cols = math.ceil(count / rows)
    cx = float(points_m[:, 0].mean())
    cz = float(points_m[:, 2].mean())
    half = (rows - 1) / 2.0 * gap
    cz = min(max(cz, z_lo + half), max(z_hi - half, z_lo + half))
    xs = (np.arange(cols) - (cols - 1) / 2.0) * gap + cx
    zs = (np.arange(rows) - (rows - 1) / 2.0) * gap + cz
    gx, gz = np.meshgrid(xs, zs)
    slots = np.column_stack([gx.ravel(), np.full(gx.size, y), gz.ravel()])
    # The `count` slots nearest the layer's centre (a compact block when the grid is not full).
    keep = np.argsort(np.hypot(slots[:, 0] - cx, slots[:, 2] - cz), kind="stable")[:count]
    return np.asarray(slots[np.sort(keep)], dtype=np.float64)


def plan_movers(a_m: np.ndarray, goals_m: np.ndarray, movers: np.ndarray, lim: Limits, *, min_distance_m: float,
                ceiling_m: float, floor_m: float, label: str, own: bool = False
                ) -> tuple[tuple[Schedule, ...], np.ndarray, np.ndarray]:
    """Fly only ``movers`` to the points ``goals_m`` while every other drone stays put.

    The movers' transition is planned on their own (:func:`plan_transition`: CAPT, delays or spread
    layers among themselves, which cannot move the still drones); each of its legs is then flown over
    *every* drone by :func:`schedule_transition`, with the still drones as fixed obstacles it keeps
    clear of (what it cannot is in the legs' ``unresolved``). The sub-plan's blended overlaps are
    dropped: the legs follow one another.

    Args:
        a_m: (N, 3) every drone's position, metres.
        goals_m: (M, 3) the movers' goal points (M >= n), metres.
        movers: (n,) indices of the drones that move.
        own: mover k must end on ``goals_m[k]`` (e.g. over its own home); else CAPT's assignment.

    Returns:
        (legs over all N drones, (N, 3) where every drone ends, (n,) the goal point of each mover).
    """
    start = a_m[movers]
    first = None if own else assign(start, goals_m)
    goal_index = np.arange(len(movers)) if first is None else first.goal_index
    sub = plan_transition(start, goals_m, goal_index, lim, min_distance_m=min_distance_m, ceiling_m=ceiling_m,
                          floor_m=floor_m, label=label, fixed_assignment=own, warm=first)
    legs: list[Schedule] = []
    at = a_m.copy()
    for leg in sub.legs:
        a_leg = at.copy()
        a_leg[movers] = leg.a_m
        at = a_leg.copy()
        at[movers] = leg.b_m
        legs.append(schedule_transition(a_leg, at, lim, min_distance_m=min_distance_m, label=label))
    return tuple(legs), at, sub.goal_index


def staged_subset(a_m: np.ndarray, points_m: np.ndarray, drones: np.ndarray, slots_m: np.ndarray, lim: Limits, *,
                  min_distance_m: float, ceiling_m: float, floor_m: float, label: str,
                  sync_s: float, own: bool = False, flyers_first: bool = False) -> tuple[TransitionPlan, np.ndarray]:
    """Into a subset formation whose others park (or land), in two stages: the others fly to the park slots
    (or over their homes) while the formation's drones wait where they are, then the formation's drones fly
    to their points while the others wait there (each stage :func:`plan_movers`).

    Clearing the stage first keeps the formation's drones from crossing the others on their way out
    (one shared window over every drone cannot, when the formation is drawn through the previous one).

    Args:
        a_m: (N, 3) start positions, metres.
        points_m: (M, 3) the formation's points; ``drones`` (n,) the drones that fly it.
        slots_m: (N - n, 3) park slots for the others (any of them), or with ``own`` each other's own
            waiting point (in the order of the others), metres.
        sync_s: the single-window synchronised minimum, seconds (for the plan's stagger).
        flyers_first: after the others' step back, the formation's drones fly first and the others then go
            to their slots (e.g. homes in front of the formation, which the others would reach through it).

    Returns:
        (the plan over all N drones, resolution "layers", its goal index into ``points_m`` then the
        others' slots in the order of the others; (N - n, 3) where each of the others parks).
    """
    n = len(a_m)
    flying = np.zeros(n, dtype=bool)
    flying[drones] = True
    others = np.flatnonzero(~flying)
    # First straight back (+y, away from the audience) to the park layer's depth, at least PARK_OFFSET_FACTOR
    # x min_distance_m behind every drone: leaving a flat x-z formation along its normal only moves a drone
    # away from the ones that stay in it (its distance to each grows as sqrt(d² + y²)); then within the layer.
    back = a_m.copy()
    back[others, 1] = max(float(slots_m[:, 1].max()), float(a_m[:, 1].max()) + PARK_OFFSET_FACTOR * min_distance_m)
    step = schedule_transition(a_m, back, lim, min_distance_m=min_distance_m, label=label)
    if flyers_first:
        fly_legs, flown, point_of = plan_movers(back, points_m, drones, lim, min_distance_m=min_distance_m,
                                                ceiling_m=ceiling_m, floor_m=floor_m, label=label)
        park_legs, _, slot_of = plan_movers(flown, slots_m, others, lim, min_distance_m=min_distance_m,
                                            ceiling_m=ceiling_m, floor_m=floor_m, label=label, own=own)
        stages = (step, *fly_legs, *park_legs)
    else:
        park_legs, parked, slot_of = plan_movers(back, slots_m, others, lim, min_distance_m=min_distance_m,
                                                 ceiling_m=ceiling_m, floor_m=floor_m, label=label, own=own)
        fly_legs, _, point_of = plan_movers(parked, points_m, drones, lim, min_distance_m=min_distance_m,
                                            ceiling_m=ceiling_m, floor_m=floor_m, label=label)
        stages = (step, *park_legs, *fly_legs)
    goal_index = np.empty(n, dtype=np.int64)
    goal_index[drones] = point_of
    goal_index[others] = len(points_m) + np.arange(len(others))
    legs = tuple(leg for leg in stages if np.any(leg.a_m != leg.b_m))
    return TransitionPlan(legs, goal_index, "layers", sync_s), np.asarray(slots_m[slot_of], dtype=np.float64)


__all__ = ["choose_drones", "park_slots", "plan_movers", "staged_subset"]
