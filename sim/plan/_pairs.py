"""Certified pair separation for drones on straight legs with their own timing.

Drone i flies p_i(t) = A_i + s_i(t)·D_i, with s_i a nondecreasing piecewise polynomial
(:mod:`sim.plan._timelaw`) that starts at its departure ``dep_i`` (optionally slowed by
a time scale ``k_i``: s_i(t) = σ_i((t - dep_i)/k_i)) and rests at 0 before and at 1 after.

**Certified lower bound on an interval [t0, t1]** of the offset r = p_j - p_i (the
larger of two bounds):

1. *Sub-segments.* s_i is monotone, so on [t0, t1] drone i stays on the sub-segment
   A_i + [s_i(t0), s_i(t1)]·D_i; the closed-form distance between the two sub-segments
   (Ericson, *Real-Time Collision Detection*, 2005, section 5.1.9) bounds |r| from below.
   It is tight when the drones are far apart on long intervals.
2. *Interpolation.* With r_lin the chord between r(t0) and r(t1),
   |r(t) - r_lin(t)| <= sup|r''|·(t - t0)(t1 - t)/2 <= sup|r''|·h²/8 (r is C¹ and piecewise C²),
   and min|r_lin| is a point-segment distance; sup|r''| <= Σ peak|s''|·|D| over the drones
   moving during the interval (0 for a drone at rest, so two parked drones are exact).

Branch and bound halves the interval until the bound clears the required distance
(safe) or a sampled distance falls below it (a certified conflict, with its time); an
interval narrower than ``H_MIN_S`` that is still undecided counts as a conflict
(conservative). Pairs with *identical timing* (same profile, departure and scale, e.g.
all drones of a synchronised CAPT transition) have r = a + s·c with one shared s, whose
minimum over s in [0, 1] is exact in closed form (the verifier's formula).

**Pruning.** Only pairs whose *paths* (the whole segments A_i B_i, rest points
included) come within the required distance can ever conflict, whatever the timing.
Each path is sampled at spacing <= c; every path point lies within c/2 of a sample, so
two paths within r have samples within r + c: a k-d tree ``query_pairs`` at radius
r + c over the samples misses no such pair; the exact segment-segment distance then
filters the candidates.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

_F = NDArray[np.float64]
_I = NDArray[np.int64]

#: Undecided intervals narrower than this count as conflicts, seconds.
H_MIN_S = 1e-5
_STACK = 256


@numba.njit(cache=True, inline="always")
def _prof(breaks: _F, coeffs: _F, row: int, u: float, deriv: int) -> float:  # pragma: no cover - numba
    """σ_row(u) (deriv 0) or σ_row'(u) (deriv 1), rest outside [0, duration]."""
    dur = breaks[row, 7]
    if u <= 0.0:
        return 0.0 if deriv == 0 or dur > 0.0 else 0.0
    if u >= dur:
        return 1.0 if deriv == 0 else 0.0
    k = 0
    for m in range(1, 7):
        if u >= breaks[row, m] and breaks[row, m] < dur:
            k = m
    x = u - breaks[row, k]
    out = 0.0
    if deriv == 0:
        for m in range(5, -1, -1):
            out = out * x + coeffs[row, k, m]
    else:
        for m in range(5, 0, -1):
            out = out * x + m * coeffs[row, k, m]
    return out


@numba.njit(cache=True, inline="always")
def _s(breaks: _F, coeffs: _F, row: int, dep: float, scale: float, t: float) -> float:  # pragma: no cover - numba
    return _prof(breaks, coeffs, row, (t - dep) / scale, 0)


@numba.njit(cache=True)
def seg_seg_dist(p0: _F, p1: _F, q0: _F, q1: _F) -> float:  # pragma: no cover - numba
    """Distance between segments [p0, p1] and [q0, q1] (3-vectors), closed form (Ericson 5.1.9)."""
    d1x, d1y, d1z = p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]
    d2x, d2y, d2z = q1[0] - q0[0], q1[1] - q0[1], q1[2] - q0[2]
    rx, ry, rz = p0[0] - q0[0], p0[1] - q0[1], p0[2] - q0[2]
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    eps = 1e-18
    if a <= eps and e <= eps:
        s = 0.0
        t = 0.0
    elif a <= eps:
        s = 0.0
        t = min(max(f / e, 0.0), 1.0)
    else:
        c = d1x * rx + d1y * ry + d1z * rz
        if e <= eps:
            t = 0.0
            s = min(max(-c / a, 0.0), 1.0)
        else:
            b = d1x * d2x + d1y * d2y + d1z * d2z
            denom = a * e - b * b
            s = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > eps * a * e else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t = 1.0
                s = min(max((b - c) / a, 0.0), 1.0)
    dx = rx + d1x * s - d2x * t
    dy = ry + d1y * s - d2y * t
    dz = rz + d1z * s - d2z * t
    return math.sqrt(dx * dx + dy * dy + dz * dz)


