"""A kinematic replay of waypoint missions at ArduCopter's WPNAV parameters, for the QGC export tests.

Independent of app/exports/_wpnav.py: the S-curve of each leg is built by integrating
a jerk sequence numerically (1 ms steps) and the peak speed found by bisection on that
integral, where the exporter uses closed forms. The mission is read from the files by
pymavlink's loader; ArduPilot's handling is applied as it flies: holds truncated to
whole seconds, NAV_DELAY waiting its (fractional) seconds where the drone is (a delay of 0
or less would wait for a UTC time: refused here), DO_CHANGE_SPEED setting the ground (speed
type 0 or 1), climb (2) or descent (3) speed of the legs after it, along-track limits from the
horizontal and vertical ones, rest at every waypoint (each is followed by a NAV_DELAY, the
land or nothing in the missions replayed). NAV_TAKEOFF climbs at the parameter
WPNAV_SPEED_UP, NAV_LAND descends at WPNAV_SPEED_DN (the commanded speeds do not apply).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STEP_S = 1e-3


@dataclass(frozen=True)
class Limits:
    speed_mps: float = 10.0  # WPNAV_SPEED 1000 cm/s
    speed_up_mps: float = 2.5  # WPNAV_SPEED_UP
    speed_dn_mps: float = 1.5  # WPNAV_SPEED_DN
    accel_mps2: float = 2.5  # WPNAV_ACCEL
    accel_z_mps2: float = 1.0  # WPNAV_ACCEL_Z
    jerk_mps3: float = 1.0  # WPNAV_JERK


def _half(vp: float, a_max: float, jerk: float) -> np.ndarray:
    """Distances (every STEP_S) of the jerk-limited rise from rest to speed vp."""
    a_peak = min(a_max, np.sqrt(vp * jerk))
    n1 = max(round(a_peak / jerk / STEP_S), 1)
    # The jerk phase is a whole number of steps: its jerk is adjusted (by under half a step's worth)
    # so that it reaches exactly a_peak, and the constant phase then reaches vp.
    jerk = a_peak / (n1 * STEP_S)
    n2 = max(round((vp / a_peak - n1 * STEP_S) / STEP_S), 0)
    j = np.r_[np.full(n1, jerk), np.zeros(n2), np.full(n1, -jerk)]
    h = STEP_S
    # Exact integration of a piecewise-constant jerk, step by step (a at the step's start, a0, v0):
    # a1 = a0 + j·h, v1 = v0 + a0·h + j·h²/2, s1 = s0 + v0·h + a0·h²/2 + j·h³/6.
    a = np.r_[0.0, np.cumsum(j * h)]
    v = np.r_[0.0, np.cumsum(a[:-1] * h + j * h * h / 2)]
    return np.r_[0.0, np.cumsum(v[:-1] * h + a[:-1] * h * h / 2 + j * h**3 / 6)]


def leg_profile(length: float, vmax: float, amax: float, jerk: float) -> np.ndarray:
    """Distance along the leg every STEP_S from departure to arrival."""
    if length <= 0:
        return np.zeros(1)
    lo, hi = 0.0, vmax
    if 2 * _half(vmax, amax, jerk)[-1] > length:
        for _ in range(50):
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if 2 * _half(mid, amax, jerk)[-1] <= length else (lo, mid)
        vp = lo
    else:
        vp = vmax
    rise = _half(vp, amax, jerk)
    cruise = max(length - 2 * rise[-1], 0.0)
    n_cruise = round(cruise / vp / STEP_S) if vp > 0 else 0
    mid = rise[-1] + np.arange(1, n_cruise + 1) * (cruise / max(n_cruise, 1))
    fall = length - rise[::-1]
    return np.r_[rise, mid, fall[1:]]


def along_track(delta: np.ndarray, speed_xy: float, lim: Limits, speed_up: float | None = None,
                speed_dn: float | None = None) -> tuple[float, float, float]:
    length = float(np.linalg.norm(delta))
    if length == 0:
        return 0.0, 1.0, 1.0
    h, vz = float(np.linalg.norm(delta[:2])) / length, float(delta[2]) / length
    caps_v, caps_a = [], []
    if h > 1e-9:
        caps_v.append(speed_xy / h)
        caps_a.append(lim.accel_mps2 / h)
    if vz > 1e-9:
        caps_v.append((lim.speed_up_mps if speed_up is None else speed_up) / vz)
    if vz < -1e-9:
        caps_v.append((lim.speed_dn_mps if speed_dn is None else speed_dn) / -vz)
    if abs(vz) > 1e-9:
        caps_a.append(lim.accel_z_mps2 / abs(vz))
    return length, min(caps_v), min(caps_a)


@dataclass
class Replay:
    times_s: np.ndarray  # (T,) every STEP_S... decimated
    positions_m: np.ndarray  # (T, 3)
    arrivals_s: list[float]  # arrival at each NAV item after the takeoff (top of takeoff first)
    departures_s: list[float]


def replay(items: list[tuple[int, float, float, np.ndarray]], home: np.ndarray, lim: Limits = Limits(),
           use_speed_commands: bool = True, sample_s: float = 0.05) -> Replay:
    """Fly ``items`` [(command, param1, param2, local point)] from ``home`` (local metres)."""
    t, pos = 0.0, home.astype(float)
    speed, up, dn = lim.speed_mps, lim.speed_up_mps, lim.speed_dn_mps
    times, points = [0.0], [pos.copy()]
    arrivals, departures = [], []
    hold_after = 0.0
    for cmd, p1, p2, target in items:
        if cmd == 178:  # DO_CHANGE_SPEED: param1 speed type, param2 m/s
            if use_speed_commands and p2 > 0:
                if int(p1) in (0, 1):
                    speed = p2
                elif int(p1) == 2:
                    up = p2
                elif int(p1) == 3:
                    dn = p2
            continue
        if cmd == 93:  # NAV_DELAY: wait param1 seconds where the drone is
            assert p1 > 0, "NAV_DELAY of 0 s or less waits for a UTC time of day"
            t += hold_after + p1
            hold_after = 0.0
            continue
        if cmd not in (16, 21, 22):
            continue
        t += hold_after
        times.append(t)
        points.append(pos.copy())
        departures.append(t)
        delta = target - pos
        if cmd == 16:
            length, vmax, amax = along_track(delta, speed, lim, up, dn)
        else:  # takeoff and landing at the parameters' vertical speeds
            length, vmax, amax = along_track(delta, speed, lim)
        s = leg_profile(length, vmax, amax, lim.jerk_mps3)
        k = np.arange(0, len(s), max(1, round(sample_s / STEP_S)))
        for kk in k[1:]:
            times.append(t + kk * STEP_S)
            points.append(pos + delta * (s[kk] / length if length else 1.0))
        t += (len(s) - 1) * STEP_S
        pos = target.astype(float)
        times.append(t)
        points.append(pos.copy())
        arrivals.append(t)
        hold_after = float(int(p1)) if cmd == 16 else 0.0  # ArduPilot truncates the hold
    return Replay(np.array(times), np.array(points), arrivals, departures)


def positions_at(rep: Replay, t: np.ndarray) -> np.ndarray:
    return np.stack([np.interp(t, rep.times_s, rep.positions_m[:, a]) for a in range(3)], axis=1)
