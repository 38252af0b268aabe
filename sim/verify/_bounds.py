"""Exact altitude-floor and geofence checks on the plan's per-drone polynomial pieces.

Every drone's position is piecewise polynomial (:class:`sim.plan.Trajectories`), so the
extremes of each coordinate over a piece are attained at the piece's ends or at a real
root of the coordinate's derivative inside it (Fermat's interior-extremum theorem). The
roots of all pieces' derivatives are found at once as eigenvalues of their companion
matrices, batched by degree, so the check is exact up to root-finding rounding and
vectorised over drones and pieces (no sampling: a dip between two samples cannot hide).

* ``min_altitude``: z >= ``settings.min_altitude_m`` between the end of takeoff and the
  start of the vertical landing (Skybrush's minimum navigation altitude).
* ``geofence``: x, y inside ``settings.geofence`` for the whole show.
"""

from __future__ import annotations

import math

import numpy as np

from formations import Settings
from sim.plan import ShowPlan, Trajectories
from sim.verify._violation import Violation

#: A bound is broken only by more than this (metres), like the other checks' float tolerance.
_TOL_M = 1e-9
#: Derivative coefficients below this fraction of the largest one are treated as zero when
#: finding a piece's degree (the extreme value moves by at most that much of its scale).
_DEGREE_RTOL = 1e-12
#: At most this many drones are named per violation (worst first).
_MAX_DRONES_LISTED = 10


def _critical_points(coeffs: np.ndarray) -> np.ndarray:
    """Real parts of every root of each polynomial's derivative.

    Args:
        coeffs: (M, D+1) ascending powers.

    Returns:
        (M, D-1) candidate abscissae, NaN where a polynomial has fewer roots. Extra
        (complex or spurious) candidates are harmless: callers clip them into the
        interval and evaluate the true polynomial there, which can never exceed its range.
    """
    m, d1 = coeffs.shape
    deg = d1 - 1
    der = coeffs[:, 1:] * np.arange(1, d1, dtype=np.float64)  # (M, D) ascending, degree D-1
    out = np.full((m, max(deg - 1, 0)), np.nan)
    scale = np.abs(der).max(axis=1, initial=0.0)
    nonzero = np.abs(der) > _DEGREE_RTOL * scale[:, None]
    # Degree of each derivative: its highest coefficient that is not negligible (-1 for zero).
    top = np.where(nonzero.any(axis=1), deg - 1 - np.argmax(nonzero[:, ::-1], axis=1), -1)
    for k in range(1, deg):
        rows = np.flatnonzero(top == k)
        if not len(rows):
            continue
        monic = der[rows, :k] / der[rows, k][:, None]  # (r, k): a_0..a_{k-1} of u^k + Σ a_j u^j
        comp = np.zeros((len(rows), k, k))
        comp[:, 0, :] = -monic[:, ::-1]
        if k > 1:
            comp[:, np.arange(1, k), np.arange(k - 1)] = 1.0
        out[rows, :k] = np.linalg.eigvals(comp).real
    return out


