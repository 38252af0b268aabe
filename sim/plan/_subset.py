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
               ceiling_m: float, behind_m: np.ndarray | None = None) -> np.ndarray:
    """``count`` parking slots in a vertical x-z layer behind the formation ``points_m`` (M, 3), (count, 3) metres.

    The layer lies ``PARK_OFFSET_FACTOR`` x min_distance_m beyond the formation's largest y (away from
    the audience), and beyond the largest y of ``behind_m`` (P, 3) too when given (e.g. where the formation's
    drones start: then the layer lies outside everything they sweep), centred on the formation's x and z;
    slots are ``PARK_SPACING_FACTOR`` x min_distance_m apart, between ``floor_m`` and ``ceiling_m`` (a wider
    layer when the height does not fit a square one).
    """
    if count == 0:
        return np.zeros((0, 3))
    gap = PARK_SPACING_FACTOR * min_distance_m
    deepest = points_m if behind_m is None or not len(behind_m) else np.concatenate([points_m, behind_m])
    y = float(deepest[:, 1].max()) + PARK_OFFSET_FACTOR * min_distance_m
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


#: A flat formation is left along its normal when the normal is at least this close to y (|n_y|), else along y.
STEP_NORMAL_MIN_Y = 0.5
#: Points within this distance of their best-fit plane make a flat formation, metres.
FLAT_TOLERANCE_M = 1e-3


def step_direction(points_m: np.ndarray) -> np.ndarray:
    """(3,) unit direction, towards +y, in which drones step out of the formation ``points_m`` (n, 3): its normal
    when it is flat and faces the audience enough (``STEP_NORMAL_MIN_Y``; along the normal every distance to a
    drone in the plane grows, a tilted ring too), else +y."""
    if len(points_m) >= 3:
        centred = points_m - points_m.mean(axis=0)
        normal = np.linalg.svd(centred, full_matrices=False)[2][-1]
        if abs(normal[1]) >= STEP_NORMAL_MIN_Y and float(np.abs(centred @ normal).max()) <= FLAT_TOLERANCE_M:
            return np.asarray(normal * np.sign(normal[1]), dtype=np.float64)
    return np.array([0.0, 1.0, 0.0])


