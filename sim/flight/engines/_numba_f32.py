"""The float32-controller lane kernel: ``precision="float32"`` of :func:`sim.flight.simulate` (issue 20 item 6).

The same step as :mod:`sim.flight.engines._numba` (same scratch layout, lanes, scalar part,
selects, divergence rules; its helpers are imported from there), with the *control laws* in
single precision. Why it is faster: the lane step is bound by its dependency chains in the
out-of-order window, not by its flops (see ``_numba``); in float32 the chain's divisions and
square roots, the exp/log of the laws' ``sig`` and the attitude's asin/atan2 are shorter
(Cephes single-precision polynomials of about half the degree, :mod:`sim.flight.engines._vmath32`;
``vdivps``/``vsqrtps`` have lower latency than their double forms on Zen 4), and 8 drones of
float32 fill a ymm register instead of a zmm one. LLVM still vectorises the lane loop 8 drones
wide (the widest type in the loop, float64, sets its factor), so the float32 arithmetic runs in
ymm (packed-single ``...ps`` instructions; ``benchmarks/bench_precision.py`` checks it).

Measured (``benchmarks/bench_precision.py``: alternating single-thread rounds in one process,
kernel CPU time, 4,000 drones, gusty-rtk, 301 steps; medians of 8 rounds in four runs): 1.30x the
float64 kernel on a quiet machine, 1.37-1.41x under load (the float64 kernel's rate falls more with
the machine's load). Also measured and not kept: 16 lanes per block, 1.34-1.39x; 16 lanes with
LLVM forced to vectorise 16 wide (``-force-vector-width=16``, a process-global LLVM option, set
only in the compiling child: float32 in zmm, float64 in zmm pairs; 3,213 instructions per 16
drones against 2,051 per 8, a third of them stack spills): 1.46-1.49x, but a process that
compiled without the option would run other machine code (see ``_cached_machine_code``). That
figure compared processes; built properly (the option set in the compile child and around an
in-process fallback compile, tested; branch speed32, d9bdd0e, reverted) and measured in one process
against this kernel (alternating single-thread rounds, kernel CPU time, 4,000 drones, gusty-rtk,
6 rounds, load ~6; its cached object code was 16 wide: 1,903 zmm packed-single instructions against
134 here): **0.99x** at the default 250 Hz position loop (0.965-1.015) and 1.01x with every loop at
1 kHz (0.93-1.02), so not kept. In the same rounds this kernel ran at 1.37x the float64 one at
250 Hz (1.367-1.378) and 1.33x at 1 kHz (1.31-1.33).

Multi-rate as the float64 kernel (``IsmcGains.position_rate_hz``): the step's body is
:func:`_lane_step32`, inlined into two lane loops (outer loop on / held), the branch outside them;
the held command u and Θ_ref are float32 values stored exactly in the float64 controller state.

What stays float64 and why (per quantity):

* the plant: positions, velocities, attitude and rates are integrated in float64 (a sum over
  10^5-10^6 steps; float32's 6e-8 relative rounding at 200 m is 1e-5 m *per step*); their
  increments come from float32 quantities (the body axis and W(Θ) from the float32 sin/cos, the
  rotor speeds), whose rounding enters each step's increment only;
* the reference (absolute coordinates) and the errors ``p̂ - p_ref``, ``v̂ - v_ref``, ``Θ - Θ_c``:
  formed in float64, then the small differences rounded to float32;
* every integrated controller state: the ISMC integrals of the nominal loop, ``u_d`` of both
  loops, the command filter, the PID integral, the estimator, the rotor lag, the limited
  fraction; each adds a float32 increment to its float64 value. The sliding variables
  ``s = ė - ė₀ - ∫`` and their steps ``s - s_prev`` are formed in float64 (the integral is a
  long sum; s is a small difference of it); the integrand is the nominal law's feedback part
  without the drift ``f`` (``u_n + f`` computed as such would cancel ~g in float32);
* the statistics, divergence checks, telemetry and commits.

Float32: both ISMC laws (``sig`` as ``exp(h log(x·x))`` with the norm² clamped at 1e-30 so
``log`` stays off subnormals), the limiter, the attitude resolution (asin, atan2), the command
filter's acceleration, the attitude law's drift (W, Ẇ, gyroscopic terms), the mixer and the
desaturating allocation. Every float32 constant is hoisted as ``np.float32`` (a Python float
literal is float64 in numba and would promote the expression).

Accuracy (``tests/test_flight_precision.py``, against this module's float64 twin): per-drone
maximum tracking error within 1 mm on a 64-drone, 10-s gusty-rtk flight (measured 0.27 mm) and
on an ideal one, the demo show's flown minimum separation within 1 mm (measured 0.1 mm with
gusty-rtk, 0 ideal), and hover bounded (~6e-12 m, not growing, where float64 holds it exactly).
What float32 gives up: the float64 kernel agrees with the numpy reference to 1e-9 over a
simulated second and holds hover bit-exactly; this one does not (its rounding is ~1e-7 relative
in the control), and where a flight crosses a discrete event (an innovation gate, the limiter,
a rotor at its bound) the two can take different branches: on the demo show with gusty-rtk one
drone's maximum tracking error differs by 9 cm between the kernels (between the float64 kernel
and the numpy reference, by 2 cm on another drone), the flown separation by 0.1 mm.
"""

from __future__ import annotations

import math
from typing import Any

import numba as nb
import numpy as np

from sim.flight._disturbance import SHEAR_LINEAR_RADIUS_FRACTION
from sim.flight._quadrotor import YAW_HEADROOM
from sim.flight.engines._numba import (
    F_ALIVE,
    F_CTRL,
    F_DRONE,
    F_DSTEP,
    F_GNSS,
    F_INV,
    F_REASON,
    F_REF,
    F_REFC,
    F_STAT,
    F_STATE,
    F_TEL,
    F_TELOK,
    F_TF,
    F_TL,
    F_WA,
    F_WB,
    F_WJ,
    LANES,
    NF,
    _aligned_zeros,
    _block_window,
    _cached_machine_code,
    _commit,
    _kernel_args,
    _load_piece,
    _ref_at,
    _seek,
)
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
    D_IY,
    D_IZ,
    D_MASS,
    D_MOTOR,
    D_SAG_RATE,
    D_SIZE,
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
    STATS_SIZE,
    TEL_SIZE,
    RefChunk,
    TrackingReference,
)
from sim.flight.engines._tables import WIND_GRAD_SIZE, ChunkTables
from sim.flight.engines._vmath32 import vasin32, vatan2_32, vexp32, vlog32, vsincos32

__all__ = ["run_chunk_numba"]

F32 = np.float32
_Z, _O, _H = F32(0.0), F32(1.0), F32(0.5)
_NINF32, _PINF32 = F32(-np.inf), F32(np.inf)
# log of a norm² clamped here: keeps vlog32 off subnormals (|x| < 1e-15 contributes nothing visible).
_QMIN32 = F32(1e-30)


@nb.njit(inline="always", cache=True)
def _sig_scale32(x0: np.float32, x1: np.float32, x2: np.float32, h: np.float32) -> np.float32:
    """``_numba._sig_scale`` in float32: ``(x·x)^h``, 0 at x = 0."""
    q = x0 * x0 + x1 * x1 + x2 * x2
    pos = q > _Z
    out = vexp32(h * vlog32(max(q, _QMIN32) if pos else _O))
    return out if pos else _Z


