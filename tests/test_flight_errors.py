"""Per-drone error models and the smooth control law (issue 20): known answers and statistics."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import solve_discrete_lyapunov

from sim.flight import (
    ERROR_PRESETS,
    BaselineGains,
    ErrorModel,
    FlightOptions,
    IsmcGains,
    QuadrotorParams,
    TrackingReference,
    error_preset,
    hover_state,
    simulate,
)
from sim.flight._disturbance import WindField, dryden_correlation
from sim.flight.engines._state import D_CLOCK, D_MASS, D_SAG_RATE
from sim.flight.scenarios._paper import run_paper_scenario
from sim.plan import Trajectories


# ---------------------------------------------------------------------------------------------
# The interface
# ---------------------------------------------------------------------------------------------
def test_presets_and_their_checks():
    assert set(ERROR_PRESETS) == {"ideal", "calm-rtk", "gusty-rtk", "gps-only"}
    assert error_preset("ideal").is_ideal and ErrorModel().is_ideal
    for name in ("calm-rtk", "gusty-rtk", "gps-only"):
        model = error_preset(name)
        assert model.name == name and not model.is_ideal and model.has_gnss and model.has_wind
    with pytest.raises(ValueError, match="'windy'"):
        error_preset("windy")
    with pytest.raises(ValueError, match="gnss_noise_m"):
        ErrorModel(gnss_noise_m=-1.0)
    with pytest.raises(ValueError, match="drag_coeff_kg_per_m"):
        ErrorModel(wind_mean_mps=5.0)
    with pytest.raises(ValueError, match="errors"):
        FlightOptions(errors="gusty-rtk")  # type: ignore[arg-type]
    keys = {FlightOptions(errors=m).cache_key() for m in ERROR_PRESETS.values()}
    assert len(keys) == len(ERROR_PRESETS)


# ---------------------------------------------------------------------------------------------
# Smooth control (item 1)
# ---------------------------------------------------------------------------------------------
def test_boundary_layer_law_is_smooth_and_tracks_at_least_as_well_as_the_paper_law():
    out = {}
    for law in ("sign", "boundary"):
        run = run_paper_scenario(switching=law, engine="numba")
        late = run.times_s >= 8.0
        span = run.times_s[late][-1] - run.times_s[late][0]
        tv = np.abs(np.diff(run.torque_nm[late], axis=0)).sum() / span  # N·m per s, summed over axes
        out[law] = (tv, np.linalg.norm(run.pos_err_m[late], axis=1).max(), run.metrics()["meets_thresholds"])
    (tv_sign, err_sign, ok_sign), (tv_smooth, err_smooth, ok_smooth) = out["sign"], out["boundary"]
    assert ok_sign and ok_smooth  # the paper's law still reproduces the paper
    assert tv_sign >= 100.0 * tv_smooth
    assert err_smooth <= err_sign


def test_default_gains_are_the_smooth_law_and_paper_mode_is_the_sign_law():
    assert IsmcGains().switching == "boundary"
    assert IsmcGains.paper().switching == "sign"
    with pytest.raises(ValueError, match="switching"):
        IsmcGains(switching="tanh")


def test_pid_removes_the_constant_offset_a_pd_leaves():
    # A plant 10 % heavier than the controller believes: the PD settles where
    # -kp e_z = 0.1 g, i.e. e_z = -0.1 g / kp (the velocity term vanishes at rest).
    pts = np.array([[0.0, 0.0, 10.0]])
    ref = TrackingReference.hover(pts)
    kw = dict(duration_s=25.0, initial_state=hover_state(pts), mismatch=0.1, engine="numba")
    pd = simulate(ref, gains=BaselineGains.paper(), **kw)
    pid = simulate(ref, gains=BaselineGains(), **kw)
    want = -0.1 * QuadrotorParams().gravity_mps2 / BaselineGains().kp
    assert pd.final_state[0, 2] - 10.0 == pytest.approx(want, rel=1e-3)
    assert abs(pid.final_state[0, 2] - 10.0) < 1e-3


def test_pid_recovers_from_a_step():
    pts = np.array([[0.0, 0.0, 10.0], [5.0, 0.0, 10.0]])
    res = simulate(TrackingReference.hover(pts), duration_s=10.0, initial_state=hover_state(pts + 1.0),
                   gains=BaselineGains(), engine="numba")
    assert res.diverged() == []
    assert np.linalg.norm(res.final_state[:, 0:3] - pts, axis=1).max() < 1e-2


# ---------------------------------------------------------------------------------------------
# Statistics with known answers (item 4)
# ---------------------------------------------------------------------------------------------
def _estimator_error_variance(*, sigma: float, wc: float, every: int, dt: float, steps_after_epoch: int) -> float:
    """Stationary variance of p̂ - p (one axis) of the held-innovation complementary filter, exactly.

    Per step: ẽv += dt k_v y; ẽp += dt (ẽv + k_p y); at an epoch (before the step) y = -ẽp + n.
    """
    kp, kv = math.sqrt(2.0) * wc, wc * wc
    step = np.array([[1.0, dt, dt * dt * kv + dt * kp], [0.0, 1.0, dt * kv], [0.0, 0.0, 1.0]])
    jump = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
    inject = np.array([0.0, 0.0, 1.0])
    epoch = np.linalg.matrix_power(step, every)
    a = epoch @ jump
    b = epoch @ inject
    p_pre = solve_discrete_lyapunov(a, sigma**2 * np.outer(b, b))  # state just before an epoch step
    after = np.linalg.matrix_power(step, steps_after_epoch)
    p_end = after @ (jump @ p_pre @ jump.T + sigma**2 * np.outer(inject, inject)) @ after.T
    return float(p_end[0, 0])


def test_estimate_error_spread_under_white_gnss_noise_matches_the_linear_model():
    n, sigma, wc, vertical = 1000, 0.05, 2.0, 1.5
    errors = ErrorModel(gnss_noise_m=sigma, gnss_vertical_factor=vertical, gnss_rate_hz=10.0,
                        estimator_bandwidth_rad_s=wc)
    pts = np.zeros((n, 3))
    pts[:, 0] = np.arange(n) * 3.0
    pts[:, 2] = 20.0
    duration = 20.0
    res = simulate(TrackingReference.hover(pts), duration_s=duration, errors=errors, seed=11,
                   gains=BaselineGains(), engine="numba", output_every=1000)
    assert res.diverged() == []
    est_err = res.extra["estimate"][:, 0:3] - res.final_state[:, 0:3]
    samples = (est_err / np.array([1.0, 1.0, vertical])).ravel()  # 3n draws of one unit-σ axis
    steps = int(round(duration / 1e-3)) + 1
    last_epoch = 100 * ((steps - 1) // 100)
    want = _estimator_error_variance(sigma=sigma, wc=wc, every=100, dt=1e-3, steps_after_epoch=steps - last_epoch)
    got = float(np.mean(samples**2))  # the mean is 0: no bias
    # Sampling error of a variance from m Gaussian draws: √(2/m) relative.
    assert abs(got / want - 1.0) < 4.0 * math.sqrt(2.0 / samples.size)
    assert abs(np.mean(samples)) < 4.0 * math.sqrt(want / samples.size)


@pytest.mark.parametrize("distance_m", [30.0, 150.0])
def test_wind_correlation_at_a_distance_matches_dryden(distance_m):
    sigma, length, seeds = 1.3, 150.0, 2500
    pts = np.array([[0.0, 0.0, 30.0], [distance_m, 0.0, 30.0], [0.0, distance_m, 30.0]])
    u = np.array([
        WindField.dryden(sigma_mps=sigma, length_m=length, modes=64, seed=s).velocity(pts, np.zeros(3))
        for s in range(seeds)
    ])  # (S, 3 points, 3 axes)
    # Along the separation (x at points 0, 1): f(r); across it (x at points 0, 2): g(r).
    for other, longitudinal in ((1, True), (2, False)):
        prod = u[:, 0, 0] * u[:, other, 0]
        want = sigma**2 * float(dryden_correlation(distance_m, length, longitudinal=longitudinal))
        assert abs(prod.mean() - want) < 4.0 * prod.std() / math.sqrt(seeds), (longitudinal, prod.mean(), want)
    var = u[:, 0, 0] ** 2
    assert abs(var.mean() - sigma**2) < 4.0 * var.std() / math.sqrt(seeds)


def test_clock_offset_shows_as_a_lag_of_speed_times_offset():
    # Every drone flies a straight line at 2 m/s (one linear piece); drone i runs its clock
    # at t + δ_i, so once settled it is v δ_i ahead of the plan along the line.
    n, speed = 64, 2.0
    coeffs = np.zeros((n, 1, 3, 6))
    coeffs[:, 0, 0, 0] = np.arange(n) * 5.0
    coeffs[:, 0, 2, 0] = 20.0
    coeffs[:, 0, 0, 1] = speed
    breaks = np.tile([0.0, 100.0], (n, 1))
    ref = TrackingReference(motion=Trajectories(breaks, coeffs), duration_s=100.0)
    start = hover_state(coeffs[:, 0, :, 0])
    start[:, 3] = speed  # already moving: no start-up transient
    res = simulate(ref, duration_s=10.0, initial_state=start, errors=ErrorModel(clock_offset_s=0.05), seed=4,
                   engine="numba", telemetry=True, output_every=1000)
    delta = res.extra["drone"][:, D_CLOCK]
    assert delta.std() == pytest.approx(0.05, rel=0.3)
    along = res.telemetry[-1, :, 0]  # e1_x = p - p_ref(t) at 10 s (settled: the start is a v δ step)
    np.testing.assert_allclose(along, speed * delta, atol=1e-4)


def test_per_drone_draws_and_battery_sag():
    model = error_preset("gusty-rtk")
    pts = np.zeros((200, 3))
    pts[:, 0] = np.arange(200) * 4.0
    pts[:, 2] = 25.0
    res = simulate(TrackingReference.hover(pts), duration_s=2.0, errors=model, seed=3, engine="numba",
                   output_every=1000)
    d = res.extra["drone"]
    mass = d[:, D_MASS] / QuadrotorParams().mass_kg - 1.0
    assert mass.std() == pytest.approx(model.mass_spread, rel=0.2)
    sag_at_endurance = d[:, D_SAG_RATE] * model.battery_duration_s  # reached at the pack's endurance
    assert sag_at_endurance.mean() == pytest.approx(model.battery_sag, abs=0.02)
    assert res.diverged() == []


# ---------------------------------------------------------------------------------------------
# Seeds, subsets, chunks and engines
# ---------------------------------------------------------------------------------------------
def _line_reference(n: int) -> TrackingReference:
    pts = np.zeros((n, 3))
    pts[:, 0] = np.arange(n) * 4.0
    pts[:, 2] = 25.0
    return TrackingReference.circle(pts, radius_m=2.0, omega_rad_s=0.5)


def test_seeds_reproduce_and_a_drone_flies_the_same_alone_or_in_any_chunking():
    ref = _line_reference(8)
    kw = dict(duration_s=3.0, errors=error_preset("gusty-rtk"), engine="numba", output_every=20)
    a = simulate(ref, seed=5, **kw)
    b = simulate(ref, seed=5, chunk_steps=377, **kw)
    c = simulate(ref, seed=6, **kw)
    np.testing.assert_array_equal(a.positions_m, b.positions_m)
    np.testing.assert_array_equal(a.final_state, b.final_state)
    assert np.abs(a.positions_m - c.positions_m).max() > 1e-3
    # Drones 2 and 5 flown alone (as a Dask shard would) with their plan indices as keys.
    rows = np.array([2, 5])
    sub = simulate(ref.subset(rows), seed=5, drone_ids=rows, **kw)
    np.testing.assert_array_equal(sub.positions_m, a.positions_m[:, rows])
    np.testing.assert_array_equal(sub.final_state, a.final_state[rows])


@pytest.mark.parametrize(("preset", "gains"), [("gusty-rtk", IsmcGains()), ("gps-only", IsmcGains()),
                                               ("gusty-rtk", BaselineGains())])
def test_engines_agree_with_the_error_models_on(preset, gains):
    model = ErrorModel(**{**error_preset(preset).__dict__, "clock_offset_s": 0.02})
    ref = _line_reference(12)
    kw = dict(duration_s=1.0, errors=model, seed=9, output_every=25, telemetry=True, chunk_steps=300, gains=gains)
    a = simulate(ref, engine="numba", **kw)
    b = simulate(ref, engine="numpy", **kw)
    assert a.diverged() == [] and b.diverged() == []
    assert np.abs(a.final_state - b.final_state).max() < 1e-8
    assert np.abs(a.positions_m - b.positions_m).max() < 1e-8
    assert np.abs(a.extra["estimate"] - b.extra["estimate"]).max() < 1e-8
    assert np.nanmax(np.abs(a.telemetry - b.telemetry)) < 1e-6  # includes N and N·m


def test_fly_show_subset_flies_like_the_whole_fleet_with_errors_on():
    # What a Dask shard does (fly_local with a drones subset): the same arrays for its drones.
    from sim import plan_show
    from sim.flight import fly_show
    from tests.conftest import fibonacci_sphere, make_show, ring

    show = make_show([
        {"name": "ring", "hold_s": 2.0, "points": ring(8, 8.0), "color": "#ff0000"},
        {"name": "sphere", "hold_s": 2.0, "points": fibonacci_sphere(8, 7.0), "color": "#00ff00"},
    ], drones=8, rows=2, cols=4, spacing_m=4.5)
    plan = plan_show(show)
    opts = FlightOptions(errors=error_preset("gusty-rtk"), seed=7, output_hz=10)
    whole = fly_show(plan, opts)
    part = fly_show(plan, opts, drones=np.array([1, 6]))
    np.testing.assert_array_equal(part.positions_m, whole.positions_m[:, [1, 6]])
    np.testing.assert_array_equal(part.tracking_rms_m, whole.tracking_rms_m[[1, 6]])
    assert whole.diverged == [] and whole.tracking_max_m.max() > 1e-3  # the errors do act


def test_fused_wind_mode_sum_equals_the_mode_by_mode_formula():
    # WindField.velocity sums its Fourier modes in a compiled loop with a polynomial cosine
    # (sim.flight._windsum); the
    # formula of its docstring, written out mode by mode in numpy with libm cosines, agrees to 1e-12 m/s.
    f = WindField.dryden(mean_mps=7.7, direction_rad=0.4, sigma_mps=1.3, length_m=152.0, modes=96, seed=8)
    rng = np.random.default_rng(2)
    pts = rng.uniform(-150.0, 150.0, size=(500, 3))
    pts[:, 2] = np.abs(pts[:, 2])
    t = rng.uniform(0.0, 600.0, size=500)
    want = f.mean_velocity(pts[:, 2])
    ux, uy = f.mean_mps * np.cos(f.direction_rad), f.mean_mps * np.sin(f.direction_rad)
    x, y, z = pts[:, 0] - ux * t, pts[:, 1] - uy * t, pts[:, 2]
    for m in range(f.omega_rad_s.size):
        kx, ky, kz = f.wavevectors[m]
        c = np.cos(kx * x + ky * y + kz * z + f.omega_rad_s[m] * t + f.phase_rad[m])
        want += f.amplitudes[m][None, :] * c[:, None]
    got = f.velocity(pts, t)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    # A point's wind does not depend on the points evaluated with it.
    np.testing.assert_array_equal(f.velocity(pts[17:18], t[17:18]), got[17:18])


@pytest.mark.parametrize(("preset", "tolerance_m"), [("gps-only", 0.25), ("gusty-rtk", 0.01)])
def test_a_gnss_drone_flies_with_its_gnss_error_and_nothing_more(preset, tolerance_m):
    # Known answer: the controller tracks the estimate, the estimate has unit DC gain on the GNSS
    # error (complementary filter), so over a window the drone's true error p - p_ref averages to
    # minus the GNSS error's average. Before the drones started on their estimate, seed 3 of
    # "gps-only" handed 50 ISMC drones a step of the whole first-fix error (up to 7 m) and three
    # of them tumbled and ran away within 15 s (issue 20).
    from sim.flight.engines._tables import ErrorTables

    n, duration, seed = 50, 20.0, 3
    pts = np.zeros((n, 3))
    pts[:, 0] = np.arange(n) * 5.0
    pts[:, 2] = 30.0
    ref = TrackingReference.circle(pts, radius_m=3.0, omega_rad_s=0.3)
    model = error_preset(preset)
    res = simulate(ref, duration_s=duration, errors=model, seed=seed, gains=IsmcGains(), engine="numba",
                   output_every=100, telemetry=True)
    assert res.diverged() == []
    steps = int(round(duration / 1e-3)) + 1
    tables = ErrorTables(model, seed=seed, drone_ids=np.arange(n), plant=QuadrotorParams(), dt_s=1e-3,
                         duration_s=duration)
    fix0 = tables.initial_gnss_error()
    # It starts where its estimate puts the start: off by exactly the first fix's error.
    np.testing.assert_allclose(res.telemetry[0, :, 0:3], -fix0, atol=1e-9)
    chunk = tables.chunk(0, steps, ref)
    epoch_t = (chunk.gnss_first + np.arange(chunk.gnss.shape[0]) * chunk.gnss_every) * 1e-3
    gnss_mean = chunk.gnss[epoch_t >= 10.0].mean(axis=0)
    flown_mean = res.telemetry[res.frame_times_s >= 10.0, :, 0:3].mean(axis=0)
    assert np.abs(flown_mean + gnss_mean).max() < tolerance_m


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_battery_sag_follows_the_pack_not_the_show(engine):
    """The sag is the battery's (issue 20 QA): linear in time, ``sag_i`` at the pack's endurance, then held.

    A 95-s show on a 600-s pack sags by 95/600 of ``sag_i``, not by all of it (the old horizon was the
    flight). Measured in each engine from one step at each time t from hover: the thrust that acts over
    the thrust its rotor speeds make (telemetry thrust / (k_F Σω²)), against the closed form
    ``g_i(t) = k_i (1 - sag_i min(t, T) / T)`` with ``sag_i`` drawn here from its own stream.
    """
    from sim.flight import make_disturbance
    from sim.flight._random import STREAMS, hashed_normal
    from sim.flight.engines._numba import run_chunk_numba
    from sim.flight.engines._numpy import init_controller, run_chunk_numpy
    from sim.flight.engines._state import C_ROTOR, D_THRUST, STATS_SIZE, TELEMETRY_FIELDS
    from sim.flight.engines._tables import ErrorTables

    n, seed, endurance = 16, 4, 600.0
    model = ErrorModel(name="sag", battery_sag=0.3, battery_sag_spread=0.1, thrust_spread=0.03,
                       battery_duration_s=endurance)
    params = QuadrotorParams()
    ids = np.arange(n)
    tables = ErrorTables(model, seed=seed, drone_ids=ids, plant=params, dt_s=1e-3, duration_s=95.0)
    sag = np.clip(0.3 + 0.1 * hashed_normal(seed, ids, STREAMS["sag"], 0), 0.0, 0.9)
    assert sag.min() < sag.max()  # the draws differ per drone
    pts = np.zeros((n, 3))
    pts[:, 0] = ids * 4.0
    pts[:, 2] = 10.0
    ref = TrackingReference.hover(pts)
    runner = run_chunk_numba if engine == "numba" else run_chunk_numpy
    opts = {"params": params, "plant": params, "gains": IsmcGains(), "disturbance": make_disturbance("none"),
            "dt_s": 1e-3, "integrator": "euler", "divergence_limit_m": 100.0, "drone": tables.drone,
            "switches": tables.switches}
    for t in (0.0, 95.0, 300.0, 600.0, 900.0):
        step = int(round(t / 1e-3))
        times = np.array([t])
        chunk = ref.chunk(times)
        state = hover_state(pts)
        ctrl = init_controller(state, ref, chunk, params=params, gains=IsmcGains())
        every = max(step, 1)  # the step is frame 1 (frame 0 at t = 0): two-frame buffers
        tel = np.zeros((2, n, len(TELEMETRY_FIELDS)))
        runner(state, ctrl, np.zeros((n, STATS_SIZE)), np.full(n, -1), np.zeros(n, dtype=np.int64), ref=ref,
               chunk=chunk, dist=np.zeros((1, 9)), step0=step, times=times, every=every,
               frames=np.zeros((2, n, 3)), tel=tel, opts=opts)
        acting = tel[step // every, :, TELEMETRY_FIELDS.index("thrust")]
        rotor = params.k_f * ctrl[:, C_ROTOR:C_ROTOR + 4].sum(axis=1)
        expected = tables.drone[:, D_THRUST] * (1.0 - sag * min(t, endurance) / endurance)
        np.testing.assert_allclose(acting / rotor, expected, rtol=1e-12, err_msg=f"t = {t} s")
    # The presets carry a show drone's endurance (not the show's length).
    for name in ("calm-rtk", "gusty-rtk", "gps-only"):
        assert error_preset(name).battery_duration_s == pytest.approx(1200.0)
