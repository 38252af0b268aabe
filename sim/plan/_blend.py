"""Blending consecutive synchronised legs of a transition: the next leg starts before the last one ends.

A "layers" transition flies spread -> middle -> contract (:func:`sim.plan._schedule.plan_transition`),
each leg a synchronised straight line p(t) = A + s_k(t)·D_k that stops at its end. Stopping
twice costs about two spread-leg durations per transition. Here leg k+1 starts δ_k seconds
before leg k ends and the two motions add:

    p(t) = A_0 + Σ_k s_k(t - o_k)·D_k,   o_{k+1} = o_k + T_k - δ_k,

(s_k = 0 before its leg, 1 after). Each drone's path is a sum of C² rest-to-rest profiles, so
it stays C² with rest at both ends; at most two legs are active at a time (δ_k + δ_{k+1} <= T_{k+1}).
Two legs each at the limits cannot add (their accelerations and jerks would), so blended legs are
flown with a share of the acceleration and jerk limits (:data:`SHARES`), and the overlap is
whatever the certificates below allow.

**Safety (certified).** Outside the overlaps the motion is one leg alone, already certified.
Inside an overlap split into sub-windows, both profiles are nondecreasing, so
(s_k, s_{k+1}) stays in the box [s_k(t_a), s_k(t_b)] × [s_{k+1}(t_a'), s_{k+1}(t_b')] of each
sub-window. A pair's offset is r = r0 + s_k·c_k + s_{k+1}·c_{k+1} (r0, c from the two drones'
leg starts and displacements), and the minimum of |r|² over the box (a convex quadratic in two
variables: the interior stationary point or one of the four clamped edges) is a lower bound over
the sub-window. Candidate pairs: within ``required + 2·max_i R_i`` at the overlap start, where R_i
bounds how far drone i moves during the overlap.

**Limits (certified).** Velocity, acceleration and jerk are s_k^(q)·D_k + s_{k+1}^(q)·D_{k+1};
the exact range of each scalar derivative over a sub-window (endpoints, piece breaks and the
roots of the next derivative) gives a box, and a convex function (a norm, or a linear vertical
component) takes its maximum over a box at a corner: so each drone's horizontal and vertical
speed, acceleration magnitude and jerk magnitude are bounded by their largest corner value.

The overlap of each junction is the longest multiple of the window step (0.1 s) passing both. Used with
the minimum-time law only: the quintic mode keeps reproducing the shared-segment plans.
"""

from __future__ import annotations

from math import comb
from typing import Protocol

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

from sim.plan._threads import pool, workers
from sim.plan._timelaw import Profiles


class Schedule(Protocol):
    """What this module reads of a leg (:class:`sim.plan._schedule.Schedule`, which calls this module)."""

    @property
    def a_m(self) -> np.ndarray: ...
    @property
    def b_m(self) -> np.ndarray: ...
    @property
    def depart_s(self) -> np.ndarray: ...
    @property
    def profiles(self) -> Profiles: ...
    @property
    def window_s(self) -> float: ...
    @property
    def unresolved(self) -> tuple[object, ...]: ...


class Limits(Protocol):
    """What this module reads of the limits (:class:`sim.plan._schedule.Limits`)."""

    @property
    def v_xy(self) -> float: ...
    @property
    def v_z(self) -> float: ...
    @property
    def v_down(self) -> float | None: ...
    @property
    def a(self) -> float: ...
    @property
    def j(self) -> float: ...
    @property
    def law(self) -> str: ...

#: Sub-windows per candidate-pair search in :meth:`Junction.safe`.
SAFE_CHUNK = 4
#: Drones from which :meth:`Junction.safe` examines several chunks at once on threads.
PARALLEL_MIN_DRONES = 500
#: Limits are certified with this relative margin (the verifier's peaks are exact).
LIMIT_MARGIN = 1e-6


def _shift(c: np.ndarray, h: float) -> np.ndarray:
    """Coefficients (..., D+1) ascending of p(τ + h) given those of p(τ) (Taylor shift)."""
    deg = c.shape[-1]
    m = np.zeros((deg, deg))
    for i in range(deg):
        for k in range(i + 1):
            m[i, k] = comb(i, k) * h ** (i - k)
    out: np.ndarray = c @ m
    return out


