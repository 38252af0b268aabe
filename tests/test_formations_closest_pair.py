"""The show file's closest-pair search against brute force (ties, duplicates, flat and 1-D sets)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from formations._points import SWEEP_MAX_POINTS, closest_pair, nearest_pair_distance


def brute(points: np.ndarray) -> tuple[int, int, float]:
    """Every pair's distance (i < j); the least, and of equal ones the first (i, j) in row-major order:
    the smallest i, then j. Whole-matrix numpy (a Python loop over the pairs took most of the 100 examples'
    time at up to 300 points)."""
    n = len(points)
    d = np.sqrt(np.sum((points[:, None, :] - points[None, :, :]) ** 2, axis=-1))
    d[np.tril_indices(n)] = math.inf  # only i < j
    i, j = np.unravel_index(int(np.argmin(d)), d.shape)
    return int(i), int(j), float(d[i, j])


coords = st.integers(-6, 6).map(lambda v: v * 0.5)  # a coarse lattice makes ties and duplicates common


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(coords, coords, coords), min_size=2, max_size=40))
def test_matches_brute_force_with_ties(raw: list[tuple[float, float, float]]) -> None:
    pts = np.array(raw)
    i, j, d = closest_pair(pts)
    bi, bj, bd = brute(pts)
    assert (i, j) == (bi, bj)  # the smallest (i, j) among the closest
    assert math.isclose(d, bd, rel_tol=0, abs_tol=1e-12)


@settings(max_examples=100, deadline=None)
@given(st.integers(2, 300), st.integers(0, 2**32 - 1), st.sampled_from(["cloud", "plane", "line"]))
def test_random_sets(n: int, seed: int, shape: str) -> None:
    rng = np.random.default_rng(seed)
    pts = rng.normal(0.0, 20.0, (n, 3))
    if shape == "plane":
        pts[:, 1] = 7.0
    elif shape == "line":
        pts[:, 0] = pts[:, 2] = -3.0
    i, j, d = closest_pair(pts)
    bi, bj, bd = brute(pts)
    assert math.isclose(d, bd, rel_tol=1e-12) and (i, j) == (bi, bj)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from(["cloud", "plane", "grid"]))
def test_large_sets_take_the_kdtree_and_agree_with_the_sweep(seed: int, shape: str) -> None:
    rng = np.random.default_rng(seed)
    n = SWEEP_MAX_POINTS + 1 + int(rng.integers(0, 500))
    if shape == "grid":
        side = int(np.ceil(np.sqrt(n)))
        pts = np.stack(np.meshgrid(np.arange(side), np.arange(side), [0.0]), axis=-1).reshape(-1, 3)[:n] * 2.0
        pts = pts + rng.normal(0.0, 1e-3, pts.shape)
    else:
        pts = rng.normal(0.0, 30.0, (n, 3))
        if shape == "plane":
            pts[:, 2] = 5.0
    i, j, d = closest_pair(pts)
    assert i < j and math.isclose(d, float(np.linalg.norm(pts[i] - pts[j])), rel_tol=1e-12)
    # The sweep on the same points (its size limit lifted) finds the same distance.
    import formations._points as points_module

    old = points_module.SWEEP_MAX_POINTS
    points_module.SWEEP_MAX_POINTS = 10**9
    try:
        assert closest_pair(pts)[2] == d
    finally:
        points_module.SWEEP_MAX_POINTS = old


def test_small_and_degenerate() -> None:
    assert closest_pair(np.zeros((1, 3))) == (-1, -1, math.inf)
    assert closest_pair(np.zeros((3, 3))) == (0, 1, 0.0)
    assert nearest_pair_distance(np.array([[0.0, 0.0], [3.0, 4.0]])) == 5.0
    grid = np.stack(np.meshgrid(np.arange(40.0), np.arange(40.0), [10.0]), axis=-1).reshape(-1, 3) * 3.0
    assert closest_pair(grid) == (0, 1, 3.0)
