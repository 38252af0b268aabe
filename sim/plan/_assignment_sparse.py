"""Exact CAPT assignment at scale: sparse ε-scaling auction, column generation, dual certificate.

The dense solver needs the N x M float64 cost matrix (800 MB at 10,000 drones)
and its augmenting-path search slows down badly on the near-ties of structured
formations. This module never stores that matrix:

1. **Coarse-to-fine prices.** Every 4th point of each set (k-d order) forms a
   coarse problem, solved recursively down to ~500 drones; its duals,
   interpolated to first order, are the fine level's starting goal prices and
   its assignment predicts each drone's target. B. Schmitzer, "A sparse
   multiscale algorithm for dense optimal transport", J. Math. Imaging Vision
   56 (2016), arXiv:1510.05466; Q. Mérigot, "A multiscale approach to optimal
   transport", Comput. Graph. Forum 30 (2011).
2. **Candidate edges.** Per drone the k goals of least reduced cost c_ij + p_j
   and the k goals nearest its predicted target; per goal the k drones of least
   c_ij - u_i (so no goal is reachable only through a far edge); plus a
   Morton-curve rank matching, which keeps a perfect matching in the graph so
   that the auction always terminates.
3. **Sparse solve.** Bertsekas' Gauss-Seidel forward auction with ε-scaling
   (min-cost form: drone i bids for argmin_j c_ij + p_j and raises its price by
   the gap to the second best plus ε). On termination every drone is ε-happy:
   c_iσ(i) + p_σ(i) <= min_j (c_ij + p_j) + ε over its edges. D. P. Bertsekas,
   "The auction algorithm: a distributed relaxation method for the assignment
   problem", Annals of Operations Research 14 (1988); "The auction algorithm
   for assignment and other network flow problems: a tutorial", MIT LIDS-P-1908
   (1989), on ε-complementary slackness and ε-scaling.
4. **Column generation over all pairs.** An exact branch-and-bound scan of all
   N x M pairs (numba ``prange`` over drone blocks; nothing N x M is stored)
   gives each drone's true best reduced cost min_j (c_ij + p_j). A drone whose
   goal is worse by more than ε lacks an edge: its k best goals under the
   current prices join the graph and the auction resumes warm (same prices and
   assignment) — Schmitzer's "sequence of sparse problems verified by dual
   feasibility", with the auction as the inner solver.
5. **Certificate.** LP duality for min Σ c_iσ(i) over injections σ (each drone
   assigned once, each goal at most once): for prices p >= 0 and
   u_i = min_j (c_ij + p_j), (u, v = -p) is dual feasible for *every* pair and
   every assignment costs at least LB(p) = Σ_i u_i - Σ_j p_j (weak duality).
   Shifting p by its minimum is always allowed (it raises LB by (M - N)·min p).
   ``gap_bound_m2 = cost - LB`` >= cost - optimum; the auction's ε-CS makes it
   at most N·ε, and ε is chosen so that N·ε <= rel_tol·cost / 4. A tampered
   assignment fails because its cost exceeds the optimum, which LB cannot.

For N < M the problem is made square with M - N dummy drones that cost 0 to
every goal (the textbook reduction; Bertsekas, Castañon & Tsaknakis, "Reverse
auction and the solution of inequality constrained assignment problems", SIAM
J. Optim. 3 (1993) treat the asymmetric case directly). Dummies find the two
cheapest goals in a lazy min-heap of prices, O(log M) per bid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from scipy.spatial import cKDTree

#: Goals per drone added to the candidate graph in each column-generation round.
DEFAULT_CANDIDATES = 20
#: Relative optimality target: the certified gap is at most this fraction of the cost.
DEFAULT_REL_TOL = 1e-10
#: ε-scaling factor between auction phases (Bertsekas suggests 4-10).
_EPS_FACTOR = 6.0
#: Drones / goals per block in the branch-and-bound all-pairs scan.
_SCAN_BLOCK = 64


@dataclass(frozen=True)
class Certificate:
    """An optimality certificate for an assignment, from dual prices checked over all pairs.

    Attributes:
        ok: ``gap_bound_m2 <= tolerance_m2``: the assignment is optimal to within the tolerance.
        cost_m2: Σ_i ||x_i - g_σ(i)||² of the checked assignment, m².
        lower_bound_m2: a lower bound on every assignment's cost (weak LP duality), m².
        gap_bound_m2: ``cost_m2 - lower_bound_m2`` >= cost - optimum, m².
        tolerance_m2: the accepted gap, m².
        max_violation_m2: max over drones of c_iσ(i) + p_σ(i) - min_j (c_ij + p_j): the largest
            dual-feasibility violation of the potentials u_i = c_iσ(i) - v_σ(i), v = -p that are
            tight on the chosen edges (complementary slackness by construction), m².
        violating_drones: drones whose violation exceeds ``tolerance_m2 / N``.
        unused_price_m2: Σ of (shifted) prices of goals left unused (0 when M = N), m²;
            part of the gap (complementary slackness for spare goals).
    """

    ok: bool
    cost_m2: float
    lower_bound_m2: float
    gap_bound_m2: float
    tolerance_m2: float
    max_violation_m2: float
    violating_drones: int
    unused_price_m2: float


@dataclass(frozen=True)
class SparseSolution:
    """Result of :func:`solve_sparse`: assignment, goal prices (m²) and its certificate."""

    goal_index: np.ndarray  # (N,) int64
    cost_m2: float
    prices_m2: np.ndarray  # (M,) float64, >= 0
    certificate: Certificate
    rounds: int  # column-generation rounds at the finest scale (0: nearest goals were already distinct)
    edges: int  # candidate edges in the final sparse graph


# --------------------------------------------------------------------------- kernels


@numba.njit(cache=True)
def _block_bound(x0, x1, x2, g_lo, g_hi, slope, offset, gb):  # pragma: no cover - numba
    """Lower bound on min_j (||x - g_j||² + p_j) over goal block ``gb`` (real arithmetic).

    With p_j >= s·g_j + a on the block (``slope`` s, ``offset`` a):
    ||x - g||² + p >= ||g - (x - s/2)||² + x·s - ||s||²/4 + a, and the first
    term is at least the squared distance from x - s/2 to the block's box.
    """
    s0 = slope[gb, 0]
    s1 = slope[gb, 1]
    s2 = slope[gb, 2]
    z0 = x0 - 0.5 * s0
    z1 = x1 - 0.5 * s1
    z2 = x2 - 0.5 * s2
    e0 = max(0.0, g_lo[gb, 0] - z0, z0 - g_hi[gb, 0])
    e1 = max(0.0, g_lo[gb, 1] - z1, z1 - g_hi[gb, 1])
    e2 = max(0.0, g_lo[gb, 2] - z2, z2 - g_hi[gb, 2])
    lin = x0 * s0 + x1 * s1 + x2 * s2 - 0.25 * (s0 * s0 + s1 * s1 + s2 * s2)
    return e0 * e0 + e1 * e1 + e2 * e2 + lin + offset[gb]


@numba.njit(cache=True, parallel=True)
def _scan_all_pairs_kernel(x, gx, gy, gz, prices, k, assigned, g_lo, g_hi, slope, offset, margin):  # pragma: no cover
    """Branch-and-bound scan over all pairs; see :func:`_scan_all_pairs`."""
    n = x.shape[0]
    m = gx.shape[0]
    bs = _SCAN_BLOCK
    n_gb = g_lo.shape[0]
    cand = np.empty((n, k), dtype=np.int64)
    row_min = np.empty(n, dtype=np.float64)
    row_assigned = np.empty(n, dtype=np.float64)
    n_rb = (n + bs - 1) // bs
    for rb in numba.prange(n_rb):
        r0 = rb * bs
        r1 = min(n, r0 + bs)
        c0 = 0.0
        c1 = 0.0
        c2 = 0.0
        for i in range(r0, r1):
            c0 += x[i, 0]
            c1 += x[i, 1]
            c2 += x[i, 2]
        c0 /= r1 - r0
        c1 /= r1 - r0
        c2 /= r1 - r0
        lbc = np.empty(n_gb)
        for gb in range(n_gb):
            lbc[gb] = _block_bound(c0, c1, c2, g_lo, g_hi, slope, offset, gb)
        order = np.argsort(lbc)  # visit likely-best goal blocks first so the k-th best drops fast
        best_w = np.empty(k)
        best_j = np.empty(k, dtype=np.int64)
        for i in range(r0, r1):
            x0 = x[i, 0]
            x1 = x[i, 1]
            x2 = x[i, 2]
            for q in range(k):
                best_w[q] = np.inf
                best_j[q] = -1
            worst = np.inf
            worst_q = 0
            for t in range(n_gb):
                gb = order[t]
                if _block_bound(x0, x1, x2, g_lo, g_hi, slope, offset, gb) - margin > worst:
                    continue
                for j in range(gb * bs, min(m, gb * bs + bs)):
                    d0 = x0 - gx[j]
                    d1 = x1 - gy[j]
                    d2 = x2 - gz[j]
                    w = d0 * d0 + d1 * d1 + d2 * d2 + prices[j]
                    if w < worst:
                        best_w[worst_q] = w
                        best_j[worst_q] = j
                        worst = -np.inf
                        for q in range(k):
                            if best_w[q] > worst:
                                worst = best_w[q]
                                worst_q = q
            lo = np.inf
            for q in range(k):
                cand[i, q] = best_j[q]
                if best_w[q] < lo:
                    lo = best_w[q]
            row_min[i] = lo
            j = assigned[i]
            if j >= 0:
                d0 = x0 - gx[j]
                d1 = x1 - gy[j]
                d2 = x2 - gz[j]
                row_assigned[i] = d0 * d0 + d1 * d1 + d2 * d2 + prices[j]
            else:
                row_assigned[i] = np.nan
    return cand, row_min, row_assigned


def _scan_all_pairs(x, gx, gy, gz, prices, k, assigned):
    """For every drone: the k goals with least c_ij + p_j, that minimum, and c_iσ(i) + p_σ(i) (m²).

    Exact over all N x M pairs without storing them (branch and bound):
    goals are cut into blocks of ``_SCAN_BLOCK`` consecutive points (inputs in
    Morton order make the blocks compact); per block an affine minorant of the
    prices, p_j >= s·g_j + a (s fitted by least squares, a = min_j p_j - s·g_j),
    gives a lower bound on every reduced cost in the block for a drone
    (:func:`_block_bound`). A block whose bound exceeds the drone's k-th best so
    far, by more than a rounding margin, cannot contain a better goal and is
    skipped. The margin (1e-11 of the magnitudes involved, ~10^4 ulps) covers
    the floating-point error of the bound, so the result equals a full scan.
    Drones run in parallel blocks (numba ``prange``). ``assigned[i] < 0`` leaves
    the assigned-edge value NaN.
    """
    m = len(gx)
    bs = _SCAN_BLOCK
    n_gb = (m + bs - 1) // bs
    pad = n_gb * bs - m
    g = np.c_[gx, gy, gz]
    gp = np.concatenate([g, np.repeat(g[-1:], pad, axis=0)]).reshape(n_gb, bs, 3)
    pp = np.concatenate([prices, np.repeat(prices[-1:], pad)]).reshape(n_gb, bs)
    g_lo, g_hi = gp.min(axis=1), gp.max(axis=1)
    # Least-squares slope of price against position per block (ridge keeps flat blocks well posed).
    gc = gp - gp.mean(axis=1, keepdims=True)
    pc = pp - pp.mean(axis=1, keepdims=True)
    gram = np.einsum("bid,bie->bde", gc, gc) + 1e-9 * (1.0 + np.einsum("bid,bid->b", gc, gc))[:, None, None] * np.eye(3)
    slope = np.linalg.solve(gram, np.einsum("bid,bi->bd", gc, pc)[..., None])[..., 0]
    offset = (pp - np.einsum("bid,bd->bi", gp, slope)).min(axis=1)
    r2 = float(max(np.abs(x).max(initial=0.0), np.abs(g).max(initial=0.0))) ** 2
    magnitude = 8.0 * r2 + float(np.abs(prices).max(initial=0.0)) + float(np.abs(slope).max(initial=0.0)) ** 2 \
        + 4.0 * float(np.abs(slope).max(initial=0.0)) * np.sqrt(r2) + float(np.abs(offset).max(initial=0.0))
    return _scan_all_pairs_kernel(
        np.ascontiguousarray(x), gx, gy, gz, prices, k, np.asarray(assigned, dtype=np.int64), g_lo, g_hi,
        np.ascontiguousarray(slope), offset, 1e-11 * magnitude,
    )


@numba.njit(cache=True)
def _drop_unhappy(indptr, indices, cost, n_real, n_rows, prices, row_col, col_row, eps):  # pragma: no cover
    """Unassign drones that are not ε-happy at the new (smaller) ε, keeping the rest (warm start).

    Rows >= ``n_real`` are dummies with cost 0 to every goal.
    """
    m = prices.shape[0]
    p_min = np.inf
    for j in range(m):
        if prices[j] < p_min:
            p_min = prices[j]
    for i in range(n_rows):
        j = row_col[i]
        if j < 0:
            continue
        if i < n_real:
            lo = np.inf
            mine = np.inf
            for e in range(indptr[i], indptr[i + 1]):
                w = cost[e] + prices[indices[e]]
                if w < lo:
                    lo = w
                if indices[e] == j:
                    mine = w
        else:
            lo = p_min
            mine = prices[j]
        if mine > lo + eps:
            row_col[i] = -1
            col_row[j] = -1


@numba.njit(cache=True)
def _heap_push(hp, hj, size, p, j):  # pragma: no cover - numba
    """Push (p, j) on the binary min-heap (hp, hj) of ``size`` entries; returns the new size."""
    q = size
    hp[q] = p
    hj[q] = j
    while q > 0:
        parent = (q - 1) // 2
        if hp[parent] <= hp[q]:
            break
        hp[parent], hp[q] = hp[q], hp[parent]
        hj[parent], hj[q] = hj[q], hj[parent]
        q = parent
    return size + 1


@numba.njit(cache=True)
def _heap_pop(hp, hj, size):  # pragma: no cover - numba
    """Drop the heap's minimum; returns the new size."""
    size -= 1
    hp[0] = hp[size]
    hj[0] = hj[size]
    q = 0
    while True:
        lo = q
        left = 2 * q + 1
        if left < size and hp[left] < hp[lo]:
            lo = left
        if left + 1 < size and hp[left + 1] < hp[lo]:
            lo = left + 1
        if lo == q:
            return size
        hp[lo], hp[q] = hp[q], hp[lo]
        hj[lo], hj[q] = hj[q], hj[lo]
        q = lo


