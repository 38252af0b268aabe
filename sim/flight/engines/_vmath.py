"""Vectorisable elementary functions for the lane kernel: sin/cos, atan2, asin, exp, log, pow.

Why: the pip llvmlite has no SVML, so a ``math.sin`` (a libm call) inside a loop stops
LLVM from vectorising that loop. These functions are plain arithmetic (no calls, no
data-dependent branches: every case is a select), so the loop that calls them
vectorises across drones (:mod:`sim.flight.engines._numba`).

Method (the classical one of Cody & Waite, *Software Manual for the Elementary
Functions*, 1980, and of fdlibm): reduce the argument exactly with a constant split in
a short high part and a low part, then evaluate a polynomial on the small reduced
range.

* ``sincos``: ``x = q·π/2 + d`` with π/2 in three parts (fdlibm's ``pio2_1/2/3``; each
  ``q·P`` exact for ``|q| < 2^20``), ``|d| <= π/4``; Taylor polynomials of sin (to d^17)
  and cos (to d^16), whose first omitted terms are below 2^-56 relative on that range;
  the quadrant ``q mod 4`` picks and signs them. Valid for ``|x| <= 1e5``.
* ``atan2``: fold to ``z = n/d = min/max`` of ``|y|, |x|`` in [0, 1], pick the nearest of
  ``c_k = tan(kπ/16)``, ``k = 0..4`` (comparing ``n`` with ``tan((2k+1)π/32)·d``: no division),
  and take ``t = (n - c_k d)/(d + c_k n)`` (one division; ``|t| <= tan(π/32)``), ``atan(t)``
  by Taylor to t^17 (first omitted term < 2^-57 relative); the angle ``mπ/16`` is added in
  two parts. ``asin(x) = atan2(x, sqrt((1-x)(1+x)))``.
* ``exp``: ``x = n ln 2 + r`` (fdlibm's ``ln2_hi/lo``), ``|r| <= ln2/2``, Taylor to r^13,
  scaled by 2^n built from its bits (as two factors, for n = 1024). Results below 2^-1022 flush to 0.
* ``log``: ``x = 2^e m``, ``m`` in [√½, √2) from the bits; ``log m = f - s(f - R(s²))``
  with ``f = m - 1``, ``s = f/(2 + f)`` (fdlibm's form), R the atanh series to s^20.

Polynomials by Estrin's scheme (Estrin 1960; Muller, *Elementary Functions*, 2016, §5.3)
instead of Horner's rule: the same terms, but pairs ``a + b·x`` combined by powers ``x², x⁴,
x⁸``, so a degree-n polynomial is a dependency chain of ~log₂ n multiply-adds instead of n.
Why: the lane kernel waits on its dependency chains, not on its arithmetic units (llvm-mca's
Ice Lake model, LLVM 14's nearest to Zen 4, on the step's machine code: 1,610 cycles per step
against 540 of port throughput; its longest dependency chain is ~640 cycles), and these
functions sit on that chain (``exp(h log(x·x))`` of the laws' ``sig``, the
attitude's asin/atan2). exp keeps Horner's last two steps ``1 + r(1 + r·Q)``, which carry its
rounding; the Estrin tails' rounding is scaled by ``r² <= 0.12`` (exp), ``s² <= 0.03`` (log),
``t² <= 0.01`` (atan). Measured: 1.023x and 1.035x the Horner kernel (medians of 8 and 6
alternating single-thread rounds in one process, 4,000 drones, gusty-rtk), within the same ulp
bounds (tests).

Accuracy (``tests/test_flight_vmath.py`` checks it against numpy over dense samples of each
input range): sin, cos, atan2, asin, exp, log within 4 ulp of numpy's result (measured: at
most 3 ulp), pow ``x^a = exp(a log x)`` within ``4 + 3|a log x|`` ulp (exp carries the
rounding of ``y = a log x`` as a relative error ~|y| 2^-52; the kernel's norms^(-2/7) have
|y| of a few units). Special values: NaN in, NaN out (the kernel's divergence check depends
on it); ``log(0) = -inf``, ``log(x<0)`` NaN, ``log(inf) = inf``, ``exp`` overflows to inf
and underflows to 0; ``atan2`` is for finite inputs (``atan2(0, 0) = 0``; the sign of a zero
``x`` is ignored).

Floating point: these functions are compiled with FMA contraction only. They must not
be compiled with ``reassoc`` (it would fold the split constants back together) and are
not ``inline='always'`` into the kernel for that reason: numba compiles them as separate
functions with their own flags, and LLVM then inlines them into the kernel's loop
keeping each instruction's flags. ``vasin`` and ``vpow`` are inlined into their caller at
numba's level instead (their only own arithmetic is a product and a square root): as
separate functions they would hold both callees inlined and grow past LLVM's inlining
threshold, and a call left in the loop stops the vectoriser.
"""

