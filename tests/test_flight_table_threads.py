"""The wind and GNSS tables on several threads are the very bits of their one-thread formulas.

The wind's mode sum (:mod:`sim.flight._windsum`) is shared among threads in point blocks, two
modes per pass, and written straight into the tables' rows; the GNSS table is drawn on a thread
beside it (:mod:`sim.flight._threads`). A seed must keep meaning the same flight, so the sum is
compared bit for bit with itself over thread counts 1-3 and over point sets that cut the blocks
elsewhere (a point's value must not depend on its block or thread), and against the documented
formula written out mode by mode in numpy with libm's cosines and sines (the independent
computation: the compiled loop's polynomials and FMA contraction round differently, so to a
tolerance), over point counts that cut the blocks anywhere and odd and even mode counts; and
whole tables and a whole flight on one thread and on two.
"""

from __future__ import annotations

import math
import threading

import numpy as np
import pytest

import sim.flight.engines._tables as tables_mod
from sim.flight import QuadrotorParams, TrackingReference, error_preset, simulate
from sim.flight._disturbance import WindField
from sim.flight._threads import Beside, share_blocks
from sim.flight._windsum import _BLOCK, turbulence_sum_and_jacobian
from sim.flight.engines._tables import WIND_GRAD_SIZE, ErrorTables


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


def _numpy_sum_and_jacobian(out, jac, x, y, z, t, k, amp, omega, phase):
    """The module docstring's formula, mode by mode over all points at once, with libm's cos and sin."""
    for m in range(k.shape[0]):
        kx, ky, kz = k[m]
        arg = kx * x + ky * y + kz * z + omega[m] * t + phase[m]
        c, s = np.cos(arg), np.sin(arg)
        for i in range(3):
            out[:, i] += amp[m, i] * c
            si = -amp[m, i] * s
            for j in range(3):
                jac[:, 3 * i + j] += si * k[m, j]


def _error_bound(x, y, z, t, k, amp, omega, phase):
    """``((P, 3), (P, 9))`` bounds on the sum's and the Jacobian's distance from the libm formula's: per mode,
    the argument's rounding (FMA-contracted or not, a few ulp of its terms' magnitudes) times the amplitude,
    plus 1e-15 for the cosine and sine themselves and the additions."""
    eps = np.finfo(float).eps
    bo, bj = np.zeros((x.size, 3)), np.zeros((x.size, 9))
    for m in range(k.shape[0]):
        mag = abs(k[m, 0] * x) + abs(k[m, 1] * y) + abs(k[m, 2] * z) + abs(omega[m] * t) + abs(phase[m])
        e = 4.0 * eps * mag + 1e-15
        for i in range(3):
            bo[:, i] += abs(amp[m, i]) * e
            for j in range(3):
                bj[:, 3 * i + j] += abs(amp[m, i] * k[m, j]) * e
    return bo + 1e-15, bj + 1e-15


def _inputs(rng: np.random.Generator, n: int, modes: int):
    f = WindField.dryden(mean_mps=7.7, direction_rad=0.4, sigma_mps=1.3, length_m=152.0, vertical_factor=0.6,
                         modes=modes, seed=int(rng.integers(1000)))
    pts = rng.uniform(-300.0, 300.0, (n, 3))
    pts[:, 2] = rng.uniform(2.0, 120.0, n)
    t = rng.uniform(0.0, 900.0, n)
    _, t, x, y, z = f._advected(pts, t)
    return f, pts, t, x, y, z


