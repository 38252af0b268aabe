"""Waypoint missions timed like the plan, and their kinematic replay at ArduCopter's WPNAV defaults.

A waypoint mission cannot say *when* to be somewhere, only how fast to fly each
leg (``MAV_CMD_DO_CHANGE_SPEED``) and how long to wait at each waypoint (the
``NAV_WAYPOINT`` hold, which ArduPilot truncates to whole seconds). So each drone's
mission is timed here against a kinematic model of ArduCopter's waypoint navigation:

* every leg is a straight line flown rest to rest with a jerk-limited S-curve speed
  profile (ArduCopter 4.x ``SCurve``): along-track limits are the horizontal ones
  (commanded speed, ``WPNAV_ACCEL``) divided by the leg's horizontal share and the
  vertical ones (``WPNAV_SPEED_UP`` / ``WPNAV_SPEED_DN``, ``WPNAV_ACCEL_Z``) divided by
  its vertical share, whichever binds; jerk ``WPNAV_JERK``; takeoff climbs at
  ``WPNAV_SPEED_UP``;
* each leg's speed is chosen (bisection on the S-curve's duration, which falls as the
  speed rises) so the drone *arrives* when the plan does, starting from when the model
  says it left the previous waypoint; a leg the limits cannot fly that fast arrives
  late and the next leg catches up; one the model cannot fly that slowly arrives early
  and waits;
* each hold is the whole number of seconds nearest to the plan's departure time
  (so the departure is within half a second of the plan's), and the next leg's speed
  absorbs the difference.

The replay then samples every drone and reports the pairs that come closer than the
show's ``min_distance_m`` where the plan keeps them apart (:func:`close_pairs`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Bisection steps for a leg's speed (the interval shrinks 2^-40: far below a mm/s).
_BISECTIONS = 40


@dataclass(frozen=True)
class Wpnav:
    """ArduCopter's waypoint-navigation limits (defaults of ArduCopter 4.5, SI units).

    Attributes: ``speed_mps`` (WPNAV_SPEED 10 m/s), ``speed_up_mps`` (WPNAV_SPEED_UP 2.5),
    ``speed_dn_mps`` (WPNAV_SPEED_DN 1.5), ``accel_mps2`` (WPNAV_ACCEL 2.5),
    ``accel_z_mps2`` (WPNAV_ACCEL_Z 1), ``jerk_mps3`` (WPNAV_JERK 1), ``min_speed_mps``
    (the slowest speed the missions command, 0.2 m/s).
    """

    speed_mps: float = 10.0
    speed_up_mps: float = 2.5
    speed_dn_mps: float = 1.5
    accel_mps2: float = 2.5
    accel_z_mps2: float = 1.0
    jerk_mps3: float = 1.0
    min_speed_mps: float = 0.2


ARDUCOPTER_DEFAULTS = Wpnav()


def scurve_phases(length_m, vmax, amax, jerk) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Rest-to-rest jerk-limited profile over ``length_m`` (arrays broadcast together).

    Returns ``(tj, ta, tv, vp)``: the jerk phase, the constant-acceleration phase, the
    cruise and the peak speed; the accelerating half lasts 2·tj + ta, the whole move
    2·(2·tj + ta) + tv. With acceleration reached the accelerating half covers
    vp·(vp/A + A/J)/2, else vp^(3/2)/√J; when vmax is not reached the peak solves
    2·(accelerating distance) = length (closed forms of both quadratics).
    """
    L, V, A, J = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (length_m, vmax, amax, jerk)))
    vp = np.minimum(V, _peak_speed(L, A, J))
    reaches_a = vp * J >= A * A
    tj = np.where(reaches_a, A / J, np.sqrt(vp / J))
    ta = np.where(reaches_a, vp / A - A / J, 0.0)
    accel_dist = np.where(reaches_a, vp * (vp / A + A / J) / 2.0, vp * np.sqrt(vp / J))
    tv = np.where(vp > 0, np.maximum(L - 2.0 * accel_dist, 0.0) / np.where(vp > 0, vp, 1.0), 0.0)
    return tj, ta, tv, vp


def _peak_speed(L: np.ndarray, A: np.ndarray, J: np.ndarray) -> np.ndarray:
    """The peak speed of the shortest rest-to-rest move over L (no speed limit)."""
    # Without reaching A: 2·v^(3/2)/√J = L. With A: v²/A + v·A/J = L.
    v_jerk = (L / 2.0 * np.sqrt(J)) ** (2.0 / 3.0)
    v_acc = (-A / J + np.sqrt((A / J) ** 2 + 4.0 * L / A)) * A / 2.0
    return np.where(v_jerk * J < A * A, v_jerk, v_acc)


def scurve_duration(length_m, vmax, amax, jerk) -> np.ndarray:
    """Duration (s) of the rest-to-rest move of :func:`scurve_phases`."""
    tj, ta, tv, _ = scurve_phases(length_m, vmax, amax, jerk)
    return 2.0 * (2.0 * tj + ta) + tv


