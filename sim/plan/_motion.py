"""Moving holds: a formation's keyframed transform (:mod:`formations._motion`) as per-drone quintic pieces.

The plan's only representation of motion is per-drone piecewise polynomials of degree <= 5
(:mod:`sim.plan._trajectory`), so the exact transform X_i(t) = c + M(t)(p_i - c) + T(t) of each
drone's formation point p_i is sampled at times t_0 < ... < t_S over each key interval, and
each sample interval becomes the quintic Hermite piece that matches X, X' and X'' of the
exact transform at both ends. Consecutive pieces therefore agree in position, velocity and
acceleration (C2), and the hold meets the transitions at rest (the first and last keys stop).

Error: the quintic Hermite interpolant of a C6 function on an interval of length h errs by
at most h⁶/46080 · max|X⁽⁶⁾| (the remainder (t-a)³(t-b)³ X⁽⁶⁾(ξ)/6!, |(t-a)³(t-b)³| <= (h/2)⁶),
so halving the sample spacing cuts the error ~64-fold. The sample count of each key
interval is chosen by doubling until the error, measured at :data:`_PROBES` interior times
per piece, is below :data:`FIT_TOLERANCE_M`. The fit is linear in the data and the data are
affine in p, so the error is affine in p, e(p) = E·(p - c) + e₀: four points give E and e₀, and
‖E‖₂·|p - c| + |e₀| bounds it for every point within the formation's radius at once
(:func:`fit_error_bound`), so the cost does not grow with the formation.
"""

from __future__ import annotations

import numpy as np

from formations._motion import Motion, apply, pivot_of, pose
from sim.plan._trajectory import DEGREE

#: Largest distance between a planned moving-hold piece and the exact transform, metres.
FIT_TOLERANCE_M = 1e-3
#: Interior times per piece at which the fit error is measured.
_PROBES = 16
#: Fewest and most samples per key interval (the most bounds the pieces a hold may cost).
_MIN_SAMPLES, _MAX_SAMPLES = 2, 1024
#: Most pieces x drones one moving hold may add to the plan (each costs 144 bytes of coefficients:
#: 288 MB at the limit), so no show file can make the planner run out of memory.
MAX_HOLD_PIECE_DRONES = 2_000_000


class MotionFitError(ValueError):
    """A moving hold cannot be fitted within the tolerance and the piece budget; ``key`` is the key
    interval's end key index (or -1 when the budget is the reason)."""

    def __init__(self, message: str, key: int) -> None:
        super().__init__(message)
        self.key = key


def hermite_quintic(p0: np.ndarray, v0: np.ndarray, a0: np.ndarray, p1: np.ndarray, v1: np.ndarray,
                    a1: np.ndarray, h: np.ndarray) -> np.ndarray:
    """(..., 6) ascending coefficients of the quintic on [0, h] with the given end values, velocities and
    accelerations (arrays (...,); ``h`` broadcasts)."""
    d = p1 - p0
    c = np.zeros(np.broadcast(p0, h).shape + (DEGREE + 1,))
    c[..., 0], c[..., 1], c[..., 2] = p0, v0, a0 / 2.0
    c[..., 3] = (20 * d - (8 * v1 + 12 * v0) * h - (3 * a0 - a1) * h**2) / (2 * h**3)
    c[..., 4] = (-30 * d + (14 * v1 + 16 * v0) * h + (3 * a0 - 2 * a1) * h**2) / (2 * h**4)
    c[..., 5] = (12 * d - 6 * (v1 + v0) * h - (a0 - a1) * h**2) / (2 * h**5)
    return c


def sample_times(motion: Motion, counts: np.ndarray) -> np.ndarray:
    """``counts[i]`` even sample intervals in key interval i: Σ counts + 1 increasing hold times."""
    t_k = np.array([k.t_s for k in motion.keys])
    parts = [t_k[i] + (t_k[i + 1] - t_k[i]) * np.arange(int(c)) / int(c) for i, c in enumerate(counts)]
    return np.append(np.concatenate(parts), t_k[-1])


