"""The readable reference engine (plain numpy, arrays over drones) and the run driver.

One control step at ``t_k = k dt`` (dt = 1 ms, the paper's), for every drone at once:

1. reference ``p_r, v_r, a_r`` and yaw ψ_r at ``t_k``;
2. position ISMC -> desired thrust acceleration ``u``; thrust ``τ_f = m u·(R e_z)``;
3. attitude resolution (eq. 51) -> raw Θ_ref -> command filter -> ``(Θ_c, Θ̇_c, Θ̈_c)``;
4. attitude ISMC -> ``u_a``; torque ``τ = I W⁻¹ u_a``;
5. mixer -> ω² -> saturation (anti-windup flag) -> the thrust and torque that act;
6. integrators advance; the plant advances one step with the inputs held.

Integrator: **semi-implicit (symplectic) Euler** at the control step
(``v += dt v̇; p += dt v``; ``Ω += dt Ω̇; Θ += dt W(Θ_k) Ω``), chosen because it needs
one model evaluation per step, which is what makes the fused kernel fast. The
switching terms never meet an adaptive solver: the inputs are held over the step.
Classical RK4 with the inputs held (disturbances at the stage times) is available
here as ``integrator="rk4"`` to measure the discretisation error; on the paper
scenario both meet the spec's thresholds (``run_paper_scenario(engine="numpy",
integrator="rk4")``).

Divergence: before a step, a drone whose position error exceeds ``divergence_limit_m``
is frozen; a step that would make any state or input non-finite is not committed and
the drone is frozen. Frozen drones keep their last finite state and are reported with
the time and the reason; the others fly on.

The controller state of each drone is a flat row of ``CTRL_SIZE`` floats (layout
below) so the numpy and numba engines share it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from sim.flight._disturbance import Disturbance, make_disturbance
from sim.flight._quadrotor import (
    STATE_SIZE,
    QuadrotorParams,
    euler_rate_matrix,
    euler_rate_matrix_inverse,
    mix,
    quadrotor_derivative,
    saturate,
    thrust_axis,
    unmix,
    w_dot_omega,
)
from sim.flight.control._attitude import resolve_attitude
from sim.flight.control._baseline import BaselineGains
from sim.flight.control._ismc import IsmcGains, ismc_nominal, ismc_switching
from sim.plan._trajectory import DEGREE, Trajectories

__all__ = [
    "CTRL_SIZE",
    "DIVERGED_NONFINITE",
    "DIVERGED_RUNAWAY",
    "TELEMETRY_FIELDS",
    "RefChunk",
    "SimResult",
    "TrackingReference",
    "hover_state",
    "init_controller",
    "numpy_step",
    "simulate",
]

# Controller state row layout (per drone).
C_E2_0, C_IPOS, C_UD, C_SPREV = 0, 3, 6, 9  # position ISMC: ė(0), ∫(u_n+f), u_d, s_{k-1}
C_E4_0, C_IATT, C_UDA, C_SAPREV = 12, 15, 18, 21  # attitude ISMC, same order
C_THC, C_THC_DOT = 24, 27  # command filter state Θ_c, Θ̇_c
C_LAST_THRUST = 30  # τ_f of the previous step (N), for the continuity metric
CTRL_SIZE = 31

# Per-drone statistics: Σ||e1||² (m²), max ||e1|| (m), max |Δτ_f| (N), steps counted.
STAT_SUMSQ, STAT_MAX, STAT_DTHRUST, STAT_COUNT = 0, 1, 2, 3
STATS_SIZE = 4

DIVERGED_RUNAWAY = 1
DIVERGED_NONFINITE = 2
DIVERGED_REASONS = {DIVERGED_RUNAWAY: "runaway", DIVERGED_NONFINITE: "non-finite"}

# Telemetry row recorded at output frames (when requested).
TELEMETRY_FIELDS = (
    "e1_x", "e1_y", "e1_z",  # position error p - p_ref (m)
    "e3_phi", "e3_theta", "e3_psi",  # Θ - Θ_c, error to the tracked (filtered) reference (rad)
    "er_phi", "er_theta", "er_psi",  # Θ - Θ_ref, error to the unfiltered eq. 51 reference (rad)
    "thrust", "tau_x", "tau_y", "tau_z",  # inputs acting on the body (N, N·m)
    "saturated",  # 1 when a rotor was clipped
)
TEL_SIZE = len(TELEMETRY_FIELDS)


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
    extra: dict = field(default_factory=dict)

    def diverged(self) -> list[tuple[int, float, str]]:
        """``[(drone, time_s, reason)]`` for every frozen drone, by drone index."""
        idx = np.flatnonzero(self.diverged_step >= 0)
        return [
            (int(i), float(self.diverged_step[i] * self.dt_s),
             DIVERGED_REASONS.get(int(self.diverged_reason[i]), "unknown"))
            for i in idx
        ]


# ----------------------------------------------------------------------------------------
# Controller initialisation (shared by both engines)
# ----------------------------------------------------------------------------------------
def init_controller(
    state: np.ndarray, ref: TrackingReference, chunk0: RefChunk, *, params: QuadrotorParams,
    gains: IsmcGains,
) -> np.ndarray:
    """Controller rows at t = 0: s(0) = 0, u_d = 0, the filter at Θ_ref(0) and at rest."""
    p, v, euler, omega = state[:, 0:3], state[:, 3:6], state[:, 6:9], state[:, 9:12]
    n = state.shape[0]
    g = params.gravity_mps2
    pr, vr, ar = ref.at_step(chunk0, 0)
    pg = gains.position
    e1, e2 = p - pr, v - vr
    f = -ar
    f[:, 2] -= g
    u = ismc_nominal(e1, e2, f, k_a=pg.k1, k_b=pg.k2, r_a=pg.r1, r_b=pg.r2)
    theta_ref = resolve_attitude(u, np.full(n, chunk0.yaw[0, 0]))
    ctrl = np.zeros((n, CTRL_SIZE))
    ctrl[:, C_E2_0:C_E2_0 + 3] = e2
    ctrl[:, C_THC:C_THC + 3] = theta_ref
    ctrl[:, C_E4_0:C_E4_0 + 3] = np.einsum("nij,nj->ni", euler_rate_matrix(euler), omega)
    ctrl[:, C_LAST_THRUST] = params.mass_kg * np.sum(u * thrust_axis(euler), axis=1)
    return ctrl


# ----------------------------------------------------------------------------------------
# The reference step
# ----------------------------------------------------------------------------------------
def numpy_step(
    state: np.ndarray, ctrl: np.ndarray, *, pr: np.ndarray, vr: np.ndarray, ar: np.ndarray,
    yaw: np.ndarray, dist: np.ndarray, t_s: float, disturbance: Disturbance,
    params: QuadrotorParams, plant: QuadrotorParams, gains: IsmcGains, dt_s: float,
    integrator: str = "euler",
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One control + integration step for every drone given.

    Args:
        state: ``(N, 12)`` plant state at ``t_s``.
        ctrl: ``(N, CTRL_SIZE)`` controller state at ``t_s``.
        pr, vr, ar: ``(N, 3)`` reference position (m), velocity (m/s), acceleration (m/s²).
        yaw: ``(3,)`` ψ_ref (rad), sin ψ_ref, cos ψ_ref.
        dist: ``(9,)`` disturbance signals at ``t_s``: accel (m/s²), wind (m/s), Δ2 (rad/s²).
        t_s: Time of the step (s), for the RK4 stage disturbances.
        disturbance: The disturbance (drag coefficient, RK4 stages).
        params: What the controller believes (mass, inertia, rotors).
        plant: The true vehicle (differs under model mismatch).
        gains: Controller gains.
        dt_s: Step (s).
        integrator: ``"euler"`` (semi-implicit, the engines' default) or ``"rk4"``.

    Returns:
        ``(new_state, new_ctrl, telemetry (N, TEL_SIZE))``; telemetry is at ``t_s``.
    """
    g = params.gravity_mps2
    m = params.mass_kg
    inertia = np.asarray(params.inertia_kgm2)
    pg, ag, fl = gains.position, gains.attitude, gains.filter
    p, v, euler, omega = state[:, 0:3], state[:, 3:6], state[:, 6:9], state[:, 9:12]
    c = ctrl

    # --- position loop (spec 4)
    e1, e2 = p - pr, v - vr
    f = -ar.copy()
    f[:, 2] -= g
    u_n = ismc_nominal(e1, e2, f, k_a=pg.k1, k_b=pg.k2, r_a=pg.r1, r_b=pg.r2)
    s = e2 - c[:, C_E2_0:C_E2_0 + 3] - c[:, C_IPOS:C_IPOS + 3]
    w_pos = ismc_switching(s, c[:, C_SPREV:C_SPREV + 3], gain=pg.alpha)
    u = u_n + c[:, C_UD:C_UD + 3]
    z_b = thrust_axis(euler)
    thrust_cmd = m * np.sum(u * z_b, axis=1)  # eq. 22: projection on the current body axis

    # --- attitude reference (spec 5) and command filter
    theta_ref = resolve_attitude(u, np.full(p.shape[0], yaw[0]))
    th_c, th_c_dot = c[:, C_THC:C_THC + 3], c[:, C_THC_DOT:C_THC_DOT + 3]
    th_c_ddot = fl.acceleration(theta_ref, th_c, th_c_dot)

    # --- attitude loop (spec 6)
    w_mat = euler_rate_matrix(euler)
    euler_dot = np.einsum("nij,nj->ni", w_mat, omega)
    e3, e4 = euler - th_c, euler_dot - th_c_dot
    gyro_acc = np.cross(omega, omega * inertia) / inertia
    f_a = -np.einsum("nij,nj->ni", w_mat, gyro_acc) + w_dot_omega(euler, omega) - th_c_ddot
    u_na = ismc_nominal(e3, e4, f_a, k_a=ag.k3, k_b=ag.k4, r_a=ag.r3, r_b=ag.r4)
    s_a = e4 - c[:, C_E4_0:C_E4_0 + 3] - c[:, C_IATT:C_IATT + 3]
    w_att = ismc_switching(s_a, c[:, C_SAPREV:C_SAPREV + 3], gain=ag.beta)
    u_a = u_na + c[:, C_UDA:C_UDA + 3]
    torque_cmd = inertia * np.einsum("nij,nj->ni", euler_rate_matrix_inverse(euler), u_a)

    # --- rotors: mix, saturate, and what actually acts (the controller's k_F, k_M, d
    # equal the plant's: mismatch is in mass and inertia only)
    omega_sq, saturated = saturate(mix(thrust_cmd, torque_cmd, plant), plant)
    thrust, torque = unmix(omega_sq, plant)

    # --- controller state update
    nc = c.copy()
    nc[:, C_IPOS:C_IPOS + 3] += dt_s * (u_n + f)
    nc[:, C_UD:C_UD + 3] += np.where(saturated[:, None], 0.0, dt_s * w_pos)
    nc[:, C_SPREV:C_SPREV + 3] = s
    nc[:, C_IATT:C_IATT + 3] += dt_s * (u_na + f_a)
    nc[:, C_UDA:C_UDA + 3] += np.where(saturated[:, None], 0.0, dt_s * w_att)
    nc[:, C_SAPREV:C_SAPREV + 3] = s_a
    nc[:, C_THC_DOT:C_THC_DOT + 3] = th_c_dot + dt_s * th_c_ddot
    nc[:, C_THC:C_THC + 3] = th_c + dt_s * nc[:, C_THC_DOT:C_THC_DOT + 3]
    nc[:, C_LAST_THRUST] = thrust

    # --- plant
    if integrator == "euler":
        acc = (thrust / plant.mass_kg)[:, None] * z_b + dist[0:3] + disturbance.drag_per_s * (
            dist[3:6] - v
        )
        acc[:, 2] -= plant.gravity_mps2
        pin = np.asarray(plant.inertia_kgm2)
        omega_dot = (torque - np.cross(omega, omega * pin)) / pin + np.einsum(
            "nij,nj->ni", euler_rate_matrix_inverse(euler), np.broadcast_to(dist[6:9], p.shape)
        )
        ns = np.empty_like(state)
        ns[:, 3:6] = v + dt_s * acc
        ns[:, 0:3] = p + dt_s * ns[:, 3:6]
        ns[:, 9:12] = omega + dt_s * omega_dot
        ns[:, 6:9] = euler + dt_s * np.einsum("nij,nj->ni", w_mat, ns[:, 9:12])
    elif integrator == "rk4":
        def deriv(x: np.ndarray, t: float) -> np.ndarray:
            sig = disturbance.signals(np.array([t]))[0]
            d1 = sig[0:3] + disturbance.drag_per_s * (sig[3:6] - x[:, 3:6])
            d2 = np.broadcast_to(sig[6:9], (x.shape[0], 3))
            return quadrotor_derivative(x, thrust, torque, d1, d2, plant)

        k1 = deriv(state, t_s)
        k2 = deriv(state + 0.5 * dt_s * k1, t_s + 0.5 * dt_s)
        k3 = deriv(state + 0.5 * dt_s * k2, t_s + 0.5 * dt_s)
        k4 = deriv(state + dt_s * k3, t_s + dt_s)
        ns = state + dt_s / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    else:
        raise ValueError(f"unknown integrator {integrator!r}")

    tel = np.concatenate(
        [e1, e3, euler - theta_ref, thrust[:, None], torque, saturated[:, None].astype(float)],
        axis=1,
    )
    return ns, nc, tel


