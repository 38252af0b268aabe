"""Waypoint missions that fly the plan, and their kinematic replay at ArduCopter's WPNAV defaults.

A waypoint mission cannot say *when* to be somewhere, only where to go, how fast to fly
each leg (``MAV_CMD_DO_CHANGE_SPEED``) and how long to wait (``MAV_CMD_NAV_DELAY``). So each
drone's mission is built from its own planned motion and timed against a kinematic model
of ArduCopter's waypoint navigation:

* **Legs from the plan** (:func:`plan_legs`). The planner makes a show safe by giving
  drones their own timing (staggered departures, takeoff and landing waves) and, where
  formations are spread apart, their own paths (layers, blended corners); the knots alone
  (one waypoint per formation, every drone leaving together) lose all of that. Each
  drone's trajectory is cut where it comes to rest (a piece starting or ending at zero
  speed): every cut is a waypoint reached at the plan's time, every rest a wait until the
  plan's departure. A leg whose planned path is not straight (within ``tol_m``) is cut
  where it strays most from its chord, again and again (Douglas & Peucker 1973), into at
  most :data:`MAX_SUBLEGS` sub-legs whose chords stay within ``tol_m`` of it; each cut is
  reached at the plan's time there.
* **Each leg flown rest to rest** with a jerk-limited S-curve speed profile (ArduCopter
  4.x ``SCurve``): along-track limits are the horizontal ones (commanded ground speed,
  ``WPNAV_ACCEL``) divided by the leg's horizontal share and the vertical ones (commanded
  climb / descent speed, ``WPNAV_ACCEL_Z``) divided by its vertical share, whichever
  binds; jerk ``WPNAV_JERK``; takeoff climbs at ``WPNAV_SPEED_UP``, landing descends at
  ``WPNAV_SPEED_DN``. The rest is real: every waypoint is followed by a ``NAV_DELAY``, and
  ArduCopter flies through a waypoint without stopping only when the next navigation
  command is another waypoint (``ModeAuto::do_nav_wp``).
* **Per-leg speeds on every axis**: the along-track speed is chosen (bisection on the
  S-curve's duration, which falls as the speed rises) so the drone *arrives* when the
  plan does, and commanded as ground, climb and descent speeds (``DO_CHANGE_SPEED``
  speed types 1, 2 and 3; ArduCopter 4.2+); a steep leg is no longer flown at the default
  ``WPNAV_SPEED_UP`` / ``_DN`` whatever the plan says. A leg the limits cannot fly that
  fast arrives late and the next leg catches up.
* **Waits to the millisecond**: ``NAV_DELAY`` (param1 seconds, a float; ArduCopter counts
  it in milliseconds) waits from the arrival until the plan's departure, rounded up (no
  drone leaves early) and never under :data:`MIN_DELAY_S` (a delay of 0 means "wait for
  a UTC time of day" to ArduPilot). The ``NAV_WAYPOINT`` hold (whole seconds, truncated)
  is not used.

The replay then samples every drone and reports the pairs that come closer than the
show's ``min_distance_m`` where the plan keeps them apart (:func:`close_pairs`).

What it cannot match (measured; the export then names the pairs and says to fly .skyc):
ArduCopter flies a long, slow leg at a near-constant speed after a short jerk-limited ramp,
while a drone the planner slowed by time-scaling its minimum-time profile (its "delays", the
landing on its own home) speeds up and slows down over the whole leg: the two drift apart by
up to about an eighth of the leg along its path. A blended (layered) path is flown with a stop
at each cut, which makes the drone late. Synchronised straight transitions, the common case,
are flown with the same near-constant profile by every drone, which keeps CAPT's separation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Bisection steps for a leg's speed (the interval shrinks 2^-40: far below a mm/s).
_BISECTIONS = 40
#: Shortest NAV_DELAY written, seconds (0 would mean an absolute UTC time to ArduPilot).
MIN_DELAY_S = 0.1
#: Slowest commanded ground / vertical speed, m/s (ArduPilot ignores ground speeds under 20 cm/s).
MIN_SPEED_XY_MPS = 0.2
MIN_SPEED_Z_MPS = 0.1
#: Decimals of the speeds written (the replay flies the written values).
SPEED_DECIMALS = 4
#: Samples per leg for the straightness check, and the most sub-legs a planned leg is cut into.
_STRAIGHT_SAMPLES = 64
MAX_SUBLEGS = 16
#: Moves sampled at once for the straightness check (memory: ~S·3·6 floats each).
_MOVES_PER_CHUNK = 4096
#: Speed under which a piece's end or start is at rest, m/s (a blended corner is flown far faster; the
#: rest-to-rest profiles' ends are zero to rounding).
_REST_MPS = 1e-4
#: A leg shorter than this is no leg (rounding in the planner's pieces), metres.
_MIN_LEG_M = 1e-3


@dataclass(frozen=True)
class Wpnav:
    """ArduCopter's waypoint-navigation limits (defaults of ArduCopter 4.5, SI units).

    Attributes: ``speed_mps`` (WPNAV_SPEED 10 m/s), ``speed_up_mps`` (WPNAV_SPEED_UP 2.5),
    ``speed_dn_mps`` (WPNAV_SPEED_DN 1.5), ``accel_mps2`` (WPNAV_ACCEL 2.5),
    ``accel_z_mps2`` (WPNAV_ACCEL_Z 1), ``jerk_mps3`` (WPNAV_JERK 1).
    """

    speed_mps: float = 10.0
    speed_up_mps: float = 2.5
    speed_dn_mps: float = 1.5
    accel_mps2: float = 2.5
    accel_z_mps2: float = 1.0
    jerk_mps3: float = 1.0


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


def _axis_shares(delta_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Length, horizontal share and signed vertical share of straight legs ``delta_m`` (..., 3)."""
    length = np.linalg.norm(delta_m, axis=-1)
    safe = np.where(length > 0, length, 1.0)
    return length, np.linalg.norm(delta_m[..., :2], axis=-1) / safe, delta_m[..., 2] / safe


