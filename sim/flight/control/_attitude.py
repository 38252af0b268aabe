"""Attitude resolution (docs/method.md §5, eq. 51) and the Θ_ref command filter.

The position loop outputs the desired thrust acceleration ``a = u`` (it contains
``+g e_z``); with the yaw reference ψ_ref the exact roll/pitch references for
``R = Rz Ry Rx`` are::

    φ_ref = arcsin((a_x sin ψ_ref - a_y cos ψ_ref) / ||a||)
    θ_ref = atan2(a_x cos ψ_ref + a_y sin ψ_ref, a_z)

**How Θ̇_ref and Θ̈_ref are obtained** (the paper leaves the method open): ``u``
contains ``u_d = ∫ω̃``, whose derivative ω̃ is discontinuous, so an analytic Θ̈_ref
(which would need u̇ and ü) does not exist. We use a second-order *command filter*
(Farrell et al., command-filtered backstepping), critically damped by default::

    Θ̈_c = ω_n² (Θ_ref - Θ_c) - 2 ζ ω_n Θ̇_c

and the attitude loop tracks ``(Θ_c, Θ̇_c, Θ̈_c)``: all three are consistent, Θ̇_c is
C¹ and Θ̈_c continuous, so the torques stay continuous. The filter is integrated with
semi-implicit Euler at the control step and starts at ``Θ_c(0) = Θ_ref(0)``,
``Θ̇_c(0) = 0``. Its lag (~2ζ/ω_n) shows up in the position loop as a thrust-direction
error, which the position ISMC's switching term rejects like any matched disturbance.
``ω_n`` is an inner-loop detail the paper does not give. The filter lag couples back
into the position loop: the switching input u_d always moves at a rate between α/2
and 3α/2, and the filter turns that into a thrust-direction error of about
2ζ/ω_n · |u̇_d| / g (rad) whose rate must stay inside the position loop's switching
margin; a faster filter on the other hand passes more of u_d's discrete chatter into
Θ̈_c and hence into the torques. Measured on the paper scenario (t >= 8 s; position
error, attitude error to the raw eq. 51 reference, peak torque):

    ω_n = 40:  1.1e-2 m  (fails the 1e-3 m requirement), smooth torques
    ω_n = 120: 7.1e-4 m, 2.6e-2 rad, 0.11 N·m
    ω_n = 200: 1.9e-4 m, 1.4e-2 rad, 0.15 N·m
    ω_n = 300: 7.0e-5 m, 8.3e-3 rad, 0.23 N·m   <- default (ζ = 1)
    ω_n = 400: 3.7e-5 m, 5.8e-3 rad, 0.36 N·m

The default (a 0.3 rad step at 1 ms, well inside semi-implicit Euler's stability
bound) is the slowest filter that meets both of the paper scenario's error thresholds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CommandFilter", "resolve_attitude"]


@dataclass(frozen=True, slots=True)
class CommandFilter:
    """Second-order command filter on Θ_ref.

    Attributes:
        omega_n_rad_s: Natural frequency ω_n (rad/s).
        zeta: Damping ratio ζ (dimensionless).
    """

    omega_n_rad_s: float = 300.0
    zeta: float = 1.0

    def acceleration(
        self, theta_ref: np.ndarray, theta_c: np.ndarray, theta_c_dot: np.ndarray
    ) -> np.ndarray:
        """Filter output Θ̈_c (rad/s²) for the raw reference and the filter state."""
        wn = self.omega_n_rad_s
        out: np.ndarray = wn * wn * (theta_ref - theta_c) - 2.0 * self.zeta * wn * theta_c_dot
        return out


def resolve_attitude(accel_mps2: np.ndarray, psi_ref_rad: np.ndarray) -> np.ndarray:
    """Euler-angle reference that aligns the thrust axis with ``accel_mps2`` (eq. 51).

    Args:
        accel_mps2: ``(N, 3)`` desired thrust acceleration ``u`` (m/s², includes +g e_z).
        psi_ref_rad: ``(N,)`` or scalar yaw reference (rad).

    Returns:
        ``(N, 3)`` ``[φ_ref, θ_ref, ψ_ref]`` (rad). A zero ``a`` gives level attitude.
    """
    psi = np.broadcast_to(np.asarray(psi_ref_rad, dtype=np.float64), accel_mps2.shape[:1])
    sps, cps = np.sin(psi), np.cos(psi)
    ax, ay, az = accel_mps2[:, 0], accel_mps2[:, 1], accel_mps2[:, 2]
    n = np.sqrt(ax * ax + ay * ay + az * az)
    ratio = np.where(n > 0.0, (ax * sps - ay * cps) / np.where(n > 0.0, n, 1.0), 0.0)
    phi = np.arcsin(np.clip(ratio, -1.0, 1.0))
    theta = np.arctan2(ax * cps + ay * sps, az)
    return np.stack([phi, theta, psi], axis=1)
