"""The exact altitude-floor and geofence checks against dense sampling and closed forms."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formations import Geofence, Settings
from sim import plan_show
from sim.plan import Trajectories
from sim.plan._plan import Segment
from sim.verify import check_bounds
from sim.verify._bounds import piece_extremes
from tests.conftest import make_show


def _random_motion(rng: np.random.Generator, n: int, p: int, degree: int) -> Trajectories:
    lengths = rng.uniform(0.0, 8.0, size=(n, p))
    lengths[rng.random((n, p)) < 0.15] = 0.0  # zero-length pieces occur in real plans
    breaks = np.concatenate([np.zeros((n, 1)), np.cumsum(lengths, axis=1)], axis=1)
    breaks[:, -1] = breaks[:, -1].max()  # every row ends at the show's end
    coeffs = np.zeros((n, p, 3, 6))
    # Random polynomials in normalised time, scaled back so that every piece wiggles over ~±10 m.
    L = np.maximum(np.diff(breaks, axis=1), 1e-3)[..., None, None]
    coeffs[..., : degree + 1] = rng.normal(0.0, 10.0, size=(n, p, 3, degree + 1)) / L ** np.arange(degree + 1)
    return Trajectories(breaks, coeffs)


def _dense(motion: Trajectories, samples: int = 4001) -> tuple[np.ndarray, np.ndarray]:
    """Per-piece min and max of x, y, z by sampling each piece densely: (N, P, 3) each."""
    b, c = motion.breaks_s, motion.coeffs_m
    s = np.linspace(0.0, 1.0, samples)
    u = np.diff(b, axis=1)[..., None, None] * s  # (N, P, 1, S)
    val = np.zeros(c.shape[:3] + (samples,))
    for k in range(c.shape[-1] - 1, -1, -1):
        val = val * u + c[..., k:k + 1]
    return val.min(axis=-1), val.max(axis=-1)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), degree=st.integers(0, 5))
def test_piece_extremes_match_dense_sampling(seed: int, degree: int) -> None:
    motion = _random_motion(np.random.default_rng(seed), 6, 5, degree)
    b = motion.breaks_s
    low, low_t, high, high_t = piece_extremes(motion, b[:, :-1], b[:, 1:])
    dense_low, dense_high = _dense(motion)
    # Exact extremes bound every sample and are approached by the dense samples (spacing ≤ 2 ms).
    assert np.all(low <= dense_low + 1e-9) and np.all(high >= dense_high - 1e-9)
    assert np.allclose(low, dense_low, atol=1e-3) and np.allclose(high, dense_high, atol=1e-3)
    # The reported times lie in their piece and give back the reported values.
    assert np.all((low_t >= b[:, :-1, None] - 1e-12) & (low_t <= b[:, 1:, None] + 1e-12))
    rows = np.arange(motion.drone_count)[:, None, None]
    pieces = np.arange(motion.piece_count)[None, :, None]
    for axis in range(3):
        u = low_t[..., axis] - b[:, :-1]
        c = motion.coeffs_m[:, :, axis]
        v = sum(c[..., k] * u**k for k in range(6))
        assert np.allclose(v, low[..., axis], atol=1e-9 * (1 + np.abs(v).max()))
    del rows, pieces, high_t


def test_piece_extremes_of_a_window_inside_a_piece() -> None:
    """z = (t - 5)² on [0, 10]: over [6, 9] the minimum is at the window's start, over [2, 9] at t = 5."""
    coeffs = np.zeros((1, 1, 3, 6))
    coeffs[0, 0, 2, :3] = [25.0, -10.0, 1.0]
    motion = Trajectories([[0.0, 10.0]], coeffs)
    low, low_t, _, _ = piece_extremes(motion, np.array([[6.0]]), np.array([[9.0]]))
    assert low[0, 0, 2] == pytest.approx(1.0) and low_t[0, 0, 2] == pytest.approx(6.0)
    low, low_t, high, high_t = piece_extremes(motion, np.array([[2.0]]), np.array([[9.0]]))
    assert low[0, 0, 2] == pytest.approx(0.0, abs=1e-12) and low_t[0, 0, 2] == pytest.approx(5.0)
    assert high[0, 0, 2] == pytest.approx(16.0) and high_t[0, 0, 2] == pytest.approx(9.0)


def _fake_plan(motion: Trajectories, cuts: list[float]) -> SimpleNamespace:
    """Takeoff [0, cuts[0]], a hold, landing [cuts[1], end]."""
    end = motion.end_s
    knots = np.array([0.0, cuts[0], cuts[1], end])
    segments = (Segment(0, "takeoff", "takeoff", 0.0, cuts[0]), Segment(1, "hold", "F", cuts[0], cuts[1] - cuts[0]),
                Segment(2, "landing", "landing", cuts[1], end - cuts[1]))
    return SimpleNamespace(motion=motion, segments=segments,
                           segment_index=lambda t: np.clip(np.searchsorted(knots, t, side="right") - 1, 0, 2))


