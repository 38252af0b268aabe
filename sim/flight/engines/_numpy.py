"""The readable reference engine: one control step for every drone at once, in plain numpy.

One control step at ``t_k = k dt`` (dt = 1 ms, the paper's), for every drone at once:

1. reference ``p_r, v_r, a_r`` and yaw ψ_r at ``t_k``;
2. position ISMC -> desired thrust acceleration ``u``; thrust ``τ_f = m u·(R e_z)``;
3. attitude resolution (eq. 51) -> raw Θ_ref -> command filter -> ``(Θ_c, Θ̇_c, Θ̈_c)``;
4. attitude ISMC -> ``u_a``; torque ``τ = I W⁻¹ u_a``;
5. allocation (PX4's desaturation, or the paper's per-rotor clip) -> ω² (anti-windup flags:
   thrust or torque not delivered) -> the thrust and torque that act;
6. integrators advance; the plant advances one step with the inputs held.

Integrator: **semi-implicit (symplectic) Euler** at the control step
(``v += dt v̇; p += dt v``; ``Ω += dt Ω̇; Θ += dt W(Θ_k) Ω``), chosen because it needs
one model evaluation per step, which is what makes the fused kernel fast. The
switching terms never meet an adaptive solver: the inputs are held over the step.
Classical RK4 with the inputs held (disturbances at the stage times) is available
here as ``integrator="rk4"`` to measure the discretisation error; on the paper
scenario both meet the paper scenario's thresholds (docs/method.md §7) (``run_paper_scenario(engine="numpy",
integrator="rk4")``).

Divergence: before a step, a drone whose position error exceeds ``divergence_limit_m``
is frozen, and so is one whose true height is below ``ground_strike_z_m`` (a flown
show's ground less ``GROUND_STRIKE_M``; reason "ground"); a step that would make any
state or input non-finite is not committed and the drone is frozen. Frozen drones keep
their last finite state and are reported with the time and the reason; the others fly on.

The controller state of each drone is a flat row of ``CTRL_SIZE`` floats; the layout,
the reference type and the result live in :mod:`sim.flight.engines._state` so the
numpy and numba engines share them without importing each other. The run driver
(:func:`sim.flight.engines._driver.simulate`) picks the engine.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sim.flight._disturbance import Disturbance
from sim.flight._quadrotor import (
    QuadrotorParams,
    allocate,
    euler_rate_matrix,
    euler_rate_matrix_inverse,
    quadrotor_derivative,
    thrust_axis,
    unmix,
    w_dot_omega,
)
from sim.flight.control._attitude import resolve_attitude
from sim.flight.control._ismc import IsmcGains, ismc_nominal, ismc_switching, limit_thrust_accel
from sim.flight.engines._state import (
    C_E2_0,
    C_E4_0,
    C_GATE,
    C_IATT,
    C_IERR,
    C_INNOV,
    C_IPOS,
    C_LAST_THRUST,
    C_LIMHOLD,
    C_LIMITED,
    C_PHAT,
    C_PUSHHOLD,
    C_RESET,
    C_RHOLD,
    C_ROTOR,
    C_RPREV,
    C_SAPREV,
    C_SPREV,
    C_THC,
    C_THC_DOT,
    C_UD,
    C_UDA,
    C_UHOLD,
    C_UNORM,
    C_VHAT,
    CTRL_SIZE,
    D_CLOCK,
    D_DRAG,
    D_IX,
    D_IZ,
    D_MASS,
    D_MOTOR,
    D_SAG_RATE,
    D_THRUST,
    DIVERGED_GROUND,
    DIVERGED_NONFINITE,
    DIVERGED_OVERPOWERED,
    DIVERGED_RUNAWAY,
    LIMITED_ALIGN_COS,
    LIMITED_FRACTION,
    LIMITED_TAU_S,
    STAT_COUNT,
    STAT_DTHRUST,
    STAT_MAX,
    STAT_SUMSQ,
    ErrorSwitches,
    RefChunk,
    TrackingReference,
)

# The shared types, re-exported for callers that still import them from here.
from sim.flight.engines._state import STATS_SIZE as STATS_SIZE
from sim.flight.engines._state import TELEMETRY_FIELDS as TELEMETRY_FIELDS
from sim.flight.engines._state import SimResult as SimResult
from sim.flight.engines._state import hover_state as hover_state
from sim.flight.engines._tables import ChunkTables, flown_wind, ideal_drone_constants

__all__ = ["init_controller", "numpy_step", "run_chunk_numpy"]

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
    ctrl[:, C_PHAT:C_PHAT + 3] = p
    ctrl[:, C_VHAT:C_VHAT + 3] = v
    # The outer loop's held outputs (step 0 always runs it, so these are only a defined start).
    ctrl[:, C_UHOLD:C_UHOLD + 3] = u
    ctrl[:, C_RHOLD:C_RHOLD + 2] = theta_ref[:, 0:2]
    ctrl[:, C_RPREV:C_RPREV + 2] = theta_ref[:, 0:2]
    ctrl[:, C_UNORM] = np.sqrt(np.sum(u * u, axis=1))
    # The motors start at the first thrust command, level (the lag then acts on the changes).
    ctrl[:, C_ROTOR:C_ROTOR + 4] = np.clip(ctrl[:, C_LAST_THRUST] / (4.0 * params.k_f), 0.0,
                                           params.omega_max_sq)[:, None]
    return ctrl


# ----------------------------------------------------------------------------------------
# The reference step
# ----------------------------------------------------------------------------------------
def numpy_step(
    state: np.ndarray, ctrl: np.ndarray, *, pr: np.ndarray, vr: np.ndarray, ar: np.ndarray,
    yaw: np.ndarray, dist: np.ndarray, t_s: float, disturbance: Disturbance,
    params: QuadrotorParams, plant: QuadrotorParams, gains: IsmcGains, dt_s: float,
    integrator: str = "euler", drone: np.ndarray | None = None, gnss: np.ndarray | None = None,
    wind: np.ndarray | None = None, errors: ErrorSwitches | None = None, phase: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One control + integration step for every drone given.

    The outer loop (the position law, the limiter, the attitude resolution, their integrators)
    runs only at ``phase`` 0 (every ``K = gains.outer_every(dt_s)`` steps, with step ``K dt``);
    in between its outputs held in the controller state are used (zero-order hold), except the
    command filter's input Θ_ref (roll, pitch), which ramps linearly from the previous run's to
    this run's over the K steps (a step of Θ_ref every K ms through the 300 rad/s filter made
    torque spikes that saturated the rotors and flipped drones at K = 4).

    Args:
        state: ``(N, 12)`` plant state at ``t_s``.
        ctrl: ``(N, CTRL_SIZE)`` controller state at ``t_s``.
        pr, vr, ar: ``(N, 3)`` reference position (m), velocity (m/s), acceleration (m/s²)
            the controller tracks (at each drone's own clock).
        yaw: ``(3,)`` ψ_ref (rad), sin ψ_ref, cos ψ_ref.
        dist: ``(9,)`` disturbance signals at ``t_s``: accel (m/s²), wind (m/s), Δ2 (rad/s²).
        t_s: Time of the step (s), for the RK4 stage disturbances and the battery sag.
        disturbance: The disturbance (drag coefficient, RK4 stages).
        params: What the controller believes (mass, inertia, rotors).
        plant: The true vehicle (differs under model mismatch).
        gains: Controller gains.
        dt_s: Step (s).
        integrator: ``"euler"`` (semi-implicit, the engines' default) or ``"rk4"``.
        drone: ``(N, D_SIZE)`` per-drone constants of the error models (default: ideal ``plant``).
        gnss: ``(N, 3)`` GNSS measurement error (m) when this step is a GNSS epoch, else None.
        wind: ``(N, 3)`` wind at the drones' flown positions (m/s) for the quadratic drag, or None.
        errors: Which error-model parts are on (default: none).
        phase: This step's place in the outer loop's period, ``k mod K`` (0: the outer loop runs).

    Returns:
        ``(new_state, new_ctrl, telemetry (N, TEL_SIZE))``; telemetry is at ``t_s`` (its
        e1 is filled in by the caller against the plan at the true time).
    """
    sw = errors or ErrorSwitches()
    g = params.gravity_mps2
    m = params.mass_kg
    inertia = np.asarray(params.inertia_kgm2)
    pg, ag, fl = gains.position, gains.attitude, gains.filter
    eps_p, eps_pq, eps_a, eps_aq = gains.switch_eps(dt_s)
    p, v, euler, omega = state[:, 0:3], state[:, 3:6], state[:, 6:9], state[:, 9:12]
    c = ctrl
    d = drone if drone is not None else ideal_drone_constants(plant, p.shape[0])
    nc = c.copy()

    # --- what the controller sees: the estimate (GNSS + accelerometer) or the true state
    if sw.gnss:
        p_c, v_c = c[:, C_PHAT:C_PHAT + 3], c[:, C_VHAT:C_VHAT + 3]
        if gnss is not None:  # a GNSS epoch: new innovation z - p̂, held until the next
            y = (p + gnss) - p_c
            # Innovation gate (PX4 EKF2's GNSS position gate; sim.flight._errors): an epoch beyond
            # k σ on any axis is rejected (the estimate coasts on the accelerometer) and counted;
            # after gate_epochs consecutive rejections p̂ is reset to the fix (EKF2 resets its
            # position states to the measurement) and the jump goes into C_RESET, which the
            # controller's view sheds at reset_mps (PX4's position controller shifts its
            # setpoint by the EKF's reset delta, so the tracking error never steps).
            inside = (np.abs(y[:, 0]) <= sw.gate_h_m) & (np.abs(y[:, 1]) <= sw.gate_h_m) & (
                np.abs(y[:, 2]) <= sw.gate_v_m)
            count = np.where(inside, 0.0, c[:, C_GATE] + 1.0)
            reset = (count >= sw.gate_epochs)[:, None]
            nc[:, C_GATE] = np.where(reset[:, 0], 0.0, count)
            p_c = np.where(reset, p_c + y, p_c)
            nc[:, C_RESET:C_RESET + 3] = np.where(reset, c[:, C_RESET:C_RESET + 3] + y, c[:, C_RESET:C_RESET + 3])
            nc[:, C_INNOV:C_INNOV + 3] = np.where(inside[:, None], y, 0.0)
        innov = nc[:, C_INNOV:C_INNOV + 3]
        p_hat = p_c
        shed = nc[:, C_RESET:C_RESET + 3]
        p_c = p_hat - shed
        nc[:, C_RESET:C_RESET + 3] = shed - np.minimum(np.maximum(shed, -sw.reset_mps * dt_s), sw.reset_mps * dt_s)
    else:
        p_c, v_c = p, v

    # --- position loop (spec 4), every K steps; its outputs are held in between
    k_outer = gains.outer_every(dt_s)
    dt_o = k_outer * dt_s
    outer = phase == 0
    z_b = thrust_axis(euler)
    f = -ar.copy()
    f[:, 2] -= g
    th_c, th_c_dot = c[:, C_THC:C_THC + 3], c[:, C_THC_DOT:C_THC_DOT + 3]
    if outer:
        e1, e2 = p_c - pr, v_c - vr
        u_n = ismc_nominal(e1, e2, f, k_a=pg.k1, k_b=pg.k2, r_a=pg.r1, r_b=pg.r2)
        s = e2 - c[:, C_E2_0:C_E2_0 + 3] - c[:, C_IPOS:C_IPOS + 3]
        w_pos = ismc_switching(s, c[:, C_SPREV:C_SPREV + 3], gain=pg.alpha, eps=eps_p, eps_diff=eps_pq)
        u = u_n + c[:, C_UD:C_UD + 3]
        u = u - pg.ki * c[:, C_IERR:C_IERR + 3]  # PID baseline's integral (0 for the ISMC)
        u_wanted = u
        u, limited = limit_thrust_accel(u, min_z=pg.min_thrust_accel_mps2,
                                        tan_tilt=float(np.tan(pg.max_tilt_rad)))
        # While limited, s integrates the nominal law minus what the limiter took away, so that
        # u_d does not learn the limiter as a disturbance (and wind up through it).
        u_n_int = np.where(limited[:, None], u_n + (u - u_wanted), u_n)
        # --- attitude reference (spec 5)
        theta_ref = resolve_attitude(u, np.full(p.shape[0], yaw[0]))
        # "Pushing back" (see C_LIMITED below) compares u with the error the controller sees.
        push_back = np.sum(u * e1, axis=1) - g * e1[:, 2] < 0.0
        u_norm = np.sqrt(np.sum(u * u, axis=1))
        nc[:, C_UHOLD:C_UHOLD + 3] = u
        nc[:, C_RPREV:C_RPREV + 2] = c[:, C_RHOLD:C_RHOLD + 2]
        nc[:, C_RHOLD:C_RHOLD + 2] = theta_ref[:, 0:2]
        nc[:, C_UNORM] = u_norm
        nc[:, C_LIMHOLD] = limited.astype(float)
        nc[:, C_PUSHHOLD] = push_back.astype(float)
    else:  # zero-order hold of the outer loop's outputs; yaw's reference is the step's own
        e1 = np.zeros_like(p)  # (telemetry's e1 is the caller's, against the plan)
        u = c[:, C_UHOLD:C_UHOLD + 3]
        theta_ref = np.column_stack([c[:, C_RHOLD:C_RHOLD + 2], np.full(p.shape[0], yaw[0])])
        u_norm = c[:, C_UNORM]
        limited = c[:, C_LIMHOLD] > 0.5
        push_back = c[:, C_PUSHHOLD] > 0.5
    # The filter's input ramps from the previous run's Θ_ref to this run's: weight (K-1-phase)/K of
    # the step between them is still to come (0 at K = 1: exactly Θ_ref).
    wgt = (k_outer - 1 - phase) / k_outer
    theta_ref[:, 0:2] = theta_ref[:, 0:2] - wgt * (theta_ref[:, 0:2] - nc[:, C_RPREV:C_RPREV + 2])
    thrust_cmd = m * np.sum(u * z_b, axis=1)  # eq. 22: projection on the current body axis

    # --- command filter (every step)
    th_c_ddot = fl.acceleration(theta_ref, th_c, th_c_dot)

    # --- attitude loop (spec 6)
    w_mat = euler_rate_matrix(euler)
    euler_dot = np.einsum("nij,nj->ni", w_mat, omega)
    e3, e4 = euler - th_c, euler_dot - th_c_dot
    gyro_acc = np.cross(omega, omega * inertia) / inertia
    f_a = -np.einsum("nij,nj->ni", w_mat, gyro_acc) + w_dot_omega(euler, omega) - th_c_ddot
    u_na = ismc_nominal(e3, e4, f_a, k_a=ag.k3, k_b=ag.k4, r_a=ag.r3, r_b=ag.r4)
    s_a = e4 - c[:, C_E4_0:C_E4_0 + 3] - c[:, C_IATT:C_IATT + 3]
    w_att = ismc_switching(s_a, c[:, C_SAPREV:C_SAPREV + 3], gain=ag.beta, eps=eps_a, eps_diff=eps_aq)
    u_a = u_na + c[:, C_UDA:C_UDA + 3]
    torque_cmd = inertia * np.einsum("nij,nj->ni", euler_rate_matrix_inverse(euler), u_a)

    # --- rotors: allocate (within [0, ω_max²]; the anti-windup flags), the motors' lag, and
    # what acts, scaled by each drone's thrust gain and battery sag (the controller's k_F, k_M,
    # d are the nominal ones)
    omega_sq, thrust_short, torque_short = allocate(thrust_cmd, torque_cmd, plant, mixer=gains.mixer)
    # Anti-windup (docs/method.md §4.1): the position loop's u_d and PID integral freeze while
    # its command is limited or the allocation cannot deliver the thrust or the torque; the
    # attitude loop's u_d only while it cannot deliver the torque (a drone whose collective is
    # cut to keep roll and pitch gets its torque: its attitude loop keeps learning). (The
    # thrust/tilt limiter is the position loop's own: freezing the attitude u_d with it left
    # the attitude loop unable to follow its reference for as long as a strong wind held the
    # tilt at the limit; its s wound up and it ran away after; issue 20.)
    saturated = thrust_short | torque_short | limited
    # "At its authority limit, pushing back": the command is limited (or a rotor clips), its
    # part beyond hover points against the error the controller sees and the body's thrust
    # axis follows it (a tumbling drone's command sits at the limit too). A decaying average of it
    # tells a drone blown off by too much wind ("overpowered") from unstable control, whose
    # command pushes along the error ("runaway"); see engines._state.
    follows = np.sum(u * z_b, axis=1) > LIMITED_ALIGN_COS * u_norm
    held = (saturated & push_back & follows).astype(float)
    nc[:, C_LIMITED] = c[:, C_LIMITED] + (dt_s / LIMITED_TAU_S) * (held - c[:, C_LIMITED])
    if sw.motor:
        rotor = c[:, C_ROTOR:C_ROTOR + 4]
        omega_sq = rotor + d[:, D_MOTOR:D_MOTOR + 1] * (omega_sq - rotor)
    nc[:, C_ROTOR:C_ROTOR + 4] = omega_sq
    thrust, torque = unmix(omega_sq, plant)
    gain = d[:, D_THRUST] * (1.0 - d[:, D_SAG_RATE] * min(t_s, sw.battery_end_s))  # held past the endurance
    thrust = thrust * gain
    torque = torque * gain[:, None]

    # --- controller state update
    if outer:  # the outer loop's integrators, with its own step
        nc[:, C_IPOS:C_IPOS + 3] += dt_o * (u_n_int + f)
        nc[:, C_UD:C_UD + 3] += np.where(saturated[:, None], 0.0, dt_o * w_pos)
        nc[:, C_SPREV:C_SPREV + 3] = s
    nc[:, C_IATT:C_IATT + 3] += dt_s * (u_na + f_a)
    nc[:, C_UDA:C_UDA + 3] += np.where(torque_short[:, None], 0.0, dt_s * w_att)
    nc[:, C_SAPREV:C_SAPREV + 3] = s_a
    nc[:, C_THC_DOT:C_THC_DOT + 3] = th_c_dot + dt_s * th_c_ddot
    nc[:, C_THC:C_THC + 3] = th_c + dt_s * nc[:, C_THC_DOT:C_THC_DOT + 3]
    nc[:, C_LAST_THRUST] = thrust
    if outer:
        lim = pg.integral_limit
        grow = ~saturated[:, None] & (np.abs(e1) < pg.integral_zone)
        nc[:, C_IERR:C_IERR + 3] = np.where(
            grow, np.minimum(np.maximum(c[:, C_IERR:C_IERR + 3] + dt_o * e1, -lim), lim), c[:, C_IERR:C_IERR + 3],
        )

    # --- plant
    pmass = d[:, D_MASS]
    pin = d[:, D_IX:D_IZ + 1]
    if integrator == "euler":
        acc = (thrust / pmass)[:, None] * z_b + dist[0:3] + disturbance.drag_per_s * (dist[3:6] - v)
        if sw.drag:  # quadratic drag on the air-relative velocity
            rel = v - (wind if wind is not None else 0.0)
            acc = acc - d[:, D_DRAG:D_DRAG + 1] * np.sqrt(np.sum(rel * rel, axis=1))[:, None] * rel
        acc[:, 2] -= plant.gravity_mps2
        omega_dot = (torque - np.cross(omega, omega * pin)) / pin + np.einsum(
            "nij,nj->ni", euler_rate_matrix_inverse(euler), np.broadcast_to(dist[6:9], p.shape)
        )
        ns = np.empty_like(state)
        ns[:, 3:6] = v + dt_s * acc
        ns[:, 0:3] = p + dt_s * ns[:, 3:6]
        ns[:, 9:12] = omega + dt_s * omega_dot
        ns[:, 6:9] = euler + dt_s * np.einsum("nij,nj->ni", w_mat, ns[:, 9:12])
        if sw.gnss:  # the estimator: predict with the accelerometer, correct with the held innovation
            nc[:, C_VHAT:C_VHAT + 3] = v_c + dt_s * (acc + sw.est_kv * innov)
            nc[:, C_PHAT:C_PHAT + 3] = p_hat + dt_s * (nc[:, C_VHAT:C_VHAT + 3] + sw.est_kp * innov)
        else:
            nc[:, C_PHAT:C_PHAT + 3] = ns[:, 0:3]
            nc[:, C_VHAT:C_VHAT + 3] = ns[:, 3:6]
    elif integrator == "rk4":
        if not sw.ideal:
            raise ValueError("the rk4 integrator flies ideal drones only (errors=ErrorModel())")
        plant_n = plant

        def deriv(x: np.ndarray, t: float) -> np.ndarray:
            sig = disturbance.signals(np.array([t]))[0]
            d1 = sig[0:3] + disturbance.drag_per_s * (sig[3:6] - x[:, 3:6])
            d2 = np.broadcast_to(sig[6:9], (x.shape[0], 3))
            return quadrotor_derivative(x, thrust, torque, d1, d2, plant_n)

        k1 = deriv(state, t_s)
        k2 = deriv(state + 0.5 * dt_s * k1, t_s + 0.5 * dt_s)
        k3 = deriv(state + 0.5 * dt_s * k2, t_s + 0.5 * dt_s)
        k4 = deriv(state + dt_s * k3, t_s + dt_s)
        ns = state + dt_s / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        nc[:, C_PHAT:C_PHAT + 3] = ns[:, 0:3]
        nc[:, C_VHAT:C_VHAT + 3] = ns[:, 3:6]
    else:
        raise ValueError(f"unknown integrator {integrator!r}")

    tel = np.concatenate(
        [e1, e3, euler - theta_ref, thrust[:, None], torque, saturated[:, None].astype(float)],
        axis=1,
    )
    return ns, nc, tel


