"""Spacing: measurement, repair, farthest-point sampling and "fit to N drones" (metres)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from formations._points import (
    FormationError,
    PointSet,
    as_points,
    check_n,
    check_positive,
    nearest_pair_distance,
)

#: Relative shortfall a generator may have and still be fixed by a negligible uniform scale-up
#: (round-off at the exact limit, e.g. a 27 m grid of 10 x 10 at 3 m).
_TOL = 1e-6
#: Relative margin the returned points keep above the minimum, so that any exact
#: re-measurement (brute force, other libraries) also sees >= the minimum.
_MARGIN = 2e-9

#: A repair may move no point by more than this many minimum spacings (else the shape is lost).
MAX_REPAIR_SHIFT = 1.0
#: Repair is only tried for local defects (crossing or touching strokes): when at most this
#: fraction of the points is too close to a neighbour. Denser sets cannot be spread within
#: MAX_REPAIR_SHIFT anyway, and relaxing them would cost seconds for nothing.
MAX_REPAIR_CLOSE_FRACTION = 0.25

RawGenerator = Callable[[int], tuple[np.ndarray, np.ndarray]]


def meets(distance: float, min_spacing_m: float) -> bool:
    """True if ``distance`` satisfies ``min_spacing_m`` up to the fixable round-off."""
    return distance >= min_spacing_m * (1.0 - _TOL)


def ensure_spacing(points: np.ndarray, min_spacing_m: float) -> np.ndarray | None:
    """Return ``points`` (possibly scaled up by < 1e-6 about their centroid) if they keep
    ``min_spacing_m`` with a tiny margin, else None."""
    d = nearest_pair_distance(points)
    if d >= min_spacing_m * (1.0 + 1e-9):
        return points
    if not meets(d, min_spacing_m) or d <= 0.0:
        return None
    c = points.mean(axis=0)
    out = (points - c) * (min_spacing_m * (1.0 + _MARGIN) / d) + c
    return out if nearest_pair_distance(out) >= min_spacing_m else None


def largest_fitting(fits: Callable[[int], bool], n_fail: int) -> int:
    """Largest k in [1, n_fail) with ``fits(k)`` by bisection (``fits(1)`` is assumed true).

    The returned k was verified with ``fits``.
    """
    lo, hi = 1, int(n_fail)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if fits(mid):
            lo = mid
        else:
            hi = mid
    return lo


def no_fit_error(what: str, n: int, min_spacing_m: float, max_n: int) -> FormationError:
    """The FormationError for ``n`` points that do not fit (message states ``max_n``)."""
    return FormationError(
        f"{n} points do not fit {what} at a minimum spacing of {min_spacing_m:g} m; "
        f"the largest N that fits is {max_n} (or make it larger / lower the spacing)",
        max_n=max_n,
    )


def accept_spacing(points: np.ndarray, min_spacing_m: float, *, repair: bool) -> np.ndarray | None:
    """``points`` made to keep ``min_spacing_m`` (see :func:`ensure_spacing`), or None.

    With ``repair``, points that are too close are spread with :func:`repair_spacing` when
    the defect is local (at most MAX_REPAIR_CLOSE_FRACTION of the points involved) and the
    result is accepted if no point moved more than MAX_REPAIR_SHIFT minimum spacings.
    """
    good = ensure_spacing(points, min_spacing_m)
    if good is not None or not repair or len(points) < 2:
        return good
    nn, _ = cKDTree(points).query(points, k=2)
    if np.mean(nn[:, 1] < min_spacing_m) > MAX_REPAIR_CLOSE_FRACTION:
        return None
    fixed, achieved = repair_spacing(points, min_spacing_m)
    shift = float(np.linalg.norm(fixed - points, axis=1).max())
    if achieved >= min_spacing_m and shift <= MAX_REPAIR_SHIFT * min_spacing_m:
        return ensure_spacing(fixed, min_spacing_m)
    return None


def guarantee(
    raw: RawGenerator,
    n: int,
    min_spacing_m: float,
    *,
    what: str,
    repair: bool = False,
) -> PointSet:
    """Build ``n`` points with ``raw(n)`` and enforce ``min_spacing_m`` (:func:`accept_spacing`).

    Otherwise raise a FormationError whose ``max_n`` is found by bisection with the same
    acceptance rule, so ``max_n`` points are accepted and ``max_n + 1`` are not.
    """
    pts, cols = raw(n)
    good = accept_spacing(pts, min_spacing_m, repair=repair)
    if good is None:
        max_n = largest_fitting(
            lambda k: accept_spacing(raw(k)[0], min_spacing_m, repair=repair) is not None, n
        )
        raise no_fit_error(what, n, min_spacing_m, max_n)
    return PointSet(good, cols)


def _span_projector(pts: np.ndarray) -> np.ndarray:
    """Projector onto the affine span of the points (keeps planar drawings planar)."""
    centred = pts - pts.mean(axis=0)
    _, sv, vt = np.linalg.svd(centred, full_matrices=False)
    if sv.size == 0 or sv[0] <= 0.0:
        return np.eye(pts.shape[1])
    basis = vt[sv > 1e-9 * sv[0]]
    out: np.ndarray = basis.T @ basis
    return out


def repair_spacing(
    points_m: ArrayLike, min_spacing_m: float, *, max_iter: int = 200, seed: int = 0
) -> tuple[np.ndarray, float]:
    """Push apart points closer than ``min_spacing_m`` while staying near the drawn shape.

    Each iteration finds all pairs closer than the minimum (plus 0.1 %) with a cKDTree and
    moves both points of each pair apart along their joining line by half the overlap
    (coincident points get a seeded random direction inside the drawing's plane or line).
    Points that are far enough apart never move, so the shape is kept.

    Args:
        points_m: (N, 3) metres (or (N, 2)).
        min_spacing_m: required nearest-pair distance, metres.
        max_iter: most relaxation iterations.
        seed: seed for the directions of coincident points (deterministic).

    Returns:
        (points, achieved_min_spacing_m); the achieved value may still be below the minimum
        if the points cannot be spread within ``max_iter`` iterations.
    """
    pts = as_points(points_m, name="points_m", dims=(2, 3)).copy()
    s = check_positive(min_spacing_m, name="min_spacing_m")
    if len(pts) < 2:
        return pts, math.inf
    rng = np.random.default_rng(seed)
    proj = _span_projector(pts)
    target = s * (1.0 + 1e-3)
    for _ in range(int(max_iter)):
        pairs = cKDTree(pts).query_pairs(target, output_type="ndarray")
        if len(pairs) == 0:
            break
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
        i, j = pairs[:, 0], pairs[:, 1]
        delta = pts[j] - pts[i]
        dist = np.linalg.norm(delta, axis=1)
        zero = dist < 1e-9 * s
        if zero.any():
            rnd = rng.normal(size=(int(zero.sum()), pts.shape[1])) @ proj
            rn = np.linalg.norm(rnd, axis=1, keepdims=True)
            rnd = np.where(rn > 0, rnd / np.maximum(rn, 1e-300), proj[:1] / np.linalg.norm(proj[0]))
            delta[zero] = rnd
            dist[zero] = 1.0
        unit = delta / dist[:, None]
        dist[zero] = 0.0
        push = (0.5 * (target - dist))[:, None] * unit
        disp = np.zeros_like(pts)
        np.add.at(disp, i, -push)
        np.add.at(disp, j, push)
        pts += disp
    return pts, nearest_pair_distance(pts)


def farthest_point_order(
    points: ArrayLike, n: int, *, start: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Greedy farthest-point sampling of ``n`` of the (M, d) ``points`` (deterministic).

    Args:
        points: (M, d) candidates.
        n: how many to pick (at most M are picked).
        start: first index; None = the candidate nearest the centroid.

    Returns:
        (indices (k,), distances (k,)): distances[i] is the distance from the i-th pick to the
        nearest earlier pick (inf for the first) and is non-increasing, so the picks'
        nearest-pair distance is ``distances[-1]``; any prefix is itself a valid sample.
    """
    pts = np.asarray(points, dtype=np.float64)
    m = len(pts)
    k = min(int(n), m)
    idx = np.empty(k, dtype=np.intp)
    dists = np.empty(k, dtype=np.float64)
    if k == 0:
        return idx, dists
    if start is None:
        start = int(np.argmin(((pts - pts.mean(axis=0)) ** 2).sum(axis=1)))
    tree = cKDTree(pts) if m > 2048 else None
    min_d2 = np.full(m, np.inf)
    cur, dcur = int(start), math.inf
    for t in range(k):
        idx[t] = cur
        dists[t] = math.sqrt(dcur)
        p = pts[cur]
        if tree is None or not math.isfinite(dcur):
            np.minimum(min_d2, ((pts - p) ** 2).sum(axis=1), out=min_d2)
        else:
            near = np.asarray(
                tree.query_ball_point(p, r=math.sqrt(dcur) * (1 + 1e-9), return_sorted=False),
                dtype=np.intp,
            )
            if near.size:
                min_d2[near] = np.minimum(min_d2[near], ((pts[near] - p) ** 2).sum(axis=1))
        cur = int(np.argmax(min_d2))
        dcur = float(min_d2[cur])
    return idx, dists


def sample_candidates(
    candidates: np.ndarray, n: int, min_spacing_m: float, *, what: str
) -> np.ndarray:
    """Pick ``n`` evenly spread candidates (farthest-point) keeping ``min_spacing_m``.

    Returns the picked indices; raises FormationError with ``max_n`` (the longest prefix of
    the same farthest-point order that keeps the spacing) if they do not fit.
    """
    if len(candidates) == 0:
        raise FormationError(f"{what} has no points to sample", max_n=0)
    idx, dists = farthest_point_order(candidates, n)
    ok = dists >= min_spacing_m * (1.0 - _TOL)
    if len(idx) < n or not ok[-1]:
        raise no_fit_error(what, n, min_spacing_m, int(ok.sum()))
    return idx


def _grow_along_polyline(
    pts: np.ndarray, cols: np.ndarray, k: int
) -> tuple[np.ndarray, np.ndarray]:
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = cum[-1]
    if total <= 0.0:
        raise FormationError("cannot grow a drawing whose points all coincide")
    s = np.linspace(0.0, total, k)
    out = np.column_stack([np.interp(s, cum, pts[:, a]) for a in range(pts.shape[1])])
    nearest = np.clip(np.searchsorted(cum, s, side="left"), 0, len(pts) - 1)
    prev = np.clip(nearest - 1, 0, len(pts) - 1)
    pick = np.where(np.abs(cum[prev] - s) <= np.abs(cum[nearest] - s), prev, nearest)
    return out, cols[pick]


def fit_to_count(
    points_m: ArrayLike, colors_rgb: ArrayLike, n: int, *, min_spacing_m: float = 3.0
) -> PointSet:
    """Fit a drawn point set to exactly ``n`` drones, then enforce the spacing.

    Reducing keeps a farthest-point subsample (in drawing order); growing resamples the
    drawing, taken as a polyline in its point order, evenly by arc length (colours from the
    nearest drawn point). Points that end up too close are spread with :func:`repair_spacing`.

    Args:
        points_m: (M, 3) drawn points, metres.
        colors_rgb: (M, 3) colours 0-255.
        n: number of points wanted.
        min_spacing_m: minimum distance between any two points, metres.

    Raises:
        FormationError: bad arguments, or the points cannot keep the spacing (``max_n`` set).
    """
    pts = as_points(points_m, name="points_m")
    cols = np.asarray(colors_rgb)
    if cols.shape != pts.shape or not np.all(np.isfinite(cols)):
        raise FormationError(f"colors_rgb must have shape {pts.shape}, got {cols.shape}")
    cols = np.clip(cols, 0, 255).astype(np.uint8)
    n = check_n(n)
    s = check_positive(min_spacing_m, name="min_spacing_m")
    if len(pts) == 0:
        raise FormationError("points_m is empty")
    m = len(pts)

    def raw(k: int) -> tuple[np.ndarray, np.ndarray]:
        if k == m:
            return pts, cols
        if k < m:
            idx = np.sort(farthest_point_order(pts, k)[0])
            return pts[idx], cols[idx]
        return _grow_along_polyline(pts, cols, k)

    return guarantee(raw, n, s, what="the drawing", repair=True)
