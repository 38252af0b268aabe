"""The closed form for synchronised straight-line segments (CAPT with one shared time law).

Within such a segment every drone follows p_i(β) = A_i + β·D_i with one shared
β in [0, 1], so a pair's offset is a + β·c (a = A_j - A_i, c = D_j - D_i) and its
minimum over β has the closed form β* = clip(-a·c / c·c, 0, 1) (Turpin et al.
2014, CAPT, the separation argument behind eq. 11).

Plans no longer share one β per segment (drones are staggered), so the show
check (:mod:`sim.verify._check`) minimises piecewise polynomials instead; this
closed form remains for one-transition benchmarks and as an independent oracle
in the tests.

Candidate pairs come from ``scipy.spatial.cKDTree`` in β-slices, with a radius
that provably misses no pair: subtracting the mean motion (which does not change
any pair's distance), each drone moves at most L_i·h/2 away from its position at
the centre of a slice of width h, so a pair that comes within r somewhere in the
slice is within r + L_max·h at its centre. With h = 1/ceil(L_max/r) the query
radius is at most 2r.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree


class PairMinima:
    """Exact pair minima of one segment: i < j, distance (m), β at the minimum."""

    def __init__(self, i: np.ndarray, j: np.ndarray, dist: np.ndarray, beta: np.ndarray) -> None:
        self.i, self.j, self.dist, self.beta = i, j, dist, beta


def segment_close_pairs(start_m: np.ndarray, end_m: np.ndarray, radius_m: float) -> PairMinima:
    """Every pair whose exact minimum distance during a synchronised straight segment is <= ``radius_m``.

    Args:
        start_m, end_m: (N, 3) positions at β = 0 and β = 1, metres.
        radius_m: search radius, metres (> 0).

    Returns:
        The pairs (i < j) with their exact minimum distance and the β where it occurs.
    """
    n = len(start_m)
    empty = PairMinima(*(np.zeros(0, dtype=np.int64),) * 2, np.zeros(0), np.zeros(0))
    if n < 2:
        return empty
    motion = end_m - start_m
    motion = motion - motion.mean(axis=0)  # a common translation changes no distance
    l_max = float(np.sqrt((motion**2).sum(axis=1).max()))
    slices = max(1, math.ceil(l_max / radius_m)) if l_max > 1e-12 else 1
    h = 1.0 / slices
    query_r = radius_m + l_max * h
    found = []
    for s in range(slices):
        centre = start_m + ((s + 0.5) * h) * motion
        pairs = cKDTree(centre).query_pairs(query_r, output_type="ndarray")
        if len(pairs):
            found.append(pairs[:, 0].astype(np.int64) * n + pairs[:, 1])
    if not found:
        return empty
    keys = np.unique(np.concatenate(found))
    i, j = np.minimum(keys // n, keys % n), np.maximum(keys // n, keys % n)
    a = start_m[j] - start_m[i]
    c = motion[j] - motion[i]
    cc = (c * c).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        beta = np.where(cc > 0, np.clip(-(a * c).sum(axis=1) / cc, 0.0, 1.0), 0.0)
    dist = np.linalg.norm(a + beta[:, None] * c, axis=1)
    keep = dist <= radius_m
    return PairMinima(i[keep], j[keep], dist[keep], beta[keep])
