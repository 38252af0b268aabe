"""Formations that move during their hold: keyframed similarity transforms (issue 21, item 5).

A formation's ``motion`` moves its points over the hold as one rigid body that may also
scale uniformly. At hold time t (seconds from the start of the hold) a point p goes to

    X(t) = c + s(t)·R(t)·(p - c) + T(t),      R = R_z(r_z)·R_y(r_y)·R_x(r_x)

with the pivot c (``pivot_m``, default the formation's centroid), the translation T
(``translate_m``), the Euler angles r (``rotate_deg``: about the fixed x, then y, then z
axes) and the scale s. Each of these seven channels is interpolated between the keys on
its own, by a quintic Hermite polynomial per key interval that matches the keys' values,
velocities and zero accelerations (so the channel is C2):

* a key's ``easing`` says how the motion passes it: ``"smooth"`` stops there (velocity 0,
  the rest-to-rest s(τ) = 10τ³ - 15τ⁴ + 6τ⁵ between two such keys), ``"linear"`` goes
  through at the rate of the chord between its neighbours (Catmull-Rom; a chain of evenly
  timed ``linear`` keys with even steps moves at a constant rate);
* the first and last keys always stop: the drones rest at the start and end of a hold,
  where the transitions meet them (the plan's knots);
* before the first key the formation rests at the first key's pose, after the last key at
  the last key's; angles interpolate as numbers, so 0 -> 360 deg is a full turn.

Distances between points scale with s (rotation and translation keep them), so the pair
distance at any instant is s(t) times the formation's own. Velocities and accelerations
are affine in p (X' = M'(t)(p - c) + T'(t), M = s·R), so their largest norms over all points
are reached at the extreme points of the formation's convex hull: the checks below evaluate
only those. Everything here is exact evaluation of the transform; the plan turns it into
per-drone polynomial pieces (:mod:`sim.plan._motion`).
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, NamedTuple

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator
from pydantic_core import PydanticCustomError

#: Most keys one motion may have (each key interval costs the plan pieces for every drone).
MAX_MOTION_KEYS = 64
#: Largest rotation a key may name, degrees (100 turns).
MAX_ROTATE_DEG = 36_000.0
#: Scale factors allowed at a key.
MIN_SCALE, MAX_SCALE = 0.01, 100.0
#: Samples per key interval when the motion's speed, acceleration and reach are checked. The
#: channels are quintics, so the sampled maxima are within O(h²) of the true ones; the exact
#: check of the planned pieces (:mod:`sim.verify`) has the last word.
CHECK_SAMPLES_PER_KEY = 128

_CONFIG = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True, revalidate_instances="never")

Vec3 = Annotated[list[float], Field(min_length=3, max_length=3)]


class MotionKey(BaseModel):
    """The formation's pose at hold time ``t_s``."""

    model_config = _CONFIG

    t_s: float = Field(ge=0, le=86_400, description="Seconds from the start of the hold.")
    translate_m: Vec3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="Translation, metres.")
    rotate_deg: Vec3 = Field(
        default_factory=lambda: [0.0, 0.0, 0.0],
        description="Rotation about the pivot, degrees about the fixed x, then y, then z axes.",
    )
    scale: float = Field(1.0, ge=MIN_SCALE, le=MAX_SCALE, description="Uniform scale about the pivot (> 0).")
    easing: Literal["smooth", "linear"] = Field(
        "smooth", description="'smooth': the motion stops at this key; 'linear': it goes through at the "
        "rate of its neighbours' chord. The first and last keys always stop.",
    )

    @model_validator(mode="after")
    def _bounded(self) -> MotionKey:
        if any(abs(v) > MAX_ROTATE_DEG for v in self.rotate_deg):
            raise PydanticCustomError("rotate_range", "rotate_deg values must lie within +-{m} deg",
                                      {"m": MAX_ROTATE_DEG})
        if any(abs(v) > 100_000 for v in self.translate_m):
            raise PydanticCustomError("translate_range", "translate_m values must lie within +-100000 m")
        return self