def scurve_distance(u_s, length_m, vmax, amax, jerk) -> np.ndarray:
    """Distance travelled (m) at time ``u_s`` into the move (clamped to [0, duration])."""
    tj, ta, tv, vp = scurve_phases(length_m, vmax, amax, jerk)
    L = np.broadcast_to(np.asarray(length_m, dtype=np.float64), tj.shape)
    J = np.broadcast_to(np.asarray(jerk, dtype=np.float64), tj.shape)
    half = 2.0 * tj + ta
    total = 2.0 * half + tv
    u = np.clip(np.asarray(u_s, dtype=np.float64), 0.0, total)
    return np.where(u <= half + tv, _accel_distance(u, tj, ta, tv, vp, J),
                    L - _accel_distance(total - u, tj, ta, tv, vp, J))


def _accel_distance(u, tj, ta, tv, vp, J):
    """Distance at time u of the accelerating half followed by the cruise."""
    a = J * tj  # the acceleration reached
    v1, s1 = J * tj * tj / 2.0, J * tj**3 / 6.0
    v2, s2 = v1 + a * ta, s1 + v1 * ta + a * ta * ta / 2.0
    half = 2.0 * tj + ta
    s_half = s2 + v2 * tj + a * tj * tj / 2.0 - J * tj**3 / 6.0
    w2 = np.clip(u - tj, 0.0, ta)
    w3 = np.clip(u - tj - ta, 0.0, tj)
    return np.where(
        u <= tj, J * u**3 / 6.0,
        np.where(u <= tj + ta, s1 + v1 * w2 + a * w2 * w2 / 2.0,
                 np.where(u <= half, s2 + v2 * w3 + a * w3 * w3 / 2.0 - J * w3**3 / 6.0,
                          s_half + vp * (u - half))))


