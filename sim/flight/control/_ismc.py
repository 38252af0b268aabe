"""Finite-time multivariable integral sliding-mode control (docs/method.md §4 and §6).

Both loops share one structure, for an error pair ``(e, ė)`` with ``ë = u + f + d``::

    u_n = -k_a sig(e, r_a) - k_b sig(ė, r_b) - f          (nominal, eq. 28)
    s   = ė(t) - ė(0) - ∫0^t (u_n + f) dt                  (eq. 30; s(0) = 0)
    ω̃   = -α ( s/||s|| + 0.5 ṡ/||ṡ|| )                     (eq. 35)
    u_d = ∫ ω̃ dt                                          (eq. 36, continuous)
    u   = u_n + u_d

Discrete implementation at the control step ``dt`` (textbook sampled form, the paper is
silent on it):

* ``ṡ``'s direction is taken from the backward difference ``s_k - s_{k-1}`` (no
  accelerometer needed; only the direction enters ω̃). At k = 0 it is zero.
* ``∫(u_n + f)`` and ``u_d`` are integrated with the rectangle rule, values of step k
  held over ``[t_k, t_{k+1}]``; ``u`` at step k uses ``u_d`` of step k.
* Anti-windup: when any rotor of a drone saturates at step k, that drone's ``u_d``
  (position and attitude) is not advanced; ``∫(u_n + f)`` keeps integrating so ``s``
  keeps measuring the true mismatch.
* **Switching law** (``IsmcGains.switching``). ``"sign"`` is the paper's law: the two
  directions of ω̃ use ``x / max(||x||, SWITCH_EPS)`` with ``SWITCH_EPS = 1e-9`` (m/s or
  rad/s). In normal sliding the discrete twisting keeps
  ``||s||`` near ``α dt²`` (~5e-6), far above it, so performance is unchanged; it only
  replaces the direction of a vector made of rounding noise (e.g. ``s - s_prev`` when it
  is exactly or nearly zero) by a proportional term, so a 1e-17 difference cannot turn
  into a full-size switching step. Its cost is chattering: after settling the torques
  carry a ~9 Hz oscillation with ±0.2 N·m peaks and 1 ms jumps (issue 20), which real
  motors (5-50 ms) cannot produce. ``"boundary"`` (the default) is the continuous
  saturation ``x / max(||x||, φ)`` with a boundary layer φ = ``boundary_layer`` of each
  loop (1e-2 by default, the value issue 20 measured): inside the layer the law is
  linear (a high-gain integral action on s), outside it is the paper's law. It gives up
  exact finite-time sliding (s converges into ||s|| ≲ φ instead of to 0) and in
  exchange makes u_d Lipschitz, so the command filter and the torques stay smooth
  (docs/method.md §4.1 has the measured trade-off).
* **PID** (the baseline, :class:`~sim.flight.control._baseline.BaselineGains`):
  ``u -= k_i ∫e1 dt``, the integral clamped to ``±integral_limit`` per axis, frozen
  while a rotor saturates and advanced on an axis only while ``|e1| < integral_zone``
  (anti-windup). ``k_i = 0`` for the ISMC.
* ``sig`` and unit vectors are guarded at zero (ISMC makes ``s(0) = 0`` exactly, an
  unguarded ``||s||^(r-1)`` is NaN at step 0). ``r = 1/2`` is evaluated as
  ``1/sqrt(||x||)`` (exact and cheap) in every engine.

The paper's gains (section 3.4) are the defaults. Note they do not satisfy the
homogeneity relation ``r1 = r2 / (2 - r2)`` of Lemma 1 (that gives 5/9 for r2 = 5/7,
the paper uses 1/2); the paper's values are kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.flight._quadrotor import MIXERS
from sim.flight.control._attitude import CommandFilter

__all__ = [
    "SWITCHING_LAWS",
    "SWITCH_EPS",
    "AttitudeGains",
    "IsmcGains",
    "PositionGains",
    "ismc_nominal",
    "ismc_switching",
    "limit_thrust_accel",
    "sig",
    "unit",
]


#: Boundary layer of the paper's ("sign") switching directions (m/s for position, rad/s for attitude).
SWITCH_EPS = 1e-9
#: The selectable switching laws of :class:`IsmcGains`.
SWITCHING_LAWS = ("boundary", "sign")


@dataclass(frozen=True, slots=True)
class PositionGains:
    """Position-loop gains (paper section 3.4).

    Attributes:
        k1: Gain on sig(e1) (1/s² · m^(1-r1)).
        k2: Gain on sig(e2) (units making k2 sig(e2) an acceleration, m/s²).
        r1: Exponent on the position error, 0 < r1 < 1.
        r2: Exponent on the velocity error, 0 < r2 < 1.
        alpha: Switching gain α (m/s³), must exceed twice the bound on ||ḋ||.
        boundary_layer: φ of the ``"boundary"`` switching law (m/s).
        ki: Integral gain on the position error (1/s³); 0 for the ISMC, > 0 makes the
            baseline a PID.
        integral_limit: Clamp of ∫e1 per axis (m·s), anti-windup.
        integral_zone: The integral advances on an axis only while |e1| is below this (m)
            (integral separation: a large transient does not wind it up).
        min_thrust_accel_mps2: Floor of the commanded vertical thrust acceleration u_z
            (m/s²): a large downward error must not command zero thrust, which with
            per-rotor clipping leaves no torque and the drone tumbles.
        max_tilt_rad: Largest angle of u from the vertical (rad); the horizontal part is
            scaled down beyond it. 0.6 rad (34°), about ArduPilot's default ANGLE_MAX of 30°;
            with 0.8 rad a 3 m GNSS-bias step (the "gps-only" preset) made the attitude loop
            lose the drone. Both limits are inactive in normal tracking (the
            paper scenario never reaches them); while one acts, the position loop's u_d
            and integral are frozen, the attitude loop's u_d is not (docs/method.md §4.1:
            freezing it too lost a drone in long gusts). At 0.6 rad a 0.5 kg drone with
            the presets' drag holds its place up to ~14 m/s of air speed.
    """

    k1: float = 5.0
    k2: float = 4.0
    r1: float = 0.5
    r2: float = 5.0 / 7.0
    alpha: float = 5.0
    boundary_layer: float = 1e-2
    ki: float = 0.0
    integral_limit: float = 2.5
    integral_zone: float = 0.5
    min_thrust_accel_mps2: float = 4.9
    max_tilt_rad: float = 0.6


@dataclass(frozen=True, slots=True)
class AttitudeGains:
    """Attitude-loop gains (paper section 3.4).

    Attributes:
        k3: Gain on sig(e3) (rad/s² scale).
        k4: Gain on sig(e4) (rad/s² scale).
        r3: Exponent on the angle error, 0 < r3 < 1.
        r4: Exponent on the angle-rate error, 0 < r4 < 1.
        beta: Switching gain β (rad/s³).
        boundary_layer: φ of the ``"boundary"`` switching law (rad/s).
    """

    k3: float = 12.0
    k4: float = 5.0
    r3: float = 0.5
    r4: float = 5.0 / 7.0
    beta: float = 4.0
    boundary_layer: float = 1e-2


@dataclass(frozen=True, slots=True)
class IsmcGains:
    """All controller settings: both ISMC loops, the switching law and the Θ_ref command filter.

    Attributes:
        position: Position-loop gains.
        attitude: Attitude-loop gains.
        filter: The Θ_ref command filter.
        kind: Label (``"ismc"`` or ``"baseline"``).
        switching: ``"boundary"`` (continuous, the default) or ``"sign"`` (the paper's
            law, eq. 35 as written; :meth:`paper` selects it).
        mixer: How rotor commands beyond ``[0, ω_max²]`` are brought back
            (:func:`sim.flight._quadrotor.allocate`): ``"desaturate"`` (PX4's sequential
            desaturation, airmode for roll and pitch: the collective shifted and yaw given up to keep
            roll and pitch; the default) or
            ``"clip"`` (each rotor on its own; :meth:`paper` selects it: the paper models no
            allocation).
        position_rate_hz: Rate of the outer loop (Hz): the controller's reference, the position
            law, the thrust/tilt limiter and the attitude resolution (eq. 51) run every
            ``K = 1 / (position_rate_hz · dt)`` control steps and their outputs (u, Θ_ref's roll
            and pitch) are held in between (zero-order hold); the command filter, the attitude
            law, the allocation, the estimator and the plant run every step. ``None``: every
            step (the paper's single-rate loop, :meth:`paper`). Flight stacks run the position
            loop slower than the attitude loop: PX4's position controller wakes on each
            ``vehicle_local_position`` (its poll's wakeup source, ``mc_pos_control_main.cpp``),
            which EKF2 publishes at the IMU integration rate, 250 Hz historically (PX4 PR #14759,
            Daniel Agar, 2020: it "controls the vehicle_attitude publication rate and subsequently
            how fast the attitude controllers run"; 400 and 200 Hz were the alternatives weighed,
            the rate loop at 800 Hz). 250 Hz (K = 4 at dt = 1 ms) is the default; the tracking
            cost against 1 kHz is measured in ``tests/test_flight_multirate.py``.
    """

    position: PositionGains = PositionGains()
    attitude: AttitudeGains = AttitudeGains()
    filter: CommandFilter = CommandFilter()
    kind: str = "ismc"
    switching: str = "boundary"
    mixer: str = "desaturate"
    position_rate_hz: float | None = 250.0

    def __post_init__(self) -> None:
        if self.position_rate_hz is not None and not (
                isinstance(self.position_rate_hz, (int, float)) and np.isfinite(self.position_rate_hz)
                and self.position_rate_hz > 0):
            raise ValueError(f"position_rate_hz must be > 0 or None, got {self.position_rate_hz}")
        if self.mixer not in MIXERS:
            raise ValueError(f"unknown mixer {self.mixer!r} (expected one of {', '.join(MIXERS)})")
        if self.switching not in SWITCHING_LAWS:
            raise ValueError(
                f"unknown switching law {self.switching!r} (expected one of {', '.join(SWITCHING_LAWS)})"
            )
        for name, value in (("position.boundary_layer", self.position.boundary_layer),
                            ("attitude.boundary_layer", self.attitude.boundary_layer)):
            if not value > 0:
                raise ValueError(f"{name} must be > 0, got {value}")

    @classmethod
    def paper(cls, *, switching: str = "sign") -> IsmcGains:
        """The paper's controller exactly: its gains, the discontinuous switching law, no thrust or tilt limits,
        each rotor clipped on its own."""
        return cls(position=PositionGains(min_thrust_accel_mps2=-np.inf, max_tilt_rad=np.pi / 2), switching=switching,
                   mixer="clip", position_rate_hz=None)

    def outer_every(self, dt_s: float) -> int:
        """Control steps per run of the outer (position) loop, ``K`` (1: every step).

        Raises:
            ValueError: ``position_rate_hz`` above the control rate or not dividing it.
        """
        if self.position_rate_hz is None:
            return 1
        ratio = 1.0 / (self.position_rate_hz * dt_s)
        k = round(ratio)
        if k < 1 or abs(ratio - k) > 1e-9 * ratio:
            raise ValueError(f"position_rate_hz must divide the control rate {1.0 / dt_s:g} Hz, "
                             f"got {self.position_rate_hz}")
        return int(k)

    def switch_eps(self, dt_s: float) -> tuple[float, float, float, float]:
        """Boundary layers of the switching directions: ``(s, s - s_prev)`` of position, then attitude.

        ``"sign"``: ``SWITCH_EPS`` for all four. ``"boundary"``: φ on s, and on the step
        difference ``s - s_prev ≈ ṡ dt`` the layer ``φ_d dt`` with ``φ_d = √(gain φ) / 4``,
        which makes the linearised law inside both layers, ``s̈ = -(gain/φ) s - (gain/(2 φ_d)) ṡ``,
        critically damped (natural frequency ``√(gain/φ)``: 22 rad/s for α = 5, φ = 1e-2).
        The position loop's step is its own, ``K dt`` (:meth:`outer_every`): s_prev is the
        previous outer step's s.
        """
        if self.switching == "sign":
            return SWITCH_EPS, SWITCH_EPS, SWITCH_EPS, SWITCH_EPS
        out: list[float] = []
        for gain, phi in ((self.position.alpha, self.position.boundary_layer),
                          (self.attitude.beta, self.attitude.boundary_layer)):
            step_s = self.outer_every(dt_s) * dt_s if not out else dt_s
            out += [phi, max(np.sqrt(gain * phi) / 4.0 * step_s, SWITCH_EPS)]
        return out[0], out[1], out[2], out[3]

    def as_vector(self, dt_s: float = 1e-3) -> np.ndarray:
        """Pack for the fused kernel (``dt_s`` scales the layers on ``s - s_prev``).

        Layout: ``[k1,k2,r1,r2,α,k3,k4,r3,r4,β,ω_n,ζ, φp_s,φp_q,φa_s,φa_q, k_i,i_lim,i_zone, u_z_min,tan_tilt_max,
        desaturate, K]`` (``desaturate`` 1.0 for ``mixer="desaturate"``, 0.0 for ``"clip"``; K the
        outer loop's steps, :meth:`outer_every`).
        """
        p, a, f = self.position, self.attitude, self.filter
        return np.array(
            [p.k1, p.k2, p.r1, p.r2, p.alpha, a.k3, a.k4, a.r3, a.r4, a.beta,
             f.omega_n_rad_s, f.zeta, *self.switch_eps(dt_s), p.ki, p.integral_limit, p.integral_zone,
             p.min_thrust_accel_mps2, float(np.tan(p.max_tilt_rad)), 1.0 if self.mixer == "desaturate" else 0.0,
             float(self.outer_every(dt_s))],
            dtype=np.float64,
        )


def sig(x: np.ndarray, r: float) -> np.ndarray:
    """Vector ``sig(x, r) = ||x||^r x / ||x||`` row-wise, 0 at x = 0.

    Args:
        x: ``(N, 3)`` vectors (any unit).
        r: Exponent (dimensionless); r = 1 returns x, r = 1/2 uses 1/sqrt.

    Returns:
        ``(N, 3)`` with norm ``||x||^r``.
    """
    n = np.sqrt(np.sum(x * x, axis=1))
    pos = n > 0.0
    safe = np.where(pos, n, 1.0)
    if r == 1.0:
        scale = np.ones_like(n)
    elif r == 0.5:
        scale = 1.0 / np.sqrt(safe)
    else:
        scale = np.power(safe, r - 1.0)
    return x * np.where(pos, scale, 0.0)[:, None]


def unit(x: np.ndarray, eps: float = 0.0) -> np.ndarray:
    """Row-wise ``x / max(||x||, eps)``, 0 where ``x = 0`` (``(N, 3)``).

    Args:
        x: ``(N, 3)`` vectors (any unit).
        eps: Boundary layer (unit of x): below it the result is ``x / eps``, linear
            instead of a unit vector. 0 gives the pure direction.
    """
    n = np.sqrt(np.sum(x * x, axis=1))
    pos = n > 0.0
    return x * np.where(pos, 1.0 / np.maximum(np.where(pos, n, 1.0), eps), 0.0)[:, None]


def ismc_nominal(
    e: np.ndarray, e_dot: np.ndarray, f: np.ndarray, *, k_a: float, k_b: float,
    r_a: float, r_b: float,
) -> np.ndarray:
    """Nominal finite-time control ``u_n = -k_a sig(e, r_a) - k_b sig(ė, r_b) - f`` (eq. 28)."""
    out: np.ndarray = -k_a * sig(e, r_a) - k_b * sig(e_dot, r_b) - f
    return out


def limit_thrust_accel(u: np.ndarray, *, min_z: float, tan_tilt: float) -> tuple[np.ndarray, np.ndarray]:
    """Clamp ``u`` ``(N, 3)``: ``u_z >= min_z`` and ``||u_xy|| <= u_z tan(max tilt)``.

    Returns:
        ``(limited u (N, 3), limited (N,) bool)``; rows within the limits are returned unchanged.
    """
    uz = np.maximum(u[:, 2], min_z)
    h = np.sqrt(u[:, 0] * u[:, 0] + u[:, 1] * u[:, 1])
    hmax = uz * tan_tilt
    tilt = h > hmax
    scale = np.where(tilt, hmax / np.where(tilt, h, 1.0), 1.0)
    out = np.stack([np.where(tilt, u[:, 0] * scale, u[:, 0]), np.where(tilt, u[:, 1] * scale, u[:, 1]), uz], axis=1)
    return out, (u[:, 2] < min_z) | tilt


def ismc_switching(
    s: np.ndarray, s_prev: np.ndarray, *, gain: float, eps: float = SWITCH_EPS, eps_diff: float = SWITCH_EPS,
) -> np.ndarray:
    """Switching law ``ω̃ = -gain (s/||s|| + 0.5 ṡ/||ṡ||)`` (eq. 35), ṡ ∝ ``s - s_prev``.

    The directions use the boundary layers ``eps`` (on s) and ``eps_diff`` (on
    ``s - s_prev``): ``SWITCH_EPS`` for the paper's law, :meth:`IsmcGains.switch_eps`
    for the continuous one (see the module docstring).
    """
    return -gain * (unit(s, eps) + 0.5 * unit(s - s_prev, eps_diff))
