"""Candidate pairs of one time window by swept balls on a uniform grid (numba), provably complete.

Replaces a ``cKDTree`` per time slice (kept as the reference path, ``method="kdtree"`` of
:func:`sim.verify.window_close_pairs`): the slicing, the per-drone swept radii, the grid
hashing and the merging of each pair's candidate slices run in one compiled pass.

**Slices.** The window [t0, t1] is cut into slices [a, b] of width h (greedy over an
envelope grid of speed bounds, as before, so that V_s·h <= R with V_s the largest speed
bound of any drone during the slice).

**Swept balls.** For drone i and slice s, V_i,s is the largest speed bound
(:func:`sim.verify._poly.speed_bounds`: the largest Bernstein coefficient of |v|² on
each eighth of each piece, an upper bound by the convex-hull property) over the parts
of its pieces that meet [a, b]; a drone at rest has V_i,s = 0. With c = (a + b)/2 and
ρ_i = V_i,s·h/2, every position of drone i during the slice lies in the ball
B(p_i(c), ρ_i), because |p_i(t) - p_i(c)| <= ∫|v| <= V_i,s·|t - c| <= ρ_i.

*Claim 1 (no pair missed in a slice).* If |p_j(t) - p_i(t)| <= R for some t in [a, b] then
|p_j(c) - p_i(c)| <= R + ρ_i + ρ_j (triangle inequality with the two balls).

*Claim 2 (the grid finds every such pair).* Cells are cubes of side w = R + 2·max_i ρ_i; a
pair with |p_j(c) - p_i(c)| <= R + ρ_i + ρ_j <= w differs by at most w in each coordinate,
so their cell indices differ by at most 1 per axis: scanning the 27 neighbouring cells and
testing the inequality of claim 1 exactly reports every pair it holds for.

*Claim 3 (exact minimum, smaller intervals).* A pair is minimised exactly
(:func:`sim.verify._poly.pair_minima`) only over [start of its first candidate slice, end of
its last candidate slice]. Every time at which the pair is within R lies in a slice where it
is a candidate (claim 1, slices cover the window), hence in that interval; so every pair whose
window minimum is <= R is found, with its window minimum (attained inside the interval).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from sim.verify import _poly

_F = NDArray[np.float64]
_I = NDArray[np.int64]

#: Cells per slice (at most) of the speed-envelope grid, and a cap on cells per window.
CELLS_PER_SLICE = 4
MAX_CELLS = 8192


@numba.njit(cache=True, nogil=True)
def greedy_slices(env: _F, t0: float, cell_s: float, radius_m: float) -> tuple[_F, _F, _F]:  # pragma: no cover
    """Slices [a, b] made of whole cells, greedily as wide as V_s·h <= radius allows: (a, b, V_s)."""
    cells = env.shape[0]
    a = np.empty(cells)
    b = np.empty(cells)
    v = np.empty(cells)
    k = 0
    s = 0
    while s < cells:
        vmax = env[s]
        e = s + 1
        while e < cells and max(vmax, env[e]) * (e + 1 - s) * cell_s <= radius_m:
            vmax = max(vmax, env[e])
            e += 1
        a[k] = t0 + s * cell_s
        b[k] = t0 + e * cell_s
        v[k] = vmax
        k += 1
        s = e
    return a[:k], b[:k], v[:k]


@numba.njit(cache=True, nogil=True)
def _first_piece(breaks: _F, i: int, t: float) -> int:  # pragma: no cover - numba
    """Drone i's first piece whose end is >= t (P if none)."""
    lo, hi = 0, breaks.shape[1] - 1
    while lo < hi:
        m = (lo + hi) // 2
        if breaks[i, m + 1] < t:
            lo = m + 1
        else:
            hi = m
    return lo


@numba.njit(cache=True, nogil=True)
def _window_speed(breaks: _F, bounds: _F, t0: float, t1: float) -> float:  # pragma: no cover - numba
    """Largest speed bound of any drone on any piece overlapping [t0, t1]."""
    n, p_count, parts = bounds.shape
    out = 0.0
    for i in range(n):
        p = _first_piece(breaks, i, t0)
        while p < p_count and breaks[i, p] <= t1:
            for q in range(parts):
                if bounds[i, p, q] > out:
                    out = bounds[i, p, q]
            p += 1
    return out