def _leg_limits(delta_m: np.ndarray, speed_xy, w: Wpnav) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Along-track (length, max speed, max acceleration) of straight legs ``delta_m`` (..., 3)."""
    length = np.linalg.norm(delta_m, axis=-1)
    safe = np.where(length > 0, length, 1.0)
    h = np.linalg.norm(delta_m[..., :2], axis=-1) / safe
    vz = delta_m[..., 2] / safe
    inf = np.inf
    with np.errstate(divide="ignore"):
        v_h = np.where(h > 1e-9, speed_xy / np.where(h > 1e-9, h, 1.0), inf)
        v_z = np.where(vz > 1e-9, w.speed_up_mps / np.where(vz > 1e-9, vz, 1.0),
                       np.where(vz < -1e-9, w.speed_dn_mps / np.where(vz < -1e-9, -vz, 1.0), inf))
        a_h = np.where(h > 1e-9, w.accel_mps2 / np.where(h > 1e-9, h, 1.0), inf)
        a_z = np.where(np.abs(vz) > 1e-9, w.accel_z_mps2 / np.where(np.abs(vz) > 1e-9, np.abs(vz), 1.0), inf)
    return length, np.minimum(v_h, v_z), np.minimum(a_h, a_z)


@dataclass
class Mission:
    """Every drone's timed waypoint mission and its replay (W waypoints after home, N drones).

    Attributes:
        points_m: (W+1, N, 3) home then the waypoints, local metres.
        speeds_mps: (W, N) commanded horizontal speed of the leg into waypoint k (leg 0: the takeoff, unused).
        holds_s: (W, N) whole-second hold at waypoint k.
        depart_s: (W, N) replayed departure towards waypoint k.
        arrive_s: (W, N) replayed arrival at waypoint k.
        plan_arrive_s: (W,) the plan's arrival at waypoint k.
        wpnav: the limits replayed.
    """

    points_m: np.ndarray
    speeds_mps: np.ndarray
    holds_s: np.ndarray
    depart_s: np.ndarray
    arrive_s: np.ndarray
    plan_arrive_s: np.ndarray
    wpnav: Wpnav

    def __post_init__(self) -> None:
        # Every leg's S-curve once (W, N each): a replay frame is then a gather and a polynomial.
        d = np.diff(self.points_m, axis=0)
        length, vmax, amax = _leg_limits(d, self.speeds_mps, self.wpnav)
        self._length = length
        self._phases = scurve_phases(length, vmax, amax, self.wpnav.jerk_mps3)
        self._unit = d / np.where(length > 0, length, 1.0)[..., None]

    def positions(self, t_s: float) -> np.ndarray:
        """(N, 3) replayed positions at time ``t_s`` (seconds from the mission start)."""
        n = self.points_m.shape[1]
        # The current leg: the last one departed at or before t.
        k = np.clip((self.depart_s <= t_s).sum(axis=0) - 1, 0, self.depart_s.shape[0] - 1)
        idx = np.arange(n)
        tj, ta, tv, vp = (x[k, idx] for x in self._phases)
        length = self._length[k, idx]
        half = 2.0 * tj + ta
        total = 2.0 * half + tv
        u = np.clip(t_s - self.depart_s[k, idx], 0.0, total)
        J = self.wpnav.jerk_mps3
        s = np.where(u <= half + tv, _accel_distance(u, tj, ta, tv, vp, J),
                     length - _accel_distance(total - u, tj, ta, tv, vp, J))
        pos = self.points_m[k, idx] + s[:, None] * self._unit[k, idx]
        return np.where((t_s < self.depart_s[0])[:, None], self.points_m[0], pos)


def time_mission(points_m: np.ndarray, plan_depart_s: np.ndarray, plan_arrive_s: np.ndarray,
                 max_speed_xy_mps: float, wpnav: Wpnav = ARDUCOPTER_DEFAULTS) -> Mission:
    """Choose every leg's speed and every hold so each drone keeps the plan's timing (module docstring).

    Args:
        points_m: (W+1, N, 3) home then the waypoints (waypoint 0: the takeoff's top).
        plan_depart_s: (W,) the plan's departure towards each waypoint.
        plan_arrive_s: (W,) the plan's arrival at each waypoint.
        max_speed_xy_mps: the fastest speed a leg is commanded (the show's horizontal limit).
    """
    legs, n = points_m.shape[0] - 1, points_m.shape[1]
    speeds = np.zeros((legs, n))
    holds = np.zeros((legs, n))
    depart = np.zeros((legs, n))
    arrive = np.zeros((legs, n))
    t = np.full(n, float(plan_depart_s[0]))  # the mission starts when the plan's takeoff does
    top = min(max_speed_xy_mps, wpnav.speed_mps * 10.0)
    for k in range(legs):
        d = points_m[k + 1] - points_m[k]
        if k > 0:
            # Hold at the previous waypoint: the whole seconds nearest to the plan's departure.
            holds[k - 1] = np.maximum(np.rint(plan_depart_s[k] - t), 0.0)
            t = t + holds[k - 1]
        depart[k] = t
        wanted = plan_arrive_s[k] - t
        if k == 0:
            speed = np.full(n, wpnav.speed_mps)  # NAV_TAKEOFF: straight up at WPNAV_SPEED_UP
        else:
            lo, hi = np.full(n, wpnav.min_speed_mps), np.full(n, top)
            for _ in range(_BISECTIONS):
                mid = (lo + hi) / 2.0
                length, vmax, amax = _leg_limits(d, mid, wpnav)
                slow = scurve_duration(length, vmax, amax, wpnav.jerk_mps3) > wanted
                lo, hi = np.where(slow, mid, lo), np.where(slow, hi, mid)
            speed = hi
        speeds[k] = speed
        length, vmax, amax = _leg_limits(d, speed, wpnav)
        t = t + scurve_duration(length, vmax, amax, wpnav.jerk_mps3)
        arrive[k] = t
    return Mission(points_m, speeds, holds, depart, arrive, np.asarray(plan_arrive_s, dtype=np.float64), wpnav)


def close_pairs(mission: Mission, plan, min_distance_m: float, *, max_samples: int = 6_000_000,
                dt_s: float = 0.1) -> tuple[list[tuple[int, int, float, float]], float]:
    """Pairs the replay brings closer than ``min_distance_m`` where the plan keeps them further apart.

    Samples every ``dt_s`` seconds (coarser for huge shows: at most ``max_samples``
    drone-samples), finds close pairs with a k-d tree per sample, and keeps those the
    plan (at the same time) holds at least ``min_distance_m`` apart.

    Returns:
        ``([(i, j, distance_m, time_s), ...] closest first, one entry per pair), dt_s used``.
    """
    from scipy.spatial import cKDTree

    n = mission.points_m.shape[1]
    end = float(mission.arrive_s[-1].max())
    dt = max(dt_s, end * n / max_samples)
    keys, dists, times = [], [], []
    for t in np.arange(float(mission.depart_s[0].min()), end + dt / 2, dt):
        pos = mission.positions(float(t))
        # A tree per frame: an unbalanced, uncompacted build is the cheaper one for a single query.
        tree = cKDTree(pos, balanced_tree=False, compact_nodes=False)
        pairs = tree.query_pairs(min_distance_m, output_type="ndarray")
        if not len(pairs):
            continue
        dist = np.linalg.norm(pos[pairs[:, 0]] - pos[pairs[:, 1]], axis=1)
        # The plan at the same time, for the drones in close pairs only.
        used = np.unique(pairs)
        ref = np.empty((n, 3))
        ref[used] = plan.evaluate(np.array([min(float(t), plan.duration_s)]), drones=used).positions_m[0]
        plan_dist = np.linalg.norm(ref[pairs[:, 0]] - ref[pairs[:, 1]], axis=1)
        lost = plan_dist >= min_distance_m - 1e-6
        keys.append(pairs[lost, 0].astype(np.int64) * n + pairs[lost, 1])
        dists.append(dist[lost])
        times.append(np.full(int(lost.sum()), float(t)))
    if not keys:
        return [], dt
    key, dist, when = np.concatenate(keys), np.concatenate(dists), np.concatenate(times)
    # Each pair's closest sample: sort by pair then distance, keep the first of each pair.
    order = np.lexsort((dist, key))
    first = order[np.r_[True, key[order][1:] != key[order][:-1]]]
    first = first[np.argsort(dist[first], kind="stable")]
    out = [(int(key[f] // n), int(key[f] % n), float(dist[f]), float(when[f])) for f in first]
    return out, dt
