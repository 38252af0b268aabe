"""What a flight reports (:class:`FlightResult`) and the flown-distance fold both runners share.

One layer below the local runner (:mod:`sim.flight._runner`) and the Dask runner
(:mod:`sim.flight._dask`), so that the Dask runner merges shards with the same fold
the local runner uses per chunk, without importing the local runner's internals.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.geometry import closest_pair

__all__ = ["FLOWN_DISTANCE_TOLERANCE_M", "FlightResult", "fold_flown_distance", "ordered_pair"]

#: Slack on the show's minimum distance before a flight counts as unsafe (m). The
#: controllers track to millimetres; a plan that sits exactly on the limit (for example
#: a home grid spaced at the minimum distance) must not fail on rounding-level deviations,
#: while any real loss of separation is far larger than this.
FLOWN_DISTANCE_TOLERANCE_M = 0.01


@dataclass
class FlightResult:
    """What was flown (arrays with time first, then drones).

    Attributes:
        times_s: ``(T,)`` output frame times (s).
        positions_m: ``(T, N, 3)`` flown positions, float32 (m).
        colors_rgb: ``(T, N, 3)`` LED colours from the plan, float32 in [0, 1]; ``(0, N, 3)``
            when the flight was asked not to evaluate them (``FlightOptions.colors``).
        drone_ids: ``(N,)`` index of each flown drone in the plan.
        tracking_rms_m: ``(N,)`` RMS of ||p - p_ref|| over every 1 ms step (m).
        tracking_max_m: ``(N,)`` maximum ||p - p_ref|| (m).
        max_thrust_step_n: ``(N,)`` largest change of thrust between steps (N).
        flown_min_distance_m: Smallest distance between two drones at any frame (m); inf
            for fewer than two drones.
        flown_min_distance_pair: The two drones (plan indices) of that distance.
        flown_min_distance_time_s: When it happened (s).
        min_distance_limit_m: The show's minimum distance setting (m).
        diverged: ``[(drone, time_s, reason)]``, reason ``"runaway"`` (unstable control, a tumble),
            ``"overpowered"`` (held at its limits and blown off: wind beyond its authority),
            ``"non-finite"`` or ``"ground"`` (sank ``GROUND_STRIKE_M`` below the show's ground: a crash)
            (see ``sim.flight.engines._state``).
        engine: Engine used.
        controller: Controller used.
        disturbance: Disturbance used.
        duration_s: Flown length (s).
        dt_s: Control and integration step (s).
        wall_time_s: Wall-clock time of the run (s).
    """

    times_s: np.ndarray
    positions_m: np.ndarray
    colors_rgb: np.ndarray
    drone_ids: np.ndarray
    tracking_rms_m: np.ndarray
    tracking_max_m: np.ndarray
    max_thrust_step_n: np.ndarray
    flown_min_distance_m: float
    flown_min_distance_pair: tuple[int, int]
    flown_min_distance_time_s: float
    min_distance_limit_m: float
    diverged: list[tuple[int, float, str]]
    engine: str
    controller: str
    disturbance: str
    duration_s: float
    dt_s: float
    wall_time_s: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def drone_steps_per_s(self) -> float:
        """Simulation speed of this run (drone-steps per wall-clock second)."""
        steps = (round(self.duration_s / self.dt_s) + 1) * len(self.drone_ids)
        return float(steps / self.wall_time_s) if self.wall_time_s > 0 else float("nan")

    @property
    def ok(self) -> bool:
        """No drone diverged and the flown separation kept the limit (within the tolerance)."""
        return not self.diverged and (
            self.flown_min_distance_m >= self.min_distance_limit_m - FLOWN_DISTANCE_TOLERANCE_M
        )

    def worst_drones(self, count: int = 5) -> list[dict[str, Any]]:
        """The ``count`` drones with the largest maximum tracking error."""
        order = np.argsort(-np.nan_to_num(self.tracking_max_m, nan=np.inf), kind="stable")[:count]
        return [
            {"drone": int(self.drone_ids[i]), "rms_m": _finite(self.tracking_rms_m[i]),
             "max_m": _finite(self.tracking_max_m[i])}
            for i in order
        ]

    def summary(self) -> dict[str, Any]:
        """JSON-safe scalars: tracking, flown separation, divergences, run settings."""
        n = len(self.drone_ids)
        pair = [int(p) for p in self.flown_min_distance_pair]
        return {
            "drones": n,
            "duration_s": self.duration_s,
            "frames": int(self.times_s.size),
            "output_hz": float(1.0 / (self.times_s[1] - self.times_s[0])) if self.times_s.size > 1 else None,
            "engine": self.engine,
            "controller": self.controller,
            "disturbance": self.disturbance,
            "dt_s": self.dt_s,
            "tracking_rms_m": _finite(float(np.sqrt(np.mean(self.tracking_rms_m**2)))) if n else None,
            "tracking_max_m": _finite(float(np.max(self.tracking_max_m))) if n else None,
            "max_thrust_step_n": _finite(float(np.max(self.max_thrust_step_n))) if n else None,
            "worst_drones": self.worst_drones(),
            "flown_min_distance_m": _finite(self.flown_min_distance_m),
            "flown_min_distance_pair": pair if all(p >= 0 for p in pair) else None,
            "flown_min_distance_time_s": _finite(self.flown_min_distance_time_s),
            "min_distance_limit_m": self.min_distance_limit_m,
            "flown_distance_tolerance_m": FLOWN_DISTANCE_TOLERANCE_M,
            "diverged": [{"drone": d, "time_s": t, "reason": r} for d, t, r in self.diverged],
            "ok": self.ok,
            "wall_time_s": self.wall_time_s,
            "drone_steps_per_s": _finite(self.drone_steps_per_s),
        }


def _finite(x: float) -> float | None:
    """``x`` as a float, or None when it is not finite (JSON has no inf/NaN)."""
    x = float(x)
    return x if np.isfinite(x) else None


def _frame_min_distance(points: np.ndarray) -> tuple[float, int, int]:
    """Closest pair of one frame's ``(n, 3)`` points: ``(distance m, i, j)`` (inf, -1, -1 if n < 2)."""
    i, j, d = closest_pair(points)
    return d, i, j


def fold_flown_distance(
    best: list[Any], frames: range, *, positions: np.ndarray, times: np.ndarray, ids: np.ndarray,
    dstep: np.ndarray, every: int,
) -> None:
    """Fold the closest pair of each frame's live drones into ``best`` = [m, drone i, drone j, s] (in place).

    A drone counts until the step it diverged at (``dstep`` < 0: never); frame f is step f·every.
    """
    for f in frames:
        alive = np.flatnonzero((dstep < 0) | (dstep > f * every))
        d, i, j = _frame_min_distance(positions[f, alive].astype(np.float64))
        if d < best[0]:
            best[:] = [d, int(ids[alive[i]]), int(ids[alive[j]]), float(times[f])]


def ordered_pair(best: list[Any]) -> tuple[int, int]:
    """The (smaller, larger) drone ids of a ``best`` record."""
    i, j = int(best[1]), int(best[2])
    return (i, j) if i <= j else (j, i)
