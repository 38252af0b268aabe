"""The wind mode sum as it was before the Cephes polynomials (``sim.flight._windsum`` at e49d0a2): the
baseline of ``bench_tables.test_bench_wind_mode_sum_against_the_taylor_form``.

The argument reduced to ``[-π, π]`` by one multiple of 2π, cos and sin by their Taylor series to r²⁴
and r²⁵ (Horner in r²), no FMA contraction, two modes per pass over a block of 1,024 points; one
thread. Kept verbatim (the loop and its copies), so that the bench compares like with like.
"""

from __future__ import annotations

import math

import numba
import numpy as np

_TWO_PI = 2.0 * math.pi
_INV_TWO_PI = 1.0 / _TWO_PI
# Taylor coefficients of cos in r²: (-1)^k / (2k)!, k = 12 .. 0 (Horner order).
_COS_COEFFS = tuple((-1.0) ** k / math.factorial(2 * k) for k in range(12, -1, -1))
# and of sin r / r in r²: (-1)^k / (2k+1)!, k = 12 .. 0 (truncation π²⁷/27! = 3e-15).
_SIN_COEFFS = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(12, -1, -1))
_BLOCK = 1024


@numba.njit(inline="always", cache=True)
def _cos_sin(a: float) -> tuple[float, float]:  # pragma: no cover - compiled
    """``(cos a, sin a)`` from one argument reduction (the cosine's bits are those of ``_cos``)."""
    r = a - _TWO_PI * float(np.floor(a * _INV_TWO_PI + 0.5))
    r2 = r * r
    c0, c1, c2, c3, c4, c5, c6, c7, c8, c9, c10, c11, c12 = _COS_COEFFS
    c = ((((((((((((c0 * r2 + c1) * r2 + c2) * r2 + c3) * r2 + c4) * r2 + c5) * r2 + c6) * r2 + c7) * r2
                + c8) * r2 + c9) * r2 + c10) * r2 + c11) * r2 + c12)
    s0, s1, s2, s3, s4, s5, s6, s7, s8, s9, s10, s11, s12 = _SIN_COEFFS
    s = r * ((((((((((((s0 * r2 + s1) * r2 + s2) * r2 + s3) * r2 + s4) * r2 + s5) * r2 + s6) * r2 + s7) * r2
                     + s8) * r2 + s9) * r2 + s10) * r2 + s11) * r2 + s12)
    return c, s


@numba.njit(cache=True, nogil=True)
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
