"""The whole-show plan: CAPT transitions made safe with per-drone timing, exact holds.

A show is a sequence of show-wide *windows* (segments): vertical takeoff, then for each
formation a transition and a hold, then a transition to a grid above the home positions and
a vertical landing. The window boundaries are stored as knots, where every drone rests:

* ``knot_times_s``: (K+1,) window boundaries, seconds;
* ``knot_positions_m``: (K+1, N, 3) every drone's position at each boundary;
* ``knot_colors_rgb``: (K+1, N, 3) LED colours in [0, 1] at each boundary.

Inside a transition window each drone has its own motion (``trajectories``, per-drone
piecewise polynomials): :func:`sim.plan._schedule.plan_transition` starts from CAPT's optimal
assignment (eq. 11) and makes the window safe by construction (synchronised straight lines,
per-drone delays, or spreading the formations apart), along straight legs flown with the time
law of ``settings.time_law`` (the jerk-limited minimum-time S-curve, or the paper's quintic
s(τ) = 10τ³ - 15τ⁴ + 6τ⁵, which reproduces the shared-segment plans exactly). Holds are
windows in which every drone rests on its formation point, or, for a formation with a
``motion`` (issue 21), follows its keyframed transform as fitted quintic pieces
(:mod:`sim.plan._motion`): the transition into it ends at the first key's pose, the hold's
knots are the first and last keys' poses (every drone rests there), and the transition out
starts at the last key's pose. Between a moving hold's knots only ``trajectories`` has the
motion (:func:`trajectories_from_knots` would fly the knots straight). Colours fade linearly
in time.

A subset formation (issue 21: a group or a count of drones, :mod:`sim.plan._subset`) is flown by
its drones while the others hold, park behind it or land on their homes, dark; its transition is
one fixed assignment over every drone, the holding ones stationary obstacles of the per-drone
scheduler, and the drones that landed climb back at the start of the next transition.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from formations import DronesFromGroup, HomeFromBoxes, Settings, ShowFile
from sim.plan._assignment import assign, assignment_cost
from sim.plan._blend import blended_pieces
from sim.plan._cues import earliest_window, fit_transition
from sim.plan._motion import MotionFitError, hold_pieces, start_pose_points
from sim.plan._schedule import (
    Limits,
    Schedule,
    TransitionPlan,
    UnresolvedConflict,
    plan_transition,
    required_distance,
    round_up,
    schedule_transition,
    sync_conflicts,
    sync_min_duration,
    synchronised,
)
from sim.plan._subset import choose_drones, park_slots, staged_subset
from sim.plan._trajectory import Trajectories, TrajectoryBuilder, rest_to_rest_quintic_coeffs
from sim.plan._waves import Waves, home_waves, layer_heights, plan_waves, takeoff_waves, wave_gap

SegmentKind = Literal["takeoff", "transition", "hold", "landing"]
#: One part of a transition window flown after another: a planned transition or a single leg.
Stage = TransitionPlan | Schedule
#: Shortest hold a ``leave_at_s`` pin may leave, seconds (the show file's shortest ``hold_s``).
MIN_HOLD_S = 0.01
ProgressFn = Callable[[float], None]


class PlanError(ValueError):
    """The show cannot be planned as asked (for example a transition forced too short).

    ``path`` is the JSON path of the offending field and ``minimum_s`` the
    shortest admissible duration, when that is the reason.
    """

    def __init__(self, message: str, *, path: str = "", minimum_s: float | None = None,
                 earliest_s: float | None = None) -> None:
        super().__init__(message)
        self.path = path
        self.minimum_s = minimum_s
        #: For an infeasible cue time (``arrive_at_s`` / ``leave_at_s``): the earliest feasible one, seconds.
        self.earliest_s = earliest_s


@dataclass(frozen=True)
class ForcedTransition:
    """A transition flown as the show forces it although that is shorter than the limits allow
    (``plan_show(enforce_limits=False)``): what ``enforce_limits=True`` refuses with a :class:`PlanError`.

    ``path`` names the show's field (``formations[k].transition_s``), ``message`` says it as that
    error does, ``forced_s`` is the duration flown and ``minimum_s`` the shortest the limits allow.
    """

    path: str
    message: str
    forced_s: float
    minimum_s: float


@dataclass(frozen=True)
class Segment:
    """One show-wide segment: every drone flies (or holds) from knot ``index`` to ``index + 1``."""

    index: int
    kind: SegmentKind
    label: str
    start_s: float
    duration_s: float

    @property
    def end_s(self) -> float:
        """End time, seconds."""
        return self.start_s + self.duration_s


@dataclass(frozen=True)
class TransitionInfo:
    """A CAPT transition: its timing, assignment and the premise of the collision guarantee.

    ``goal_index[i]`` is the index of drone i's target among the destination's
    points (the formation's points, or the home positions for the landing
    approach). ``start_spacing_m`` / ``goal_spacing_m`` are the closest-pair
    distances of the starts and of the assigned goals; CAPT then guarantees a
    separation of at least min(start, goal spacing) / √2 throughout.

    Per-drone timing: drone i leaves its start at ``depart_s[i]`` and reaches its goal
    at ``arrive_s[i]`` (absolute seconds, inside [start_s, start_s + duration_s]);
    ``stagger_s`` is the window length added beyond the synchronised minimum,
    ``resolution`` how conflicts were resolved ("none": CAPT's synchronised lines; "delays":
    per-drone departures and profiles; "layers": through spread formations; "unresolved") and
    ``unresolved`` what could not be made safe (empty when the transition is safe).
    """

    segment: int
    from_name: str
    to_name: str
    start_s: float
    duration_s: float
    min_duration_s: float
    assignment_cost_m2: float
    goal_index: np.ndarray = field(repr=False)
    start_spacing_m: float
    goal_spacing_m: float
    depart_s: np.ndarray | None = field(default=None, repr=False)
    arrive_s: np.ndarray | None = field(default=None, repr=False)
    stagger_s: float = 0.0
    resolution: str = "none"
    unresolved: tuple[UnresolvedConflict, ...] = ()

    @property
    def safe(self) -> bool:
        """True when the planner certified every pair of this transition (nothing unresolved)."""
        return not self.unresolved

    @property
    def guaranteed_separation_m(self) -> float:
        """CAPT's bound min(start, goal spacing)/√2, metres."""
        return float(min(self.start_spacing_m, self.goal_spacing_m) / np.sqrt(2.0))