def _deriv(c: np.ndarray, q: int) -> np.ndarray:
    """Ascending coefficients of the q-th derivative (same length, zero padded)."""
    out = np.array(c, dtype=np.float64)
    for _ in range(q):
        out = np.concatenate([out[1:] * np.arange(1, len(out)), [0.0]])
    return out


def profile_range(breaks_s: np.ndarray, coeffs: np.ndarray, t0: float, t1: float, order: int) -> tuple[float, float]:
    """Exact (min, max) of the ``order``-th derivative of one scalar profile over [t0, t1] ⊂ [0, T].

    ``breaks_s`` (8,), ``coeffs`` (7, 6) ascending in local piece time. Candidates: the ends of
    each piece's part of the interval and the real roots of the next derivative inside it (at a
    break where the jerk jumps both one-sided values count, which can only widen the range).
    """
    lo, hi = np.inf, -np.inf
    for p in range(len(breaks_s) - 1):
        b0, b1 = float(breaks_s[p]), float(breaks_s[p + 1])
        u0, u1 = max(t0, b0), min(t1, b1)
        if u1 < u0:
            continue
        d = _deriv(coeffs[p], order)
        pts = [u0 - b0, u1 - b0]
        dd = np.trim_zeros(_deriv(coeffs[p], order + 1), "b")
        if len(dd) > 1:
            for r in np.polynomial.polynomial.polyroots(dd):
                if abs(r.imag) < 1e-12 and u0 - b0 < r.real < u1 - b0:
                    pts.append(float(r.real))
        vals = np.polynomial.polynomial.polyval(np.array(pts), d)
        lo, hi = min(lo, float(vals.min())), max(hi, float(vals.max()))
    return lo, hi


def _value(breaks_s: np.ndarray, coeffs: np.ndarray, t: float) -> float:
    if t <= 0.0:
        return 0.0
    if t >= breaks_s[-1]:
        return 1.0
    p = int(np.clip(np.searchsorted(breaks_s, t, side="right") - 1, 0, len(coeffs) - 1))
    return float(np.polynomial.polynomial.polyval(t - breaks_s[p], coeffs[p]))


#: Width of the sub-windows of an overlap, seconds (half the planner's window step, 0.1 s).
SUB_WINDOW_S = 0.05


def _ranges(leg: Schedule, order: int, count: int, from_end: bool) -> np.ndarray:
    """(count, 2) exact (min, max) of the profile's ``order``-th derivative (order 0: the value) over
    consecutive sub-windows of ``SUB_WINDOW_S``, from the leg's start, or backwards from its end.

    Each sub-window's range is taken over the derivative's values at the sub-window's ends, at the
    piece breaks inside it (both one-sided values) and at the real roots of the next derivative
    inside each piece: the extremes of a polynomial on an interval are among those points.
    """
    b, c = leg.profiles.breaks_s[0], leg.profiles.coeffs[0]
    t_end = float(b[-1])
    edges = np.arange(count + 1) * SUB_WINDOW_S
    if from_end:
        edges = t_end - edges[::-1]
    edges = np.clip(edges, 0.0, t_end)
    ts: list[np.ndarray] = []
    vs: list[np.ndarray] = []
    for p in range(len(b) - 1):
        b0, b1 = float(b[p]), float(b[p + 1])
        if b1 <= b0:
            continue
        pts = [np.array([0.0, b1 - b0]), edges[(edges >= b0) & (edges <= b1)] - b0]
        dd = np.trim_zeros(_deriv(c[p], order + 1), "b")
        if len(dd) > 1:
            r = np.polynomial.polynomial.polyroots(dd)
            r = r.real[(np.abs(r.imag) < 1e-12) & (r.real > 0.0) & (r.real < b1 - b0)]
            pts.append(r)
        u = np.concatenate(pts)
        ts.append(u + b0)
        vs.append(np.polynomial.polynomial.polyval(u, _deriv(c[p], order)))
    t, v = np.concatenate(ts), np.concatenate(vs)
    o = np.argsort(t, kind="stable")
    t, v = t[o], v[o]
    lo = np.searchsorted(t, edges[:-1], side="left")
    hi = np.searchsorted(t, edges[1:], side="right")
    out = np.empty((count, 2))
    for k in range(count):
        seg = v[lo[k]:hi[k]]
        out[k] = seg.min(), seg.max()
    if from_end:
        out = out[::-1]
    return out


