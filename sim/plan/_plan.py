"""The whole-show plan: CAPT transitions with a shared quintic time law.

A show is a sequence of *segments* shared by every drone: vertical takeoff,
then for each formation a CAPT transition and a hold, then a CAPT transition to
a grid above the home positions and a vertical landing. All drones of a segment
share its start time and duration (CAPT's collision guarantee needs this), so
the plan is stored compactly as knots:

* ``knot_times_s``: (K+1,) segment boundaries, seconds;
* ``knot_positions_m``: (K+1, N, 3) every drone's position at each boundary;
* ``knot_colors_rgb``: (K+1, N, 3) LED colours in [0, 1] at each boundary.

Within segment k every drone flies the straight line between its two knots with
the common rest-to-rest law β(t) = s((t - t_k)/T_k), s(τ) = 10τ³ - 15τ⁴ + 6τ⁵;
holds are segments whose two knots coincide. Colours fade linearly in time.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal, NamedTuple

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from formations import Settings, ShowFile
from sim.plan._assignment import assign
from sim.plan._timing import min_transition_duration
from sim.plan._trajectory import Trajectories, TrajectoryBuilder, rest_to_rest_quintic_coeffs

SegmentKind = Literal["takeoff", "transition", "hold", "landing"]
ProgressFn = Callable[[float], None]


class PlanError(ValueError):
    """The show cannot be planned as asked (for example a transition forced too short).

    ``path`` is the JSON path of the offending field and ``minimum_s`` the
    shortest admissible duration, when that is the reason.
    """

    def __init__(self, message: str, *, path: str = "", minimum_s: float | None = None) -> None:
        super().__init__(message)
        self.path = path
        self.minimum_s = minimum_s


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

    @property
    def guaranteed_separation_m(self) -> float:
        """CAPT's bound min(start, goal spacing)/√2, metres."""
        return min(self.start_spacing_m, self.goal_spacing_m) / np.sqrt(2.0)


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
        tau = np.clip((t - t0) / (self.knot_times_s[k + 1] - t0), 0.0, 1.0)
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
    return builder.build()


def _closest_distance(points: np.ndarray) -> float:
    """Closest-pair distance of ``points`` (inf for fewer than two), metres."""
    if len(points) < 2:
        return float("inf")
    dist, _ = cKDTree(points).query(points, k=2)
    return float(dist[:, 1].min())


def plan_show(show: ShowFile, *, enforce_limits: bool = True, progress: ProgressFn | None = None) -> ShowPlan:
    """Plan a whole show: takeoff, CAPT transitions and holds, landing approach, landing.

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
    limits = {
        "max_speed_xy_mps": s.max_speed_xy_mps,
        "max_speed_z_mps": s.max_speed_z_mps,
        "max_accel_mps2": s.max_accel_mps2,
    }
    lift = np.array([0.0, 0.0, s.takeoff_altitude_m])
    home = np.array(show.home_positions_m)
    n_steps = len(show.formations) + 2

    times = [0.0]
    positions = [home]
    colors = [np.zeros_like(home)]
    segments: list[Segment] = []
    transitions: list[TransitionInfo] = []

    def add(kind: SegmentKind, label: str, duration_s: float, pos: np.ndarray, col: np.ndarray) -> int:
        segments.append(Segment(len(segments), kind, label, times[-1], float(duration_s)))
        times.append(times[-1] + float(duration_s))
        positions.append(pos)
        colors.append(col)
        return len(segments) - 1

    def capt(from_name: str, to_name: str, goals: np.ndarray, forced_s: float | None, where: str):
        start = positions[-1]
        a = assign(start, goals)
        end = goals[a.goal_index]
        t_min = min_transition_duration(start, end, **limits)
        duration = t_min
        if forced_s is not None:
            if forced_s < t_min - 1e-9 and enforce_limits:
                raise PlanError(
                    f"{where} = {forced_s} s is shorter than the minimum {t_min:.1f} s that the speed and "
                    f"acceleration limits allow for the transition {from_name!r} -> {to_name!r}",
                    path=where,
                    minimum_s=t_min,
                )
            duration = float(forced_s)
        info = dict(
            from_name=from_name,
            to_name=to_name,
            start_s=times[-1],
            duration_s=duration,
            min_duration_s=t_min,
            assignment_cost_m2=a.cost_m2,
            goal_index=a.goal_index,
            start_spacing_m=_closest_distance(start),
            goal_spacing_m=_closest_distance(end),
        )
        return end, a.goal_index, info

    # Vertical takeoff: a rigid translation, so every pair keeps its ground distance.
    up = home + lift
    add("takeoff", "takeoff", min_transition_duration(home, up, **limits), up, colors[-1])
    if progress:
        progress(1 / n_steps)

    previous = "takeoff"
    for k, f in enumerate(show.formations):
        end, goal_index, info = capt(previous, f.name, f.points_m, f.transition_s, f"formations[{k}].transition_s")
        col = f.colors_rgb[goal_index]
        seg = add("transition", f.name, info["duration_s"], end, col)
        transitions.append(TransitionInfo(segment=seg, **info))
        add("hold", f.name, f.hold_s, end, col)
        previous = f.name
        if progress:
            progress((k + 2) / n_steps)

    # Landing approach: CAPT onto the home positions lifted to takeoff altitude (any
    # drone may land on any home), then a vertical descent.
    homes_up = np.array(show.all_home_positions_m) + lift
    end, goal_index, info = capt(previous, "landing", homes_up, None, "landing")
    seg = add("transition", "landing", info["duration_s"], end, np.zeros_like(end))
    transitions.append(TransitionInfo(segment=seg, **info))
    down = end - lift
    add("landing", "landing", min_transition_duration(end, down, **limits), down, np.zeros_like(end))
    if progress:
        progress(1.0)

    return ShowPlan(
        knot_times_s=np.array(times),
        knot_positions_m=np.stack(positions),
        knot_colors_rgb=np.stack(colors),
        segments=tuple(segments),
        transitions=tuple(transitions),
        settings=s,
        show_name=show.name,
    )


__all__ = [
    "PlanError",
    "PlanSample",
    "Segment",
    "ShowPlan",
    "TransitionInfo",
    "plan_show",
]