@nb.njit(inline="always", cache=True)
def _unit_scale32(x0: np.float32, x1: np.float32, x2: np.float32, eps: np.float32) -> np.float32:
    """``_numba._unit_scale`` in float32: ``1/max(||x||, eps)``, 0 at x = 0."""
    n = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    inv = _O / max(n, eps)
    return inv if n > _Z else _Z


@nb.njit(inline="always", cache=True)
def _ismc_law32(
    ex: np.float32, ey: np.float32, ez: np.float32, edx: np.float32, edy: np.float32, edz: np.float32,
    ka: np.float32, kb: np.float32, ha: np.float32, hb: np.float32,
    sx: np.float32, sy: np.float32, sz: np.float32, qx: np.float32, qy: np.float32, qz: np.float32,
    gain: np.float32, eps: np.float32, eps_q: np.float32,
) -> tuple[np.float32, ...]:
    """``_numba._ismc_law`` in float32, given the sliding variable s and its step s - s_prev (formed in float64).

    Returns the nominal law's feedback part ``-k_a sig(e) - k_b sig(ė)`` (u_n = it - f: the
    integral of the nominal closed loop then integrates it without the drift f, which would
    cancel in float32) and the rate of u_d.
    """
    sa = _sig_scale32(ex, ey, ez, ha)
    sb = _sig_scale32(edx, edy, edz, hb)
    fbx = -ka * (ex * sa) - kb * (edx * sb)
    fby = -ka * (ey * sa) - kb * (edy * sb)
    fbz = -ka * (ez * sa) - kb * (edz * sb)
    us = _unit_scale32(sx, sy, sz, eps)
    uq = _unit_scale32(qx, qy, qz, eps_q)
    wx = -gain * (sx * us + _H * (qx * uq))
    wy = -gain * (sy * us + _H * (qy * uq))
    wz = -gain * (sz * us + _H * (qz * uq))
    return fbx, fby, fbz, wx, wy, wz


@nb.njit(inline="always", cache=True)
def _shift(hi_p: np.float32, lo_p: np.float32, hi_m: np.float32, lo_m: np.float32, top: np.float32) -> np.float32:
    """``_numba._shift`` in float32."""
    k_min = min(min(top - hi_p, lo_m), _Z)
    k_max = max(max(_Z - lo_p, hi_m - top), _Z)
    return k_min + k_max


@nb.njit(inline="always", cache=True)
def _allocate(base: np.float32, roll: np.float32, pitch: np.float32, yw: np.float32, top: np.float32,
              top_yaw: np.float32, on: bool) -> tuple[np.float32, np.float32, np.float32, np.float32, bool, bool]:
    """``_numba._allocate`` in float32 (all arguments float32)."""
    a1, a2, a3, a4 = base - pitch, base + roll, base + pitch, base - roll
    ninf, pinf = _NINF32, _PINF32
    hi = max(max(a1, a2), max(a3, a4))
    lo = min(min(a1, a2), min(a3, a4))
    g = _shift(hi, lo, ninf, pinf, top)
    g = g if on else _Z
    g2 = _H * _shift(hi + g, lo + g, ninf, pinf, top)
    g2 = g2 if on else _Z
    t1 = (g != _Z) | (g2 != _Z)
    a1, a2, a3, a4 = (a1 + g) + g2, (a2 + g) + g2, (a3 + g) + g2, (a4 + g) + g2
    a1, a2, a3, a4 = a1 + yw, a2 - yw, a3 + yw, a4 - yw
    hp, lp = max(a1, a3), min(a1, a3)
    hm, lm = max(a2, a4), min(a2, a4)
    g = _shift(hp, lp, hm, lm, top_yaw)
    g = g if on else _Z
    g2 = _H * _shift(hp + g, lp + g, hm - g, lm - g, top_yaw)
    g2 = g2 if on else _Z
    y = (g != _Z) | (g2 != _Z)
    a1, a2, a3, a4 = (a1 + g) + g2, (a2 - g) - g2, (a3 + g) + g2, (a4 - g) - g2
    hi = max(max(a1, a2), max(a3, a4))
    lo = min(min(a1, a2), min(a3, a4))
    g = _shift(hi, lo, ninf, pinf, top)
    use = (g <= _Z) & on
    g = g if use else _Z
    g2 = _H * _shift(hi + g, lo + g, ninf, pinf, top)
    g2 = g2 if use else _Z
    t2 = (g != _Z) | (g2 != _Z)
    a1, a2, a3, a4 = (a1 + g) + g2, (a2 + g) + g2, (a3 + g) + g2, (a4 + g) + g2
    hi = (hi + g) + g2
    lo = (lo + g) + g2
    cut = (lo < _Z) | (hi > top)
    o1 = min(max(a1, _Z), top)
    o2 = min(max(a2, _Z), top)
    o3 = min(max(a3, _Z), top)
    o4 = min(max(a4, _Z), top)
    return o1, o2, o3, o4, (t1 | t2) | cut, y | cut