@numba.njit(cache=True)
def _heap_rebuild(hp, hj, prices):  # pragma: no cover - numba
    size = 0
    for j in range(prices.shape[0]):
        size = _heap_push(hp, hj, size, prices[j], j)
    return size


@numba.njit(cache=True)
def _auction(indptr, indices, cost, n_real, n_rows, prices, row_col, col_row, eps, big):  # pragma: no cover
    """Gauss-Seidel forward auction (min-cost form) until every row is assigned; returns the bid count.

    A bidder takes its best goal j1 (least c + p) and raises p_j1 by
    (second best - best) + ε, evicting the previous owner (Bertsekas 1988).
    With a perfect matching in the graph this terminates with ε-CS.

    Dummy rows (>= ``n_real``, cost 0 to every goal) bid for the two cheapest
    goals, found in a min-heap of prices with lazy deletion (an entry is live
    while it equals the goal's current price; prices only rise), so a dummy
    bid costs O(log M) instead of a scan of all M prices.
    """
    m = prices.shape[0]
    dummies = n_rows > n_real
    cap = 4 * m + 1024 if dummies else 1
    hp = np.empty(cap)
    hj = np.empty(cap, dtype=np.int64)
    hsize = _heap_rebuild(hp, hj, prices) if dummies else 0
    queue = np.empty(n_rows + 1, dtype=np.int64)
    head = 0
    tail = 0
    size = n_rows + 1
    for i in range(n_rows):
        if row_col[i] < 0:
            queue[tail] = i
            tail = (tail + 1) % size
    bids = 0
    while head != tail:
        i = queue[head]
        head = (head + 1) % size
        best = np.inf
        second = np.inf
        bj = -1
        if i < n_real:
            for e in range(indptr[i], indptr[i + 1]):
                w = cost[e] + prices[indices[e]]
                if w < best:
                    second = best
                    best = w
                    bj = indices[e]
                elif w < second:
                    second = w
        else:
            while prices[hj[0]] != hp[0]:
                hsize = _heap_pop(hp, hj, hsize)
            best = hp[0]
            bj = hj[0]
            hsize = _heap_pop(hp, hj, hsize)
            while hsize > 0 and prices[hj[0]] != hp[0]:
                hsize = _heap_pop(hp, hj, hsize)
            if hsize > 0:
                second = hp[0]
            hsize = _heap_push(hp, hj, hsize, best, bj)
        if second == np.inf:
            second = best + big
        prices[bj] += (second - best) + eps
        if dummies:
            if hsize == cap:
                hsize = _heap_rebuild(hp, hj, prices)
            else:
                hsize = _heap_push(hp, hj, hsize, prices[bj], bj)
        old = col_row[bj]
        col_row[bj] = i
        row_col[i] = bj
        if old >= 0:
            row_col[old] = -1
            queue[tail] = old
            tail = (tail + 1) % size
        bids += 1
    return bids


