"""Frame sources for playback: the exact plan or a simulated flight, sampled at any time.

A *track* answers, for a time t (seconds), every drone's position (m) and LED
colour (in [0, 1]) plus the fastest drone's speed (m/s), fully vectorised over
drones. Scrubbing and looping need random access: the plan track keeps only a
cache (each drone's current piece), never state that changes an answer.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, Protocol

import numpy as np

if TYPE_CHECKING:  # annotations only: importing app.exports stays cheap (no numba, no scipy)
    from sim import ShowPlan
    from sim.plan import Trajectories

Source = Literal["planned", "simulated"]


@dataclass(frozen=True)
class Frame:
    """The show at one instant.

    Attributes:
        time_s: the (clamped) time, seconds.
        positions_m: (N, 3) float64 positions, metres, ENU.
        colors_rgb: (N, 3) LED colours in [0, 1].
        max_speed_mps: the fastest drone's speed, m/s.
    """

    time_s: float
    positions_m: np.ndarray
    colors_rgb: np.ndarray
    max_speed_mps: float


class Track(Protocol):
    """Anything playback can sample."""

    duration_s: float
    drone_count: int

    def frame(self, time_s: float) -> Frame:
        """The show at ``time_s`` (seconds, clamped to the show)."""
        ...

    def positions(self, times_s: np.ndarray) -> np.ndarray:
        """(T, N, 3) positions at ``times_s`` (seconds), metres."""
        ...

    def sample(self, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(T, N, 3) positions (m), (T, N, 3) colours in [0, 1] and (T,) max speeds (m/s) at once."""
        ...


