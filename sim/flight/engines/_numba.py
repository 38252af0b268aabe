"""The fast engine: one fused numba kernel, parallel over drones.

The kernel computes exactly what :func:`sim.flight.engines._numpy.numpy_step` computes (same
controller, same mixer and saturation, same semi-implicit Euler step, same divergence
rules), but with the loops the other way round: ``prange`` over drones, and for each
drone a serial loop over the steps of the chunk with the whole state in registers.
Drones are independent (disturbances depend on time only), so no synchronisation is
needed inside a chunk; the driver (:func:`sim.flight.engines._driver.simulate`) calls the
kernel once per chunk of steps, which bounds the memory of the reference and
disturbance tables and gives progress granularity.

``cache=True`` keeps the compiled kernel on disk (``__pycache__``), so only the first
run on a machine pays the compile time (about 10-20 s).

The numpy step is the readable reference; ``tests/test_flight_engines.py`` checks that
both agree to 1e-9 over one simulated second (24 drones off their circles, with and
without disturbances) and from arbitrary states for a few steps.

Floating point: ``fastmath`` allows reassociation, FMA contraction, approximate
functions and signed-zero freedom (about 15 % faster), but *not* ``nnan``/``ninf`` (the
divergence checks need NaN and inf to behave) nor ``arcp`` (reciprocal instead of
division: it changes the mixer's rounding so that the hover thrust no longer comes
back as exactly m·g, and hover would drift by ~1e-7 m in a second). The kernel
therefore holds hover bit-exactly, like the reference, and otherwise differs from it
by rounding: libm's transcendental functions here, numpy's own SIMD versions there
(asin, atan2 and pow differ by an ulp). That is invisible while errors are above the
discrete chattering floor of the finite-time laws, but once an error sits at that
floor (``sig(e, 1/2)`` has unbounded gain at 0, so the sampled loop chatters at about
1e-9 rad/s) the closed loop amplifies an ulp by ~7 % per step: from there the two
engines give equally valid trajectories that drift apart at the 1e-5 level inside
the chatter, with the same tracking statistics. Two runs of the same engine are
bit-identical.
"""

from __future__ import annotations

import math
from typing import Any

import numba as nb
import numpy as np

from sim.flight.engines._state import (
    C_E2_0,
    C_E4_0,
    C_IATT,
    C_IERR,
    C_INNOV,
    C_IPOS,
    C_LAST_THRUST,
    C_PHAT,
    C_ROTOR,
    C_SAPREV,
    C_SPREV,
    C_THC,
    C_THC_DOT,
    C_UD,
    C_UDA,
    C_VHAT,
    D_CLOCK,
    D_DRAG,
    D_IX,
    D_IY,
    D_IZ,
    D_MASS,
    D_MOTOR,
    D_SAG_RATE,
    D_THRUST,
    DIVERGED_NONFINITE,
    DIVERGED_RUNAWAY,
    STAT_COUNT,
    STAT_DTHRUST,
    STAT_MAX,
    STAT_SUMSQ,
    TEL_SIZE,
    ErrorSwitches,
    RefChunk,
    TrackingReference,
)
from sim.flight.engines._tables import ChunkTables, ideal_drone_constants

__all__ = ["run_chunk_numba"]


@nb.njit(inline="always", cache=True)
def _sig_scale(x0: float, x1: float, x2: float, r: float) -> float:
    """Factor ``||x||^(r-1)`` of ``sig(x, r)``, 0 at x = 0 (same branches as ``sim.flight.control._ismc.sig``)."""
    n = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    if not n > 0.0:
        return 0.0
    if r == 1.0:
        return 1.0
    if r == 0.5:
        return 1.0 / math.sqrt(n)
    # exp(log) is about twice as fast as libm pow here and equal to within a few ulp.
    return math.exp((r - 1.0) * math.log(n))


@nb.njit(inline="always", cache=True)
def _unit_scale(x0: float, x1: float, x2: float, eps: float) -> float:
    """Factor ``1/max(||x||, eps)``, 0 at x = 0 (``sim.flight.control._ismc.unit``)."""
    n = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
    if not n > 0.0:
        return 0.0
    return 1.0 / max(n, eps)