@dataclass(frozen=True)
class LaunchInfo:
    """Launch boxes and takeoff / landing waves of a plan (:mod:`sim.plan._waves`).

    ``start_box`` / ``end_box`` (N,): the launch box of each drone's takeoff / landing home
    (-1: a loose home); ``box_clearance_m``: how far (horizontally) an airborne drone stays from a
    parked drone of its own box (half the box spacing: never over it); ``takeoff`` / ``landing``:
    the waves, None when everybody climbs (descends) at once.
    """

    start_box: np.ndarray = field(repr=False)
    end_box: np.ndarray = field(repr=False)
    box_clearance_m: float
    takeoff: Waves | None = None
    landing: Waves | None = None


class PlanSample(NamedTuple):
    """Plan state at T times for N drones: (T, N, 3) arrays in m, m/s, m/s²; colours in [0, 1]."""

    times_s: np.ndarray
    positions_m: np.ndarray
    velocities_mps: np.ndarray
    accelerations_mps2: np.ndarray
    colors_rgb: np.ndarray


@dataclass(frozen=True)
class ShowPlan:
    """Per-drone piecewise-quintic trajectories of a whole show (see the module docstring)."""

    knot_times_s: np.ndarray
    knot_positions_m: np.ndarray
    knot_colors_rgb: np.ndarray
    segments: tuple[Segment, ...]
    transitions: tuple[TransitionInfo, ...]
    settings: Settings
    show_name: str = ""
    trajectories: Trajectories | None = field(default=None, repr=False)
    #: Launch boxes and waves (None: loose homes, everybody takes off and lands at once).
    launch: LaunchInfo | None = field(default=None, repr=False)
    #: Drones landed mid-show (issue 21, a subset formation's ``"others": "land"``): (from, to, drones) with
    #: from the start of their descent and to the end of their climb, seconds; the altitude floor does not
    #: apply to them then.
    grounded: tuple[tuple[float, float, np.ndarray], ...] = field(default=(), repr=False)
    #: Transitions flown shorter than the limits allow, as the show forces them (only with
    #: ``plan_show(enforce_limits=False)``, which plays and simulates a show as designed: the check,
    #: the 3D preview and simulation; the exports that drones fly refuse such a show).
    forced: tuple[ForcedTransition, ...] = ()

    def __post_init__(self) -> None:
        if self.trajectories is None:
            object.__setattr__(self, "trajectories", trajectories_from_knots(self.knot_times_s, self.knot_positions_m))

    @property
    def motion(self) -> Trajectories:
        """Every drone's piecewise-polynomial position (the one source of motion for all consumers)."""
        assert self.trajectories is not None  # set in __post_init__
        return self.trajectories

    @property
    def drone_count(self) -> int:
        """N, the number of drones."""
        return int(self.knot_positions_m.shape[1])

    @property
    def duration_s(self) -> float:
        """Show length from the start of takeoff to touchdown, seconds."""
        return float(self.knot_times_s[-1])

    @property
    def durations_s(self) -> np.ndarray:
        """(K,) segment durations, seconds."""
        return np.diff(self.knot_times_s)

    def segment_index(self, times_s: ArrayLike) -> np.ndarray:
        """Index of the segment containing each time (times outside the show are clamped)."""
        t = np.asarray(times_s, dtype=np.float64)
        k = np.searchsorted(self.knot_times_s, t, side="right") - 1
        return np.clip(k, 0, len(self.segments) - 1)

    def evaluate(self, times_s: ArrayLike, *, drones: slice | np.ndarray | None = None) -> PlanSample:
        """Positions, velocities, accelerations and colours at ``times_s`` for all (or some) drones.

        Args:
            times_s: (T,) times, seconds.
            drones: optional subset (slice or index array) of drones.

        Returns:
            A :class:`PlanSample` of (T, n, 3) arrays.
        """
        t = np.atleast_1d(np.asarray(times_s, dtype=np.float64))
        sel = slice(None) if drones is None else drones
        motion = self.motion.evaluate(t, sel)
        k = self.segment_index(t)
        t0 = self.knot_times_s[k]
        span = self.knot_times_s[k + 1] - t0
        # A zero-length window has faded completely at its instant (its end colour), not 0/0.
        tau = np.clip(np.divide(t - t0, span, out=np.ones_like(t), where=span > 0.0), 0.0, 1.0)
        c0 = self.knot_colors_rgb[k][:, sel]
        dc = self.knot_colors_rgb[k + 1][:, sel] - c0
        return PlanSample(
            times_s=t,
            positions_m=motion.positions_m,
            velocities_mps=motion.velocities_mps,
            accelerations_mps2=motion.accelerations_mps2,
            colors_rgb=c0 + tau[:, None, None] * dc,
        )

    def sample_times(self, fps: float) -> np.ndarray:
        """Times 0, 1/fps, ... up to and including the end of the show, seconds."""
        if not fps > 0:
            raise ValueError(f"fps must be > 0, got {fps}")
        n = int(np.floor(self.duration_s * fps + 1e-9)) + 1
        t = np.arange(n) / fps
        return t if t[-1] >= self.duration_s - 1e-12 else np.append(t, self.duration_s)

    def formation_segments(self) -> list[tuple[str, Segment]]:
        """(formation name, hold segment) for each formation, in show order."""
        return [(s.label, s) for s in self.segments if s.kind == "hold"]


def trajectories_from_knots(knot_times_s: np.ndarray, knot_positions_m: np.ndarray) -> Trajectories:
    """Shared-segment knots (K+1,), (K+1, N, 3) as one rest-to-rest quintic piece per segment and drone."""
    n = knot_positions_m.shape[1]
    builder = TrajectoryBuilder(knot_positions_m[0], float(knot_times_s[0]))
    for k in range(len(knot_times_s) - 1):
        dur = np.full(n, float(knot_times_s[k + 1] - knot_times_s[k]))
        builder.append(dur, rest_to_rest_quintic_coeffs(knot_positions_m[k], knot_positions_m[k + 1], dur))
    return builder.build(end_s=float(knot_times_s[-1]))


