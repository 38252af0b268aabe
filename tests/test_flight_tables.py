"""The compiled random streams, GNSS tables and piece evaluation give the very bits of their numpy formulas.

The streams are counter-based (a value is a function of its key only), so a stored seed must
keep meaning the same flight: the compiled versions are checked bit for bit against the numpy
formulas they replaced, written out again here as the independent computation, on random
keys, chunkings and pieces, and a whole simulation with every error model on is flown with
the old formulas patched back in and compared bit for bit.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sim.flight.engines._tables as tables_mod
from sim.flight import QuadrotorParams, TrackingReference, error_preset, simulate
from sim.flight._random import STREAMS, hashed_normal, hashed_uniform, uniform_pairs_grid
from sim.flight.engines._tables import ErrorTables
from sim.plan import Trajectories, TrajectoryBuilder
from sim.plan._trajectory import TrajectorySample, rest_to_rest_quintic_coeffs

# ---------------------------------------------------------------------------------------------
# The numpy formulas the compiled code replaced (verbatim, the reference)
# ---------------------------------------------------------------------------------------------
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _old_mix(z):
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return np.asarray(z ^ (z >> np.uint64(31)))


def _old_hash(seed, drone, stream, counter, lane):
    with np.errstate(over="ignore"):
        h = _old_mix(np.uint64(seed & 0xFFFFFFFFFFFFFFFF) * _GOLDEN + np.uint64(stream))
        h = _old_mix(h ^ (np.asarray(drone, dtype=np.uint64) * _GOLDEN))
        h = _old_mix(h ^ (np.asarray(counter, dtype=np.uint64) * _GOLDEN + np.uint64(lane)))
    return h


def _old_uniform(seed, drone, stream, counter, lane=0):
    h = _old_hash(seed, drone, stream, counter, lane)
    return ((h >> np.uint64(11)).astype(np.float64) + 0.5) * (1.0 / 9007199254740992.0)


def _old_normal(seed, drone, stream, counter):
    u1 = _old_uniform(seed, drone, stream, counter, 0)
    u2 = _old_uniform(seed, drone, stream, counter, 1)
    return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)


def _old_gnss_chunk(self: ErrorTables, step0: int, count: int) -> tuple[np.ndarray, int]:
    n = self.ids.size
    gnss = np.zeros((0, n, 3))
    first = 0
    if self.use_gnss:
        ge = self.gnss_every
        first_epoch = -(-step0 // ge)
        last_epoch = (step0 + count - 1) // ge
        epochs = np.arange(first_epoch, last_epoch + 1)
        first = first_epoch * ge
        if epochs.size:
            assert epochs[0] == self._bias_epoch + 1
            e = self.errors
            counter = epochs[:, None, None] * 3 + np.arange(3)[None, None, :]
            drone = self.ids[None, :, None]
            walk = e.gnss_bias_walk_m_per_sqrt_s * math.sqrt(ge * self.dt_s)
            steps = walk * self._axis_sigma * _old_normal(self.seed, drone, STREAMS["gnss_walk"], counter)
            steps[epochs == 0] = 0.0
            bias = np.empty_like(steps)
            current = self._bias
            for e_row in range(epochs.size):
                current = current + steps[e_row]
                bias[e_row] = current
            self._bias = current.copy()
            self._bias_epoch = int(epochs[-1])
            white = e.gnss_noise_m * self._axis_sigma * _old_normal(self.seed, drone, STREAMS["gnss_white"], counter)
            gnss = np.ascontiguousarray(bias + white)
    return gnss, first


def _old_horner(c, u):
    acc = c[..., -1].copy()
    for k in range(c.shape[-1] - 2, -1, -1):
        acc = acc * u + c[..., k]
    return acc


def _old_derivative_coeffs(c, order):
    out = np.array(c, copy=True)
    for _ in range(order):
        k = np.arange(1, out.shape[-1], dtype=np.float64)
        out = np.concatenate([out[..., 1:] * k, np.zeros_like(out[..., :1])], axis=-1)
    return out


def _old_evaluate(self: Trajectories, times_s, drones=None, *, derivatives: int = 2):
    t = np.atleast_1d(np.asarray(times_s, dtype=np.float64))
    rows = self._rows(drones)
    pos = np.empty((len(t), len(rows), 3))
    vel = np.zeros_like(pos)
    acc = np.zeros_like(pos)
    inside = ((t >= self.start_s) & (t <= self.end_s))[:, None, None]
    tc = np.clip(t, self.start_s, self.end_s)
    idx = self.piece_index(tc, rows)
    c = self.coeffs_m[rows[None, :], idx]
    u = (tc[:, None] - self.breaks_s[rows[None, :], idx])[..., None]
    pos[:] = _old_horner(c, u)
    if derivatives >= 1:
        vel[:] = np.where(inside, _old_horner(_old_derivative_coeffs(c, 1), u), 0.0)
    if derivatives >= 2:
        acc[:] = np.where(inside, _old_horner(_old_derivative_coeffs(c, 2), u), 0.0)
    return TrajectorySample(pos, vel, acc)


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


# ---------------------------------------------------------------------------------------------
# Streams
# ---------------------------------------------------------------------------------------------
@settings(max_examples=40, deadline=None)
@given(seed=st.integers(-(2**70), 2**70), stream=st.integers(0, 2**20), lane=st.integers(0, 5),
       key_seed=st.integers(0, 2**32 - 1))
def test_compiled_streams_are_the_numpy_formula_bit_for_bit(seed, stream, lane, key_seed):
    rng = np.random.default_rng(key_seed)
    drone = rng.integers(0, 2**62, (9, 1)) * rng.integers(1, 3)  # up to 2⁶³: the uint64 cast wraps alike
    counter = rng.integers(0, 2**62, (1, 5))
    uniform = hashed_uniform(seed, drone, stream, counter, lane)
    assert _same_bits(uniform, _old_uniform(seed, drone, stream, counter, lane))
    assert _same_bits(hashed_normal(seed, drone, stream, counter), _old_normal(seed, drone, stream, counter))
    # Scalars and broadcasts the error tables use.
    assert _same_bits(hashed_normal(seed, drone[:, 0], stream, 0), _old_normal(seed, drone[:, 0], stream, 0))
    grid = (np.arange(4)[:, None] * 3 + np.arange(3)[None, :]) + int(rng.integers(0, 2**40))
    u1, u2 = np.empty((4, 9, 3)), np.empty((4, 9, 3))
    uniform_pairs_grid(seed, drone[:, 0], stream, grid, u1, u2)
    assert _same_bits(u1, _old_uniform(seed, drone[None, :, :], stream, grid[:, None, :], 0))
    assert _same_bits(u2, _old_uniform(seed, drone[None, :, :], stream, grid[:, None, :], 1))


def test_normals_over_many_keys_hit_numpys_log_where_libm_differs():
    # numpy's AVX-512 log and libm's differ in the last bit for ~0.3 % of arguments: over 2·10⁵
    # keys a compiled log would show; the numbers must stay numpy's.
    drone, counter = np.arange(2000)[:, None], np.arange(100)[None, :]
    assert _same_bits(hashed_normal(11, drone, 8, counter), _old_normal(11, drone, 8, counter))


# ---------------------------------------------------------------------------------------------
# GNSS tables
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("preset", ["gusty-rtk", "gps-only"])
@pytest.mark.parametrize("chunk_steps", [1, 37, 100, 450])
def test_gnss_tables_are_the_numpy_formula_bit_for_bit_in_any_chunking(preset, chunk_steps):
    errors = error_preset(preset)
    ids = np.random.default_rng(chunk_steps).choice(10**6, 57, replace=False)

    def tables():
        return ErrorTables(errors, seed=-3 + chunk_steps, drone_ids=ids, plant=QuadrotorParams(), dt_s=1e-3,
                           duration_s=1.0)

    new, old = tables(), tables()
    step = 0
    while step < 1203:
        count = min(chunk_steps, 1203 - step)
        g_new, f_new = new._gnss_chunk(step, count)
        g_old, f_old = _old_gnss_chunk(old, step, count)
        assert f_new == f_old and _same_bits(g_new, g_old)
        step += count
    assert _same_bits(new._bias, old._bias) and new._bias_epoch == old._bias_epoch
    with pytest.raises(ValueError, match="in order"):
        new._gnss_chunk(0, 10)


# ---------------------------------------------------------------------------------------------
# Wind tables
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("chunks", [[1000, 1000, 1], [1, 999, 417, 584], [2001]])
def test_wind_table_rows_are_the_same_bits_in_any_chunking(chunks):
    # Consecutive chunks share their boundary grid row, which the tables reuse instead of summing it
    # again: every row must still be the one a fresh, whole-flight table holds at that grid time.
    rng = np.random.default_rng(6)
    ref = TrackingReference.circle(rng.uniform(-80.0, 80.0, (23, 3)) + [0.0, 0.0, 40.0], radius_m=3.0,
                                   omega_rad_s=0.5)

    def tables():
        return ErrorTables(error_preset("gusty-rtk"), seed=5, drone_ids=np.arange(23), plant=QuadrotorParams(),
                           dt_s=1e-3, duration_s=2.0)

    whole = tables().chunk(0, 2001, ref)
    assert np.abs(whole.wind_grad).max() > 1e-3  # the rows hold a real field
    split, step = tables(), 0
    for count in chunks:
        part = split.chunk(step, count, ref)
        rows = slice(part.wind_k0 - whole.wind_k0, part.wind_k0 - whole.wind_k0 + part.wind.shape[0])
        assert _same_bits(part.wind, whole.wind[rows]) and _same_bits(part.wind_grad, whole.wind_grad[rows])
        step += count
    # Another reference is another field sample: its first row is summed, not taken from the tail.
    other = TrackingReference.circle(rng.uniform(-80.0, 80.0, (23, 3)) + [0.0, 0.0, 40.0], radius_m=3.0,
                                     omega_rad_s=0.5)
    fresh = tables()
    fresh.chunk(0, 1000, ref)
    second = fresh.chunk(1000, 1000, other)
    assert _same_bits(second.wind, tables().chunk(0, 2001, other).wind[10:21])
    assert not _same_bits(second.wind[0], whole.wind[10])


# ---------------------------------------------------------------------------------------------
# Piece evaluation
# ---------------------------------------------------------------------------------------------
def _random_motion(rng: np.random.Generator, n: int, pieces: int) -> Trajectories:
    b = TrajectoryBuilder(rng.uniform(-5.0, 5.0, (n, 3)), start_s=float(rng.uniform(-2.0, 2.0)))
    for _ in range(pieces):
        d = rng.uniform(0.0, 2.0, n) * (rng.random(n) > 0.3)  # zero-length pieces too
        end = b.positions_m + rng.uniform(-3.0, 3.0, (n, 3)) * (d > 0)[:, None]
        b.append(d, rest_to_rest_quintic_coeffs(b.positions_m, end, d))
    b.hold_until(b.times_s.max())
    return b.build()


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 12), pieces=st.integers(1, 6), derivatives=st.integers(0, 2))
def test_compiled_evaluation_is_the_numpy_formula_bit_for_bit(seed, n, pieces, derivatives):
    rng = np.random.default_rng(seed)
    m = _random_motion(rng, n, pieces)
    # Inside, outside, exactly at the breaks (where the later piece is taken) and at the ends.
    t = np.concatenate([rng.uniform(m.start_s - 1.0, m.end_s + 1.0, 30), m.breaks_s.ravel(), [m.start_s, m.end_s]])
    drones = [None, rng.permutation(n)[: max(1, n // 2)]]
    for d in drones:
        new = m.evaluate(t, d, derivatives=derivatives)
        old = _old_evaluate(m, t, d, derivatives=derivatives)
        for a, b in zip(new, old, strict=True):
            assert _same_bits(a, b)


# ---------------------------------------------------------------------------------------------
# A whole flight
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("engine", ["numba", "numpy"])
def test_a_flight_with_every_error_model_is_bit_identical_to_the_numpy_formulas(engine, monkeypatch):
    rng = np.random.default_rng(4)
    motion = _random_motion(rng, 24, 3)
    centers = motion.evaluate([motion.start_s], derivatives=0).positions_m[0]
    refs = [TrackingReference(motion=motion, duration_s=motion.end_s),
            TrackingReference.circle(centers + [0.0, 0.0, 30.0], radius_m=2.0, omega_rad_s=0.7)]
    # Every model on, with a GNSS walk that matters and a clock offset of 10 ms.
    errors = error_preset("gps-only")
    assert errors.has_gnss and errors.has_wind and errors.has_spread and errors.clock_offset_s > 0
    duration = 1.3 if engine == "numba" else 0.25

    def fly(ref):
        return simulate(ref, duration_s=duration, engine=engine, output_every=7, errors=errors, seed=9,
                        chunk_steps=173, drone_ids=np.arange(24) * 5 + 2, telemetry=True)

    new = [fly(r) for r in refs]
    monkeypatch.setattr(ErrorTables, "_gnss_chunk", _old_gnss_chunk)
    monkeypatch.setattr(tables_mod, "hashed_normal", _old_normal)
    monkeypatch.setattr(Trajectories, "evaluate", _old_evaluate)
    old = [fly(r) for r in refs]
    for a, b in zip(new, old, strict=True):
        assert a.diverged_step.max() < 0
        for name in ("positions_m", "telemetry", "rms_error_m", "max_error_m", "max_thrust_step_n", "final_state"):
            assert _same_bits(getattr(a, name), getattr(b, name)), name
        assert _same_bits(a.extra["estimate"], b.extra["estimate"])
        assert _same_bits(a.extra["drone"], b.extra["drone"])
