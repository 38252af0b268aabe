"""Independent checks of the rigid-body model: kinematics by finite differences, trim, conservation.

Each test computes its expectation without the code under test: the rotation matrix's
own time derivative (Ṙ = R [Ω]×, body rates), Newton's laws at hover, and the two
invariants of a torque-free rigid body (world angular momentum R I Ω and kinetic energy
½ Ωᵀ I Ω) under a plain RK4 written here.
"""

from __future__ import annotations

import numpy as np
import pytest

from sim.flight._quadrotor import (
    STATE_SIZE,
    QuadrotorParams,
    euler_rate_matrix,
    euler_rate_matrix_inverse,
    mix,
    quadrotor_derivative,
    rotation_matrix,
    saturate,
    unmix,
    w_dot_omega,
)


def _hat(w: np.ndarray) -> np.ndarray:
    """(N, 3) -> (N, 3, 3) skew matrices with hat(a) b = a x b."""
    out = np.zeros((w.shape[0], 3, 3))
    out[:, 0, 1], out[:, 0, 2] = -w[:, 2], w[:, 1]
    out[:, 1, 0], out[:, 1, 2] = w[:, 2], -w[:, 0]
    out[:, 2, 0], out[:, 2, 1] = -w[:, 1], w[:, 0]
    return out