def _fit(motion: Motion, pivot_m: np.ndarray, points_m: np.ndarray, times_s: np.ndarray) -> np.ndarray:
    """(n, S, 3, 6) Hermite pieces of ``points_m`` (n, 3) between consecutive ``times_s`` (S+1,)."""
    pos, vel, acc = apply(pose(motion, times_s), pivot_m, points_m)  # (S+1, n, 3)
    h = np.diff(times_s)[:, None, None]
    c = hermite_quintic(pos[:-1], vel[:-1], acc[:-1], pos[1:], vel[1:], acc[1:], h)  # (S, n, 3, 6)
    return np.ascontiguousarray(c.transpose(1, 0, 2, 3))


def fit_error(motion: Motion, pivot_m: np.ndarray, points_m: np.ndarray, times_s: np.ndarray,
              probes: int = _PROBES) -> float:
    """Largest distance (m) between the pieces through ``times_s`` and the exact transform of ``points_m``,
    at ``probes`` interior times per piece."""
    c = _fit(motion, pivot_m, points_m, times_s)  # (n, S, 3, 6)
    h = np.diff(times_s)
    u = (np.arange(1, probes + 1) / (probes + 1))[None, :] * h[:, None]  # (S, probes)
    exact, _, _ = apply(pose(motion, (times_s[:-1, None] + u).ravel()), pivot_m, points_m)  # (S*probes, n, 3)
    exact = exact.reshape(len(h), probes, len(points_m), 3)
    fitted = np.zeros_like(exact)
    for k in range(DEGREE, -1, -1):  # Horner over (S, probes, n, 3)
        fitted = fitted * u[:, :, None, None] + c[:, :, :, k].transpose(1, 0, 2)[:, None]
    return float(np.linalg.norm(fitted - exact, axis=-1).max(initial=0.0))


def fit_error_bound(motion: Motion, pivot_m: np.ndarray, radius_m: float, times_s: np.ndarray,
                    probes: int = _PROBES) -> float:
    """An upper bound (m) of :func:`fit_error` over every point within ``radius_m`` of the pivot.

    The fit is linear in the data and the data are affine in p, so the error is e(p) = E·(p - c) + e₀:
    four points (the pivot and a unit step along each axis) give E and e₀ exactly, and
    |e(p)| <= ‖E‖₂·|p - c| + |e₀| (triangle inequality) bounds every point at once, at the cost of
    four points whatever the formation's size.
    """
    probe_pts = pivot_m + np.vstack([np.zeros(3), np.eye(3)])  # (4, 3)
    c = _fit(motion, pivot_m, probe_pts, times_s)  # (4, S, 3, 6)
    h = np.diff(times_s)
    u = (np.arange(1, probes + 1) / (probes + 1))[None, :] * h[:, None]  # (S, probes)
    exact, _, _ = apply(pose(motion, (times_s[:-1, None] + u).ravel()), pivot_m, probe_pts)
    exact = exact.reshape(len(h), probes, 4, 3)
    fitted = np.zeros_like(exact)
    for k in range(DEGREE, -1, -1):
        fitted = fitted * u[:, :, None, None] + c[:, :, :, k].transpose(1, 0, 2)[:, None]
    err = fitted - exact  # (S, probes, 4, 3)
    e0 = err[:, :, 0]  # (S, probes, 3)
    e_lin = (err[:, :, 1:] - e0[:, :, None, :]).transpose(0, 1, 3, 2)  # (S, probes, 3, 3): columns E·e_k
    norm = np.linalg.norm(e_lin, ord=2, axis=(-2, -1))  # spectral norms
    return float((norm * radius_m + np.linalg.norm(e0, axis=-1)).max(initial=0.0))


