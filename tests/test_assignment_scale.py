"""Scalable exact assignment: equals scipy's dense optimum, certificate holds, tampering is caught."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

from sim.bench._shows import grid_to_sphere_input
from sim.plan._assignment import SPARSE_MIN_DRONES, AssignmentError, assign, assignment_cost, certify
from sim.plan._assignment_sparse import _kd_order, _scan_all_pairs, solve_sparse


def dense_optimum(x: np.ndarray, g: np.ndarray) -> float:
    """scipy's dense LSA on the full squared-distance matrix (the reference)."""
    c = cdist(x, g, "sqeuclidean")
    r, col = linear_sum_assignment(c)
    return float(c[r, col].sum())


def random_pair(n: int, m: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Uniform drones and goals in overlapping boxes at show density (~4.5 m spacing)."""
    rng = np.random.default_rng(seed)
    side = 4.5 * max(n, m) ** (1 / 3) * 1.2
    return rng.uniform(0, side, (n, 3)), rng.uniform(0, side, (m, 3)) + [0.3 * side, 0.0, 10.0]


def assert_valid_optimum(x: np.ndarray, g: np.ndarray, goal_index: np.ndarray, cost: float) -> None:
    assert goal_index.shape == (len(x),)
    assert len(np.unique(goal_index)) == len(x)
    assert goal_index.min() >= 0 and goal_index.max() < len(g)
    assert cost == pytest.approx(assignment_cost(x, g, goal_index), rel=1e-12, abs=1e-9)
    assert cost == pytest.approx(dense_optimum(x, g), rel=1e-9, abs=1e-9)


STRUCTURED = {
    "grid_to_sphere_1200": lambda: grid_to_sphere_input(1200),
    "grid_to_sphere_1500": lambda: grid_to_sphere_input(1500),
    "random_1500": lambda: random_pair(1500, 1500, 1),
    "random_rect_900x1000": lambda: random_pair(900, 1000, 2),
    "random_rect_400x1200": lambda: random_pair(400, 1200, 4),  # many spare goals: dummy drones bid
    # A rigid shift of a ring-like cloud: a huge set of near-optimal permutations.
    "shifted_copy_1000": lambda: (lambda p: (p, p + [3.0, 0.0, 0.0]))(random_pair(1000, 1, 3)[0]),
}


@pytest.mark.parametrize("name", sorted(STRUCTURED))
def test_sparse_equals_dense_and_certifies(name: str) -> None:
    x, g = STRUCTURED[name]()
    sol = solve_sparse(x, g)
    assert sol is not None
    assert_valid_optimum(x, g, sol.goal_index, sol.cost_m2)
    cert = sol.certificate
    assert cert.ok
    assert 0.0 <= cert.gap_bound_m2 <= cert.tolerance_m2
    assert cert.lower_bound_m2 <= dense_optimum(x, g) * (1 + 1e-12) + 1e-9  # weak duality
    assert cert.max_violation_m2 <= cert.tolerance_m2
    assert (sol.prices_m2 >= 0).all()
    # The public certify() agrees, with the solver's prices and with freshly solved ones.
    assert certify(x, g, sol.goal_index, prices_m2=sol.prices_m2).ok
    assert certify(x, g, sol.goal_index).ok


def test_assign_picks_sparse_above_threshold_and_keeps_its_results() -> None:
    x, g = grid_to_sphere_input(SPARSE_MIN_DRONES + 200)
    a = assign(x, g)
    assert a.certificate is not None and a.certificate.ok
    dense = assign(x, g, method="dense")
    assert dense.certificate is None
    assert a.cost_m2 == pytest.approx(dense.cost_m2, rel=1e-9)
    small = assign(*grid_to_sphere_input(50))
    assert small.certificate is None  # dense below the threshold


def test_tampered_assignment_fails_the_certificate() -> None:
    x, g = random_pair(1200, 1200, 7)
    sol = solve_sparse(x, g)
    assert sol is not None and sol.certificate.ok
    rng = np.random.default_rng(0)
    for _ in range(5):
        i, j = rng.choice(len(x), 2, replace=False)
        tampered = sol.goal_index.copy()
        tampered[[i, j]] = tampered[[j, i]]
        extra = assignment_cost(x, g, tampered) - sol.cost_m2
        cert = certify(x, g, tampered, prices_m2=sol.prices_m2)
        if extra > 10 * cert.tolerance_m2:
            assert not cert.ok
            assert cert.gap_bound_m2 >= extra * (1 - 1e-9)  # the bound sees the whole loss
            assert cert.violating_drones >= 1
        # Without prices certify() solves for them: the same verdict.
        assert certify(x, g, tampered).ok == cert.ok


def test_tampered_with_spare_goal_fails() -> None:
    """Moving a drone to an unused goal (M > N) that is worse is caught too."""
    x, g = random_pair(300, 340, 11)
    sol = solve_sparse(x, g)
    assert sol is not None
    unused = np.setdiff1d(np.arange(len(g)), sol.goal_index)
    tampered = sol.goal_index.copy()
    tampered[0] = unused[np.argmax(((g[unused] - x[0]) ** 2).sum(axis=1))]  # the farthest spare goal
    assert assignment_cost(x, g, tampered) > sol.cost_m2 + 1.0
    assert not certify(x, g, tampered, prices_m2=sol.prices_m2).ok


def test_more_drones_than_goals_is_an_error() -> None:
    with pytest.raises(AssignmentError, match="3 drones but only 2 goals"):
        assign(np.zeros((3, 3)), np.ones((2, 3)), method="sparse")
    with pytest.raises(AssignmentError, match="3 drones but only 2 goals"):
        certify(np.zeros((3, 3)), np.ones((2, 3)), np.array([0, 1, 1]))


def test_certify_rejects_a_non_injective_goal_index() -> None:
    x, g = random_pair(10, 10, 0)
    with pytest.raises(AssignmentError, match="distinct"):
        certify(x, g, np.zeros(10, dtype=np.int64))
    with pytest.raises(AssignmentError, match="integers"):
        certify(x, g, np.zeros(3, dtype=np.int64))


@pytest.mark.parametrize("k", [1, 5])
def test_blocked_scan_equals_brute_force(k: int) -> None:
    """The branch-and-bound all-pairs scan returns exactly the brute-force minima (bit for bit)."""
    rng = np.random.default_rng(k)
    x, g = random_pair(700, 900, k)
    x, g = x[_kd_order(x)], g[_kd_order(g)]
    for prices in (np.zeros(len(g)), rng.uniform(0, 500, len(g)), 40.0 * g[:, 0] + rng.uniform(0, 5, len(g))):
        cand, row_min, row_assigned = _scan_all_pairs(
            x, *(np.ascontiguousarray(g[:, d]) for d in range(3)), prices, k, np.arange(len(x), dtype=np.int64)
        )
        w = cdist(x, g, "sqeuclidean") + prices
        assert np.array_equal(row_min, w.min(axis=1))
        kth = np.sort(w, axis=1)[:, k - 1]
        assert np.array_equal(np.take_along_axis(w, cand, axis=1).max(axis=1), kth)
        np.testing.assert_allclose(row_assigned, w[np.arange(len(x)), np.arange(len(x))], rtol=1e-14)


def test_lower_bound_holds_for_arbitrary_prices() -> None:
    """Weak duality: any prices give a lower bound on the dense optimum, so ok=True is never a false claim."""
    x, g = random_pair(200, 230, 5)
    opt = dense_optimum(x, g)
    rng = np.random.default_rng(1)
    sol = solve_sparse(x, g)
    assert sol is not None
    for prices in (np.zeros(len(g)), rng.uniform(0, 1e3, len(g)), sol.prices_m2 + rng.uniform(0, 1, len(g))):
        cert = certify(x, g, sol.goal_index, prices_m2=prices)
        assert cert.lower_bound_m2 <= opt + 1e-9 * opt


def _instances(draw_kind: str, n: int, extra: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    m = n + extra
    if draw_kind == "uniform":
        return rng.uniform(-20, 20, (n, 3)), rng.uniform(-20, 20, (m, 3))
    if draw_kind == "lattice_ties":  # small integer lattice: duplicates and many exact ties
        return rng.integers(0, 3, (n, 3)).astype(float), rng.integers(0, 3, (m, 3)).astype(float)
    if draw_kind == "collinear":
        t, s = rng.uniform(0, 30, (n, 1)), rng.uniform(0, 30, (m, 1))
        d = np.array([[1.0, 2.0, -0.5]])
        return t * d, s * d + [0.0, 1.0, 0.0]
    if draw_kind == "identical":  # every drone at one point, every goal at another
        return np.tile([1.0, 2.0, 3.0], (n, 1)), np.tile([4.0, -2.0, 0.5], (m, 1))
    # "same_set": goals are the drones (plus spares): the optimum is 0
    x = rng.uniform(-10, 10, (n, 3))
    return x, np.r_[x, rng.uniform(-10, 10, (extra, 3))][rng.permutation(m)]


@settings(max_examples=60, deadline=None)
@given(
    kind=st.sampled_from(["uniform", "lattice_ties", "collinear", "identical", "same_set"]),
    n=st.integers(1, 40),
    extra=st.integers(0, 6),
    k=st.integers(1, 6),
    seed=st.integers(0, 2**31 - 1),
)
def test_small_instances_match_dense(kind: str, n: int, extra: int, k: int, seed: int) -> None:
    """Tiny candidate sets force column generation; ties and degenerate geometry must not matter."""
    x, g = _instances(kind, n, extra, seed)
    sol = solve_sparse(x, g, candidates=k)
    assert sol is not None
    assert sol.certificate.ok
    assert_valid_optimum(x, g, sol.goal_index, sol.cost_m2)
    a = assign(x, g, method="sparse")
    assert a.cost_m2 == pytest.approx(dense_optimum(x, g), rel=1e-9, abs=1e-9)
