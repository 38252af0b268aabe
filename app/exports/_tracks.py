"""Frame sources for playback: the exact plan or a simulated flight, sampled at any time.

A *track* answers, for a time t (seconds), every drone's position (m) and LED
colour (in [0, 1]) plus the fastest drone's speed (m/s), fully vectorised over
drones. Scrubbing and looping need random access, so nothing here keeps state
between calls.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal, Protocol

import numpy as np

if TYPE_CHECKING:  # annotations only: importing app.exports stays cheap (no numba, no scipy)
    from sim import ShowPlan

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
    """The exact plan (piecewise quintic), evaluated on demand."""

    def __init__(self, plan: ShowPlan) -> None:
        self.plan = plan
        self.duration_s = plan.duration_s
        self.drone_count = plan.drone_count
        self._segment = -1
        # Per-segment start knot, displacement, colours and the longest displacement
        # (all drones share the time law, so the fastest drone is the longest leg).
        self._p0 = self._dp = self._c0 = self._dc = np.zeros((0, 3))
        self._longest_m = 0.0

    def _enter(self, k: int) -> None:
        if k == self._segment:
            return
        knots, cols = self.plan.knot_positions_m, self.plan.knot_colors_rgb
        self._p0, self._c0 = knots[k], cols[k]
        self._dp, self._dc = knots[k + 1] - knots[k], cols[k + 1] - cols[k]
        self._longest_m = float(np.sqrt(np.einsum("ij,ij->i", self._dp, self._dp).max())) if len(self._dp) else 0.0
        self._segment = k

    def frame(self, time_s: float) -> Frame:
        """The plan at ``time_s`` (seconds); equals ``plan.evaluate`` at that time."""
        t = float(np.clip(time_s, 0.0, self.duration_s))
        law = self.plan.time_law(np.array([t]))
        self._enter(int(law.segment[0]))
        positions = self._p0 + float(law.beta[0]) * self._dp
        colors = self._c0 + float(law.tau[0]) * self._dc
        return Frame(t, positions, colors, abs(float(law.beta_d[0])) * self._longest_m)

    def positions(self, times_s: np.ndarray) -> np.ndarray:
        """(T, N, 3) planned positions, metres."""
        return self.plan.evaluate(np.clip(times_s, 0.0, self.duration_s)).positions_m

    def sample(self, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (m), colours and max speeds (m/s) at many times (see :class:`Track`)."""
        s = self.plan.evaluate(np.clip(times_s, 0.0, self.duration_s))
        v = s.velocities_mps
        return s.positions_m, s.colors_rgb, np.sqrt(np.einsum("tij,tij->ti", v, v).max(axis=1))


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


def make_track(plan: ShowPlan, flight: Any, source: Source) -> Track:
    """The track for ``source`` (``"simulated"`` needs a flight)."""
    if source == "simulated":
        if flight is None:
            raise ValueError("no simulated flight for this show: simulate it first")
        return FlightTrack(flight)
    return PlanTrack(plan)


def show_bounds(plan: ShowPlan, flight: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds (lo, hi) of everything the show visits, metres.

    Straight-line quintic segments never leave the box of their knots, so the
    knots bound the plan exactly.
    """
    pts = plan.knot_positions_m.reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    if flight is not None:
        fp = np.asarray(flight.positions_m).reshape(-1, 3)
        lo, hi = np.minimum(lo, fp.min(axis=0)), np.maximum(hi, fp.max(axis=0))
    return lo, hi


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
    "PlanTrack",
    "Source",
    "Track",
    "framing_camera",
    "make_track",
    "show_bounds",
]
