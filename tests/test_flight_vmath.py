"""The lane kernel's elementary functions (sim.flight.engines._vmath) against numpy, over their input ranges.

Each function is applied through a loop compiled with the kernel's own fastmath flags
(the situation in the kernel: LLVM inlines them into a fastmath loop) and compared with
numpy's result in ulp over dense random samples of its documented range, plus the
special values the kernel's divergence checks rely on.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
import pytest

from sim.flight.engines._vmath import vasin, vatan2, vexp, vlog, vpow, vsincos

_KERNEL_FLAGS = {"nsz", "afn", "contract", "reassoc"}


@nb.njit(fastmath=_KERNEL_FLAGS, error_model="numpy")
def _apply(which, x, y, out, out2):  # type: ignore[no-untyped-def]
    # One loop per function: each is a straight loop LLVM vectorises, as in the kernel.
    if which == 0:
        for i in range(x.size):
            out[i], out2[i] = vsincos(x[i])
    elif which == 1:
        for i in range(x.size):
            out[i] = vatan2(y[i], x[i])
    elif which == 2:
        for i in range(x.size):
            out[i] = vasin(x[i])
    elif which == 3:
        for i in range(x.size):
            out[i] = vexp(x[i])
    elif which == 4:
        for i in range(x.size):
            out[i] = vlog(x[i])
    else:
        for i in range(x.size):
            out[i] = vpow(x[i], y[i])


def _run(which: int, x: np.ndarray, y: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    x = np.ascontiguousarray(x, dtype=np.float64)
    y = x if y is None else np.ascontiguousarray(y, dtype=np.float64)
    out, out2 = np.empty_like(x), np.empty_like(x)
    _apply(which, x, y, out, out2)
    return out, out2


def _ulp(got: np.ndarray, want: np.ndarray) -> float:
    """Largest error in units of the last place of numpy's result (0 where both are equal)."""
    scale = np.spacing(np.maximum(np.abs(want), np.finfo(np.float64).tiny))
    err = np.where(got == want, 0.0, np.abs(got - want) / scale)
    return float(err.max())


RNG = np.random.default_rng(20)
N = 400_000


@pytest.mark.parametrize("half_width", [math.pi / 4, math.pi, 50.0, 1e5])
def test_sincos_within_4_ulp(half_width):
    x = RNG.uniform(-half_width, half_width, N)
    s, c = _run(0, x)
    # Near a zero of sin or cos the result's ulp is tiny; numpy's own error there is
    # ~1 ulp of |x| (its reduction). Compare in ulp of max(|result|, 2^-30) there.
    floor = 2.0**-30
    for got, want in ((s, np.sin(x)), (c, np.cos(x))):
        big = np.abs(want) > floor
        assert _ulp(got[big], want[big]) <= 4.0
        assert np.abs(got - want)[~big].max(initial=0.0) <= 4.0 * np.spacing(floor)


def test_sincos_exact_at_zero_and_nan_propagates():
    s, c = _run(0, np.array([0.0, -0.0, np.nan, np.inf]))
    assert s[0] == 0.0 and c[0] == 1.0 and s[1] == 0.0 and c[1] == 1.0  # hover: sin 0 = 0, cos 0 = 1 exactly
    assert np.isnan(s[2:]).all() and np.isnan(c[2:]).all()


def test_atan2_within_4_ulp_over_all_quadrants_and_scales():
    x = RNG.normal(size=N) * np.exp(RNG.uniform(-20, 20, N))
    y = RNG.normal(size=N) * np.exp(RNG.uniform(-20, 20, N))
    got, _ = _run(1, x, y)
    assert _ulp(got, np.arctan2(y, x)) <= 4.0
    # Along the axes, the diagonals and the fold points tan(kπ/16).
    t = np.tan(np.arange(0, 17) * np.pi / 32.0)
    xs = np.concatenate([np.ones_like(t), -np.ones_like(t), t, -t, [1.0, -1.0, 0.0, 1.0]])
    ys = np.concatenate([t, t, np.ones_like(t), -np.ones_like(t), [0.0, 0.0, 1.0, -0.0]])
    got, _ = _run(1, xs, ys)
    assert _ulp(got, np.arctan2(ys, xs)) <= 4.0


def test_atan2_special_values():
    got, _ = _run(1, np.array([0.0, np.nan, 1.0]), np.array([0.0, 1.0, np.nan]))
    assert got[0] == 0.0 and np.isnan(got[1]) and np.isnan(got[2])


