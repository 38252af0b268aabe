"""Fly a planned show: every drone in the rigid-body model under its controller.

:func:`fly_show` turns a :class:`~sim.plan._plan.ShowPlan` into a tracking reference (each
drone's own polynomial pieces, ``plan.motion``, give ``p_ref, v_ref, a_ref`` exactly, no
sampling, with every drone on its own timing), flies it at 1 kHz with one of the engines,
and reports what was *flown*:
per-drone tracking error, the flown minimum distance between any two drones (per
output frame, with a k-d tree), and drones that diverged.

With ``engine="dask"`` the drones are split into shards flown on a Dask ``distributed``
cluster and merged into the same result (:mod:`sim.flight._dask`).

Memory: the run is split into time chunks (``chunk_s``); per chunk only the shared
reference and disturbance tables are built, and the flown minimum distance of the
frames that chunk completed is computed right away. What is kept for the whole show
is the output itself, ``positions_m`` in float32 (and the colours), 12 bytes per drone
per frame each: a 10,000-drone, 10-minute show at 25 Hz is 1.8 GB of positions, so
pass a lower ``output_hz`` or a ``drones`` subset for very large shows.

A diverged drone (non-finite state, or farther than ``divergence_limit_m`` from its
reference) is stopped where it was, reported with the time and the reason, and left
out of the flown-distance computation from then on; the others fly on.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from sim.flight._disturbance import make_disturbance
from sim.flight._quadrotor import QuadrotorParams
from sim.flight.control._baseline import BaselineGains
from sim.flight.control._ismc import IsmcGains
from sim.flight.engines._numpy import STATE_SIZE, TrackingReference, simulate
from sim.geometry import closest_pair
from sim.plan._plan import ShowPlan

__all__ = ["FLOWN_DISTANCE_TOLERANCE_M", "FlightResult", "fly_show", "plan_reference"]

#: Slack on the show's minimum distance before a flight counts as unsafe (m). The
#: controllers track to millimetres; a plan that sits exactly on the limit (for example
#: a home grid spaced at the minimum distance) must not fail on rounding-level deviations,
#: while any real loss of separation is far larger than this.
FLOWN_DISTANCE_TOLERANCE_M = 0.01

ENGINES = ("numba", "numpy", "dask")
CONTROLLERS = ("ismc", "baseline")
DISTURBANCES = ("none", "paper", "wind")


@dataclass
class FlightResult:
    """What was flown (arrays with time first, then drones).

    Attributes:
        times_s: ``(T,)`` output frame times (s).
        positions_m: ``(T, N, 3)`` flown positions, float32 (m).
        colors_rgb: ``(T, N, 3)`` LED colours from the plan, float32 in [0, 1].
        drone_ids: ``(N,)`` index of each flown drone in the plan.
        tracking_rms_m: ``(N,)`` RMS of ||p - p_ref|| over every 1 ms step (m).
        tracking_max_m: ``(N,)`` maximum ||p - p_ref|| (m).
        max_thrust_step_n: ``(N,)`` largest change of thrust between steps (N).
        flown_min_distance_m: Smallest distance between two drones at any frame (m); inf
            for fewer than two drones.
        flown_min_distance_pair: The two drones (plan indices) of that distance.
        flown_min_distance_time_s: When it happened (s).
        min_distance_limit_m: The show's minimum distance setting (m).
        diverged: ``[(drone, time_s, reason)]``, reason ``"non-finite"`` or ``"runaway"``.
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
    extra: dict = field(default_factory=dict)

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

    def worst_drones(self, count: int = 5) -> list[dict]:
        """The ``count`` drones with the largest maximum tracking error."""
        order = np.argsort(-np.nan_to_num(self.tracking_max_m, nan=np.inf), kind="stable")[:count]
        return [
            {"drone": int(self.drone_ids[i]), "rms_m": _finite(self.tracking_rms_m[i]),
             "max_m": _finite(self.tracking_max_m[i])}
            for i in order
        ]

    def summary(self) -> dict:
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


