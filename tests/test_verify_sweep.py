"""The swept-ball grid candidate search and the pruned peaks against independent computations.

Oracles: the k-d-tree-per-slice search (the previous reference path) and the exact kernel on
all pairs (no pruning at all); per-part speed bounds converted part by part in numpy; peaks
without pruning.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.verify import _poly, piece_extrema, speed_bounds, window_close_pairs
from tests.test_verify_exact import all_pairs_exact, random_piecewise


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 60), radius=st.floats(0.3, 12.0),
       spread=st.floats(2.0, 40.0), cut=st.floats(0.0, 1.0))
def test_sweep_equals_all_pairs_and_kdtree(seed: int, n: int, radius: float, spread: float, cut: float) -> None:
    motion = random_piecewise(seed, n, spread=spread)
    t0 = motion.start_s + cut * 0.5 * (motion.end_s - motion.start_s)  # also windows inside the show
    t1 = motion.end_s
    i, j, d = all_pairs_exact(motion, t0, t1)
    expected = {(int(a), int(b)): float(x) for a, b, x in zip(i, j, d, strict=True) if x <= radius}
    sweep = window_close_pairs(motion, t0, t1, radius, method="sweep")
    tree = window_close_pairs(motion, t0, t1, radius, method="kdtree")
    got = {(int(a), int(b)): float(x) for a, b, x in zip(sweep.i, sweep.j, sweep.dist_m, strict=True)}
    ref = {(int(a), int(b)): float(x) for a, b, x in zip(tree.i, tree.j, tree.dist_m, strict=True)}
    strict = {k for k, v in expected.items() if v < radius * (1 - 1e-9)}
    assert strict <= set(got)
    for k in strict:
        assert got[k] == pytest.approx(expected[k], abs=1e-9)
        assert got[k] == pytest.approx(ref[k], abs=1e-9)
    assert set(got) <= set(expected) | {k for k in got if abs(got[k] - radius) < 1e-7}


def test_sweep_finds_a_brief_close_pass_between_resting_drones() -> None:
    """Two drones cross 0.5 m apart for an instant in a long window where everyone else rests far away:
    the pair is found with the closed-form minimum of their constant-velocity crossing."""
    from sim.plan._trajectory import TrajectoryBuilder

    rng = np.random.default_rng(3)
    far = rng.uniform(100, 400, (30, 3)) * np.array([1, 1, 0.2])
    start = np.vstack([[[-50.0, 0.0, 10.0], [0.0, -50.0, 10.5]], far])
    vel = np.zeros_like(start)
    vel[0] = [10.0, 0.0, 0.0]
    vel[1] = [0.0, 10.0, 0.0]
    b = TrajectoryBuilder(start, 0.0)
    b.hold_until(np.full(len(start), 20.0))
    lin = np.zeros((len(start), 3, 2))
    lin[..., 0], lin[..., 1] = start, vel
    b.append(np.full(len(start), 10.0), lin)
    b.hold_until(np.full(len(start), 60.0))
    motion = b.build()
    got = window_close_pairs(motion, 0.0, 60.0, 1.0)
    assert [(int(a), int(c)) for a, c in zip(got.i, got.j, strict=True)] == [(0, 1)]
    assert got.dist_m[0] == pytest.approx(0.5, abs=1e-9)
    assert got.time_s[0] == pytest.approx(25.0, abs=1e-4)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 10))
def test_speed_bounds_by_subdivision_equal_per_part_conversion(seed: int, n: int) -> None:
    motion = random_piecewise(seed, n)
    got = speed_bounds(motion)
    b, c = motion.breaks_s, motion.coeffs_m
    parts = got.shape[2]
    for i in range(n):
        for p in range(motion.piece_count):
            length = b[i, p + 1] - b[i, p]
            vel = np.polynomial.polynomial.polyder(c[i, p].T).T  # (3, D)
            for s in range(parts):
                h = length / parts
                if h <= 0:
                    continue
                # |v|² on the part, in u' = u - s·h, then its Bernstein coefficients (independently, in numpy)
                shifted = [np.polynomial.Polynomial(v).__call__(np.polynomial.Polynomial([s * h, 1.0])).coef
                           for v in vel]
                sq = sum(np.polynomial.polynomial.polymul(x, x) for x in shifted)
                full = np.zeros(_poly.NB + 1)
                full[:len(sq)] = sq
                deg = _poly.NB
                scaled = full * h ** np.arange(deg + 1)
                bern = [sum(math.comb(k, m) / math.comb(deg, m) * scaled[m] for m in range(k + 1))
                        for k in range(deg + 1)]
                want = math.sqrt(max(max(bern), 0.0))
                assert got[i, p, s] == pytest.approx(want, rel=1e-9, abs=1e-9)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 8), frac=st.floats(0.2, 1.2))
def test_pruned_peaks_keep_every_peak_and_every_excess_exact(seed: int, n: int, frac: float) -> None:
    motion = random_piecewise(seed, n)
    exact = piece_extrema(motion)
    lim = (float(exact.speed_xy_mps.max() * frac), float(exact.speed_z_mps.max() * frac),
           float(exact.accel_mps2.max() * frac), float(exact.z_max_m.max() * frac), float(exact.z_min_m.min() / frac))
    pruned = piece_extrema(motion, lim)
    pairs = [(exact.speed_xy_mps, pruned.speed_xy_mps, lim[0], 1), (exact.speed_z_mps, pruned.speed_z_mps, lim[1], 1),
             (exact.accel_mps2, pruned.accel_mps2, lim[2], 1), (exact.z_max_m, pruned.z_max_m, lim[3], 1),
             (exact.z_min_m, pruned.z_min_m, lim[4], -1)]
    for e, p, limit, sense in pairs:
        # every drone's peak is exact
        best_e = e.max(axis=1) if sense > 0 else e.min(axis=1)
        best_p = p.max(axis=1) if sense > 0 else p.min(axis=1)
        np.testing.assert_allclose(best_p, best_e, rtol=1e-9, atol=1e-9)
        # pieces past the limit are exact; the others never overstate
        over = sense * e > sense * limit + 1e-6 * (1 + abs(limit))
        np.testing.assert_allclose(p[over], e[over], rtol=1e-9, atol=1e-9)
        assert np.all(sense * p <= sense * e + 1e-9 * (1 + np.abs(e)))


@pytest.mark.parametrize("spacing", [3.0, 2.0])
def test_check_on_threads_reports_exactly_what_the_sequential_check_reports(spacing: float, monkeypatch) -> None:
    """The segments searched on threads give the same report, field for field (violations in the same order
    included), as one after another; at 2 m spacing (below CAPT's guarantee) there are violations to order."""
    from sim.bench._dense import dense_show
    from sim.plan import plan_show
    from sim.verify import _check, check_plan

    show = dense_show(60, formations=3, spacing_m=spacing)
    show = show.model_copy(update={"settings": show.settings.model_copy(update={"min_distance_m": 3.0})})
    plan = plan_show(show)
    check_plan(plan)  # a parallel kernel has run: the threading layer is known
    monkeypatch.setattr(_check, "PARALLEL_MIN_DRONES", 1 << 30)
    sequential = check_plan(plan)
    monkeypatch.setattr(_check, "PARALLEL_MIN_DRONES", 0)
    assert _check._threads_ok(60) == (_check.workers() >= 2)
    threaded = check_plan(plan)
    assert threaded.model_dump() == sequential.model_dump()
    assert (sequential.violations_total > 0) == (spacing < 3.0)