from __future__ import annotations

import math
import struct

import numba as nb
import numpy as np
from llvmlite import ir  # type: ignore[import-untyped]
from numba.core import types
from numba.extending import intrinsic

__all__ = ["vasin", "vatan2", "vexp", "vlog", "vpow", "vsincos"]

_FLAGS = {"contract"}


@intrinsic
def _f2i(typingctx, x):
    """The bits of a float64 as an int64 (a bitcast; vectorises, unlike a libm frexp)."""
    if x is not types.float64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


@intrinsic
def _i2f(typingctx, x):
    """The float64 whose bits are the int64 ``x``."""
    if x is not types.int64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(types.int64), codegen


# ---- sin / cos -------------------------------------------------------------------------
_TWO_OVER_PI = 0.63661977236758134308
# π/2 = P1 + P2 + P3 (fdlibm e_rem_pio2.c: pio2_1, pio2_2, pio2_3; 33 + 33 + 53 bits).
_PIO2_1 = 1.57079632673412561417e00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_3 = 2.02226624871116645580e-21
# Taylor coefficients (-1)^k/(2k+1)! and (-1)^k/(2k)!.
_S = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(1, 9))
_C = tuple((-1.0) ** k / math.factorial(2 * k) for k in range(2, 9))


@nb.njit(cache=True, fastmath=_FLAGS, error_model="numpy")
def vsincos(x: float) -> tuple[float, float]:
    """``(sin x, cos x)`` for ``|x| <= 1e5`` within 4 ulp (Cody-Waite reduction + Taylor)."""
    q = np.rint(x * _TWO_OVER_PI)
    d = x - q * _PIO2_1
    d = d - q * _PIO2_2
    d = d - q * _PIO2_3
    z = d * d
    z2 = z * z
    z4 = z2 * z2
    ps = ((_S[0] + z * _S[1]) + z2 * (_S[2] + z * _S[3])) + z4 * (
        (_S[4] + z * _S[5]) + z2 * (_S[6] + z * _S[7]))
    s = d + (d * z) * ps
    pc = ((_C[0] + z * _C[1]) + z2 * (_C[2] + z * _C[3])) + z4 * ((_C[4] + z * _C[5]) + z2 * _C[6])
    c = (1.0 - 0.5 * z) + (z * z) * pc
    qm = q - 4.0 * np.floor(q * 0.25)  # q mod 4, exact (q is an integer-valued float)
    odd = (qm == 1.0) | (qm == 3.0)
    sn = c if odd else s
    cs = s if odd else c
    sn = -sn if qm >= 2.0 else sn
    cs = -cs if (qm == 1.0) | (qm == 2.0) else cs
    return sn, cs


