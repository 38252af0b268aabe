"""Formations that move during their hold (issue 21, item 5): show file rules, fitted pieces, exact check.

The transform is checked against scipy's rotations (an independent implementation of
R_z R_y R_x) and finite differences; the planned pieces against dense sampling of the
closed-form motion; the exact check against motions made to break each limit.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from formations import ShowValidationError
from formations._motion import Motion, apply, motion_peaks, pivot_of, pose, sample_channels
from formations._points import closest_pair
from formations.sources import generate_shape, text_points
from sim.plan import FIT_TOLERANCE_M, PlanError, plan_show
from sim.plan._motion import (
    MotionFitError,
    fit_error,
    fit_error_bound,
    hermite_quintic,
    hold_pieces,
    sample_counts,
)
from sim.verify import check_plan
from tests.conftest import make_show


def smoothstep(tau: np.ndarray) -> np.ndarray:
    """The rest-to-rest quintic 10τ³ - 15τ⁴ + 6τ⁵ (the 'smooth' easing between two keys)."""
    tau = np.clip(tau, 0.0, 1.0)
    return 10 * tau**3 - 15 * tau**4 + 6 * tau**5


def _star(n: int = 30) -> np.ndarray:
    return generate_shape("star", n, size_m=60.0, center_m=(0.0, 0.0, 45.0), plane="xz", min_spacing_m=3.0).points_m


def _show(points, motion, *, hold_s=20.0, drones=None, **settings):
    n = len(points) if drones is None else drones
    f = {"name": "moving", "hold_s": hold_s, "points": points, "color": "#ffcc00"}
    if motion is not None:
        f["motion"] = motion
    return make_show([f, {"name": "after", "hold_s": 2.0, "points": np.asarray(points) + [0.0, 10.0, 0.0]}],
                     drones=n, rows=int(np.ceil(n / 8)), cols=8, spacing_m=4.0, **settings)


def _hold(plan, name="moving"):
    return next(s for s in plan.segments if s.kind == "hold" and s.label == name)


def _drone_points(plan, show, k=0):
    """Each drone's (untransformed) formation point, from the plan's assignment."""
    return show.formations[k].points_m[plan.transitions[k].goal_index]


# ----------------------------------------------------------------------------------- the transform


def test_pose_matches_scipy_rotations_and_finite_differences():
    motion = Motion.model_validate({"pivot_m": [1.0, -2.0, 30.0], "keys": [
        {"t_s": 0.0},
        {"t_s": 3.0, "rotate_deg": [20.0, -35.0, 80.0], "translate_m": [2.0, 1.0, -3.0], "scale": 1.3,
         "easing": "linear"},
        {"t_s": 7.0, "rotate_deg": [45.0, 10.0, 200.0], "translate_m": [-4.0, 3.0, 2.0], "scale": 0.8},
    ]})
    rng = np.random.default_rng(3)
    pts = rng.uniform(-10, 10, (7, 3)) + [0, 0, 30]
    t = rng.uniform(0.0, 7.0, 40)
    ch = sample_channels(motion, t)
    pos, vel, acc = apply(pose(motion, t), pivot_of(motion, pts), pts)
    c = np.array([1.0, -2.0, 30.0])
    for k in range(len(t)):
        r = Rotation.from_euler("xyz", ch.q[k, 3:6]).as_matrix()  # extrinsic x, y, z: R_z R_y R_x
        want = c + ch.q[k, 6] * (pts - c) @ r.T + ch.q[k, :3]
        np.testing.assert_allclose(pos[k], want, atol=1e-9)
    h = 1e-4
    p_plus = apply(pose(motion, t + h), c, pts)[0]
    p_minus = apply(pose(motion, t - h), c, pts)[0]
    np.testing.assert_allclose(vel, (p_plus - p_minus) / (2 * h), atol=1e-5)
    np.testing.assert_allclose(acc, (p_plus - 2 * pos + p_minus) / h**2, atol=2e-3)


def test_keys_are_interpolated_as_documented():
    motion = Motion.model_validate({"keys": [
        {"t_s": 1.0, "rotate_deg": [0, 0, 0]},
        {"t_s": 3.0, "rotate_deg": [0, 0, 90], "easing": "linear"},
        {"t_s": 5.0, "rotate_deg": [0, 0, 180], "easing": "linear"},
        {"t_s": 7.0, "rotate_deg": [0, 0, 270]},
    ]})
    ch = sample_channels(motion, np.array([0.0, 1.0, 3.0, 4.0, 5.0, 7.0, 9.0]))
    # Keys are met; before the first and after the last the pose rests; the first and last keys stop.
    np.testing.assert_allclose(np.degrees(ch.q[:, 5]), [0, 0, 90, 135, 180, 270, 270], atol=1e-9)
    assert ch.dq[0, 5] == ch.dq[1, 5] == ch.dq[-2, 5] == ch.dq[-1, 5] == 0.0
    # Evenly timed linear keys with even steps: a constant rate between them (45 deg/s).
    mid = sample_channels(motion, np.linspace(3.0, 5.0, 9))
    np.testing.assert_allclose(np.degrees(mid.dq[:, 5]), 45.0, atol=1e-9)
    np.testing.assert_allclose(mid.ddq[:, 5], 0.0, atol=1e-9)


def test_hermite_quintic_matches_its_end_conditions():
    rng = np.random.default_rng(0)
    p0, v0, a0, p1, v1, a1 = rng.normal(size=(6, 5))
    h = rng.uniform(0.1, 3.0, 5)
    c = hermite_quintic(p0, v0, a0, p1, v1, a1, h)
    poly = [np.polynomial.Polynomial(row) for row in c]
    for i, q in enumerate(poly):
        assert q(0) == pytest.approx(p0[i]) and q.deriv()(0) == pytest.approx(v0[i])
        assert q.deriv(2)(0) == pytest.approx(a0[i])
        assert q(h[i]) == pytest.approx(p1[i]) and q.deriv()(h[i]) == pytest.approx(v1[i])
        assert q.deriv(2)(h[i]) == pytest.approx(a1[i])


# ----------------------------------------------------------------------------------- planned shows


@pytest.fixture(scope="module")
def rotating_star():
    """A star logo in the audience plane turning 90 deg about the vertical axis through its centre."""
    pts = _star()
    show = _show(pts, {"keys": [{"t_s": 0.0}, {"t_s": 20.0, "rotate_deg": [0.0, 0.0, 90.0]}]})
    return show, plan_show(show)


def test_rotating_logo_passes_the_exact_check(rotating_star):
    show, plan = rotating_star
    report = check_plan(plan)
    assert report.ok, [v.message for v in report.violations]
    assert report.min_distance_m >= show.settings.min_distance_m - 1e-9


def test_rotating_logo_pieces_follow_the_closed_form_within_tolerance(rotating_star):
    show, plan = rotating_star
    seg = _hold(plan)
    p = _drone_points(plan, show)
    c = show.formations[0].points_m.mean(axis=0)
    t = np.linspace(seg.start_s, seg.end_s, 2001)
    theta = np.radians(90.0) * smoothstep((t - seg.start_s) / 20.0)
    cos, sin = np.cos(theta)[:, None], np.sin(theta)[:, None]
    rel = p - c
    want = np.stack([c[0] + cos * rel[:, 0] - sin * rel[:, 1], c[1] + sin * rel[:, 0] + cos * rel[:, 1],
                     np.broadcast_to(c[2] + rel[:, 2], cos.shape[:1] + rel[:, 2].shape)], axis=-1)
    got = plan.motion.evaluate(t, derivatives=0).positions_m
    err = float(np.linalg.norm(got - want, axis=-1).max())
    assert err < FIT_TOLERANCE_M, err
    # The knots are the first and last keys' poses: the transitions meet the hold there, at rest.
    k = seg.index
    np.testing.assert_allclose(plan.knot_positions_m[k], want[0], atol=1e-9)
    np.testing.assert_allclose(plan.knot_positions_m[k + 1], want[-1], atol=1e-6)
    v = plan.motion.evaluate([seg.start_s, seg.end_s]).velocities_mps
    assert np.abs(v).max() < 1e-9
    # Turning about z really moved the points (the x extent of the planar logo became a y extent).
    assert np.ptp(plan.knot_positions_m[k + 1][:, 1]) > 50.0


def test_the_pieces_are_c2_at_every_break(rotating_star):
    _, plan = rotating_star
    seg = _hold(plan)
    b = plan.motion.breaks_s[0]
    inner = b[(b > seg.start_s + 1e-9) & (b < seg.end_s - 1e-9)]
    assert len(inner) >= 3
    left = plan.motion.evaluate(inner - 1e-7)
    right = plan.motion.evaluate(inner + 1e-7)
    np.testing.assert_allclose(left.positions_m, right.positions_m, atol=1e-6)
    np.testing.assert_allclose(left.velocities_mps, right.velocities_mps, atol=1e-5)
    np.testing.assert_allclose(left.accelerations_mps2, right.accelerations_mps2, atol=1e-4)


def test_fit_error_bound_shrinks_like_h6_and_sample_count_meets_the_tolerance():
    pts = _star()
    motion = Motion.model_validate({"keys": [{"t_s": 0.0}, {"t_s": 10.0, "rotate_deg": [0, 0, 180.0]}]})
    c = pivot_of(motion, pts)
    e = [fit_error(motion, c, pts, np.linspace(0.0, 10.0, n + 1), probes=32) for n in (4, 8, 16)]
    # Quintic Hermite: error ~ h^6, so halving h divides it by about 64 (at least 30 here).
    assert e[0] / e[1] > 30 and e[1] / e[2] > 30, e
    (n,) = sample_counts(motion, pts)
    assert fit_error(motion, c, pts, np.linspace(0.0, 10.0, n + 1), probes=64) < FIT_TOLERANCE_M
    if n > 2:
        assert fit_error(motion, c, pts, np.linspace(0.0, 10.0, n // 2 + 1), probes=64) > FIT_TOLERANCE_M / 64


def test_the_error_bound_covers_every_point_brute_force():
    """fit_error_bound (four points and a norm) is at least the error of every point of the formation."""
    pts = _cloud()
    motion = Motion.model_validate({"keys": [{"t_s": 0.0}, {"t_s": 6.0, "rotate_deg": [30.0, -20.0, 150.0],
                                                            "translate_m": [3.0, 1.0, 2.0], "scale": 1.4}]})
    c = pivot_of(motion, pts)
    radius = float(np.linalg.norm(pts - c, axis=1).max())
    for n in (2, 4, 8, 16):
        times = np.linspace(0.0, 6.0, n + 1)
        brute = fit_error(motion, c, pts, times)
        bound = fit_error_bound(motion, c, radius, times)
        assert brute <= bound * (1 + 1e-9) + 1e-12 and bound < 4 * brute, (n, brute, bound)


def test_each_key_interval_gets_its_own_sample_count():
    pts = _star()
    motion = Motion.model_validate({"keys": [{"t_s": 0.0}, {"t_s": 10.0, "translate_m": [0.0, 0.0, 1.0]},
                                             {"t_s": 20.0, "translate_m": [0.0, 0.0, 1.0], "rotate_deg": [0, 0, 180]}]})
    quiet, turning = sample_counts(motion, pts)
    assert quiet < turning


def test_a_motion_beyond_the_sample_cap_or_the_piece_budget_is_refused(monkeypatch):
    from sim.plan import _motion as motion_module

    pts = _star(20)
    motion = Motion.model_validate({"keys": [{"t_s": 0.0}, {"t_s": 10.0, "rotate_deg": [0, 0, 3600.0]}]})
    monkeypatch.setattr(motion_module, "_MAX_SAMPLES", 4)
    with pytest.raises(MotionFitError, match="between keys 0 and 1") as err:
        sample_counts(motion, pts)
    assert err.value.key == 1
    monkeypatch.setattr(motion_module, "_MAX_SAMPLES", 1024)
    monkeypatch.setattr(motion_module, "MAX_HOLD_PIECE_DRONES", 50)
    with pytest.raises(MotionFitError, match="pieces x drones"):
        hold_pieces(motion, pts, pts, 10.0)
    # Through the planner: a PlanError naming the field (the budget is the reason here).
    show = _unvalidated(_show(pts, None), {"keys": [{"t_s": 0.0}, {"t_s": 20.0, "rotate_deg": [0, 0, 90.0]}]})
    with pytest.raises(PlanError) as plan_err:
        plan_show(show)
    assert plan_err.value.path == "formations[0].motion.keys"


@settings(max_examples=25, deadline=None)
@given(
    turns=st.lists(st.tuples(st.floats(-120, 120), st.floats(-120, 120), st.floats(-400, 400)), min_size=1,
                   max_size=3),
    moves=st.lists(st.tuples(st.floats(-20, 20), st.floats(-20, 20), st.floats(-10, 10)), min_size=3, max_size=3),
    scales=st.lists(st.floats(0.5, 2.0), min_size=3, max_size=3),
    easings=st.lists(st.sampled_from(["smooth", "linear"]), min_size=3, max_size=3),
    spans=st.lists(st.floats(2.0, 30.0), min_size=3, max_size=3),
)
def test_fitted_pieces_stay_within_tolerance_of_any_motion(turns, moves, scales, easings, spans):
    """Random motions: the planned pieces of every point, densely sampled at times the fit never probed,
    stay within FIT_TOLERANCE_M of the exact transform."""
    pts = _cloud()
    keys, t = [{"t_s": 0.0}], 0.0
    for i, r in enumerate(turns):
        t += spans[i]
        keys.append({"t_s": t, "rotate_deg": list(r), "translate_m": list(moves[i]), "scale": scales[i],
                     "easing": easings[i]})
    motion = Motion.model_validate({"keys": keys})
    durations, coeffs = hold_pieces(motion, pts, pts, t)
    breaks = np.r_[0.0, np.cumsum(durations)]
    tt = np.sort(np.random.default_rng(len(keys)).uniform(0.0, t, 4000))
    piece = np.clip(np.searchsorted(breaks, tt, side="right") - 1, 0, len(durations) - 1)
    u = (tt - breaks[piece])[:, None, None]
    c = coeffs[:, piece].transpose(1, 0, 2, 3)  # (T, n, 3, 6)
    got = np.zeros(c.shape[:3])
    for k in range(5, -1, -1):
        got = got * u + c[..., k]
    want = apply(pose(motion, tt), pivot_of(motion, pts), pts)[0]
    assert float(np.linalg.norm(got - want, axis=-1).max()) < FIT_TOLERANCE_M


def _cloud() -> np.ndarray:
    rng = np.random.default_rng(7)
    return rng.uniform(-15.0, 15.0, (80, 3)) + [0.0, 0.0, 50.0]


@pytest.fixture(scope="module")
def translating_scaling():
    """Text that grows 1.3x while rising 5 m and drifting 6 m east, then shrinks back, through a linear key."""
    pts = text_points("HI", 36, height_m=22.0, center_m=(0.0, 0.0, 40.0), min_spacing_m=3.0).points_m
    motion = {"pivot_m": [0.0, 0.0, 40.0], "keys": [
        {"t_s": 2.0},
        {"t_s": 14.0, "translate_m": [6.0, 0.0, 5.0], "scale": 1.3, "easing": "linear"},
        {"t_s": 26.0, "translate_m": [0.0, 0.0, 3.0], "scale": 1.0},
    ]}
    show = _show(pts, motion, hold_s=30.0)
    return show, plan_show(show)


def test_translating_and_scaling_formation_passes_the_check_and_follows_the_transform(translating_scaling):
    show, plan = translating_scaling
    report = check_plan(plan)
    assert report.ok, [v.message for v in report.violations]
    seg = _hold(plan)
    p = _drone_points(plan, show)
    motion = show.formations[0].motion
    t = np.linspace(seg.start_s, seg.end_s, 3001)
    ch = sample_channels(motion, t - seg.start_s)  # channels (independently: a similarity has no rotation here)
    assert np.abs(ch.q[:, 3:6]).max() == 0.0
    pivot = np.array([0.0, 0.0, 40.0])
    want = pivot + ch.q[:, 6, None, None] * (p - pivot) + ch.q[:, None, :3]
    got = plan.motion.evaluate(t, derivatives=0).positions_m
    assert float(np.linalg.norm(got - want, axis=-1).max()) < FIT_TOLERANCE_M
    # Rests before the first key (2 s) and after the last (26 s of 30).
    before = plan.motion.evaluate(np.linspace(seg.start_s, seg.start_s + 2.0, 5), derivatives=0).positions_m
    assert np.ptp(before, axis=0).max() < 1e-9
    # The closest pair is reached at the largest scale's opposite: never below the formation's own.
    assert report.min_distance_m >= show.settings.min_distance_m - 1e-9


def test_leave_at_s_shorter_than_the_keys_is_a_plan_error_naming_the_key():
    pts = _star(20)
    show = _show(pts, {"keys": [{"t_s": 0.0}, {"t_s": 15.0, "rotate_deg": [0, 0, 45.0]}]})
    arrived = _hold(plan_show(show)).start_s
    f0 = show.formations[0].model_copy(update={"leave_at_s": round(arrived + 10.0, 2)})
    show = show.model_copy(update={"formations": [f0, show.formations[1]]})
    with pytest.raises(PlanError) as err:
        plan_show(show)
    assert err.value.path == "formations[0].motion.keys[1].t_s"
    assert "after the end of the hold" in str(err.value)


# ----------------------------------------------------------------------------------- validation


def _error(show_kwargs) -> ShowValidationError:
    with pytest.raises(ShowValidationError) as err:
        _show(**show_kwargs)
    return err.value


def test_too_fast_motion_is_rejected_naming_the_field_and_the_shortest_span_works():
    pts = _star()
    keys = [{"t_s": 0.0}, {"t_s": 2.0, "rotate_deg": [0, 0, 180.0]}]
    e = _error({"points": pts, "motion": {"keys": keys}})
    assert e.errors[0]["path"] == "formations[0].motion.keys"
    msg = e.errors[0]["msg"]
    assert "too fast" in msg and "must span at least" in msg
    span = float(msg.split("must span at least ")[1].split(" s")[0])
    assert span > 2.0
    # The span it names is enough (to its printed precision), and 1 % less is not.
    ok = [{"t_s": 0.0}, {"t_s": round(span + 0.01, 2), "rotate_deg": [0, 0, 180.0]}]
    _show(pts, {"keys": ok}, hold_s=30.0)
    short = [{"t_s": 0.0}, {"t_s": span * 0.99, "rotate_deg": [0, 0, 180.0]}]
    assert "too fast" in _error({"points": pts, "motion": {"keys": short}, "hold_s": 30.0}).errors[0]["msg"]


def test_motion_peaks_match_the_closed_form_of_a_spin():
    # A point at radius r spinning by Θ with the smooth easing over T: peak speed r Θ 15/8 / T.
    pts = np.array([[10.0, 0.0, 40.0], [-10.0, 0.0, 40.0], [0.0, 10.0, 40.0], [0.0, -10.0, 40.0]])
    motion = Motion.model_validate({"keys": [{"t_s": 0.0}, {"t_s": 8.0, "rotate_deg": [0, 0, 90.0]}]})
    peaks = motion_peaks(motion, pts)
    assert peaks.speed_xy_mps == pytest.approx(10.0 * np.pi / 2 * 15 / 8 / 8.0, rel=1e-4)
    assert peaks.speed_z_mps == 0.0


@pytest.mark.parametrize(("motion", "path", "words"), [
    ({"keys": [{"t_s": 0.0}, {"t_s": 25.0, "rotate_deg": [0, 0, 10]}]}, "formations[0].motion.keys[1].t_s",
     "after the end of the hold"),
    ({"keys": [{"t_s": 5.0}, {"t_s": 5.0, "rotate_deg": [0, 0, 10]}]}, "formations[0].motion", "must increase"),
    ({"keys": [{"t_s": 0.0}, {"t_s": 10.0, "scale": 0.5}]}, "formations[0].motion.keys", "smallest scale"),
    ({"keys": [{"t_s": 0.0}, {"t_s": 10.0, "scale": 0.0}]}, "formations[0].motion.keys[1].scale", ""),
    ({"keys": [{"t_s": 0.0}, {"t_s": 18.0, "translate_m": [0, 0, 120.0]}]}, "formations[0].motion.keys",
     "above max_altitude_m"),
    ({"keys": [{"t_s": 0.0}, {"t_s": 18.0, "translate_m": [0, 0, -30.0]}]}, "formations[0].motion.keys",
     "below min_altitude_m"),
    ({"keys": [{"t_s": 0.0}, {"t_s": 18.0, "rotate_deg": [90.0, 0, 0]}]}, "formations[0].motion.keys",
     "geofence"),
    ({"keys": [{"t_s": 0.0}]}, "formations[0].motion.keys", ""),
])
def test_bad_motions_name_their_field(motion, path, words):
    pts = _star(24)
    fence = {"x_min_m": -60.0, "x_max_m": 60.0, "y_min_m": -20.0, "y_max_m": 60.0}
    e = _error({"points": pts, "motion": motion, "geofence": fence})
    assert e.errors[0]["path"] == path, e.errors
    assert words in e.errors[0]["msg"]


def test_api_rejects_a_too_fast_motion_with_422_naming_the_field(tmp_path):
    from fastapi.testclient import TestClient

    from app.server import create_app
    from app.settings import AppSettings

    pts = _star(20)
    show = _show(pts, None).model_dump(mode="json", exclude_none=True)
    show["formations"][0]["motion"] = {"keys": [{"t_s": 0.0}, {"t_s": 1.0, "rotate_deg": [0, 0, 360.0]}]}
    with TestClient(create_app(AppSettings(data_dir=tmp_path, workers=1)), base_url="http://127.0.0.1") as client:
        r = client.post("/api/shows", json=show)
    assert r.status_code == 422, r.text
    (problem,) = r.json()["detail"]
    assert problem["path"] == "formations[0].motion.keys" and "too fast" in problem["msg"]


# ----------------------------------------------------------------------------------- the exact check sees moving holds


def _unvalidated(show, motion: dict):
    """The show with formation 0 given ``motion`` without the file's rules (to feed the exact check a bad hold)."""
    f0 = show.formations[0].model_copy(update={"motion": Motion.model_validate(motion)})
    return show.model_copy(update={"formations": [f0, *show.formations[1:]]})


