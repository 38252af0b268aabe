"""The float32 kernel's elementary functions (sim.flight.engines._vmath32) against numpy, over their input ranges.

As ``tests/test_flight_vmath.py`` for the float64 ones: each function runs in a loop compiled
with the kernel's fastmath flags, on float32 inputs, and is compared with numpy's float64
result of the same (float32) input, in float32 ulp of that result: the error of the function
itself, not of the input's rounding.
"""

from __future__ import annotations

import math
import re

import numba as nb
import numpy as np
import pytest

from sim.flight.engines._vmath32 import vasin32, vatan2_32, vexp32, vlog32, vsincos32

_KERNEL_FLAGS = {"nsz", "afn", "contract", "reassoc"}
F = np.float32


@nb.njit(fastmath=_KERNEL_FLAGS, error_model="numpy")
def _apply(which, x, y, out, out2):  # type: ignore[no-untyped-def]
    if which == 0:
        for i in range(x.size):
            out[i], out2[i] = vsincos32(x[i])
    elif which == 1:
        for i in range(x.size):
            out[i] = vatan2_32(y[i], x[i])
    elif which == 2:
        for i in range(x.size):
            out[i] = vasin32(x[i])
    elif which == 3:
        for i in range(x.size):
            out[i] = vexp32(x[i])
    else:
        for i in range(x.size):
            out[i] = vlog32(x[i])


def _run(which: int, x: np.ndarray, y: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    x = np.ascontiguousarray(x, dtype=F)
    y = x if y is None else np.ascontiguousarray(y, dtype=F)
    out, out2 = np.empty_like(x), np.empty_like(x)
    _apply(which, x, y, out, out2)
    assert out.dtype == F
    return out, out2


def _ulp32(got: np.ndarray, want64: np.ndarray) -> float:
    """Largest |got - want| in float32 ulp of the float64 result rounded to float32."""
    scale = np.spacing(np.maximum(np.abs(want64.astype(F)), np.finfo(F).tiny)).astype(np.float64)
    err = np.abs(got.astype(np.float64) - want64) / scale
    return float(err.max())


RNG = np.random.default_rng(32)
N = 400_000


@pytest.mark.parametrize("half_width", [math.pi / 4, math.pi, 50.0])
def test_sincos32_within_4_ulp(half_width):
    x = RNG.uniform(-half_width, half_width, N).astype(F)
    s, c = _run(0, x)
    x64 = x.astype(np.float64)
    assert _ulp32(s, np.sin(x64)) <= 4.0
    assert _ulp32(c, np.cos(x64)) <= 4.0


def test_sincos32_exact_at_zero_and_nan_propagates():
    s, c = _run(0, np.array([0.0, np.nan]))
    assert s[0] == 0.0 and c[0] == 1.0 and np.isnan(s[1]) and np.isnan(c[1])


def test_atan2_32_within_4_ulp_over_all_quadrants_and_scales():
    y = (RNG.standard_normal(N) * 10.0 ** RNG.uniform(-6, 6, N)).astype(F)
    x = (RNG.standard_normal(N) * 10.0 ** RNG.uniform(-6, 6, N)).astype(F)
    got, _ = _run(1, x, y)
    assert _ulp32(got, np.arctan2(y.astype(np.float64), x.astype(np.float64))) <= 4.0
    z, _ = _run(1, np.zeros(2), np.zeros(2))
    assert np.all(z == 0.0)


def test_asin32_within_4_ulp_including_near_one():
    x = np.concatenate([RNG.uniform(-1.0, 1.0, N), 1.0 - 10.0 ** RNG.uniform(-7, -1, 1000), [1.0, -1.0, 0.0]])
    x = x.astype(F)
    got, _ = _run(2, x)
    assert _ulp32(got, np.arcsin(x.astype(np.float64))) <= 4.0


@pytest.mark.parametrize(("lo", "hi"), [(-0.35, 0.35), (-87.0, 88.5), (-20.0, 20.0)])
def test_exp32_within_4_ulp(lo, hi):
    x = RNG.uniform(lo, hi, N).astype(F)
    got, _ = _run(3, x)
    assert _ulp32(got, np.exp(x.astype(np.float64))) <= 4.0


def test_exp32_special_values():
    got, _ = _run(3, np.array([0.0, 100.0, -100.0, np.nan, -np.inf, np.inf]))
    assert got[0] == 1.0 and got[1] == np.inf and got[2] == 0.0 and np.isnan(got[3])
    assert got[4] == 0.0 and got[5] == np.inf


@pytest.mark.parametrize(("lo", "hi"), [(0.5, 2.0), (-44.0, 38.0)])
def test_log32_within_4_ulp(lo, hi):
    x = (10.0 ** RNG.uniform(lo, hi, N)) if lo < 0 else RNG.uniform(lo, hi, N)
    x = x.astype(F)
    x = x[x > 0]  # 1e-44 is a float32 subnormal: included, the bits path scales it
    got, _ = _run(4, x)
    assert _ulp32(got, np.log(x.astype(np.float64))) <= 4.0


def test_log32_special_values():
    got, _ = _run(4, np.array([0.0, -1.0, np.inf, np.nan, 1.0]))
    assert got[0] == -np.inf and np.isnan(got[1]) and got[2] == np.inf and np.isnan(got[3]) and got[4] == 0.0


def test_functions32_vectorise_to_packed_single_precision():
    # A float64 literal would promote the arithmetic to double (``...pd``); a call would leave it
    # scalar: the loop must compile to packed single-precision arithmetic.
    x = np.linspace(0.1, 1.0, 64).astype(F)
    _run(4, x)
    asm = _apply.inspect_asm(_apply.signatures[0])
    packed_ps = re.findall(r"^\s*v(?:fn?m(?:add|sub)\w*|add|sub|mul|div|sqrt)ps\s[^\n]*%[yz]mm", asm, re.M)
    packed_pd = re.findall(r"^\s*v(?:fn?m(?:add|sub)\w*|add|sub|mul|div|sqrt)pd\s[^\n]*%[yz]mm", asm, re.M)
    assert len(packed_ps) >= 50 and not packed_pd