# ---- atan2 / asin ----------------------------------------------------------------------
# Thresholds tan((2k+1)π/32) between the centres c_k = tan(kπ/16), k = 0..4.
_T0, _T1, _T2, _T3 = (math.tan((2 * k + 1) * math.pi / 32.0) for k in range(4))
_C1, _C2, _C3 = (math.tan(k * math.pi / 16.0) for k in range(1, 4))
# π/16 in two parts: a high part with 26 significant bits (m·hi exact for m <= 32), the rest.
_PI16_HI = struct.unpack("<d", struct.pack("<q", struct.unpack("<q", struct.pack("<d", math.pi / 16.0))[0]
                                             & ~((1 << 27) - 1)))[0]
_PI16_LO = (math.pi / 16.0 - _PI16_HI) + 1.2246467991473532e-16 / 16.0  # π - math.pi = 1.2246e-16
_A = tuple((-1.0) ** k / (2 * k + 1) for k in range(1, 9))


@nb.njit(cache=True, fastmath=_FLAGS, error_model="numpy")
def vatan2(y: float, x: float) -> float:
    """``atan2(y, x)`` for finite inputs within 4 ulp (fold to [0, 1], centre on tan(kπ/16), Taylor)."""
    ay = abs(y)
    ax = abs(x)
    swap = ay > ax
    num = ax if swap else ay
    den = ay if swap else ax
    den = den if den > 0.0 else 1.0  # atan2(0, 0) = 0
    # The sector from num/den > tan((2k+1)π/32) compared as num > tan(..)·den (den > 0):
    # no division for it (the divider unit is the kernel's bottleneck).
    k = ((1.0 if num > _T0 * den else 0.0) + (1.0 if num > _T1 * den else 0.0)) + (
        (1.0 if num > _T2 * den else 0.0) + (1.0 if num > _T3 * den else 0.0))
    c = 0.0
    c = _C1 if k == 1.0 else c
    c = _C2 if k == 2.0 else c
    c = _C3 if k == 3.0 else c
    c = 1.0 if k == 4.0 else c
    t = (num - c * den) / (den + c * num)
    t2 = t * t
    t4 = t2 * t2
    t8 = t4 * t4
    pa = ((_A[0] + t2 * _A[1]) + t4 * (_A[2] + t2 * _A[3])) + t8 * (
        (_A[4] + t2 * _A[5]) + t4 * (_A[6] + t2 * _A[7]))
    a = t + (t * t2) * pa
    # angle = m·π/16 ± a: m = k, or 8 - k when |y| > |x|, then 16 - m when x < 0.
    m = 8.0 - k if swap else k
    sgn = -1.0 if swap else 1.0
    neg = x < 0.0
    m = 16.0 - m if neg else m
    sgn = -sgn if neg else sgn
    r = m * _PI16_HI + (m * _PI16_LO + sgn * a)
    r = -r if y < 0.0 else r
    bad = (x != x) | (y != y)
    return x + y if bad else r


@nb.njit(cache=True, inline="always")
def vasin(x: float) -> float:
    """``asin(x)`` for ``|x| <= 1`` within 4 ulp, as ``atan2(x, sqrt((1-x)(1+x)))``.

    The square root as ``w · rsqrt(w)`` (no divider; 0 at |x| = 1).
    """
    return vatan2(x, math.sqrt((1.0 - x) * (1.0 + x)))


# ---- exp / log / pow -------------------------------------------------------------------
_LOG2E = 1.4426950408889634
_LN2_HI = 6.93147180369123816490e-01  # fdlibm: ln 2 in 32 + 53 bits
_LN2_LO = 1.90821492927058770002e-10
_E = tuple(1.0 / math.factorial(k) for k in range(14))
_E_2_9 = _E[2:10]


@nb.njit(inline="always", cache=True, fastmath=_FLAGS, error_model="numpy")
def _estrin8(x: float, x2: float, x4: float, c: tuple[float, ...]) -> float:
    """``c[0] + c[1] x + ... + c[7] x^7`` by Estrin's scheme, given ``x² and x⁴``: a chain of three multiply-adds."""
    return (((c[0] + x * c[1]) + x2 * (c[2] + x * c[3]))
            + x4 * ((c[4] + x * c[5]) + x2 * (c[6] + x * c[7])))


