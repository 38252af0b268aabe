"""The wind at the flown position (issue 20): the field's Jacobian, its first-order expansion and the clamps.

Independent computations: central finite differences of the exact mode sum, the exact field at
the flown position over dense samples of displacements, the Dryden ensemble over seeds, and a
drone held off its plan in a sheared mean wind whose steady tilt tells the wind it feels.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim.flight import ErrorModel, QuadrotorParams, TrackingReference, simulate
from sim.flight._disturbance import (
    SHEAR_LINEAR_RADIUS_FRACTION,
    TURBULENCE_LINEAR_RADIUS_FRACTION,
    WindField,
)
from sim.flight.engines._tables import WIND_GRAD_SIZE, flown_wind


def _field(seed: int = 3, *, mean_mps: float = 7.7, sigma_mps: float = 1.3) -> WindField:
    return WindField.dryden(mean_mps=mean_mps, direction_rad=0.7, ref_height_m=10.0, sigma_mps=sigma_mps,
                            length_m=152.0, vertical_factor=0.6, modes=128, seed=seed)


def _points(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    pts = rng.uniform(-200.0, 200.0, (n, 3))
    pts[:, 2] = rng.uniform(5.0, 150.0, n)  # above the profile's 1 m floor, where it is smooth
    return pts, rng.uniform(0.0, 600.0, n)


def _tables_at(f: WindField, pts: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What the engines' tables hold at the planned points: the wind and its derivative row."""
    vel, jac, shear = f.velocity_and_gradients(pts, t)
    grad = np.concatenate([jac.reshape(-1, 9), shear], axis=1)
    assert grad.shape[1] == WIND_GRAD_SIZE
    return vel, grad


def test_jacobian_matches_central_differences_of_the_exact_field():
    f = _field()
    rng = np.random.default_rng(0)
    pts, t = _points(rng, 300)
    jac = f.jacobian(pts, t)
    h = 1e-3  # m: the finest resolved wavelength is 2π L / 200 = 4.8 m; FD error ~ h² k³ σ ~ 1e-7 /s
    fd = np.empty_like(jac)
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        fd[:, :, j] = (f.velocity(pts + e, t) - f.velocity(pts - e, t)) / (2.0 * h)
    scale = np.abs(fd).max()
    assert scale > 0.1  # the gradients are not trivially zero
    np.testing.assert_allclose(jac, fd, rtol=0, atol=1e-6)
    # The value computed with it is the value of velocity(), bit for bit.
    vel, jac_t, shear = f.velocity_and_gradients(pts, t)
    np.testing.assert_array_equal(vel, f.velocity(pts, t))
    # A point's values do not depend on the points evaluated with it (a shard's tables equal the fleet's).
    one = f.velocity_and_gradients(pts[17:18], t[17:18])
    for a, b in zip(one, (vel[17:18], jac_t[17:18], shear[17:18]), strict=True):
        np.testing.assert_array_equal(a, b)


def test_mean_shear_is_the_derivative_of_the_power_law():
    f = _field(sigma_mps=0.0)
    z = np.array([0.5, 1.5, 10.0, 37.0, 120.0])
    h = 1e-4
    want = (f.mean_velocity(z + h) - f.mean_velocity(z - h))[:, 0:2] / (2.0 * h)
    want[0] = 0.0  # below the 1 m floor the profile is constant
    np.testing.assert_allclose(f.mean_shear(z), want, rtol=1e-7, atol=1e-12)


def test_linearised_wind_error_is_second_order_in_the_displacement():
    # Dense samples of small displacements in every direction, well inside the clamps: the
    # expansion's error against the exact field at the flown position falls 4x per halving,
    # while the planned position's error (the old model) only halves.
    f = _field()
    rng = np.random.default_rng(1)
    pts, t = _points(rng, 4000)
    u = rng.normal(size=pts.shape)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    vel, grad = _tables_at(f, pts, t)
    radius = f.linear_radius_m
    assert radius == pytest.approx(152.0 / 150.0)
    lin_err, plan_err = [], []
    for s in (0.4, 0.2, 0.1, 0.05, 0.025):
        exact = f.velocity(pts + s * u, t)
        got = flown_wind(vel, grad, s * u, pts[:, 2], radius)
        lin_err.append(np.sqrt(np.mean(np.sum((got - exact) ** 2, axis=1))))
        plan_err.append(np.sqrt(np.mean(np.sum((vel - exact) ** 2, axis=1))))
    lin_ratio = np.array(lin_err[:-1]) / np.array(lin_err[1:])
    plan_ratio = np.array(plan_err[:-1]) / np.array(plan_err[1:])
    np.testing.assert_allclose(lin_ratio, 4.0, rtol=0.1)
    np.testing.assert_allclose(plan_ratio, 2.0, rtol=0.1)
    assert lin_err[2] < 0.05 * plan_err[2]  # at 10 cm the expansion removes 95 % of the error