def _random_attitudes(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    euler = np.column_stack([
        rng.uniform(-np.pi, np.pi, n), rng.uniform(-1.3, 1.3, n), rng.uniform(-np.pi, np.pi, n),
    ])  # pitch kept away from the ZYX singularity at ±π/2
    omega = rng.normal(0.0, 2.0, (n, 3))
    return euler, omega


def test_euler_rate_matrix_matches_the_rotation_convention() -> None:
    """R(Θ + h Θ̇) - R(Θ - h Θ̇) over 2h equals R [Ω]× (body rates) when Θ̇ = W(Θ) Ω."""
    euler, omega = _random_attitudes(np.random.default_rng(1), 200)
    euler_dot = np.einsum("nij,nj->ni", euler_rate_matrix(euler), omega)
    h = 1e-6
    r_dot_fd = (rotation_matrix(euler + h * euler_dot) - rotation_matrix(euler - h * euler_dot)) / (2 * h)
    r_dot = rotation_matrix(euler) @ _hat(omega)
    np.testing.assert_allclose(r_dot_fd, r_dot, atol=1e-7)


def test_euler_rate_inverse_and_its_derivative() -> None:
    """W⁻¹ W = I, and Ẇ Ω equals the central difference of W(Θ(t)) Ω along Θ̇ = W Ω."""
    euler, omega = _random_attitudes(np.random.default_rng(2), 200)
    w = euler_rate_matrix(euler)
    np.testing.assert_allclose(euler_rate_matrix_inverse(euler) @ w, np.broadcast_to(np.eye(3), w.shape), atol=1e-9)
    euler_dot = np.einsum("nij,nj->ni", w, omega)
    h = 1e-6
    w_dot = (euler_rate_matrix(euler + h * euler_dot) - euler_rate_matrix(euler - h * euler_dot)) / (2 * h)
    np.testing.assert_allclose(w_dot_omega(euler, omega), np.einsum("nij,nj->ni", w_dot, omega),
                               rtol=1e-6, atol=1e-5)


@pytest.mark.parametrize("yaw_rad", [0.0, 1.0, -2.5])
def test_hover_trim_is_an_equilibrium(yaw_rad: float) -> None:
    """Level, at rest, m g of thrust through the mixer and no torque: every derivative is zero."""
    params = QuadrotorParams()
    state = np.zeros((1, STATE_SIZE))
    state[0, 0:3] = (3.0, -2.0, 40.0)
    state[0, 8] = yaw_rad
    w_sq = mix(np.array([params.mass_kg * params.gravity_mps2]), np.zeros((1, 3)), params)
    # Newton: four equal rotors each carry a quarter of the weight, inside the rotor limits.
    np.testing.assert_allclose(w_sq, params.mass_kg * params.gravity_mps2 / (4 * params.k_f), rtol=1e-12)
    clipped, saturated = saturate(w_sq, params)
    assert not saturated.any()
    thrust, torque = unmix(clipped, params)
    deriv = quadrotor_derivative(state, thrust, torque, np.zeros((1, 3)), np.zeros((1, 3)), params)
    np.testing.assert_allclose(deriv, 0.0, atol=1e-12)


def _rk4(state: np.ndarray, dt_s: float, steps: int, params: QuadrotorParams) -> list[np.ndarray]:
    zero1, zero3 = np.zeros(state.shape[0]), np.zeros((state.shape[0], 3))

    def f(s: np.ndarray) -> np.ndarray:
        return quadrotor_derivative(s, zero1, zero3, zero3, zero3, params)

    out = [state]
    for _ in range(steps):
        k1 = f(state)
        k2 = f(state + 0.5 * dt_s * k1)
        k3 = f(state + 0.5 * dt_s * k2)
        k4 = f(state + dt_s * k3)
        state = state + dt_s / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(state)
    return out


def test_torque_free_tumble_conserves_angular_momentum_and_energy() -> None:
    """No thrust, no torque: world angular momentum R I Ω and ½ Ωᵀ I Ω stay constant (RK4, 1 ms)."""
    params = QuadrotorParams()
    inertia = np.asarray(params.inertia_kgm2)
    state = np.zeros((3, STATE_SIZE))
    state[:, 6:9] = [(0.1, -0.2, 0.3), (0.0, 0.0, 0.0), (-0.3, 0.2, 2.0)]
    # Spins mostly about z (the largest moment, a stable axis: pitch stays far from ±π/2)
    # with enough x/y rate that the gyroscopic term works.
    state[:, 9:12] = [(0.8, 0.5, 6.0), (0.3, -0.6, 4.0), (-0.5, 0.4, 5.0)]
    traj = _rk4(state, 1e-3, 3000, params)

    def momentum(s: np.ndarray) -> np.ndarray:
        return np.einsum("nij,nj->ni", rotation_matrix(s[:, 6:9]), inertia * s[:, 9:12])

    def energy(s: np.ndarray) -> np.ndarray:
        return 0.5 * np.sum(inertia * s[:, 9:12] ** 2, axis=1)

    l0, e0 = momentum(traj[0]), energy(traj[0])
    assert np.all(np.abs(traj[-1][:, 9:11] - traj[0][:, 9:11]).max(axis=1) > 1e-3)  # the body really tumbles
    for s in traj[::100]:
        np.testing.assert_allclose(momentum(s), l0, rtol=0, atol=1e-7 * np.abs(l0).max())
        np.testing.assert_allclose(energy(s), e0, rtol=1e-7)
    assert np.abs(traj[-1][:, 7]).max() < 1.0


def test_the_tumble_check_catches_a_wrong_gyroscopic_sign() -> None:
    """The invariants are a real test: flipping the sign of Ω x IΩ breaks the momentum check."""
    params = QuadrotorParams()
    inertia = np.asarray(params.inertia_kgm2)
    s = np.zeros((1, STATE_SIZE))
    s[0, 9:12] = (0.8, 0.5, 6.0)
    zero1, zero3 = np.zeros(1), np.zeros((1, 3))
    good = quadrotor_derivative(s, zero1, zero3, zero3, zero3, params)[0, 9:12]
    omega = s[0, 9:12]
    # d/dt (R I Ω) = R (I Ω̇ + Ω x IΩ) = 0 at R = I: holds for the model, fails for the flipped sign.
    np.testing.assert_allclose(inertia * good + np.cross(omega, inertia * omega), 0.0, atol=1e-12)
    flipped = np.cross(omega, inertia * omega) / inertia
    assert np.abs(inertia * flipped + np.cross(omega, inertia * omega)).max() > 1e-4
