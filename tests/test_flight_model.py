"""Quadrotor model, ISMC building blocks and attitude resolution (docs/method.md §1, §4-§6)."""

from __future__ import annotations

import numpy as np
import pytest

from sim.flight import (
    Disturbance,
    TrackingReference,
    hover_state,
    resolve_attitude,
    sig,
    simulate,
    unit,
)
from sim.flight._quadrotor import (
    QuadrotorParams,
    euler_rate_matrix,
    euler_rate_matrix_inverse,
    mix,
    rotation_matrix,
    saturate,
    thrust_axis,
    unmix,
)

RNG = np.random.default_rng(7)


def test_sig_and_unit_are_zero_not_nan_at_zero():
    z = np.zeros((2, 3))
    for r in (0.5, 5.0 / 7.0, 1.0):
        out = sig(z, r)
        assert np.all(out == 0.0) and np.all(np.isfinite(out))
    assert np.all(unit(z) == 0.0)
    x = RNG.normal(size=(50, 3))
    for r in (0.5, 5.0 / 7.0):
        np.testing.assert_allclose(np.linalg.norm(sig(x, r), axis=1), np.linalg.norm(x, axis=1) ** r, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(unit(x), axis=1), 1.0, rtol=1e-12)


def test_rotation_thrust_axis_and_euler_rates():
    e = RNG.uniform(-1.0, 1.0, (40, 3))
    r = rotation_matrix(e)
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", r, r), np.broadcast_to(np.eye(3), r.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-12)
    np.testing.assert_allclose(r[:, :, 2], thrust_axis(e), atol=1e-15)
    w, wi = euler_rate_matrix(e), euler_rate_matrix_inverse(e)
    np.testing.assert_allclose(np.einsum("nij,njk->nik", w, wi), np.broadcast_to(np.eye(3), w.shape), atol=1e-12)


def test_mixer_round_trip_and_saturation():
    p = QuadrotorParams()
    thrust = np.full(5, p.hover_thrust_n)
    torque = RNG.normal(scale=1e-2, size=(5, 3))
    w = mix(thrust, torque, p)
    t2, q2 = unmix(w, p)
    np.testing.assert_allclose(t2, thrust, rtol=1e-12)
    np.testing.assert_allclose(q2, torque, atol=1e-14)
    # Full throttle at the thrust-to-weight ratio, and clipping flags the drone.
    np.testing.assert_allclose(4 * p.k_f * p.omega_max_sq, 2.0 * p.hover_thrust_n)
    clipped, sat = saturate(np.array([[-1.0, 0.0, 1.0, 2.0 * p.omega_max_sq], [1.0, 1.0, 1.0, 1.0]]), p)
    assert sat.tolist() == [True, False]
    assert clipped[0, 0] == 0.0 and clipped[0, 3] == p.omega_max_sq


def test_resolve_attitude_aligns_thrust_axis():
    a = RNG.normal(size=(30, 3)) + np.array([0.0, 0.0, 9.81])
    psi = RNG.uniform(-np.pi, np.pi, 30)
    e = resolve_attitude(a, psi)
    np.testing.assert_allclose(e[:, 2], psi)
    np.testing.assert_allclose(thrust_axis(e), a / np.linalg.norm(a, axis=1, keepdims=True), atol=1e-12)
    assert np.all(resolve_attitude(np.zeros((1, 3)), 0.0) == 0.0)


def test_mismatch_keeps_rotors():
    p = QuadrotorParams()
    q = p.mismatched(fraction=0.2)
    assert q.mass_kg == pytest.approx(0.6) and q.inertia_kgm2[0] == pytest.approx(2.76e-3)
    assert q.omega_max_sq == pytest.approx(p.omega_max_sq)


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_hover_equilibrium_is_held_exactly(engine):
    pts = np.array([[0.0, 0.0, 10.0], [3.0, -4.0, 25.0], [-7.5, 2.25, 1.0]])
    res = simulate(TrackingReference.hover(pts), duration_s=1.0, initial_state=hover_state(pts),
                   engine=engine, disturbance="none")
    assert res.diverged() == []
    np.testing.assert_array_equal(res.final_state[:, 6:12], 0.0)  # level, no rotation at all
    assert np.abs(res.final_state[:, 0:3] - pts).max() < 1e-12  # m, rounding of m·g through the mixer
    assert res.max_error_m.max() < 1e-12


def test_disturbances():
    t = np.linspace(0.0, 10.0, 101)
    sig_p = Disturbance.paper().signals(t)
    expect = np.c_[0.1 * np.sin(t), 0.1 * np.cos(t), 0.1 * (np.sin(t) + np.cos(t))]
    np.testing.assert_allclose(sig_p[:, 0:3], expect, atol=1e-15)
    np.testing.assert_allclose(sig_p[:, 6:9], expect, atol=1e-15)
    w1 = Disturbance.wind_gusts(seed=3).signals(t)
    w2 = Disturbance.wind_gusts(seed=3).signals(t)
    w3 = Disturbance.wind_gusts(seed=4).signals(t)
    np.testing.assert_array_equal(w1, w2)
    assert not np.allclose(w1, w3)
    assert np.all(Disturbance.none().signals(t) == 0.0)