@numba.njit(cache=True, nogil=True)
def envelope(breaks: _F, bounds: _F, t0: float, cell_s: float, cells: int, out: _F) -> None:  # pragma: no cover
    """out[c] = max bound of any part overlapping cell c = [t0 + c·cell_s, t0 + (c+1)·cell_s] (closed, and
    one cell of slack each side for rounding); only the pieces that meet the window are visited."""
    n, p_count, parts = bounds.shape
    t1 = t0 + cells * cell_s
    for c in range(cells):
        out[c] = 0.0
    for i in range(n):
        p = _first_piece(breaks, i, t0 - cell_s)
        while p < p_count and breaks[i, p] <= t1 + cell_s:
            a, b = breaks[i, p], breaks[i, p + 1]
            h = (b - a) / parts
            for s in range(parts):
                v = bounds[i, p, s]
                if v <= 0.0:
                    continue
                c0 = max(int(math.floor((a + s * h - t0) / cell_s)) - 1, 0)
                c1 = min(int(math.floor((a + (s + 1) * h - t0) / cell_s)) + 1, cells - 1)
                for c in range(c0, c1 + 1):
                    if v > out[c]:
                        out[c] = v
            p += 1


@numba.njit(cache=True, nogil=True, inline="always")
def _position(breaks: _F, coeffs: _F, i: int, t: float, out: _F) -> None:  # pragma: no cover - numba
    p_count = breaks.shape[1] - 1
    if t >= breaks[i, p_count]:
        p = p_count - 1
        u = breaks[i, p_count] - breaks[i, p]
    else:
        p = _poly.piece_at(breaks, i, t)
        u = t - breaks[i, p]
    for ax in range(3):
        acc = 0.0
        for k in range(coeffs.shape[3] - 1, -1, -1):
            acc = acc * u + coeffs[i, p, ax, k]
        out[ax] = acc


@numba.njit(cache=True, nogil=True)
def _drone_speed(breaks: _F, bounds: _F, i: int, a: float, b: float) -> float:  # pragma: no cover - numba
    """Largest speed bound of drone i over the parts of its pieces that meet [a, b] (closed, with slack)."""
    p_count, parts = bounds.shape[1], bounds.shape[2]
    slack = 1e-9 * max(1.0, abs(a), abs(b))
    lo, hi = a - slack, b + slack
    # First piece whose end is >= lo.
    l, r = 0, p_count
    while l < r:
        m = (l + r) // 2
        if breaks[i, m + 1] < lo:
            l = m + 1
        else:
            r = m
    v = 0.0
    p = l
    while p < p_count and breaks[i, p] <= hi:
        pa, pb = breaks[i, p], breaks[i, p + 1]
        h = (pb - pa) / parts
        for q in range(parts):
            sa = pa + q * h
            sb = pa + (q + 1) * h
            if sb >= lo and sa <= hi and bounds[i, p, q] > v:
                v = bounds[i, p, q]
        p += 1
    return v


