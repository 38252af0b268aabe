"""sim.geometry.closest_pair: exact against brute force, and a clear error (never a hang) on NaN/inf points."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.distance import pdist, squareform

from sim.geometry import closest_pair


@pytest.mark.parametrize("seed", range(5))
def test_matches_brute_force(seed: int) -> None:
    pts = np.random.default_rng(seed).uniform(-30, 30, size=(200, 3))
    i, j, d = closest_pair(pts)
    m = squareform(pdist(pts))
    np.fill_diagonal(m, np.inf)
    assert d == pytest.approx(m.min(), rel=1e-12) and i < j and m[i, j] == pytest.approx(d, rel=1e-12)


@pytest.mark.timeout(30)
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_points_are_refused(bad: float) -> None:
    pts = np.random.default_rng(5).uniform(-20, 20, size=(25, 3))
    pts[3, 1] = bad
    with pytest.raises(ValueError, match="finite"):
        closest_pair(pts)