def piece_extremes(plan_motion: Trajectories, start_s: np.ndarray, end_s: np.ndarray) -> tuple[np.ndarray, ...]:
    """Exact minimum and maximum of x, y, z of every drone's piece over [start_s, end_s].

    Args:
        plan_motion: :class:`sim.plan.Trajectories` with N drones and P pieces.
        start_s, end_s: (N, P) the part of each piece to consider (seconds, inside the piece);
            pieces with start_s > end_s are skipped (their results are NaN).

    Returns:
        ``(low_m, low_t_s, high_m, high_t_s)``: (N, P, 3) extreme values and when they occur.
    """
    b, c = plan_motion.breaks_s, plan_motion.coeffs_m  # (N, P+1), (N, P, 3, D+1)
    n, p, _, d1 = c.shape
    t0_all = np.repeat(b[:, :-1, None], 3, axis=2).reshape(-1)
    lo_all = (np.repeat(start_s[..., None], 3, axis=2).reshape(-1)) - t0_all
    hi_all = (np.repeat(end_s[..., None], 3, axis=2).reshape(-1)) - t0_all
    valid = lo_all <= hi_all
    shape = (n, p, 3)
    low_all, high_all = np.full(n * p * 3, np.nan), np.full(n * p * 3, np.nan)
    low_t, high_t = np.full(n * p * 3, np.nan), np.full(n * p * 3, np.nan)
    rows_v = np.flatnonzero(valid)  # only the pieces asked for (root finding is the costly part)
    flat = c.reshape(-1, d1)[rows_v]
    t0, lo_u, hi_u = t0_all[rows_v], lo_all[rows_v], hi_all[rows_v]
    # Roots in the piece's normalised time s = u / L in [0, 1], so that the degree cut-off
    # compares coefficients on one scale whatever the piece's length.
    length = np.repeat(np.diff(b, axis=1)[..., None], 3, axis=2).reshape(-1)[rows_v]
    length = np.where(length > 0, length, 1.0)
    scaled = flat * length[:, None] ** np.arange(d1, dtype=np.float64)
    roots_u = _critical_points(scaled) * length[:, None]
    cand = np.concatenate([lo_u[:, None], hi_u[:, None], roots_u], axis=1)  # (M, C)
    cand = np.clip(np.where(np.isnan(cand), lo_u[:, None], cand), lo_u[:, None], hi_u[:, None])
    val = flat[:, -1:].repeat(cand.shape[1], axis=1)
    for k in range(d1 - 2, -1, -1):  # Horner at every candidate
        val = val * cand + flat[:, k:k + 1]
    rows = np.arange(len(flat))
    imin, imax = np.argmin(val, axis=1), np.argmax(val, axis=1)
    low_all[rows_v], high_all[rows_v] = val[rows, imin], val[rows, imax]
    low_t[rows_v], high_t[rows_v] = cand[rows, imin] + t0, cand[rows, imax] + t0
    return low_all.reshape(shape), low_t.reshape(shape), high_all.reshape(shape), high_t.reshape(shape)


def hull_bounds(plan_motion: Trajectories) -> tuple[np.ndarray, np.ndarray]:
    """(N, P, 3) lower and upper bounds of x, y, z on every piece: the smallest and largest
    Bernstein coefficient of each coordinate on the piece (convex-hull property; Farouki &
    Rajan 1987). Cheap, used to skip root finding on pieces that cannot break a bound."""
    b, c = plan_motion.breaks_s, plan_motion.coeffs_m
    n, p, _, d1 = c.shape
    deg = d1 - 1
    w = np.array([[math.comb(k, m) / math.comb(deg, m) if m <= k else 0.0 for m in range(d1)] for k in range(d1)])
    lo, hi = np.empty((n, p, 3)), np.empty((n, p, 3))
    for a in range(0, n, 512):
        length = np.diff(b[a:a + 512], axis=1)[..., None, None]  # (n', P, 1, 1)
        scaled = c[a:a + 512] * length ** np.arange(d1)
        bern = scaled @ w.T  # (n', P, 3, D+1)
        lo[a:a + 512], hi[a:a + 512] = bern.min(axis=-1), bern.max(axis=-1)
    return lo, hi


def _window_s(plan: ShowPlan) -> tuple[float, float]:
    """When the altitude floor applies: from the end of takeoff to the start of the vertical landing."""
    takeoff = [s.end_s for s in plan.segments if s.kind == "takeoff"]
    landing = [s.start_s for s in plan.segments if s.kind == "landing"]
    start = max(takeoff) if takeoff else plan.motion.start_s
    end = min(landing) if landing else plan.motion.end_s
    return start, end