@numba.njit(cache=True, inline="always")
def _point_seg_origin(r0: _F, r1: _F) -> float:  # pragma: no cover - numba
    cx, cy, cz = r1[0] - r0[0], r1[1] - r0[1], r1[2] - r0[2]
    cc = cx * cx + cy * cy + cz * cz
    b = 0.0
    if cc > 0.0:
        b = min(max(-(r0[0] * cx + r0[1] * cy + r0[2] * cz) / cc, 0.0), 1.0)
    x, y, z = r0[0] + b * cx, r0[1] + b * cy, r0[2] + b * cz
    return math.sqrt(x * x + y * y + z * z)


@numba.njit(cache=True)
def pair_conflict(i: int, j: int, a_m: _F, d_m: _F, breaks: _F, coeffs: _F, prof_row: _I, dep: _F,
                  scale: _F, arr: _F, peak_s2: _F, length: _F, required_m: float,
                  ) -> tuple[bool, float]:  # pragma: no cover - numba
    """Certified check of one pair over all time.

    Returns (conflict, time_s): conflict is False iff the distance provably stays >= required_m.
    ``prof_row[i]`` selects drone i's profile row in ``breaks`` / ``coeffs``; ``arr[i]`` is
    its arrival time and ``peak_s2[i]`` the peak |σ''| of its profile (before scaling).
    """
    # Rest states: before both depart and after both arrive the offset is constant.
    ax = a_m[j, 0] - a_m[i, 0]
    ay = a_m[j, 1] - a_m[i, 1]
    az = a_m[j, 2] - a_m[i, 2]
    t_lo = min(dep[i], dep[j])
    t_hi = max(arr[i], arr[j])
    if math.sqrt(ax * ax + ay * ay + az * az) < required_m:
        return True, t_lo
    bx = ax + d_m[j, 0] - d_m[i, 0]
    by = ay + d_m[j, 1] - d_m[i, 1]
    bz = az + d_m[j, 2] - d_m[i, 2]
    if math.sqrt(bx * bx + by * by + bz * bz) < required_m:
        return True, t_hi
    ri, rj = prof_row[i], prof_row[j]
    if ri == rj and dep[i] == dep[j] and scale[i] == scale[j]:
        # Identical timing: r = a + s·c for one shared s in [0, 1], exact minimum.
        cx, cy, cz = bx - ax, by - ay, bz - az
        cc = cx * cx + cy * cy + cz * cz
        s = 0.0
        if cc > 0.0:
            s = min(max(-(ax * cx + ay * cy + az * cz) / cc, 0.0), 1.0)
        x, y, z = ax + s * cx, ay + s * cy, az + s * cz
        if math.sqrt(x * x + y * y + z * z) < required_m:
            # Time at which the shared profile reaches s (bisection on the monotone profile).
            lo, hi = dep[i], arr[i]
            for _ in range(60):
                mid = 0.5 * (lo + hi)
                if _s(breaks, coeffs, ri, dep[i], scale[i], mid) < s:
                    lo = mid
                else:
                    hi = mid
            return True, 0.5 * (lo + hi)
        return False, 0.0
    acc_i = peak_s2[ri] / (scale[i] * scale[i]) * length[i]
    acc_j = peak_s2[rj] / (scale[j] * scale[j]) * length[j]
    st0 = np.empty(_STACK)
    st1 = np.empty(_STACK)
    top = 0
    st0[0] = t_lo
    st1[0] = t_hi
    top = 1
    p0 = np.empty(3)
    p1 = np.empty(3)
    q0 = np.empty(3)
    q1 = np.empty(3)
    r0 = np.empty(3)
    r1 = np.empty(3)
    while top > 0:
        top -= 1
        t0 = st0[top]
        t1 = st1[top]
        si0 = _s(breaks, coeffs, ri, dep[i], scale[i], t0)
        si1 = _s(breaks, coeffs, ri, dep[i], scale[i], t1)
        sj0 = _s(breaks, coeffs, rj, dep[j], scale[j], t0)
        sj1 = _s(breaks, coeffs, rj, dep[j], scale[j], t1)
        for c in range(3):
            p0[c] = a_m[i, c] + si0 * d_m[i, c]
            p1[c] = a_m[i, c] + si1 * d_m[i, c]
            q0[c] = a_m[j, c] + sj0 * d_m[j, c]
            q1[c] = a_m[j, c] + sj1 * d_m[j, c]
            r0[c] = q0[c] - p0[c]
            r1[c] = q1[c] - p1[c]
        d0 = math.sqrt(r0[0] * r0[0] + r0[1] * r0[1] + r0[2] * r0[2])
        d1 = math.sqrt(r1[0] * r1[0] + r1[1] * r1[1] + r1[2] * r1[2])
        if d0 < required_m:
            return True, t0
        if d1 < required_m:
            return True, t1
        h = t1 - t0
        lb = seg_seg_dist(p0, p1, q0, q1)
        if lb >= required_m:
            continue
        m2 = 0.0
        if t1 > dep[i] and t0 < arr[i]:
            m2 += acc_i
        if t1 > dep[j] and t0 < arr[j]:
            m2 += acc_j
        lb2 = _point_seg_origin(r0, r1) - m2 * h * h / 8.0
        if lb2 >= required_m:
            continue
        if h < H_MIN_S or top + 2 > _STACK:
            return True, 0.5 * (t0 + t1)
        tm = 0.5 * (t0 + t1)
        st0[top] = tm
        st1[top] = t1
        st0[top + 1] = t0
        st1[top + 1] = tm
        top += 2
    return False, 0.0


