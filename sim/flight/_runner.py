"""Fly a planned show in this process: every drone in the rigid-body model under its controller.

:func:`fly_local` turns a :class:`~sim.plan._plan.ShowPlan` into a tracking reference (each
drone's own polynomial pieces, ``plan.motion``, give ``p_ref, v_ref, a_ref`` exactly, no
sampling, with every drone on its own timing), flies it at 1 kHz with one of the engines,
and reports what was *flown*:
per-drone tracking error, the flown minimum distance between any two drones (per
output frame, exact closest pair: :func:`sim.geometry.closest_pair`), and drones that
diverged. :func:`sim.flight.fly_show` dispatches here, or for ``engine="dask"`` to the
shards of :mod:`sim.flight._dask`, which fly this same function on the workers.

Memory: the run is split into time chunks (``chunk_s``); per chunk only the shared
reference and disturbance tables are built, and the flown minimum distance of the
frames that chunk completed is computed right away. What is kept for the whole show
is the output itself, ``positions_m`` in float32 (and the colours), 12 bytes per drone
per frame each: a 10,000-drone, 10-minute show at 25 Hz is 1.8 GB of positions, so
pass a lower ``output_hz`` or a ``drones`` subset for very large shows.

A diverged drone (non-finite state, farther than ``divergence_limit_m`` from its
reference, or sunk more than ``GROUND_STRIKE_M`` below the show's ground) is stopped
where it was, reported with the time and the reason, and left out of the
flown-distance computation from then on; the others fly on.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from sim.flight._disturbance import make_disturbance
from sim.flight._options import FlightOptions
from sim.flight._quadrotor import STATE_SIZE
from sim.flight._result import FLOWN_DISTANCE_TOLERANCE_M as FLOWN_DISTANCE_TOLERANCE_M  # moved; old path kept
from sim.flight._result import FlightResult as FlightResult  # moved to _result; old import path kept
from sim.flight._result import fold_flown_distance, ordered_pair
from sim.flight.control._baseline import BaselineGains
from sim.flight.control._ismc import IsmcGains
from sim.flight.engines._driver import simulate
from sim.flight.engines._state import TrackingReference
from sim.plan._plan import ShowPlan

__all__ = ["fly_local", "plan_reference"]

def plan_reference(plan: ShowPlan, *, drones: slice | np.ndarray | None = None) -> TrackingReference:
    """The tracking reference of a plan: every drone's own polynomial pieces (``plan.motion``), exactly.

    Args:
        plan: The planned show.
        drones: Optional subset (slice or index array) of the plan's drones.
    """
    motion = plan.motion if drones is None else plan.motion.select(drones)
    return TrackingReference(motion=motion, duration_s=plan.duration_s)


def fly_local(
    plan: ShowPlan,
    options: FlightOptions,
    *,
    drones: slice | np.ndarray | None = None,
    progress: Callable[[float], None] | None = None,
) -> FlightResult:
    """Fly every drone of ``plan`` (or the ``drones`` subset) in this process, at 1 kHz.

    Args:
        plan: The planned show (``sim.plan_show``).
        options: How to fly (:class:`~sim.flight._options.FlightOptions`); its engine
            must be ``"numba"`` or ``"numpy"`` (``fly_show`` sends ``"dask"`` to
            :mod:`sim.flight._dask`, whose shards come back here).
        drones: Optional subset (slice or index array) of the plan's drones to fly.
        progress: Called with the completed fraction in [0, 1] after every chunk; if it
            raises, the run stops and the exception propagates (cancellation).

    Returns:
        A :class:`FlightResult`.
    """
    if options.engine == "dask":
        raise ValueError("fly_local flies in this process; engine='dask' goes through fly_show")
    engine, controller, disturbance = options.engine, options.controller, options.disturbance
    output_hz, seed, params, gains = options.output_hz, options.seed, options.params, options.gains
    mismatch, divergence_limit_m, chunk_s = options.mismatch, options.divergence_limit_m, options.chunk_s
    flown_distance = options.flown_distance
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

    best: list[Any] = [float("inf"), -1, -1, float("nan")]  # distance (m), i, j, time (s)
    done_frames = [0]

    def on_chunk(steps_done: int, dstep: np.ndarray) -> None:
        # Frames below ``ready`` were written by the chunks so far (a frame is recorded
        # at the start of its step).
        ready = min(-(-steps_done // every), n_frames)
        fold_flown_distance(best, range(done_frames[0], ready), positions=positions, times=times, ids=ids,
                             dstep=dstep, every=every)
        done_frames[0] = ready

    # The show's ground, as the verifier takes it (sim.verify._check): z = 0, or the lowest home if
    # one is lower. A drone that sinks GROUND_STRIKE_M below it has crashed (engines._state, "ground").
    ground_m = min(0.0, float(plan.knot_positions_m[0][:, 2].min()))
    start = time.perf_counter()
    sim = simulate(
        ref, duration_s=duration, initial_state=initial, params=params, mismatch=mismatch,
        gains=gains, disturbance=dist, seed=seed, dt_s=dt_s, output_every=every, engine=engine,
        divergence_limit_m=divergence_limit_m, chunk_steps=max(int(round(chunk_s / dt_s)), 1),
        progress=progress, frames_out=positions, on_chunk=on_chunk if flown_distance else None,
        errors=options.errors, drone_ids=ids, ground_m=ground_m, precision=options.precision,
    )
    wall = time.perf_counter() - start

    # Only when asked for (options.colors): the Monte-Carlo runs never read them.
    colors = np.empty((n_frames if options.colors else 0, n, 3), dtype=np.float32)
    block = max(1, 2_000_000 // max(n, 1))  # bounded temporaries of plan.evaluate
    for f0 in range(0, colors.shape[0], block):
        colors[f0:f0 + block] = plan.evaluate(times[f0:f0 + block], drones=ids).colors_rgb

    pair = ordered_pair(best)
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