@pytest.mark.parametrize("n", [1, 5, _BLOCK - 1, _BLOCK, _BLOCK + 1, 3 * _BLOCK + 17])
@pytest.mark.parametrize("modes", [1, 2, 7, 128])
def test_mode_sum_and_jacobian_are_the_formula_and_the_same_bits_on_any_thread_count(n, modes):
    rng = np.random.default_rng(n * 131 + modes)
    f, _, t, x, y, z = _inputs(rng, n, modes)
    start_out = rng.normal(size=(n, 3))
    start_jac = rng.normal(size=(n, 9))  # added to, not overwritten
    want_out, want_jac = start_out.copy(), start_jac.copy()
    _numpy_sum_and_jacobian(want_out, want_jac, x, y, z, t, *f._modes())
    bound_out, bound_jac = _error_bound(x, y, z, t, *f._modes())
    first = None
    for threads in (1, 2, 3):
        out = start_out.copy()
        wide = np.full((n, WIND_GRAD_SIZE), 7.5)  # the tables' wider rows: columns 9, 10 left alone
        wide[:, 0:9] = start_jac
        turbulence_sum_and_jacobian(out, wide, x, y, z, t, *f._modes(), threads=threads)
        assert np.all(np.abs(out - want_out) <= bound_out)
        assert np.all(np.abs(wide[:, 0:9] - want_jac) <= bound_jac)
        assert np.all(wide[:, 9:] == 7.5)
        if first is None:
            first = out, np.ascontiguousarray(wide[:, 0:9])
        assert _same_bits(out, first[0]) and _same_bits(np.ascontiguousarray(wide[:, 0:9]), first[1]), threads
    # The points from the 17th on, summed by themselves: every block cut elsewhere, the same bits.
    cut = min(17, n - 1)
    out, jac = start_out[cut:].copy(), start_jac[cut:].copy()
    turbulence_sum_and_jacobian(out, jac, x[cut:], y[cut:], z[cut:], t[cut:], *f._modes(), threads=2)
    assert _same_bits(out, first[0][cut:]) and _same_bits(jac, first[1][cut:])


def test_mode_cosine_and_sine_are_libms_to_a_few_ulp_over_a_wide_argument_range():
    # One mode along x with unit amplitude isolates the sum's cosine and sine: out = cos(x),
    # jac[0] = -sin(x). Arguments up to 2e4 rad (the flights' reach ~1e3) and around the
    # quadrant boundaries (odd multiples of π/4), where the reduction switches polynomials.
    rng = np.random.default_rng(5)
    quarter = (2 * rng.integers(-20_000, 20_000, 4000) + 1) * (math.pi / 4)
    x = np.concatenate([rng.uniform(-2e4, 2e4, 20_000), rng.uniform(-7.0, 7.0, 20_000), quarter,
                        np.nextafter(quarter, np.inf), np.nextafter(quarter, -np.inf), [0.0, -0.0]])
    zeros = np.zeros_like(x)
    k, amp = np.array([[1.0, 0.0, 0.0]]), np.array([[1.0, 0.0, 0.0]])
    out, jac = np.zeros((x.size, 3)), np.zeros((x.size, 9))
    turbulence_sum_and_jacobian(out, jac, x, zeros, zeros, zeros, k, amp, np.zeros(1), np.zeros(1))
    assert np.abs(out[:, 0] - np.cos(x)).max() <= 4.5e-16
    assert np.abs(-jac[:, 0] - np.sin(x)).max() <= 4.5e-16
    assert out[-1, 0] == 1.0 and jac[-1, 0] == 0.0  # cos 0 and sin 0 exactly


def test_velocity_and_gradients_keep_the_bits_of_velocity_and_the_formula():
    rng = np.random.default_rng(3)
    f, pts, t, x, y, z = _inputs(rng, 2 * _BLOCK + 3, 128)
    vel, jac, shear = f.velocity_and_gradients(pts, t)
    assert _same_bits(vel, f.velocity(pts, t))
    want_out, want_jac = f.mean_velocity(pts[:, 2]), np.zeros((pts.shape[0], 9))
    _numpy_sum_and_jacobian(want_out, want_jac, x, y, z, t, *f._modes())
    bound_out, bound_jac = _error_bound(x, y, z, t, *f._modes())
    assert np.all(np.abs(vel - want_out) <= bound_out)
    assert np.all(np.abs(jac.reshape(-1, 9) - want_jac) <= bound_jac)
    assert _same_bits(shear, f.mean_shear(pts[:, 2]))
    v2, g2 = np.empty_like(vel), np.full((pts.shape[0], WIND_GRAD_SIZE), np.nan)
    f.velocity_and_gradients_into(pts, t, v2, g2, threads=2)
    assert _same_bits(v2, vel) and _same_bits(np.ascontiguousarray(g2[:, 0:9]), jac.reshape(-1, 9))
    assert _same_bits(np.ascontiguousarray(g2[:, 9:11]), shear)