def _extreme_points(features: np.ndarray) -> np.ndarray:
    """Rows of ``features`` (N, k) that include every maximiser of every linear function: the convex
    hull's vertices (all unique rows when the hull is degenerate)."""
    from scipy.spatial import ConvexHull, QhullError

    pts = np.unique(features, axis=0)
    if len(pts) <= features.shape[1] + 1:
        return pts
    try:
        return np.asarray(pts[ConvexHull(pts).vertices])
    except (QhullError, ValueError):
        return pts


class Junction:
    """The certificates of one junction between two synchronised legs, for overlaps q·SUB_WINDOW_S.

    Per drone the limit quantities over a box corner (u, w) are |u·D1 + w·D2|² (a linear function of
    the features |D1|², |D2|², D1·D2, horizontally the same with the horizontal parts) and the
    vertical component u·D1z + w·D2z: the maximum over drones of a linear function is reached at a
    vertex of the features' convex hull, so only those drones are evaluated (exactly the same maximum).
    """

    def __init__(self, leg1: Schedule, leg2: Schedule, lim: Limits | None, required_m: float) -> None:
        self.leg1, self.leg2, self.lim, self.required_m = leg1, leg2, lim, required_m
        d1, d2 = leg1.b_m - leg1.a_m, leg2.b_m - leg2.a_m
        self.d1, self.d2 = d1, d2
        self.count = int(np.floor(min(leg1.window_s, leg2.window_s) / SUB_WINDOW_S + 1e-9))
        self.r1 = {q: _ranges(leg1, q, self.count, True)[::-1] for q in range(4)}  # sub-windows in time order
        self.r2 = {q: _ranges(leg2, q, self.count, False) for q in range(4)}
        h1, h2 = d1[:, :2], d2[:, :2]
        self.full = _extreme_points(np.column_stack([(d1 * d1).sum(1), (d2 * d2).sum(1), (d1 * d2).sum(1)]))
        self.flat = _extreme_points(np.column_stack([(h1 * h1).sum(1), (h2 * h2).sum(1), (h1 * h2).sum(1)]))
        self.vert = _extreme_points(np.column_stack([d1[:, 2], d2[:, 2]]))

    def _boxes(self, q: int, order: int) -> tuple[np.ndarray, np.ndarray]:
        """(q, 2) ranges of leg 1 (its last q sub-windows) and leg 2 (its first q), in time order."""
        return self.r1[order][self.count - q:], self.r2[order][:q]

    def within_limits(self, q: int) -> bool:
        """True when an overlap of q sub-windows keeps every drone within the limits (module docstring)."""
        lim = self.lim
        assert lim is not None
        keep = 1.0 - LIMIT_MARGIN
        v_down = lim.v_z if lim.v_down is None else lim.v_down
        for order, limit, feats in ((1, lim.v_xy, self.flat), (2, lim.a, self.full), (3, lim.j, self.full)):
            b1, b2 = self._boxes(q, order)
            u = np.repeat(b1, 2, axis=1).ravel()  # corners (u, w) of every box
            w = np.tile(b2, (1, 2)).ravel()
            sq = feats[:, 0:1] * u**2 + feats[:, 1:2] * w**2 + 2.0 * feats[:, 2:3] * u * w
            if float(sq.max()) > (limit * keep) ** 2:
                return False
        b1, b2 = self._boxes(q, 1)
        u = np.repeat(b1, 2, axis=1).ravel()
        w = np.tile(b2, (1, 2)).ravel()
        vz = self.vert[:, 0:1] * u + self.vert[:, 1:2] * w
        return float(vz.max()) <= lim.v_z * keep and float(-vz.min()) <= v_down * keep

    def safe(self, q: int) -> bool:
        """True when every pair provably keeps the distance during an overlap of q sub-windows.

        Chunks of :data:`SAFE_CHUNK` sub-windows each get their own candidate pairs (within
        ``required + R_i + R_j`` at the chunk's start, R_i how far drone i moves in the chunk). Boxes
        are refined only where needed: a box spanning several sub-windows contains each of theirs,
        so a pair whose minimum over it is >= the distance is safe in all of them.
        """
        a, d1, d2 = self.leg1.a_m, self.d1, self.d2
        b1, b2 = self._boxes(q, 0)
        len1, len2 = np.linalg.norm(d1, axis=1), np.linalg.norm(d2, axis=1)
        need = self.required_m**2

        def chunk_unsafe(c0: int) -> bool:
            c1 = min(q, c0 + SAFE_CHUNK)
            s1_lo, s1_hi, s2_lo, s2_hi = float(b1[c0, 0]), float(b1[c1 - 1, 1]), float(b2[c0, 0]), float(b2[c1 - 1, 1])
            start = a + s1_lo * d1 + s2_lo * d2
            reach = (s1_hi - s1_lo) * len1 + (s2_hi - s2_lo) * len2
            pairs = cKDTree(start).query_pairs(self.required_m + 2.0 * float(reach.max()), output_type="ndarray")
            return len(pairs) > 0 and bool(
                _chunk_unsafe(start, a, d1, d2, b1, b2, pairs.astype(np.int64), reach, c0, c1, self.required_m, need))

        # Chunks are independent (the k-d tree and the kernel release the GIL): a batch of them per core at a
        # time, stopping after the first batch with an unsafe chunk (the answer does not depend on the order).
        chunks = list(range(0, q, SAFE_CHUNK))
        batch = workers() if len(a) >= PARALLEL_MIN_DRONES else 1
        for k in range(0, len(chunks), batch):
            part = chunks[k:k + batch]
            if any(pool().map(chunk_unsafe, part) if len(part) > 1 else map(chunk_unsafe, part)):
                return False
        return True