def _closest_distance(points: np.ndarray) -> float:
    """Closest-pair distance of ``points`` (inf for fewer than two), metres."""
    if len(points) < 2:
        return float("inf")
    dist, _ = cKDTree(points).query(points, k=2)
    return float(dist[:, 1].min())


def _limits(s: Settings) -> Limits:
    return Limits(
        v_xy=s.max_speed_xy_mps, v_z=s.max_speed_z_mps, a=s.max_accel_mps2, j=s.max_jerk_mps3, law=s.time_law,
        v_down=s.max_descent_speed_mps,
    )


def plan_show(show: ShowFile, *, enforce_limits: bool = True, progress: ProgressFn | None = None) -> ShowPlan:
    """Plan a whole show: takeoff, CAPT transitions with per-drone timing and holds, landing approach, landing.

    Every transition starts from CAPT's optimal assignment; :func:`sim.plan._schedule.schedule_transition`
    then gives each drone its departure and profile so that every pair provably keeps
    ``min_distance_m`` (or reports in ``TransitionInfo.unresolved`` what could not be made safe).

    Args:
        show: a validated show file.
        enforce_limits: if True, a formation's ``transition_s`` shorter than the
            minimum the limits allow raises :class:`PlanError`; if False it is
            flown as asked (so that ``check`` can report the violation).
        progress: optional callback receiving the fraction done in [0, 1].

    Raises:
        PlanError: a forced transition duration is below the minimum (names it).
    """
    s = show.settings
    lim = _limits(s)
    lift = np.array([0.0, 0.0, s.takeoff_altitude_m])
    home = np.array(show.home_positions_m)
    n_steps = len(show.formations) + 2

    times = [0.0]
    positions = [home]
    colors = [np.zeros_like(home)]
    segments: list[Segment] = []
    transitions: list[TransitionInfo] = []
    builder = TrajectoryBuilder(home, 0.0)

    def add(kind: SegmentKind, label: str, duration_s: float, pos: np.ndarray, col: np.ndarray) -> int:
        segments.append(Segment(len(segments), kind, label, times[-1], float(duration_s)))
        times.append(times[-1] + float(duration_s))
        positions.append(pos)
        colors.append(col)
        return len(segments) - 1

    def fly(legs: tuple[Schedule, ...], overlaps_s: tuple[float, ...] = (), start_s: float | None = None) -> None:
        """Append the legs (each from where the previous ends) to the trajectories, from ``start_s``
        (default times[-1])."""
        t0 = times[-1] if start_s is None else start_s
        if any(overlaps_s):  # blended synchronised legs (sim.plan._blend): pieces shared by all drones
            for dur, c3 in blended_pieces(legs, overlaps_s):
                builder.append(np.full(len(home), dur), c3)
            wait(t0 + sum(leg.window_s for leg in legs) - sum(overlaps_s))
            return
        for sched in legs:
            prof = sched.drone_profiles()
            wait(t0 + sched.depart_s)
            d = sched.b_m - sched.a_m
            for k in range(prof.coeffs.shape[1]):
                dur = prof.breaks_s[:, k + 1] - prof.breaks_s[:, k]
                if not np.any(dur > 0):
                    continue  # a phase no drone has (e.g. the quintic's unused six): no piece at all
                c3 = d[:, :, None] * prof.coeffs[:, k][:, None, :]
                c3[:, :, 0] += sched.a_m
                builder.append(dur, c3)
            t0 += sched.window_s
            wait(t0)

    def wait(until_s: np.ndarray | float) -> None:
        """Rest until ``until_s`` (no piece when nobody has to wait)."""
        if np.any(np.broadcast_to(until_s, (len(home),)) > builder.times_s + 1e-12):
            builder.hold_until(until_s)

    too_short: list[ForcedTransition] = []

    def forced(start: np.ndarray, end: np.ndarray, forced_s: float | None, where: str, label: str) -> float | None:
        t_min = round_up(sync_min_duration(end - start, lim))
        if forced_s is not None and forced_s < t_min - 1e-9:
            message = (f"{where} = {forced_s} s is shorter than the minimum {t_min:.1f} s that the speed and "
                       f"acceleration limits allow for the transition {label}")
            if enforce_limits:
                raise PlanError(message, path=where, minimum_s=t_min)
            too_short.append(ForcedTransition(path=where, message=message, forced_s=float(forced_s),
                                              minimum_s=float(t_min)))
        return forced_s

    def vertical(start: np.ndarray, end: np.ndarray) -> float:
        # A rigid translation: every pair keeps its distance, so the shared profile is safe.
        sched = synchronised(start, end, lim, round_up(sync_min_duration(end - start, lim)))
        fly((sched,))
        return sched.window_s

    def prepare(start: np.ndarray, from_name: str, to_name: str, goals: np.ndarray, forced_s: float | None,
                where: str, goal_index: np.ndarray | None = None) -> TransitionPlan:
        fixed = goal_index is not None
        first = None
        if goal_index is None:
            first = assign(start, goals)
            goal_index = first.goal_index
        label = f"{from_name!r} -> {to_name!r}"
        duration = forced(start, goals[goal_index], forced_s, where, label)
        return plan_transition(start, goals, goal_index, lim, min_distance_m=s.min_distance_m,
                               ceiling_m=s.max_altitude_m, floor_m=s.min_altitude_m, duration_s=duration, label=label,
                               fixed_assignment=fixed, warm=first)

    def vertical_leg(start: np.ndarray, drones: np.ndarray, z_m: np.ndarray, label: str) -> Schedule:
        """``drones`` straight up or down to altitudes ``z_m`` while every other drone stays, certified
        against them (per-drone timing; what cannot be made safe is in ``unresolved``)."""
        end = start.copy()
        end[drones, 2] = z_m
        return schedule_transition(start, end, lim, min_distance_m=s.min_distance_m, label=label)

    def overlap(k: int, point_index: np.ndarray, drones: np.ndarray, waiting: np.ndarray, others: np.ndarray, *,
                landed: bool = False) -> None:
        """Refuse subset formation k when one of its drones' points (``point_index`` (n,) of ``drones``) lies
        closer than min_distance_m to where one of the ``others`` waits (``waiting``; ``landed``: they stay on
        their homes, landed for an earlier formation): no plan can be safe then, the designer must move the
        points (or park the others)."""
        if not len(others) or not len(drones):
            return
        f = show.formations[k]
        near_m, j = cKDTree(waiting).query(f.points_m[point_index])
        bad = np.flatnonzero(near_m < s.min_distance_m * (1.0 - 1e-9))
        if not len(bad):
            return
        i = int(bad[np.argmin(near_m[bad])])
        point = int(point_index[i])
        other = int(others[j[i]])
        x, y, z = (float(v) for v in waiting[j[i]])
        who = f"group {f.drones.group!r}" if isinstance(f.drones, DronesFromGroup) else f"the {len(drones)} drones"
        mode = f.others or "hold"
        does = {"hold": "holds", "land": "waits to land"}.get(mode, "parks")
        where = {"hold": "where it was", "land": "over its home"}.get(mode, "behind the formation")
        if landed:
            does, where = "stays landed", "on its home"
        raise PlanError(
            f"formations[{k}].points[{point}]: point {point} of formation {f.name!r} (flown by {who}) is "
            f"{float(near_m[i]):.3f} m from drone {other}, which {does} {where} at ({x:.2f}, {y:.2f}, {z:.2f}) m; "
            f"the minimum distance is {s.min_distance_m:g} m ({len(bad)} of the formation's points are that close), "
            "so no plan can keep it: move the formation's points away from the waiting drones, or let the others "
            "park ('others': 'park')", path=f"formations[{k}].points[{point}]")

    def staged(tp: TransitionPlan, start: np.ndarray, pts: np.ndarray, drones: np.ndarray, others: np.ndarray,
               slots: np.ndarray, label: str, *, land: bool) -> tuple[TransitionPlan, np.ndarray | None]:
        """``tp`` (a subset window with conflicts) cleared in stages (:func:`sim.plan._subset.staged_subset`):
        ``others`` (k,) first out of the stage to ``slots`` (k, 3) (park slots, any; landing: each over its own
        home, stepping out on its home's side), then ``drones`` to ``pts``; drones in neither set stay put.
        Landing others also in the other order after the step out (the formation's drones first), and then
        all stepping back (+y) whatever their home's side (the others' own paths to their homes may cross
        on one route and not on the other); parking others also by the radial route out of a 3-D formation
        (:func:`sim.plan._subset.radial_exit`) to a park layer behind the group's start too; the first safe
        plan, else the one with fewest conflicts, is kept when it has fewer than ``tp``. Returns (the plan
        kept, where the others end (k, 3); None when ``tp`` is kept)."""
        ends = None
        ways = (((True, False, False), (True, True, False), (False, False, False), (False, True, False)) if land
                else ((False, False, False), (False, False, True)))
        # Parking others also by the radial route out of a 3-D formation (sim.plan._subset.radial_exit), to a park
        # layer behind the group's start too: the step back (one translation) passes group drones inside the
        # formation, and the layer behind the next formation alone may cut through the previous one.
        deep = (park_slots(pts, len(others), min_distance_m=s.min_distance_m, floor_m=s.min_altitude_m,
                           ceiling_m=s.max_altitude_m, behind_m=start[drones]) if not land else slots)
        for sides, flyers_first, radial in ways:
            cand, parked = staged_subset(start, pts, drones, deep if radial else slots, lim,
                                         min_distance_m=s.min_distance_m, ceiling_m=s.max_altitude_m,
                                         floor_m=s.min_altitude_m, label=label, sync_s=tp.sync_s, own=land,
                                         sides=sides, flyers_first=flyers_first, others=others, radial=radial)
            if len(cand.unresolved) < len(tp.unresolved):
                tp, ends = cand, parked
            if not tp.unresolved:
                break
        return tp, ends

    def explain_waiting(tp: TransitionPlan, k: int, flying: np.ndarray, forced_s: bool) -> TransitionPlan:
        """Subset formation k's conflicts with a drone that does not fly it: say so, and what helps (spacing
        the formations wider does not: that drone waits in the way, or the forced duration kept the planner
        from clearing the others first)."""
        f = show.formations[k]
        mode = f.others or "hold"
        does = {"hold": "holds where it was", "land": "flies home to land"}.get(mode, "parks")
        if forced_s and mode != "hold":
            helps = (f"remove formations[{k}].transition_s, so that the planner can clear the others first "
                     "and then fly the formation's drones")
        else:
            helps = ("let the others park ('others': 'park') or move the formation's points so that its drones "
                     "need not pass the waiting ones")

        def fix(u: UnresolvedConflict) -> UnresolvedConflict:
            idle = [d for d in u.drones if not flying[d]]
            if not idle:
                return u
            return replace(u, fix=f"drone {idle[0]} {does} (others: {mode!r}) in the way of formation {f.name!r}'s "
                                  f"drones: {helps}")

        return replace(tp, legs=tuple(replace(leg, unresolved=tuple(fix(u) for u in leg.unresolved))
                                      for leg in tp.legs))

    def prepare_formation(k: int, start: np.ndarray, from_name: str
                          ) -> tuple[TransitionPlan, np.ndarray, np.ndarray, Schedule | None]:
        """The transition into formation k from ``start``: (plan, its goal points, which drones fly it,
        the landing descent of the others when they land, else None).

        A subset formation (issue 21, :mod:`sim.plan._subset`) is one fixed assignment over every
        drone: the flying ones onto their points, the others onto their own start (hold: stationary,
        so the per-drone scheduler keeps clear of them) or a park slot behind the formation. It is
        flown with per-drone timing only (no spreading, which would move the holding drones);
        what cannot be made safe so is reported in ``unresolved`` like any transition. Landing others
        fly to their own home at takeoff altitude, then descend vertically (a leg after the transition,
        certified against the drones already in the formation).
        """
        f = show.formations[k]
        where = f"formations[{k}].transition_s"
        sel = show.formation_drones(k)
        flying = np.ones(len(start), dtype=bool)
        if sel is None:
            goals = goal_points(k)  # a moving formation: its first key's pose (subsets never move)
            return prepare(start, from_name, f.name, goals, f.transition_s, where), goals, flying, None
        pts = f.points_m
        if isinstance(sel, int):
            drones, point_index = choose_drones(start, pts, sel)
        else:
            drones = sel
            point_index = assign(start[drones], pts).goal_index
        flying[:] = False
        flying[drones] = True
        others = np.flatnonzero(~flying)
        slots = np.empty((0, 3))
        if f.others == "park":
            slots = park_slots(pts, len(others), min_distance_m=s.min_distance_m, floor_m=s.min_altitude_m,
                               ceiling_m=s.max_altitude_m)
            waiting = slots[assign(start[others], slots).goal_index]
        elif f.others == "land":
            waiting = home[others] + lift
        else:
            waiting = start[others]
        overlap(k, point_index, drones, waiting, others)
        goals = np.concatenate([pts, waiting])
        goal_index = np.empty(len(start), dtype=np.int64)
        goal_index[drones] = point_index
        goal_index[others] = len(pts) + np.arange(len(others))
        label = f"{from_name!r} -> {f.name!r}"
        duration = forced(start, goals[goal_index], f.transition_s, where, label)

        def subset_plan(layers: bool) -> TransitionPlan:
            return plan_transition(start, goals, goal_index, lim, min_distance_m=s.min_distance_m,
                                   ceiling_m=s.max_altitude_m, floor_m=s.min_altitude_m, duration_s=duration,
                                   label=label, allow_layers=layers, fixed_assignment=True)

        tp = subset_plan(False)
        if tp.unresolved and duration is None:
            # Holding drones stand in the flyers' way (e.g. in the middle of a launch grid): spreading both
            # sets apart and back (every drone, the holding ones return to their place) is the fallback
            # that keeps the show safe; still unresolved conflicts are reported as for any transition.
            layered = subset_plan(True)
            if not layered.unresolved:
                tp = layered
        if tp.unresolved and duration is None and f.others in ("park", "land") and len(others):
            # The formation drawn through the previous one: the flyers cross the others on their way out.
            tp, parked = staged(tp, start, pts, drones, others, slots if f.others == "park" else waiting, label,
                                land=f.others == "land")
            if parked is not None:
                goals = np.concatenate([pts, parked])
        if tp.unresolved:
            tp = explain_waiting(tp, k, flying, duration is not None)
        descent = None
        if f.others == "land" and len(others):
            descent = vertical_leg(tp.legs[-1].b_m, others, home[others, 2], f"landing the others of {f.name!r}")
        return tp, goals, flying, descent

    def commit(tp: TransitionPlan, from_name: str, to_name: str, goals: np.ndarray, pre: tuple[Stage, ...] = (),
               post: tuple[Stage, ...] = ()) -> tuple[np.ndarray, dict[str, Any]]:
        """Fly the stages ``pre`` (e.g. landed drones climbing), the transition, then ``post`` (others landing),
        one after the other, as one window."""
        start = positions[-1]
        goal_index = tp.goal_index
        last = post[-1] if post else tp
        end = last.legs[-1].b_m if isinstance(last, TransitionPlan) else last.b_m
        t0 = times[-1]
        # Elapsed time within the window, summed from 0 (not t0 + ... - t0, which rounds: a lone
        # transition's duration must be its window exactly, as the quintic-reproduction test requires).
        elapsed = 0.0
        extra: list[UnresolvedConflict] = []
        pre_s = 0.0
        for stage in (*pre, tp, *post):
            legs, overlaps = (stage.legs, stage.overlaps_s) if isinstance(stage, TransitionPlan) else ((stage,), ())
            fly(legs, overlaps, start_s=t0 + elapsed)
            if stage is not tp:
                extra += [replace(u, time_s=t0 + elapsed + u.time_s) for u in stage.unresolved]
            else:
                pre_s = elapsed
            elapsed += stage.window_s
        info = dict(
            from_name=from_name,
            to_name=to_name,
            start_s=t0,
            duration_s=elapsed,
            min_duration_s=round_up(sync_min_duration(goals[goal_index] - start, lim)),
            assignment_cost_m2=assignment_cost(start, goals, goal_index),
            goal_index=goal_index,
            start_spacing_m=_closest_distance(start),
            goal_spacing_m=_closest_distance(end),
            depart_s=t0 + pre_s + tp.depart_s,
            arrive_s=t0 + pre_s + tp.arrive_s,
            stagger_s=tp.stagger_s,
            resolution=tp.resolution,
            unresolved=tuple(
                replace(u, time_s=t0 + pre_s + u.time_s) for u in tp.unresolved
            ) + tuple(extra),
        )
        return end, info

    def fold_first(tp: TransitionPlan, before: np.ndarray) -> tuple[TransitionPlan, np.ndarray]:
        """Fly ``before`` -> the first leg's end directly if that is safe (saves one stop)."""
        if tp.resolution != "layers" or len(tp.legs) < 2:
            return tp, tp.legs[0].a_m
        target = tp.legs[0].b_m
        if len(sync_conflicts(before, target, required_distance(s.min_distance_m))):
            return tp, tp.legs[0].a_m
        return replace(tp, legs=tp.legs[1:], overlaps_s=tp.overlaps_s[1:]), target

    def fold_last(tp: TransitionPlan, after: np.ndarray) -> tuple[TransitionPlan, np.ndarray]:
        """Fly the last leg's start -> ``after`` directly if that is safe (saves one stop)."""
        if tp.resolution != "layers" or len(tp.legs) < 2:
            return tp, tp.legs[-1].b_m
        source = tp.legs[-1].a_m
        if len(sync_conflicts(source, after, required_distance(s.min_distance_m))):
            return tp, tp.legs[-1].b_m
        return replace(tp, legs=tp.legs[:-1], overlaps_s=tp.overlaps_s[:-1]), source

    def pin_arrival(tp: TransitionPlan, k: int, t0: float, tail_s: float = 0.0) -> TransitionPlan:
        """Fit the transition into formation k (starting at ``t0``, followed by ``tail_s`` of others landing)
        to end at its ``arrive_at_s`` (issue 18)."""
        f = show.formations[k]
        if f.arrive_at_s is None:
            return tp
        label = f"into {f.name!r}"
        fitted = fit_transition(tp, f.arrive_at_s - t0 - tail_s, lim, min_distance_m=s.min_distance_m, label=label)
        if fitted is not None:
            return fitted
        earliest = t0 + tail_s + earliest_window(tp, lim, min_distance_m=s.min_distance_m, label=label)
        raise PlanError(
            f"formations[{k}].arrive_at_s = {f.arrive_at_s:g} s is too early for formation {f.name!r}: the "
            f"transition into it starts at {t0:.2f} s and needs {earliest - t0:.1f} s, so the earliest feasible "
            f"arrival is {earliest:.1f} s",
            path=f"formations[{k}].arrive_at_s", minimum_s=earliest - t0, earliest_s=earliest,
        )

    def hold_length(k: int) -> float:
        """Formation k's hold: ``hold_s``, or until its ``leave_at_s`` (issue 18)."""
        f = show.formations[k]
        if f.leave_at_s is None:
            return f.hold_s
        arrived = times[-1]
        if f.leave_at_s - arrived < MIN_HOLD_S - 1e-9:
            earliest = arrived + MIN_HOLD_S
            raise PlanError(
                f"formations[{k}].leave_at_s = {f.leave_at_s:g} s is too early for formation {f.name!r}: it is "
                f"reached at {arrived:.2f} s at the earliest, so the earliest feasible leave time is {earliest:.2f} s",
                path=f"formations[{k}].leave_at_s", earliest_s=earliest,
            )
        return f.leave_at_s - arrived

    def goal_points(k: int) -> np.ndarray:
        """Formation k's points where the transition into it ends: at its motion's first pose (issue 21)."""
        f = show.formations[k]
        return f.points_m if f.motion is None else start_pose_points(f.motion, f.points_m)

    def move(k: int, goal_index: np.ndarray, hold_s: float, end: np.ndarray) -> np.ndarray:
        """Fly formation k's hold (from times[-1]): at rest, or its motion as fitted pieces (sim.plan._motion).

        Returns every drone's position at the end of the hold (the last key's pose).
        """
        f = show.formations[k]
        if f.motion is None:
            return end
        if f.motion.end_s > hold_s + 1e-9:
            last = len(f.motion.keys) - 1
            raise PlanError(
                f"formations[{k}].motion.keys[{last}].t_s = {f.motion.end_s:g} s is after the end of the hold of "
                f"formation {f.name!r}, which lasts {hold_s:.2f} s (until leave_at_s): keys must lie within the hold",
                path=f"formations[{k}].motion.keys[{last}].t_s",
            )
        try:
            durations, coeffs = hold_pieces(f.motion, f.points_m, f.points_m[goal_index], hold_s)
        except MotionFitError as exc:
            where = f"formations[{k}].motion.keys" + (f"[{exc.key}]" if exc.key >= 0 else "")
            raise PlanError(f"{where}: {exc} (formation {f.name!r})", path=where) from exc
        for p in range(len(durations)):
            builder.append(np.full(len(home), durations[p]), coeffs[:, p])
        return builder.positions_m

    # Vertical takeoff: a rigid translation, so every pair keeps its ground distance; when the home
    # layout is too dense for that (launch boxes), in waves to altitude layers (sim.plan._waves).
    # When the first transition starts by spreading the lifted grid, the takeoff climbs straight
    # into the spread grid instead (a similarity plus a common lift: distances only grow).
    boxes = show.all_home_boxes
    dw = s.downwash_axes_m
    box_spacing = float(show.home.boxes.spacing_m) if isinstance(show.home, HomeFromBoxes) else 0.0
    waves_up = takeoff_waves(home, lim, min_distance_m=s.min_distance_m, downwash_m=dw,
                             base_m=s.takeoff_altitude_m)
    first = show.formations[0]
    if waves_up is not None and float(waves_up.schedule.b_m[:, 2].max()) > s.max_altitude_m:
        path = "home.boxes.per_box" if isinstance(show.home, HomeFromBoxes) else "home"
        raise PlanError(
            f"{path}: the home layout needs {waves_up.count} takeoff waves, stacked in altitude layers up to "
            f"{float(waves_up.schedule.b_m[:, 2].max()):.1f} m, above max_altitude_m {s.max_altitude_m:g} m; "
            "use fewer drones per box (or space them at least settings.min_distance_m apart), a lower "
            "takeoff_altitude_m or a higher max_altitude_m", path=path)
    if waves_up is not None:
        # Mid-show landings (a subset formation's others) descend together onto their homes: not yet in
        # waves, so on a dense layout they would land beside and over their box mates. Refused by name.
        for k, f in enumerate(show.formations):
            if show.formation_drones(k) is not None and f.others == "land":
                raise PlanError(
                    f"formations[{k}].others: 'land' lands drones mid-show onto homes too close to climb or land "
                    f"together ({waves_up.count} takeoff waves); use 'hold' or 'park' for formation {f.name!r}, "
                    "or space the homes at least settings.min_distance_m apart", path=f"formations[{k}].others")
    if waves_up is None:
        up = home + lift
        tp, goals, flying, post = prepare_formation(0, up, "takeoff")
        if first.arrive_at_s is None:
            tp, up = fold_first(tp, home)
        else:
            # A pinned first formation: the takeoff's length must be known before the transition is fitted
            # (folding would change it), so the takeoff climbs to the lifted grid.
            tp = pin_arrival(tp, 0, round_up(sync_min_duration(up - home, lim)), post.window_s if post else 0.0)
        add("takeoff", "takeoff", vertical(home, up), up, colors[-1])
    else:
        up = waves_up.schedule.b_m
        tp, goals, flying, post = prepare_formation(0, up, "takeoff")
        if first.arrive_at_s is not None:
            tp = pin_arrival(tp, 0, waves_up.window_s, post.window_s if post else 0.0)
        fly((waves_up.schedule,))
        add("takeoff", "takeoff", waves_up.window_s, up, colors[-1])
    if progress:
        progress(1 / n_steps)

    # Subset formations whose others land (issue 21): when each drone touched down (its descent's start;
    # NaN: airborne), and every (descent start, climb end, drones) interval, which the altitude floor
    # does not apply to.
    down_since = np.full(len(home), np.nan)
    grounded: list[tuple[float, float, np.ndarray]] = []

    def climb(start: np.ndarray, drones: np.ndarray, label: str) -> Schedule | None:
        """Landed ``drones`` straight up to takeoff altitude above their homes (None: none of them)."""
        if not len(drones):
            return None
        return vertical_leg(start, drones, home[drones, 2] + s.takeoff_altitude_m, label)

    def airborne_again(drones: np.ndarray, t_s: float) -> None:
        """``drones`` finished climbing at ``t_s``: close their grounded intervals."""
        for since in np.unique(down_since[drones]):
            grounded.append((float(since), t_s, drones[down_since[drones] == since]))
        down_since[drones] = np.nan

    def prepare_swap(k: int, start: np.ndarray, from_name: str) -> tuple[
            TransitionPlan, np.ndarray, np.ndarray, tuple[Stage, ...], np.ndarray, np.ndarray, float, float]:
        """Into subset formation k whose others land while some of its drones are on the ground: first the
        airborne drones fly (to their points, or to their homes and down), then the landed ones of the
        formation climb and fly to their points; landed drones that do not fly stay down. Sequential, so
        the drones leaving never cross the ones arriving from the ground. Returns (the arriving transition,
        its goals, who flies, the stages before it, who lands, who climbs, when the landing starts and when
        the climb ends, seconds into the window)."""
        f = show.formations[k]
        sel = show.formation_drones(k)
        assert sel is not None
        pts = f.points_m
        down_now = ~np.isnan(down_since)
        lifted = start.copy()
        lifted[down_now] = home[down_now] + lift  # where the landed drones would start from
        if isinstance(sel, int):
            drones, point_index = choose_drones(lifted, pts, sel)
        else:
            drones = sel
            point_index = assign(lifted[drones], pts).goal_index
        flying = np.zeros(len(start), dtype=bool)
        flying[drones] = True
        point_of = np.full(len(start), -1, dtype=np.int64)
        point_of[drones] = point_index
        landers = np.flatnonzero(~flying & ~down_now)
        climbers = np.flatnonzero(flying & down_now)
        label = f"{from_name!r} -> {f.name!r}"

        def stay_but(moving: np.ndarray, at: np.ndarray, targets: np.ndarray) -> TransitionPlan:
            goals = at.copy()
            goals[moving] = targets
            return plan_transition(at, goals, np.arange(len(at)), lim, min_distance_m=s.min_distance_m,
                                   ceiling_m=s.max_altitude_m, floor_m=s.min_altitude_m, label=label,
                                   allow_layers=False, fixed_assignment=True)

        leaving = np.flatnonzero(~down_now)  # airborne: fly to their points, or home to land
        aloft = leaving[flying[leaving]]  # the airborne drones of the formation
        # No plan can be safe with a point of the airborne flyers where a lander waits over its home (they arrive
        # together), nor with any point on a drone that stays landed: refused naming the point (as for others).
        overlap(k, point_of[aloft], aloft, home[landers] + lift, landers)
        stayers = np.flatnonzero(~flying & down_now)
        overlap(k, point_of[drones], drones, home[stayers], stayers, landed=True)
        targets = np.where(flying[leaving, None], pts[np.maximum(point_of[leaving], 0)], home[leaving] + lift)
        first = stay_but(leaving, start, targets)
        if first.unresolved and len(landers) and len(aloft):
            # The airborne flyers cross the landers on their way home (a formation drawn through the previous
            # one): the landers clear the stage first, as for any landing others (the landed drones stay put).
            sub = point_of[aloft]
            first, ends = staged(first, start, pts[sub], aloft, landers, home[landers] + lift, label, land=True)
            if ends is not None:
                point_of[aloft] = sub[first.goal_index[aloft]]
        if first.unresolved:
            first = explain_waiting(first, k, flying, False)
        stages: list[Stage] = [first]
        at = first.legs[-1].b_m
        t_down = t_up = first.window_s
        if len(landers):
            descent = vertical_leg(at, landers, home[landers, 2], f"landing the others of {f.name!r}")
            stages.append(descent)
            at = descent.b_m
            t_up += descent.window_s
        up = climb(at, climbers, f"taking off again into {f.name!r}")
        if up is not None:
            stages.append(up)
            at = up.b_m
            t_up += up.window_s
        arrive = stay_but(climbers, at, pts[point_of[climbers]])
        goals = np.concatenate([pts, at[~flying]])
        goal_index = np.empty(len(start), dtype=np.int64)
        goal_index[flying] = point_of[flying]
        goal_index[~flying] = len(pts) + np.arange(int((~flying).sum()))
        return (replace(arrive, goal_index=goal_index), goals, flying, tuple(stages), landers, climbers, t_down,
                t_up)

    def swap_duration(tp: TransitionPlan, k: int, pre_s: float) -> TransitionPlan:
        """The swap into formation k (``tp`` its arriving transition after ``pre_s`` of stages) lasting the
        formation's ``transition_s``: the arrival re-timed to fill what the stages leave. Shorter than the stages
        and the arrival allow is refused naming the field, whether or not limits are enforced: the sequence of
        stages cannot be flown faster as a whole."""
        f = show.formations[k]
        if f.transition_s is None:
            return tp
        label = f"into {f.name!r}"
        left_s = f.transition_s - pre_s
        fitted = fit_transition(tp, left_s, lim, min_distance_m=s.min_distance_m, label=label) if left_s > 0 else None
        if fitted is not None:
            return fitted
        earliest = pre_s + earliest_window(tp, lim, min_distance_m=s.min_distance_m, label=label)
        where = f"formations[{k}].transition_s"
        raise PlanError(
            f"{where} = {f.transition_s:g} s is shorter than the {earliest:.1f} s that formation {f.name!r} needs: "
            "its others land while some of its drones are down, so its airborne drones fly and the others land "
            "before the landed ones take off and fly to their points", path=where, minimum_s=earliest)

    previous = "takeoff"
    homes_up = np.array(show.all_home_positions_m) + lift
    own = np.arange(len(home)) if s.landing == "own_home" else None
    for k, f in enumerate(show.formations):
        pre: tuple[Stage, ...] = ()
        posts: tuple[Stage, ...] = () if post is None else (post,)
        t_start = times[-1]
        down_now = np.flatnonzero(~np.isnan(down_since))
        if k > 0 and len(down_now) and f.others == "land" and show.formation_drones(k) is not None:
            tp, goals, flying, pre, landers, climbers, t_down, t_up = prepare_swap(k, positions[-1], previous)
            tp = swap_duration(tp, k, sum(x.window_s for x in pre))
            tp = pin_arrival(tp, k, t_start + sum(x.window_s for x in pre))
            end, info = commit(tp, previous, f.name, goals, pre)
            if len(climbers):
                airborne_again(climbers, t_start + t_up)
            down_since[landers] = t_start + t_down
        else:
            if k > 0:
                up = climb(positions[-1], down_now, f"taking off again into {f.name!r}")
                pre = () if up is None else (up,)
                tp, goals, flying, post = prepare_formation(k, positions[-1] if up is None else up.b_m, previous)
                posts = () if post is None else (post,)
                tp = pin_arrival(tp, k, t_start + (up.window_s if up else 0.0), post.window_s if post else 0.0)
            end, info = commit(tp, previous, f.name, goals, pre, posts)
            if pre:  # the landed drones are airborne again at the end of the climb
                airborne_again(down_now, t_start + pre[0].window_s)
            if posts:  # the others touch down from the start of the descent on
                down_since[~flying] = t_start + info["duration_s"] - posts[0].window_s
        # Drones not flying this formation are dark and have no point (goal_index -1).
        info["goal_index"] = np.where(flying, tp.goal_index, -1)
        col = np.zeros((len(home), 3))
        col[flying] = f.colors_rgb[tp.goal_index[flying]]
        seg = add("transition", f.name, info["duration_s"], end, col)
        transitions.append(TransitionInfo(segment=seg, **info))
        held = hold_length(k)
        add("hold", f.name, held, move(k, tp.goal_index, held, end), col)
        wait(times[-1])
        previous = f.name
        if progress:
            progress((k + 2) / n_steps)

    # Landing approach onto the home positions lifted to takeoff altitude: CAPT onto any home
    # ("any_home"), or each drone onto its own ("own_home", conflicts resolved like any transition);
    # then a vertical descent (straight from the spread grid when the approach ends by contracting it).
    # Drones landed mid-show (a subset formation's others) climb back first (issue 21).
    down_now = np.flatnonzero(~np.isnan(down_since))
    up_leg = climb(positions[-1], down_now, "taking off again for the landing")
    start_l = positions[-1] if up_leg is None else up_leg.b_m
    pre = () if up_leg is None else (up_leg,)
    # With dense homes, into the layers over the landing homes: own homes fixed, or any home chosen by
    # CAPT among the layers over every home (each home's layer from a colouring of all homes).
    # The colours may go to the layers in any order (the lowest layer lands first whatever its colour):
    # orders are tried until the approach is certified (drones from high up to high layers first).
    waves_down: Waves | None = None
    tp_layers: TransitionPlan | None = None
    cand = show.all_home_positions_m if own is None else show.all_home_positions_m[own]
    colour = home_waves(cand, min_distance_m=s.min_distance_m, downwash_radius_m=dw[0])
    if colour is not None:
        count = int(colour.max()) + 1
        gap = wave_gap(s.min_distance_m, dw)
        heights = layer_heights(count, s.takeoff_altitude_m, gap)
        orders = [np.arange(count), np.arange(count)[::-1]]
        if own is not None:  # by the altitude the drones come from: the highest-coming colour to the top layer
            z_from = np.bincount(colour, weights=start_l[:, 2], minlength=count) / np.maximum(
                np.bincount(colour, minlength=count), 1)
            orders.insert(0, np.argsort(np.argsort(-z_from, kind="stable"), kind="stable"))
        for order in orders:
            layer_of = order[colour]
            layered_all = np.array(cand)
            layered_all[:, 2] += heights[layer_of]
            if own is None:
                tp_layers = prepare(start_l, previous, "landing", layered_all, None, "landing")
            else:
                tp_layers = prepare(start_l, previous, "landing", layered_all, None, "landing",
                                    goal_index=np.arange(len(home)))
            if not tp_layers.unresolved:
                break
        assert tp_layers is not None
        land_index = tp_layers.goal_index if own is None else own
        waves_down = plan_waves(show.all_home_positions_m[land_index], layer_of[tp_layers.goal_index], lim,
                                s.takeoff_altitude_m, gap, landing=True, count=count)
    def approach(tp: TransitionPlan, goals: np.ndarray) -> np.ndarray:
        """Fly the landing approach (after the mid-show landed drones' climb, if any); its end positions."""
        t_start = times[-1]
        end, info = commit(tp, previous, "landing", goals, pre)
        if up_leg is not None:
            airborne_again(down_now, t_start + up_leg.window_s)
        seg = add("transition", "landing", info["duration_s"], end, np.zeros_like(end))
        transitions.append(TransitionInfo(segment=seg, **info))
        return end

    if waves_down is None:
        tp = prepare(start_l, previous, "landing", homes_up, None, "landing", goal_index=own)
        down = homes_up[tp.goal_index] - lift
        tp, _ = fold_last(tp, down)
        end = approach(tp, homes_up)
        add("landing", "landing", vertical(end, down), down, np.zeros_like(end))
    else:
        # Into the layers over the landing homes, then down in waves.
        assert tp_layers is not None
        tp = tp_layers
        end = approach(tp, layered_all)
        fly((waves_down.schedule,))
        add("landing", "landing", waves_down.window_s, waves_down.schedule.b_m, np.zeros_like(end))
    if progress:
        progress(1.0)

    launch = None
    if waves_up is not None or waves_down is not None or np.any(boxes >= 0):
        end_index = tp.goal_index if waves_down is None else land_index
        launch = LaunchInfo(start_box=boxes[: len(home)].copy(), end_box=boxes[end_index].copy(),
                            box_clearance_m=min(box_spacing / 2.0, dw[0]), takeoff=waves_up, landing=waves_down)

    return ShowPlan(
        knot_times_s=np.array(times),
        knot_positions_m=np.stack(positions),
        knot_colors_rgb=np.stack(colors),
        segments=tuple(segments),
        transitions=tuple(transitions),
        settings=s,
        show_name=show.name,
        trajectories=builder.build(end_s=times[-1]),
        launch=launch,
        grounded=tuple(grounded),
        forced=tuple(too_short),
    )


__all__ = [
    "ForcedTransition",
    "LaunchInfo",
    "PlanError",
    "PlanSample",
    "Segment",
    "ShowPlan",
    "TransitionInfo",
    "UnresolvedConflict",
    "plan_show",
]