def plan_reference(plan: ShowPlan, *, drones: slice | np.ndarray | None = None) -> TrackingReference:
    """The tracking reference of a plan: every drone's own polynomial pieces (``plan.motion``), exactly.

    Args:
        plan: The planned show.
        drones: Optional subset (slice or index array) of the plan's drones.
    """
    motion = plan.motion if drones is None else plan.motion.select(drones)
    return TrackingReference(motion=motion, duration_s=plan.duration_s)


def _frame_min_distance(points: np.ndarray) -> tuple[float, int, int]:
    """Closest pair of one frame's ``(n, 3)`` points: ``(distance m, i, j)`` (inf, -1, -1 if n < 2)."""
    i, j, d = closest_pair(points)
    return d, i, j


def _fold_flown_distance(
    best: list, frames: range, *, positions: np.ndarray, times: np.ndarray, ids: np.ndarray,
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


def _ordered_pair(best: list) -> tuple[int, int]:
    """The (smaller, larger) drone ids of a ``best`` record."""
    i, j = int(best[1]), int(best[2])
    return (i, j) if i <= j else (j, i)


def fly_show(
    plan: ShowPlan,
    *,
    engine: str = "numba",
    controller: str = "ismc",
    disturbance: str = "none",
    output_hz: float = 25.0,
    seed: int = 0,
    drones: slice | np.ndarray | None = None,
    progress: Callable[[float], None] | None = None,
    params: QuadrotorParams | None = None,
    gains: IsmcGains | BaselineGains | None = None,
    mismatch: float = 0.0,
    divergence_limit_m: float = 25.0,
    chunk_s: float = 2.0,
    scheduler: Any = None,
    shards: int | None = None,
    connect_timeout_s: float = 10.0,
    flown_distance: bool = True,
) -> FlightResult:
    """Fly every drone of ``plan`` along its planned trajectory at 1 kHz.

    Args:
        plan: The planned show (``sim.plan_show``).
        engine: ``"numba"`` (fused parallel kernel), ``"numpy"`` (reference) or ``"dask"``
            (numba on shards of drones on a Dask cluster, same arrays as ``"numba"``).
        controller: ``"ismc"`` (the paper's) or ``"baseline"`` (cascaded PD).
        disturbance: ``"none"``, ``"paper"`` (spec section 7) or ``"wind"`` (seeded gusts).
        output_hz: Rate of the recorded frames (Hz); frames are every
            ``round(1000 / output_hz)`` control steps, so 25, 40 and 50 Hz are exact.
        seed: Seed of the wind gusts.
        drones: Optional subset (slice or index array) of the plan's drones to fly.
        progress: Called with the completed fraction in [0, 1] after every chunk; if it
            raises, the run stops and the exception propagates (cancellation).
        params: Vehicle parameters (default: the paper's quadrotor).
        gains: Explicit controller gains; overrides ``controller``.
        mismatch: Plant mass and inertia off by this fraction (dimensionless).
        divergence_limit_m: Tracking error beyond which a drone is stopped as a runaway (m).
        chunk_s: Simulated time per engine call (s); bounds the working memory.
        scheduler: With ``engine="dask"``: ``"tcp://HOST:PORT"``, ``"local"`` (an
            in-process ``LocalCluster``) or a ``distributed.Client``.
        shards: With ``engine="dask"``: number of tasks (default two per worker thread).
        connect_timeout_s: With ``engine="dask"``: how long to try to reach the
            scheduler and a first worker (s).
        flown_distance: Compute the flown minimum distance; False leaves it inf (the
            dask engine's shards skip it and compute it once over all drones).

    Returns:
        A :class:`FlightResult`.
    """
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r} (expected one of {', '.join(ENGINES)})")
    if controller not in CONTROLLERS:
        raise ValueError(f"unknown controller {controller!r} (expected one of {', '.join(CONTROLLERS)})")
    if not output_hz > 0:
        raise ValueError(f"output_hz must be > 0, got {output_hz}")
    if engine != "dask" and (scheduler is not None or shards is not None):
        # A scheduler given to a local engine would silently fly on this machine instead.
        raise ValueError(f"scheduler and shards are only used with engine='dask', not {engine!r}")
    if engine == "dask":
        from sim.flight._dask import fly_show_dask

        return fly_show_dask(
            plan, scheduler=scheduler, shards=shards, connect_timeout_s=connect_timeout_s,
            drones=drones, progress=progress, controller=controller, disturbance=disturbance,
            output_hz=output_hz, seed=seed, params=params, gains=gains, mismatch=mismatch,
            divergence_limit_m=divergence_limit_m, chunk_s=chunk_s,
        )
    dt_s = 1e-3
    every = max(int(round(1.0 / (output_hz * dt_s))), 1)
    if gains is None:
        gains = BaselineGains() if controller == "baseline" else IsmcGains()
    dist = make_disturbance(disturbance, seed=seed)

    ids = np.arange(plan.drone_count)
    if drones is not None:
        ids = ids[drones]
    ref = plan_reference(plan, drones=ids)
    n = ids.size
    duration = plan.duration_s
    steps = int(round(duration / dt_s)) + 1
    n_frames = (steps - 1) // every + 1
    times = np.arange(n_frames) * every * dt_s
    positions = np.zeros((n_frames, n, 3), dtype=np.float32)
    initial = np.zeros((n, STATE_SIZE))
    initial[:, 0:3] = ref.motion.evaluate(np.zeros(1), derivatives=0).positions_m[0]

    best = [float("inf"), -1, -1, float("nan")]  # distance (m), i, j, time (s)
    done_frames = [0]

    def on_chunk(steps_done: int, dstep: np.ndarray) -> None:
        # Frames below ``ready`` were written by the chunks so far (a frame is recorded
        # at the start of its step).
        ready = min(-(-steps_done // every), n_frames)
        _fold_flown_distance(best, range(done_frames[0], ready), positions=positions, times=times, ids=ids,
                             dstep=dstep, every=every)
        done_frames[0] = ready

    start = time.perf_counter()
    sim = simulate(
        ref, duration_s=duration, initial_state=initial, params=params, mismatch=mismatch,
        gains=gains, disturbance=dist, seed=seed, dt_s=dt_s, output_every=every, engine=engine,
        divergence_limit_m=divergence_limit_m, chunk_steps=max(int(round(chunk_s / dt_s)), 1),
        progress=progress, frames_out=positions, on_chunk=on_chunk if flown_distance else None,
    )
    wall = time.perf_counter() - start

    colors = np.empty((n_frames, n, 3), dtype=np.float32)
    block = max(1, 2_000_000 // max(n, 1))  # bounded temporaries of plan.evaluate
    for f0 in range(0, n_frames, block):
        colors[f0:f0 + block] = plan.evaluate(times[f0:f0 + block], drones=ids).colors_rgb

    pair = _ordered_pair(best)
    return FlightResult(
        times_s=times,
        positions_m=positions,
        colors_rgb=colors,
        drone_ids=ids,
        tracking_rms_m=sim.rms_error_m,
        tracking_max_m=sim.max_error_m,
        max_thrust_step_n=sim.max_thrust_step_n,
        flown_min_distance_m=float(best[0]),
        flown_min_distance_pair=pair,
        flown_min_distance_time_s=float(best[3]),
        min_distance_limit_m=float(plan.settings.min_distance_m),
        diverged=[(int(ids[d]), t, r) for d, t, r in sim.diverged()],
        engine=engine,
        controller="baseline" if isinstance(gains, BaselineGains) else gains.kind,
        disturbance=dist.name,
        duration_s=duration,
        dt_s=dt_s,
        wall_time_s=wall,
    )
