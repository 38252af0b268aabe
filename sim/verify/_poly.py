"""Certified extrema of polynomials on intervals: Bernstein-basis branch and bound (numba).

A polynomial of degree <= n on [0, L] is rewritten in the Bernstein basis of
[0, 1] (x = u/L). Its Bernstein coefficients b_0..b_n bound it from below and
above on the interval (convex-hull property), b_0 and b_n are its end values,
and de Casteljau's algorithm splits it at x = 1/2 into the two halves'
coefficients (Farouki & Rajan 1987, "Algorithms for polynomials in Bernstein
form"). The minimum is then found by branch and bound: an interval whose lowest
coefficient is not below the best value found so far (minus a relative
tolerance of 1e-13), or not below a caller's cut-off, cannot hold anything
better and is dropped; the others are halved. The gap between the lowest
coefficient and the true minimum shrinks as the square of the interval width,
so a handful of splits pin the minimum to rounding. The result is the value
*attained* at the returned point (an upper bound on the minimum) within the
tolerance of the certified lower bound; a node budget bounds the work, and if
it runs out the certified lower bound is returned instead (conservative).

Everything here works in a fixed working degree :data:`NB` = 10 (the squared
distance of two quintic pieces); lower degrees are zero-padded, which is exact.
"""

from __future__ import annotations

import math

import numba
import numpy as np

#: Working degree: squared distance of two quintic pieces.
NB = 10
#: Polynomial degree of a trajectory piece.
DP = 5
_STACK = 64
_MAX_NODES = 20_000
_REL_TOL = 1e-13


def _conversion_table(n: int) -> np.ndarray:
    """W[k, m] = C(k, m) / C(n, m) for m <= k: b_k = Σ_m W[k, m]·a_m for x in [0, 1]."""
    w = np.zeros((n + 1, n + 1))
    for k in range(n + 1):
        for m in range(k + 1):
            w[k, m] = math.comb(k, m) / math.comb(n, m)
    return w


_W = _conversion_table(NB)