def _safe_div(num, den) -> np.ndarray:
    """num / den where den > 1e-9, else inf (an axis the leg does not use never binds)."""
    den = np.asarray(den, dtype=np.float64)
    ok = den > 1e-9
    return np.where(ok, np.asarray(num, dtype=np.float64) / np.where(ok, den, 1.0), np.inf)


def leg_limits(delta_m: np.ndarray, speed_xy_mps, speed_up_mps, speed_dn_mps,
               w: Wpnav) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Along-track (length, max speed, max acceleration) of straight legs ``delta_m`` (..., 3).

    The horizontal limits (``speed_xy_mps``, ``WPNAV_ACCEL``) divided by the leg's horizontal
    share, the vertical ones (climb or descent speed, ``WPNAV_ACCEL_Z``) by its vertical share;
    the smaller binds.
    """
    length, h, vz = _axis_shares(delta_m)
    v = np.minimum(_safe_div(speed_xy_mps, h),
                   np.minimum(_safe_div(speed_up_mps, vz), _safe_div(speed_dn_mps, -vz)))
    a = np.minimum(_safe_div(w.accel_mps2, h), _safe_div(w.accel_z_mps2, np.abs(vz)))
    # A zero-length leg (padding) takes no time whatever its limits: keep them finite.
    return length, np.where(length > 0, v, 1.0), np.where(length > 0, a, 1.0)


def axis_speeds(delta_m: np.ndarray, along_mps: np.ndarray, top_xy_mps: float, top_up_mps: float,
                top_dn_mps: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Commanded (ground, climb, descent) speeds that fly legs ``delta_m`` at ``along_mps`` along track.

    Each axis gets its share of the along-track speed, at least the slowest speed ArduPilot
    takes (a floor that does not bind when the other axis does) and at most the show's limit;
    rounded to the decimals written in the files.
    """
    _, h, vz = _axis_shares(delta_m)
    r = SPEED_DECIMALS
    xy = np.round(np.clip(along_mps * h, MIN_SPEED_XY_MPS, top_xy_mps), r)
    up = np.round(np.clip(along_mps * np.maximum(vz, 0.0), MIN_SPEED_Z_MPS, top_up_mps), r)
    dn = np.round(np.clip(along_mps * np.maximum(-vz, 0.0), MIN_SPEED_Z_MPS, top_dn_mps), r)
    return xy, up, dn


