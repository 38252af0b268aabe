"""Per-drone piecewise polynomials (sim.plan.Trajectories) against a per-drone brute-force evaluation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.polynomial import polynomial as P

from sim.plan import Trajectories, TrajectoryBuilder, states_at
from sim.plan._trajectory import rest_to_rest_quintic_coeffs


def _random_builder(rng: np.random.Generator, n: int, pieces: int) -> TrajectoryBuilder:
    """Random continuous motion: each piece a random polynomial continuing from where the drone is.

    A third of the pieces have zero length (as vanishing profile phases do), and every
    drone has its own durations, so no two drones share piece boundaries.
    """
    b = TrajectoryBuilder(rng.uniform(-50, 50, (n, 3)), start_s=rng.uniform(-2, 2))
    for _ in range(pieces):
        dur = rng.uniform(0.1, 5.0, n) * (rng.random(n) > 0.33)
        c = np.concatenate([b.positions_m[..., None], rng.normal(0, 1, (n, 3, 5))], axis=-1)
        b.append(dur, c)
    b.hold_until(b.times_s.max() + rng.uniform(0, 1))
    return b


def _brute(traj: Trajectories, t: float, i: int, order: int) -> np.ndarray:
    """Drone i's ``order``-th derivative at t by scanning its pieces in Python (the last piece starting <= t)."""
    br = traj.breaks_s[i]
    tc = min(max(t, br[0]), br[-1])
    p = max(k for k in range(traj.piece_count) if br[k] <= tc)
    if order and not br[0] <= t <= br[-1]:
        return np.zeros(3)
    return np.array([P.polyval(tc - br[p], P.polyder(traj.coeffs_m[i, p, ax], order) if order else
                               traj.coeffs_m[i, p, ax]) for ax in range(3)])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 6), pieces=st.integers(1, 6))
def test_evaluate_matches_per_drone_scan(seed: int, n: int, pieces: int) -> None:
    rng = np.random.default_rng(seed)
    traj = _random_builder(rng, n, pieces).build()
    # Random times plus every break exactly (zero-length pieces meet there) and outside the show.
    times = np.concatenate([rng.uniform(traj.start_s - 1, traj.end_s + 1, 20), traj.breaks_s.ravel()])
    got = traj.evaluate(times)
    for k, t in enumerate(times):
        for i in range(n):
            np.testing.assert_allclose(got.positions_m[k, i], _brute(traj, t, i, 0), rtol=1e-9, atol=1e-6)
            np.testing.assert_allclose(got.velocities_mps[k, i], _brute(traj, t, i, 1), rtol=1e-9, atol=1e-6)
            np.testing.assert_allclose(got.accelerations_mps2[k, i], _brute(traj, t, i, 2), rtol=1e-9, atol=1e-6)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 5), pieces=st.integers(1, 6),
       degree=st.sampled_from([5, 1, 3, 7]))