def _grouped(
    plan: ShowPlan, kind: str, excess_m: np.ndarray, value_m: np.ndarray, time_s: np.ndarray,
    limit_m: float, describe: str,
) -> list[Violation]:
    """One violation per segment in which some drone's worst piece breaks the bound.

    ``excess_m`` (N, P): how far past the bound each piece goes (NaN or <= tol: fine).
    """
    bad_drone, bad_piece = np.nonzero(np.nan_to_num(excess_m, nan=-np.inf) > _TOL_M)
    if not len(bad_drone):
        return []
    seg = np.asarray(plan.segment_index(time_s[bad_drone, bad_piece]))
    out: list[Violation] = []
    for k in np.unique(seg):
        sel = seg == k
        d, pc = bad_drone[sel], bad_piece[sel]
        ex = excess_m[d, pc]
        order = np.argsort(-ex, kind="stable")
        drones: list[int] = []
        for i in d[order]:
            if int(i) not in drones:
                drones.append(int(i))
        w = order[0]
        value, t = float(value_m[d[w], pc[w]]), float(time_s[d[w], pc[w]])
        label = plan.segments[int(k)].label
        out.append(Violation(
            kind=kind, drones=drones[:_MAX_DRONES_LISTED], time_s=t, value=value, limit=float(limit_m),
            segment=int(k),
            message=(f"{len(drones)} drone{'s' if len(drones) > 1 else ''} {describe} during {label!r}: "
                     f"drone {drones[0]} reaches {value:.2f} m at {t:.1f} s (limit {limit_m:g} m)"),
        ))
    return out


def check_bounds(plan: ShowPlan, settings: Settings) -> list[Violation]:
    """Exact minimum-altitude and geofence violations of a plan, one per (bound, segment).

    Args:
        plan: the planned show (its ``motion`` and ``segments`` are read).
        settings: the limits: ``min_altitude_m`` and the optional ``geofence``.

    Returns:
        Violations of kind ``"min_altitude"`` (value: the lowest altitude reached, metres) and
        ``"geofence"`` (value: the coordinate reached beyond the fence's side, metres), worst drone first.
    """
    motion = plan.motion
    b = motion.breaks_s
    w0, w1 = _window_s(plan)
    start = np.maximum(b[:, :-1], w0)
    end = np.minimum(b[:, 1:], w1)
    out: list[Violation] = []
    floor = float(settings.min_altitude_m)
    fence = settings.geofence
    if not ((floor > 0 and w0 <= w1) or fence is not None):
        return out
    hull_lo, hull_hi = hull_bounds(motion)
    if floor > 0 and w0 <= w1:
        # Pieces whose hull stays above the floor cannot break it: no root finding there.
        skip = hull_lo[..., 2] > floor + _TOL_M
        # Drones landed mid-show (a subset formation's others, issue 21) are exempt from their descent
        # to their climb, as in takeoff and landing; their pieces start and end on those times.
        for g0, g1, drones in getattr(plan, "grounded", ()):  # a plan-like stand-in may have none
            skip[drones] |= (b[drones, :-1] >= g0 - 1e-9) & (b[drones, 1:] <= g1 + 1e-9)
        low, low_t, _, _ = piece_extremes(motion, start, np.where(skip, start - 1.0, end))
        out += _grouped(plan, "min_altitude", floor - low[..., 2], low[..., 2], low_t[..., 2], floor,
                        "fly below the minimum altitude")
    if fence is not None:
        inside = ((hull_lo[..., 0] > fence.x_min_m + _TOL_M) & (hull_hi[..., 0] < fence.x_max_m - _TOL_M)
                  & (hull_lo[..., 1] > fence.y_min_m + _TOL_M) & (hull_hi[..., 1] < fence.y_max_m - _TOL_M))
        low, low_t, high, high_t = piece_extremes(motion, b[:, :-1], np.where(inside, b[:, :-1] - 1.0, b[:, 1:]))
        sides = (
            (0, "x_min_m", fence.x_min_m, fence.x_min_m - low[..., 0], low[..., 0], low_t[..., 0]),
            (0, "x_max_m", fence.x_max_m, high[..., 0] - fence.x_max_m, high[..., 0], high_t[..., 0]),
            (1, "y_min_m", fence.y_min_m, fence.y_min_m - low[..., 1], low[..., 1], low_t[..., 1]),
            (1, "y_max_m", fence.y_max_m, high[..., 1] - fence.y_max_m, high[..., 1], high_t[..., 1]),
        )
        for axis, name, limit, excess, value, when in sides:
            out += _grouped(plan, "geofence", excess, value, when, limit,
                            f"leave the geofence ({'xy'[axis]} beyond {name})")
    out.sort(key=lambda v: v.time_s)
    return out


__all__ = ["check_bounds", "piece_extremes"]