@numba.njit(cache=True, nogil=True)
def slice_candidates(breaks: _F, coeffs: _F, bounds: _F, sa: _F, sb: _F, radius_m: float,
                     ) -> tuple[_I, _I, _I, _I]:  # pragma: no cover - numba
    """Every pair (i < j) that is a candidate in some slice (claims 1 and 2): (i, j, first slice, last slice)."""
    n = breaks.shape[0]
    cap = 1 << 16
    ki = np.empty(cap, dtype=np.int64)
    ks = np.empty(cap, dtype=np.int64)
    count = 0
    pos = np.empty((n, 3))
    rho = np.empty(n)
    cell = np.empty((n, 3), dtype=np.int64)
    key = np.empty(n, dtype=np.int64)
    for s in range(sa.shape[0]):
        a, b = sa[s], sb[s]
        c = 0.5 * (a + b)
        h = b - a
        rmax = 0.0
        for i in range(n):
            _position(breaks, coeffs, i, c, pos[i])
            rho[i] = 0.5 * h * _drone_speed(breaks, bounds, i, a, b)
            rmax = max(rmax, rho[i])
        lo = np.empty(3)
        ext = np.empty(3)
        for ax in range(3):
            lo[ax] = np.inf
            hi_ax = -np.inf
            for i in range(n):
                lo[ax] = min(lo[ax], pos[i, ax])
                hi_ax = max(hi_ax, pos[i, ax])
            ext[ax] = hi_ax - lo[ax]
        # Any cell side w >= R + 2·max ρ is correct (claim 2); wider cells keep the table small.
        w = radius_m + 2.0 * rmax
        while (ext[0] / w + 3.0) * (ext[1] / w + 3.0) * (ext[2] / w + 3.0) > max(8.0 * n, 4096.0):
            w *= 1.5
        span = np.zeros(3, dtype=np.int64)
        for ax in range(3):
            span[ax] = int(ext[ax] / w) + 3
        for i in range(n):
            for ax in range(3):
                cell[i, ax] = min(int(math.floor((pos[i, ax] - lo[ax]) / w)), span[ax] - 2)
            key[i] = (cell[i, 0] * span[1] + cell[i, 1]) * span[2] + cell[i, 2]
        # Counting sort of the drones by cell: head[q] .. head[q + 1] are the drones in cell q.
        n_cells = span[0] * span[1] * span[2]
        head = np.zeros(n_cells + 1, dtype=np.int64)
        for i in range(n):
            head[key[i] + 1] += 1
        for q in range(n_cells):
            head[q + 1] += head[q]
        fill = head[:-1].copy()
        order = np.empty(n, dtype=np.int64)
        for i in range(n):
            order[fill[key[i]]] = i
            fill[key[i]] += 1
        for i in range(n):
            for dx in range(-1, 2):
                for dy in range(-1, 2):
                    for dz in range(-1, 2):
                        cx, cy, cz = cell[i, 0] + dx, cell[i, 1] + dy, cell[i, 2] + dz
                        if cx < 0 or cy < 0 or cz < 0 or cx >= span[0] or cy >= span[1] or cz >= span[2]:
                            continue
                        q = (cx * span[1] + cy) * span[2] + cz
                        for m in range(head[q], head[q + 1]):
                            j = order[m]
                            if j <= i:
                                continue
                            lim = radius_m + rho[i] + rho[j]
                            d0 = pos[j, 0] - pos[i, 0]
                            d1 = pos[j, 1] - pos[i, 1]
                            d2 = pos[j, 2] - pos[i, 2]
                            if d0 * d0 + d1 * d1 + d2 * d2 <= lim * lim:
                                if count == cap:
                                    cap *= 2
                                    ki2 = np.empty(cap, dtype=np.int64)
                                    ks2 = np.empty(cap, dtype=np.int64)
                                    ki2[:count] = ki[:count]
                                    ks2[:count] = ks[:count]
                                    ki, ks = ki2, ks2
                                ki[count] = i * n + j
                                ks[count] = s
                                count += 1
    # Merge each pair's slices into [first, last] (claim 3).
    ki, ks = ki[:count], ks[:count]
    o = np.argsort(ki, kind="mergesort")
    out_i = np.empty(count, dtype=np.int64)
    out_j = np.empty(count, dtype=np.int64)
    first = np.empty(count, dtype=np.int64)
    last = np.empty(count, dtype=np.int64)
    u = -1
    prev = -1
    for m in range(count):
        k = ki[o[m]]
        s = ks[o[m]]
        if k != prev:
            u += 1
            out_i[u] = k // n
            out_j[u] = k % n
            first[u] = s
            last[u] = s
            prev = k
        else:
            first[u] = min(first[u], s)
            last[u] = max(last[u], s)
    u += 1
    return out_i[:u], out_j[:u], first[:u], last[:u]


def window_slices(breaks: _F, bounds: _F, t0: float, t1: float, radius_m: float) -> tuple[_F, _F]:
    """Slice starts and ends (S,) covering [t0, t1] with V_s·h <= radius (module docstring)."""
    length = t1 - t0
    v_w = _window_speed(breaks, bounds, t0, t1)
    if length <= 0 or v_w * length <= 0:
        return np.array([t0]), np.array([max(t1, t0)])
    cells = int(min(MAX_CELLS, max(1, math.ceil(CELLS_PER_SLICE * v_w * length / radius_m))))
    cell_s = length / cells
    env = np.empty(cells)
    envelope(breaks, bounds, t0, cell_s, cells, env)
    a, b, _ = greedy_slices(env, t0, cell_s, radius_m)
    b[-1] = t1  # the last cell ends at t1 up to rounding
    return a, b


__all__ = ["greedy_slices", "slice_candidates", "window_slices"]