class Motion(BaseModel):
    """Keyframed motion of a formation during its hold (see the module docstring)."""

    model_config = _CONFIG

    pivot_m: Vec3 | None = Field(None, description="Pivot of rotation and scale, metres (default: the centroid).")
    keys: Annotated[list[MotionKey], Field(min_length=2, max_length=MAX_MOTION_KEYS)]

    @model_validator(mode="after")
    def _increasing(self) -> Motion:
        for k in range(1, len(self.keys)):
            if self.keys[k].t_s <= self.keys[k - 1].t_s:
                raise PydanticCustomError(
                    "keys_order", "keys[{k}].t_s = {t} s is not after keys[{p}].t_s = {tp} s: key times must "
                    "increase", {"k": k, "t": self.keys[k].t_s, "p": k - 1, "tp": self.keys[k - 1].t_s},
                )
        return self

    @property
    def start_s(self) -> float:
        """First key's time, seconds into the hold."""
        return float(self.keys[0].t_s)

    @property
    def end_s(self) -> float:
        """Last key's time, seconds into the hold."""
        return float(self.keys[-1].t_s)


def pivot_of(motion: Motion, points_m: np.ndarray) -> np.ndarray:
    """(3,) the pivot: ``pivot_m`` or the centroid of ``points_m`` (M, 3)."""
    if motion.pivot_m is not None:
        return np.asarray(motion.pivot_m, dtype=np.float64)
    centroid: np.ndarray = np.asarray(points_m, dtype=np.float64).mean(axis=0)
    return centroid