@numba.njit(cache=True, nogil=True)
def to_bernstein(a: np.ndarray, length: float, w: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover
    """Power coefficients a (NB+1,) in u on [0, length] -> Bernstein coefficients on x = u/length."""
    n = a.shape[0] - 1
    scaled = np.empty(n + 1)
    s = 1.0
    for m in range(n + 1):
        scaled[m] = a[m] * s
        s *= length
    for k in range(n + 1):
        acc = 0.0
        for m in range(k + 1):
            acc += w[k, m] * scaled[m]
        out[k] = acc


@numba.njit(cache=True, nogil=True)
def bernstein_min(
    b: np.ndarray, cutoff: float, stack: np.ndarray, lo_s: np.ndarray, hi_s: np.ndarray
) -> tuple[float, float]:  # pragma: no cover - numba
    """Minimum of the polynomial with Bernstein coefficients ``b`` on [0, 1] and where (x).

    Intervals that cannot go below ``cutoff`` are not refined, so when the true
    minimum is >= cutoff the returned value is only some attained value >= it.
    ``stack`` (S, n+1), ``lo_s``/``hi_s`` (S,) are scratch space.
    """
    n = b.shape[0] - 1
    scale = 0.0
    for k in range(n + 1):
        scale = max(scale, abs(b[k]))
    tol = _REL_TOL * (1.0 + scale)
    best, xb = b[0], 0.0
    if b[n] < best:
        best, xb = b[n], 1.0
    cap = stack.shape[0]
    stack[0, :] = b
    lo_s[0], hi_s[0] = 0.0, 1.0
    sp = 1
    nodes = 0
    tmp = np.empty(n + 1)
    while sp > 0:
        sp -= 1
        lo, hi = lo_s[sp], hi_s[sp]
        lb = stack[sp, 0]
        for k in range(1, n + 1):
            lb = min(lb, stack[sp, k])
        if lb >= min(best, cutoff) - tol:
            continue
        nodes += 1
        if hi - lo < 1e-12 or sp + 2 > cap or nodes > _MAX_NODES:
            # Out of resolution or budget: keep the certified lower bound (never optimistic).
            if lb < best:
                best, xb = lb, 0.5 * (lo + hi)
            continue
        # de Casteljau at 1/2: left half into slot sp + 1, right half into slot sp.
        for k in range(n + 1):
            tmp[k] = stack[sp, k]
        stack[sp + 1, 0] = tmp[0]
        right_last = tmp[n]
        for r in range(1, n + 1):
            for k in range(n - r + 1):
                tmp[k] = 0.5 * (tmp[k] + tmp[k + 1])
            stack[sp + 1, r] = tmp[0]
            stack[sp, n - r] = tmp[n - r]
        stack[sp, n] = right_last
        mid = 0.5 * (lo + hi)
        fm = stack[sp, 0]
        if fm < best:
            best, xb = fm, mid
        lo_s[sp], hi_s[sp] = mid, hi
        lo_s[sp + 1], hi_s[sp + 1] = lo, mid
        sp += 2
    return best, xb


@numba.njit(cache=True, nogil=True)
def taylor_shift(c: np.ndarray, delta: float, out: np.ndarray) -> None:  # pragma: no cover - numba
    """out(u) = c(u + delta) for ascending coefficients (repeated synthetic division)."""
    d = c.shape[0] - 1
    for k in range(d + 1):
        out[k] = c[k]
    if delta == 0.0:
        return
    for k in range(d):
        for m in range(d - 1, k - 1, -1):
            out[m] += delta * out[m + 1]


@numba.njit(cache=True, nogil=True)
def piece_at(breaks: np.ndarray, i: int, t: float) -> int:  # pragma: no cover - numba
    """Drone i's piece p with breaks[p] <= t < breaks[p+1] (zero-length pieces skipped; the last at the end)."""
    p_count = breaks.shape[1] - 1
    lo, hi = 1, p_count + 1  # first k in [1, P] with breaks[i, k] > t (P + 1 if none)
    while lo < hi:
        mid = (lo + hi) // 2
        if breaks[i, mid] > t:
            hi = mid
        else:
            lo = mid + 1
    return int(min(lo - 1, p_count - 1))


@numba.njit(cache=True, nogil=True)
def _square_sum(rel: np.ndarray, f: np.ndarray) -> None:  # pragma: no cover - numba
    """f = Σ_axis rel[axis]², rel (3, d+1) ascending, f (2d+1,)."""
    d = rel.shape[1] - 1
    for k in range(2 * d + 1):
        f[k] = 0.0
    for ax in range(3):
        for a in range(d + 1):
            ra = rel[ax, a]
            if ra == 0.0:
                continue
            for b in range(d + 1):
                f[a + b] += ra * rel[ax, b]


@numba.njit(cache=True, parallel=True, nogil=True)
def pair_minima(
    pi: np.ndarray, pj: np.ndarray, t0: np.ndarray, t1: np.ndarray, cutoff2: np.ndarray,
    breaks: np.ndarray, coeffs: np.ndarray, w: np.ndarray, out_d2: np.ndarray, out_t: np.ndarray,
) -> None:  # pragma: no cover - numba
    """Exact minimum of |p_j(t) - p_i(t)|² over [t0[q], t1[q]] for each pair q (drones pi[q], pj[q]).

    The interval is cut at both drones' piece breaks; on each part the squared
    distance is one polynomial of degree <= 10, minimised by :func:`bernstein_min`
    (parts that cannot go below ``cutoff2[q]`` are not refined). Writes the minimum
    (m²) and its time (s).
    """
    nq = pi.shape[0]
    chunk = 128
    nchunks = (nq + chunk - 1) // chunk
    for ch in numba.prange(nchunks):
        stack = np.empty((_STACK, NB + 1))
        lo_s = np.empty(_STACK)
        hi_s = np.empty(_STACK)
        ci = np.empty(DP + 1)
        cj = np.empty(DP + 1)
        rel = np.empty((3, DP + 1))
        f = np.zeros(NB + 1)
        bern = np.empty(NB + 1)
        for q in range(ch * chunk, min(nq, (ch + 1) * chunk)):
            i, j = pi[q], pj[q]
            ta, tb = t0[q], t1[q]
            cut = cutoff2[q]
            p_count = breaks.shape[1] - 1
            # Past its last break a drone rests, so the distance is constant there: clamp the
            # window to both drones' spans (a window end one ulp past them, from summed
            # durations, would otherwise never be reached by the piece walk below).
            tb = max(ta, min(tb, breaks[i, p_count], breaks[j, p_count]))
            a_ = piece_at(breaks, i, ta)
            b_ = piece_at(breaks, j, ta)
            t = ta
            best, tbest = np.inf, ta
            while True:
                e = min(tb, breaks[i, a_ + 1], breaks[j, b_ + 1])
                if e < t:
                    e = t
                for ax in range(3):
                    taylor_shift(coeffs[i, a_, ax], t - breaks[i, a_], ci)
                    taylor_shift(coeffs[j, b_, ax], t - breaks[j, b_], cj)
                    for k in range(DP + 1):
                        rel[ax, k] = cj[k] - ci[k]
                _square_sum(rel, f)
                length = e - t
                if length > 0.0:
                    to_bernstein(f, length, w, bern)
                    v, x = bernstein_min(bern, cut, stack, lo_s, hi_s)
                    tv = t + x * length
                else:
                    v, tv = f[0], t
                if v < best:
                    best, tbest = v, tv
                if e >= tb:
                    break
                t = e
                a_prev, b_prev = a_, b_
                while a_ < p_count - 1 and breaks[i, a_ + 1] <= t:
                    a_ += 1
                while b_ < p_count - 1 and breaks[j, b_ + 1] <= t:
                    b_ += 1
                if a_ == a_prev and b_ == b_prev and e <= t and breaks[i, a_ + 1] <= t and breaks[j, b_ + 1] <= t:
                    break  # both drones past their last piece: nothing left to walk
            out_d2[q] = best
            out_t[q] = tbest


@numba.njit(cache=True, parallel=True)
def piece_extrema(
    breaks: np.ndarray, coeffs: np.ndarray, w: np.ndarray, out_v: np.ndarray, out_t: np.ndarray,
    limits: np.ndarray,
) -> None:  # pragma: no cover - numba
    """Per piece (i, p), extrema and their times (s):

    0: max horizontal speed² (vx² + vy²), 1: max vertical speed² (vz²),
    2: max acceleration² (|a|²), 3: max altitude z, 4: min altitude z.
    ``out_v``, ``out_t``: (N, P, 5).

    ``limits`` (5,) in the same units (speeds and acceleration squared; ±inf: none; NaN: refine every
    piece exactly).
    A piece is refined exactly whenever it could pass its limit or beat the drone's
    peak over its earlier pieces; otherwise the branch and bound stops as soon as the
    bound proves neither (the value is then an attained value below both). So every
    value past its limit is exact, and so is every drone's (hence the show's) peak.
    """
    n, p_count = coeffs.shape[0], coeffs.shape[1]
    for i in numba.prange(n):
        run = np.full(5, np.inf)  # best minimised value so far (sgn·extremum) of this drone
        stack = np.empty((_STACK, NB + 1))
        lo_s = np.empty(_STACK)
        hi_s = np.empty(_STACK)
        vel = np.zeros((3, DP + 1))
        acc = np.zeros((3, DP + 1))
        f = np.zeros(NB + 1)
        bern = np.empty(NB + 1)
        sub = np.zeros((3, DP + 1))
        for p in range(p_count):
            length = breaks[i, p + 1] - breaks[i, p]
            for ax in range(3):
                for k in range(DP + 1):
                    vel[ax, k] = 0.0
                    acc[ax, k] = 0.0
                for k in range(1, DP + 1):
                    vel[ax, k - 1] = k * coeffs[i, p, ax, k]
                for k in range(2, DP + 1):
                    acc[ax, k - 2] = k * (k - 1) * coeffs[i, p, ax, k]
            for q in range(5):
                sgn = -1.0  # maximise by minimising the negation
                for ax in range(3):
                    for k in range(DP + 1):
                        sub[ax, k] = 0.0
                if q == 0:
                    for k in range(DP + 1):
                        sub[0, k] = vel[0, k]
                        sub[1, k] = vel[1, k]
                    _square_sum(sub, f)
                elif q == 1:
                    for k in range(DP + 1):
                        sub[2, k] = vel[2, k]
                    _square_sum(sub, f)
                elif q == 2:
                    for ax in range(3):
                        for k in range(DP + 1):
                            sub[ax, k] = acc[ax, k]
                    _square_sum(sub, f)
                else:
                    for k in range(NB + 1):
                        f[k] = 0.0
                    for k in range(DP + 1):
                        f[k] = coeffs[i, p, 2, k]
                    if q == 4:
                        sgn = 1.0
                for k in range(NB + 1):
                    f[k] *= sgn
                # Minimising sgn·f: refine below the running best or the limit, whichever is larger.
                lim = sgn * limits[q]
                cut = np.inf  # NaN limit: no pruning, every piece exact
                if run[q] < np.inf and not math.isnan(lim):
                    cut = max(run[q], lim - 1e-6 * (1.0 + abs(lim)))
                if length > 0.0:
                    to_bernstein(f, length, w, bern)
                    v, x = bernstein_min(bern, cut, stack, lo_s, hi_s)
                else:
                    v, x = f[0], 0.0
                if v < run[q]:
                    run[q] = v
                out_v[i, p, q] = sgn * v
                out_t[i, p, q] = breaks[i, p] + x * length


@numba.njit(cache=True, parallel=True)
def speed_bounds(
    breaks: np.ndarray, coeffs: np.ndarray, w: np.ndarray, parts: int, out: np.ndarray
) -> None:  # pragma: no cover - numba
    """Upper bound of the speed |v| on each of ``parts`` equal sub-intervals of each piece: out (N, P, parts).

    The largest Bernstein coefficient of |v|² on a sub-interval bounds it from above
    (convex-hull property), so each value is >= the true maximum speed there.
    """
    n, p_count = coeffs.shape[0], coeffs.shape[1]
    for i in numba.prange(n):
        vel = np.zeros((3, DP + 1))
        shifted = np.zeros((3, DP + 1))
        f = np.zeros(NB + 1)
        bern = np.empty(NB + 1)
        tmp = np.empty(NB + 1)
        level = np.empty((parts, NB + 1))
        for p in range(p_count):
            length = breaks[i, p + 1] - breaks[i, p]
            h = length / parts
            for ax in range(3):
                for k in range(DP + 1):
                    vel[ax, k] = 0.0
                for k in range(1, DP + 1):
                    vel[ax, k - 1] = k * coeffs[i, p, ax, k]
            still = True
            for ax in range(3):
                for k in range(DP):
                    if vel[ax, k] != 0.0:
                        still = False
            if still:  # at rest: speed 0 on every part
                for s in range(parts):
                    out[i, p, s] = 0.0
                continue
            _square_sum(vel, f)
            if h <= 0.0 or parts & (parts - 1) != 0:
                for s in range(parts):
                    for ax in range(3):
                        taylor_shift(vel[ax], s * h, shifted[ax])
                    _square_sum(shifted, f)
                    if h > 0.0:
                        to_bernstein(f, h, w, bern)
                        top = bern[0]
                        for k in range(1, NB + 1):
                            top = max(top, bern[k])
                    else:
                        top = f[0]
                    out[i, p, s] = math.sqrt(max(top, 0.0))
                continue
            # Bernstein coefficients on the whole piece, then de Casteljau halvings down to the
            # parts (the same coefficients as converting on each part: subdivision is exact).
            to_bernstein(f, length, w, bern)
            level[0, :] = bern
            width = 1
            while width < parts:
                for q in range(width - 1, -1, -1):
                    for k in range(NB + 1):
                        tmp[k] = level[q, k]
                    left = level[2 * q]
                    right = level[2 * q + 1]
                    last = tmp[NB]
                    left[0] = tmp[0]
                    for r in range(1, NB + 1):
                        for k in range(NB - r + 1):
                            tmp[k] = 0.5 * (tmp[k] + tmp[k + 1])
                        left[r] = tmp[0]
                        right[NB - r] = tmp[NB - r]
                    right[NB] = last
                width *= 2
            for s in range(parts):
                top = level[s, 0]
                for k in range(1, NB + 1):
                    top = max(top, level[s, k])
                out[i, p, s] = math.sqrt(max(top, 0.0))


@numba.njit(cache=True)
def envelope_cells(
    breaks: np.ndarray, bounds: np.ndarray, t0: float, cell_s: float, cells: int, out: np.ndarray
) -> None:  # pragma: no cover - numba
    """out[c] = max bound of any sub-interval overlapping cell c = [t0 + c·cell_s, t0 + (c+1)·cell_s]."""
    n, p_count, parts = bounds.shape
    for c in range(cells):
        out[c] = 0.0
    for i in range(n):
        for p in range(p_count):
            a, b = breaks[i, p], breaks[i, p + 1]
            h = (b - a) / parts
            for s in range(parts):
                v = bounds[i, p, s]
                if v <= 0.0:
                    continue
                sa, sb = a + s * h, a + (s + 1) * h
                c0 = int(math.floor((sa - t0) / cell_s))
                c1 = int(math.floor((sb - t0) / cell_s))
                # Closed intervals, so a shared endpoint counts on both sides (rounding-safe).
                c0 = max(c0 - 1, 0)
                c1 = min(c1 + 1, cells - 1)
                for c in range(c0, c1 + 1):
                    if v > out[c]:
                        out[c] = v


#: The power-to-Bernstein table for degree :data:`NB`.
W = _W