def test_turbulence_clamp_holds_the_correction_beyond_the_radius():
    f = _field(mean_mps=0.0)
    rng = np.random.default_rng(2)
    pts, t = _points(rng, 50)
    vel, grad = _tables_at(f, pts, t)
    r = f.linear_radius_m
    jac = grad[:, 0:9].reshape(-1, 3, 3)
    for axis in range(3):
        far = np.zeros_like(pts)
        far[:, axis] = 5.0 * r
        farther = far * 20.0
        at_edge = far * (r / (5.0 * r))
        a = flown_wind(vel, grad, far, pts[:, 2], r)
        np.testing.assert_array_equal(a, flown_wind(vel, grad, farther, pts[:, 2], r))
        np.testing.assert_array_equal(a, flown_wind(vel, grad, at_edge, pts[:, 2], r))
        # -> the linear term at the edge of the box: the wind plus R times column `axis` of J
        np.testing.assert_allclose(a, vel + r * jac[:, :, axis], rtol=0, atol=1e-14)
        np.testing.assert_allclose(flown_wind(vel, grad, -far, pts[:, 2], r), vel - r * jac[:, :, axis],
                                   rtol=0, atol=1e-14)
    # Per axis: a diagonal drift is clamped axis by axis.
    d = np.array([[3.0 * r, -0.5 * r, 0.25 * r]])
    want = vel[:1] + jac[0] @ np.array([r, -0.5 * r, 0.25 * r])
    np.testing.assert_allclose(flown_wind(vel[:1], grad[:1], d, pts[:1, 2], r), want, rtol=0, atol=1e-14)
    # A non-finite displacement (a diverging drone) gives a finite wind only if it is infinite.
    assert np.all(np.isfinite(flown_wind(vel[:1], grad[:1], np.array([[np.inf, -np.inf, 0.0]]), pts[:1, 2], r)))


@pytest.mark.parametrize("distance_frac", [1 / 500, 1 / 100, 1 / 50, 1 / 20, 1 / 5, 1.0])
def test_turbulence_expansion_is_never_worse_than_the_planned_positions_wind(distance_frac):
    # The clamp radius's reason (sim.flight._disturbance.TURBULENCE_LINEAR_RADIUS_FRACTION): over
    # the Dryden ensemble (seeds, points, directions) the clamped expansion's mean-square error
    # against the exact field at the flown position is at most that of the wind at the planned
    # position, at every distance, and far below it at small ones.
    length = 152.0
    d = distance_frac * length
    rng = np.random.default_rng(5)
    lin, plan = 0.0, 0.0
    for seed in range(12):
        f = WindField.dryden(sigma_mps=1.0, length_m=length, modes=128, seed=seed)
        pts, t = _points(rng, 1500)
        u = rng.normal(size=pts.shape)
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        vel, grad = _tables_at(f, pts, t)
        exact = f.velocity(pts + d * u, t)
        lin += np.sum((flown_wind(vel, grad, d * u, pts[:, 2], f.linear_radius_m) - exact) ** 2)
        plan += np.sum((vel - exact) ** 2)
    ratio = lin / plan
    assert ratio < 1.03  # sampling error of 18,000 samples
    if d <= TURBULENCE_LINEAR_RADIUS_FRACTION * length:
        assert ratio < 0.3


def test_shear_clamp_is_half_the_planned_height():
    f = _field(sigma_mps=0.0)
    z = np.array([10.0, 40.0, 100.0])
    pts = np.stack([np.zeros(3), np.zeros(3), z], axis=1)
    vel, grad = _tables_at(f, pts, np.zeros(3))
    r = f.linear_radius_m
    speed = lambda w: np.hypot(w[:, 0], w[:, 1])  # noqa: E731
    for frac in (-0.5, -0.25, 0.25, 0.5):
        d = np.zeros_like(pts)
        d[:, 2] = frac * z
        got = speed(flown_wind(vel, grad, d, z, r))
        exact = speed(f.mean_velocity(z + d[:, 2]))
        # the tangent of the concave 1/7 power law: within 2.6 % down to half the height
        np.testing.assert_allclose(got, exact, rtol=0.026)
        assert np.all(got >= exact)  # concave: the tangent lies above
    half = np.zeros_like(pts)
    half[:, 2] = -SHEAR_LINEAR_RADIUS_FRACTION * z
    lower = half * 1.8
    np.testing.assert_array_equal(flown_wind(vel, grad, lower, z, r), flown_wind(vel, grad, half, z, r))