def channels(motion: Motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Key times (K,), channel values (K, 7) = [tx, ty, tz, rx, ry, rz (rad), s] and key velocities (K, 7)."""
    t = np.array([k.t_s for k in motion.keys])
    q = np.array([[*k.translate_m, *np.radians(k.rotate_deg), k.scale] for k in motion.keys])
    v = np.zeros_like(q)
    for i in range(1, len(t) - 1):
        if motion.keys[i].easing == "linear":
            v[i] = (q[i + 1] - q[i - 1]) / (t[i + 1] - t[i - 1])
    return t, q, v


class ChannelSample(NamedTuple):
    """Channels and their first two time derivatives at T times: (T, 7) each."""

    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray


def sample_channels(motion: Motion, times_s: np.ndarray) -> ChannelSample:
    """The interpolated channels at hold times ``times_s`` (T,) (clamped to the keys: rest outside)."""
    t_k, q_k, v_k = channels(motion)
    t = np.clip(np.asarray(times_s, dtype=np.float64), t_k[0], t_k[-1])
    i = np.clip(np.searchsorted(t_k, t, side="right") - 1, 0, len(t_k) - 2)
    h = (t_k[i + 1] - t_k[i])[:, None]
    u = (t - t_k[i])[:, None] / h
    p0, p1 = q_k[i], q_k[i + 1]
    m0, m1 = v_k[i] * h, v_k[i + 1] * h  # velocities in the unit interval's time
    # Quintic Hermite basis with zero end accelerations (values and slopes only).
    h00 = 1 - 10 * u**3 + 15 * u**4 - 6 * u**5
    h10 = u - 6 * u**3 + 8 * u**4 - 3 * u**5
    h01 = 10 * u**3 - 15 * u**4 + 6 * u**5
    h11 = -4 * u**3 + 7 * u**4 - 3 * u**5
    d00 = -30 * u**2 + 60 * u**3 - 30 * u**4
    d10 = 1 - 18 * u**2 + 32 * u**3 - 15 * u**4
    d11 = -12 * u**2 + 28 * u**3 - 15 * u**4
    dd00 = -60 * u + 180 * u**2 - 120 * u**3
    dd10 = -36 * u + 96 * u**2 - 60 * u**3
    dd11 = -24 * u + 84 * u**2 - 60 * u**3
    q = h00 * p0 + h10 * m0 + h01 * p1 + h11 * m1
    dq = (d00 * (p0 - p1) + d10 * m0 + d11 * m1) / h
    ddq = (dd00 * (p0 - p1) + dd10 * m0 + dd11 * m1) / h**2
    outside = ((np.asarray(times_s) < t_k[0]) | (np.asarray(times_s) > t_k[-1]))[:, None]
    return ChannelSample(q, np.where(outside, 0.0, dq), np.where(outside, 0.0, ddq))


def _axis_rotation(angle: np.ndarray, axis: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """R(θ), dR/dθ and d²R/dθ² about a coordinate axis, (T, 3, 3) each."""
    c, s = np.cos(angle), np.sin(angle)
    a, b = [(1, 2), (0, 2), (0, 1)][axis]
    sign = -1.0 if axis == 1 else 1.0  # R_y has the sine's signs swapped (right-handed)
    r, d, dd = (np.zeros((len(angle), 3, 3)) for _ in range(3))
    r[:, axis, axis] = 1.0
    r[:, a, a], r[:, b, b] = c, c
    r[:, a, b], r[:, b, a] = -sign * s, sign * s
    d[:, a, a], d[:, b, b] = -s, -s
    d[:, a, b], d[:, b, a] = -sign * c, sign * c
    dd[:, a, a], dd[:, b, b] = -c, -c
    dd[:, a, b], dd[:, b, a] = sign * s, -sign * s
    return r, d, dd


def _chain(f: tuple[np.ndarray, np.ndarray, np.ndarray],
           g: tuple[np.ndarray, np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(F·G, (F·G)', (F·G)'') from (F, F', F'') and (G, G', G'') (the product rule twice)."""
    return f[0] @ g[0], f[1] @ g[0] + f[0] @ g[1], f[2] @ g[0] + 2 * f[1] @ g[1] + f[0] @ g[2]


class Pose(NamedTuple):
    """The transform at T times: linear part M = s·R and translation T, with two time derivatives.

    ``m``, ``dm``, ``ddm``: (T, 3, 3); ``t``, ``dt``, ``ddt``: (T, 3). A point p goes to
    c + M (p - c) + T.
    """

    m: np.ndarray
    dm: np.ndarray
    ddm: np.ndarray
    t: np.ndarray
    dt: np.ndarray
    ddt: np.ndarray


def pose(motion: Motion, times_s: np.ndarray) -> Pose:
    """The exact transform and its first two derivatives at hold times ``times_s`` (T,)."""
    ch = sample_channels(motion, np.atleast_1d(np.asarray(times_s, dtype=np.float64)))
    out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    for axis in (2, 1, 0):  # R = R_z R_y R_x
        r, d, dd = _axis_rotation(ch.q[:, 3 + axis], axis)
        w, dw = ch.dq[:, 3 + axis, None, None], ch.ddq[:, 3 + axis, None, None]
        factor = (r, w * d, dw * d + w * w * dd)  # chain rule for R(θ(t))
        out = factor if out is None else _chain(out, factor)
    assert out is not None
    s, ds, dds = (x[:, 6, None, None] for x in ch)
    m = s * out[0]
    dm = ds * out[0] + s * out[1]
    ddm = dds * out[0] + 2 * ds * out[1] + s * out[2]
    return Pose(m, dm, ddm, ch.q[:, :3], ch.dq[:, :3], ch.ddq[:, :3])


def apply(p: Pose, pivot_m: np.ndarray, points_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions, velocities, accelerations of ``points_m`` (n, 3) under the pose: (T, n, 3) each."""
    rel = np.asarray(points_m, dtype=np.float64) - pivot_m
    # (n, 3) @ (T, 3, 3)ᵀ -> (T, n, 3): matmul (BLAS), not einsum, which loops.
    pos = np.matmul(rel, p.m.transpose(0, 2, 1)) + (pivot_m + p.t)[:, None, :]
    vel = np.matmul(rel, p.dm.transpose(0, 2, 1)) + p.dt[:, None, :]
    acc = np.matmul(rel, p.ddm.transpose(0, 2, 1)) + p.ddt[:, None, :]
    return pos, vel, acc


def extreme_points(points_m: np.ndarray) -> np.ndarray:
    """Indices of points that include every vertex of their convex hull (all points when the hull is degenerate).

    Any affine function's largest norm over the points is reached at one of these.
    """
    pts = np.asarray(points_m, dtype=np.float64)
    if len(pts) <= 64:
        return np.arange(len(pts))
    from scipy.spatial import ConvexHull, QhullError

    try:
        # "QJ" joggles the input so that flat formations (a logo in a plane) have a hull too; the
        # joggled hull's vertices are still indices of input points, and include the true ones.
        return np.asarray(ConvexHull(pts, qhull_options="QJ").vertices, dtype=np.int64)
    except (QhullError, ValueError):
        return np.arange(len(pts))


def check_times(motion: Motion, per_key: int | None = None) -> np.ndarray:
    """Hold times at which the motion is checked: ``per_key`` per key interval, keys included.

    By default :data:`CHECK_SAMPLES_PER_KEY`, fewer (at least 16) when there are many keys, so
    that a check never takes more than :data:`_MAX_CHECK_TIMES` times.
    """
    t_k = np.array([k.t_s for k in motion.keys])
    if per_key is None:
        per_key = max(16, min(CHECK_SAMPLES_PER_KEY, _MAX_CHECK_TIMES // (len(t_k) - 1)))
    u = np.arange(per_key) / per_key
    return np.append((t_k[:-1, None] + np.diff(t_k)[:, None] * u).ravel(), t_k[-1])


#: Most times a motion is checked at, and most (time, hull point) pairs evaluated at once.
_MAX_CHECK_TIMES = 1024
_CHUNK_PAIRS = 1 << 20


_Scan = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
#: Most hull points a show file's motion check evaluates (a sphere's hull is all its points): the
#: check's cost stays bounded per formation; the exact check of the planned pieces has the last word.
MAX_SCAN_POINTS = 4096


def _few(hull: np.ndarray, pivot: np.ndarray) -> np.ndarray:
    """At most :data:`MAX_SCAN_POINTS` of the hull points: the farthest from the pivot, the extremes
    along each axis, and an even stride through the rest."""
    if len(hull) <= MAX_SCAN_POINTS:
        return hull
    far = np.argsort(-np.linalg.norm(hull - pivot, axis=1))[: MAX_SCAN_POINTS // 4]
    ends = np.r_[hull.argmin(axis=0), hull.argmax(axis=0)]
    stride = np.linspace(0, len(hull) - 1, MAX_SCAN_POINTS - len(far) - len(ends)).astype(np.int64)
    few: np.ndarray = hull[np.unique(np.r_[far, ends, stride])]
    return few


def _scan(motion: Motion, points_m: np.ndarray) -> _Scan:
    """Per check time (T,): lowest and highest x, y, z (T, 3) each, and peak velocity terms (T, 4) =
    [horizontal speed, |vertical speed|, descent speed, acceleration] over the hull points, and the times.

    Evaluated in chunks of times, so that memory stays bounded however many hull points there are.
    """
    pts = np.asarray(points_m, dtype=np.float64)
    pivot = pivot_of(motion, pts)
    hull = _few(pts[extreme_points(pts)], pivot)
    t = check_times(motion)
    lo, hi, peaks = np.empty((len(t), 3)), np.empty((len(t), 3)), np.empty((len(t), 4))
    step = max(1, _CHUNK_PAIRS // max(len(hull), 1))
    rel_t = np.ascontiguousarray((hull - pivot).T)  # (3, H): points last, so every reduction is contiguous
    for a in range(0, len(t), step):
        p = pose(motion, t[a:a + step])
        pos = np.matmul(p.m, rel_t) + (pivot + p.t)[:, :, None]  # (Tc, 3, H)
        lo[a:a + step], hi[a:a + step] = pos.min(axis=-1), pos.max(axis=-1)
        vel = np.matmul(p.dm, rel_t) + p.dt[:, :, None]
        peaks[a:a + step, 0] = np.sqrt(vel[:, 0] ** 2 + vel[:, 1] ** 2).max(axis=-1)
        peaks[a:a + step, 1] = vel[:, 2].max(axis=-1)
        peaks[a:a + step, 2] = -vel[:, 2].min(axis=-1)
        acc = np.matmul(p.ddm, rel_t) + p.ddt[:, :, None]
        peaks[a:a + step, 3] = np.sqrt((acc**2).sum(axis=1)).max(axis=-1)
    # |vertical speed| and descent speed: the largest upward and downward vertical speeds.
    up, down = peaks[:, 1].copy(), peaks[:, 2].copy()
    peaks[:, 1] = np.maximum(up, down)
    peaks[:, 2] = np.maximum(down, 0.0)
    return lo, hi, peaks, t


class MotionPeaks(NamedTuple):
    """Largest horizontal speed, vertical speed, descent speed (m/s) and acceleration (m/s²), and when (s)."""

    speed_xy_mps: float
    speed_xy_t_s: float
    speed_z_mps: float
    speed_z_t_s: float
    descent_mps: float
    descent_t_s: float
    accel_mps2: float
    accel_t_s: float


def motion_peaks(motion: Motion, points_m: np.ndarray, scan: _Scan | None = None) -> MotionPeaks:
    """The motion's peak speeds and acceleration over every point of ``points_m`` (M, 3) (sampled in time)."""
    _, _, peaks, t = scan if scan is not None else _scan(motion, points_m)
    i, j, k, m = (int(np.argmax(peaks[:, c])) for c in range(4))
    return MotionPeaks(float(peaks[i, 0]), float(t[i]), float(peaks[j, 1]), float(t[j]), float(peaks[k, 2]),
                       float(t[k]), float(peaks[m, 3]), float(t[m]))


def stretch_needed(peaks: MotionPeaks, v_xy: float, v_z: float, v_down: float, a_max: float) -> float:
    """The factor by which the key times must at least be stretched to meet the limits (1: they are met).

    Stretching time by λ divides velocities by λ and accelerations by λ².
    """
    return max(1.0, peaks.speed_xy_mps / v_xy, peaks.speed_z_mps / v_z, peaks.descent_mps / v_down,
               math.sqrt(peaks.accel_mps2 / a_max))


def min_scale(motion: Motion) -> tuple[float, float]:
    """(smallest scale, hold time it is reached) over the sampled motion (keys included)."""
    t = check_times(motion)
    s = sample_channels(motion, t).q[:, 6]
    i = int(np.argmin(s))
    return float(s[i]), float(t[i])


def reach(motion: Motion, points_m: np.ndarray,
          scan: _Scan | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Lowest and highest x, y, z any point reaches during the motion, (3,) each, and when (hold times, (3,))."""
    lo, hi, _, t = scan if scan is not None else _scan(motion, points_m)
    ilo, ihi = lo.argmin(axis=0), hi.argmax(axis=0)
    ax = np.arange(3)
    return lo[ilo, ax], t[ilo], hi[ihi, ax], t[ihi]


def motion_problem(
    motion: Motion, points_m: np.ndarray, hold_s: float | None, *, min_distance_m: float, closest_m: float,
    floor_m: float, ceiling_m: float, extent_m: float, fence: tuple[float, float, float, float] | None,
    v_xy: float, v_z: float, v_down: float, a_max: float,
) -> tuple[tuple[str | int, ...], str] | None:
    """The first rule a formation's motion breaks, as (path below ``motion``, reason), or None.

    Args:
        motion: the formation's motion.
        points_m: (M, 3) the formation's points.
        hold_s: its hold, seconds (None when ``leave_at_s`` sets it: checked when planned).
        closest_m: the formation's own closest-pair distance, metres.
        fence: (x_min, x_max, y_min, y_max) metres, or None.
        floor_m, ceiling_m, extent_m: altitude floor and ceiling, show area half-width, metres.
        v_xy, v_z, v_down, a_max: the speed (m/s) and acceleration (m/s²) limits.
    """
    if hold_s is not None and motion.end_s > hold_s + 1e-9:
        return ("keys", len(motion.keys) - 1, "t_s"), (
            f"{motion.end_s:g} s is after the end of the hold (hold_s = {hold_s:g} s): keys must lie within "
            f"[0, hold_s]"
        )
    s_min, s_t = min_scale(motion)
    if s_min <= 0:
        return ("keys",), f"the scale reaches {s_min:.3f} at {s_t:.2f} s into the hold; it must stay > 0"
    if math.isfinite(closest_m) and closest_m * s_min < min_distance_m - 1e-9:
        need = min_distance_m / closest_m
        return ("keys",), (
            f"at its smallest scale {s_min:.3f} ({s_t:.2f} s into the hold) the formation's closest points are "
            f"{closest_m * s_min:.3f} m apart, closer than min_distance_m {min_distance_m} m: keep the scale at "
            f"least {need:.3f}"
        )
    scan = _scan(motion, points_m)
    lo, lo_t, hi, hi_t = reach(motion, points_m, scan)
    reasons: list[tuple[bool, int, float, float, str]] = [
        (hi[2] > ceiling_m + 1e-9, 2, hi[2], hi_t[2], f"above max_altitude_m {ceiling_m:g} m"),
        (lo[2] < floor_m - 1e-9, 2, lo[2], lo_t[2], f"below min_altitude_m {floor_m:g} m"),
        (max(-lo[0], hi[0]) > extent_m, 0, lo[0] if -lo[0] > hi[0] else hi[0], lo_t[0] if -lo[0] > hi[0] else hi_t[0],
         f"outside the show area +-{extent_m:g} m (settings.max_horizontal_extent_m)"),
        (max(-lo[1], hi[1]) > extent_m, 1, lo[1] if -lo[1] > hi[1] else hi[1], lo_t[1] if -lo[1] > hi[1] else hi_t[1],
         f"outside the show area +-{extent_m:g} m (settings.max_horizontal_extent_m)"),
    ]
    if fence is not None:
        x0, x1, y0, y1 = fence
        reasons += [
            (lo[0] < x0 - 1e-9, 0, lo[0], lo_t[0], f"outside the geofence (x_min_m {x0:g} m)"),
            (hi[0] > x1 + 1e-9, 0, hi[0], hi_t[0], f"outside the geofence (x_max_m {x1:g} m)"),
            (lo[1] < y0 - 1e-9, 1, lo[1], lo_t[1], f"outside the geofence (y_min_m {y0:g} m)"),
            (hi[1] > y1 + 1e-9, 1, hi[1], hi_t[1], f"outside the geofence (y_max_m {y1:g} m)"),
        ]
    for bad, axis, value, when, what in reasons:
        if bad:
            return ("keys",), (
                f"the motion takes the formation to {'xyz'[axis]} = {value:.2f} m at {when:.2f} s into the hold, "
                f"{what}"
            )
    peaks = motion_peaks(motion, points_m, scan)
    lam = stretch_needed(peaks, v_xy, v_z, v_down, a_max)
    if lam > 1.0 + 1e-9:
        span = motion.end_s - motion.start_s
        worst = max(
            (peaks.speed_xy_mps / v_xy, f"a horizontal speed of {peaks.speed_xy_mps:.2f} m/s (limit {v_xy:g})"),
            (peaks.speed_z_mps / v_z, f"a vertical speed of {peaks.speed_z_mps:.2f} m/s (limit {v_z:g})"),
            (peaks.descent_mps / v_down, f"a descent speed of {peaks.descent_mps:.2f} m/s (limit {v_down:g})"),
            (math.sqrt(peaks.accel_mps2 / a_max),
             f"an acceleration of {peaks.accel_mps2:.2f} m/s^2 (limit {a_max:g})"),
        )[1]
        shortest = motion.start_s + span * lam
        return ("keys",), (
            f"the motion is too fast: it needs {worst}; its keys span {span:g} s and must span at least "
            f"{span * lam:.2f} s (stretch the key times by x{lam:.3f}, e.g. the last key at {shortest:.2f} s "
            f"and hold_s >= {shortest:.2f} s)"
        )
    return None


__all__ = [
    "MAX_MOTION_KEYS",
    "Motion",
    "MotionKey",
    "MotionPeaks",
    "Pose",
    "apply",
    "channels",
    "extreme_points",
    "min_scale",
    "motion_problem",
    "motion_peaks",
    "pivot_of",
    "pose",
    "reach",
    "sample_channels",
    "stretch_needed",
]