@dataclass
class PlanLegs:
    """Every drone's waypoints and the plan's times at them (W legs, N drones, padded).

    Leg 0 is the takeoff (vertical, from home), leg W-1 the landing; legs 1..W-2 are the
    moves, ``real[k, i]`` False for padding (a zero-length leg at the drone's last point, so
    every drone has W legs in the arrays; padding is neither written nor flown).

    Attributes:
        points_m: (W+1, N, 3) home, then the end of each leg, local metres.
        depart_s: (W, N) the plan's departure on each leg.
        arrive_s: (W, N) the plan's arrival at each leg's end.
        real: (W, N) bool.
        split: (W, N) int, how many sub-legs the planned leg this one belongs to was cut into.
        max_deviation_m: the largest distance between a planned path and its sub-legs' chords.
    """

    points_m: np.ndarray
    depart_s: np.ndarray
    arrive_s: np.ndarray
    real: np.ndarray
    split: np.ndarray
    max_deviation_m: float


def _piece_states(traj, rows: np.ndarray, times_s: np.ndarray) -> np.ndarray:
    """(Q, 3) positions of drones ``rows`` (Q,) at ``times_s`` (Q,): one time per drone sample.

    The piece is found by one sorted search over every drone's breaks laid end to end (each
    row shifted past the previous one), then evaluated by Horner's rule.
    """
    b, c = traj.breaks_s, traj.coeffs_m
    n, p = b.shape[0], b.shape[1] - 1
    span = float(b[:, -1].max() - b[:, 0].min()) + 10.0
    shift = np.arange(n, dtype=np.float64) * span
    inner = (b[:, 1:-1] + shift[:, None]).ravel()  # interior breaks, (N·(P-1),), sorted
    piece = np.searchsorted(inner, times_s + shift[rows], side="right") - rows * (p - 1)
    piece = np.clip(piece, 0, p - 1)
    u = times_s - b[rows, piece]
    coeff = c[rows, piece]  # (Q, 3, D+1)
    out = coeff[..., -1].copy()
    for k in range(coeff.shape[-1] - 2, -1, -1):
        out = out * u[:, None] + coeff[..., k]
    return out


