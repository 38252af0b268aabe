"""Rigid-body quadrotor model of docs/method.md §1 (eqs. 1-7), vectorised over drones.

State layout (one row per drone, ``(N, 12)``): position ``p`` (m, world ENU, z up),
velocity ``v`` (m/s, world), Euler angles ``Θ = [φ, θ, ψ]`` (rad, ZYX: roll, pitch,
yaw) and body rates ``Ω`` (rad/s)::

    ṗ = v
    v̇ = -g e_z + τ_f R e_z / m + Δ1
    Θ̇ = W(Θ) Ω
    Ω̇ = I⁻¹ (τ - Ω × IΩ) + W⁻¹(Θ) Δ2

``R = Rz(ψ) Ry(θ) Rx(φ)`` is body-to-world. ``Δ2`` is an *angular acceleration of the
Euler angles* (rad/s², docs/method.md §7): it is mapped through ``W⁻¹`` so that it appears
unchanged in ``Θ̈`` and hence in the attitude error dynamics ``ė4``.

Rotor layout ("+" configuration, viewed from above, x forward, y left, z up):
rotor 1 on +x, rotor 2 on +y, rotor 3 on -x, rotor 4 on -y, each at arm length
``d`` from the centre. Rotors 1 and 3 turn so that their drag reaction torque on the
body is about +z, rotors 2 and 4 about -z. With ``w_i = ω_i²``::

    τ_f = k_F (w1 + w2 + w3 + w4)
    τ_x = d k_F (w2 - w4)          (rotor on +y lifts the left side: positive roll)
    τ_y = d k_F (w3 - w1)          (rotor on -x lifts the back: positive pitch)
    τ_z = k_M (w1 - w2 + w3 - w4)

Saturation (:func:`allocate`): the rotor commands are brought into ``[0, ω_max²]`` as PX4's
control allocator does (sequential desaturation: the collective thrust and yaw are given up
before roll and pitch), or, for the paper scenario, each ``w_i`` is clipped on its own
(``mixer="clip"``); what the rotors then make is what acts on the body.
``ω_max`` follows from a thrust-to-weight ratio: ``4 k_F ω_max² = (T/W) m g``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

__all__ = [
    "MIXERS",
    "STATE_SIZE",
    "YAW_HEADROOM",
    "allocate",
    "QuadrotorParams",
    "euler_rate_matrix",
    "euler_rate_matrix_inverse",
    "mix",
    "quadrotor_derivative",
    "rotation_matrix",
    "saturate",
    "thrust_axis",
    "unmix",
    "w_dot_omega",
]

STATE_SIZE = 12


@dataclass(frozen=True, slots=True)
class QuadrotorParams:
    """Physical parameters of one quadrotor (defaults: the paper's, section 3.4).

    Attributes:
        mass_kg: Mass m (kg).
        inertia_kgm2: Principal moments of inertia (Ix, Iy, Iz) (kg·m²).
        arm_m: Distance d from the centre to each rotor (m).
        k_f: Thrust coefficient k_F (N·s²/rad²).
        k_m: Drag-torque coefficient k_M (N·m·s²/rad²).
        gravity_mps2: Gravitational acceleration g (m/s²).
        thrust_to_weight: Ratio of full-throttle thrust to weight, sets ω_max when
            ``omega_max_rad_s`` is None.
        omega_max_rad_s: Explicit maximum rotor speed (rad/s); None derives it from
            ``thrust_to_weight``.
    """

    mass_kg: float = 0.5
    inertia_kgm2: tuple[float, float, float] = (2.3e-3, 2.4e-3, 2.6e-3)
    arm_m: float = 0.225
    k_f: float = 5.55e-8
    k_m: float = 2.5e-9
    gravity_mps2: float = 9.81
    thrust_to_weight: float = 2.0
    omega_max_rad_s: float | None = None

    @property
    def omega_max_sq(self) -> float:
        """Maximum squared rotor speed ω_max² (rad²/s²)."""
        if self.omega_max_rad_s is not None:
            return float(self.omega_max_rad_s) ** 2
        return self.thrust_to_weight * self.mass_kg * self.gravity_mps2 / (4.0 * self.k_f)

    @property
    def hover_thrust_n(self) -> float:
        """Thrust that balances gravity, m g (N)."""
        return self.mass_kg * self.gravity_mps2

    def mismatched(self, *, fraction: float) -> QuadrotorParams:
        """Return the parameters of a plant whose mass and inertia are off by ``fraction``.

        The rotors are the same hardware, so ω_max is kept at this vehicle's value
        (the plant's true thrust-to-weight ratio changes accordingly).

        Args:
            fraction: Relative error, e.g. 0.1 makes the plant 10 % heavier and
                10 % harder to rotate than the controller believes (dimensionless).
        """
        scale = 1.0 + float(fraction)
        ix, iy, iz = (float(i) for i in self.inertia_kgm2)
        return replace(
            self,
            mass_kg=self.mass_kg * scale,
            inertia_kgm2=(ix * scale, iy * scale, iz * scale),
            omega_max_rad_s=float(np.sqrt(self.omega_max_sq)),
        )

    def as_vector(self) -> np.ndarray:
        """Pack for the fused kernel: ``[m, Ix, Iy, Iz, d, k_F, k_M, g, ω_max²]``."""
        ix, iy, iz = self.inertia_kgm2
        return np.array(
            [self.mass_kg, ix, iy, iz, self.arm_m, self.k_f, self.k_m, self.gravity_mps2,
             self.omega_max_sq],
            dtype=np.float64,
        )


def rotation_matrix(euler_rad: np.ndarray) -> np.ndarray:
    """Body-to-world rotation ``R = Rz(ψ) Ry(θ) Rx(φ)``.

    Args:
        euler_rad: ``(N, 3)`` Euler angles [φ, θ, ψ] (rad).

    Returns:
        ``(N, 3, 3)`` rotation matrices.
    """
    sph, cph = np.sin(euler_rad[:, 0]), np.cos(euler_rad[:, 0])
    sth, cth = np.sin(euler_rad[:, 1]), np.cos(euler_rad[:, 1])
    sps, cps = np.sin(euler_rad[:, 2]), np.cos(euler_rad[:, 2])
    r = np.empty((euler_rad.shape[0], 3, 3))
    r[:, 0, 0] = cth * cps
    r[:, 0, 1] = sph * sth * cps - cph * sps
    r[:, 0, 2] = cph * sth * cps + sph * sps
    r[:, 1, 0] = cth * sps
    r[:, 1, 1] = sph * sth * sps + cph * cps
    r[:, 1, 2] = cph * sth * sps - sph * cps
    r[:, 2, 0] = -sth
    r[:, 2, 1] = sph * cth
    r[:, 2, 2] = cph * cth
    return r


def thrust_axis(euler_rad: np.ndarray) -> np.ndarray:
    """Third column of R, the body z axis in the world frame, ``(N, 3)`` (unit)."""
    sph, cph = np.sin(euler_rad[:, 0]), np.cos(euler_rad[:, 0])
    sth, cth = np.sin(euler_rad[:, 1]), np.cos(euler_rad[:, 1])
    sps, cps = np.sin(euler_rad[:, 2]), np.cos(euler_rad[:, 2])
    return np.stack(
        [cph * sth * cps + sph * sps, cph * sth * sps - sph * cps, cph * cth], axis=1
    )


def euler_rate_matrix(euler_rad: np.ndarray) -> np.ndarray:
    """``W(Θ)`` with ``Θ̇ = W Ω`` (ZYX Euler angles), ``(N, 3, 3)``; singular at θ = ±π/2."""
    sph, cph = np.sin(euler_rad[:, 0]), np.cos(euler_rad[:, 0])
    cth = np.cos(euler_rad[:, 1])
    tth = np.sin(euler_rad[:, 1]) / cth
    w = np.zeros((euler_rad.shape[0], 3, 3))
    w[:, 0, 0] = 1.0
    w[:, 0, 1] = sph * tth
    w[:, 0, 2] = cph * tth
    w[:, 1, 1] = cph
    w[:, 1, 2] = -sph
    w[:, 2, 1] = sph / cth
    w[:, 2, 2] = cph / cth
    return w


def euler_rate_matrix_inverse(euler_rad: np.ndarray) -> np.ndarray:
    """``W⁻¹(Θ)`` with ``Ω = W⁻¹ Θ̇``, ``(N, 3, 3)`` (defined everywhere)."""
    sph, cph = np.sin(euler_rad[:, 0]), np.cos(euler_rad[:, 0])
    sth, cth = np.sin(euler_rad[:, 1]), np.cos(euler_rad[:, 1])
    w = np.zeros((euler_rad.shape[0], 3, 3))
    w[:, 0, 0] = 1.0
    w[:, 0, 2] = -sth
    w[:, 1, 1] = cph
    w[:, 1, 2] = sph * cth
    w[:, 2, 1] = -sph
    w[:, 2, 2] = cph * cth
    return w


def mix(thrust_n: np.ndarray, torque_nm: np.ndarray, params: QuadrotorParams) -> np.ndarray:
    """Invert the "+" mixer: squared rotor speeds for a thrust and body torque.

    Args:
        thrust_n: ``(N,)`` collective thrust τ_f (N).
        torque_nm: ``(N, 3)`` body torque τ (N·m).
        params: Vehicle parameters (k_F, k_M, d).

    Returns:
        ``(N, 4)`` squared rotor speeds ω_i² (rad²/s²), unsaturated (may be negative).
    """
    base = thrust_n / (4.0 * params.k_f)
    roll = torque_nm[:, 0] / (2.0 * params.arm_m * params.k_f)
    pitch = torque_nm[:, 1] / (2.0 * params.arm_m * params.k_f)
    yaw = torque_nm[:, 2] / (4.0 * params.k_m)
    return np.stack(
        [base - pitch + yaw, base + roll - yaw, base + pitch + yaw, base - roll - yaw], axis=1
    )


def unmix(omega_sq: np.ndarray, params: QuadrotorParams) -> tuple[np.ndarray, np.ndarray]:
    """Forward mixer (eq. 7, "+" layout): thrust (N) and body torque (N·m) from ω_i².

    Args:
        omega_sq: ``(N, 4)`` squared rotor speeds (rad²/s²).
        params: Vehicle parameters.

    Returns:
        ``(thrust (N,), torque (N, 3))`` in N and N·m.
    """
    w1, w2, w3, w4 = omega_sq[:, 0], omega_sq[:, 1], omega_sq[:, 2], omega_sq[:, 3]
    thrust = params.k_f * (w1 + w2 + w3 + w4)
    torque = np.stack(
        [
            params.arm_m * params.k_f * (w2 - w4),
            params.arm_m * params.k_f * (w3 - w1),
            params.k_m * (w1 - w2 + w3 - w4),
        ],
        axis=1,
    )
    return thrust, torque


def saturate(omega_sq: np.ndarray, params: QuadrotorParams) -> tuple[np.ndarray, np.ndarray]:
    """Clip squared rotor speeds to ``[0, ω_max²]``.

    Returns:
        ``(clipped (N, 4) rad²/s², saturated (N,) bool)``; ``saturated`` is True when
        any rotor of that drone was clipped (used to freeze the ISMC integrators).
    """
    top = params.omega_max_sq
    clipped = np.minimum(np.maximum(omega_sq, 0.0), top)
    saturated = np.any((omega_sq < 0.0) | (omega_sq > top), axis=1)
    return clipped, saturated


#: Mixers: ``"desaturate"`` (PX4's sequential desaturation, airmode for roll and pitch; the default) or
#: ``"clip"`` (each rotor clipped on its own: the paper scenario's, which has no allocation).
MIXERS: tuple[str, ...] = ("desaturate", "clip")
#: Room above ω_max² the yaw step may use before the collective comes down (PX4: 15 % of the range).
YAW_HEADROOM = 0.15

# Desaturation directions in squared-speed space (the "+" layout of ``mix``): what one unit of the
# collective, roll, pitch and yaw shares adds to each rotor.
_THRUST_DIR = np.array([1.0, 1.0, 1.0, 1.0])
_YAW_DIR = np.array([1.0, -1.0, 1.0, -1.0])
_ROLL_PITCH = np.array([1.0, 1.0, 0.0])  # a torque's roll and pitch, its yaw zeroed


def _desaturation_gain(a: np.ndarray, direction: np.ndarray, top: float) -> np.ndarray:
    """PX4's ``computeDesaturationGain``: the shift along ``direction`` that un-saturates ``a`` ``(N, 4)``.

    For each rotor the direction moves (entries ±1) and that is outside ``[0, top]``, the multiple
    of ``direction`` that brings it back to the bound; the result is the most negative plus the
    most positive of them (0 if none): an overshoot on one side is removed, overshoots on both
    sides are traded against each other. Returns ``(N,)``.
    """
    k = np.where(a > top, (top - a) * direction, np.where(a < 0.0, (0.0 - a) * direction, 0.0))
    k = np.where(direction != 0.0, k, 0.0)
    out: np.ndarray = np.minimum(k.min(axis=1), 0.0) + np.maximum(k.max(axis=1), 0.0)
    return out


def _desaturate(
    a: np.ndarray, direction: np.ndarray, top: float, *, on: bool, reduce_only: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """PX4's ``desaturateActuators``: shift by the gain, then by half the gain that is left.

    ``reduce_only``: the collective is lowered, never raised, to un-saturate (PX4's
    ``increase_only`` on its downward thrust axis). ``on`` False: no shift (the plain clip).
    Returns ``(a (N, 4), shifted (N,) bool)``.
    """
    g = _desaturation_gain(a, direction, top)
    use = (g <= 0.0) & on if reduce_only else np.full(g.shape, on)
    g = np.where(use, g, 0.0)
    a = a + g[:, None] * direction
    g2 = np.where(use, 0.5 * _desaturation_gain(a, direction, top), 0.0)
    a = a + g2[:, None] * direction
    return a, (g != 0.0) | (g2 != 0.0)


def allocate(
    thrust_n: np.ndarray, torque_nm: np.ndarray, params: QuadrotorParams, *, mixer: str = "desaturate",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Squared rotor speeds in ``[0, ω_max²]`` for a thrust and torque command, and what fell short.

    ``"desaturate"``: PX4's sequential desaturation with airmode for roll and pitch
    (``MC_AIRMODE = 1``; ``ControlAllocationSequentialDesaturation::mixAirmodeRP`` and ``mixYaw``
    in PX4-Autopilot's control_allocator): mix the collective, roll and pitch and shift the
    collective, down or up, until the rotors fit in ``[0, ω_max²]`` (overshoots on both sides
    are split); add yaw and give it up as far as a rotor leaves ``[0, 1.15 ω_max²]``; lower the
    collective again (never raise it for yaw); clip. So roll and pitch are delivered whenever
    some shift of the collective makes room for them, and yaw is given up first. Issue 20's QA:
    with each rotor clipped on its own a weak drone lost its roll authority at a landing (the
    top rotors clipped), rolled ±0.7 rad and fell through the pad. Why airmode for roll and pitch
    and not PX4's default (off: the collective only lowered, roll and pitch cut instead): in a
    gusty descent the collective is low and the rotors on the slow side hit zero; with airmode
    off the attitude then gives way, and on the 12-drone test show in gusty-RTK (seed 3, drone 7)
    it was blown 4 m off in the descent and hit the ground at the landing, which the plain
    clip (that raises a rotor at zero, i.e. the collective, implicitly) and airmode both fly.
    The collective is raised only as far as roll and pitch need it (hover and a level descent
    are unchanged).
    ``"clip"``: each rotor clipped on its own (the paper scenario, which models no allocation).

    Args:
        thrust_n: ``(N,)`` commanded collective thrust (N).
        torque_nm: ``(N, 3)`` commanded body torque (N·m).
        params: The vehicle (k_F, k_M, d, ω_max).
        mixer: One of :data:`MIXERS`.

    Returns:
        ``(omega_sq (N, 4) rad²/s², thrust_short (N,), torque_short (N,))``: the flags say the
        allocation could not deliver the commanded collective thrust, resp. the commanded torque
        (what the controllers' anti-windup freezes on).
    """
    if mixer not in MIXERS:
        raise ValueError(f"unknown mixer {mixer!r} (expected one of {', '.join(MIXERS)})")
    top = params.omega_max_sq
    on = mixer == "desaturate"
    # ``mix``'s shares, the yaw share kept apart (added after roll and pitch, as PX4 does).
    a = mix(thrust_n, torque_nm * _ROLL_PITCH, params)
    yaw = torque_nm[:, 2] / (4.0 * params.k_m)
    a, t1 = _desaturate(a, _THRUST_DIR, top, on=on)
    a, y = _desaturate(a + yaw[:, None] * _YAW_DIR, _YAW_DIR, (1.0 + YAW_HEADROOM) * top, on=on)
    a, t2 = _desaturate(a, _THRUST_DIR, top, on=on, reduce_only=True)
    omega_sq, cut = saturate(a, params)
    return omega_sq, t1 | t2 | cut, y | cut


def quadrotor_derivative(
    state: np.ndarray,
    thrust_n: np.ndarray,
    torque_nm: np.ndarray,
    accel_dist_mps2: np.ndarray,
    ang_dist_radps2: np.ndarray,
    params: QuadrotorParams,
) -> np.ndarray:
    """Time derivative of the ``(N, 12)`` state (eqs. 1-4) with inputs held.

    Args:
        state: ``(N, 12)`` rows ``[p (m), v (m/s), Θ (rad), Ω (rad/s)]``.
        thrust_n: ``(N,)`` collective thrust τ_f actually produced (N).
        torque_nm: ``(N, 3)`` body torque actually produced (N·m).
        accel_dist_mps2: ``(N, 3)`` Δ1, added to v̇ (m/s²).
        ang_dist_radps2: ``(N, 3)`` Δ2, an Euler-angle acceleration added to Θ̈
            (rad/s²), i.e. ``W⁻¹ Δ2`` is added to Ω̇.
        params: Plant parameters.

    Returns:
        ``(N, 12)`` derivative ``[ṗ, v̇, Θ̇, Ω̇]``.
    """
    euler = state[:, 6:9]
    omega = state[:, 9:12]
    inertia = np.asarray(params.inertia_kgm2)
    acc = thrust_n[:, None] / params.mass_kg * thrust_axis(euler) + accel_dist_mps2
    acc[:, 2] -= params.gravity_mps2
    euler_dot = np.einsum("nij,nj->ni", euler_rate_matrix(euler), omega)
    gyro = np.cross(omega, omega * inertia)
    omega_dot = (torque_nm - gyro) / inertia + np.einsum(
        "nij,nj->ni", euler_rate_matrix_inverse(euler), ang_dist_radps2
    )
    return np.concatenate([state[:, 3:6], acc, euler_dot, omega_dot], axis=1)


def w_dot_omega(euler_rad: np.ndarray, omega_radps: np.ndarray) -> np.ndarray:
    """``Ẇ(Θ, Θ̇) Ω`` with ``Θ̇ = W Ω``: the part of Θ̈ not produced by Ω̇, ``(N, 3)`` (rad/s²).

    Args:
        euler_rad: ``(N, 3)`` Euler angles (rad).
        omega_radps: ``(N, 3)`` body rates (rad/s).
    """
    sph, cph = np.sin(euler_rad[:, 0]), np.cos(euler_rad[:, 0])
    sth, cth = np.sin(euler_rad[:, 1]), np.cos(euler_rad[:, 1])
    tth = sth / cth
    q, r = omega_radps[:, 1], omega_radps[:, 2]
    # Θ̇ = W Ω; only φ̇ and θ̇ enter Ẇ (W does not depend on ψ).
    phid = omega_radps[:, 0] + sph * tth * q + cph * tth * r
    thed = cph * q - sph * r
    sec2 = 1.0 / (cth * cth)
    x0 = (cph * tth * phid + sph * sec2 * thed) * q + (-sph * tth * phid + cph * sec2 * thed) * r
    x1 = -sph * phid * q - cph * phid * r
    x2 = (cph / cth * phid + sph * sth * sec2 * thed) * q + (
        -sph / cth * phid + cph * sth * sec2 * thed
    ) * r
    return np.stack([x0, x1, x2], axis=1)
