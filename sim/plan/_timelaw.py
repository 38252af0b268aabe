"""Rest-to-rest time laws along a straight leg: the paper's quintic and the jerk-limited minimum-time S-curve.

A leg from A to B = A + D is flown as p(t) = A + s(t)·D with a scalar, nondecreasing
profile s from 0 to 1. Profiles are stored as piecewise polynomials in local time:
``breaks_s`` (n, 8) (seven pieces; unused ones have zero length) and ``coeffs`` (n, 7, 6)
ascending powers, so both laws share one representation and map one-to-one onto
:class:`sim.plan.Trajectories` pieces (coefficients D ⊗ c, constant A).

**Minimum time (double S).** Biagiotti & Melchiorri, *Trajectory Planning for Automatic
Machines and Robots* (Springer 2008), section 3.4: for a displacement h under
|v| <= v, |a| <= a, |j| <= j the fastest rest-to-rest motion is the 7-phase profile
jerk +j, 0, -j (accelerate), 0 (cruise), -j, 0, +j (decelerate), a piecewise cubic with
continuous velocity and acceleration. Closed forms for v0 = v1 = 0 (eqs. 3.25-3.27):

* v reached (v·j >= a²: Tj = a/j, Ta = Tj + v/a; else Tj = √(v/j), Ta = 2Tj) and
  Tv = h/v - Ta >= 0;
* otherwise no cruise: Tj = a/j, Ta = (a²/j + √(a⁴/j² + 4ah)) / (2a) when Ta >= 2Tj,
  else a is not reached either: Tj = (h/(2j))^(1/3), Ta = 2Tj.

Total time T = 2Ta + Tv. On a straight leg of direction u the vector limits become
scalar: speed <= min(v_xy/|u_xy|, v_z/|u_z|), |a| <= a_max, |jerk| <= j_max.

**Stretched.** To make a leg last a given longer time T (synchronising drones), the
cruise speed is lowered until the same a, j profile takes exactly T: T(v) is
continuous and strictly decreasing in v, so bisection on v finds it (the accelerations
and jerk stay within their limits, the speed drops).

**Default jerk.** 10 m/s³ (``Settings.max_jerk_mps3``): PX4's multicopter default
``MPC_JERK_AUTO`` is 4 m/s³ for smooth auto missions and ``MPC_JERK_MAX`` 8 m/s³
(PX4 user guide, "Multicopter jerk-limited type trajectory"); show drones use stiffer
tunings, and 10 m/s³ lets a 4 m/s² acceleration build up in 0.4 s.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

#: Pieces per profile (the 7 phases of the double S; the quintic uses the first).
PIECES = 7
#: Polynomial degree stored per piece (quintic: 5; double S: 3).
DEGREE = 5
#: Jerk pattern of the 7 phases, in units of j (Biagiotti & Melchiorri, fig. 3.18).
_JERK_SIGNS = np.array([1.0, 0.0, -1.0, 0.0, -1.0, 0.0, 1.0])


class Profiles(NamedTuple):
    """n scalar rest-to-rest profiles s(u), u in [0, duration]: s(0) = 0, s(duration) = 1.

    ``breaks_s`` (n, 8) local piece starts (breaks[:, 0] = 0, breaks[:, -1] = duration),
    ``coeffs`` (n, 7, 6) ascending powers of the local time within each piece.
    """

    breaks_s: np.ndarray
    coeffs: np.ndarray

    @property
    def duration_s(self) -> np.ndarray:
        """(n,) durations, seconds."""
        return self.breaks_s[:, -1]


class DoubleS(NamedTuple):
    """Phase durations of a rest-to-rest double S (arrays broadcast over drones), seconds."""

    tj: np.ndarray  # jerk phase
    ta: np.ndarray  # whole acceleration phase (= deceleration phase)
    tv: np.ndarray  # cruise
    jerk: np.ndarray  # the jerk magnitude used

    @property
    def duration_s(self) -> np.ndarray:
        return np.asarray(2.0 * self.ta + self.tv, dtype=np.float64)


def double_s_phases(h: ArrayLike, v: ArrayLike, a: ArrayLike, j: ArrayLike) -> DoubleS:
    """Minimum-time rest-to-rest double-S phases for displacement h >= 0 under v, a, j > 0 (closed form)."""
    h, v, a, j = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (h, v, a, j)))
    # Case 1: v reached (with or without a constant-acceleration phase).
    a_reach = v * j >= a * a
    tj1 = np.where(a_reach, a / j, np.sqrt(v / j))
    ta1 = np.where(a_reach, tj1 + v / a, 2.0 * tj1)
    tv1 = h / v - ta1
    # Case 2: no cruise. 2a: a reached; 2b: neither v nor a reached.
    tj2 = a / j
    ta2 = (a * a / j + np.sqrt(a**4 / j**2 + 4.0 * a * h)) / (2.0 * a)
    tj3 = np.cbrt(h / (2.0 * j))
    no_a = ta2 < 2.0 * tj2
    tj_nc = np.where(no_a, tj3, tj2)
    ta_nc = np.where(no_a, 2.0 * tj3, ta2)
    cruise = tv1 >= 0
    tj = np.where(cruise, tj1, tj_nc)
    ta = np.where(cruise, ta1, ta_nc)
    tv = np.where(cruise, tv1, 0.0)
    zero = h <= 0
    return DoubleS(np.where(zero, 0.0, tj), np.where(zero, 0.0, ta), np.where(zero, 0.0, tv), j)


def double_s_duration(h: ArrayLike, v: ArrayLike, a: ArrayLike, j: ArrayLike) -> np.ndarray:
    """Minimum rest-to-rest time (seconds) for displacement h under v, a, j."""
    return double_s_phases(h, v, a, j).duration_s


def double_s_stretched(h: ArrayLike, v: ArrayLike, a: ArrayLike, j: ArrayLike, duration_s: ArrayLike) -> DoubleS:
    """The double S for h under a, j whose cruise speed (<= v) makes it last exactly ``duration_s``.

    Durations shorter than the minimum give the minimum-time profile. Bisection on the
    cruise speed (T(v) is continuous and strictly decreasing), 60 halvings: relative 1e-18.
    """
    h, v, a, j, t = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (h, v, a, j, duration_s)))
    fast = double_s_phases(h, v, a, j)
    need = (t > fast.duration_s) & (h > 0)
    lo = np.zeros_like(v)
    hi = v.copy()
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        slow = double_s_duration(h, np.where(need, np.maximum(mid, 1e-300), v), a, j) > t
        lo = np.where(slow, mid, lo)
        hi = np.where(slow, hi, mid)
    v_fit = np.where(need, hi, v)
    out = double_s_phases(h, v_fit, a, j)
    # The cruise absorbs the last rounding so that the duration is exact.
    tv = np.where(need, np.maximum(t - 2.0 * out.ta, 0.0), out.tv)
    return DoubleS(out.tj, out.ta, tv, out.jerk)


def double_s_profiles(phases: DoubleS, h: ArrayLike) -> Profiles:
    """Piecewise-cubic s(u) = x(u)/h of the double S moving a distance h (h = 0 gives a constant 0... 1 step).

    The cruise phase takes whatever time remains so that s ends exactly at 1.
    """
    h = np.broadcast_to(np.asarray(h, dtype=np.float64), phases.tj.shape).astype(np.float64)
    n = h.shape[0]
    tj, ta, tv, jerk = (np.broadcast_to(x, (n,)) for x in phases)
    dur = np.stack([tj, ta - 2.0 * tj, tj, tv, tj, ta - 2.0 * tj, tj], axis=1)
    dur = np.maximum(dur, 0.0)
    breaks = np.zeros((n, PIECES + 1))
    breaks[:, 1:] = np.cumsum(dur, axis=1)
    coeffs = np.zeros((n, PIECES, DEGREE + 1))
    safe_h = np.where(h > 0, h, 1.0)
    jn = np.where(h > 0, jerk / safe_h, 0.0)  # normalised jerk, 1/s³
    x = np.zeros(n)
    xd = np.zeros(n)
    xdd = np.zeros(n)
    for k in range(PIECES):
        jk = _JERK_SIGNS[k] * jn
        coeffs[:, k, 0] = x
        coeffs[:, k, 1] = xd
        coeffs[:, k, 2] = xdd / 2.0
        coeffs[:, k, 3] = jk / 6.0
        u = dur[:, k]
        x = x + xd * u + xdd * u**2 / 2.0 + jk * u**3 / 6.0
        xd = xd + xdd * u + jk * u**2 / 2.0
        xdd = xdd + jk * u
    # Rounding leaves s(T) = 1 ± 1e-15; put the remainder in the cruise (or last) constant term scale.
    end = np.where(h > 0, x, 1.0)
    coeffs = coeffs / end[:, None, None]
    coeffs[h <= 0] = 0.0
    coeffs[h <= 0, -1, 0] = 1.0  # a zero leg: s jumps to 1 at no distance (nothing moves)
    return Profiles(breaks, coeffs)


def quintic_profiles(duration_s: ArrayLike) -> Profiles:
    """s(u) = 10τ³ - 15τ⁴ + 6τ⁵, τ = u/T, as the first piece (the other six have zero length)."""
    t = np.atleast_1d(np.asarray(duration_s, dtype=np.float64))
    n = len(t)
    breaks = np.repeat(t[:, None], PIECES + 1, axis=1)
    breaks[:, 0] = 0.0
    coeffs = np.zeros((n, PIECES, DEGREE + 1))
    safe = np.where(t > 0, t, 1.0)
    coeffs[:, 0, 3] = 10.0 / safe**3
    coeffs[:, 0, 4] = -15.0 / safe**4
    coeffs[:, 0, 5] = 6.0 / safe**5
    coeffs[:, 1:, 0] = 1.0  # zero-length pieces carry s = 1 (their Taylor polynomial at u = T)
    coeffs[t <= 0, 0] = 0.0
    coeffs[t <= 0, 0, 0] = 1.0
    return Profiles(breaks, coeffs)


def time_scaled(p: Profiles, factor: ArrayLike) -> Profiles:
    """s(u / k): the same path k >= 1 times slower (speed / k, acceleration / k², jerk / k³)."""
    k = np.broadcast_to(np.asarray(factor, dtype=np.float64), (len(p.breaks_s),))
    powers = k[:, None, None] ** -np.arange(DEGREE + 1)[None, None, :]
    return Profiles(p.breaks_s * k[:, None], p.coeffs * powers)


def evaluate_profiles(p: Profiles, u_s: ArrayLike, derivative: int = 0) -> np.ndarray:
    """s (or its ``derivative``-th time derivative) of every profile at local times ``u_s`` (n,) or (T, n).

    Before 0 the profile rests at 0, after its duration at 1 (derivatives 0 there).
    """
    u = np.asarray(u_s, dtype=np.float64)
    dur = p.breaks_s[:, -1]
    uc = np.clip(u, 0.0, dur)
    k = np.zeros(uc.shape, dtype=np.int64)
    for m in range(1, PIECES):
        k = k + (uc >= p.breaks_s[:, m]) * (p.breaks_s[:, m] < dur)
    rows = np.broadcast_to(np.arange(len(dur)), uc.shape)
    c = p.coeffs[rows, k]
    x = uc - p.breaks_s[rows, k]
    c = _derivative(c, derivative)
    out = np.zeros(uc.shape)
    for m in range(c.shape[-1] - 1, -1, -1):
        out = out * x + c[..., m]
    if derivative:
        out = np.where((u < 0) | (u > dur), 0.0, out)
    return out


def _derivative(c: np.ndarray, order: int) -> np.ndarray:
    for _ in range(order):
        c = c[..., 1:] * np.arange(1, c.shape[-1])
    return c


def path_speed_limit(d: np.ndarray, v_xy: float, v_z: float, v_down: float | None = None) -> np.ndarray:
    """(n,) scalar speed limit along straight legs d (n, 3): min(v_xy/|u_xy|, v_z/|u_z|), m/s.

    ``v_down`` (optional) replaces ``v_z`` for descending legs.
    """
    length = np.linalg.norm(d, axis=1)
    safe = np.where(length > 0, length, 1.0)
    uxy = np.hypot(d[:, 0], d[:, 1]) / safe
    uz = d[:, 2] / safe
    vz = np.where(uz < 0, v_z if v_down is None else v_down, v_z)
    with np.errstate(divide="ignore"):
        lim = np.minimum(np.where(uxy > 0, v_xy / np.maximum(uxy, 1e-300), np.inf),
                         np.where(uz != 0, vz / np.maximum(np.abs(uz), 1e-300), np.inf))
    return np.where(length > 0, lim, v_xy)


def min_time_leg_duration(d: np.ndarray, *, v_xy: float, v_z: float, a: float, j: float,
                          v_down: float | None = None) -> np.ndarray:
    """(n,) minimum rest-to-rest times (s) of straight legs d (n, 3) under the per-axis speed, a and j limits."""
    length = np.linalg.norm(d, axis=1)
    return double_s_duration(length, path_speed_limit(d, v_xy, v_z, v_down), a, j)


def quintic_leg_duration(d: np.ndarray, *, v_xy: float, v_z: float, a: float,
                         v_down: float | None = None) -> np.ndarray:
    """(n,) shortest times (s) of quintic legs: peak speed 1.875·L/T and peak accel (10/√3)·L/T² within limits."""
    length = np.linalg.norm(d, axis=1)
    v = path_speed_limit(d, v_xy, v_z, v_down)
    return np.asarray(np.maximum(1.875 * length / v, np.sqrt(10.0 / math.sqrt(3.0) * length / a)), dtype=np.float64)


__all__ = [
    "DoubleS",
    "Profiles",
    "double_s_duration",
    "double_s_phases",
    "double_s_profiles",
    "double_s_stretched",
    "evaluate_profiles",
    "min_time_leg_duration",
    "path_speed_limit",
    "quintic_leg_duration",
    "quintic_profiles",
    "time_scaled",
]
