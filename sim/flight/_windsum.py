"""The turbulence field's Fourier-mode sum, compiled and vectorised: the error models' wind at 1,000s of drones.

The wind tables of :mod:`sim.flight.engines._tables` hold the wind and its spatial Jacobian
(:func:`turbulence_sum_and_jacobian`: a sine and nine multiply-adds more per mode, 2-2.7x the
time of the wind alone) at every drone's planned position on a 10 Hz grid, evaluated per run
(the field is seeded per run): for a 1,000-drone, 10-minute show that is 6e6 points times
M = 128 modes, 7.7e8 cosines per run, 11 % of a Monte-Carlo run with numpy (issue 20). Here
the modes are summed in a loop over points that LLVM vectorises (a polynomial cosine instead
of a libm call, which would keep the loop scalar), in blocks of 1,024 points.

Threads (issue 20: on one thread the tables were ~30 % of a 1-s, 4,000-drone flight's wall
time). The Jacobian sum's blocks are shared by plain Python threads
(:func:`sim.flight._threads.share_blocks`; the compiled block loop releases the GIL), each
block the same arithmetic whichever thread does it, so the same bits. Tried and measured
(44,000 points, 127-128 modes, alternating in one process, medians of 7-9 runs):

* a ``prange`` over the blocks with the sum inline: 3.5x *slower* than one thread on an idle
  machine (numba's parfor body was not vectorised like the plain loop), and a parallel region
  cost ~50 ms to start at a load of 16 (55 ms for 1,050 points against 1.2 ms in one thread);
* a ``prange`` over the blocks, or over exactly ``numba.get_num_threads()`` halves, whose body
  calls a separately compiled block function: vectorised again (CPU 1.1-1.25x the one-thread
  loop's), but it is numba's parallel machinery, a second user of the kernel's OpenMP pool, and
  it cannot run the GNSS draws beside it; plain threads do both, at the same CPU;
* the block function with the block range as arguments, indexing the whole arrays at
  ``b * 1024 + q``: 5-6x slower (the wrap-around check of a possibly negative index stayed in
  the loop, which then did not vectorise); slicing the block's inputs first fixed it;
* two modes per pass over a block (each point's additions still in mode order): 1.05-1.09x
  less CPU (half the loads and stores of the thirteen accumulators); kept. Three to eight modes
  per pass: another 1.03-1.09x (11 alternating runs, ranges 0.86-1.21), not kept (a longer loop
  for under 1 % of a flight). All modes, or four, in an inner loop over modes inside the loop
  over points with register accumulators: 6-7x slower (not vectorised);
* blocks of 128-1,024 points: within ±3 % (the L1 cache is not what limits the loop; its
  ~95 flops per point and mode, with the polynomials' dependent chains, run at ~280 M
  point-modes/s per core).

On the loaded shared machine (load 3-8 on 2 cores) the second thread rarely finds a core free,
so the wall-clock gain there is mostly the CPU cut; the split pays when a core is idle.

Cosine and sine (issue 20 item 6: the tables were 17 % of a 1-s, 4,000-drone gusty-rtk flight's wall
time, 22 of 132 ms): the argument is reduced to ``r ∈ [-π/4, π/4]`` by the nearest multiple n of
π/2 (Cody and Waite's two-part π/2, fdlibm's constants: ``n·π/2`` exact for ``|n| < 2^20``), ``cos r``
and ``sin r`` are Cephes' minimax polynomials (Moshier 1989; degree 14 and 13, within 1.2e-16 of
libm's on the interval), and the quadrant n mod 4 swaps and negates them by selects. FMA
contraction is on (``fastmath={"contract"}`` only: no reassociation, so the additions keep their
order). Both functions are within 4.5e-16 of libm's for arguments up to 2e4 rad (tested); the sums
differ from the formula with libm's cosines by the argument's own rounding (a few ulp of its terms;
``tests/test_flight_table_threads.py``). Measured against the previous form (the Taylor series to
``r²⁴`` on ``[-π, π]``, no contraction; kept as ``benchmarks/_windsum_taylor.py``), 44,000 points x
128 modes (4,000 drones x 11 rows), one thread, alternating in one process: **1.60x** less CPU
(median of 9 pairs, 1.41-1.61, load ~10; ``pytest -m slow benchmarks/bench_tables.py -k taylor -s``),
466 M point-modes per CPU second; 1.51x (1.30-1.52) in an earlier run of 7 at load 2-3, 1.52x on
two threads. The order of the
additions per point is fixed (mode by mode), so a point's value does not depend on the other
points, or the block it falls in.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from sim.flight._threads import share_blocks

__all__ = ["turbulence_sum", "turbulence_sum_and_jacobian"]

# Cody and Waite's two-part π/2 (fdlibm's ``pio2_1``, its first 33 bits, and ``pio2_1t`` = π/2 - pio2_1):
# n·_PIO2_HI is exact for |n| < 2^20 (|argument| < 1.6e6 rad), so the reduced argument is good to ~1e-22.
_TWO_OVER_PI = 2.0 / math.pi
_PIO2_HI = 1.57079632673412561417e+00
_PIO2_LO = 6.07710050650619224932e-11
# Cephes' sin.c minimax coefficients on [-π/4, π/4] (Moshier 1989): sin r = r + r³ S(r²), cos r = 1 - r²/2 + r⁴ C(r²),
# within 1.2e-16 of libm's there (Horner in r²).
_SIN_COEFFS = (1.58962301576546568060e-10, -2.50507477628578072866e-8, 2.75573136213857245213e-6,
               -1.98412698295895385996e-4, 8.33333333332211858878e-3, -1.66666666666666307295e-1)
_COS_COEFFS = (-1.13585365213876817300e-11, 2.08757008419747316778e-9, -2.75573141792967388112e-7,
               2.48015872888517045348e-5, -1.38888888888730564116e-3, 4.16666666666665929218e-2)
_BLOCK = 1024


@numba.njit(inline="always", cache=True)
def _cos_sin(a: float) -> tuple[float, float]:  # pragma: no cover - compiled
    """``(cos a, sin a)``: the quadrant n = round(a / (π/2)), r = a - n π/2 in [-π/4, π/4], both polynomials,
    then the quadrant's swap and signs (selects: the loop stays branch-free and vectorised)."""
    n = float(np.floor(a * _TWO_OVER_PI + 0.5))
    r = (a - n * _PIO2_HI) - n * _PIO2_LO
    z = r * r
    s0, s1, s2, s3, s4, s5 = _SIN_COEFFS
    c0, c1, c2, c3, c4, c5 = _COS_COEFFS
    sr = r + (r * z) * (((((s0 * z + s1) * z + s2) * z + s3) * z + s4) * z + s5)
    cr = (1.0 - 0.5 * z) + (z * z) * (((((c0 * z + c1) * z + c2) * z + c3) * z + c4) * z + c5)
    q = n - 4.0 * float(np.floor(n * 0.25))  # n mod 4 in {0, 1, 2, 3}
    odd = (q == 1.0) | (q == 3.0)  # cos(r + π/2) = -sin r, sin(r + π/2) = cos r
    c = sr if odd else cr
    s = cr if odd else sr
    c = -c if (q == 1.0) | (q == 2.0) else c
    s = -s if q >= 2.0 else s
    return c, s