@nb.njit(inline="always", cache=True)
def _ismc_law(
    ex: float, ey: float, ez: float, edx: float, edy: float, edz: float, fx: float, fy: float, fz: float,
    ka: float, kb: float, ra: float, rb: float, e0x: float, e0y: float, e0z: float,
    ix: float, iy: float, iz: float, spx: float, spy: float, spz: float, gain: float, eps: float,
    eps_q: float,
) -> tuple[float, ...]:
    """One ISMC law, shared by position (spec 4) and attitude (spec 6); scalar form of ``sim.flight.control._ismc``.

    Args: error e and its rate ė (3 components each), the drift f, gains k_a, k_b and powers
    r_a, r_b of the nominal law, ė at the start, the integral of the nominal closed loop, the
    previous step's sliding variable, the switching gain and the switching law's boundary layers
    (on s and on s - s_prev).

    Returns:
        (u_n x, y, z: nominal control; s x, y, z: sliding variable; w x, y, z: rate of u_d).
    """
    sa = _sig_scale(ex, ey, ez, ra)
    sb = _sig_scale(edx, edy, edz, rb)
    unx = -ka * (ex * sa) - kb * (edx * sb) - fx
    uny = -ka * (ey * sa) - kb * (edy * sb) - fy
    unz = -ka * (ez * sa) - kb * (edz * sb) - fz
    sx = edx - e0x - ix
    sy = edy - e0y - iy
    sz = edz - e0z - iz
    us = _unit_scale(sx, sy, sz, eps)
    qx = sx - spx
    qy = sy - spy
    qz = sz - spz
    uq = _unit_scale(qx, qy, qz, eps_q)
    wx = -gain * (sx * us + 0.5 * (qx * uq))
    wy = -gain * (sy * us + 0.5 * (qy * uq))
    wz = -gain * (sz * us + 0.5 * (qz * uq))
    return unx, uny, unz, sx, sy, sz, wx, wy, wz


@nb.njit(inline="always", cache=True)
def _piece_state(coeffs: np.ndarray, i: int, p: int, a: int, u: float, inside: bool) -> tuple[float, float, float]:
    """Position, velocity, acceleration of axis ``a`` of drone i's piece p at local time u (Horner).

    The derivative coefficients are formed as ``Trajectories.evaluate`` forms them (k·c_k, then
    (k-1)·(k·c_k)), so both engines round alike; velocity and acceleration are 0 outside the show.
    """
    c0, c1, c2 = coeffs[i, p, a, 0], coeffs[i, p, a, 1], coeffs[i, p, a, 2]
    c3, c4, c5 = coeffs[i, p, a, 3], coeffs[i, p, a, 4], coeffs[i, p, a, 5]
    pos = ((((c5 * u + c4) * u + c3) * u + c2) * u + c1) * u + c0
    if not inside:
        return pos, 0.0, 0.0
    d5, d4, d3, d2 = 5.0 * c5, 4.0 * c4, 3.0 * c3, 2.0 * c2
    vel = (((d5 * u + d4) * u + d3) * u + d2) * u + c1
    acc = ((4.0 * d5 * u + 3.0 * d4) * u + 2.0 * d3) * u + d2
    return pos, vel, acc


@nb.njit(parallel=True, cache=True, error_model="numpy",
         fastmath={"nsz", "afn", "contract", "reassoc"})