def within_limits(leg1: Schedule, leg2: Schedule, delta_s: float, lim: Limits) -> bool:
    """True when every drone's speed, acceleration and jerk provably respect ``lim`` with the legs overlapping
    by ``delta_s`` (a multiple of ``SUB_WINDOW_S``)."""
    return Junction(leg1, leg2, lim, 0.0).within_limits(int(round(delta_s / SUB_WINDOW_S)))


def overlap_safe(leg1: Schedule, leg2: Schedule, delta_s: float, required_m: float) -> bool:
    """True when every pair provably keeps ``required_m`` while the two legs overlap by ``delta_s``."""
    return Junction(leg1, leg2, None, required_m).safe(int(round(delta_s / SUB_WINDOW_S)))


def _box_min_sq(r0: np.ndarray, c1: np.ndarray, c2: np.ndarray, r1: tuple[float, float],
                r2: tuple[float, float]) -> np.ndarray:
    """(K,) exact min over (u, w) in the box of |r0 + u·c1 + w·c2|² (convex quadratic in 2 variables)."""
    a11 = (c1 * c1).sum(axis=1)
    a22 = (c2 * c2).sum(axis=1)
    a12 = (c1 * c2).sum(axis=1)
    b1 = (r0 * c1).sum(axis=1)
    b2 = (r0 * c2).sum(axis=1)

    def sq(u: np.ndarray, w: np.ndarray, sel: slice | np.ndarray = slice(None)) -> np.ndarray:
        v = r0[sel] + u[:, None] * c1[sel] + w[:, None] * c2[sel]
        out: np.ndarray = (v * v).sum(axis=1)
        return out

    best = np.full(len(r0), np.inf)
    ones = np.ones(len(r0))
    # Edges: fix one variable at a bound, minimise the other (clamped 1-D quadratic).
    for w_fix in r2:
        u_opt = np.where(a11 > 0, -(b1 + w_fix * a12) / np.where(a11 > 0, a11, 1.0), r1[0])
        best = np.minimum(best, sq(np.clip(u_opt, *r1), w_fix * ones))
    for u_fix in r1:
        w_opt = np.where(a22 > 0, -(b2 + u_fix * a12) / np.where(a22 > 0, a22, 1.0), r2[0])
        best = np.minimum(best, sq(u_fix * ones, np.clip(w_opt, *r2)))
    # Interior stationary point (when the Hessian is regular and it lies in the box).
    det = a11 * a22 - a12 * a12
    regular = det > 1e-12 * np.maximum(a11 * a22, 1e-300)
    safe_det = np.where(regular, det, 1.0)
    u = (-b1 * a22 + b2 * a12) / safe_det
    w = (-b2 * a11 + b1 * a12) / safe_det
    inside = regular & (u >= r1[0]) & (u <= r1[1]) & (w >= r2[0]) & (w <= r2[1])
    if inside.any():
        best[inside] = np.minimum(best[inside], sq(u[inside], w[inside], inside))
    return best


