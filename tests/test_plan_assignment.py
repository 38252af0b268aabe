"""CAPT assignment: optimal against brute force and against scipy on the raw cost matrix."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

from sim import AssignmentError, assign, assignment_cost
from tests.conftest import fibonacci_sphere


def brute_force_cost(x: np.ndarray, g: np.ndarray) -> float:
    best = np.inf
    for perm in itertools.permutations(range(len(g)), len(x)):
        best = min(best, float(((x - g[list(perm)]) ** 2).sum()))
    return best


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 6), extra=st.integers(0, 2), seed=st.integers(0, 2**31 - 1))
def test_cost_equals_brute_force(n: int, extra: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    x = rng.uniform(-20, 20, (n, 3))
    g = rng.uniform(-20, 20, (n + extra, 3))
    a = assign(x, g)
    assert a.cost_m2 == pytest.approx(brute_force_cost(x, g), rel=1e-12, abs=1e-9)
    assert len(set(a.goal_index.tolist())) == n  # each goal at most one drone
    assert a.cost_m2 == pytest.approx(assignment_cost(x, g, a.goal_index), rel=1e-12)


def test_seven_drones_brute_force() -> None:
    rng = np.random.default_rng(7)
    x, g = rng.normal(size=(7, 3)) * 10, rng.normal(size=(7, 3)) * 10
    assert assign(x, g).cost_m2 == pytest.approx(brute_force_cost(x, g), rel=1e-12)


@pytest.mark.parametrize("n,m", [(300, 300), (200, 260)])
def test_cost_equals_scipy_on_raw_matrix(n: int, m: int) -> None:
    """The reduced matrix must not change the optimum (square: rows and columns; N < M: rows only)."""
    side = int(np.ceil(np.sqrt(n)))
    gx, gy = np.meshgrid(np.arange(side) * 3.0, np.arange(side) * 3.0)
    grid = np.c_[gx.ravel(), gy.ravel(), np.zeros(gx.size)][:n]
    goals = fibonacci_sphere(m, 25.0)
    c = cdist(grid, goals, "sqeuclidean")
    r, col = linear_sum_assignment(c)
    assert assign(grid, goals).cost_m2 == pytest.approx(float(c[r, col].sum()), rel=1e-12)


def test_more_drones_than_goals_is_an_error() -> None:
    with pytest.raises(AssignmentError, match="3 drones but only 2 goals"):
        assign(np.zeros((3, 3)), np.ones((2, 3)))


def test_non_finite_input_is_an_error() -> None:
    with pytest.raises(AssignmentError, match="finite"):
        assign(np.array([[np.nan, 0, 0]]), np.zeros((1, 3)))


def _lsa_cost(x: np.ndarray, g: np.ndarray) -> float:
    cost = cdist(x, g, "sqeuclidean")
    rows, cols = linear_sum_assignment(cost)
    return float(cost[rows, cols].sum())


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(600, 1200), extra=st.integers(0, 40),
       garbage=st.booleans())
def test_warm_started_sparse_assignment_is_exactly_optimal(seed: int, n: int, extra: int, garbage: bool) -> None:
    """A warm start (another problem's prices and targets, or garbage) changes the work, never the optimum:
    the cost equals scipy's linear_sum_assignment on the full matrix."""
    from sim.plan._schedule import spread

    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    x = np.column_stack([np.arange(n) % side * 3.0, np.arange(n) // side * 3.0, np.full(n, 10.0)])
    g = rng.uniform(-40, 40, (n + extra, 3))
    g[:, 1] *= 0.1  # a flat-ish vertical formation
    base = assign(x, g, method="sparse")
    assert base.prices_m2 is not None
    sx, sg = spread(x, 1.28, 3.0, 1e4), spread(g, 1.28, 3.0, 1e4, similar=True)
    assert sx is not None and sg is not None
    if garbage:
        base = type(base)(rng.permutation(len(g))[:n], 0.0, None, rng.uniform(0, 1e4, len(g)))
    warm = assign(sx, sg, method="sparse", warm=base)
    cold = assign(sx, sg, method="sparse")
    assert len(np.unique(warm.goal_index)) == n
    ref = _lsa_cost(sx, sg)
    assert warm.cost_m2 == pytest.approx(ref, rel=1e-9)
    assert assignment_cost(sx, sg, warm.goal_index) == pytest.approx(ref, rel=1e-9)
    assert cold.cost_m2 == pytest.approx(ref, rel=1e-9)