def _step_sides(a_m: np.ndarray, others: np.ndarray, still: np.ndarray, front: np.ndarray, min_distance_m: float,
                dir_m: np.ndarray) -> np.ndarray:
    """(k,) which of ``others`` step out to the front (-``dir_m``): ``front`` (their homes' side), except where a
    drone that stays during the step (``still``) stands in the way on that side and not on the other (closer than
    min_distance_m to the straight line along ``dir_m``, e.g. inside a 3-D formation): stepping cannot pass it."""
    if not len(still) or not len(others):
        return front
    # Pairs closer than min_distance_m across the line: a k-d tree in the plane normal to dir_m (no k x m matrix).
    e1 = np.cross(dir_m, [1.0, 0.0, 0.0] if abs(dir_m[0]) < 0.9 else [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    plane = np.column_stack([e1, np.cross(dir_m, e1)])  # (3, 2)
    near = cKDTree(a_m[others] @ plane).sparse_distance_matrix(cKDTree(a_m[still] @ plane), min_distance_m,
                                                                output_type="ndarray")
    near = near[near["v"] < min_distance_m]
    i, j = near["i"], near["j"]
    along = (a_m[still[j]] - a_m[others[i]]) @ dir_m  # > 0: the still drone lies behind (+dir) the other
    blocked_front = np.bincount(i[along < 0.0], minlength=len(others)) > 0
    blocked_back = np.bincount(i[along > 0.0], minlength=len(others)) > 0
    flip = np.where(front, blocked_front & ~blocked_back, blocked_back & ~blocked_front)
    return np.asarray(front ^ flip, dtype=bool)


def radial_exit(a_m: np.ndarray, drones: np.ndarray, others: np.ndarray, park_y_m: float, *, min_distance_m: float,
                floor_m: float, ceiling_m: float) -> list[np.ndarray] | None:
    """Where the ``others`` (k,) go, in three straight moves, to leave a 3-D formation whose ``drones`` (n,) stay in
    it, until they lie behind ``park_y_m`` (the park layer's y, beyond every drone that stays): (3,) of (N, 3)
    positions after each move, metres; None when a move would leave the altitude band [floor_m, ceiling_m] (or a
    drone sits on the centre).

    1. A uniform dilation of the others about the formation's centre c (the mean of the moving drones), until the
       nearest lies ``PARK_OFFSET_FACTOR`` x min_distance_m beyond the farthest staying drone from c (radius R1):
       every distance between two others grows by the factor, and between an other p and a staying q,
       |s p - q|² (about c) grows with s >= 1 whenever |p|² >= p·q, e.g. every drone of a sphere.
    2. Out from the y axis through c in x-z (y kept) to at least R1 from it: |p - c| only grows, so the others
       stay outside the ball of radius R1 that holds every staying drone.
    3. One translation along +y for all of them (their distances kept) until the nearest is behind ``park_y_m``:
       outside the cylinder of radius R1 about that axis, so at least R1 - R (the gap) from the staying drones.

    From there to the park layer every straight path lies in the half-space y >= ``park_y_m`` (convex), behind
    the staying drones. Each move is still certified by :func:`schedule_transition` (what it cannot keep is in the
    legs' ``unresolved``; the planner keeps the staged plan with fewest conflicts).
    """
    moving = np.concatenate([drones, others])
    centre = a_m[moving].mean(axis=0)
    gap_m = PARK_OFFSET_FACTOR * min_distance_m
    reach_m = float(np.linalg.norm(a_m[drones] - centre, axis=1).max(initial=0.0)) + gap_m
    radius_m = np.linalg.norm(a_m[others] - centre, axis=1)
    if not len(others) or float(radius_m.min()) < 1e-6:
        return None
    dilated = a_m.copy()
    dilated[others] = centre + max(1.0, reach_m / float(radius_m.min())) * (a_m[others] - centre)
    out = dilated.copy()
    xz = out[others][:, [0, 2]] - centre[[0, 2]]  # (k, 2)
    rho_m = np.hypot(xz[:, 0], xz[:, 1])
    on_axis = rho_m < 1e-9
    xz[on_axis] = (0.0, 1.0)  # straight up: any direction leaves the axis
    rho_m[on_axis] = 1.0
    out[others[:, None], [0, 2]] = centre[[0, 2]] + xz * (np.maximum(rho_m, reach_m) / rho_m)[:, None]
    behind = out.copy()
    behind[others, 1] += max(0.0, park_y_m - float(out[others, 1].min()))
    z_m = np.concatenate([dilated[others, 2], out[others, 2]])
    if float(z_m.min()) < floor_m or float(z_m.max()) > ceiling_m:
        return None
    return [dilated, out, behind]


def staged_subset(a_m: np.ndarray, points_m: np.ndarray, drones: np.ndarray, slots_m: np.ndarray, lim: Limits, *,
                  min_distance_m: float, ceiling_m: float, floor_m: float, label: str,
                  sync_s: float, own: bool = False, flyers_first: bool = False, others: np.ndarray | None = None,
                  sides: bool = False, radial: bool = False) -> tuple[TransitionPlan, np.ndarray]:
    """Into a subset formation whose others park (or land), in stages: the others step out of the stage, then
    fly to the park slots (or over their homes) while the formation's drones wait where they are, then the
    formation's drones fly to their points while the others wait there (each stage :func:`plan_movers`).

    Clearing the stage first keeps the formation's drones from crossing the others on their way out
    (one shared window over every drone cannot, when the formation is drawn through the previous one).

    The step out is straight along y, one translation for all the drones of a side (so they keep their
    distances; projecting a 3-D formation onto one plane would bring drones behind one another together), until
    the nearest is ``PARK_OFFSET_FACTOR`` x min_distance_m beyond every moving drone in y: leaving a flat
    formation along its normal only moves a drone away from the ones that stay in it (its distance to each
    grows as sqrt(d² + s²)), so a flat formation tilted towards the audience is left along its normal
    (:func:`step_direction`; along y when that would leave the altitude band). Parking drones step back (+y,
    away from the audience), at least to the park layer's depth, and then move to it.

    With ``sides`` (landing others, each over its own home) every drone steps out on its home's side of the
    stage (the homes in front of its middle y to the front, the others to the back: stepping back from a
    formation and then flying to a home in front of it crosses the formation; the other side when a drone
    that stays stands in the way on its home's side and not on the other, :func:`_step_sides`), flies within
    that clear region to its home *shifted out along y* as far as its side's homes must be to lie beyond the
    stage, descending there, and only then slides in at its home's altitude to over its home (a translation
    shared by its side, so the drones of a side keep their distances, under a formation that stays above it).

    Args:
        a_m: (N, 3) start positions, metres.
        points_m: (M, 3) the formation's points; ``drones`` (n,) the drones that fly it (CAPT among them).
        slots_m: (len(others), 3) park slots for the others (any of them), or with ``own`` each other's own
            waiting point (in the order of ``others``), metres.
        sync_s: the single-window synchronised minimum, seconds (for the plan's stagger).
        flyers_first: after the others' step out, the formation's drones fly first and the others then go
            to their slots (e.g. homes in front of the formation, which the others would reach through it).
        others: (k,) the drones that go to ``slots_m`` (default: every drone not in ``drones``); any drone in
            neither stays where it is throughout (e.g. one landed on its home), a fixed obstacle.
        sides: step out towards each other's own waiting point (needs ``own``), see above.
        radial: the others leave a 3-D stage by :func:`radial_exit` (outwards from its centre, off the y axis,
            then back behind the park layer ``slots_m``, which must lie behind every drone of ``drones``) instead
            of the step, its first two moves as one when that straight move is certified clear; the step when
            that route leaves the altitude band.

    Returns:
        (the plan over all N drones, resolution "layers", its goal index into ``points_m`` then the
        others' slots in the order of the others, -1 for a drone in neither; (len(others), 3) where each of
        the others ends).
    """
    if sides and not own:
        raise ValueError("sides needs own waiting points")
    n = len(a_m)
    if others is None:
        others = np.setdiff1d(np.arange(n), drones)
    gap_m = PARK_OFFSET_FACTOR * min_distance_m
    # The stage is where the moving drones are (a drone in neither set, e.g. landed, is an obstacle on the ground).
    moving = np.concatenate([drones, others])
    y_lo, y_hi = float(a_m[moving, 1].min()), float(a_m[moving, 1].max())
    y_m = a_m[others, 1]
    home_front = slots_m[:, 1] < 0.5 * (y_lo + y_hi)
    still = np.setdiff1d(np.arange(n), others)
    for dir_m in (step_direction(a_m[moving]), np.array([0.0, 1.0, 0.0])):
        slide = np.zeros(len(others))
        if sides:
            front = _step_sides(a_m, others, still, home_front, min_distance_m, dir_m)
            reach_front, reach_back = y_lo - gap_m, y_hi + gap_m
            # How far each side's waiting points move out along y so that the nearest lies at the step's depth.
            if front.any():
                slide[front] = min(0.0, reach_front - float(slots_m[front, 1].max()))
            if (~front).any():
                slide[~front] = max(0.0, reach_back - float(slots_m[~front, 1].min()))
        else:
            front = np.zeros(len(others), dtype=bool)
            reach_front, reach_back = y_lo - gap_m, max(float(slots_m[:, 1].max()), y_hi + gap_m)
        # One translation per side (along dir_m), so that the side's drones keep their distances (projecting a
        # 3-D formation onto one plane would bring drones behind one another together), until the nearest
        # reaches the step's depth in y.
        shift_y = np.zeros(len(others))
        if front.any():
            shift_y[front] = reach_front - float(y_m[front].max())
        if (~front).any():
            shift_y[~front] = reach_back - float(y_m[~front].min())
        back = a_m.copy()
        back[others] += (shift_y / dir_m[1])[:, None] * dir_m[None, :]
        if floor_m <= float(back[others, 2].min()) and float(back[others, 2].max()) <= ceiling_m:
            break  # else straight along y (a tilted formation's normal would leave the altitude band)
    route = None
    if radial and not sides:
        route = radial_exit(a_m, drones, others, float(slots_m[:, 1].min()), min_distance_m=min_distance_m,
                            floor_m=floor_m, ceiling_m=ceiling_m)
    if route is not None:
        back = route[-1]
        slide[:] = 0.0
        # The dilation and the move off the axis as one straight move when that is certified clear (shorter).
        out = schedule_transition(a_m, route[1], lim, min_distance_m=min_distance_m, label=label)
        at_m = [a_m, *route] if out.unresolved else [a_m, *route[1:]]
        steps = [schedule_transition(at_m[i], at_m[i + 1], lim, min_distance_m=min_distance_m, label=label)
                 for i in range(len(at_m) - 1)]
    else:
        steps = [schedule_transition(a_m, back, lim, min_distance_m=min_distance_m, label=label)]
    approach = slots_m.copy()
    approach[:, 1] += slide

    def clear_stage(at: np.ndarray) -> tuple[list[Schedule], np.ndarray, np.ndarray]:
        """The others from ``at`` to their slots (via the shifted approach points, then the slide in)."""
        legs, there, slot_of = plan_movers(at, approach, others, lim, min_distance_m=min_distance_m,
                                           ceiling_m=ceiling_m, floor_m=floor_m, label=label, own=own)
        if not np.any(slide != 0.0):
            return list(legs), there, slot_of
        end = there.copy()
        end[others] = slots_m[slot_of]
        return [*legs, schedule_transition(there, end, lim, min_distance_m=min_distance_m, label=label)], end, slot_of

    if flyers_first:
        fly_legs, flown, point_of = plan_movers(back, points_m, drones, lim, min_distance_m=min_distance_m,
                                                ceiling_m=ceiling_m, floor_m=floor_m, label=label)
        park_legs, _, slot_of = clear_stage(flown)
        stages = (*steps, *fly_legs, *park_legs)
    else:
        park_legs, parked, slot_of = clear_stage(back)
        fly_legs, _, point_of = plan_movers(parked, points_m, drones, lim, min_distance_m=min_distance_m,
                                            ceiling_m=ceiling_m, floor_m=floor_m, label=label)
        stages = (*steps, *park_legs, *fly_legs)
    goal_index = np.full(n, -1, dtype=np.int64)
    goal_index[drones] = point_of
    goal_index[others] = len(points_m) + np.arange(len(others))
    legs = tuple(leg for leg in stages if np.any(leg.a_m != leg.b_m))
    return TransitionPlan(legs, goal_index, "layers", sync_s), np.asarray(slots_m[slot_of], dtype=np.float64)


__all__ = ["choose_drones", "park_slots", "plan_movers", "radial_exit", "staged_subset", "step_direction"]