class PlanTrack:
    """The exact plan (every drone's own polynomial pieces, ``plan.motion``), evaluated on demand."""

    def __init__(self, plan: ShowPlan) -> None:
        self.plan = plan
        self.duration_s = plan.duration_s
        self.drone_count = plan.drone_count
        motion: Trajectories = plan.motion
        self._breaks = np.ascontiguousarray(motion.breaks_s, dtype=np.float64)
        self._coeffs = np.ascontiguousarray(motion.coeffs_m, dtype=np.float64)
        # Each drone's piece at the last frame (and at the last trail / batch sample):
        # playback moves it a step at a time instead of searching.
        self._cursor = np.zeros(self.drone_count, dtype=np.int64)
        self._trail_cursor = np.zeros(self.drone_count, dtype=np.int64)

    def _states(self, times_s: np.ndarray, cursor: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (m), velocities (m/s) and colours of every drone at ``times_s`` (T,): (T, N, 3) each."""
        t = np.clip(np.atleast_1d(np.asarray(times_s, dtype=np.float64)), 0.0, self.duration_s)
        n = self.drone_count
        pos, vel = np.empty((len(t), n, 3)), np.empty((len(t), n, 3))
        if n:
            from sim.plan import states_at  # numba: loaded on the first frame, not with app.exports

            states_at(self._breaks, self._coeffs, np.clip(t, self._breaks[0, 0], self._breaks[0, -1]), cursor, pos, vel)
        # Colours fade linearly over each show-wide window, as ShowPlan.evaluate fades them.
        k = self.plan.segment_index(t)
        t0, t1 = self.plan.knot_times_s[k], self.plan.knot_times_s[k + 1]
        tau = np.clip(np.divide(t - t0, t1 - t0, out=np.ones_like(t), where=t1 > t0), 0.0, 1.0)
        cols = self.plan.knot_colors_rgb
        colors = cols[k] + tau[:, None, None] * (cols[k + 1] - cols[k])
        return pos, vel, colors

    def frame(self, time_s: float) -> Frame:
        """The plan at ``time_s`` (seconds); equals ``plan.evaluate`` at that time."""
        t = float(np.clip(time_s, 0.0, self.duration_s))
        pos, vel, colors = self._states(np.array([t]), self._cursor)
        speed = float(np.sqrt(np.einsum("ij,ij->i", vel[0], vel[0]).max())) if self.drone_count else 0.0
        return Frame(t, pos[0], colors[0], speed)

    def positions(self, times_s: np.ndarray) -> np.ndarray:
        """(T, N, 3) planned positions, metres."""
        return self._states(times_s, self._trail_cursor)[0]

    def sample(self, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (m), colours and max speeds (m/s) at many times (see :class:`Track`)."""
        pos, vel, colors = self._states(times_s, self._trail_cursor)
        return pos, colors, np.sqrt(np.einsum("tij,tij->ti", vel, vel).max(axis=1, initial=0.0))


class FlightTrack:
    """A simulated flight (``sim.flight.FlightResult``-like: ``times_s``, ``positions_m``, ``colors_rgb``).

    Samples are interpolated linearly in time; speed is the finite difference
    of the bracketing samples (the flown velocity between them).
    """

    def __init__(self, flight: Any) -> None:
        self.times_s = np.asarray(flight.times_s, dtype=np.float64)
        # Kept in the flight's own dtype: a long flight of many drones is hundreds of MB.
        self.positions_m = np.asarray(flight.positions_m)
        colors = getattr(flight, "colors_rgb", None)
        self.colors_rgb = np.asarray(colors) if colors is not None else np.ones_like(self.positions_m)
        if self.positions_m.ndim != 3 or self.positions_m.shape[0] != len(self.times_s):
            raise ValueError(f"flight positions must be (T, N, 3) with T = {len(self.times_s)} times")
        self.duration_s = float(self.times_s[-1]) if len(self.times_s) else 0.0
        self.drone_count = int(self.positions_m.shape[1])

    def _bracket(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Index of the sample at or before each time, and the fraction to the next one."""
        n = len(self.times_s)
        if n < 2:
            return np.zeros(t.shape, dtype=np.intp), np.zeros(t.shape)
        k = np.clip(np.searchsorted(self.times_s, t, side="right") - 1, 0, n - 2)
        dt = self.times_s[k + 1] - self.times_s[k]
        return k, np.clip((t - self.times_s[k]) / np.where(dt > 0, dt, 1.0), 0.0, 1.0)

    def frame(self, time_s: float) -> Frame:
        """The flight at ``time_s`` (seconds), interpolated."""
        t = float(np.clip(time_s, self.times_s[0] if len(self.times_s) else 0.0, self.duration_s))
        (k,), (a,) = self._bracket(np.array([t]))
        p0, c0 = self.positions_m[k], self.colors_rgb[k]
        if len(self.times_s) < 2:
            return Frame(t, p0.copy(), c0.copy(), 0.0)
        p1, c1 = self.positions_m[k + 1], self.colors_rgb[k + 1]
        d = p1 - p0
        dt = float(self.times_s[k + 1] - self.times_s[k])
        speed = float(np.sqrt(np.einsum("ij,ij->i", d, d).max())) / dt if dt > 0 else 0.0
        return Frame(t, p0 + a * d, c0 + a * (c1 - c0), speed)

    def positions(self, times_s: np.ndarray) -> np.ndarray:
        """(T, N, 3) flown positions, metres, interpolated."""
        t = np.clip(np.asarray(times_s, dtype=np.float64), 0.0, self.duration_s)
        k, a = self._bracket(t)
        if len(self.times_s) < 2:
            return self.positions_m[k]
        p0 = self.positions_m[k]
        return p0 + a[:, None, None] * (self.positions_m[k + 1] - p0)

    def sample(self, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (m), colours and max speeds (m/s) at many times (see :class:`Track`)."""
        t = np.clip(np.asarray(times_s, dtype=np.float64), 0.0, self.duration_s)
        if len(self.times_s) < 2:
            k = np.zeros(t.shape, dtype=np.intp)
            return self.positions_m[k], self.colors_rgb[k], np.zeros(t.shape)
        k, a = self._bracket(t)
        p0, c0 = self.positions_m[k], self.colors_rgb[k]
        d = self.positions_m[k + 1] - p0
        dt = self.times_s[k + 1] - self.times_s[k]
        speed = np.sqrt(np.einsum("tij,tij->ti", d, d).max(axis=1)) / np.where(dt > 0, dt, np.inf)
        w = a[:, None, None]
        return p0 + w * d, c0 + w * (self.colors_rgb[k + 1] - c0), speed


class LitTrack:
    """A track with a show's light effects (``sim.light.LightStack``) painted over its colours (issue 18)."""

    def __init__(self, track: Track, lights: Any) -> None:
        self.track = track
        self.lights = lights
        self.duration_s = track.duration_s
        self.drone_count = track.drone_count

    def frame(self, time_s: float) -> Frame:
        """The inner track's frame with the effects painted on (see :class:`Track`)."""
        f = self.track.frame(time_s)
        colors = self.lights.apply([f.time_s], f.colors_rgb[None], f.positions_m[None])[0]
        return Frame(f.time_s, f.positions_m, colors, f.max_speed_mps)

    def positions(self, times_s: np.ndarray) -> np.ndarray:
        """(T, N, 3) positions, metres (the inner track's)."""
        return self.track.positions(times_s)

    def sample(self, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (m), painted colours and max speeds (m/s) at many times (see :class:`Track`)."""
        t = np.clip(np.asarray(times_s, dtype=np.float64), 0.0, self.duration_s)
        pos, colors, speeds = self.track.sample(t)
        return pos, self.lights.apply(t, colors, pos), speeds


def make_track(plan: ShowPlan, flight: Any, source: Source, lights: Any = None) -> Track:
    """The track for ``source`` (``"simulated"`` needs a flight); with ``lights`` (a non-empty
    ``sim.light.LightStack``) its colours carry the show's effects."""
    if source == "simulated":
        if flight is None:
            raise ValueError("no simulated flight for this show: simulate it first")
        track: Track = FlightTrack(flight)
    else:
        track = PlanTrack(plan)
    return LitTrack(track, lights) if lights else track


def show_bounds(plan: ShowPlan, flight: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (lo, hi) of everything the show visits, metres.

    Each polynomial piece lies in the convex hull of its Bézier (Bernstein) control
    points (Farin, *Curves and Surfaces for CAGD*, convex-hull property), so their box
    bounds the plan; for a straight rest-to-rest leg they are the leg's ends, exact.
    """
    pts = bezier_control_points(plan.motion).reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    if flight is not None:
        fp = np.asarray(flight.positions_m).reshape(-1, 3)
        lo, hi = np.minimum(lo, fp.min(axis=0)), np.maximum(hi, fp.max(axis=0))
    return lo, hi


def bezier_control_points(motion: Trajectories) -> np.ndarray:
    """(N, P, D+1, 3) Bézier control points of every piece over its own interval, metres.

    A piece Σ_k c_k u^k on [0, h] is Σ_k a_k τ^k with a_k = c_k h^k, τ = u/h; its
    Bernstein coefficients are b_j = Σ_{k<=j} C(j, k)/C(D, k)·a_k.
    """
    c = motion.coeffs_m  # (N, P, 3, D+1)
    d = c.shape[-1] - 1
    h = np.diff(motion.breaks_s, axis=1)[:, :, None, None]
    a = c * h ** np.arange(d + 1)
    j, k = np.arange(d + 1)[:, None], np.arange(d + 1)[None, :]
    w = np.where(k <= j, _comb(j, k) / _comb(np.full_like(k, d), k), 0.0)  # (D+1, D+1)
    return np.einsum("jk,npak->npja", w, a)


def _comb(n: np.ndarray, k: np.ndarray) -> np.ndarray:
    """Binomial coefficients C(n, k) for small integer arrays (0 where k > n)."""
    from math import comb

    return np.vectorize(lambda a, b: comb(int(a), int(b)) if b <= a else 0, otypes=[float])(n, k)


def framing_camera(lo: np.ndarray, hi: np.ndarray, *, fov_rad: float = 1.3) -> tuple[np.ndarray, np.ndarray]:
    """A camera (position, look-at), metres, that sees the whole box from the south-west, above.

    The camera stands back along a fixed oblique direction far enough for the
    box's bounding sphere to fit the vertical field of view ``fov_rad``.
    """
    center = (lo + hi) / 2.0
    radius = max(float(np.linalg.norm(hi - lo)) / 2.0, 5.0)
    direction = np.array([-0.45, -0.85, 0.35])
    direction /= np.linalg.norm(direction)
    distance = radius / np.sin(fov_rad / 2.0) * 1.05
    return center + direction * distance, center


__all__ = [
    "FlightTrack",
    "Frame",
    "LitTrack",
    "PlanTrack",
    "Source",
    "Track",
    "bezier_control_points",
    "framing_camera",
    "make_track",
    "show_bounds",
]