def test_asin_within_4_ulp_including_near_one():
    x = np.concatenate([RNG.uniform(-1, 1, N), 1.0 - np.exp(RNG.uniform(-36, 0, N // 4)),
                        -1.0 + np.exp(RNG.uniform(-36, 0, N // 4)), [-1.0, 0.0, 1.0]])
    got, _ = _run(2, x)
    assert _ulp(got, np.arcsin(x)) <= 4.0
    assert got[-2] == 0.0


@pytest.mark.parametrize("lo,hi", [(-1.0, 1.0), (-30.0, 30.0), (-708.0, 709.7)])
def test_exp_within_4_ulp(lo, hi):
    x = RNG.uniform(lo, hi, N)
    got, _ = _run(3, x)
    assert _ulp(got, np.exp(x)) <= 4.0


def test_exp_special_values():
    got, _ = _run(3, np.array([np.nan, 710.0, -746.0, 0.0, -np.inf, np.inf]))
    assert np.isnan(got[0]) and got[1] == np.inf and got[2] == 0.0 and got[3] == 1.0
    assert got[4] == 0.0 and got[5] == np.inf


@pytest.mark.parametrize("lo,hi", [(-745.0, 709.0), (-0.4, 0.4), (-1e-6, 1e-6)])
def test_log_within_4_ulp(lo, hi):
    x = np.exp(RNG.uniform(lo, hi, N))  # log-uniform over the range, subnormals included
    got, _ = _run(4, x)
    assert _ulp(got, np.log(x)) <= 4.0


def test_log_special_values():
    got, _ = _run(4, np.array([0.0, -1.0, np.inf, np.nan, 1.0, 5e-324]))
    assert got[0] == -np.inf and np.isnan(got[1]) and got[2] == np.inf and np.isnan(got[3])
    assert got[4] == 0.0 and got[5] == pytest.approx(np.log(5e-324), rel=1e-15)


def test_pow_error_bound_for_the_kernels_exponents():
    # sig(x, r) needs ||x||^(r - 1) for r in (0, 1]: exponents in [-1, 0), norms over many
    # decades. exp(a log x) carries the rounding of y = a log x (~1.5 ulp of y) into a
    # relative error ~1.5 |y| 2^-52: the bound is 4 + 3 |y| ulp (<= 10 ulp for |y| <= 2).
    x = np.exp(RNG.uniform(-40, 20, N))
    a = RNG.choice([5.0 / 7.0 - 1.0, -0.5, -0.25, -0.9], N)
    got, _ = _run(5, x, a)
    want = np.power(x, a)
    err = np.where(got == want, 0.0, np.abs(got - want) / np.spacing(want))
    assert np.all(err <= 4.0 + 3.0 * np.abs(a * np.log(x)))
    small = np.abs(a * np.log(x)) <= 2.0
    assert err[small].max() <= 10.0


@nb.njit(fastmath=_KERNEL_FLAGS, error_model="numpy")
def _lane_mix(sc):  # type: ignore[no-untyped-def]
    # The kernel's pattern: a lane loop (runtime trip count) over one scratch array, every
    # function and a select in its body.
    lanes = sc.size // 4
    for lane in range(lanes):
        x = sc[lane]
        s, c = vsincos(x)
        r = vasin(0.5 * s) + vatan2(c, 2.0 + x) + vpow(1.0 + x * x, -2.0 / 7.0) + vexp(-x) + vlog(2.0 + c)
        sc[2 * lanes + lane] = r if x > 0.0 else sc[3 * lanes + lane]


def test_functions_vectorise_in_a_lane_loop():
    # A libm call or a call LLVM does not inline would leave this loop scalar (no packed
    # ymm/zmm arithmetic); the kernel's own loop is checked by benchmarks/bench_sim.py.
    sc = np.linspace(0.0, 1.0, 64)
    before = sc.copy()
    _lane_mix(sc)
    import re

    asm = _lane_mix.inspect_asm(_lane_mix.signatures[0])
    packed = re.findall(r"^\s*v(?:fn?m(?:add|sub)\w*|add|sub|mul|div|sqrt)pd\s[^\n]*%[yz]mm", asm, re.M)
    assert len(packed) >= 50
    x = before[:16]
    c = np.cos(x)
    r = np.arcsin(0.5 * np.sin(x)) + np.arctan2(c, 2.0 + x) + (1.0 + x * x) ** (-2.0 / 7.0)
    r = r + np.exp(-x) + np.log(2.0 + c)
    np.testing.assert_allclose(sc[32:48], np.where(x > 0.0, r, before[48:64]), rtol=1e-15, atol=1e-15)