def test_dip_between_samples_is_found() -> None:
    """A drone dips to 1 m for a moment mid-show (between 1 s samples) and climbs back."""
    coeffs = np.zeros((2, 3, 3, 6))
    coeffs[:, :, 2, 0] = 20.0
    # Piece 1 of drone 1 on [10.2, 10.8]: z = 1 + 19·(2u/L - 1)², 1 m at its middle (10.5 s).
    coeffs[1, 1, 2, :3] = [20.0, -76.0 / 0.6, 76.0 / 0.6**2]
    breaks = np.array([[0.0, 10.2, 10.8, 30.0]] * 2)
    plan = _fake_plan(Trajectories(breaks, coeffs), [5.0, 25.0])
    assert np.all(plan.motion.evaluate(np.arange(0.0, 31.0)).positions_m[..., 2] >= 19.0 - 1e-9)
    v = check_bounds(plan, Settings(min_altitude_m=2.5))
    assert len(v) == 1 and v[0].kind == "min_altitude" and v[0].drones == [1]
    assert v[0].value == pytest.approx(1.0) and v[0].time_s == pytest.approx(10.5) and v[0].limit == 2.5
    assert v[0].segment == 1 and "drone 1" in v[0].message
    assert check_bounds(plan, Settings(min_altitude_m=0.5)) == []


def test_takeoff_and_landing_are_exempt_from_the_floor() -> None:
    """z rises 0 -> 20 during takeoff and falls back during landing: no floor violation."""
    coeffs = np.zeros((1, 3, 3, 6))
    coeffs[0, 0, 2, :2] = [0.0, 4.0]
    coeffs[0, 1, 2, 0] = 20.0
    coeffs[0, 2, 2, :2] = [20.0, -4.0]
    plan = _fake_plan(Trajectories([[0.0, 5.0, 25.0, 30.0]], coeffs), [5.0, 25.0])
    assert check_bounds(plan, Settings()) == []
    # The floor's window starting at 4 s catches the climb at 16 m (fine); at 0.5 s, at 2 m (too low).
    assert check_bounds(_fake_plan(plan.motion, [4.0, 25.0]), Settings()) == []
    low_start = _fake_plan(plan.motion, [0.5, 25.0])
    v = check_bounds(low_start, Settings())
    assert [x.kind for x in v] == ["min_altitude"] and v[0].value == pytest.approx(2.0) and v[0].time_s == 0.5


def _plan(z_m: float, x_span_m: float = 12.0, **st):
    a = 2 * np.pi * np.arange(8) / 8
    flat = np.c_[x_span_m / 2 * np.cos(a), x_span_m / 2 * np.sin(a), np.full(8, z_m)]  # horizontal ring
    show = make_show([{"name": "low", "hold_s": 4.0, "points": flat}], drones=8, rows=2, cols=4, spacing_m=5.0, **st)
    return plan_show(show)


def test_real_plan_formation_below_the_floor() -> None:
    """A formation 0.5 m above the ground mid-show breaks the 2.5 m floor; at 3 m it passes."""
    plan = _plan(0.5)
    v = check_bounds(plan, plan.settings)
    assert v and all(x.kind == "min_altitude" for x in v)
    worst = min(x.value for x in v)
    assert worst == pytest.approx(0.5, abs=1e-6)
    assert {d for x in v for d in x.drones} == set(range(8))
    ok = _plan(3.0)
    assert check_bounds(ok, ok.settings) == []


def test_real_plan_geofence_sides() -> None:
    """A 15 m wide home grid and a 12 m ring against a fence 10 m wide: both x sides are broken; y is fine."""
    plan = _plan(30.0)
    fence = Geofence(x_min_m=-5.0, x_max_m=5.0, y_min_m=-20.0, y_max_m=20.0)
    v = check_bounds(plan, plan.settings.model_copy(update={"geofence": fence}))
    assert {x.kind for x in v} == {"geofence"}
    # Straight rest-to-rest moves: x is extreme at the knots (the 2 × 4 home grid reaches ±7.5 m).
    x = plan.knot_positions_m[..., 0]
    assert max(x.value for x in v) == pytest.approx(x.max(), abs=1e-6) and x.max() == pytest.approx(7.5)
    assert min(x.value for x in v) == pytest.approx(x.min(), abs=1e-6)
    assert all("x beyond" in x.message for x in v)
    wide = Geofence(x_min_m=-50.0, x_max_m=50.0, y_min_m=-50.0, y_max_m=50.0)
    assert check_bounds(plan, plan.settings.model_copy(update={"geofence": wide})) == []


def test_settings_refuse_a_floor_above_the_ceiling_and_an_empty_fence() -> None:
    with pytest.raises(ValueError, match="min_altitude_m"):
        Settings(min_altitude_m=200.0)
    with pytest.raises(ValueError, match="x_min_m < x_max_m"):
        Geofence(x_min_m=1.0, x_max_m=1.0, y_min_m=0.0, y_max_m=1.0)