def test_a_drone_held_below_its_plan_feels_the_wind_where_it_is():
    # Physical: a steady, sheared mean wind (7.7 m/s at 10 m, 1/7 law, toward +x, no turbulence).
    # A constant GNSS bias b (no noise, no walk) holds each drone at plan - b: the controller tracks
    # its estimate. In steady hover the drag balances the thrust's tilt, so the pitch θ tells the
    # air speed the drone feels: g tan θ = (c/m) w². That must be the wind at the flown height
    # (drones 5-15 m off), not at the planned one (all at 60 m).
    n, z_plan = 6, 60.0
    pts = np.zeros((n, 3))
    pts[:, 0] = np.arange(n) * 20.0
    pts[:, 2] = z_plan
    model = ErrorModel(gnss_bias_m=8.0, gnss_vertical_factor=1.0, wind_mean_mps=7.7, wind_direction_rad=0.0,
                       wind_ref_height_m=10.0, drag_coeff_kg_per_m=0.018)
    ref = TrackingReference.hover(pts)
    res = simulate(ref, duration_s=12.0, engine="numba", errors=model, seed=4, output_every=100)
    assert res.diverged() == []
    state = res.final_state
    dz = state[:, 2] - z_plan
    assert np.abs(dz).max() < SHEAR_LINEAR_RADIUS_FRACTION * z_plan  # inside the shear clamp
    assert np.abs(dz).max() > 5.0  # the bias does hold drones well off their plan
    assert np.abs(state[:, 3:6]).max() < 1e-3  # settled
    params = QuadrotorParams()
    g, c_over_m = params.gravity_mps2, 0.018 / params.mass_kg
    # The wind blows toward +x, so the thrust axis leans into it: its x part over its z part
    # (which carries g) is the drag's acceleration (c/m) w² over g.
    ph, th, ps = state[:, 6], state[:, 7], state[:, 8]
    zb_x = np.cos(ph) * np.sin(th) * np.cos(ps) + np.sin(ph) * np.sin(ps)
    zb_z = np.cos(ph) * np.cos(th)
    assert np.all(zb_x < 0.0)
    felt = np.sqrt(g * (-zb_x / zb_z) / c_over_m)
    field = WindField.dryden(mean_mps=7.7, ref_height_m=10.0)
    at_flown = field.mean_velocity(state[:, 2])[:, 0]
    at_plan = field.mean_velocity(np.full(n, z_plan))[:, 0]
    # The tangent's error at |dz| <= 15 m of 60 m is < 0.4 % (1/7 law); the plan's wind differs by 1-4 %.
    np.testing.assert_allclose(felt, at_flown, rtol=0.005)
    far = np.abs(dz) > 5.0
    assert np.all(np.abs(felt[far] - at_plan[far]) > 2.0 * np.abs(felt[far] - at_flown[far]))


def test_both_engines_feel_the_flown_wind_alike():
    # Drones held metres off their plan (GNSS bias) in turbulence and sheared wind: the clamps
    # and the expansion act, and the two engines still agree.
    n = 10
    rng = np.random.default_rng(3)
    pts = rng.uniform(-30.0, 30.0, (n, 3)) + [0.0, 0.0, 40.0]
    model = ErrorModel(gnss_bias_m=3.0, gnss_noise_m=0.05, gnss_vertical_factor=1.0, wind_mean_mps=6.0,
                       wind_direction_rad=0.3, turbulence_sigma_mps=1.3, turbulence_length_m=152.0,
                       drag_coeff_kg_per_m=0.018)
    ref = TrackingReference.circle(pts, radius_m=2.0, omega_rad_s=0.5)
    kw = dict(duration_s=0.6, errors=model, seed=2, output_every=20, chunk_steps=250)
    a = simulate(ref, engine="numba", **kw)
    b = simulate(ref, engine="numpy", **kw)
    assert a.diverged() == [] and b.diverged() == []
    assert np.abs(a.final_state - b.final_state).max() < 1e-8
    assert np.abs(a.positions_m - b.positions_m).max() < 1e-8
