"""Baseline for comparison: a cascaded PID controller with model-inversion feed-forward.

Same interface and same inner plumbing as the ISMC (attitude resolution, command
filter, mixer), with the discontinuity-rejection parts removed::

    u   = -kp e1 - kd e2 - ki ∫e1 + g e_z + p̈_ref       (position PID + feed-forward)
    u_a = -kp_att e3 - kd_att e4 + Θ̈_c + W I⁻¹(Ω × IΩ) - ẆΩ
    τ   = I W⁻¹ u_a

This is exactly the ISMC nominal law with ``r = 1`` and zero switching gains, so the
default gains equal the paper's linear gains (k1..k4): the comparison isolates what
the finite-time exponents and the integral sliding mode add. Under a persistent
disturbance a PD leaves a steady error ``≈ ||Δ1|| / kp``; the integral term (as flight
stacks' position controllers have, e.g. PX4's velocity-loop integrator) removes a
constant one (wind, mass error, battery sag) with anti-windup (clamp ``integral_limit``,
frozen while a rotor saturates, integral separation outside ``integral_zone``).
``ki = 0`` gives the paper's comparison PD (:meth:`BaselineGains.paper`). The default ``ki = 2``
keeps the position loop's
characteristic polynomial ``s³ + kd s² + kp s + ki`` well inside Routh's bound
``ki < kp kd = 20``, leaving margin for the attitude loop's lag.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.flight.control._attitude import CommandFilter
from sim.flight.control._ismc import AttitudeGains, IsmcGains, PositionGains

__all__ = ["BaselineGains"]


@dataclass(frozen=True, slots=True)
class BaselineGains:
    """Cascaded PD gains.

    Attributes:
        kp: Position gain (1/s²).
        kd: Velocity gain (1/s).
        ki: Integral gain (1/s³); 0 gives a PD.
        integral_limit: Anti-windup clamp of ∫e1 per axis (m·s): k_i times it (5 m/s²) covers
            a 30 % battery sag and strong wind.
        integral_zone: The integral advances on an axis only while |e1| is below this (m).
        min_thrust_accel_mps2: Floor of the commanded u_z (m/s²), as :class:`PositionGains`.
        max_tilt_rad: Largest tilt of the command (rad), as :class:`PositionGains`.
        kp_att: Attitude gain (1/s²).
        kd_att: Attitude-rate gain (1/s).
        filter: The same Θ_ref command filter as the ISMC.
        position_rate_hz: Rate of the outer loop (Hz), as :class:`IsmcGains` (None: every step,
            the paper's comparison).
    """

    kp: float = 5.0
    kd: float = 4.0
    ki: float = 2.0
    integral_limit: float = 2.5
    integral_zone: float = 0.5
    min_thrust_accel_mps2: float = 4.9
    max_tilt_rad: float = 0.6
    kp_att: float = 12.0
    kd_att: float = 5.0
    filter: CommandFilter = CommandFilter()
    position_rate_hz: float | None = 250.0

    @classmethod
    def paper(cls) -> BaselineGains:
        """The PD the paper scenario compares against (no integral term)."""
        return cls(ki=0.0, min_thrust_accel_mps2=-math.inf, max_tilt_rad=math.pi / 2, position_rate_hz=None)

    def as_ismc(self) -> IsmcGains:
        """The equivalent ISMC gains (r = 1, α = β = 0, plus k_i) the engines run."""
        return IsmcGains(
            position=PositionGains(k1=self.kp, k2=self.kd, r1=1.0, r2=1.0, alpha=0.0, ki=self.ki,
                                   integral_limit=self.integral_limit, integral_zone=self.integral_zone,
                                   min_thrust_accel_mps2=self.min_thrust_accel_mps2, max_tilt_rad=self.max_tilt_rad),
            attitude=AttitudeGains(k3=self.kp_att, k4=self.kd_att, r3=1.0, r4=1.0, beta=0.0),
            filter=self.filter,
            kind="baseline",
            position_rate_hz=self.position_rate_hz,
        )