@numba.njit(inline="always", cache=True)
def _cos(a: float) -> float:  # pragma: no cover - compiled
    """``cos a`` (the bits of :func:`_cos_sin`'s; LLVM drops the unused sine)."""
    return _cos_sin(a)[0]


@numba.njit(cache=True, nogil=True, fastmath={"contract"})
def turbulence_sum(
    out: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray, t: np.ndarray, k: np.ndarray,
    amp: np.ndarray, omega: np.ndarray, phase: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """``out[p] += Σ_m amp[m] cos(k[m]·(x, y, z)[p] + ω[m] t[p] + φ[m])`` for every point p, in place.

    Args:
        out: ``(P, 3)`` wind (m/s), added to.
        x, y, z: ``(P,)`` the advected point coordinates (m).
        t: ``(P,)`` times (s).
        k: ``(M, 3)`` wave vectors (rad/m).
        amp: ``(M, 3)`` mode amplitudes (m/s).
        omega: ``(M,)`` temporal drift (rad/s).
        phase: ``(M,)`` phases (rad).
    """
    n = x.shape[0]
    for b in range((n + _BLOCK - 1) // _BLOCK):
        p0 = b * _BLOCK
        p1 = min(p0 + _BLOCK, n)
        o0 = out[p0:p1, 0].copy()
        o1 = out[p0:p1, 1].copy()
        o2 = out[p0:p1, 2].copy()
        for m in range(k.shape[0]):
            kx, ky, kz, w, ph = k[m, 0], k[m, 1], k[m, 2], omega[m], phase[m]
            a0, a1, a2 = amp[m, 0], amp[m, 1], amp[m, 2]
            for q in range(p1 - p0):
                p = p0 + q
                c = _cos(kx * x[p] + ky * y[p] + kz * z[p] + w * t[p] + ph)
                o0[q] += a0 * c
                o1[q] += a1 * c
                o2[q] += a2 * c
        out[p0:p1, 0] = o0
        out[p0:p1, 1] = o1
        out[p0:p1, 2] = o2


@numba.njit(cache=True, nogil=True, fastmath={"contract"})
def _sum_and_jacobian_blocks(
    out: np.ndarray, jac: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray, t: np.ndarray,
    k: np.ndarray, amp: np.ndarray, omega: np.ndarray, phase: np.ndarray, b0: int, b1: int,
) -> None:  # pragma: no cover - compiled
    """:func:`turbulence_sum_and_jacobian` over the point blocks ``b0 .. b1 - 1`` (``_BLOCK`` points each).

    The block's inputs are sliced before the loop over its points (indexing the whole arrays
    at ``b * _BLOCK + q`` did not vectorise: module docstring). Two modes per pass over the
    block (a last odd mode alone), each point's additions still in mode order, so the bits of
    one mode per pass.
    """
    n = x.shape[0]
    n_modes = k.shape[0]
    for b in range(b0, b1):
        p0 = b * _BLOCK
        p1 = min(p0 + _BLOCK, n)
        o0 = out[p0:p1, 0].copy()
        o1 = out[p0:p1, 1].copy()
        o2 = out[p0:p1, 2].copy()
        # One contiguous array per entry: the vectoriser needs to see that the nine do not alias.
        j0, j1, j2 = jac[p0:p1, 0].copy(), jac[p0:p1, 1].copy(), jac[p0:p1, 2].copy()
        j3, j4, j5 = jac[p0:p1, 3].copy(), jac[p0:p1, 4].copy(), jac[p0:p1, 5].copy()
        j6, j7, j8 = jac[p0:p1, 6].copy(), jac[p0:p1, 7].copy(), jac[p0:p1, 8].copy()
        xb, yb, zb, tb = x[p0:p1], y[p0:p1], z[p0:p1], t[p0:p1]
        m = 0
        while m < n_modes:
            kx, ky, kz, w, ph = k[m, 0], k[m, 1], k[m, 2], omega[m], phase[m]
            a0, a1, a2 = amp[m, 0], amp[m, 1], amp[m, 2]
            if m + 1 < n_modes:
                kx_, ky_, kz_, w_, ph_ = k[m + 1, 0], k[m + 1, 1], k[m + 1, 2], omega[m + 1], phase[m + 1]
                a0_, a1_, a2_ = amp[m + 1, 0], amp[m + 1, 1], amp[m + 1, 2]
                for q in range(p1 - p0):
                    px, py, pz, pt = xb[q], yb[q], zb[q], tb[q]
                    c, s = _cos_sin(kx * px + ky * py + kz * pz + w * pt + ph)
                    c_, s_ = _cos_sin(kx_ * px + ky_ * py + kz_ * pz + w_ * pt + ph_)
                    o0[q] = (o0[q] + a0 * c) + a0_ * c_
                    o1[q] = (o1[q] + a1 * c) + a1_ * c_
                    o2[q] = (o2[q] + a2 * c) + a2_ * c_
                    s0, s1, s2 = -a0 * s, -a1 * s, -a2 * s
                    r0, r1, r2 = -a0_ * s_, -a1_ * s_, -a2_ * s_
                    j0[q] = (j0[q] + s0 * kx) + r0 * kx_
                    j1[q] = (j1[q] + s0 * ky) + r0 * ky_
                    j2[q] = (j2[q] + s0 * kz) + r0 * kz_
                    j3[q] = (j3[q] + s1 * kx) + r1 * kx_
                    j4[q] = (j4[q] + s1 * ky) + r1 * ky_
                    j5[q] = (j5[q] + s1 * kz) + r1 * kz_
                    j6[q] = (j6[q] + s2 * kx) + r2 * kx_
                    j7[q] = (j7[q] + s2 * ky) + r2 * ky_
                    j8[q] = (j8[q] + s2 * kz) + r2 * kz_
                m += 2
            else:
                for q in range(p1 - p0):
                    c, s = _cos_sin(kx * xb[q] + ky * yb[q] + kz * zb[q] + w * tb[q] + ph)
                    o0[q] += a0 * c
                    o1[q] += a1 * c
                    o2[q] += a2 * c
                    s0, s1, s2 = -a0 * s, -a1 * s, -a2 * s
                    j0[q] += s0 * kx
                    j1[q] += s0 * ky
                    j2[q] += s0 * kz
                    j3[q] += s1 * kx
                    j4[q] += s1 * ky
                    j5[q] += s1 * kz
                    j6[q] += s2 * kx
                    j7[q] += s2 * ky
                    j8[q] += s2 * kz
                m += 1
        out[p0:p1, 0] = o0
        out[p0:p1, 1] = o1
        out[p0:p1, 2] = o2
        for e, col in enumerate((j0, j1, j2, j3, j4, j5, j6, j7, j8)):
            jac[p0:p1, e] = col


def turbulence_sum_and_jacobian(
    out: np.ndarray, jac: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray, t: np.ndarray,
    k: np.ndarray, amp: np.ndarray, omega: np.ndarray, phase: np.ndarray, *, threads: int = 1,
) -> None:
    """:func:`turbulence_sum` (the same bits in ``out``) plus the field's spatial Jacobian, in place.

    The derivative of a mode is closed-form: ``∂/∂x_j amp_i cos(k·x + ...) = -amp_i k_j sin(k·x + ...)``,
    so ``jac[p, 3 i + j] += Σ_m -amp[m, i] k[m, j] sin(arg_m(p))`` (row-major ``∂u_i/∂x_j``, 1/s),
    from the same argument as the value (one reduction for both).

    Args:
        out: ``(P, 3)`` wind (m/s), added to.
        jac: ``(P, J)`` with ``J ≥ 9``: the Jacobian (1/s) is added to its first nine columns (the
            others are left alone, so the caller's wider table can be passed as it is).
        x, y, z, t, k, amp, omega, phase: as :func:`turbulence_sum`.
        threads: Threads to share the point blocks (module docstring); each point's sum is the
            same arithmetic whichever thread does its block, so the same bits for any count.
    """
    n = x.shape[0]
    if out.shape != (n, 3) or jac.ndim != 2 or jac.shape[0] != n or jac.shape[1] < 9:
        raise ValueError(f"turbulence_sum_and_jacobian: out {out.shape}, jac {jac.shape} for {n} points")
    blocks = (n + _BLOCK - 1) // _BLOCK
    args = (out, jac, x, y, z, t, k, amp, omega, phase)
    if threads <= 1 or blocks < 2:
        _sum_and_jacobian_blocks(*args, 0, blocks)
        return
    share_blocks(blocks, lambda b: _sum_and_jacobian_blocks(*args, b, b + 1), threads=threads)