@nb.njit(inline="always", cache=True)
def _lane_step32(sc: np.ndarray, lane: int, outer: bool, epoch: bool, cst: tuple[float, ...],
                 c32: tuple[np.float32, ...], flg: tuple[bool, ...], stp: tuple[float, ...],
                 s32: tuple[np.float32, ...]) -> None:
    """One step of one lane, as ``_numba._lane_step`` (the outer loop only when ``outer``, a constant
    at each call); ``cst``/``c32``: the kernel's float64/float32 constants, ``stp``/``s32``: the
    step's uniform inputs."""
    L = LANES
    (kf, arm, km, pg, ilim, izone, limit, ground_z, reset_v, dt, dto, drag, wrad, est_kp, est_kv, gate_h,
     gate_v, gate_n) = cst
    (g32, m32, ix32, iy32, iz32, k1f, k2f, k3f, k4f, h1f, h2f, h3f, h4f, alpha32, beta32, wn2_32, zw2_32,
     eps_p32, eps_pq32, eps_a32, eps_aq32, ki32, uz_min32, tan_tilt32, inv_ix32, inv_iy32, inv_iz32,
     inv_4kf32, inv_2akf32, inv_4km32, wmax2_32, wmax2_yaw32) = c32
    desat, use_clock, use_gnss, use_motor, use_drag = flg
    (t, off0, off1, off2, off3, off4, off5, off6, off7, off8, rps, dx0, dx1, dx2, dw0, dw1, dw2, kf_step,
     t_batt, fw) = stp
    rps32, ysin32, ycos32, d2x32, d2y32, d2z32, wgt32 = s32
    px, py, pz = sc[0 * L + lane], sc[1 * L + lane], sc[2 * L + lane]
    vx, vy, vz = sc[3 * L + lane], sc[4 * L + lane], sc[5 * L + lane]
    ph, th, ps = sc[6 * L + lane], sc[7 * L + lane], sc[8 * L + lane]
    wx, wy, wz = sc[9 * L + lane], sc[10 * L + lane], sc[11 * L + lane]
    alive = sc[F_ALIVE * L + lane] > 0.5
    tf, tl = sc[F_TF * L + lane], sc[F_TL * L + lane]

    prx, pry, prz, vrx, vry, vrz, arx, ary, arz = _ref_at(sc, F_REF, lane, t, tf, tl)
    prx, pry, prz = prx + off0, pry + off1, prz + off2
    qx, qy, qz = px - prx, py - pry, pz - prz
    err = math.sqrt(qx * qx + qy * qy + qz * qz)
    err_ok = err <= limit
    below = pz < ground_z
    err_ok = err_ok & (pz >= ground_z)
    if outer:  # the controller's reference: the outer loop's input
        if use_clock:
            prx, pry, prz, vrx, vry, vrz, arx, ary, arz = _ref_at(
                sc, F_REFC, lane, t + sc[(F_DRONE + D_CLOCK) * L + lane], tf, tl)
            prx, pry, prz = prx + off0, pry + off1, prz + off2
        vrx, vry, vrz = vrx + off3, vry + off4, vrz + off5
        arx, ary, arz = arx + off6, ary + off7, arz + off8

    ph0 = sc[(F_CTRL + C_PHAT) * L + lane]
    ph1 = sc[(F_CTRL + C_PHAT + 1) * L + lane]
    ph2 = sc[(F_CTRL + C_PHAT + 2) * L + lane]
    in0 = sc[(F_CTRL + C_INNOV) * L + lane]
    in1 = sc[(F_CTRL + C_INNOV + 1) * L + lane]
    in2 = sc[(F_CTRL + C_INNOV + 2) * L + lane]
    gcount = sc[(F_CTRL + C_GATE) * L + lane]
    rs0 = sc[(F_CTRL + C_RESET) * L + lane]
    rs1 = sc[(F_CTRL + C_RESET + 1) * L + lane]
    rs2 = sc[(F_CTRL + C_RESET + 2) * L + lane]
    if epoch:
        in0 = (px + sc[(F_GNSS + 0) * L + lane]) - ph0
        in1 = (py + sc[(F_GNSS + 1) * L + lane]) - ph1
        in2 = (pz + sc[(F_GNSS + 2) * L + lane]) - ph2
        inside = (abs(in0) <= gate_h) & (abs(in1) <= gate_h) & (abs(in2) <= gate_v)
        gcount = 0.0 if inside else gcount + 1.0
        reset = gcount >= gate_n
        gcount = 0.0 if reset else gcount
        ph0 = ph0 + in0 if reset else ph0
        ph1 = ph1 + in1 if reset else ph1
        ph2 = ph2 + in2 if reset else ph2
        rs0 = rs0 + in0 if reset else rs0
        rs1 = rs1 + in1 if reset else rs1
        rs2 = rs2 + in2 if reset else rs2
        in0 = in0 if inside else 0.0
        in1 = in1 if inside else 0.0
        in2 = in2 if inside else 0.0
    if use_gnss:
        cpx, cpy, cpz = ph0 - rs0, ph1 - rs1, ph2 - rs2
        rs0 = rs0 - min(max(rs0, -reset_v * dt), reset_v * dt)
        rs1 = rs1 - min(max(rs1, -reset_v * dt), reset_v * dt)
        rs2 = rs2 - min(max(rs2, -reset_v * dt), reset_v * dt)
        cvx = sc[(F_CTRL + C_VHAT) * L + lane]
        cvy = sc[(F_CTRL + C_VHAT + 1) * L + lane]
        cvz = sc[(F_CTRL + C_VHAT + 2) * L + lane]
    else:
        cpx, cpy, cpz, cvx, cvy, cvz = px, py, pz, vx, vy, vz
    if outer:
        # The errors formed in float64 (differences of large coordinates), then rounded.
        e1x, e1y, e1z = cpx - prx, cpy - pry, cpz - prz
        e2x, e2y, e2z = cvx - vrx, cvy - vry, cvz - vrz
        e1x32, e1y32, e1z32 = F32(e1x), F32(e1y), F32(e1z)
        e2x32, e2y32, e2z32 = F32(e2x), F32(e2y), F32(e2z)

        # ---- position ISMC (spec 4)
        ud0 = sc[(F_CTRL + C_UD) * L + lane]
        ud1 = sc[(F_CTRL + C_UD + 1) * L + lane]
        ud2 = sc[(F_CTRL + C_UD + 2) * L + lane]
        ie0 = sc[(F_CTRL + C_IERR) * L + lane]
        ie1 = sc[(F_CTRL + C_IERR + 1) * L + lane]
        ie2 = sc[(F_CTRL + C_IERR + 2) * L + lane]
        fx32, fy32, fz32 = -F32(arx), -F32(ary), -F32(arz) - g32
        # s = ė - ė0 - ∫(nominal loop) in float64: the integral is a long sum.
        ip0 = sc[(F_CTRL + C_IPOS) * L + lane]
        ip1 = sc[(F_CTRL + C_IPOS + 1) * L + lane]
        ip2 = sc[(F_CTRL + C_IPOS + 2) * L + lane]
        sx = (e2x - sc[(F_CTRL + C_E2_0) * L + lane]) - ip0
        sy = (e2y - sc[(F_CTRL + C_E2_0 + 1) * L + lane]) - ip1
        sz = (e2z - sc[(F_CTRL + C_E2_0 + 2) * L + lane]) - ip2
        sqx = F32(sx - sc[(F_CTRL + C_SPREV) * L + lane])
        sqy = F32(sy - sc[(F_CTRL + C_SPREV + 1) * L + lane])
        sqz = F32(sz - sc[(F_CTRL + C_SPREV + 2) * L + lane])
        fbx, fby, fbz, wpx, wpy, wpz = _ismc_law32(
            e1x32, e1y32, e1z32, e2x32, e2y32, e2z32, k1f, k2f, h1f, h2f,
            F32(sx), F32(sy), F32(sz), sqx, sqy, sqz, alpha32, eps_p32, eps_pq32)
        unx, uny, unz = fbx - fx32, fby - fy32, fbz - fz32
        ux = unx + F32(ud0)
        uy = uny + F32(ud1)
        uz = unz + F32(ud2)
        ux = ux - ki32 * F32(ie0)
        uy = uy - ki32 * F32(ie1)
        uz = uz - ki32 * F32(ie2)
        wux, wuy, wuz = ux, uy, uz
        floor_hit = uz < uz_min32
        uz = uz_min32 if floor_hit else uz
        hxy2 = ux * ux + uy * uy
        lim_xy = uz * tan_tilt32
        hxy = np.sqrt(hxy2)
        tilt_hit = hxy > lim_xy
        tsc = lim_xy / hxy
        ux = ux * tsc if tilt_hit else ux
        uy = uy * tsc if tilt_hit else uy
        limited = floor_hit | tilt_hit
        # The nominal loop's integrand u_n + f (+ what the limiter took away), without f.
        inx = fbx + (ux - wux) if limited else fbx
        iny = fby + (uy - wuy) if limited else fby
        inz = fbz + (uz - wuz) if limited else fbz
    else:  # zero-order hold of the outer loop's outputs (unused names: 0, the commits skip them)
        ux = F32(sc[(F_CTRL + C_UHOLD) * L + lane])
        uy = F32(sc[(F_CTRL + C_UHOLD + 1) * L + lane])
        uz = F32(sc[(F_CTRL + C_UHOLD + 2) * L + lane])
        limited = sc[(F_CTRL + C_LIMHOLD) * L + lane] > 0.5
        e1x, e1y, e1z = 0.0, 0.0, 0.0
        e1x32, e1y32, e1z32 = _Z, _Z, _Z
        sx, sy, sz = 0.0, 0.0, 0.0
        ip0, ip1, ip2 = 0.0, 0.0, 0.0
        inx, iny, inz = _Z, _Z, _Z
        wpx, wpy, wpz = _Z, _Z, _Z
        ud0, ud1, ud2 = 0.0, 0.0, 0.0
        ie0, ie1, ie2 = 0.0, 0.0, 0.0

    sph, cph = vsincos32(F32(ph))
    sth, cth = vsincos32(F32(th))
    sps, cps = vsincos32(F32(ps))
    zbx = cph * sth * cps + sph * sps
    zby = cph * sth * sps - sph * cps
    zbz = cph * cth
    thrust_cmd = m32 * (ux * zbx + uy * zby + uz * zbz)

    # ---- attitude resolution (spec 5) and command filter
    if outer:
        un2 = ux * ux + uy * uy + uz * uz
        un = np.sqrt(un2)
        ratio = (ux * ysin32 - uy * ycos32) / un if un > _Z else _Z
        ratio = min(max(ratio, -_O), _O)
        rph = vasin32(ratio)
        rth = vatan2_32(ux * ycos32 + uy * ysin32, uz)
        rpp = F32(sc[(F_CTRL + C_RHOLD) * L + lane])  # the previous run's, the ramp's start
        rtp = F32(sc[(F_CTRL + C_RHOLD + 1) * L + lane])
    else:
        rph = F32(sc[(F_CTRL + C_RHOLD) * L + lane])
        rth = F32(sc[(F_CTRL + C_RHOLD + 1) * L + lane])
        rpp = F32(sc[(F_CTRL + C_RPREV) * L + lane])
        rtp = F32(sc[(F_CTRL + C_RPREV + 1) * L + lane])
        un = F32(sc[(F_CTRL + C_UNORM) * L + lane])
    # The filter's input ramps from the previous run's Θ_ref to this one's (as _numba).
    rph_out, rth_out = rph, rth
    rph = rph - wgt32 * (rph - rpp)
    rth = rth - wgt32 * (rth - rtp)
    cx = sc[(F_CTRL + C_THC) * L + lane]
    cy = sc[(F_CTRL + C_THC + 1) * L + lane]
    cz = sc[(F_CTRL + C_THC + 2) * L + lane]
    cdx = sc[(F_CTRL + C_THC_DOT) * L + lane]
    cdy = sc[(F_CTRL + C_THC_DOT + 1) * L + lane]
    cdz = sc[(F_CTRL + C_THC_DOT + 2) * L + lane]
    cdx32, cdy32, cdz32 = F32(cdx), F32(cdy), F32(cdz)
    cddx = wn2_32 * (rph - F32(cx)) - zw2_32 * cdx32
    cddy = wn2_32 * (rth - F32(cy)) - zw2_32 * cdy32
    cddz = wn2_32 * (rps32 - F32(cz)) - zw2_32 * cdz32

    # ---- attitude ISMC (spec 6)
    wx32, wy32, wz32 = F32(wx), F32(wy), F32(wz)
    icth = _O / cth
    tth = sth * icth
    w01, w02 = sph * tth, cph * tth
    w11, w12 = cph, -sph
    w21, w22 = sph * icth, cph * icth
    edx = wx32 + w01 * wy32 + w02 * wz32
    edy = w11 * wy32 + w12 * wz32
    edz = w21 * wy32 + w22 * wz32
    e3x, e3y, e3z = F32(ph - cx), F32(th - cy), F32(ps - cz)
    e4x, e4y, e4z = edx - cdx32, edy - cdy32, edz - cdz32
    gax = (wy32 * (wz32 * iz32) - wz32 * (wy32 * iy32)) * inv_ix32
    gay = (wz32 * (wx32 * ix32) - wx32 * (wz32 * iz32)) * inv_iy32
    gaz = (wx32 * (wy32 * iy32) - wy32 * (wx32 * ix32)) * inv_iz32
    sec2 = icth * icth
    wd0 = (cph * tth * edx + sph * sec2 * edy) * wy32 + (-sph * tth * edx + cph * sec2 * edy) * wz32
    wd1 = -sph * edx * wy32 - cph * edx * wz32
    wd2 = (w22 * edx + sph * sth * sec2 * edy) * wy32 + (
        -w21 * edx + cph * sth * sec2 * edy
    ) * wz32
    fax = -(gax + w01 * gay + w02 * gaz) + wd0 - cddx
    fay = -(w11 * gay + w12 * gaz) + wd1 - cddy
    faz = -(w21 * gay + w22 * gaz) + wd2 - cddz
    ia0 = sc[(F_CTRL + C_IATT) * L + lane]
    ia1 = sc[(F_CTRL + C_IATT + 1) * L + lane]
    ia2 = sc[(F_CTRL + C_IATT + 2) * L + lane]
    sax = (float(e4x) - sc[(F_CTRL + C_E4_0) * L + lane]) - ia0
    say = (float(e4y) - sc[(F_CTRL + C_E4_0 + 1) * L + lane]) - ia1
    saz = (float(e4z) - sc[(F_CTRL + C_E4_0 + 2) * L + lane]) - ia2
    sqax = F32(sax - sc[(F_CTRL + C_SAPREV) * L + lane])
    sqay = F32(say - sc[(F_CTRL + C_SAPREV + 1) * L + lane])
    sqaz = F32(saz - sc[(F_CTRL + C_SAPREV + 2) * L + lane])
    fbax, fbay, fbaz, wax, way, waz = _ismc_law32(
        e3x, e3y, e3z, e4x, e4y, e4z, k3f, k4f, h3f, h4f,
        F32(sax), F32(say), F32(saz), sqax, sqay, sqaz, beta32, eps_a32, eps_aq32)
    uda0 = sc[(F_CTRL + C_UDA) * L + lane]
    uda1 = sc[(F_CTRL + C_UDA + 1) * L + lane]
    uda2 = sc[(F_CTRL + C_UDA + 2) * L + lane]
    uax = (fbax - fax) + F32(uda0)
    uay = (fbay - fay) + F32(uda1)
    uaz = (fbaz - faz) + F32(uda2)
    tcx = ix32 * (uax - sth * uaz)
    tcy = iy32 * (cph * uay + sph * cth * uaz)
    tcz = iz32 * (-sph * uay + cph * cth * uaz)

    # ---- rotors, allocation (float32), then what acts (float64)
    base = thrust_cmd * inv_4kf32
    roll = tcx * inv_2akf32
    pitch = tcy * inv_2akf32
    yw = tcz * inv_4km32
    o1f, o2f, o3f, o4f, thrust_short, clipped = _allocate(
        base, roll, pitch, yw, wmax2_32, wmax2_yaw32, desat)
    sat = (limited | thrust_short) | clipped
    lf_old = sc[(F_CTRL + C_LIMITED) * L + lane]
    if outer:
        push = (ux * e1x32 + uy * e1y32 + uz * e1z32) - g32 * e1z32 < _Z
    else:
        push = sc[(F_CTRL + C_PUSHHOLD) * L + lane] > 0.5
    follows = ux * zbx + uy * zby + uz * zbz > F32(LIMITED_ALIGN_COS) * un
    held = 1.0 if sat & push & follows else 0.0
    lf_new = lf_old + (dt / LIMITED_TAU_S) * (held - lf_old)
    o1, o2, o3, o4 = float(o1f), float(o2f), float(o3f), float(o4f)
    if use_motor:
        mot = sc[(F_DRONE + D_MOTOR) * L + lane]
        ro1 = sc[(F_CTRL + C_ROTOR) * L + lane]
        ro2 = sc[(F_CTRL + C_ROTOR + 1) * L + lane]
        ro3 = sc[(F_CTRL + C_ROTOR + 2) * L + lane]
        ro4 = sc[(F_CTRL + C_ROTOR + 3) * L + lane]
        o1 = ro1 + mot * (o1 - ro1)
        o2 = ro2 + mot * (o2 - ro2)
        o3 = ro3 + mot * (o3 - ro3)
        o4 = ro4 + mot * (o4 - ro4)
    rg = sc[(F_DRONE + D_THRUST) * L + lane] * (1.0 - sc[(F_DRONE + D_SAG_RATE) * L + lane] * t_batt)
    thrust = kf * (o1 + o2 + o3 + o4) * rg
    tqx = arm * kf * (o2 - o4) * rg
    tqy = arm * kf * (o3 - o1) * rg
    tqz = km * (o1 - o2 + o3 - o4) * rg

    # ---- plant, semi-implicit Euler with the inputs held (float64; the body axis and
    # W(Θ) from the float32 sin/cos: their rounding enters the increments only)
    pix = sc[(F_DRONE + D_IX) * L + lane]
    piy = sc[(F_DRONE + D_IY) * L + lane]
    piz = sc[(F_DRONE + D_IZ) * L + lane]
    tpm = thrust * sc[(F_INV + 3) * L + lane]
    zbx64, zby64, zbz64 = float(zbx), float(zby), float(zbz)
    ax = tpm * zbx64 + dx0 + drag * (dw0 - vx)
    ay = tpm * zby64 + dx1 + drag * (dw1 - vy)
    az = tpm * zbz64 + dx2 + drag * (dw2 - vz)
    if use_drag:
        wa0, wa1, wa2 = sc[F_WA * L + lane], sc[(F_WA + 1) * L + lane], sc[(F_WA + 2) * L + lane]
        wb0, wb1, wb2 = sc[F_WB * L + lane], sc[(F_WB + 1) * L + lane], sc[(F_WB + 2) * L + lane]
        dqx, dqy, dqz = min(max(qx, -wrad), wrad), min(max(qy, -wrad), wrad), min(max(qz, -wrad), wrad)
        hz = SHEAR_LINEAR_RADIUS_FRACTION * (pz - qz)
        dsz = min(max(qz, -hz), hz)
        oj = F_WJ * L + lane
        jx = (sc[oj] * dqx + sc[oj + L] * dqy + sc[oj + 2 * L] * dqz) + sc[oj + 9 * L] * dsz
        jy = (sc[oj + 3 * L] * dqx + sc[oj + 4 * L] * dqy + sc[oj + 5 * L] * dqz) + sc[oj + 10 * L] * dsz
        jz = sc[oj + 6 * L] * dqx + sc[oj + 7 * L] * dqy + sc[oj + 8 * L] * dqz
        rlx = vx - ((wa0 + fw * (wb0 - wa0)) + jx)
        rly = vy - ((wa1 + fw * (wb1 - wa1)) + jy)
        rlz = vz - ((wa2 + fw * (wb2 - wa2)) + jz)
        dsp = sc[(F_DRONE + D_DRAG) * L + lane] * math.sqrt(rlx * rlx + rly * rly + rlz * rlz)
        ax -= dsp * rlx
        ay -= dsp * rly
        az -= dsp * rlz
    az -= pg
    odx = (tqx - (wy * (wz * piz) - wz * (wy * piy))) * sc[F_INV * L + lane] + float(
        d2x32 - sth * d2z32)
    ody = (tqy - (wz * (wx * pix) - wx * (wz * piz))) * sc[(F_INV + 1) * L + lane] + float(
        cph * d2y32 + sph * cth * d2z32)
    odz = (tqz - (wx * (wy * piy) - wy * (wx * pix))) * sc[(F_INV + 2) * L + lane] + float(
        -sph * d2y32 + cph * cth * d2z32)
    nvx, nvy, nvz = vx + dt * ax, vy + dt * ay, vz + dt * az
    npx, npy, npz = px + dt * nvx, py + dt * nvy, pz + dt * nvz
    nwx, nwy, nwz = wx + dt * odx, wy + dt * ody, wz + dt * odz
    nwx32, nwy32, nwz32 = F32(nwx), F32(nwy), F32(nwz)
    nph = ph + dt * float(nwx32 + w01 * nwy32 + w02 * nwz32)
    nth = th + dt * float(w11 * nwy32 + w12 * nwz32)
    nps = ps + dt * float(w21 * nwy32 + w22 * nwz32)
    if use_gnss:
        nvh0 = cvx + dt * (ax + est_kv * in0)
        nvh1 = cvy + dt * (ay + est_kv * in1)
        nvh2 = cvz + dt * (az + est_kv * in2)
        nph0 = ph0 + dt * (nvh0 + est_kp * in0)
        nph1 = ph1 + dt * (nvh1 + est_kp * in1)
        nph2 = ph2 + dt * (nvh2 + est_kp * in2)
    else:
        nvh0, nvh1, nvh2, nph0, nph1, nph2 = nvx, nvy, nvz, npx, npy, npz

    # ---- controller state candidates (float64 sums of float32 increments)
    if outer:  # the outer loop's integrators, with its own step K dt
        ipx = ip0 + dto * float(inx)
        ipy = ip1 + dto * float(iny)
        ipz = ip2 + dto * float(inz)
    else:
        ipx, ipy, ipz = 0.0, 0.0, 0.0
    iax = ia0 + dt * float(fbax)
    iay = ia1 + dt * float(fbay)
    iaz = ia2 + dt * float(fbaz)
    ncdx, ncdy, ncdz = cdx + dt * float(cddx), cdy + dt * float(cddy), cdz + dt * float(cddz)
    ncx, ncy, ncz = cx + dt * ncdx, cy + dt * ncdy, cz + dt * ncdz
    if outer:
        nie0 = min(max(ie0 + dto * e1x, -ilim), ilim) if abs(e1x) < izone else ie0
        nie1 = min(max(ie1 + dto * e1y, -ilim), ilim) if abs(e1y) < izone else ie1
        nie2 = min(max(ie2 + dto * e1z, -ilim), ilim) if abs(e1z) < izone else ie2
        nie0 = ie0 if sat else nie0
        nie1 = ie1 if sat else nie1
        nie2 = ie2 if sat else nie2
        udx = ud0 if sat else ud0 + dto * float(wpx)
        udy = ud1 if sat else ud1 + dto * float(wpy)
        udz = ud2 if sat else ud2 + dto * float(wpz)
    else:
        nie0, nie1, nie2 = 0.0, 0.0, 0.0
        udx, udy, udz = 0.0, 0.0, 0.0
    uadx = uda0 if clipped else uda0 + dt * float(wax)
    uady = uda1 if clipped else uda1 + dt * float(way)
    uadz = uda2 if clipped else uda2 + dt * float(waz)

    sc[(F_TEL + 0) * L + lane] = qx
    sc[(F_TEL + 1) * L + lane] = qy
    sc[(F_TEL + 2) * L + lane] = qz
    sc[(F_TEL + 3) * L + lane] = float(e3x)
    sc[(F_TEL + 4) * L + lane] = float(e3y)
    sc[(F_TEL + 5) * L + lane] = float(e3z)
    sc[(F_TEL + 6) * L + lane] = ph - float(rph)
    sc[(F_TEL + 7) * L + lane] = th - float(rth)
    sc[(F_TEL + 8) * L + lane] = ps - rps
    sc[(F_TEL + 9) * L + lane] = thrust
    sc[(F_TEL + 10) * L + lane] = tqx
    sc[(F_TEL + 11) * L + lane] = tqy
    sc[(F_TEL + 12) * L + lane] = tqz
    sc[(F_TEL + 13) * L + lane] = 1.0 if sat else 0.0
    sc[F_TELOK * L + lane] = 1.0 if alive & err_ok else 0.0

    check = (((npx + npy + npz) + (nvx + nvy + nvz)) + ((nph + nth + nps) + (nwx + nwy + nwz))
             + ((ipx + ipy + ipz) + (iax + iay + iaz)) + ((udx + udy + udz) + (uadx + uady + uadz))
             + ((ncx + ncy + ncz) + (ncdx + ncdy + ncdz)) + ((sx + sy + sz) + (sax + say + saz))
             + thrust + ((nph0 + nph1 + nph2) + (nvh0 + nvh1 + nvh2)) + (nie0 + nie1 + nie2))
    finite = math.isfinite(check)
    ok = alive & err_ok & finite
    died = alive and not ok
    sc[F_ALIVE * L + lane] = 1.0 if ok else 0.0
    sc[F_DSTEP * L + lane] = kf_step if died else sc[F_DSTEP * L + lane]
    far = DIVERGED_OVERPOWERED if lf_old > LIMITED_FRACTION else DIVERGED_RUNAWAY
    why = far if (not err_ok) and err > limit else DIVERGED_NONFINITE
    why = DIVERGED_GROUND if below else why
    sc[F_REASON * L + lane] = float(why) if died else sc[F_REASON * L + lane]

    # Statistics and the commit, for the drones that flew this step.
    so = F_STAT * L + lane
    ssum, smax = sc[so + STAT_SUMSQ * L], sc[so + STAT_MAX * L]
    sdth, scount = sc[so + STAT_DTHRUST * L], sc[so + STAT_COUNT * L]
    last_thrust = sc[(F_CTRL + C_LAST_THRUST) * L + lane]
    sc[so + STAT_SUMSQ * L] = ssum + err * err if ok else ssum
    sc[so + STAT_MAX * L] = max(smax, err) if ok else smax
    sc[so + STAT_DTHRUST * L] = max(sdth, abs(thrust - last_thrust)) if ok else sdth
    sc[so + STAT_COUNT * L] = scount + 1.0 if ok else scount

    _commit(sc, F_STATE + 0, lane, npx, ok)
    _commit(sc, F_STATE + 1, lane, npy, ok)
    _commit(sc, F_STATE + 2, lane, npz, ok)
    _commit(sc, F_STATE + 3, lane, nvx, ok)
    _commit(sc, F_STATE + 4, lane, nvy, ok)
    _commit(sc, F_STATE + 5, lane, nvz, ok)
    _commit(sc, F_STATE + 6, lane, nph, ok)
    _commit(sc, F_STATE + 7, lane, nth, ok)
    _commit(sc, F_STATE + 8, lane, nps, ok)
    _commit(sc, F_STATE + 9, lane, nwx, ok)
    _commit(sc, F_STATE + 10, lane, nwy, ok)
    _commit(sc, F_STATE + 11, lane, nwz, ok)
    if outer:
        _commit(sc, F_CTRL + C_IPOS, lane, ipx, ok)
    if outer:
        _commit(sc, F_CTRL + C_IPOS + 1, lane, ipy, ok)
    if outer:
        _commit(sc, F_CTRL + C_IPOS + 2, lane, ipz, ok)
    if outer:
        _commit(sc, F_CTRL + C_UD, lane, udx, ok)
    if outer:
        _commit(sc, F_CTRL + C_UD + 1, lane, udy, ok)
    if outer:
        _commit(sc, F_CTRL + C_UD + 2, lane, udz, ok)
    if outer:
        _commit(sc, F_CTRL + C_SPREV, lane, sx, ok)
    if outer:
        _commit(sc, F_CTRL + C_SPREV + 1, lane, sy, ok)
    if outer:
        _commit(sc, F_CTRL + C_SPREV + 2, lane, sz, ok)
    _commit(sc, F_CTRL + C_IATT, lane, iax, ok)
    _commit(sc, F_CTRL + C_IATT + 1, lane, iay, ok)
    _commit(sc, F_CTRL + C_IATT + 2, lane, iaz, ok)
    _commit(sc, F_CTRL + C_UDA, lane, uadx, ok)
    _commit(sc, F_CTRL + C_UDA + 1, lane, uady, ok)
    _commit(sc, F_CTRL + C_UDA + 2, lane, uadz, ok)
    _commit(sc, F_CTRL + C_SAPREV, lane, sax, ok)
    _commit(sc, F_CTRL + C_SAPREV + 1, lane, say, ok)
    _commit(sc, F_CTRL + C_SAPREV + 2, lane, saz, ok)
    _commit(sc, F_CTRL + C_THC, lane, ncx, ok)
    _commit(sc, F_CTRL + C_THC + 1, lane, ncy, ok)
    _commit(sc, F_CTRL + C_THC + 2, lane, ncz, ok)
    _commit(sc, F_CTRL + C_THC_DOT, lane, ncdx, ok)
    _commit(sc, F_CTRL + C_THC_DOT + 1, lane, ncdy, ok)
    _commit(sc, F_CTRL + C_THC_DOT + 2, lane, ncdz, ok)
    _commit(sc, F_CTRL + C_LAST_THRUST, lane, thrust, ok)
    if outer:
        _commit(sc, F_CTRL + C_IERR, lane, nie0, ok)
    if outer:
        _commit(sc, F_CTRL + C_IERR + 1, lane, nie1, ok)
    if outer:
        _commit(sc, F_CTRL + C_IERR + 2, lane, nie2, ok)
    _commit(sc, F_CTRL + C_PHAT, lane, nph0, ok)
    _commit(sc, F_CTRL + C_PHAT + 1, lane, nph1, ok)
    _commit(sc, F_CTRL + C_PHAT + 2, lane, nph2, ok)
    _commit(sc, F_CTRL + C_VHAT, lane, nvh0, ok)
    _commit(sc, F_CTRL + C_VHAT + 1, lane, nvh1, ok)
    _commit(sc, F_CTRL + C_VHAT + 2, lane, nvh2, ok)
    _commit(sc, F_CTRL + C_INNOV, lane, in0, ok)
    _commit(sc, F_CTRL + C_INNOV + 1, lane, in1, ok)
    _commit(sc, F_CTRL + C_INNOV + 2, lane, in2, ok)
    _commit(sc, F_CTRL + C_ROTOR, lane, o1, ok)
    _commit(sc, F_CTRL + C_ROTOR + 1, lane, o2, ok)
    _commit(sc, F_CTRL + C_ROTOR + 2, lane, o3, ok)
    _commit(sc, F_CTRL + C_ROTOR + 3, lane, o4, ok)
    _commit(sc, F_CTRL + C_GATE, lane, gcount, ok)
    _commit(sc, F_CTRL + C_RESET, lane, rs0, ok)
    _commit(sc, F_CTRL + C_RESET + 1, lane, rs1, ok)
    _commit(sc, F_CTRL + C_RESET + 2, lane, rs2, ok)
    _commit(sc, F_CTRL + C_LIMITED, lane, lf_new, ok)
    if outer:  # the held outputs of the outer loop
        _commit(sc, F_CTRL + C_UHOLD, lane, float(ux), ok)
        _commit(sc, F_CTRL + C_UHOLD + 1, lane, float(uy), ok)
        _commit(sc, F_CTRL + C_UHOLD + 2, lane, float(uz), ok)
        _commit(sc, F_CTRL + C_RHOLD, lane, float(rph_out), ok)
        _commit(sc, F_CTRL + C_RHOLD + 1, lane, float(rth_out), ok)
        _commit(sc, F_CTRL + C_RPREV, lane, float(rpp), ok)
        _commit(sc, F_CTRL + C_RPREV + 1, lane, float(rtp), ok)
        _commit(sc, F_CTRL + C_UNORM, lane, float(un), ok)
        _commit(sc, F_CTRL + C_LIMHOLD, lane, 1.0 if limited else 0.0, ok)
        _commit(sc, F_CTRL + C_PUSHHOLD, lane, 1.0 if push else 0.0, ok)