def close_path_pairs(a_m: np.ndarray, b_m: np.ndarray, radius_m: float) -> np.ndarray:
    """(K, 2) pairs i < j whose segments A_i B_i and A_j B_j come within ``radius_m`` (see module docstring)."""
    n = len(a_m)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    d = b_m - a_m
    length = np.linalg.norm(d, axis=1)
    step = radius_m  # sample spacing c
    counts = np.maximum(1, np.ceil(length / step).astype(np.int64)) + 1
    owner = np.repeat(np.arange(n), counts)
    start = np.repeat(np.cumsum(counts) - counts, counts)
    frac = (np.arange(len(owner)) - start) / np.repeat(counts - 1, counts)
    pts = a_m[owner] + frac[:, None] * d[owner]
    raw = cKDTree(pts).query_pairs(radius_m + step, output_type="ndarray")
    if len(raw) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    i = owner[raw[:, 0]]
    j = owner[raw[:, 1]]
    keep = i != j
    lo, hi = np.minimum(i[keep], j[keep]), np.maximum(i[keep], j[keep])
    keys = np.unique(lo * n + hi)
    pairs = np.stack([keys // n, keys % n], axis=1)
    dist = _seg_dists(a_m, b_m, pairs)
    return np.asarray(pairs[dist < radius_m], dtype=np.int64)


@numba.njit(cache=True)
def _seg_dists(a_m: _F, b_m: _F, pairs: _I) -> _F:  # pragma: no cover - numba
    out = np.empty(len(pairs))
    for k in range(len(pairs)):
        i, j = pairs[k, 0], pairs[k, 1]
        out[k] = seg_seg_dist(a_m[i], b_m[i], a_m[j], b_m[j])
    return out


@numba.njit(cache=True)
def point_seg_dists(points: _F, a_m: _F, b_m: _F, pt_idx: _I, seg_idx: _I) -> _F:  # pragma: no cover - numba
    """Distance from points[pt_idx[k]] to segment A B [seg_idx[k]], for every k."""
    out = np.empty(len(pt_idx))
    for k in range(len(pt_idx)):
        p = points[pt_idx[k]]
        out[k] = seg_seg_dist(p, p, a_m[seg_idx[k]], b_m[seg_idx[k]])
    return out


@numba.njit(cache=True)
def pairs_conflicts(pairs: _I, a_m: _F, d_m: _F, breaks: _F, coeffs: _F, prof_row: _I, dep: _F,
                    scale: _F, arr: _F, peak_s2: _F, length: _F, required_m: float,
                    ) -> tuple[NDArray[np.bool_], _F]:  # pragma: no cover - numba
    """pair_conflict over (K, 2) pairs: (K,) conflict flags and times."""
    flags = np.zeros(len(pairs), dtype=np.bool_)
    times = np.zeros(len(pairs))
    for k in range(len(pairs)):
        c, t = pair_conflict(pairs[k, 0], pairs[k, 1], a_m, d_m, breaks, coeffs, prof_row, dep, scale, arr,
                             peak_s2, length, required_m)
        flags[k] = c
        times[k] = t
    return flags, times