def _moves(plan, t_from: float, t_to: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every rest-to-rest move of every drone inside [t_from, t_to]: (drone, start, end time), by drone then time.

    A move is a run of consecutive moving pieces (zero-length pieces, profile phases that
    vanished, are skipped) cut wherever the drone comes to rest: a resting piece between two
    moving ones, or a junction where one piece ends or the next starts at (near) zero speed.
    """
    traj = plan.motion
    b, c = traj.breaks_s, traj.coeffs_m
    dur = np.diff(b, axis=1)
    deg = c.shape[-1] - 1
    powers = np.arange(1, deg + 1)
    v_start = np.linalg.norm(c[..., 1], axis=-1)  # (N, P)
    # velocity at the end of each piece: Σ k·c_k·dur^(k-1)
    v_end = np.linalg.norm(np.einsum("npak,npk->npa", c[..., 1:] * powers,
                                     dur[..., None] ** (powers - 1)), axis=-1)
    positive = dur > 1e-9
    moving = positive & (np.abs(c[..., 1:]).max(axis=(2, 3)) > 1e-9)
    inside = (b[:, :-1] >= t_from - 1e-9) & (b[:, 1:] <= t_to + 1e-9)
    rests = np.cumsum(positive & ~moving, axis=1)  # resting pieces so far, per drone
    d, p = np.nonzero(moving & inside)  # by drone, then piece
    if not len(d):
        return d, np.zeros(0), np.zeros(0)
    # A new move at the first piece, on a new drone, after a resting piece, or at a junction at rest.
    joined = ((d[1:] == d[:-1]) & (rests[d[1:], p[1:]] == rests[d[:-1], p[:-1]])
              & (v_end[d[:-1], p[:-1]] >= _REST_MPS) & (v_start[d[1:], p[1:]] >= _REST_MPS))
    first = np.r_[True, ~joined]
    last = np.r_[~joined, True]
    return d[first], b[d[first], p[first]], b[d[last], p[last] + 1]


def _cuts(pts: np.ndarray, tol_m: float) -> tuple[np.ndarray, float]:
    """Douglas-Peucker over the samples ``pts`` (M, S+1, 3) of M paths, all at once.

    Returns ``(cut (M, S+1) bool, the largest remaining deviation)``: the samples kept as
    waypoints (always the ends). Each round adds, on every path still straying more than
    ``tol_m`` from its polyline, the sample farthest from its chord; at most MAX_SUBLEGS - 1 rounds.
    """
    m, s1 = pts.shape[:2]
    idx = np.arange(s1)
    cut = np.zeros((m, s1), dtype=bool)
    cut[:, 0] = cut[:, -1] = True
    rows = np.arange(m)[:, None]
    dev = np.zeros((m, s1))
    for _ in range(MAX_SUBLEGS):
        prev = np.maximum.accumulate(np.where(cut, idx, 0), axis=1)
        nxt = np.minimum.accumulate(np.where(cut, idx, s1 - 1)[:, ::-1], axis=1)[:, ::-1]
        pa, pb = pts[rows, prev], pts[rows, nxt]
        d = pb - pa
        lam = np.clip(np.einsum("mqa,mqa->mq", pts - pa, d) / np.maximum(np.einsum("mqa,mqa->mq", d, d), 1e-18),
                      0.0, 1.0)
        dev = np.linalg.norm(pts - (pa + lam[..., None] * d), axis=-1)
        worst = dev.argmax(axis=1)
        add = (dev[rows[:, 0], worst] > tol_m) & (cut.sum(axis=1) <= MAX_SUBLEGS)
        if not add.any():
            break
        cut[rows[add, 0], worst[add]] = True
    return cut, float(dev.max(initial=0.0))


def plan_legs(plan, tol_m: float) -> PlanLegs:
    """Every drone's waypoint legs from its planned motion (see the module docstring).

    Args:
        plan: a :class:`sim.plan.ShowPlan` (every drone rests at the knots).
        tol_m: how far a planned path may stray from its legs' chords, metres.
    """
    traj = plan.motion
    kt = plan.knot_times_s
    n = plan.drone_count
    # Every move of every drone: its first is the takeoff (vertical, from home), its last the landing.
    drone, t0, t1 = _moves(plan, float(kt[0]), float(kt[-1]))
    first = np.r_[True, drone[1:] != drone[:-1]]
    last = np.r_[drone[1:] != drone[:-1], True]
    if np.any(np.bincount(drone, minlength=n) < 2) or np.any(first & last):
        raise ValueError("every drone's plan must take off and land")
    up_drone, up_t0, up_t1 = drone[first], t0[first], t1[first]
    down_drone, down_t0, down_t1 = drone[last], t0[last], t1[last]
    middle = ~first & ~last
    drone, t0, t1 = drone[middle], t0[middle], t1[middle]
    # Straightness: S+1 samples per move at equal times, cut where the path strays (Douglas-Peucker).
    s = _STRAIGHT_SAMPLES
    frac = np.linspace(0.0, 1.0, s + 1)
    times = t0[:, None] + (t1 - t0)[:, None] * frac
    pts = np.empty((len(drone), s + 1, 3))
    cut = np.zeros((len(drone), s + 1), dtype=bool)
    max_dev = 0.0
    # In chunks of moves: the gathered coefficients of a chunk's samples stay a few tens of MB.
    for lo in range(0, len(drone), _MOVES_PER_CHUNK):
        sl = slice(lo, lo + _MOVES_PER_CHUNK)
        m = len(drone[sl])
        pts[sl] = _piece_states(traj, np.repeat(drone[sl], s + 1), times[sl].ravel()).reshape(m, s + 1, 3)
        cut[sl], dev = _cuts(pts[sl], tol_m)
        max_dev = max(max_dev, dev)
    keep = np.linalg.norm(pts - pts[:, :1], axis=-1).max(axis=1) > _MIN_LEG_M
    drone, times, pts, cut = drone[keep], times[keep], pts[keep], cut[keep]
    parts = cut.sum(axis=1) - 1
    # The sub-legs, in order by drone and time: from each cut to the next.
    mv, at = np.nonzero(cut)  # by move, then sample
    last = np.r_[mv[1:] != mv[:-1], True]
    first = np.r_[True, mv[1:] != mv[:-1]]
    rep = mv[~last]
    sub_t0 = times[rep, at[~last]]
    sub_t1 = times[rep, at[~first]]
    sub_end = pts[rep, at[~first]]
    sub_drone = drone[rep]
    # Pad to W legs per drone: takeoff, the moves, padding, landing.
    count = np.bincount(sub_drone, minlength=n)
    m = int(count.max(initial=0))
    w = m + 2
    rank = np.arange(len(sub_drone)) - np.repeat(np.cumsum(count) - count, count)
    points = np.empty((w + 1, n, 3))
    points[0] = plan.knot_positions_m[0]
    points[1, up_drone] = _piece_states(traj, up_drone, up_t1)
    depart = np.zeros((w, n))
    arrive = np.zeros((w, n))
    real = np.zeros((w, n), dtype=bool)
    split = np.ones((w, n), dtype=np.int64)
    points[2 + rank, sub_drone] = sub_end
    depart[1 + rank, sub_drone] = sub_t0
    arrive[1 + rank, sub_drone] = sub_t1
    real[1 + rank, sub_drone] = True
    split[1 + rank, sub_drone] = parts[mv[~last]]
    # Takeoff and landing: each drone's own (waves leave at their own times).
    depart[0, up_drone], arrive[0, up_drone] = up_t0, up_t1
    depart[w - 1, down_drone], arrive[w - 1, down_drone] = down_t0, down_t1
    real[0] = real[w - 1] = True
    # Padding: zero-length legs at the last point, at the last arrival.
    for k in range(1, w - 1):
        pad = ~real[k]
        points[k + 1, pad] = points[k, pad]
        depart[k, pad] = arrive[k - 1, pad]
        arrive[k, pad] = arrive[k - 1, pad]
    points[w] = plan.knot_positions_m[-1]
    return PlanLegs(points, depart, arrive, real, split, max_dev)


@dataclass
class Mission:
    """Every drone's timed waypoint mission and its replay (W legs, N drones; see :class:`PlanLegs`).

    Attributes:
        legs: the plan's legs flown.
        speed_xy_mps, speed_up_mps, speed_dn_mps: (W, N) commanded on each leg (legs 1..W-2).
        delay_s: (W, N) the NAV_DELAY before each leg (0: none written, the takeoff of a drone
            that leaves at once and padding).
        depart_s: (W, N) replayed departure on each leg.
        arrive_s: (W, N) replayed arrival at each leg's end.
        wpnav: the limits replayed.
    """

    legs: PlanLegs
    speed_xy_mps: np.ndarray
    speed_up_mps: np.ndarray
    speed_dn_mps: np.ndarray
    delay_s: np.ndarray
    depart_s: np.ndarray
    arrive_s: np.ndarray
    wpnav: Wpnav

    @property
    def points_m(self) -> np.ndarray:
        """(W+1, N, 3) home then the end of each leg."""
        return self.legs.points_m

    def __post_init__(self) -> None:
        # Every leg's S-curve once (W, N each): a replay frame is then a gather and a polynomial.
        d = np.diff(self.points_m, axis=0)
        length, vmax, amax = leg_limits(d, self.speed_xy_mps, self.speed_up_mps, self.speed_dn_mps, self.wpnav)
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


def _wait(until_s: np.ndarray, now_s: np.ndarray) -> np.ndarray:
    """The NAV_DELAY from ``now_s`` to ``until_s``: whole milliseconds rounded up, at least MIN_DELAY_S."""
    return np.maximum(np.ceil(np.round((until_s - now_s) * 1000.0, 6)) / 1000.0, MIN_DELAY_S)


def time_mission(legs: PlanLegs, top_xy_mps: float, top_up_mps: float, top_dn_mps: float,
                 wpnav: Wpnav = ARDUCOPTER_DEFAULTS) -> Mission:
    """Choose every leg's speeds and every wait so each drone keeps the plan's timing (module docstring).

    Args:
        legs: the plan's legs (:func:`plan_legs`).
        top_xy_mps, top_up_mps, top_dn_mps: the fastest ground, climb and descent speeds commanded
            (the show's limits).
    """
    w, n = legs.depart_s.shape
    pts = legs.points_m
    xy = np.full((w, n), wpnav.speed_mps)
    up = np.full((w, n), wpnav.speed_up_mps)
    dn = np.full((w, n), wpnav.speed_dn_mps)
    delay = np.zeros((w, n))
    depart = np.zeros((w, n))
    arrive = np.zeros((w, n))
    # The mission starts at the plan's t = 0; a drone of a later takeoff wave waits on the ground.
    t = np.zeros(n)
    delay[0] = np.where(legs.depart_s[0] > MIN_DELAY_S / 2, _wait(legs.depart_s[0], t), 0.0)
    for k in range(w):
        d = pts[k + 1] - pts[k]
        real = legs.real[k]
        if k > 0:
            delay[k] = np.where(real, _wait(legs.depart_s[k], t), 0.0)
        t = t + delay[k]
        depart[k] = t
        if 0 < k < w - 1:
            wanted = legs.arrive_s[k] - t
            _, h, vz = _axis_shares(d)
            hi = np.minimum(_safe_div(top_xy_mps, h), np.minimum(_safe_div(top_up_mps, vz), _safe_div(top_dn_mps, -vz)))
            hi = np.where(np.isfinite(hi), hi, top_xy_mps)
            lo = np.full(n, 1e-3)
            for _ in range(_BISECTIONS):
                mid = (lo + hi) / 2.0
                length, vmax, amax = leg_limits(d, *axis_speeds(d, mid, top_xy_mps, top_up_mps, top_dn_mps), wpnav)
                slow = scurve_duration(length, vmax, amax, wpnav.jerk_mps3) > wanted
                lo, hi = np.where(slow, mid, lo), np.where(slow, hi, mid)
            xy[k], up[k], dn[k] = axis_speeds(d, hi, top_xy_mps, top_up_mps, top_dn_mps)
        elif k == w - 1:
            # NAV_LAND descends at the descent speed in force; the missions leave it at WPNAV_SPEED_DN.
            xy[k], up[k], dn[k] = wpnav.speed_mps, wpnav.speed_up_mps, wpnav.speed_dn_mps
        length, vmax, amax = leg_limits(d, xy[k], up[k], dn[k], wpnav)
        t = t + np.where(real | (k == 0) | (k == w - 1), scurve_duration(length, vmax, amax, wpnav.jerk_mps3), 0.0)
        arrive[k] = t
    return Mission(legs, xy, up, dn, delay, depart, arrive, wpnav)


def _moving_frames(mission: Mission, plan, grid_s: np.ndarray, dt_s: float) -> np.ndarray:
    """(T,) bool: the frames of ``grid_s`` within ``dt_s`` of an instant where some replayed drone or the plan
    moves. Every other frame lies in a stretch where nothing moves, so it repeats the kept frame just before
    it (positions, distances and the plan's alike) and the pair search may skip it: a show with day-long
    holds then costs frames for its moves only (it sampled every 0.1 s of every hold)."""
    # Replayed moves: each leg from its departure to its arrival (the drone is still outside them).
    a = [mission.depart_s.ravel()]
    b = [mission.arrive_s.ravel()]
    # The plan's: everything but its holds (still: the QGC export refuses a show with a moving hold).
    segs = [(sg.start_s, sg.end_s) for sg in plan.segments if sg.kind != "hold"]
    if segs:
        a.append(np.array([x for x, _ in segs], dtype=np.float64))
        b.append(np.array([y for _, y in segs], dtype=np.float64))
    start, stop = np.concatenate(a) - dt_s, np.concatenate(b) + dt_s
    order = np.argsort(start, kind="stable")
    start, stop = start[order], np.maximum.accumulate(stop[order])
    # Merged windows: a new one begins where a start exceeds every earlier stop.
    new = np.r_[True, start[1:] > stop[:-1]]
    w0, w1 = start[new], np.r_[stop[np.flatnonzero(new)[1:] - 1], stop[-1]]
    k = np.searchsorted(w0, grid_s, side="right") - 1
    return (k >= 0) & (grid_s <= w1[np.maximum(k, 0)])


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
    grid = np.arange(float(mission.depart_s[0].min()), end + dt / 2, dt)
    for t in grid[_moving_frames(mission, plan, grid, dt)]:
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
        # Closer by more than rounding (1 µm: parked drones on a grid spaced exactly min_distance_m) where the
        # plan keeps the pair at least min_distance_m apart (to the same rounding).
        lost = (dist < min_distance_m - 1e-6) & (plan_dist >= min_distance_m - 1e-6)
        keys.append(pairs[lost, 0].astype(np.int64) * n + pairs[lost, 1])
        dists.append(dist[lost])
        times.append(np.full(int(lost.sum()), float(t)))
    if not keys:
        return [], dt
    key, dist, when = np.concatenate(keys), np.concatenate(dists), np.concatenate(times)
    if not key.size:  # close pairs only where the plan has them close too
        return [], dt
    # Each pair's closest sample: sort by pair then distance, keep the first of each pair.
    order = np.lexsort((dist, key))
    first = order[np.r_[True, key[order][1:] != key[order][:-1]]]
    first = first[np.argsort(dist[first], kind="stable")]
    out = [(int(key[f] // n), int(key[f] % n), float(dist[f]), float(when[f])) for f in first]
    return out, dt