@nb.njit(parallel=True, cache=True, error_model="numpy",
         fastmath={"nsz", "afn", "contract", "reassoc"})
def _kernel(
    state, ctrl, stats, dstep, dreason, breaks, coeffs, cursor0, times, offset, yaw, dist, step0, every,
    frames, tel, use_tel, prm, plt, gn, drag, dt, limit, drone, gnss, gnss_every, gnss_first, wtab, wind_k0,
    wind_dt, wgrad, wrad, use_gnss, use_motor, use_drag, use_clock, est_kp, est_kv, gate_h, gate_v, gate_n, reset_v,
    ground_z, batt_end,
):
    n = state.shape[0]
    steps = times.shape[0]
    last_piece = breaks.shape[1] - 2
    # Controller model (what the controller believes).
    m = prm[0]
    ix, iy, iz = prm[1], prm[2], prm[3]
    g = prm[7]
    # The plant's rotors (its mass and inertia are per drone, in ``drone``).
    arm, kf, km, pg, wmax2 = plt[4], plt[5], plt[6], plt[7], plt[8]
    k1, k2, r1, r2, alpha = gn[0], gn[1], gn[2], gn[3], gn[4]
    k3, k4, r3, r4, beta_g = gn[5], gn[6], gn[7], gn[8], gn[9]
    # The laws' powers as the exponents of x·x (``_sig_scale``).
    h1, h2, h3, h4 = 0.5 * (r1 - 1.0), 0.5 * (r2 - 1.0), 0.5 * (r3 - 1.0), 0.5 * (r4 - 1.0)
    wn, zeta = gn[10], gn[11]
    eps_p, eps_pq, eps_a, eps_aq, ki, ilim, izone = gn[12], gn[13], gn[14], gn[15], gn[16], gn[17], gn[18]
    uz_min, tan_tilt = gn[19], gn[20]
    desat = gn[21] > 0.5  # PX4's sequential desaturation (else the paper's per-rotor clip)
    wmax2_yaw = (1.0 + YAW_HEADROOM) * wmax2
    # Reciprocals of the constants, hoisted: a multiply is ~5x cheaper than a divide.
    inv_ix, inv_iy, inv_iz = 1.0 / ix, 1.0 / iy, 1.0 / iz
    inv_2akf, inv_4km = 1.0 / (2.0 * arm * kf), 1.0 / (4.0 * km)
    # The controller's constants in float32 (a float64 operand would promote the expression).
    g32, m32 = F32(g), F32(m)
    ix32, iy32, iz32 = F32(ix), F32(iy), F32(iz)
    k1f, k2f, k3f, k4f = F32(k1), F32(k2), F32(k3), F32(k4)
    h1f, h2f, h3f, h4f = F32(h1), F32(h2), F32(h3), F32(h4)
    alpha32, beta32 = F32(alpha), F32(beta_g)
    wn2_32, zw2_32 = F32(wn * wn), F32(2.0 * zeta * wn)
    eps_p32, eps_pq32, eps_a32, eps_aq32 = F32(eps_p), F32(eps_pq), F32(eps_a), F32(eps_aq)
    ki32, uz_min32, tan_tilt32 = F32(ki), F32(uz_min), F32(tan_tilt)
    inv_ix32, inv_iy32, inv_iz32 = F32(inv_ix), F32(inv_iy), F32(inv_iz)
    inv_4kf32, inv_2akf32, inv_4km32 = F32(1.0 / (4.0 * kf)), F32(inv_2akf), F32(inv_4km)
    wmax2_32, wmax2_yaw32 = F32(wmax2), F32(wmax2_yaw)
    n_wind = wtab.shape[0]
    blocks = (n + LANES - 1) // LANES
    L = LANES
    kev = int(gn[22])  # the outer loop runs every kev steps (IsmcGains.outer_every), with step dto
    dto = float(kev) * dt
    cst = (kf, arm, km, pg, ilim, izone, limit, ground_z, reset_v, dt, dto, drag, wrad, est_kp, est_kv, gate_h,
           gate_v, gate_n)
    c32 = (g32, m32, ix32, iy32, iz32, k1f, k2f, k3f, k4f, h1f, h2f, h3f, h4f, alpha32, beta32, wn2_32, zw2_32,
           eps_p32, eps_pq32, eps_a32, eps_aq32, ki32, uz_min32, tan_tilt32, inv_ix32, inv_iy32, inv_iz32,
           inv_4kf32, inv_2akf32, inv_4km32, wmax2_32, wmax2_yaw32)
    flg = (desat, use_clock, use_gnss, use_motor, use_drag)

    for b in nb.prange(blocks):
        i0 = b * L
        cnt = min(L, n - i0)
        sc = _aligned_zeros(NF * L)
        nl = sc.size // NF
        cur = np.zeros(L, dtype=np.int64)
        nxt = np.zeros(L)
        prv = np.zeros(L)
        curc = np.zeros(L, dtype=np.int64)
        nxtc = np.zeros(L)
        prvc = np.zeros(L)
        # ---- fill the scratch (lanes past the fleet fly a copy of its last drone, never stored)
        for lane in range(L):
            i = min(i0 + lane, n - 1)
            for f in range(12):
                sc[(F_STATE + f) * L + lane] = state[i, f]
            for f in range(CTRL_SIZE):
                sc[(F_CTRL + f) * L + lane] = ctrl[i, f]
            for f in range(D_SIZE):
                sc[(F_DRONE + f) * L + lane] = drone[i, f]
            sc[(F_INV + 0) * L + lane] = 1.0 / drone[i, D_IX]
            sc[(F_INV + 1) * L + lane] = 1.0 / drone[i, D_IY]
            sc[(F_INV + 2) * L + lane] = 1.0 / drone[i, D_IZ]
            sc[(F_INV + 3) * L + lane] = 1.0 / drone[i, D_MASS]
            sc[F_TF * L + lane] = breaks[i, 0]
            sc[F_TL * L + lane] = breaks[i, last_piece + 1]
            for f in range(STATS_SIZE):
                sc[(F_STAT + f) * L + lane] = stats[i, f]
            sc[F_ALIVE * L + lane] = 1.0 if dstep[i] < 0 else 0.0
            sc[F_DSTEP * L + lane] = float(dstep[i])
            sc[F_REASON * L + lane] = float(dreason[i])
            c0 = cursor0[i]
            cur[lane], curc[lane] = c0, c0
            nxt[lane] = breaks[i, c0 + 1] if c0 < last_piece else math.inf
            prv[lane] = breaks[i, c0] if c0 > 0 else -math.inf
            nxtc[lane], prvc[lane] = nxt[lane], prv[lane]
            _load_piece(sc, F_REF, lane, coeffs, breaks, i, c0)
            _load_piece(sc, F_REFC, lane, coeffs, breaks, i, c0)
        win_lo, win_hi = math.inf, -math.inf  # empty: the first step searches
        # Next frame step, advanced by a counter (an integer division per step costs ~5 %).
        next_rec = ((step0 + every - 1) // every) * every
        next_outer = ((step0 + kev - 1) // kev) * kev
        next_gnss = gnss_first
        gidx = 0
        iw_loaded = -1
        for j in range(steps):
            k = step0 + j
            t = times[j]
            rec = k == next_rec
            if rec:
                next_rec += every
                fr = k // every
                for lane in range(cnt):
                    frames[fr, i0 + lane, 0] = sc[(F_STATE + 0) * L + lane]
                    frames[fr, i0 + lane, 1] = sc[(F_STATE + 1) * L + lane]
                    frames[fr, i0 + lane, 2] = sc[(F_STATE + 2) * L + lane]
            # ---- the scalar part: pieces, GNSS and wind table rows (uniform or rare)
            # The piece cursors: while t stays inside the block's common window no lane can
            # leave its piece (see ``_block_window``), which is most steps: two comparisons
            # instead of a pass over the lanes.
            if not (win_lo <= t < win_hi):
                for lane in range(L):
                    i = min(i0 + lane, n - 1)
                    tf, tl = sc[F_TF * L + lane], sc[F_TL * L + lane]
                    _seek(sc, F_REF, lane, cur, nxt, prv, coeffs, breaks, i, min(max(t, tf), tl), last_piece)
                    if use_clock:
                        tcc = min(max(t + sc[(F_DRONE + D_CLOCK) * L + lane], tf), tl)
                        _seek(sc, F_REFC, lane, curc, nxtc, prvc, coeffs, breaks, i, tcc, last_piece)
                win_lo, win_hi = _block_window(sc, nxt, prv, nxtc, prvc, use_clock)
            epoch = use_gnss and k == next_gnss
            if epoch:  # a GNSS epoch: the lanes take a new innovation z - p̂, held until the next
                for lane in range(L):
                    i = min(i0 + lane, n - 1)
                    for a in range(3):
                        sc[(F_GNSS + a) * L + lane] = gnss[gidx, i, a]
                next_gnss += gnss_every
                gidx += 1
            fw = 0.0
            if use_drag:  # the wind, linear on its grid: the rows around t
                xw = t / wind_dt
                iw = min(max(int(math.floor(xw)) - wind_k0, 0), n_wind - 2)
                fw = xw - (wind_k0 + iw)
                if iw != iw_loaded:
                    iw_loaded = iw
                    for lane in range(L):
                        i = min(i0 + lane, n - 1)
                        for a in range(3):
                            sc[(F_WA + a) * L + lane] = wtab[iw, i, a]
                            sc[(F_WB + a) * L + lane] = wtab[iw + 1, i, a]
                        for a in range(WIND_GRAD_SIZE):
                            sc[(F_WJ + a) * L + lane] = 0.5 * (wgrad[iw, i, a] + wgrad[iw + 1, i, a])
            off0, off1, off2 = offset[j, 0], offset[j, 1], offset[j, 2]
            off3, off4, off5 = offset[j, 3], offset[j, 4], offset[j, 5]
            off6, off7, off8 = offset[j, 6], offset[j, 7], offset[j, 8]
            rps, ysin, ycos = yaw[j, 0], yaw[j, 1], yaw[j, 2]
            dx0, dx1, dx2 = dist[j, 0], dist[j, 1], dist[j, 2]
            dw0, dw1, dw2 = dist[j, 3], dist[j, 4], dist[j, 5]
            d2x, d2y, d2z = dist[j, 6], dist[j, 7], dist[j, 8]
            kf_step = float(k)
            t_batt = min(t, batt_end)  # the battery sag grows until the pack's endurance, then is held

            rps32, ysin32, ycos32 = F32(rps), F32(ysin), F32(ycos)
            d2x32, d2y32, d2z32 = F32(d2x), F32(d2y), F32(d2z)

            # ---- the vector part: one control + integration step of every lane. (The trip
            # count is read from the scratch's size, not the constant LANES: LLVM fully
            # unrolls a loop with a small constant trip count before it could vectorise it.)
            # float64: the plant, the reference, the errors, the estimator and every integrated
            # state; float32 (names ``*_32`` or built from them): the control laws between.
            outer = k == next_outer
            if outer:
                next_outer += kev
            # The step's place in the outer loop's period (0 when it runs) and the ramp's weight.
            phase = k - (next_outer - kev)
            wgt = float(kev - 1 - phase) / float(kev)
            stp = (t, off0, off1, off2, off3, off4, off5, off6, off7, off8, rps, dx0, dx1, dx2, dw0, dw1, dw2,
                   kf_step, t_batt, fw)
            s32 = (rps32, ysin32, ycos32, d2x32, d2y32, d2z32, F32(wgt))
            if outer:
                for lane in range(nl):
                    _lane_step32(sc, lane, True, epoch, cst, c32, flg, stp, s32)
            else:
                for lane in range(nl):
                    _lane_step32(sc, lane, False, epoch, cst, c32, flg, stp, s32)
            if use_tel and rec:
                fr = k // every
                for lane in range(cnt):
                    if sc[F_TELOK * L + lane] > 0.5:
                        for f in range(TEL_SIZE):
                            tel[fr, i0 + lane, f] = sc[(F_TEL + f) * L + lane]

        # ---- write the block back
        for lane in range(cnt):
            i = i0 + lane
            for f in range(12):
                state[i, f] = sc[(F_STATE + f) * L + lane]
            for f in range(CTRL_SIZE):
                ctrl[i, f] = sc[(F_CTRL + f) * L + lane]
            for f in range(STATS_SIZE):
                stats[i, f] = sc[(F_STAT + f) * L + lane]
            dstep[i] = int(sc[F_DSTEP * L + lane])
            dreason[i] = int(sc[F_REASON * L + lane])


def run_chunk_numba(
    state: np.ndarray, ctrl: np.ndarray, stats: np.ndarray, dstep: np.ndarray,
    dreason: np.ndarray, *, ref: TrackingReference, chunk: RefChunk, dist: np.ndarray,
    step0: int, times: np.ndarray, every: int, frames: np.ndarray, tel: np.ndarray | None,
    opts: dict[str, Any], tables: ChunkTables | None = None,
) -> None:
    """Advance ``len(times)`` steps in place with the float32-controller kernel.

    Same arguments and contract as :func:`sim.flight.engines._numba.run_chunk_numba`.
    """
    args = _kernel_args(state, ctrl, stats, dstep, dreason, ref=ref, chunk=chunk, dist=dist, step0=step0,
                        times=times, every=every, frames=frames, tel=tel, opts=opts, tables=tables)
    _cached_machine_code(_kernel, args)
    _kernel(*args)