@pytest.mark.parametrize(("motion", "kind"), [
    ({"keys": [{"t_s": 0.0}, {"t_s": 10.0, "scale": "shrink"}, {"t_s": 20.0}]}, "min_distance"),
    ({"keys": [{"t_s": 0.0}, {"t_s": 10.0, "translate_m": [0, 0, -20.0]}, {"t_s": 20.0}]}, "min_altitude"),
    ({"keys": [{"t_s": 0.0}, {"t_s": 10.0, "translate_m": [0, 0, 90.0]}, {"t_s": 20.0}]}, "altitude"),
    ({"keys": [{"t_s": 0.0}, {"t_s": 10.0, "translate_m": [0, -50.0, 0]}, {"t_s": 20.0}]}, "geofence"),
    ({"keys": [{"t_s": 0.0}, {"t_s": 1.0, "rotate_deg": [0, 0, 180.0]}, {"t_s": 20.0}]}, "speed_xy"),
])
def test_exact_check_finds_violations_inside_a_moving_hold_that_returns_to_its_start(motion, kind):
    """Every motion here ends where it started, so a check that treats holds as static would pass them."""
    base = _show(_star(24), None, geofence={"x_min_m": -60.0, "x_max_m": 60.0, "y_min_m": -20.0, "y_max_m": 60.0})
    if motion["keys"][1].get("scale") == "shrink":  # to 80 % of the scale that keeps the minimum distance
        closest = closest_pair(base.formations[0].points_m)[2]
        motion = {"keys": [motion["keys"][0], {"t_s": 10.0, "scale": 0.8 * 3.0 / closest}, motion["keys"][2]]}
    show = _unvalidated(base, motion)
    plan = plan_show(show)
    seg = _hold(plan)
    np.testing.assert_allclose(plan.knot_positions_m[seg.index], plan.knot_positions_m[seg.index + 1], atol=1e-6)
    report = check_plan(plan)
    found = [v for v in report.violations if v.kind == kind]
    assert found, (kind, [v.kind for v in report.violations])
    assert all(seg.start_s - 1e-6 <= v.time_s <= seg.end_s + 1e-6 for v in found)
    assert check_plan(plan_show(base)).ok


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_the_editors_motion_preview_matches_the_show_files_transform():
    """frontend/js/motion.js (the canvas playback) against formations/_motion.py on random motions."""
    rng = np.random.default_rng(11)
    pts = rng.uniform(-10, 10, (6, 3)) + [0, 0, 40]
    cases = []
    for _ in range(20):
        keys, t = [{"t_s": 0.0}], 0.0
        for _ in range(int(rng.integers(1, 4))):
            t += float(rng.uniform(1, 10))
            keys.append({"t_s": t, "rotate_deg": rng.uniform(-200, 200, 3).round(3).tolist(),
                         "translate_m": rng.uniform(-5, 5, 3).round(3).tolist(), "scale": float(rng.uniform(0.5, 2)),
                         "easing": str(rng.choice(["smooth", "linear"]))})
        motion = {"keys": keys} if rng.random() < 0.5 else {"keys": keys, "pivot_m": [1.0, -2.0, 38.0]}
        cases.append({"motion": motion, "times": rng.uniform(-1, t + 1, 7).tolist()})
    module = (Path(__file__).parent.parent / "frontend" / "js" / "motion.js").as_uri()
    script = (f"import {{ movedPoints }} from {json.dumps(module)};\n"
              f"const cases = {json.dumps(cases)}; const pts = {json.dumps(pts.tolist())};\n"
              "console.log(JSON.stringify(cases.map((c) => c.times.map((t) => movedPoints(c.motion, pts, t)))));\n")
    out = subprocess.run(["node", "--input-type=module", "-e", script], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    got = json.loads(out.stdout)
    for case, js in zip(cases, got, strict=True):
        motion = Motion.model_validate(case["motion"])
        want = apply(pose(motion, np.array(case["times"])), pivot_of(motion, pts), pts)[0]
        np.testing.assert_allclose(np.array(js), want, atol=1e-9)


def test_a_large_formations_motion_check_is_bounded_and_still_close():
    """A 20,000-point sphere (every point on its hull): the check evaluates at most MAX_SCAN_POINTS of them
    and still finds the spin's peak speed r·θ·15/(8 T) to 0.5 %."""
    from formations import _motion as motion_module
    from tests.conftest import fibonacci_sphere

    pts = fibonacci_sphere(20_000, 100.0, center=(0.0, 0.0, 150.0))
    motion = Motion.model_validate({"keys": [{"t_s": 0.0}, {"t_s": 30.0, "rotate_deg": [0, 0, 90.0]}]})
    assert len(motion_module._few(pts, pivot_of(motion, pts))) <= motion_module.MAX_SCAN_POINTS
    want = 100.0 * np.pi / 2 * 15 / 8 / 30.0
    got = motion_peaks(motion, pts).speed_xy_mps
    assert want * 0.995 <= got <= want * (1 + 1e-5)  # (the centroid is a hair off the centre)