# --------------------------------------------------------------------------- helpers


def _sorted_unique(keys: np.ndarray) -> np.ndarray:
    """Sorted distinct values (a sort and a mask: numpy's hash-based ``unique`` is slower here)."""
    keys = np.sort(keys)
    return keys[np.r_[True, keys[1:] != keys[:-1]]] if len(keys) else keys


def _csr(
    keys: np.ndarray, n: int, m: int, x: np.ndarray, g: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CSR arrays (indptr, indices, cost m²) of the candidate edges ``keys = i·M + j`` (sorted, unique)."""
    rows = keys // m
    cols = keys % m
    indptr = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(rows, minlength=n), out=indptr[1:])
    diff = x[rows] - g[cols]
    cost = np.einsum("ij,ij->i", diff, diff)
    return indptr, cols.astype(np.int64), cost


def _lower_bound(row_min_shifted: np.ndarray, prices_shifted: np.ndarray) -> float:
    """Weak-duality bound Σ_i min_j (c_ij + p_j) - Σ_j p_j for prices p >= 0, m²."""
    return math.fsum(row_min_shifted) - math.fsum(prices_shifted)


def _tolerance(cost_m2: float, n: int, scale_m2: float, rel_tol: float) -> float:
    """Accepted gap: ``rel_tol`` of the cost plus N·1e-13·extent², m².

    The floor covers zero-cost instances and the float64 rounding of the
    certificate's own sums (each reduced cost is exact to ~1e-16·extent²).
    """
    return rel_tol * cost_m2 + n * 1e-13 * scale_m2


def _centred(x: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Both point sets shifted by one common centre (costs unchanged, less rounding); and extent² (m²)."""
    centre = 0.5 * (np.concatenate([x, g]).max(axis=0) + np.concatenate([x, g]).min(axis=0))
    xc = np.ascontiguousarray(x - centre)
    gc = np.ascontiguousarray(g - centre)
    extent = float(np.ptp(np.concatenate([xc, gc]), axis=0).max()) if len(x) else 0.0
    return xc, gc, max(extent, 1.0) ** 2


def _certificate_from_scan(
    cost_m2: float, prices: np.ndarray, goal_index: np.ndarray, row_min: np.ndarray, row_assigned: np.ndarray,
    scale_m2: float, rel_tol: float,
) -> Certificate:
    n, m = len(goal_index), len(prices)
    shift = float(prices.min()) if m else 0.0
    shifted = prices - shift
    lower = _lower_bound(row_min - shift, shifted)
    used = np.zeros(m, dtype=bool)
    used[goal_index] = True
    violation = row_assigned - row_min
    tol = _tolerance(cost_m2, n, scale_m2, rel_tol)
    gap = cost_m2 - lower
    return Certificate(
        ok=bool(gap <= tol),
        cost_m2=cost_m2,
        lower_bound_m2=lower,
        gap_bound_m2=gap,
        tolerance_m2=tol,
        max_violation_m2=float(violation.max()) if n else 0.0,
        violating_drones=int(np.count_nonzero(violation > tol / max(n, 1))),
        unused_price_m2=float(shifted[~used].sum()),
    )


def _morton_order(points: np.ndarray) -> np.ndarray:
    """Indices of ``points`` sorted along a Morton (Z-order) curve over their bounding box."""
    lo = points.min(axis=0)
    span = max(float(np.ptp(points, axis=0).max()), 1e-12)
    q = np.minimum(((points - lo) / span * 1023.0).astype(np.uint64), np.uint64(1023))
    code = np.zeros(len(points), dtype=np.uint64)
    for bit in range(10):
        for d in range(3):
            code |= ((q[:, d] >> np.uint64(bit)) & np.uint64(1)) << np.uint64(3 * bit + d)
    return np.argsort(code, kind="stable")


def _kd_order(points: np.ndarray, leaf: int = _SCAN_BLOCK) -> np.ndarray:
    """Indices of ``points`` so that consecutive runs of ``leaf`` points are compact k-d tree cells.

    Recursive split of the longest side at a multiple of ``leaf`` near the
    median, so the scan's blocks (``leaf`` consecutive points) have small
    bounding boxes; a Morton curve leaves long jumps inside blocks.
    """
    order = np.arange(len(points), dtype=np.int64)
    stack = [(0, len(points))]
    while stack:
        a, b = stack.pop()
        if b - a <= leaf:
            continue
        seg = order[a:b]
        pts = points[seg]
        axis = int(np.argmax(np.ptp(pts, axis=0)))
        half = max(leaf, ((b - a) // 2 + leaf // 2) // leaf * leaf)
        if half >= b - a:
            continue
        part = np.argpartition(pts[:, axis], half)
        order[a:b] = seg[part]
        stack += [(a, a + half), (a + half, b)]
    return order


def _stratified(points: np.ndarray, count: int) -> np.ndarray:
    """``count`` indices spread evenly over ``points``: every (len/count)-th point in k-d order (sorted)."""
    return np.sort(_kd_order(points)[(np.arange(count, dtype=np.int64) * len(points)) // count])


def _fallback_matching(x: np.ndarray, g: np.ndarray) -> np.ndarray:
    """A perfect matching of drones to distinct goals by rank along the Morton curve.

    Its edges keep every candidate graph feasible (so the auction terminates)
    while being local enough not to drag prices far when the auction must use
    one; a classic space-filling-curve approximation of the transport map.
    """
    goal_of = np.empty(len(x), dtype=np.int64)
    both = np.concatenate([x, g])
    order = _morton_order(both)  # one curve over both sets, so equal ranks are near each other
    xs, gs = order[order < len(x)], order[order >= len(x)] - len(x)
    goal_of[xs] = gs[(np.arange(len(x), dtype=np.int64) * len(g)) // len(x)]
    return goal_of


def _coarse_guess(
    x: np.ndarray, g: np.ndarray, *, ratio: int, base: int, candidates: int
) -> tuple[np.ndarray, np.ndarray] | None:
    """Goal prices and predicted targets from a coarse problem (every ``ratio``-th point of each set).

    Coarse-to-fine initialisation as in Schmitzer (2016) and Mérigot, "A
    multiscale approach to optimal transport", Comput. Graph. Forum 30 (2011):
    the discrete duals approximate the continuous Kantorovich potentials, so a
    coarse solve predicts the fine prices. First-order interpolation: the dual
    potential v = -p has gradient 2·(y - x_σ⁻¹(y)) at a goal y (Brenier), so
    p(y) ≈ p(y_c) - 2·(y_c - x_c)·(y - y_c) from the nearest coarse goal y_c.
    The coarse assignment also predicts each drone's target: x_i plus the
    displacement of its nearest coarse drone.

    Returns:
        (prices (M,) m², predicted targets (N, 3) m), or None when too small to coarsen.
    """
    n, m = len(x), len(g)
    n_c = n // ratio
    if n_c < base // 2:
        return None
    m_c = max(n_c, (m * n_c) // n)
    xs, gs = x[_stratified(x, n_c)], g[_stratified(g, m_c)]
    coarse = _solve(xs, gs, candidates=candidates, rel_tol=1e-6, max_rounds=30, ratio=ratio, base=base)
    if coarse is None:
        return None
    owner = np.full(m_c, -1, dtype=np.int64)
    owner[coarse.goal_index] = np.arange(n_c)
    _, near = cKDTree(gs).query(g)
    slope = np.where((owner[near] >= 0)[:, None], 2.0 * (gs[near] - xs[np.maximum(owner[near], 0)]), 0.0)
    prices = coarse.prices_m2[near] - np.einsum("ij,ij->i", slope, g - gs[near])
    _, near_x = cKDTree(xs).query(x)
    targets = x + (gs[coarse.goal_index[near_x]] - xs[near_x])
    return prices, targets


def _solve(
    x: np.ndarray, g: np.ndarray, *, candidates: int, rel_tol: float, max_rounds: int, ratio: int, base: int
) -> SparseSolution | None:
    guess = _coarse_guess(x, g, ratio=ratio, base=base, candidates=candidates) if len(x) > base else None
    return _solve_level(x, g, guess, candidates=candidates, rel_tol=rel_tol, max_rounds=max_rounds)


def _solve_level(
    x: np.ndarray, g: np.ndarray, guess: tuple[np.ndarray, np.ndarray] | None, *, candidates: int,
    rel_tol: float, max_rounds: int,
) -> SparseSolution | None:
    """Column generation around the sparse auction at one scale (see the module docstring)."""
    initial_prices = None if guess is None else guess[0]
    n, m = len(x), len(g)
    scale_m2 = max(float(np.ptp(np.concatenate([x, g]), axis=0).max()), 1.0) ** 2
    k = int(min(max(candidates, 1), m))
    gx, gy, gz = (np.ascontiguousarray(g[:, d]) for d in range(3))
    prices = np.zeros(m) if initial_prices is None else np.asarray(initial_prices, dtype=np.float64).copy()
    prices -= prices.min()
    n_rows = m  # N real drones, M - N dummies
    row_col = np.full(n_rows, -1, dtype=np.int64)
    col_row = np.full(m, -1, dtype=np.int64)
    ident = np.arange(n, dtype=np.int64)

    # Cost scale for ε: Σ_i min_j c_ij <= optimum, from a k-d tree on the raw goals (exact nearest).
    nearest_d, nearest = cKDTree(g).query(x)
    cost_floor = float(np.sum(nearest_d**2))
    if len(np.unique(nearest)) == n:
        # Every drone's nearest goal is its own (e.g. near-identity transitions): zero prices prove it
        # optimal, since then LB = Σ_i min_j c_ij equals the cost. Checked by the same all-pairs scan.
        zero = np.zeros(m)
        _, rmin0, w0 = _scan_all_pairs(x, gx, gy, gz, zero, 1, nearest.astype(np.int64))
        cost_m2 = _assignment_cost(x, g, nearest.astype(np.int64))
        cert = _certificate_from_scan(cost_m2, zero, nearest.astype(np.int64), rmin0, w0, scale_m2, rel_tol)
        if cert.ok:
            return SparseSolution(nearest.astype(np.int64), cost_m2, zero, cert, 0, n)
    cand, row_min, _ = _scan_all_pairs(x, gx, gy, gz, prices, k, row_col[:n])
    first = [np.repeat(ident, k) * m + cand.ravel(), ident * m + _fallback_matching(x, g)]
    first.append(_column_candidates(x, g, row_min, k, m))
    if guess is not None:
        _, near_t = cKDTree(g).query(guess[1], k=k)
        first.append(np.repeat(ident, k) * m + np.asarray(near_t, dtype=np.int64).ravel())
    # Drones may end up to 8·ε short of their true best (see `loose` below), so N·8·ε_final must stay
    # inside the certified gap rel_tol·cost (>= rel_tol·cost_floor): ε_final = rel_tol·cost_floor / (32·N).
    eps_final = max(rel_tol * cost_floor / (32.0 * n_rows), 1e-13 * scale_m2 / 32.0)
    keys = _sorted_unique(np.concatenate(first))
    indptr, indices, cost = _csr(keys, n, m, x, g)
    big = float(cost.max()) + scale_m2
    # First ε: a few squared goal spacings. Warm prices are off by about the coarse spacing squared;
    # from zero prices a larger ε (Bertsekas' C/θ) lets bids overshoot by up to ε, distorting prices on
    # goals outside the candidate graph, which costs many column-generation rounds to undo.
    d_nn, _ = cKDTree(g).query(g, k=min(2, m))
    spacing = float(np.median(d_nn[:, -1])) if m > 1 else 0.0
    spread = float(np.ptp(cost)) if len(cost) else 0.0
    # (Duplicate goals give zero spacing; 1e-3 of the cost spread keeps ties from bidding up by tiny ε.)
    eps = max(min(max(4.0 * spacing**2, 1e-3 * spread), spread / _EPS_FACTOR), eps_final)

    # Prices only ever rise (auction bids; the warm restarts keep them), so min_j (c_ij + p_j) never
    # falls: a drone whose assigned value w_i = c_iσ(i) + p_σ(i) did not rise since its last exact scan
    # cannot have become short: its last scanned minimum is still a lower bound, and only drones whose
    # w_i exceeds that bound by more than ε are rescanned between rounds. The certificate itself always
    # comes from a full scan.
    row_min = np.full(n, -np.inf)
    full = True
    for rnd in range(1, max_rounds + 1):
        while True:
            _drop_unhappy(indptr, indices, cost, n, n_rows, prices, row_col, col_row, eps)
            _auction(indptr, indices, cost, n, n_rows, prices, row_col, col_row, eps, big)
            if eps <= eps_final:
                break
            eps = max(eps / _EPS_FACTOR, eps_final)
        goal_index = row_col[:n].copy()
        w = _edge_cost(x, g, ident, goal_index) + prices[goal_index]
        # Prices of magnitude P carry ~P·2^-52 rounding per bid (4e-15·P is ~18 ulps). With near-ties
        # (lattices) the auction's ε-CS leaves drones a few ε short of goals outside the graph, and
        # chasing those churns forever: only drones more than 8·ε short get new edges (the
        # certificate still counts every shortfall).
        rounding = 4e-15 * (scale_m2 + float(prices.max()))
        loose = 8.0 * eps_final + rounding
        rows = ident if full else ident[w - row_min > loose]
        cand_rows, min_rows, w_rows = _scan_all_pairs(x[rows], gx, gy, gz, prices, k, goal_index[rows])
        row_min[rows] = min_rows
        violation = w_rows - min_rows
        short = violation > loose
        if full:
            cost_m2 = _assignment_cost(x, g, goal_index)
            cert = _certificate_from_scan(cost_m2, prices, goal_index, row_min, w_rows, scale_m2, rel_tol)
            if cert.ok:
                return SparseSolution(goal_index, cost_m2, prices - prices.min(), cert, rnd, len(indices))
            if not short.any():
                short = violation > eps_final * (1.0 + 1e-6) + rounding
        # Column generation: drones that lack a good goal get their k best goals under the current prices.
        grown = _sorted_unique(np.concatenate([keys, np.repeat(rows[short], k) * m + cand_rows[short].ravel()]))
        if len(grown) == len(keys):
            if full:
                return None  # no edge left to add and no certificate: the caller falls back to dense
            full = True  # nothing left to add: certify with a full scan
            continue
        keys = grown
        indptr, indices, cost = _csr(keys, n, m, x, g)
        big = float(cost.max()) + scale_m2
        eps = max(float(violation[short].max()), eps_final)
        full = False
    return None


# --------------------------------------------------------------------------- public


def solve_sparse(
    starts: np.ndarray,
    goals: np.ndarray,
    *,
    candidates: int = DEFAULT_CANDIDATES,
    rel_tol: float = DEFAULT_REL_TOL,
    max_rounds: int = 60,
    multiscale: bool = True,
    coarse_ratio: int = 4,
    coarse_base: int = 500,
    warm: tuple[np.ndarray, np.ndarray] | None = None,
) -> SparseSolution | None:
    """Certified-optimal assignment of N drones to M >= N goals without an N x M matrix.

    Args:
        starts: (N, 3) drone positions, metres (validated by the caller).
        goals: (M, 3) goal positions, metres, M >= N.
        candidates: goals per drone proposed per column-generation round.
        rel_tol: certified relative optimality gap (the auction's final ε is set from it).
        max_rounds: column-generation rounds per scale before giving up.
        multiscale: warm-start the prices from coarser problems (every ``coarse_ratio``-th
            point, recursively down to about ``coarse_base`` drones).
        warm: (goal prices (M,) m², goal index (N,)) of a *nearby* problem with the same drone and goal
            numbering (e.g. the same formations before they were spread apart): its prices start the
            auction and its targets propose candidate edges, instead of the coarse levels. Any prices are
            a valid start (the certificate and the column generation do not depend on them), so the
            result is exactly as optimal; only the work changes.

    Returns:
        The solution with its certificate, or None if the certificate did not
        close within ``max_rounds`` (the caller then falls back to the dense solver).
    """
    x, g, _ = _centred(np.asarray(starts, np.float64), np.asarray(goals, np.float64))
    base = coarse_base if multiscale else len(x) + 1
    # Work in k-d order: compact blocks for the all-pairs scan, cache-friendly auction.
    ox, og = _kd_order(x), _kd_order(g)
    if warm is not None and len(x) > 0:
        prices_w, index_w = (np.asarray(w) for w in warm)
        guess = (np.asarray(prices_w, dtype=np.float64)[og], g[np.asarray(index_w, dtype=np.int64)][ox])
        sol = _solve_level(x[ox], g[og], guess, candidates=candidates, rel_tol=rel_tol, max_rounds=max_rounds)
    else:
        sol = _solve(x[ox], g[og], candidates=candidates, rel_tol=rel_tol, max_rounds=max_rounds,
                     ratio=coarse_ratio, base=base)
    if sol is None:
        return None
    goal_index = np.empty(len(x), dtype=np.int64)
    goal_index[ox] = og[sol.goal_index]
    prices = np.empty(len(g))
    prices[og] = sol.prices_m2
    return SparseSolution(goal_index, sol.cost_m2, prices, sol.certificate, sol.rounds, sol.edges)


def _column_candidates(x: np.ndarray, g: np.ndarray, row_min: np.ndarray, k: int, m: int) -> np.ndarray:
    """Edge keys i·M + j joining every goal j to the k drones of least reduced cost c_ij - u_i.

    Row-wise candidates can leave a goal with no good in-edge; the auction then
    has to reach it through a far fallback edge and prices run away. The
    symmetric scan (drone potentials u_i = min_j c_ij + p_j as "prices" of the
    drones, shifted to be >= 0) gives each goal its own best drones.
    """
    n = len(x)
    kk = int(min(k, n))
    u = np.where(np.isfinite(row_min), row_min, 0.0)
    xx, xy, xz = (np.ascontiguousarray(x[:, d]) for d in range(3))
    cand_t, _, _ = _scan_all_pairs(g, xx, xy, xz, u.max() - u, kk, np.full(len(g), -1, dtype=np.int64))
    out: np.ndarray = cand_t.ravel() * m + np.repeat(np.arange(len(g), dtype=np.int64), kk)
    return out


def _edge_cost(x: np.ndarray, g: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    diff = x[rows] - g[cols]
    out: np.ndarray = np.einsum("ij,ij->i", diff, diff)
    return out


def certify(
    starts: np.ndarray,
    goals: np.ndarray,
    goal_index: np.ndarray,
    prices_m2: np.ndarray,
    *,
    rel_tol: float = DEFAULT_REL_TOL,
) -> Certificate:
    """Check ``goal_index`` against goal prices over all N x M pairs (weak LP duality).

    Args:
        starts: (N, 3) drone positions, metres.
        goals: (M, 3) goal positions, metres.
        goal_index: (N,) distinct goal indices, the assignment to check.
        prices_m2: (M,) goal prices, m² (any values give a valid bound; optimal ones a tight one).
        rel_tol: accepted gap relative to the cost.
    """
    x, g, scale_m2 = _centred(np.asarray(starts, np.float64), np.asarray(goals, np.float64))
    gx, gy, gz = (np.ascontiguousarray(g[:, d]) for d in range(3))
    prices = np.asarray(prices_m2, dtype=np.float64)
    gi = np.asarray(goal_index, dtype=np.int64)
    _, row_min, row_assigned = _scan_all_pairs(x, gx, gy, gz, prices, 1, gi)
    cost_m2 = _assignment_cost(x, g, gi)
    return _certificate_from_scan(cost_m2, prices, gi, row_min, row_assigned, scale_m2, rel_tol)


def _assignment_cost(x: np.ndarray, g: np.ndarray, goal_index: np.ndarray) -> float:
    """Σ_i ||x_i - g_σ(i)||², m² (compensated sum)."""
    diff = x - g[goal_index]
    return math.fsum(np.einsum("ij,ij->i", diff, diff))
