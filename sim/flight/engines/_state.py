"""What both engines share: the controller-state layout, the reference type, the result.

The controller state of each drone is a flat row of ``CTRL_SIZE`` floats (layout
below) so the numpy engine (:mod:`sim.flight.engines._numpy`) and the fused numba
kernel (:mod:`sim.flight.engines._numba`) share it; both import this module and
neither imports the other (the driver, :mod:`sim.flight.engines._driver`, picks one).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.flight._quadrotor import STATE_SIZE
from sim.plan._trajectory import DEGREE, Trajectories

__all__ = [
    "CTRL_SIZE",
    "D_SIZE",
    "DIVERGED_GROUND",
    "DIVERGED_NONFINITE",
    "DIVERGED_OVERPOWERED",
    "DIVERGED_REASONS",
    "ErrorSwitches",
    "DIVERGED_RUNAWAY",
    "GROUND_STRIKE_M",
    "STATS_SIZE",
    "TELEMETRY_FIELDS",
    "TEL_SIZE",
    "RefChunk",
    "SimResult",
    "TrackingReference",
    "hover_state",
]

# Controller state row layout (per drone).
C_E2_0, C_IPOS, C_UD, C_SPREV = 0, 3, 6, 9  # position ISMC: ė(0), ∫(u_n+f), u_d, s_{k-1}
C_E4_0, C_IATT, C_UDA, C_SAPREV = 12, 15, 18, 21  # attitude ISMC, same order
C_THC, C_THC_DOT = 24, 27  # command filter state Θ_c, Θ̇_c
C_LAST_THRUST = 30  # τ_f of the previous step (N), for the continuity metric
C_IERR = 31  # ∫e1 dt of the PID baseline (m·s)
C_PHAT, C_VHAT = 34, 37  # estimator: p̂ (m), v̂ (m/s) (the true p, v when GNSS is off)
C_INNOV = 40  # GNSS innovation z - p̂ held since the last epoch (m)
C_ROTOR = 43  # squared rotor speeds acting (rad²/s²), the motor-lag state (4)
# GNSS innovation gate: consecutive rejected epochs (0 while the fixes pass the gate).
C_GATE = 47
# Decaying average (time constant LIMITED_TAU_S) of "the command is at its authority limit,
# points back toward the reference and the attitude follows it": near 1 when a drone is
# blown off (it does all it can), not when it falls over or its control is unstable.
C_LIMITED = 48
# What the last estimator resets moved p̂ by, not yet passed on to the controller (m): it
# sees p̂ - this, which returns to p̂ at <= reset_mps per axis (3).
C_RESET = 49
# The outer (position) loop's outputs, held between its runs (IsmcGains.position_rate_hz): the
# limited command u (m/s², 3), Θ_ref's roll and pitch (rad, 2) and those of the run before (2;
# the command filter's input ramps from those to these over the K steps), ||u||, and the flags
# "limited" and "pushing back" (1.0 / 0.0) that the anti-windup and C_LIMITED read in between.
C_UHOLD = 52
C_RHOLD = 55
C_RPREV = 57
C_UNORM = 59
C_LIMHOLD = 60
C_PUSHHOLD = 61
CTRL_SIZE = 62

#: Time constant (s) of the C_LIMITED average: "most of the last second".
LIMITED_TAU_S = 1.0
#: C_LIMITED above this when the error passes the divergence limit: "overpowered".
LIMITED_FRACTION = 0.5
#: The body's thrust axis within acos(this) = 0.2 rad of the command u counts as "following":
#: a drone that tumbles has its command at the limit too, but its attitude does not follow it.
LIMITED_ALIGN_COS = math.cos(0.2)

# Per-drone constants of the error models (rows of ``drone``, built by engines._tables).
D_MASS, D_IX, D_IY, D_IZ = 0, 1, 2, 3  # the true plant's mass (kg) and inertia (kg·m²)
D_THRUST = 4  # rotor thrust-gain factor at t = 0 (dimensionless)
D_SAG_RATE = 5  # thrust-gain loss per second of flight (1/s), until ErrorSwitches.battery_end_s
D_CLOCK = 6  # show-clock offset δ (s): the drone flies the reference at t + δ
D_MOTOR = 7  # motor-lag blend 1 - exp(-dt/τ) per step (1: no lag)
D_DRAG = 8  # quadratic drag over mass c / m (1/m)
D_SIZE = 9

# Per-drone statistics: Σ||e1||² (m²), max ||e1|| (m), max |Δτ_f| (N), steps counted.
STAT_SUMSQ, STAT_MAX, STAT_DTHRUST, STAT_COUNT = 0, 1, 2, 3
STATS_SIZE = 4

# Why a drone was stopped (issue 20):
# * "runaway": its error passed the divergence limit while its control was not held at its
#   authority limit pushing back (unstable control, a tumble);
# * "overpowered": its error passed the limit while, for most of the last second
#   (C_LIMITED > LIMITED_FRACTION), its command had sat at the tilt/thrust limit (or a rotor
#   clipped) pointing back toward the reference with the attitude following it (thrust axis
#   within 0.2 rad of the command): it lacked the authority, e.g. wind beyond its airspeed
#   limit;
# * "non-finite": a state or input became NaN or inf (or the reference did);
# * "ground": its true position sank more than GROUND_STRIKE_M below the ground of the show it
#   flies (a crash: the model has no ground contact). Only a flown show has a ground
#   (``simulate(ground_m=...)``, set by ``sim.flight._runner.fly_local``); the free-space
#   references of the tests and the paper scenario (p_ref z = sin t dips to -1 m) have none.
#   Checked before the error limit: a drone that falls is "ground" even if it also fell far.
DIVERGED_RUNAWAY = 1
DIVERGED_NONFINITE = 2
DIVERGED_OVERPOWERED = 3
DIVERGED_GROUND = 4
DIVERGED_REASONS = {DIVERGED_RUNAWAY: "runaway", DIVERGED_NONFINITE: "non-finite",
                    DIVERGED_OVERPOWERED: "overpowered", DIVERGED_GROUND: "ground"}
#: Depth below the show's ground (its lowest home, at most z = 0) at which a flown drone has crashed
#: into it (m): a landing sinks a few centimetres under its home while the controller settles.
GROUND_STRIKE_M = 0.5

# Telemetry row recorded at output frames (when requested).
TELEMETRY_FIELDS = (
    "e1_x", "e1_y", "e1_z",  # position error p - p_ref (m)
    "e3_phi", "e3_theta", "e3_psi",  # Θ - Θ_c, error to the tracked (filtered) reference (rad)
    "er_phi", "er_theta", "er_psi",  # Θ - Θ_ref, error to the unfiltered eq. 51 reference (rad)
    "thrust", "tau_x", "tau_y", "tau_z",  # inputs acting on the body (N, N·m)
    "saturated",  # 1 when the command was limited or the allocation could not deliver it
)
TEL_SIZE = len(TELEMETRY_FIELDS)


@dataclass(frozen=True)
class ErrorSwitches:
    """Which parts of the error models an engine runs (all off: the ideal, exact path).

    Attributes:
        gnss: The controller sees the GNSS/accelerometer estimate (p̂, v̂).
        motor: First-order motor lag.
        drag: Quadratic drag against the wind tables.
        clock: Per-drone clock offsets.
        est_kp: Estimator position gain on the held innovation (1/s).
        est_kv: Estimator velocity gain on the held innovation (1/s²).
        gate_h_m: Innovation gate per horizontal axis (m): k σ; inf = no gate.
        gate_v_m: Innovation gate vertically (m).
        gate_epochs: Consecutive rejected epochs after which p̂ is reset to the fix.
        reset_mps: Speed (m/s, per axis) at which a reset is passed on to what the controller sees.
        battery_end_s: The pack's endurance (s): the battery sag (``D_SAG_RATE`` t) grows until
            then and is held after it (``sim.flight._errors``).
    """

    gnss: bool = False
    motor: bool = False
    drag: bool = False
    clock: bool = False
    est_kp: float = 0.0
    est_kv: float = 0.0
    gate_h_m: float = math.inf
    gate_v_m: float = math.inf
    gate_epochs: float = 0.0
    reset_mps: float = math.inf
    battery_end_s: float = math.inf

    @property
    def ideal(self) -> bool:
        """True when no switch is on."""
        return not (self.gnss or self.motor or self.drag or self.clock)


def _constant_motion(points_m: np.ndarray, duration_s: float) -> Trajectories:
    """Every drone at rest at ``points_m`` (N, 3) over [0, duration_s]: one constant piece each."""
    p = np.asarray(points_m, dtype=np.float64)
    coeffs = np.zeros((p.shape[0], 1, 3, DEGREE + 1))
    coeffs[:, 0, :, 0] = p
    breaks = np.zeros((p.shape[0], 2))
    breaks[:, 1] = max(float(duration_s), 0.0)
    return Trajectories(breaks, coeffs)


@dataclass(frozen=True)
class RefChunk:
    """The parts of the reference shared by every drone, at a run of steps.

    Each drone's own motion is not tabulated here: the engines evaluate its
    polynomial pieces (:class:`~sim.plan.Trajectories`) at ``times`` themselves.

    Attributes:
        times: ``(T,)`` step times (s).
        offset: ``(T, 9)`` common offset p (m), v (m/s), a (m/s²).
        yaw: ``(T, 3)`` ψ_ref (rad), sin ψ_ref, cos ψ_ref.
    """

    times: np.ndarray
    offset: np.ndarray
    yaw: np.ndarray


@dataclass(frozen=True)
class TrackingReference:
    """Per-drone reference trajectories: each drone's own polynomial pieces (+ a shared offset).

    ``p_ref[i](t) = motion_i(t) + offset_p(t)``, likewise v and a with the piece
    derivatives; outside ``[motion.start_s, motion.end_s]`` a drone rests at its
    first / last position (velocity and acceleration zero), as
    :meth:`~sim.plan.Trajectories.evaluate` defines.

    Attributes:
        motion: Per-drone piecewise polynomials (``breaks_s`` (N, P+1), ``coeffs_m`` (N, P, 3, 6)).
        offset: Optional ``times (T,) -> (T, 9)`` common offset p, v, a.
        yaw: Optional ``times (T,) -> (T,)`` yaw reference (rad); default 0.
        duration_s: Nominal length (s).
    """

    motion: Trajectories
    offset: Callable[[np.ndarray], np.ndarray] | None = None
    yaw: Callable[[np.ndarray], np.ndarray] | None = None
    duration_s: float = 0.0

    @property
    def drone_count(self) -> int:
        """Number of drones N."""
        return self.motion.drone_count

    def subset(self, drones: slice | np.ndarray) -> TrackingReference:
        """The same reference for a subset of drones (index array or slice)."""
        return TrackingReference(
            motion=self.motion.select(drones), offset=self.offset, yaw=self.yaw, duration_s=self.duration_s,
        )

    def chunk(self, times_s: np.ndarray) -> RefChunk:
        """Evaluate the shared parts at ``(T,)`` times (s)."""
        t = np.ascontiguousarray(times_s, dtype=np.float64)
        off = np.zeros((t.size, 9)) if self.offset is None else np.asarray(self.offset(t))
        psi = np.zeros(t.size) if self.yaw is None else np.asarray(self.yaw(t), dtype=np.float64)
        return RefChunk(
            times=t,
            offset=np.ascontiguousarray(off, dtype=np.float64),
            yaw=np.ascontiguousarray(np.stack([psi, np.sin(psi), np.cos(psi)], axis=1)),
        )

    def at_step(self, chunk: RefChunk, j: int) -> tuple[np.ndarray, ...]:
        """``(p_r, v_r, a_r)`` ``(N, 3)`` of every drone at row ``j`` of a chunk.

        :meth:`~sim.plan.Trajectories.evaluate` at one time (each drone on its own piece,
        clamped to the show, at rest outside it), with the derivative polynomials written
        out by Horner's rule as the numba kernel writes them.
        """
        m = self.motion
        t = float(chunk.times[j])
        inside = m.start_s <= t <= m.end_s
        tc = min(max(t, m.start_s), m.end_s)
        rows = np.arange(m.drone_count)
        idx = m.piece_index(np.array([tc]))[0]
        c = m.coeffs_m[rows, idx]  # (N, 3, 6)
        u = (tc - m.breaks_s[rows, idx])[:, None]
        c0, c1, c2, c3, c4, c5 = (c[..., k] for k in range(6))
        off = chunk.offset[j]
        pos = ((((c5 * u + c4) * u + c3) * u + c2) * u + c1) * u + c0 + off[0:3]
        if not inside:
            return pos, np.broadcast_to(off[3:6], pos.shape).copy(), np.broadcast_to(off[6:9], pos.shape).copy()
        d5, d4, d3, d2 = 5.0 * c5, 4.0 * c4, 3.0 * c3, 2.0 * c2
        vel = (((d5 * u + d4) * u + d3) * u + d2) * u + c1 + off[3:6]
        acc = ((4.0 * d5 * u + 3.0 * d4) * u + 2.0 * d3) * u + d2 + off[6:9]
        return pos, vel, acc

    def at_times(self, chunk: RefChunk, j: int, clock_s: np.ndarray) -> tuple[np.ndarray, ...]:
        """Like :meth:`at_step` with each drone's own motion at ``chunk.times[j] + clock_s`` ``(N,)``.

        The shared offset and yaw stay at the chunk's time (they are the tests' and
        scenarios' shared motions; a show's reference is its drones' own pieces).
        """
        m = self.motion
        t = float(chunk.times[j]) + np.asarray(clock_s, dtype=np.float64)
        inside = (m.start_s <= t) & (t <= m.end_s)
        tc = np.minimum(np.maximum(t, m.start_s), m.end_s)
        rows = np.arange(m.drone_count)
        # The last piece starting at or before tc (the later piece at a break), as piece_index.
        idx = np.minimum(np.sum(m.breaks_s[:, 1:-1] <= tc[:, None], axis=1), m.piece_count - 1)
        c = m.coeffs_m[rows, idx]  # (N, 3, 6)
        u = (tc - m.breaks_s[rows, idx])[:, None]
        c0, c1, c2, c3, c4, c5 = (c[..., k] for k in range(6))
        off = chunk.offset[j]
        pos = ((((c5 * u + c4) * u + c3) * u + c2) * u + c1) * u + c0 + off[0:3]
        d5, d4, d3, d2 = 5.0 * c5, 4.0 * c4, 3.0 * c3, 2.0 * c2
        vel = np.where(inside[:, None], (((d5 * u + d4) * u + d3) * u + d2) * u + c1, 0.0) + off[3:6]
        acc = np.where(inside[:, None], ((4.0 * d5 * u + 3.0 * d4) * u + 2.0 * d3) * u + d2, 0.0) + off[6:9]
        return pos, vel, acc

    # -- simple references for tests and scenarios ------------------------------------
    @classmethod
    def hover(cls, points_m: np.ndarray, *, duration_s: float = 0.0) -> TrackingReference:
        """Hold each drone at ``points_m`` ``(N, 3)`` (m); a step reference from elsewhere."""
        return cls(motion=_constant_motion(points_m, duration_s), duration_s=duration_s)

    @classmethod
    def circle(
        cls, centers_m: np.ndarray, *, radius_m: float, omega_rad_s: float,
        duration_s: float = 0.0,
    ) -> TrackingReference:
        """Horizontal circles ``c + r [cos ωt, sin ωt, 0]`` around each centre ``(N, 3)``."""
        r, w = float(radius_m), float(omega_rad_s)

        def offset(t: np.ndarray) -> np.ndarray:
            c, s, z = np.cos(w * t), np.sin(w * t), np.zeros_like(t)
            return np.stack(
                [r * c, r * s, z, -r * w * s, r * w * c, z, -r * w * w * c, -r * w * w * s, z],
                axis=1,
            )

        return cls(motion=_constant_motion(centers_m, duration_s), offset=offset, duration_s=duration_s)

    @classmethod
    def paper(cls, *, drones: int = 1) -> TrackingReference:
        """Spec section 7: ``p_ref = [sin t, cos t, sin t]``, ψ_ref = 0."""

        def offset(t: np.ndarray) -> np.ndarray:
            s, c = np.sin(t), np.cos(t)
            return np.stack([s, c, s, c, -s, c, -s, -c, -s], axis=1)

        return cls(motion=_constant_motion(np.zeros((drones, 3)), 20.0), offset=offset, duration_s=20.0)


def hover_state(points_m: np.ndarray) -> np.ndarray:
    """``(N, 12)`` state at rest, level, at ``points_m`` ``(N, 3)`` (m)."""
    p = np.asarray(points_m, dtype=np.float64)
    s = np.zeros((p.shape[0], STATE_SIZE))
    s[:, 0:3] = p
    return s


@dataclass
class SimResult:
    """Output of one engine run (arrays over drones on axis 1 for frames).

    Attributes:
        frame_times_s: ``(F,)`` output times (s).
        positions_m: ``(F, N, 3)`` flown positions at the frames (m).
        telemetry: ``(F, N, TEL_SIZE)`` (see ``TELEMETRY_FIELDS``) or None.
        rms_error_m: ``(N,)`` RMS of ||p - p_ref|| over every control step (m).
        max_error_m: ``(N,)`` maximum of ||p - p_ref|| (m).
        max_thrust_step_n: ``(N,)`` largest change of τ_f between steps (N).
        diverged_step: ``(N,)`` step at which the drone was frozen, -1 if it was not.
        diverged_reason: ``(N,)`` ``DIVERGED_*`` code, 0 if it was not.
        final_state: ``(N, 12)`` state at the end.
        dt_s: Control and integration step (s).
        engine: ``"numpy"`` or ``"numba"``.
    """

    frame_times_s: np.ndarray
    positions_m: np.ndarray
    telemetry: np.ndarray | None
    rms_error_m: np.ndarray
    max_error_m: np.ndarray
    max_thrust_step_n: np.ndarray
    diverged_step: np.ndarray
    diverged_reason: np.ndarray
    final_state: np.ndarray
    dt_s: float
    engine: str
    extra: dict[str, Any] = field(default_factory=dict)

    def diverged(self) -> list[tuple[int, float, str]]:
        """``[(drone, time_s, reason)]`` for every frozen drone, by drone index."""
        idx = np.flatnonzero(self.diverged_step >= 0)
        return [
            (int(i), float(self.diverged_step[i] * self.dt_s),
             DIVERGED_REASONS.get(int(self.diverged_reason[i]), "unknown"))
            for i in idx
        ]
