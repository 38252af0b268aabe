"""Single-precision (float32) vectorisable sin/cos, atan2, asin, exp, log for the float32 lane kernel.

The float32 counterparts of :mod:`sim.flight.engines._vmath` (same structure: Cody-Waite
reduction by a constant split into exactly-multiplying parts, a polynomial on the reduced
range, every case a select, no calls), with the coefficients of Moshier's Cephes library
single-precision functions (S. L. Moshier, *Methods and Programs for Mathematical
Functions*, 1989; Cephes ``sinf.c``, ``atanf.c``, ``expf.c``, ``logf.c``), which are
minimax fits on the same reduced ranges:

* ``sincos``: ``x = q·π/2 + d``, π/2 in three parts (Cephes' ``DP1..3`` doubled; ``q·P1``
  exact for ``|q| < 2^16``), ``|d| <= π/4``; Cephes' sinf/cosf polynomials of degree 7/8.
* ``atan2``: fold to ``z = min/max`` of ``|y|, |x|`` in [0, 1]; above ``tan(π/8)`` take
  ``t = (n - d)/(d + n)`` and add π/4 (Cephes atanf's reduction, as one division); Cephes'
  degree-9 odd polynomial; the angle ``m·π/4`` added in two parts. ``asin(x) = atan2(x,
  sqrt((1-x)(1+x)))``.
* ``exp``: ``x = n ln 2 + r`` (Cephes' ``C1, C2``), Cephes expf's degree-7 polynomial,
  ``2^n`` from its bits. Overflows to inf above 88.72; flushes to 0 below -87.33.
* ``log``: ``x = 2^e m`` with ``m`` in [√½, √2) from the bits, Cephes logf's
  ``f - f²/2 + f³ P(f)`` with P of degree 8.

Polynomials by Estrin's scheme (as in ``_vmath``: the lane kernel waits on its chains).
Every literal is a float32 constant (a Python float literal is float64 in numba and would
promote the whole expression to double precision).

Accuracy (``tests/test_flight_vmath32.py``, against numpy in float64 rounded to float32):
within 4 ulp of float32.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from llvmlite import ir  # type: ignore[import-untyped]
from numba.core import types
from numba.extending import intrinsic

__all__ = ["vasin32", "vatan2_32", "vexp32", "vlog32", "vsincos32"]

_FLAGS = {"contract"}
F = np.float32


@intrinsic
def _f2i32(typingctx, x):
    """The bits of a float32 as an int32 (a bitcast)."""
    if x is not types.float32:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(32))

    return types.int32(types.float32), codegen


@intrinsic
def _i2f32(typingctx, x):
    """The float32 whose bits are the low 32 bits of the integer ``x`` (numba widens int32 arithmetic to int64)."""
    if not isinstance(x, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        v = args[0]
        if x.bitwidth > 32:  # type: ignore[attr-defined]
            v = builder.trunc(v, ir.IntType(32))
        elif x.bitwidth < 32:  # type: ignore[attr-defined]
            v = builder.sext(v, ir.IntType(32))
        return builder.bitcast(v, ir.FloatType())

    return types.float32(x), codegen


_ZERO, _ONE, _HALF, _TWO = F(0.0), F(1.0), F(0.5), F(2.0)
_INF = F(np.inf)
_NAN = F(np.nan)

# ---- sin / cos -------------------------------------------------------------------------
_TWO_OVER_PI = F(0.63661977236758134308)
_P1 = F(1.5703125)  # Cephes sinf.c DP1..DP3 (π/4 in three parts), doubled: exact
_P2 = F(4.837512969970703125e-4)
_P3 = F(7.54978995489188216e-8)
_S1, _S2, _S3 = F(-1.6666654611e-1), F(8.3321608736e-3), F(-1.9515295891e-4)
_C1, _C2, _C3 = F(4.166664568298827e-2), F(-1.388731625493765e-3), F(2.443315711809948e-5)
_FOUR, _QUARTER, _THREE = F(4.0), F(0.25), F(3.0)


@nb.njit(cache=True, fastmath=_FLAGS, error_model="numpy")
def vsincos32(x: np.float32) -> tuple[np.float32, np.float32]:
    """``(sin x, cos x)`` in float32, within 4 ulp for ``|x| <= 50`` (Cody-Waite reduction, Cephes polynomials)."""
    q = np.rint(x * _TWO_OVER_PI)
    d = x - q * _P1
    d = d - q * _P2
    d = d - q * _P3
    z = d * d
    z2 = z * z
    s = d + (d * z) * ((_S1 + z * _S2) + z2 * _S3)
    c = (_ONE - _HALF * z) + z2 * ((_C1 + z * _C2) + z2 * _C3)
    qm = q - _FOUR * np.floor(q * _QUARTER)
    odd = (qm == _ONE) | (qm == _THREE)
    sn = c if odd else s
    cs = s if odd else c
    sn = -sn if qm >= _TWO else sn
    cs = -cs if (qm == _ONE) | (qm == _TWO) else cs
    return sn, cs


# ---- atan2 / asin ----------------------------------------------------------------------
_TAN_PI8 = F(0.41421356237309504880)
_A1, _A2, _A3, _A4 = F(-3.33329491539e-1), F(1.99777106478e-1), F(-1.38776856032e-1), F(8.05374449538e-2)
_PI4_HI = F(0.78515625)  # π/4 = hi + lo; m·hi exact for m <= 4
_PI4_LO = F(2.4191339240e-4)


@nb.njit(cache=True, fastmath=_FLAGS, error_model="numpy")
def vatan2_32(y: np.float32, x: np.float32) -> np.float32:
    """``atan2(y, x)`` in float32 for finite inputs (fold to [0, 1], Cephes atanf's reduction and polynomial)."""
    ay = abs(y)
    ax = abs(x)
    swap = ay > ax
    num = ax if swap else ay
    den = ay if swap else ax
    den = den if den > _ZERO else _ONE  # atan2(0, 0) = 0
    k = _ONE if num > _TAN_PI8 * den else _ZERO
    t = (num - k * den) / (den + k * num)
    z = t * t
    z2 = z * z
    a = t + (t * z) * ((_A1 + z * _A2) + z2 * (_A3 + z * _A4))
    # angle = m·π/4 ± a: m = k, or 2 - k when |y| > |x|, then 4 - m when x < 0.
    m = _TWO - k if swap else k
    sgn = -_ONE if swap else _ONE
    neg = x < _ZERO
    m = _FOUR - m if neg else m
    sgn = -sgn if neg else sgn
    r = m * _PI4_HI + (m * _PI4_LO + sgn * a)
    r = -r if y < _ZERO else r
    bad = (x != x) | (y != y)
    return x + y if bad else r


@nb.njit(cache=True, inline="always")
def vasin32(x: np.float32) -> np.float32:
    """``asin(x)`` in float32 for ``|x| <= 1``, as ``atan2(x, sqrt((1-x)(1+x)))``."""
    return vatan2_32(x, np.sqrt((_ONE - x) * (_ONE + x)))


# ---- exp / log -------------------------------------------------------------------------
_LOG2E = F(1.44269504088896341)
_LN2_HI = F(0.693359375)  # Cephes expf/logf C1, C2: ln 2 = C1 - C2'
_LN2_LO = F(-2.12194440e-4)
_E0, _E1, _E2 = F(5.0000001201e-1), F(1.6666665459e-1), F(4.1665795894e-2)
_E3, _E4, _E5 = F(8.3334519073e-3), F(1.3981999507e-3), F(1.9875691500e-4)
_EXP_MAX = F(88.72283905206835)
_EXP_MIN = F(-87.33654475055310898657)  # below: under 2^-126 (flushed to 0)
_NMIN, _NMAX = F(-126.0), F(127.0)


@nb.njit(cache=True, fastmath=_FLAGS, error_model="numpy")
def vexp32(x: np.float32) -> np.float32:
    """``exp(x)`` in float32 (Cody-Waite reduction by ln 2, Cephes expf's polynomial, 2^n from bits)."""
    n = np.rint(x * _LOG2E)
    n = min(max(n, _NMIN), _NMAX) if n == n else _ZERO
    r = x - n * _LN2_HI
    r = r - n * _LN2_LO
    r2 = r * r
    r4 = r2 * r2
    p = ((_E0 + r * _E1) + r2 * (_E2 + r * _E3)) + r4 * (_E4 + r * _E5)
    p = (_ONE + r) + r2 * p
    s: np.float32 = _i2f32((np.int32(n) + np.int32(127)) << np.int32(23))  # type: ignore[call-arg]
    out = p * s
    out = _INF if x > _EXP_MAX else out
    out = _ZERO if x < _EXP_MIN else out
    return x if x != x else out


_SQRT2 = F(1.41421356237309504880)
_MIN_NORMAL = F(1.17549435e-38)
_L0, _L1, _L2 = F(3.3333331174e-1), F(-2.4999993993e-1), F(2.0000714765e-1)
_L3, _L4, _L5 = F(-1.6668057665e-1), F(1.4249322787e-1), F(-1.2420140846e-1)
_L6, _L7, _L8 = F(1.1676998740e-1), F(-1.1514610310e-1), F(7.0376836292e-2)
_TWO25 = F(33554432.0)


@nb.njit(cache=True, fastmath=_FLAGS, error_model="numpy")
def vlog32(x: np.float32) -> np.float32:
    """``log(x)`` in float32 (exponent from the bits, Cephes logf's polynomial on [√½, √2) - 1)."""
    sub = x < _MIN_NORMAL
    xs = x * _TWO25 if sub else x  # subnormals to normals
    bits: int = _f2i32(xs)  # type: ignore[call-arg]
    e = (bits >> np.int32(23)) - np.int32(127)
    mant = _i2f32((bits & np.int32(0x7FFFFF)) | np.int32(0x3F800000))  # [1, 2)
    big = mant > _SQRT2
    mant = mant * _HALF if big else mant
    ef = F(e) + (_ONE if big else _ZERO) - (F(25.0) if sub else _ZERO)
    f = mant - _ONE
    z = f * f
    z2 = z * z
    z4 = z2 * z2
    p = (((_L0 + f * _L1) + z * (_L2 + f * _L3)) + z2 * ((_L4 + f * _L5) + z * (_L6 + f * _L7))) + z4 * _L8
    y = (f * z) * p + ef * _LN2_LO
    y = y - _HALF * z
    out = (f + y) + ef * _LN2_HI
    out = -_INF if x == _ZERO else out
    out = _INF if x == _INF else out
    out = _NAN if x < _ZERO else out
    return x if x != x else out