def run_chunk_numpy(
    state: np.ndarray, ctrl: np.ndarray, stats: np.ndarray, dstep: np.ndarray,
    dreason: np.ndarray, *, ref: TrackingReference, chunk: RefChunk, dist: np.ndarray,
    step0: int, times: np.ndarray, every: int, frames: np.ndarray, tel: np.ndarray | None,
    opts: dict[str, Any], tables: ChunkTables | None = None,
) -> None:
    """Advance ``len(times)`` steps in place (the numpy engine's chunk).

    ``opts`` may carry ``drone`` (``(N, D_SIZE)`` constants), ``switches``
    (:class:`ErrorSwitches`) and ``ground_strike_z_m`` (height below which a drone stops, "ground";
    default -inf: no ground); ``tables`` the chunk's GNSS and wind tables (default: ideal).
    """
    limit = opts["divergence_limit_m"]
    ground_z = float(opts.get("ground_strike_z_m", -np.inf))
    sw: ErrorSwitches = opts.get("switches") or ErrorSwitches()
    drone = opts.get("drone")
    if drone is None:
        drone = ideal_drone_constants(opts["plant"], state.shape[0])
    outer_every = opts["gains"].outer_every(opts["dt_s"])
    for j in range(times.size):
        k = step0 + j
        alive = dstep < 0
        pr, vr, ar = ref.at_step(chunk, j)  # the plan at the true time: the error is measured here
        pc, vc, ac = ref.at_times(chunk, j, drone[:, D_CLOCK]) if sw.clock else (pr, vr, ar)
        gnss = None
        if sw.gnss and tables is not None and k % tables.gnss_every == 0:
            gnss = tables.gnss[(k - tables.gnss_first) // tables.gnss_every]
        wind = None
        if sw.drag and tables is not None:  # the wind at the flown position, to first order about the plan's
            w_plan, w_grad = tables.wind_at(float(times[j]))
            with np.errstate(all="ignore"):
                wind = flown_wind(w_plan, w_grad, state[:, 0:3] - pr, pr[:, 2], tables.wind_radius_m)
        with np.errstate(all="ignore"):
            err = np.sqrt(np.sum((state[:, 0:3] - pr) ** 2, axis=1))
        below = state[:, 2] < ground_z  # through the show's ground (never for NaN: caught as non-finite)
        runaway = alive & (~(err <= limit) | below)  # NaN (a non-finite reference) or a runaway drone
        dstep[runaway] = k
        far = np.where(ctrl[runaway, C_LIMITED] > LIMITED_FRACTION, DIVERGED_OVERPOWERED, DIVERGED_RUNAWAY)
        why = np.where(err[runaway] > limit, far, DIVERGED_NONFINITE)
        dreason[runaway] = np.where(below[runaway], DIVERGED_GROUND, why)
        alive &= ~runaway
        with np.errstate(all="ignore"):  # a diverging row may overflow; it is caught below
            ns, nc, trow = numpy_step(
                state, ctrl, pr=pc, vr=vc, ar=ac, yaw=chunk.yaw[j], dist=dist[j], t_s=times[j],
                disturbance=opts["disturbance"], params=opts["params"], plant=opts["plant"],
                gains=opts["gains"], dt_s=opts["dt_s"], integrator=opts["integrator"],
                drone=drone, gnss=gnss, wind=wind, errors=sw, phase=k % outer_every,
            )
            trow[:, 0:3] = state[:, 0:3] - pr
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