_EXP_MAX = 709.782712893384  # exp overflows above
_EXP_MIN = -708.3964185322641  # exp(x) < 2^-1022 below (flushed to 0)


@nb.njit(cache=True, fastmath=_FLAGS, error_model="numpy")
def vexp(x: float) -> float:
    """``exp(x)`` within 4 ulp (Cody-Waite reduction by ln 2, Taylor to r^13, 2^n from bits)."""
    n = np.rint(x * _LOG2E)
    n = min(max(n, -1022.0), 1024.0) if n == n else 0.0
    r = x - n * _LN2_HI
    r = r - n * _LN2_LO
    # Horner's last two steps (they carry the rounding), Estrin's scheme for the tail
    # E2 + E3 r + ... + E13 r^11 (its rounding is scaled by r² <= 0.12): the same terms in a
    # dependency chain of ~6 operations instead of 12 (the lane kernel waits on its chains).
    r2 = r * r
    r4 = r2 * r2
    q8b = (_E[10] + r * _E[11]) + r2 * (_E[12] + r * _E[13])
    p = _estrin8(r, r2, r4, _E_2_9) + (r4 * r4) * q8b
    p = 1.0 + r * p
    p = 1.0 + r * p
    # 2^n in two normal factors (n = 1024 just below the overflow threshold).
    n1 = np.int64(n) >> 1
    n2 = np.int64(n) - n1
    s1: float = _i2f((n1 + 1023) << 52)  # type: ignore[call-arg]
    s2: float = _i2f((n2 + 1023) << 52)
    out = (p * s1) * s2
    out = math.inf if x > _EXP_MAX else out
    out = 0.0 if x < _EXP_MIN else out
    return x if x != x else out


_SQRT2 = 1.4142135623730951
_MIN_NORMAL = 2.2250738585072014e-308
_L = tuple(2.0 / (2 * k + 1) for k in range(1, 11))
_L_0_7 = _L[:8]
_MANT = (1 << 52) - 1
_ONE_BITS = 1023 << 52


@nb.njit(cache=True, fastmath=_FLAGS, error_model="numpy")
def vlog(x: float) -> float:
    """``log(x)`` within 4 ulp (exponent from the bits, fdlibm's ``f - s(f - R)`` on [√½, √2))."""
    sub = x < _MIN_NORMAL
    xs = x * 18014398509481984.0 if sub else x  # 2^54: subnormals to normals
    bits: int = _f2i(xs)  # type: ignore[call-arg]
    e = (bits >> 52) - np.int64(1023)
    mant = _i2f((bits & _MANT) | _ONE_BITS)  # [1, 2)
    big = mant > _SQRT2
    mant = mant * 0.5 if big else mant
    ef = float(e) + (1.0 if big else 0.0) - (54.0 if sub else 0.0)
    f = mant - 1.0
    s = f / (2.0 + f)
    z = s * s
    # R's polynomial in z by Estrin's scheme (a chain of ~5 operations instead of 10; its
    # rounding is scaled by s² <= 0.03 in the result).
    z2 = z * z
    z4 = z2 * z2
    pr = _estrin8(z, z2, z4, _L_0_7) + (z4 * z4) * (_L[8] + z * _L[9])
    rr = z * pr
    lm = f - s * (f - rr)
    out = ef * _LN2_HI + (lm + ef * _LN2_LO)
    out = -math.inf if x == 0.0 else out
    out = math.inf if x == math.inf else out
    out = math.nan if x < 0.0 else out
    return x if x != x else out


@nb.njit(cache=True, inline="always")
def vpow(x: float, a: float) -> float:
    """``x^a`` for ``x > 0`` as ``exp(a log x)``, within ``4 + 3|a log x|`` ulp."""
    return vexp(a * vlog(x))
