"""Whole-show plans: structure, timing under the limits, colours, forced durations."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim import PlanError, check_plan, min_transition_duration, plan_show
from tests.conftest import fibonacci_sphere, make_show, ring


def test_structure(small_show) -> None:
    plan = plan_show(small_show)
    kinds = [s.kind for s in plan.segments]
    assert kinds == ["takeoff", "transition", "hold", "transition", "hold", "transition", "landing"]
    P = plan.knot_positions_m
    home = np.array(small_show.home_positions_m)
    np.testing.assert_array_equal(P[0], home)
    # vertical takeoff to the takeoff altitude
    np.testing.assert_allclose(P[1], home + [0, 0, small_show.settings.takeoff_altitude_m])
    # formations reached exactly, each drone on a distinct point
    for f, k in ((small_show.formations[0], 2), (small_show.formations[1], 4)):
        d = np.linalg.norm(P[k][:, None] - f.points_m[None], axis=2)
        assert np.all(d.min(axis=1) < 1e-12)
        assert len(np.unique(d.argmin(axis=1))) == small_show.drones
    # landing: every drone on a distinct home position on the ground
    d = np.linalg.norm(P[-1][:, None] - home[None], axis=2)
    assert np.all(d.min(axis=1) < 1e-12) and len(np.unique(d.argmin(axis=1))) == small_show.drones
    # holds last as long as asked
    holds = [s.duration_s for s in plan.segments if s.kind == "hold"]
    assert holds == [2.0, 3.0]


def test_evaluation_is_continuous_and_rests_at_knots(small_show) -> None:
    plan = plan_show(small_show)
    eps = 1e-9
    for t in plan.knot_times_s[1:-1]:
        a, b = plan.evaluate([t - eps, t + eps]), plan.evaluate([t])
        np.testing.assert_allclose(a.positions_m[0], a.positions_m[1], atol=1e-6)
        np.testing.assert_allclose(b.velocities_mps, 0.0, atol=1e-12)
        np.testing.assert_allclose(b.accelerations_mps2, 0.0, atol=1e-12)
    # velocity is the derivative of position (central differences)
    t = np.linspace(0.05, plan.duration_s - 0.05, 400)
    h = 1e-5
    fd = (plan.evaluate(t + h).positions_m - plan.evaluate(t - h).positions_m) / (2 * h)
    np.testing.assert_allclose(fd, plan.evaluate(t).velocities_mps, atol=1e-5)
    fd = (plan.evaluate(t + h).velocities_mps - plan.evaluate(t - h).velocities_mps) / (2 * h)
    np.testing.assert_allclose(fd, plan.evaluate(t).accelerations_mps2, atol=1e-4)


def test_colors_fade_linearly_and_start_unlit(small_show) -> None:
    plan = plan_show(small_show)
    seg = plan.segments[1]  # takeoff -> ring
    t = seg.start_s + np.array([0.0, 0.25, 0.5, 1.0]) * seg.duration_s
    c = plan.evaluate(t).colors_rgb
    np.testing.assert_allclose(c[0], 0.0)
    np.testing.assert_allclose(c[-1], np.tile([1.0, 0.0, 0.0], (16, 1)))
    np.testing.assert_allclose(c[1], 0.25 * c[-1])
    np.testing.assert_allclose(c[2], 0.5 * c[-1])
    np.testing.assert_allclose(plan.evaluate([plan.duration_s]).colors_rgb, 0.0)  # landed unlit


def test_extra_points_stay_dark() -> None:
    pts = ring(24, 15.0)
    colors = [f"#{(40 * i) % 256:02x}0000" for i in range(24)]
    show = make_show([{"name": "r", "hold_s": 1.0, "points": pts, "colors": colors}], drones=9, rows=3, cols=3,
                     spacing_m=4.5)
    plan = plan_show(show)
    tr = plan.transitions[0]
    assert len(set(tr.goal_index.tolist())) == 9
    np.testing.assert_allclose(plan.knot_colors_rgb[2], show.formations[0].colors_rgb[tr.goal_index])


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), vxy=st.floats(1, 15), vz=st.floats(0.5, 5), acc=st.floats(0.5, 8))
def test_sampled_peaks_never_exceed_limits(seed: int, vxy: float, vz: float, acc: float) -> None:
    rng = np.random.default_rng(seed)
    start = rng.uniform(-50, 50, (20, 3))
    end = rng.uniform(-50, 50, (20, 3))
    T = min_transition_duration(start, end, max_speed_xy_mps=vxy, max_speed_z_mps=vz, max_accel_mps2=acc)
    tau = np.linspace(0, 1, 2001)
    from sim import rest_to_rest

    law = rest_to_rest(tau, T)
    d = end - start
    v = law.s_d[:, None, None] * d[None]
    a = law.s_dd[:, None, None] * d[None]
    assert np.hypot(v[..., 0], v[..., 1]).max() <= vxy * (1 + 1e-9)
    assert np.abs(v[..., 2]).max() <= vz * (1 + 1e-9)
    assert np.linalg.norm(a, axis=2).max() <= acc * (1 + 1e-9)
    # and it is the shortest on the 0.1 s grid: 0.1 s less breaks a limit
    if T > 0.1 + 1e-9:
        law = rest_to_rest(tau, T - 0.1)
        v = law.s_d[:, None, None] * d[None]
        a = law.s_dd[:, None, None] * d[None]
        broken = (
            np.hypot(v[..., 0], v[..., 1]).max() > vxy
            or np.abs(v[..., 2]).max() > vz
            or np.linalg.norm(a, axis=2).max() > acc
        )
        assert broken


def test_forced_short_duration_names_the_minimum(small_show) -> None:
    data = small_show.model_dump(mode="json", exclude_none=True)
    data["formations"][1]["transition_s"] = 0.5
    from formations import parse_show

    show = parse_show(data)
    with pytest.raises(PlanError, match=r"formations\[1\]\.transition_s = 0.5 s is shorter than the minimum"):
        plan_show(show)
    minimum = plan_show(small_show).transitions[1].min_duration_s
    with pytest.raises(PlanError) as info:
        plan_show(show)
    assert info.value.minimum_s == pytest.approx(minimum)
    # flown as asked, the plan says what enforcing the limits refuses, word for word (the preview and
    # simulation name it as the exports' refusal does); a show within its limits has nothing there
    loose = plan_show(show, enforce_limits=False)
    assert [(f.path, f.message, f.forced_s) for f in loose.forced] == [
        ("formations[1].transition_s", str(info.value), 0.5)]
    assert loose.forced[0].minimum_s == info.value.minimum_s
    assert plan_show(small_show).forced == () and plan_show(small_show, enforce_limits=False).forced == ()
    # check mode flies it as asked and reports which drones break the limits, and when
    report = check_plan(plan_show(show, enforce_limits=False))
    assert not report.ok
    kinds = {v.kind for v in report.violations}
    assert "transition_duration" in kinds and "acceleration" in kinds
    acc = next(v for v in report.violations if v.kind == "acceleration")
    seg = plan_show(show, enforce_limits=False).segments[acc.segment]
    assert seg.label == "sphere" and seg.start_s <= acc.time_s <= seg.end_s
    # the named drone is the one with the longest leg
    P = plan_show(show, enforce_limits=False).knot_positions_m
    legs = np.linalg.norm(P[acc.segment + 1] - P[acc.segment], axis=1)
    assert acc.drones[0] == int(np.argmax(legs))


def test_takeoff_timing_is_exact() -> None:
    show = make_show([{"name": "s", "hold_s": 1.0, "points": fibonacci_sphere(4, 5.0)}], drones=4, rows=2, cols=2,
                     spacing_m=4.5, takeoff_altitude_m=10.0, time_law="quintic")
    plan = plan_show(show)
    # 1.875 * 10 m / 2 m/s = 9.375 s -> 9.4 s
    assert plan.segments[0].duration_s == pytest.approx(9.4)
    # Minimum time (the default), 4 m/s², 10 m/s³: 0.4 s of jerk, 0.9 s accelerating, 4.1 s at 2 m/s, 0.9 s braking.
    fast = plan_show(show.model_copy(update={"settings": show.settings.model_copy(update={"time_law": "min_time"})}))
    assert fast.segments[0].duration_s == pytest.approx(5.9)


def test_colour_fade_over_a_zero_length_window_is_the_window_end(small_show) -> None:
    """A window of zero length (a plan ending exactly on its last knot, e.g. one cut short) has
    faded completely at its time: its end colour, not 0/0 (NaN and a RuntimeWarning)."""
    import warnings
    from dataclasses import replace

    from sim.plan._plan import Segment

    plan = plan_show(small_show)
    times = plan.knot_times_s.copy()
    times[-1] = times[-2]  # the landing window shrunk to an instant
    last = plan.segments[-1]
    cut = replace(plan, knot_times_s=times,
                  segments=(*plan.segments[:-1], Segment(last.index, last.kind, last.label, last.start_s, 0.0)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = cut.evaluate([times[-1], times[-1] + 1.0]).colors_rgb
    assert np.array_equal(got, np.broadcast_to(plan.knot_colors_rgb[-1], got.shape))
    # the windows before it fade as before
    t = 0.5 * (times[1] + times[2])
    assert np.array_equal(cut.evaluate([t]).colors_rgb, plan.evaluate([t]).colors_rgb)
