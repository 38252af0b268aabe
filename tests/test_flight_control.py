"""Closed-loop behaviour: step and circle tracking, the paper scenario, baseline, divergence."""

from __future__ import annotations

import numpy as np
import pytest

from sim.flight import (
    BaselineGains,
    IsmcGains,
    PositionGains,
    TrackingReference,
    hover_state,
    paper_report,
    simulate,
)
from sim.plan import Trajectories


def test_step_reference_converges():
    rng = np.random.default_rng(0)
    targets = rng.uniform(-20.0, 20.0, (12, 3)) + [0.0, 0.0, 40.0]
    start = hover_state(targets + rng.normal(scale=1.0, size=(12, 3)))  # ~1.7 m steps
    # 10 s: the ~1.7 m steps engage the tilt limit, while which the attitude loop keeps
    # learning (docs/method.md §4.1); one drone is still ~2 mm off at 8 s.
    res = simulate(TrackingReference.hover(targets), duration_s=10.0, initial_state=start,
                   output_every=100, engine="numba")
    assert res.diverged() == []
    final_err = np.linalg.norm(res.final_state[:, 0:3] - targets, axis=1)
    assert final_err.max() < 1e-3
    assert np.abs(res.final_state[:, 3:6]).max() < 1e-2  # at rest (m/s)


@pytest.mark.parametrize("disturbance", ["none", "wind"])
def test_circle_reference_converges(disturbance):
    centers = np.array([[0.0, 0.0, 30.0], [10.0, 5.0, 40.0], [-6.0, 8.0, 20.0]])
    ref = TrackingReference.circle(centers, radius_m=3.0, omega_rad_s=1.0)
    start = hover_state(centers + [3.5, 0.5, -0.5])  # off the circle, at rest
    res = simulate(ref, duration_s=10.0, initial_state=start, output_every=10, telemetry=True,
                   disturbance=disturbance, engine="numba")
    assert res.diverged() == []
    err = np.linalg.norm(res.telemetry[:, :, 0:3], axis=2)
    # (From 3.5 m off the circle the default tilt limit, 0.6 rad as flight stacks use, makes the
    # approach take about 7 s; the paper's unlimited law is back on the circle by 6 s.)
    late = res.frame_times_s >= 8.0
    assert err[0].max() > 0.5 and err[late].max() < 1e-3


def test_paper_scenario_meets_thresholds_and_beats_baseline():
    report, run, base = paper_report(controller="ismc", engine="numba")
    assert report["meets_thresholds"]
    assert report["pos_err_m"]["max_t_ge_8s"] < 1e-3
    assert report["att_err_rad"]["max_t_ge_8s"] < 1e-2
    assert report["pos_err_m"]["at_20s"] < 1e-3 and report["att_err_rad"]["at_20s"] < 1e-2
    assert report["settle_time_s"] is not None and report["settle_time_s"] < 8.0
    # Thrust stays continuous once settled (largest change per 1 ms step, N).
    assert report["max_thrust_step_after_settle_n"] < 0.02
    # The PD baseline keeps a steady error of about |Δ1| / kp; ISMC removes it.
    assert report["baseline"]["pos_err_m"]["max_t_ge_8s"] > 1e-2
    assert report["baseline_over_ismc"]["pos_err"] >= 10.0
    assert report["baseline_over_ismc"]["att_err_tracked"] >= 10.0
    assert run.times_s[-1] == pytest.approx(20.0) and base.controller == "baseline"


def test_baseline_runs_with_the_same_interface():
    pts = np.array([[0.0, 0.0, 10.0], [5.0, 0.0, 10.0]])
    # The paper's PD settles from a 1.7 m step in 6 s (the PID, with its overshoot, in 10 s:
    # tests/test_flight_errors.py).
    res = simulate(TrackingReference.hover(pts), duration_s=6.0, initial_state=hover_state(pts + 1.0),
                   gains=BaselineGains.paper(), engine="numba")
    assert res.diverged() == []
    assert np.linalg.norm(res.final_state[:, 0:3] - pts, axis=1).max() < 1e-2


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_diverging_drones_are_reported_and_the_rest_fly_on(engine):
    pts = np.array([[0.0, 0.0, 10.0], [5.0, 0.0, 10.0], [10.0, 0.0, 10.0]])
    motion = TrackingReference.hover(pts).motion
    coeffs = motion.coeffs_m.copy()
    coeffs[1] = np.nan  # drone 1: a broken (non-finite) reference
    ref = TrackingReference(motion=Trajectories(motion.breaks_s, coeffs))
    start = hover_state(pts + [0.5, 0.0, 0.0])
    res = simulate(ref, duration_s=0.5, initial_state=start, engine=engine, output_every=10)
    assert res.diverged() == [(1, 0.0, "non-finite")]
    assert np.all(np.isfinite(res.final_state)) and np.all(np.isfinite(res.positions_m))

    # Absurd gains: every drone is unstable, each is stopped and named, nothing crashes.
    absurd = IsmcGains(position=PositionGains(k1=-50.0, k2=-50.0))
    res = simulate(TrackingReference.hover(pts), duration_s=3.0, initial_state=start, gains=absurd,
                   engine=engine, output_every=10, divergence_limit_m=20.0)
    div = res.diverged()
    assert [d for d, _, _ in div] == [0, 1, 2]
    assert all(reason in ("runaway", "non-finite") and 0.0 < t < 3.0 for _, t, reason in div)
    assert np.all(np.isfinite(res.final_state))