def _kernel(
    state, ctrl, stats, dstep, dreason, breaks, coeffs, cursor0, times, offset, yaw, dist, step0, every,
    frames, tel, use_tel, prm, plt, gn, drag, dt, limit, drone, gnss, gnss_every, gnss_first, wtab, wind_k0,
    wind_dt, use_gnss, use_motor, use_drag, use_clock, est_kp, est_kv,
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
    wn, zeta = gn[10], gn[11]
    eps_p, eps_pq, eps_a, eps_aq, ki, ilim, izone = gn[12], gn[13], gn[14], gn[15], gn[16], gn[17], gn[18]
    uz_min, tan_tilt = gn[19], gn[20]
    # Reciprocals of the constants, hoisted: a multiply is ~5x cheaper than a divide.
    inv_ix, inv_iy, inv_iz = 1.0 / ix, 1.0 / iy, 1.0 / iz
    n_wind = wtab.shape[0]

    for i in nb.prange(n):
        px, py, pz = state[i, 0], state[i, 1], state[i, 2]
        vx, vy, vz = state[i, 3], state[i, 4], state[i, 5]
        ph, th, ps = state[i, 6], state[i, 7], state[i, 8]
        wx, wy, wz = state[i, 9], state[i, 10], state[i, 11]
        alive = dstep[i] < 0
        # This drone's true plant and error-model constants (engines._tables).
        pix, piy, piz = drone[i, D_IX], drone[i, D_IY], drone[i, D_IZ]
        inv_pix, inv_piy, inv_piz, inv_pm = 1.0 / pix, 1.0 / piy, 1.0 / piz, 1.0 / drone[i, D_MASS]
        thr0, sag, clk = drone[i, D_THRUST], drone[i, D_SAG_RATE], drone[i, D_CLOCK]
        mot, drg = drone[i, D_MOTOR], drone[i, D_DRAG]
        # Controller state in locals for the whole chunk (stored back below): keeps it in
        # registers instead of re-reading memory the compiler must assume aliased.
        e200, e201, e202 = ctrl[i, C_E2_0], ctrl[i, C_E2_0 + 1], ctrl[i, C_E2_0 + 2]
        ip0, ip1, ip2 = ctrl[i, C_IPOS], ctrl[i, C_IPOS + 1], ctrl[i, C_IPOS + 2]
        ud0, ud1, ud2 = ctrl[i, C_UD], ctrl[i, C_UD + 1], ctrl[i, C_UD + 2]
        sp0, sp1, sp2 = ctrl[i, C_SPREV], ctrl[i, C_SPREV + 1], ctrl[i, C_SPREV + 2]
        e400, e401, e402 = ctrl[i, C_E4_0], ctrl[i, C_E4_0 + 1], ctrl[i, C_E4_0 + 2]
        ia0, ia1, ia2 = ctrl[i, C_IATT], ctrl[i, C_IATT + 1], ctrl[i, C_IATT + 2]
        uda0, uda1, uda2 = ctrl[i, C_UDA], ctrl[i, C_UDA + 1], ctrl[i, C_UDA + 2]
        sap0, sap1, sap2 = ctrl[i, C_SAPREV], ctrl[i, C_SAPREV + 1], ctrl[i, C_SAPREV + 2]
        thc0, thc1, thc2 = ctrl[i, C_THC], ctrl[i, C_THC + 1], ctrl[i, C_THC + 2]
        thcd0, thcd1, thcd2 = ctrl[i, C_THC_DOT], ctrl[i, C_THC_DOT + 1], ctrl[i, C_THC_DOT + 2]
        last_thrust = ctrl[i, C_LAST_THRUST]
        ie0, ie1, ie2 = ctrl[i, C_IERR], ctrl[i, C_IERR + 1], ctrl[i, C_IERR + 2]
        ph0, ph1, ph2 = ctrl[i, C_PHAT], ctrl[i, C_PHAT + 1], ctrl[i, C_PHAT + 2]
        vh0, vh1, vh2 = ctrl[i, C_VHAT], ctrl[i, C_VHAT + 1], ctrl[i, C_VHAT + 2]
        in0, in1, in2 = ctrl[i, C_INNOV], ctrl[i, C_INNOV + 1], ctrl[i, C_INNOV + 2]
        ro1, ro2 = ctrl[i, C_ROTOR], ctrl[i, C_ROTOR + 1]
        ro3, ro4 = ctrl[i, C_ROTOR + 2], ctrl[i, C_ROTOR + 3]
        next_gnss = gnss_first
        gidx = 0
        curc = cursor0[i]
        ssum, smax = stats[i, STAT_SUMSQ], stats[i, STAT_MAX]
        sdth, scount = stats[i, STAT_DTHRUST], stats[i, STAT_COUNT]
        # Next frame step, advanced by a counter (an integer division per step costs ~5 %).
        next_rec = ((step0 + every - 1) // every) * every
        # This drone's own pieces: a cursor that only moves forward with time (steps are
        # increasing), so finding the piece costs one comparison per step, no search.
        cur = cursor0[i]
        t_first, t_last = breaks[i, 0], breaks[i, last_piece + 1]
        for j in range(steps):
            k = step0 + j
            rec = k == next_rec
            if rec:
                next_rec += every
                fr = k // every
                frames[fr, i, 0] = px
                frames[fr, i, 1] = py
                frames[fr, i, 2] = pz
            if not alive:
                continue

            # ---- reference: the drone's piece at t (Trajectories.evaluate: clamped to the
            # show, at rest outside it, the later piece at a break), plus the shared offset
            t = times[j]
            inside = t >= t_first and t <= t_last
            tc = min(max(t, t_first), t_last)
            while cur < last_piece and breaks[i, cur + 1] <= tc:
                cur += 1
            # (Backwards only if the chunk's starting search, done in a row-offset key
            # space, rounded past a break: then the piece is still this drone's exact one.)
            while cur > 0 and breaks[i, cur] > tc:
                cur -= 1
            u = tc - breaks[i, cur]
            prx, vrx, arx = _piece_state(coeffs, i, cur, 0, u, inside)
            pry, vry, ary = _piece_state(coeffs, i, cur, 1, u, inside)
            prz, vrz, arz = _piece_state(coeffs, i, cur, 2, u, inside)
            prx += offset[j, 0]
            pry += offset[j, 1]
            prz += offset[j, 2]
            vrx += offset[j, 3]
            vry += offset[j, 4]
            vrz += offset[j, 5]
            arx += offset[j, 6]
            ary += offset[j, 7]
            arz += offset[j, 8]

            # The plan at the true time: the flown error is measured against it.
            qx, qy, qz = px - prx, py - pry, pz - prz
            err = math.sqrt(qx * qx + qy * qy + qz * qz)
            if not err <= limit:  # NaN (a non-finite reference) or a runaway drone
                dstep[i] = k
                dreason[i] = DIVERGED_RUNAWAY if err > limit else DIVERGED_NONFINITE
                alive = False
                continue
            if use_clock:  # the controller flies its own clock t + δ (the shared offset stays at t)
                tcl = t + clk
                inside_c = tcl >= t_first and tcl <= t_last
                tcc = min(max(tcl, t_first), t_last)
                while curc < last_piece and breaks[i, curc + 1] <= tcc:
                    curc += 1
                while curc > 0 and breaks[i, curc] > tcc:
                    curc -= 1
                uc = tcc - breaks[i, curc]
                prx, vrx, arx = _piece_state(coeffs, i, curc, 0, uc, inside_c)
                pry, vry, ary = _piece_state(coeffs, i, curc, 1, uc, inside_c)
                prz, vrz, arz = _piece_state(coeffs, i, curc, 2, uc, inside_c)
                prx += offset[j, 0]
                pry += offset[j, 1]
                prz += offset[j, 2]
                vrx += offset[j, 3]
                vry += offset[j, 4]
                vrz += offset[j, 5]
                arx += offset[j, 6]
                ary += offset[j, 7]
                arz += offset[j, 8]
            # What the controller sees: the GNSS/accelerometer estimate, or the true state.
            if use_gnss:
                if k == next_gnss:  # a GNSS epoch: the innovation z - p̂, held until the next
                    in0 = (px + gnss[gidx, i, 0]) - ph0
                    in1 = (py + gnss[gidx, i, 1]) - ph1
                    in2 = (pz + gnss[gidx, i, 2]) - ph2
                    next_gnss += gnss_every
                    gidx += 1
                cpx, cpy, cpz, cvx, cvy, cvz = ph0, ph1, ph2, vh0, vh1, vh2
            else:
                cpx, cpy, cpz, cvx, cvy, cvz = px, py, pz, vx, vy, vz
            e1x, e1y, e1z = cpx - prx, cpy - pry, cpz - prz

            # ---- position ISMC (spec 4)
            e2x, e2y, e2z = cvx - vrx, cvy - vry, cvz - vrz
            fx, fy, fz = -arx, -ary, -arz - g
            unx, uny, unz, sx, sy, sz, wpx, wpy, wpz = _ismc_law(
                e1x, e1y, e1z, e2x, e2y, e2z, fx, fy, fz, k1, k2, r1, r2,
                e200, e201, e202, ip0, ip1, ip2, sp0, sp1, sp2, alpha, eps_p, eps_pq,
            )
            ux = unx + ud0
            uy = uny + ud1
            uz = unz + ud2
            ux = ux - ki * ie0  # the PID baseline's integral (0 for the ISMC)
            uy = uy - ki * ie1
            uz = uz - ki * ie2
            # Thrust floor and tilt limit (inactive in normal tracking; see PositionGains).
            wux, wuy, wuz = ux, uy, uz
            limited = uz < uz_min
            if limited:
                uz = uz_min
            hxy = math.sqrt(ux * ux + uy * uy)
            if hxy > uz * tan_tilt:
                limited = True
                sc = uz * tan_tilt / hxy
                ux = ux * sc
                uy = uy * sc
            # While limited, s integrates the nominal law minus what the limiter took away.
            inx, iny, inz = unx, uny, unz
            if limited:
                inx = unx + (ux - wux)
                iny = uny + (uy - wuy)
                inz = unz + (uz - wuz)

            sph, cph = math.sin(ph), math.cos(ph)
            sth, cth = math.sin(th), math.cos(th)
            sps, cps = math.sin(ps), math.cos(ps)
            zbx = cph * sth * cps + sph * sps
            zby = cph * sth * sps - sph * cps
            zbz = cph * cth
            thrust_cmd = m * (ux * zbx + uy * zby + uz * zbz)

            # ---- attitude resolution (spec 5) and command filter
            ysin, ycos = yaw[j, 1], yaw[j, 2]
            un = math.sqrt(ux * ux + uy * uy + uz * uz)
            ratio = (ux * ysin - uy * ycos) / un if un > 0.0 else 0.0
            ratio = min(max(ratio, -1.0), 1.0)
            rph = math.asin(ratio)
            rth = math.atan2(ux * ycos + uy * ysin, uz)
            rps = yaw[j, 0]
            cx, cy, cz = thc0, thc1, thc2
            cdx, cdy, cdz = thcd0, thcd1, thcd2
            cddx = wn * wn * (rph - cx) - 2.0 * zeta * wn * cdx
            cddy = wn * wn * (rth - cy) - 2.0 * zeta * wn * cdy
            cddz = wn * wn * (rps - cz) - 2.0 * zeta * wn * cdz

            # ---- attitude ISMC (spec 6)
            # One division for every 1/cos θ term (W, Ẇ): divisions dominate the arithmetic.
            icth = 1.0 / cth
            tth = sth * icth
            w01, w02 = sph * tth, cph * tth
            w11, w12 = cph, -sph
            w21, w22 = sph * icth, cph * icth
            edx = wx + w01 * wy + w02 * wz
            edy = w11 * wy + w12 * wz
            edz = w21 * wy + w22 * wz
            e3x, e3y, e3z = ph - cx, th - cy, ps - cz
            e4x, e4y, e4z = edx - cdx, edy - cdy, edz - cdz
            gax = (wy * (wz * iz) - wz * (wy * iy)) * inv_ix
            gay = (wz * (wx * ix) - wx * (wz * iz)) * inv_iy
            gaz = (wx * (wy * iy) - wy * (wx * ix)) * inv_iz
            # Ẇ Ω (see sim.flight._quadrotor.w_dot_omega), with Θ̇ = (edx, edy) for φ̇, θ̇.
            sec2 = icth * icth
            wd0 = (cph * tth * edx + sph * sec2 * edy) * wy + (-sph * tth * edx + cph * sec2 * edy) * wz
            wd1 = -sph * edx * wy - cph * edx * wz
            wd2 = (w22 * edx + sph * sth * sec2 * edy) * wy + (
                -w21 * edx + cph * sth * sec2 * edy
            ) * wz
            fax = -(gax + w01 * gay + w02 * gaz) + wd0 - cddx
            fay = -(w11 * gay + w12 * gaz) + wd1 - cddy
            faz = -(w21 * gay + w22 * gaz) + wd2 - cddz
            unax, unay, unaz, sax, say, saz, wax, way, waz = _ismc_law(
                e3x, e3y, e3z, e4x, e4y, e4z, fax, fay, faz, k3, k4, r3, r4,
                e400, e401, e402, ia0, ia1, ia2, sap0, sap1, sap2, beta_g, eps_a, eps_aq,
            )
            uax = unax + uda0
            uay = unay + uda1
            uaz = unaz + uda2
            # τ = I W⁻¹ u_a
            tcx = ix * (uax - sth * uaz)
            tcy = iy * (cph * uay + sph * cth * uaz)
            tcz = iz * (-sph * uay + cph * cth * uaz)

            # ---- rotors ("+" mixer of sim.flight._quadrotor), saturation, what acts
            # Divisions kept here: the same rounding as the reference mixer is what makes the
            # hover thrust come back as exactly m·g (hover is held bit-exactly).
            base = thrust_cmd / (4.0 * kf)
            roll = tcx / (2.0 * arm * kf)
            pitch = tcy / (2.0 * arm * kf)
            yw = tcz / (4.0 * km)
            o1 = base - pitch + yw
            o2 = base + roll - yw
            o3 = base + pitch + yw
            o4 = base - roll - yw
            clipped = (o1 < 0.0 or o1 > wmax2 or o2 < 0.0 or o2 > wmax2
                       or o3 < 0.0 or o3 > wmax2 or o4 < 0.0 or o4 > wmax2)
            sat = limited or clipped
            o1 = min(max(o1, 0.0), wmax2)
            o2 = min(max(o2, 0.0), wmax2)
            o3 = min(max(o3, 0.0), wmax2)
            o4 = min(max(o4, 0.0), wmax2)
            if use_motor:  # first-order lag of the squared rotor speeds toward the command
                o1 = ro1 + mot * (o1 - ro1)
                o2 = ro2 + mot * (o2 - ro2)
                o3 = ro3 + mot * (o3 - ro3)
                o4 = ro4 + mot * (o4 - ro4)
            # Thrust gain of this drone's rotors, falling with its battery (1 when ideal).
            rg = thr0 * (1.0 - sag * t)
            thrust = kf * (o1 + o2 + o3 + o4) * rg
            tqx = arm * kf * (o2 - o4) * rg
            tqy = arm * kf * (o3 - o1) * rg
            tqz = km * (o1 - o2 + o3 - o4) * rg

            # ---- plant, semi-implicit Euler with the inputs held
            tpm = thrust * inv_pm
            ax = tpm * zbx + dist[j, 0] + drag * (dist[j, 3] - vx)
            ay = tpm * zby + dist[j, 1] + drag * (dist[j, 4] - vy)
            az = tpm * zbz + dist[j, 2] + drag * (dist[j, 5] - vz)
            if use_drag:  # quadratic drag on the air-relative velocity (wind interpolated on its grid)
                xw = t / wind_dt
                iw = min(max(int(math.floor(xw)) - wind_k0, 0), n_wind - 2)
                fw = xw - (wind_k0 + iw)
                rlx = vx - (wtab[iw, i, 0] + fw * (wtab[iw + 1, i, 0] - wtab[iw, i, 0]))
                rly = vy - (wtab[iw, i, 1] + fw * (wtab[iw + 1, i, 1] - wtab[iw, i, 1]))
                rlz = vz - (wtab[iw, i, 2] + fw * (wtab[iw + 1, i, 2] - wtab[iw, i, 2]))
                dsp = drg * math.sqrt(rlx * rlx + rly * rly + rlz * rlz)
                ax -= dsp * rlx
                ay -= dsp * rly
                az -= dsp * rlz
            az -= pg
            d2x, d2y, d2z = dist[j, 6], dist[j, 7], dist[j, 8]
            odx = (tqx - (wy * (wz * piz) - wz * (wy * piy))) * inv_pix + (d2x - sth * d2z)
            ody = (tqy - (wz * (wx * pix) - wx * (wz * piz))) * inv_piy + (cph * d2y + sph * cth * d2z)
            odz = (tqz - (wx * (wy * piy) - wy * (wx * pix))) * inv_piz + (-sph * d2y + cph * cth * d2z)
            nvx, nvy, nvz = vx + dt * ax, vy + dt * ay, vz + dt * az
            npx, npy, npz = px + dt * nvx, py + dt * nvy, pz + dt * nvz
            nwx, nwy, nwz = wx + dt * odx, wy + dt * ody, wz + dt * odz
            nph = ph + dt * (nwx + w01 * nwy + w02 * nwz)
            nth = th + dt * (w11 * nwy + w12 * nwz)
            nps = ps + dt * (w21 * nwy + w22 * nwz)
            if use_gnss:  # estimator: accelerometer prediction plus the held innovation
                nvh0 = cvx + dt * (ax + est_kv * in0)
                nvh1 = cvy + dt * (ay + est_kv * in1)
                nvh2 = cvz + dt * (az + est_kv * in2)
                nph0 = cpx + dt * (nvh0 + est_kp * in0)
                nph1 = cpy + dt * (nvh1 + est_kp * in1)
                nph2 = cpz + dt * (nvh2 + est_kp * in2)
            else:
                nvh0, nvh1, nvh2, nph0, nph1, nph2 = nvx, nvy, nvz, npx, npy, npz

            # ---- controller state candidates
            ipx = ip0 + dt * (inx + fx)
            ipy = ip1 + dt * (iny + fy)
            ipz = ip2 + dt * (inz + fz)
            iax = ia0 + dt * (unax + fax)
            iay = ia1 + dt * (unay + fay)
            iaz = ia2 + dt * (unaz + faz)
            ncdx, ncdy, ncdz = cdx + dt * cddx, cdy + dt * cddy, cdz + dt * cddz
            ncx, ncy, ncz = cx + dt * ncdx, cy + dt * ncdy, cz + dt * ncdz
            # Anti-windup (as the numpy step): the position u_d and the PID integral frozen
            # while the command is limited or a rotor clips, the attitude u_d only while a
            # rotor clips.
            if sat:
                udx, udy, udz = ud0, ud1, ud2
                nie0, nie1, nie2 = ie0, ie1, ie2
            else:
                nie0 = min(max(ie0 + dt * e1x, -ilim), ilim) if abs(e1x) < izone else ie0
                nie1 = min(max(ie1 + dt * e1y, -ilim), ilim) if abs(e1y) < izone else ie1
                nie2 = min(max(ie2 + dt * e1z, -ilim), ilim) if abs(e1z) < izone else ie2
                udx = ud0 + dt * wpx
                udy = ud1 + dt * wpy
                udz = ud2 + dt * wpz
            if clipped:
                uadx, uady, uadz = uda0, uda1, uda2
            else:
                uadx = uda0 + dt * wax
                uady = uda1 + dt * way
                uadz = uda2 + dt * waz

            if use_tel and rec:
                fr = k // every
                tel[fr, i, 0], tel[fr, i, 1], tel[fr, i, 2] = qx, qy, qz
                tel[fr, i, 3], tel[fr, i, 4], tel[fr, i, 5] = e3x, e3y, e3z
                tel[fr, i, 6], tel[fr, i, 7], tel[fr, i, 8] = ph - rph, th - rth, ps - rps
                tel[fr, i, 9], tel[fr, i, 10], tel[fr, i, 11], tel[fr, i, 12] = thrust, tqx, tqy, tqz
                tel[fr, i, 13] = 1.0 if sat else 0.0

            # A step that is not finite everywhere is not committed (the drone stops here).
            # (Any NaN or inf makes the sum non-finite; independent partial sums keep the
            # dependency chain short.)
            check = (((npx + npy + npz) + (nvx + nvy + nvz)) + ((nph + nth + nps) + (nwx + nwy + nwz))
                     + ((ipx + ipy + ipz) + (iax + iay + iaz)) + ((udx + udy + udz) + (uadx + uady + uadz))
                     + ((ncx + ncy + ncz) + (ncdx + ncdy + ncdz)) + ((sx + sy + sz) + (sax + say + saz))
                     + thrust + ((nph0 + nph1 + nph2) + (nvh0 + nvh1 + nvh2)) + (nie0 + nie1 + nie2))
            if not math.isfinite(check):
                dstep[i] = k
                dreason[i] = DIVERGED_NONFINITE
                alive = False
                continue

            ssum += err * err
            smax = max(smax, err)
            sdth = max(sdth, abs(thrust - last_thrust))
            scount += 1.0

            ip0, ip1, ip2 = ipx, ipy, ipz
            ud0, ud1, ud2 = udx, udy, udz
            sp0, sp1, sp2 = sx, sy, sz
            ia0, ia1, ia2 = iax, iay, iaz
            uda0, uda1, uda2 = uadx, uady, uadz
            sap0, sap1, sap2 = sax, say, saz
            thc0, thc1, thc2 = ncx, ncy, ncz
            thcd0, thcd1, thcd2 = ncdx, ncdy, ncdz
            last_thrust = thrust
            ie0, ie1, ie2 = nie0, nie1, nie2
            ph0, ph1, ph2, vh0, vh1, vh2 = nph0, nph1, nph2, nvh0, nvh1, nvh2
            ro1, ro2, ro3, ro4 = o1, o2, o3, o4
            px, py, pz, vx, vy, vz = npx, npy, npz, nvx, nvy, nvz
            ph, th, ps, wx, wy, wz = nph, nth, nps, nwx, nwy, nwz

        ctrl[i, C_IPOS], ctrl[i, C_IPOS + 1], ctrl[i, C_IPOS + 2] = ip0, ip1, ip2
        ctrl[i, C_UD], ctrl[i, C_UD + 1], ctrl[i, C_UD + 2] = ud0, ud1, ud2
        ctrl[i, C_SPREV], ctrl[i, C_SPREV + 1], ctrl[i, C_SPREV + 2] = sp0, sp1, sp2
        ctrl[i, C_IATT], ctrl[i, C_IATT + 1], ctrl[i, C_IATT + 2] = ia0, ia1, ia2
        ctrl[i, C_UDA], ctrl[i, C_UDA + 1], ctrl[i, C_UDA + 2] = uda0, uda1, uda2
        ctrl[i, C_SAPREV], ctrl[i, C_SAPREV + 1], ctrl[i, C_SAPREV + 2] = sap0, sap1, sap2
        ctrl[i, C_THC], ctrl[i, C_THC + 1], ctrl[i, C_THC + 2] = thc0, thc1, thc2
        ctrl[i, C_THC_DOT], ctrl[i, C_THC_DOT + 1], ctrl[i, C_THC_DOT + 2] = thcd0, thcd1, thcd2
        ctrl[i, C_LAST_THRUST] = last_thrust
        ctrl[i, C_IERR], ctrl[i, C_IERR + 1], ctrl[i, C_IERR + 2] = ie0, ie1, ie2
        ctrl[i, C_PHAT], ctrl[i, C_PHAT + 1], ctrl[i, C_PHAT + 2] = ph0, ph1, ph2
        ctrl[i, C_VHAT], ctrl[i, C_VHAT + 1], ctrl[i, C_VHAT + 2] = vh0, vh1, vh2
        ctrl[i, C_INNOV], ctrl[i, C_INNOV + 1], ctrl[i, C_INNOV + 2] = in0, in1, in2
        ctrl[i, C_ROTOR], ctrl[i, C_ROTOR + 1], ctrl[i, C_ROTOR + 2], ctrl[i, C_ROTOR + 3] = ro1, ro2, ro3, ro4
        stats[i, STAT_SUMSQ], stats[i, STAT_MAX] = ssum, smax
        stats[i, STAT_DTHRUST], stats[i, STAT_COUNT] = sdth, scount
        state[i, 0], state[i, 1], state[i, 2] = px, py, pz
        state[i, 3], state[i, 4], state[i, 5] = vx, vy, vz
        state[i, 6], state[i, 7], state[i, 8] = ph, th, ps
        state[i, 9], state[i, 10], state[i, 11] = wx, wy, wz


def run_chunk_numba(
    state: np.ndarray, ctrl: np.ndarray, stats: np.ndarray, dstep: np.ndarray,
    dreason: np.ndarray, *, ref: TrackingReference, chunk: RefChunk, dist: np.ndarray,
    step0: int, times: np.ndarray, every: int, frames: np.ndarray, tel: np.ndarray | None,
    opts: dict[str, Any], tables: ChunkTables | None = None,
) -> None:
    """Advance ``len(times)`` steps in place with the fused kernel (same contract as the numpy chunk).

    Args:
        state: ``(N, 12)`` plant states, updated in place.
        ctrl: ``(N, CTRL_SIZE)`` controller states, updated in place.
        stats: ``(N, STATS_SIZE)`` running statistics, updated in place.
        dstep: ``(N,)`` divergence step (-1 while flying), updated in place.
        dreason: ``(N,)`` divergence reason code, updated in place.
        ref: The drones' reference (their polynomial pieces, m).
        chunk: The shared reference tables at ``times``.
        dist: ``(T, 9)`` disturbance signals at ``times``.
        step0: Index of the first step of the chunk.
        times: ``(T,)`` step times (s).
        every: Frame decimation (steps per output frame).
        frames: ``(F, N, 3)`` output positions (m), written at frame steps.
        tel: ``(F, N, TEL_SIZE)`` telemetry or None.
        opts: ``params``, ``plant``, ``gains``, ``disturbance``, ``dt_s``,
            ``divergence_limit_m``, optionally ``drone`` and ``switches``, as in the numpy engine.
        tables: The chunk's GNSS and wind tables (None: ideal).
    """
    sw: ErrorSwitches = opts.get("switches") or ErrorSwitches()
    drone = opts.get("drone")
    if drone is None:
        drone = ideal_drone_constants(opts["plant"], state.shape[0])
    if tables is None:
        tables = ChunkTables(gnss=np.zeros((0, state.shape[0], 3)), gnss_every=1, gnss_first=0,
                             wind=np.zeros((0, state.shape[0], 3)), wind_k0=0, wind_dt_s=1.0)
    if (sw.gnss and tables.gnss.shape[0] == 0 and times.size
            and (step0 + times.size - 1) // tables.gnss_every >= -(-step0 // tables.gnss_every)):
        raise ValueError("the GNSS error model needs the chunk's GNSS table")
    if sw.drag and tables.wind.shape[0] < 2:
        raise ValueError("quadratic drag needs the chunk's wind table")
    use_tel = tel is not None
    tel_arr = tel if use_tel else np.zeros((0, 0, TEL_SIZE))
    motion = ref.motion
    # Each drone's piece at the chunk's first step (one search per chunk); the kernel
    # advances from there.
    cursor0 = np.ascontiguousarray(motion.piece_index(chunk.times[:1])[0], dtype=np.int64)
    _kernel(
        state, ctrl, stats, dstep, dreason, np.ascontiguousarray(motion.breaks_s, dtype=np.float64),
        np.ascontiguousarray(motion.coeffs_m, dtype=np.float64), cursor0, chunk.times, chunk.offset,
        chunk.yaw, dist, int(step0), int(every),
        frames, tel_arr, use_tel, opts["params"].as_vector(), opts["plant"].as_vector(),
        opts["gains"].as_vector(float(opts["dt_s"])), float(opts["disturbance"].drag_per_s), float(opts["dt_s"]),
        float(opts["divergence_limit_m"]), np.ascontiguousarray(drone, dtype=np.float64),
        np.ascontiguousarray(tables.gnss, dtype=np.float64), int(tables.gnss_every), int(tables.gnss_first),
        np.ascontiguousarray(tables.wind, dtype=np.float64), int(tables.wind_k0), float(tables.wind_dt_s),
        bool(sw.gnss), bool(sw.motor), bool(sw.drag), bool(sw.clock), float(sw.est_kp), float(sw.est_kv),
    )