@njit(cache=True, nogil=True)
def _box_min_sq_one(r0: np.ndarray, e1: np.ndarray, e2: np.ndarray, u_lo: float, u_hi: float, w_lo: float,
                    w_hi: float) -> float:  # pragma: no cover - numba
    """Exact min over (u, w) in [u_lo, u_hi] x [w_lo, w_hi] of |r0 + u·e1 + w·e2|² (one pair of
    :func:`_box_min_sq`, same candidates: the four clamped edges and the interior stationary point)."""
    a11 = e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]
    a22 = e2[0] * e2[0] + e2[1] * e2[1] + e2[2] * e2[2]
    a12 = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2]
    b1 = r0[0] * e1[0] + r0[1] * e1[1] + r0[2] * e1[2]
    b2 = r0[0] * e2[0] + r0[1] * e2[1] + r0[2] * e2[2]
    best = np.inf
    for side in range(4):
        if side < 2:
            w = w_lo if side == 0 else w_hi
            u = -(b1 + w * a12) / a11 if a11 > 0 else u_lo
            u = min(max(u, u_lo), u_hi)
        else:
            u = u_lo if side == 2 else u_hi
            w = -(b2 + u * a12) / a22 if a22 > 0 else w_lo
            w = min(max(w, w_lo), w_hi)
        v0 = r0[0] + u * e1[0] + w * e2[0]
        v1 = r0[1] + u * e1[1] + w * e2[1]
        v2 = r0[2] + u * e1[2] + w * e2[2]
        best = min(best, v0 * v0 + v1 * v1 + v2 * v2)
    det = a11 * a22 - a12 * a12
    if det > 1e-12 * max(a11 * a22, 1e-300):
        u = (-b1 * a22 + b2 * a12) / det
        w = (-b2 * a11 + b1 * a12) / det
        if u_lo <= u <= u_hi and w_lo <= w <= w_hi:
            v0 = r0[0] + u * e1[0] + w * e2[0]
            v1 = r0[1] + u * e1[1] + w * e2[1]
            v2 = r0[2] + u * e1[2] + w * e2[2]
            best = min(best, v0 * v0 + v1 * v1 + v2 * v2)
    return best


@njit(cache=True, nogil=True)
def _chunk_unsafe(start: np.ndarray, a: np.ndarray, d1: np.ndarray, d2: np.ndarray, b1: np.ndarray,
                  b2: np.ndarray, pairs: np.ndarray, reach: np.ndarray, c0: int, c1: int, required_m: float,
                  need: float) -> bool:  # pragma: no cover - numba
    """True when some candidate pair's box minimum is below ``need`` (= required²) on a single sub-window
    of ``[c0, c1)`` (see :meth:`Junction.safe`).

    Per pair (i, j) of ``pairs`` (K, 2) within ``required + reach_i + reach_j`` at the chunk's start
    ``start`` (N, 3) (a pair farther apart cannot close the distance in the chunk), the sub-windows are refined by
    halving, depth first: a box spanning several sub-windows contains each of theirs, so a pair whose
    minimum over it is >= ``need`` is safe in all of them. Boxes: ``b1``/``b2`` (q, 2) ranges of the
    two profiles per sub-window.
    """
    r0 = np.empty(3)
    e1 = np.empty(3)
    e2 = np.empty(3)
    st = np.empty(c1 - c0 + 4, dtype=np.int64)
    sh = np.empty(c1 - c0 + 4, dtype=np.int64)
    for p in range(pairs.shape[0]):
        i = pairs[p, 0]
        j = pairs[p, 1]
        dist_sq = 0.0
        for x in range(3):
            r0[x] = a[j, x] - a[i, x]
            e1[x] = d1[j, x] - d1[i, x]
            e2[x] = d2[j, x] - d2[i, x]
            g = start[j, x] - start[i, x]
            dist_sq += g * g
        if np.sqrt(dist_sq) >= required_m + reach[i] + reach[j]:
            continue
        top = 0
        st[0] = c0
        sh[0] = c1
        while top >= 0:
            lo = st[top]
            hi = sh[top]
            top -= 1
            u_lo = np.inf
            u_hi = -np.inf
            w_lo = np.inf
            w_hi = -np.inf
            for k in range(lo, hi):
                u_lo = min(u_lo, b1[k, 0])
                u_hi = max(u_hi, b1[k, 1])
                w_lo = min(w_lo, b2[k, 0])
                w_hi = max(w_hi, b2[k, 1])
            if _box_min_sq_one(r0, e1, e2, u_lo, u_hi, w_lo, w_hi) >= need:
                continue
            if hi - lo == 1:
                return True
            mid = (lo + hi) // 2
            top += 1
            st[top] = lo
            sh[top] = mid
            top += 1
            st[top] = mid
            sh[top] = hi
    return False


