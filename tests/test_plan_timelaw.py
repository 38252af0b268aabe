"""Time laws: the jerk-limited double S against closed forms, a numerical optimum and dense sampling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

from sim.plan._quintic import rest_to_rest
from sim.plan._timelaw import (
    double_s_phases,
    double_s_profiles,
    double_s_stretched,
    evaluate_profiles,
    min_time_leg_duration,
    path_speed_limit,
    quintic_profiles,
    time_scaled,
)


def sample(h, v, a, j, *, stretched_to=None, n=20001):
    """Dense samples (u, x, x', x'', x''') of the double S in metres (not normalised)."""
    h = np.atleast_1d(np.asarray(h, dtype=float))
    ph = double_s_phases(h, v, a, j) if stretched_to is None else double_s_stretched(h, v, a, j, stretched_to)
    prof = double_s_profiles(ph, h)
    u = np.linspace(0.0, float(ph.duration_s[0]), n)[:, None]
    out = [evaluate_profiles(prof, u, d)[:, 0] * h[0] for d in range(4)]
    return u[:, 0], out, ph, prof


def test_closed_form_cases_by_hand() -> None:
    # Cruise with a constant-acceleration phase: Tj = a/j, Ta = Tj + v/a, Tv = h/v - Ta.
    ph = double_s_phases(100.0, 10.0, 4.0, 10.0)
    assert (float(ph.tj), float(ph.ta), float(ph.tv)) == pytest.approx((0.4, 2.9, 7.1))
    # No cruise, a reached: Ta = (a²/j + √(a⁴/j² + 4ah)) / 2a.
    ph = double_s_phases(10.0, 10.0, 4.0, 10.0)
    assert float(ph.tv) == 0.0
    assert float(ph.ta) == pytest.approx((1.6 + np.sqrt(2.56 + 160.0)) / 8.0)
    # Neither v nor a reached: Tj = (h / 2j)^(1/3), Ta = 2 Tj.
    ph = double_s_phases(0.01, 10.0, 4.0, 10.0)
    assert float(ph.tj) == pytest.approx((0.01 / 20.0) ** (1 / 3))
    assert float(ph.ta) == pytest.approx(2 * float(ph.tj))
    # v reached without a constant-acceleration phase (v·j < a²): Tj = √(v/j).
    ph = double_s_phases(100.0, 1.0, 4.0, 10.0)
    assert float(ph.tj) == pytest.approx(np.sqrt(0.1))
    assert float(ph.duration_s) == pytest.approx(100.0 + 2 * np.sqrt(0.1))


@settings(max_examples=60, deadline=None)
@given(h=st.floats(1e-3, 500.0), v=st.floats(0.2, 20.0), a=st.floats(0.3, 10.0), j=st.floats(0.5, 50.0),
       stretch=st.one_of(st.none(), st.floats(1.0, 3.0)))
def test_limits_hold_and_motion_is_continuous(h, v, a, j, stretch) -> None:
    t_min = float(double_s_phases(h, v, a, j).duration_s)
    u, (x, xd, xdd, xddd), ph, prof = sample(h, v, a, j, stretched_to=None if stretch is None else stretch * t_min)
    if stretch is not None:
        assert float(ph.duration_s[0]) == pytest.approx(stretch * t_min, rel=1e-9)
    assert x[0] == pytest.approx(0.0, abs=1e-12) and x[-1] == pytest.approx(h, rel=1e-9)
    assert xd[0] == pytest.approx(0.0, abs=1e-9 * v) and abs(xd[-1]) <= 1e-7 * max(v, 1)
    assert np.all(np.diff(x) >= -1e-12 * h)  # monotone: the drone never backs up
    assert np.max(np.abs(xd)) <= v * (1 + 1e-9)
    assert np.max(np.abs(xdd)) <= a * (1 + 1e-9)
    assert np.max(np.abs(xddd)) <= j * (1 + 1e-9)
    # Continuity of position, velocity and acceleration across every piece boundary.
    b = prof.breaks_s[0]
    for k in range(1, 7):
        left = [evaluate_profiles(prof, np.array([b[k] - 1e-9]), d)[0] for d in range(3)]
        right = [evaluate_profiles(prof, np.array([b[k] + 1e-9]), d)[0] for d in range(3)]
        scale = [1.0, v / h, a / h]
        for d in range(3):
            assert left[d] == pytest.approx(right[d], abs=1e-6 * scale[d] + 1e-12)


def lp_feasible(h: float, v: float, a: float, j: float, T: float, steps: int = 120) -> bool:
    """Is there a piecewise-constant-jerk rest-to-rest motion of length h in time T (an LP)?"""
    dt = T / steps
    # State after k steps is linear in the jerks j_0..j_{k-1} (exact integration of constant jerk).
    k = np.arange(steps)
    rem = (steps - 1 - k) * dt  # time from the end of step k to T
    acc_row = np.full(steps, dt)
    vel_row = dt * dt / 2 + dt * rem
    pos_row = dt**3 / 6 + dt * dt / 2 * rem + dt * rem**2 / 2
    a_eq = np.vstack([acc_row, vel_row, pos_row])
    b_eq = np.array([0.0, 0.0, h])
    # Speed and acceleration at every step end: lower-triangular maps.
    tri = np.tril(np.ones((steps, steps)))
    acc_at = tri * dt
    m = np.arange(steps)[:, None]
    r = (m - k[None, :]) * dt
    vel_at = np.where(k[None, :] <= m, dt * dt / 2 + dt * r, 0.0)
    a_ub = np.vstack([acc_at, -acc_at, vel_at, -vel_at])
    b_ub = np.concatenate([np.full(steps, a), np.full(steps, a), np.full(steps, v), np.full(steps, v)])
    res = linprog(np.zeros(steps), A_ub=a_ub, b_ub=b_ub, A_eq=a_eq, b_eq=b_eq, bounds=[(-j, j)] * steps,
                  method="highs")
    return res.status == 0


@pytest.mark.parametrize("h, v", [(0.05, 10.0), (2.0, 10.0), (12.0, 2.0), (30.0, 10.0)])
def test_min_time_is_not_beaten_by_a_numerical_optimum(h: float, v: float) -> None:
    """No piecewise-constant-jerk motion (an LP over 120 steps) is 3% faster; 3% slower is feasible."""
    a, j = 4.0, 10.0
    t = float(double_s_phases(h, v, a, j).duration_s)
    assert not lp_feasible(h, v, a, j, 0.97 * t)
    assert lp_feasible(h, v, a, j, 1.03 * t)


def test_quintic_profile_matches_the_papers_law() -> None:
    T = 7.3
    prof = quintic_profiles([T])
    u = np.linspace(0, T, 101)
    law = rest_to_rest(u / T, T)
    assert evaluate_profiles(prof, u[:, None])[:, 0] == pytest.approx(law.s, abs=1e-12)
    assert evaluate_profiles(prof, u[:, None], 1)[:, 0] == pytest.approx(law.s_d, abs=1e-12)
    assert evaluate_profiles(prof, u[:, None], 2)[:, 0] == pytest.approx(law.s_dd, abs=1e-12)


def test_time_scaling_slows_everything() -> None:
    ph = double_s_phases(np.array([20.0]), 10.0, 4.0, 10.0)
    prof = double_s_profiles(ph, np.array([20.0]))
    slow = time_scaled(prof, 2.0)
    u = np.linspace(0, float(ph.duration_s[0]), 50)
    assert evaluate_profiles(slow, 2 * u[:, None])[:, 0] == pytest.approx(evaluate_profiles(prof, u[:, None])[:, 0])
    assert evaluate_profiles(slow, 2 * u[:, None], 1)[:, 0] == pytest.approx(
        evaluate_profiles(prof, u[:, None], 1)[:, 0] / 2)


def test_per_axis_speed_limit_of_a_straight_leg() -> None:
    d = np.array([[10.0, 0, 0], [0, 0, 10.0], [0, 0, -10.0], [3.0, 4.0, 10.0], [0, 0, 0]])
    lim = path_speed_limit(d, 10.0, 2.0, v_down=1.0)
    assert lim[0] == pytest.approx(10.0) and lim[1] == pytest.approx(2.0) and lim[2] == pytest.approx(1.0)
    # (5, 10)/|.|: horizontal 10/(5/√125), vertical 2/(10/√125): the vertical one binds.
    assert lim[3] == pytest.approx(2.0 * np.sqrt(125) / 10)
    # A takeoff of 10 m at 2 m/s, 4 m/s², 10 m/s³: 0.4 s jerk, 0.9 s accelerating, 4.1 s cruise.
    assert min_time_leg_duration(d[1:2], v_xy=10, v_z=2, a=4, j=10)[0] == pytest.approx(5.9)