@pytest.mark.parametrize("chunks", [[1001], [400, 601], [1, 999, 300]])
def test_tables_on_two_threads_are_the_one_thread_bits(chunks, monkeypatch):
    # Small enough to be quick, so the threshold that keeps tiny tables on one thread is lowered.
    monkeypatch.setattr(tables_mod, "_THREAD_MIN_POINT_MODES", 0)
    rng = np.random.default_rng(len(chunks))
    ref = TrackingReference.circle(rng.uniform(-80.0, 80.0, (300, 3)) + [0.0, 0.0, 40.0], radius_m=3.0,
                                   omega_rad_s=0.5)

    def tables():
        return ErrorTables(error_preset("gps-only"), seed=11, drone_ids=np.arange(300) * 3, plant=QuadrotorParams(),
                           dt_s=1e-3, duration_s=1.0)

    one, two, step = tables(), tables(), 0
    for count in chunks:
        a, b = one.chunk(step, count, ref, threads=1), two.chunk(step, count, ref, threads=2)
        assert a.gnss.shape[0] > 0 and a.wind.shape[0] >= 2
        for name in ("gnss", "wind", "wind_grad"):
            assert _same_bits(getattr(a, name), getattr(b, name)), name
        assert (a.gnss_first, a.wind_k0, a.wind_radius_m) == (b.gnss_first, b.wind_k0, b.wind_radius_m)
        step += count
    # The GNSS thread's error reaches the caller (chunks out of order).
    with pytest.raises(ValueError, match="in order"):
        two.chunk(0, 500, ref, threads=2)


def test_a_flight_is_the_same_bits_with_one_table_thread_and_with_two(monkeypatch):
    rng = np.random.default_rng(8)
    ref = TrackingReference.circle(rng.uniform(-60.0, 60.0, (64, 3)) + [0.0, 0.0, 30.0], radius_m=2.0,
                                   omega_rad_s=0.7)
    monkeypatch.setattr(tables_mod, "_THREAD_MIN_POINT_MODES", 0)

    def fly(threads):
        monkeypatch.setattr(tables_mod, "table_threads", lambda: threads)
        return simulate(ref, duration_s=0.7, engine="numba", output_every=7, errors=error_preset("gps-only"),
                        seed=4, chunk_steps=230, telemetry=True)

    a, b = fly(1), fly(2)
    for name in ("positions_m", "telemetry", "rms_error_m", "max_error_m", "final_state"):
        assert _same_bits(getattr(a, name), getattr(b, name)), name


def test_share_blocks_runs_every_block_once_and_raises_the_first_error():
    seen: list[tuple[int, str]] = []
    lock = threading.Lock()

    def work(b):
        with lock:
            seen.append((b, threading.current_thread().name))

    share_blocks(37, work, threads=3)
    assert sorted(b for b, _ in seen) == list(range(37))
    share_blocks(0, work, threads=2)  # nothing to do
    assert len(seen) == 37

    def fail(b):
        if b == 5:
            raise KeyError("block 5")

    with pytest.raises(KeyError, match="block 5"):
        share_blocks(40, fail, threads=2)
    with pytest.raises(ZeroDivisionError):
        Beside(lambda: 1 / 0).result()
    assert Beside(lambda: 41 + 1).result() == 42