def blendable(leg: Schedule) -> bool:
    """A synchronised, resolved leg (one shared profile, everyone departing at once)."""
    return (not leg.unresolved and len(leg.profiles.breaks_s) == 1 and not np.any(leg.depart_s)
            and abs(leg.window_s - float(leg.profiles.breaks_s[0, -1])) < 1e-9)


def blend_overlaps(legs: tuple[Schedule, ...], lim: Limits, required_m: float,
                   step_s: float = 2 * SUB_WINDOW_S) -> tuple[float, ...]:
    """(len(legs) - 1,) overlaps, seconds: for each junction the longest multiple of ``step_s`` (a multiple of
    ``SUB_WINDOW_S``) certified safe and
    within the limits (0 where the legs cannot blend), with δ_k + δ_{k+1} <= T_{k+1}."""
    out: list[float] = []
    for k in range(len(legs) - 1):
        leg1, leg2 = legs[k], legs[k + 1]
        delta = 0.0
        if lim.law != "quintic" and blendable(leg1) and blendable(leg2):
            room = min(leg1.window_s - (out[-1] if out else 0.0), leg2.window_s)
            junction = Junction(leg1, leg2, lim, required_m)
            per_step = int(round(step_s / SUB_WINDOW_S))
            for m in range(int(np.floor(room / step_s + 1e-9)), 0, -1):
                if junction.within_limits(m * per_step) and junction.safe(m * per_step):
                    delta = round(m * step_s, 10)
                    break
        out.append(delta)
    return tuple(out)


def blended_pieces(legs: tuple[Schedule, ...], overlaps_s: tuple[float, ...]) -> list[tuple[float, np.ndarray]]:
    """The blended motion of synchronised ``legs`` as pieces shared by all drones: (duration s, (N, 3, 6)).

    p(t) = A_0 + Σ_k s_k(t - o_k)·D_k (module docstring), cut at every leg's piece breaks.
    """
    offsets = [0.0]
    for leg, d in zip(legs[:-1], overlaps_s, strict=True):
        offsets.append(offsets[-1] + leg.window_s - d)
    end = offsets[-1] + legs[-1].window_s
    cuts = {0.0, end}
    for o, leg in zip(offsets, legs, strict=True):
        cuts.update(float(o + b) for b in leg.profiles.breaks_s[0])
    times = np.array(sorted(c for c in cuts if 0.0 <= c <= end))
    times = times[np.concatenate([[True], np.diff(times) > 1e-12])]
    a0 = legs[0].a_m
    pieces = []
    for u0, u1 in zip(times[:-1], times[1:], strict=True):
        c3 = np.zeros((len(a0), 3, 6))
        c3[:, :, 0] = a0
        mid = 0.5 * (u0 + u1)
        for o, leg in zip(offsets, legs, strict=True):
            d = leg.b_m - leg.a_m
            b, c = leg.profiles.breaks_s[0], leg.profiles.coeffs[0]
            local = mid - o
            if local <= 0.0:
                continue
            if local >= b[-1]:
                c3[:, :, 0] += d
                continue
            p = int(np.clip(np.searchsorted(b, local, side="right") - 1, 0, len(c) - 1))
            poly = _shift(c[p], u0 - o - float(b[p]))
            c3 += d[:, :, None] * poly[None, None, :]
        pieces.append((float(u1 - u0), c3))
    return pieces


__all__ = [
    "Junction", "blend_overlaps", "blendable", "blended_pieces", "overlap_safe", "profile_range", "within_limits",
]