def test_cursor_kernel_matches_per_drone_scan(seed: int, n: int, pieces: int, degree: int) -> None:
    """states_at (playback's compiled evaluator: piece cursors walked from the last call, Horner) against
    the scan, for the planner's quintic tables and for other degrees; the cursors land on piece_index's
    pieces, whether time runs forwards or jumps either way."""
    rng = np.random.default_rng(seed)
    traj = _random_builder(rng, n, pieces).build()
    if degree != 5:  # the same breaks, random pieces of another degree (evaluation needs no continuity)
        traj = Trajectories(traj.breaks_s, rng.normal(0, 2, traj.coeffs_m.shape[:3] + (degree + 1,)))
    inside = rng.uniform(traj.start_s, traj.end_s, 20)
    times = np.concatenate([np.sort(inside), traj.breaks_s.ravel(), inside])  # play, every break, scrub
    cursor = np.zeros(n, dtype=np.int64)
    pos, vel = np.empty((1, n, 3)), np.empty((1, n, 3))
    for t in times:
        states_at(traj.breaks_s, traj.coeffs_m, np.array([t]), cursor, pos, vel)
        np.testing.assert_array_equal(cursor, traj.piece_index(t)[0])
        for i in range(n):
            np.testing.assert_allclose(pos[0, i], _brute(traj, t, i, 0), rtol=1e-9, atol=1e-6)
            np.testing.assert_allclose(vel[0, i], _brute(traj, t, i, 1), rtol=1e-9, atol=1e-6)
    # All times in one call: the same numbers as one at a time.
    many_pos, many_vel = np.empty((len(times), n, 3)), np.empty((len(times), n, 3))
    states_at(traj.breaks_s, traj.coeffs_m, times, np.zeros(n, dtype=np.int64), many_pos, many_vel)
    np.testing.assert_allclose(many_pos, traj.evaluate(times).positions_m, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(many_vel, traj.evaluate(times).velocities_mps, rtol=1e-12, atol=1e-9)


def test_motion_is_continuous_across_every_break() -> None:
    """Each piece starts where the previous one ends (its polynomial at its own length)."""
    traj = _random_builder(np.random.default_rng(3), 8, 5).build()
    lengths = np.diff(traj.breaks_s, axis=1)
    for i in range(8):
        for p in range(1, traj.piece_count):
            end = [P.polyval(lengths[i, p - 1], traj.coeffs_m[i, p - 1, ax]) for ax in range(3)]
            np.testing.assert_allclose(traj.coeffs_m[i, p, :, 0], end, rtol=1e-12, atol=1e-9)


def test_quintic_leg_matches_closed_form_and_rests_at_both_ends() -> None:
    a, bpt, dur = np.array([[0.0, 0, 10]]), np.array([[30.0, -4, 50]]), np.array([12.5])
    builder = TrajectoryBuilder(a)
    builder.hold_until(2.0)
    builder.append(dur, rest_to_rest_quintic_coeffs(a, bpt, dur))
    builder.hold_until(20.0)
    traj = builder.build()
    t = np.linspace(2.0, 14.5, 101)
    tau = (t - 2.0) / 12.5
    s = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    got = traj.evaluate(t).positions_m[:, 0]
    np.testing.assert_allclose(got, a + s[:, None] * (bpt - a), atol=1e-9)
    ends = traj.evaluate([0.0, 2.0, 14.5, 20.0])
    np.testing.assert_allclose(ends.positions_m[:, 0], [a[0], a[0], bpt[0], bpt[0]], atol=1e-9)
    assert np.abs(ends.velocities_mps).max() < 1e-9


def test_builder_refuses_jumps_backward_holds_and_ragged_ends() -> None:
    b = TrajectoryBuilder(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="start where"):
        b.append([1.0, 1.0], np.ones((2, 3, 1)))
    b.append([1.0, 2.0], np.zeros((2, 3, 1)))
    with pytest.raises(ValueError, match="back in time"):
        b.hold_until(1.5)
    with pytest.raises(ValueError, match="different times"):
        b.build()
    b.hold_until(2.0)
    assert b.build().end_s == 2.0


def test_select_keeps_each_drones_pieces() -> None:
    traj = _random_builder(np.random.default_rng(7), 5, 3).build()
    sub = traj.select(np.array([4, 1]))
    t = np.linspace(traj.start_s, traj.end_s, 17)
    np.testing.assert_array_equal(sub.evaluate(t).positions_m, traj.evaluate(t, np.array([4, 1])).positions_m)


def test_piece_lookup_is_exact_for_large_fleets_and_long_shows() -> None:
    """A break 0.1 ns away decides the piece for the last drone of 16,000 in a 1,000 s show."""
    n = 16_000
    b = TrajectoryBuilder(np.zeros((n, 3)))
    b.hold_until(np.full(n, 999.123456789))
    b.hold_until(1000.0)
    traj = b.build()
    t_break = 999.123456789
    idx = traj.piece_index([t_break - 1e-10, t_break, t_break + 1e-10])
    assert idx.shape == (3, n)
    np.testing.assert_array_equal(idx[:, -1], [0, 1, 1])
    assert (idx == idx[:, :1]).all()


def test_planned_motion_ends_exactly_at_the_last_knot() -> None:
    """Summed piece durations round; the plan's motion must still end at its last window boundary."""
    from sim import plan_show
    from tests.conftest import fibonacci_sphere, make_show, ring

    show = make_show(
        [
            {"name": "ring", "hold_s": 2.0, "points": ring(12, 6.0, center=(0, 0, 20))},
            {"name": "ball", "hold_s": 2.0, "points": fibonacci_sphere(12, 3.5, center=(5, 3, 25))},
        ],
        drones=12, rows=3, cols=4, spacing_m=3.0,
    )
    plan = plan_show(show)
    assert plan.motion.end_s == plan.knot_times_s[-1]
    assert (plan.motion.breaks_s[:, -1] == plan.knot_times_s[-1]).all()