def _run_chunk_numpy(
    state: np.ndarray, ctrl: np.ndarray, stats: np.ndarray, dstep: np.ndarray,
    dreason: np.ndarray, *, ref: TrackingReference, chunk: RefChunk, dist: np.ndarray,
    step0: int, times: np.ndarray, every: int, frames: np.ndarray, tel: np.ndarray | None,
    opts: dict,
) -> None:
    """Advance ``len(times)`` steps in place (the numpy engine's chunk)."""
    limit = opts["divergence_limit_m"]
    for j in range(times.size):
        k = step0 + j
        alive = dstep < 0
        pr, vr, ar = ref.at_step(chunk, j)
        with np.errstate(all="ignore"):
            err = np.sqrt(np.sum((state[:, 0:3] - pr) ** 2, axis=1))
        runaway = alive & ~(err <= limit)  # NaN (a non-finite reference) or a runaway drone
        dstep[runaway] = k
        dreason[runaway] = np.where(err[runaway] > limit, DIVERGED_RUNAWAY, DIVERGED_NONFINITE)
        alive &= ~runaway
        with np.errstate(all="ignore"):  # a diverging row may overflow; it is caught below
            ns, nc, trow = numpy_step(
                state, ctrl, pr=pr, vr=vr, ar=ar, yaw=chunk.yaw[j], dist=dist[j], t_s=times[j],
                disturbance=opts["disturbance"], params=opts["params"], plant=opts["plant"],
                gains=opts["gains"], dt_s=opts["dt_s"], integrator=opts["integrator"],
            )
        bad = alive & ~(np.all(np.isfinite(ns), axis=1) & np.all(np.isfinite(nc), axis=1))
        dstep[bad] = k
        dreason[bad] = DIVERGED_NONFINITE
        alive &= ~bad
        if k % every == 0:
            frames[k // every] = state[:, 0:3]
            if tel is not None:
                tel[k // every] = trow
        thrust = nc[:, C_LAST_THRUST]
        stats[alive, STAT_SUMSQ] += err[alive] ** 2
        stats[alive, STAT_MAX] = np.maximum(stats[alive, STAT_MAX], err[alive])
        stats[alive, STAT_DTHRUST] = np.maximum(
            stats[alive, STAT_DTHRUST], np.abs(thrust[alive] - ctrl[alive, C_LAST_THRUST])
        )
        stats[alive, STAT_COUNT] += 1.0
        state[alive] = ns[alive]
        ctrl[alive] = nc[alive]


# ----------------------------------------------------------------------------------------
# Driver
# ----------------------------------------------------------------------------------------
def simulate(
    reference: TrackingReference,
    *,
    duration_s: float,
    initial_state: np.ndarray | None = None,
    params: QuadrotorParams | None = None,
    mismatch: float = 0.0,
    gains: IsmcGains | BaselineGains | None = None,
    disturbance: str | Disturbance | None = None,
    seed: int = 0,
    dt_s: float = 1e-3,
    output_every: int = 40,
    telemetry: bool = False,
    engine: str = "numba",
    integrator: str = "euler",
    divergence_limit_m: float = 100.0,
    chunk_steps: int = 1000,
    progress: Callable[[float], None] | None = None,
    frames_out: np.ndarray | None = None,
    on_chunk: Callable[[int, np.ndarray], None] | None = None,
) -> SimResult:
    """Fly every drone of ``reference`` for ``duration_s`` at a fixed step.

    Args:
        reference: What each drone tracks (per-drone pieces + offset + yaw).
        duration_s: Flight length (s); ``round(duration/dt) + 1`` control steps are
            taken so that the state at ``duration_s`` is recorded.
        initial_state: ``(N, 12)`` start state; default at rest, level, on the
            reference at t = 0.
        params: The vehicle the controller is tuned for (default: the paper's).
        mismatch: Plant mass and inertia off by this fraction (dimensionless).
        gains: ISMC gains (default the paper's) or ``BaselineGains`` for the PD baseline.
        disturbance: ``"none" | "paper" | "wind"`` or a ``Disturbance``.
        seed: Seed of the wind gusts.
        dt_s: Control and integration step (s), default 1 ms (the paper's).
        output_every: Record positions (and telemetry) every this many steps.
        telemetry: Also record ``TELEMETRY_FIELDS`` at the frames.
        engine: ``"numba"`` (fused kernel) or ``"numpy"`` (reference).
        integrator: ``"euler"`` (semi-implicit; both engines) or ``"rk4"`` (numpy only).
        divergence_limit_m: Position error beyond which a drone is frozen (m).
        chunk_steps: Steps per kernel call (progress granularity).
        progress: Called with the completed fraction in [0, 1] after every chunk; an
            exception it raises stops the run and propagates (used to cancel).
        frames_out: Optional preallocated ``(F, N, 3)`` frame buffer (float32 or
            float64), F = ``(steps - 1) // output_every + 1``; saves a float64 copy.
        on_chunk: Called after every chunk with ``(steps_done, diverged_step)``:
            frames with index ``< ceil(steps_done / output_every)`` are final.

    Returns:
        A ``SimResult``.
    """
    params = params or QuadrotorParams()
    plant = params.mismatched(fraction=mismatch) if mismatch else params
    if gains is None:
        gains = IsmcGains()
    if isinstance(gains, BaselineGains):
        gains = gains.as_ismc()
    dist = make_disturbance(disturbance, seed=seed)
    n = reference.drone_count
    steps = int(round(duration_s / dt_s)) + 1
    every = max(int(output_every), 1)
    n_frames = (steps - 1) // every + 1

    chunk0 = reference.chunk(np.zeros(1))
    if initial_state is None:
        initial_state = hover_state(reference.at_step(chunk0, 0)[0])
    state = np.array(initial_state, dtype=np.float64, copy=True)
    if state.shape != (n, STATE_SIZE):
        raise ValueError(f"initial_state must be ({n}, {STATE_SIZE}), got {state.shape}")
    ctrl = init_controller(state, reference, chunk0, params=params, gains=gains)
    stats = np.zeros((n, STATS_SIZE))
    dstep = np.full(n, -1, dtype=np.int64)
    dreason = np.zeros(n, dtype=np.int64)
    if frames_out is None:
        frames = np.zeros((n_frames, n, 3))
    else:
        frames = frames_out
        if frames.shape != (n_frames, n, 3):
            raise ValueError(f"frames_out must be {(n_frames, n, 3)}, got {frames.shape}")
    tel = np.full((n_frames, n, TEL_SIZE), np.nan) if telemetry else None

    if engine == "numba":
        if integrator != "euler":
            raise ValueError("the numba engine integrates with semi-implicit Euler only")
        from sim.flight.engines._numba import run_chunk_numba as runner
    elif engine == "numpy":
        runner = _run_chunk_numpy
    else:
        raise ValueError(f"unknown engine {engine!r} (expected numba or numpy)")

    opts = {
        "params": params, "plant": plant, "gains": gains, "disturbance": dist, "dt_s": dt_s,
        "integrator": integrator, "divergence_limit_m": float(divergence_limit_m),
    }
    step = 0
    while step < steps:
        count = min(int(chunk_steps), steps - step)
        times = (step + np.arange(count)) * dt_s
        runner(
            state, ctrl, stats, dstep, dreason, ref=reference, chunk=reference.chunk(times),
            dist=np.ascontiguousarray(dist.signals(times)), step0=step, times=times,
            every=every, frames=frames, tel=tel, opts=opts,
        )
        step += count
        if on_chunk is not None:
            on_chunk(step, dstep)
        if progress is not None:
            progress(step / steps)

    count = np.maximum(stats[:, STAT_COUNT], 1.0)
    return SimResult(
        frame_times_s=np.arange(n_frames) * every * dt_s,
        positions_m=frames,
        telemetry=tel,
        rms_error_m=np.sqrt(stats[:, STAT_SUMSQ] / count),
        max_error_m=stats[:, STAT_MAX].copy(),
        max_thrust_step_n=stats[:, STAT_DTHRUST].copy(),
        diverged_step=dstep,
        diverged_reason=dreason,
        final_state=state,
        dt_s=dt_s,
        engine=engine,
    )