def sample_counts(motion: Motion, points_m: np.ndarray, tolerance_m: float = FIT_TOLERANCE_M) -> np.ndarray:
    """(K-1,) samples per key interval that fit the motion of ``points_m`` (M, 3) within ``tolerance_m``.

    Each interval doubles from :data:`_MIN_SAMPLES` on its own (a quiet interval stays cheap) until
    :func:`fit_error_bound` over the formation's radius about the pivot is below the tolerance.

    Raises:
        MotionFitError: an interval needs more than :data:`_MAX_SAMPLES` (far more turning between two
            keys than drones can fly; more keys help).
    """
    pts = np.asarray(points_m, dtype=np.float64)
    pivot = pivot_of(motion, pts)
    radius = float(np.linalg.norm(pts - pivot, axis=1).max(initial=0.0))
    t_k = [k.t_s for k in motion.keys]
    counts = np.full(len(t_k) - 1, _MIN_SAMPLES, dtype=np.int64)
    for i in range(len(counts)):
        while fit_error_bound(motion, pivot, radius, np.linspace(t_k[i], t_k[i + 1], counts[i] + 1)) > tolerance_m:
            if counts[i] >= _MAX_SAMPLES:
                raise MotionFitError(
                    f"the motion between keys {i} and {i + 1} cannot be fitted within {tolerance_m * 1000:g} mm "
                    f"with {_MAX_SAMPLES} pieces: add keys in between", key=i + 1,
                )
            counts[i] *= 2
    return counts


def hold_pieces(motion: Motion, formation_points_m: np.ndarray, drone_points_m: np.ndarray, hold_s: float,
                tolerance_m: float = FIT_TOLERANCE_M) -> tuple[np.ndarray, np.ndarray]:
    """The pieces of a moving hold that every drone shares in time.

    Args:
        motion: the formation's motion (keys within [0, hold_s]).
        formation_points_m: (M, 3) all the formation's points (the default pivot is their centroid).
        drone_points_m: (N, 3) each drone's formation point (before the motion).
        hold_s: the hold's length, seconds.

    Returns:
        ``durations_s`` (P,) and ``coeffs_m`` (N, P, 3, 6): a rest at the first key's pose until the
        first key, the fitted pieces, and a rest at the last key's pose until ``hold_s`` (rests only
        when they are longer than zero).
    """
    pivot = pivot_of(motion, formation_points_m)
    times = sample_times(motion, sample_counts(motion, formation_points_m, tolerance_m))
    if (len(times) + 1) * len(drone_points_m) > MAX_HOLD_PIECE_DRONES:
        raise MotionFitError(
            f"the motion needs {len(times) - 1} pieces per drone for {len(drone_points_m)} drones, more than the "
            f"{MAX_HOLD_PIECE_DRONES:,} pieces x drones a hold may cost: use fewer keys or less motion", key=-1,
        )
    coeffs = _fit(motion, pivot, drone_points_m, times)
    durations = np.diff(times)
    first, _, _ = apply(pose(motion, times[:1]), pivot, drone_points_m)
    last, _, _ = apply(pose(motion, times[-1:]), pivot, drone_points_m)
    n = len(drone_points_m)
    if motion.start_s > 0:
        rest = np.zeros((n, 1, 3, DEGREE + 1))
        rest[:, 0, :, 0] = first[0]
        coeffs = np.concatenate([rest, coeffs], axis=1)
        durations = np.r_[motion.start_s, durations]
    if hold_s > motion.end_s:
        rest = np.zeros((n, 1, 3, DEGREE + 1))
        rest[:, 0, :, 0] = last[0]
        coeffs = np.concatenate([coeffs, rest], axis=1)
        durations = np.r_[durations, hold_s - motion.end_s]
    return durations, coeffs


def start_pose_points(motion: Motion, formation_points_m: np.ndarray) -> np.ndarray:
    """(M, 3) the formation's points at the first key's pose (where the transition into it ends)."""
    pts = np.asarray(formation_points_m, dtype=np.float64)
    at_start: np.ndarray = apply(pose(motion, np.array([motion.start_s])), pivot_of(motion, pts), pts)[0][0]
    return at_start


__all__ = [
    "FIT_TOLERANCE_M",
    "MAX_HOLD_PIECE_DRONES",
    "MotionFitError",
    "fit_error",
    "hermite_quintic",
    "hold_pieces",
    "sample_counts",
    "sample_times",
    "start_pose_points",
]
