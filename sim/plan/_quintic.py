"""Quintic time law (docs/method.md; Mueller, Hehn & D'Andrea 2015, eqs. 15-19).

Two forms of the same polynomial:

* :func:`quintic_coefficients` / :func:`quintic_eval`: the general coefficient
  form for arbitrary boundary position, velocity and acceleration (eqs. 15-19).
* :func:`rest_to_rest`: the hover-move-hover special case
  ``s(τ) = 10τ³ - 15τ⁴ + 6τ⁵`` (τ = t/T) with its time derivatives, which CAPT
  shares between all drones of a transition (a common β(t) keeps straight lines).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

#: Peak of ds/dτ for the rest-to-rest quintic: a leg of length L flown in T peaks at 1.875·L/T.
PEAK_SPEED_FACTOR = 1.875
#: Peak of |d²s/dτ²|: 10/√3 ≈ 5.7735, reached at τ = (3 ∓ √3)/6; peak acceleration (10/√3)·L/T².
PEAK_ACCEL_FACTOR = 10.0 / math.sqrt(3.0)
#: τ at which the acceleration peaks (the deceleration peak is at 1 - this).
TAU_PEAK_ACCEL = (3.0 - math.sqrt(3.0)) / 6.0


class QuinticCoefficients(NamedTuple):
    """α1, α2, α3 of eq. 15 plus the initial state, broadcast over any leading shape."""

    alpha1: np.ndarray
    alpha2: np.ndarray
    alpha3: np.ndarray
    p0: np.ndarray
    v0: np.ndarray
    a0: np.ndarray


def quintic_coefficients(
    p0: ArrayLike,
    pf: ArrayLike,
    duration_s: float,
    *,
    v0: ArrayLike = 0.0,
    a0: ArrayLike = 0.0,
    vf: ArrayLike = 0.0,
    af: ArrayLike = 0.0,
) -> QuinticCoefficients:
    """Coefficients of the minimum-jerk quintic between two full states (eq. 15).

    Args:
        p0, pf: start and end positions, metres (any broadcastable shape).
        duration_s: T, seconds (> 0).
        v0, a0, vf, af: boundary velocities (m/s) and accelerations (m/s²).

    Returns:
        α1 (m/s⁵), α2 (m/s⁴), α3 (m/s³) and the initial state.
    """
    if not duration_s > 0:
        raise ValueError(f"duration_s must be > 0, got {duration_s}")
    T = float(duration_s)
    p0, pf, v0, a0, vf, af = (np.asarray(x, dtype=np.float64) for x in (p0, pf, v0, a0, vf, af))
    dp = pf - p0 - v0 * T - a0 * T**2 / 2.0
    dv = vf - v0 - a0 * T
    da = af - a0
    a1 = (720.0 * dp - 360.0 * T * dv + 60.0 * T**2 * da) / T**5
    a2 = (-360.0 * T * dp + 168.0 * T**2 * dv - 24.0 * T**3 * da) / T**5
    a3 = (60.0 * T**2 * dp - 24.0 * T**3 * dv + 3.0 * T**4 * da) / T**5
    return QuinticCoefficients(a1, a2, a3, p0, v0, a0)


def quintic_eval(c: QuinticCoefficients, t_s: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position (m), velocity (m/s) and acceleration (m/s²) of eqs. 16-18 at times ``t_s`` (s)."""
    t = np.asarray(t_s, dtype=np.float64)
    p = c.alpha1 * t**5 / 120 + c.alpha2 * t**4 / 24 + c.alpha3 * t**3 / 6 + c.a0 * t**2 / 2 + c.v0 * t + c.p0
    v = c.alpha1 * t**4 / 24 + c.alpha2 * t**3 / 6 + c.alpha3 * t**2 / 2 + c.a0 * t + c.v0
    a = c.alpha1 * t**3 / 6 + c.alpha2 * t**2 / 2 + c.alpha3 * t + c.a0
    return p, v, a


class RestToRest(NamedTuple):
    """s(t) and its time derivatives for one or many (τ, T): dimensionless, 1/s, 1/s², 1/s³, 1/s⁴."""

    s: np.ndarray
    s_d: np.ndarray
    s_dd: np.ndarray
    s_ddd: np.ndarray
    s_dddd: np.ndarray


def rest_to_rest(tau: ArrayLike, duration_s: ArrayLike) -> RestToRest:
    """The rest-to-rest quintic s = 10τ³ - 15τ⁴ + 6τ⁵ and its derivatives in time.

    Args:
        tau: normalised time t/T in [0, 1] (not clipped here).
        duration_s: T, seconds (> 0), broadcast against ``tau``.
    """
    x = np.asarray(tau, dtype=np.float64)
    T = np.asarray(duration_s, dtype=np.float64)
    x2 = x * x
    x3 = x2 * x
    s = x3 * (10.0 + x * (-15.0 + 6.0 * x))
    s_d = 30.0 * x2 * (1.0 - x) ** 2 / T
    s_dd = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / T**2
    s_ddd = 60.0 * (1.0 - 6.0 * x + 6.0 * x2) / T**3
    s_dddd = 360.0 * (2.0 * x - 1.0) / T**4
    return RestToRest(s, s_d, s_dd, s_ddd, s_dddd)


def invert_rest_to_rest(s: ArrayLike) -> np.ndarray:
    """τ in [0, 1] with 10τ³ - 15τ⁴ + 6τ⁵ = s, for s in [0, 1] (vectorised Newton + bisection).

    The polynomial is strictly increasing on (0, 1), so the root is unique.
    """
    target = np.clip(np.asarray(s, dtype=np.float64), 0.0, 1.0)
    lo = np.zeros_like(target)
    hi = np.ones_like(target)
    x = target.copy()  # s(τ) ≈ τ near the middle: a fine first guess
    for _ in range(60):
        f = x**3 * (10.0 + x * (-15.0 + 6.0 * x)) - target
        lo = np.where(f < 0, x, lo)
        hi = np.where(f >= 0, x, hi)
        df = 30.0 * x**2 * (1.0 - x) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = x - f / df
        # Newton where it stays inside the bracket, bisection otherwise (flat ends at τ=0, 1).
        x = np.where((newton > lo) & (newton < hi) & (df > 1e-12), newton, 0.5 * (lo + hi))
        if np.all(hi - lo < 1e-15) or np.all(np.abs(f) < 1e-15):
            break
    return x
