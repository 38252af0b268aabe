"""Quintic time law: coefficient form (eqs. 15-19) against the closed form and boundary conditions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim import PEAK_ACCEL_FACTOR, PEAK_SPEED_FACTOR, quintic_coefficients, quintic_eval, rest_to_rest
from sim.plan._quintic import invert_rest_to_rest

finite = st.floats(-100, 100, allow_nan=False)


@settings(max_examples=50, deadline=None)
@given(p0=finite, pf=finite, T=st.floats(0.1, 100))
def test_rest_to_rest_coefficients_equal_closed_form(p0: float, pf: float, T: float) -> None:
    t = np.linspace(0, T, 101)
    p, v, a = quintic_eval(quintic_coefficients(p0, pf, T), t)
    law = rest_to_rest(t / T, T)
    scale = max(1.0, abs(pf - p0))
    np.testing.assert_allclose(p, p0 + (pf - p0) * law.s, atol=1e-9 * scale)
    np.testing.assert_allclose(v, (pf - p0) * law.s_d, atol=1e-9 * scale / T)
    np.testing.assert_allclose(a, (pf - p0) * law.s_dd, atol=1e-9 * scale / T**2)


@settings(max_examples=50, deadline=None)
@given(st.lists(finite, min_size=6, max_size=6), st.floats(0.5, 20))
def test_general_boundary_conditions(bc: list[float], T: float) -> None:
    p0, v0, a0, pf, vf, af = bc
    c = quintic_coefficients(p0, pf, T, v0=v0, a0=a0, vf=vf, af=af)
    p, v, a = quintic_eval(c, np.array([0.0, T]))
    np.testing.assert_allclose([p[0], v[0], a[0]], [p0, v0, a0], atol=1e-9)
    scale = 1 + max(abs(x) for x in bc) * (1 + T) ** 2
    np.testing.assert_allclose([p[1], v[1], a[1]], [pf, vf, af], atol=1e-8 * scale)


def test_rest_boundary_and_peaks() -> None:
    T = 7.0
    law = rest_to_rest(np.array([0.0, 1.0]), T)
    np.testing.assert_array_equal(law.s, [0.0, 1.0])
    np.testing.assert_array_equal(law.s_d, [0.0, 0.0])
    np.testing.assert_array_equal(law.s_dd, [0.0, 0.0])
    tau = np.linspace(0, 1, 200_001)
    dense = rest_to_rest(tau, 1.0)
    assert dense.s_d.max() == pytest.approx(PEAK_SPEED_FACTOR, rel=1e-9)
    assert np.abs(dense.s_dd).max() == pytest.approx(PEAK_ACCEL_FACTOR, rel=1e-8)


def test_derivatives_match_finite_differences() -> None:
    T, h = 3.0, 1e-5
    t = np.linspace(0.1, 2.9, 29)
    f = lambda tt: rest_to_rest(tt / T, T)  # noqa: E731
    for name, dname in (("s", "s_d"), ("s_d", "s_dd"), ("s_dd", "s_ddd"), ("s_ddd", "s_dddd")):
        fd = (getattr(f(t + h), name) - getattr(f(t - h), name)) / (2 * h)
        np.testing.assert_allclose(fd, getattr(f(t), dname), rtol=1e-5, atol=1e-7)


def test_invert() -> None:
    tau = np.linspace(0, 1, 1001)
    s = rest_to_rest(tau, 1.0).s
    back = invert_rest_to_rest(s)
    # s is flat (cubic) at both ends, so τ is only determined to ~eps^(1/3) there; s itself round-trips.
    np.testing.assert_allclose(rest_to_rest(back, 1.0).s, s, atol=1e-15)
    inner = (tau > 0.05) & (tau < 0.95)
    np.testing.assert_allclose(back[inner], tau[inner], atol=1e-12)
