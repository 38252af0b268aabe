"""The run driver: :func:`simulate` flies a reference in chunks with either engine.

It allocates the state, controller and statistics arrays (layout in
:mod:`sim.flight.engines._state`), evaluates the shared reference tables and the
disturbance one chunk at a time, and hands each chunk to the numpy step
(:mod:`sim.flight.engines._numpy`) or the fused numba kernel
(:mod:`sim.flight.engines._numba`).

Outside the kernel a chunk's time is the error models' tables (:mod:`sim.flight.engines._tables`,
on the table threads); the driver's own per-chunk work, the shared reference and disturbance
rows, measured ~0.1 ms for a 1,001-step chunk of 4,000 drones (against ~130 ms of kernel), and
its set-up ~1 ms (two evaluations of the reference at t = 0, 0.46 ms each): nothing there worth
hoisting out of the loop.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from sim.flight._disturbance import Disturbance, make_disturbance
from sim.flight._errors import ErrorModel
from sim.flight._quadrotor import STATE_SIZE, QuadrotorParams
from sim.flight.control._baseline import BaselineGains
from sim.flight.control._ismc import IsmcGains
from sim.flight.engines._numpy import init_controller, run_chunk_numpy
from sim.flight.engines._state import (
    C_PHAT,
    GROUND_STRIKE_M,
    STAT_COUNT,
    STAT_DTHRUST,
    STAT_MAX,
    STAT_SUMSQ,
    STATS_SIZE,
    TEL_SIZE,
    SimResult,
    TrackingReference,
    hover_state,
)
from sim.flight.engines._tables import ErrorTables

__all__ = ["PRECISIONS", "simulate", "warm_up"]

#: The numba kernel's arithmetic: ``float64`` (the reference's), or ``float32`` control laws.
PRECISIONS: tuple[str, ...] = ("float64", "float32")

ChunkRunner = Callable[..., None]


def simulate(
    reference: TrackingReference,
    *,
    duration_s: float,
    initial_state: np.ndarray | None = None,
    params: QuadrotorParams | None = None,
    mismatch: float = 0.0,
    gains: IsmcGains | BaselineGains | None = None,
    disturbance: str | Disturbance | None = None,
    seed: int = 0,
    dt_s: float = 1e-3,
    output_every: int = 40,
    telemetry: bool = False,
    engine: str = "numba",
    integrator: str = "euler",
    divergence_limit_m: float = 100.0,
    chunk_steps: int = 1000,
    progress: Callable[[float], None] | None = None,
    frames_out: np.ndarray | None = None,
    on_chunk: Callable[[int, np.ndarray], None] | None = None,
    errors: ErrorModel | None = None,
    drone_ids: np.ndarray | None = None,
    ground_m: float | None = None,
    precision: str = "float64",
) -> SimResult:
    """Fly every drone of ``reference`` for ``duration_s`` at a fixed step.

    Args:
        reference: What each drone tracks (knots + time law + offset + yaw).
        duration_s: Flight length (s); ``round(duration/dt) + 1`` control steps are
            taken so that the state at ``duration_s`` is recorded.
        initial_state: ``(N, 12)`` start state; default at rest, level, on the
            reference at t = 0.
        params: The vehicle the controller is tuned for (default: the paper's).
        mismatch: Plant mass and inertia off by this fraction (dimensionless).
        gains: ISMC gains (default the paper's) or ``BaselineGains`` for the PD baseline.
        disturbance: ``"none" | "paper" | "wind"`` or a ``Disturbance``.
        seed: Seed of the wind gusts and of every draw of ``errors``.
        dt_s: Control and integration step (s), default 1 ms (the paper's).
        output_every: Record positions (and telemetry) every this many steps.
        telemetry: Also record ``TELEMETRY_FIELDS`` at the frames.
        engine: ``"numba"`` (fused kernel) or ``"numpy"`` (reference).
        integrator: ``"euler"`` (semi-implicit; both engines) or ``"rk4"`` (numpy only).
        divergence_limit_m: Position error beyond which a drone is frozen (m).
        chunk_steps: Steps per kernel call (progress granularity).
        progress: Called with the completed fraction in [0, 1] after every chunk; an
            exception it raises stops the run and propagates (used to cancel).
        frames_out: Optional preallocated ``(F, N, 3)`` frame buffer (float32 or
            float64), F = ``(steps - 1) // output_every + 1``; saves a float64 copy.
        on_chunk: Called after every chunk with ``(steps_done, diverged_step)``:
            frames with index ``< ceil(steps_done / output_every)`` are final.
        errors: Per-drone error models (default: ideal drones).
        drone_ids: ``(N,)`` each drone's index in the plan, the key of its random
            streams (default ``0..N-1``); a subset flown alone gets its drones' own draws.
        ground_m: Height of the ground (m): a drone whose true position sinks more than
            ``GROUND_STRIKE_M`` below it is stopped there ("ground"). None (the default): no
            ground, for free-space references (the paper scenario's p_ref dips to z = -1 m);
            a flown show passes its own (``sim.flight._runner.fly_local``).
        precision: ``"float64"`` (default) or, with the numba engine, ``"float32"``: the control
            laws in single precision (:mod:`sim.flight.engines._numba_f32`; 1.3-1.4x the kernel's
            speed; the plant and every integrated state stay float64). Only float64 keeps the
            1e-9 agreement with the numpy reference and the bit-exact hover.

    Returns:
        A ``SimResult``.
    """
    params = params or QuadrotorParams()
    plant = params.mismatched(fraction=mismatch) if mismatch else params
    if gains is None:
        gains = IsmcGains()
    if isinstance(gains, BaselineGains):
        gains = gains.as_ismc()
    dist = make_disturbance(disturbance, seed=seed)
    n = reference.drone_count
    steps = int(round(duration_s / dt_s)) + 1
    every = max(int(output_every), 1)
    n_frames = (steps - 1) // every + 1

    chunk0 = reference.chunk(np.zeros(1))
    if initial_state is None:
        initial_state = hover_state(reference.at_step(chunk0, 0)[0])
    state = np.array(initial_state, dtype=np.float64, copy=True)
    if state.shape != (n, STATE_SIZE):
        raise ValueError(f"initial_state must be ({n}, {STATE_SIZE}), got {state.shape}")
    ctrl = init_controller(state, reference, chunk0, params=params, gains=gains)
    stats = np.zeros((n, STATS_SIZE))
    dstep = np.full(n, -1, dtype=np.int64)
    dreason = np.zeros(n, dtype=np.int64)
    if frames_out is None:
        frames = np.zeros((n_frames, n, 3))
    else:
        frames = frames_out
        if frames.shape != (n_frames, n, 3):
            raise ValueError(f"frames_out must be {(n_frames, n, 3)}, got {frames.shape}")
    tel = np.full((n_frames, n, TEL_SIZE), np.nan) if telemetry else None
    ids = np.arange(n) if drone_ids is None else np.asarray(drone_ids, dtype=np.int64)
    if ids.shape != (n,):
        raise ValueError(f"drone_ids must be ({n},), got {ids.shape}")
    err_tables = ErrorTables(errors or ErrorModel(), seed=seed, drone_ids=ids, plant=plant, dt_s=dt_s,
                             duration_s=(steps - 1) * dt_s)
    if err_tables.use_gnss:
        # The drone starts where its navigation puts the start, as after a pre-show hold on its
        # own estimate: the estimate (the first GNSS fix) is at ``initial_state`` and the true
        # position is off by the fix's error. Starting the drone on the true spot instead handed
        # the controller a step of the whole GNSS error at t = 0 (metres with "gps-only": σ 1.5 m
        # horizontal, 3 m vertical), which tilted it to the limiter at once and tumbled a few
        # ISMC drones in 50 (issue 20); no flight stack sees such a step, its estimate converged
        # on the ground before take-off. The tracking error then starts at the GNSS error, which
        # is what such a drone really flies with.
        state[:, 0:3] -= err_tables.initial_gnss_error()
    if integrator != "euler" and not err_tables.switches.ideal:
        raise ValueError("the rk4 integrator flies ideal drones only (errors=ErrorModel())")

    if precision not in PRECISIONS:
        raise ValueError(f"unknown precision {precision!r} (expected one of {', '.join(PRECISIONS)})")
    if engine == "numba":
        if integrator != "euler":
            raise ValueError("the numba engine integrates with semi-implicit Euler only")
        # Imported on first use: numba's import and the kernel's cache load cost a second.
        runner: ChunkRunner
        if precision == "float32":
            from sim.flight.engines._numba_f32 import run_chunk_numba as run_chunk_f32

            runner = run_chunk_f32
        else:
            from sim.flight.engines._numba import run_chunk_numba

            runner = run_chunk_numba
    elif engine == "numpy":
        if precision != "float64":
            raise ValueError("precision='float32' needs engine='numba' (the numpy reference is float64)")
        runner = run_chunk_numpy
    else:
        raise ValueError(f"unknown engine {engine!r} (expected numba or numpy)")

    opts: dict[str, Any] = {
        "params": params, "plant": plant, "gains": gains, "disturbance": dist, "dt_s": dt_s,
        "integrator": integrator, "divergence_limit_m": float(divergence_limit_m),
        "drone": err_tables.drone, "switches": err_tables.switches,
        "ground_strike_z_m": -math.inf if ground_m is None else float(ground_m) - GROUND_STRIKE_M,
    }
    step = 0
    while step < steps:
        count = min(int(chunk_steps), steps - step)
        if 0 < steps - step - count <= int(chunk_steps) // 16:
            # A remainder of a few steps rides with this chunk: a run has round(d/dt) + 1 steps, so
            # a whole-second flight would otherwise end with a one-step chunk that pays a chunk's
            # set-up (two wind-table rows for every drone, a GNSS epoch, a kernel launch). The
            # results do not depend on the chunking (tables keyed by global step and epoch).
            count = steps - step
        times = (step + np.arange(count)) * dt_s
        runner(
            state, ctrl, stats, dstep, dreason, ref=reference, chunk=reference.chunk(times),
            dist=np.ascontiguousarray(dist.signals(times)), step0=step, times=times,
            every=every, frames=frames, tel=tel, opts=opts, tables=err_tables.chunk(step, count, reference),
        )
        step += count
        if on_chunk is not None:
            on_chunk(step, dstep)
        if progress is not None:
            progress(step / steps)

    counted = np.maximum(stats[:, STAT_COUNT], 1.0)
    return SimResult(
        frame_times_s=np.arange(n_frames) * every * dt_s,
        positions_m=frames,
        telemetry=tel,
        rms_error_m=np.sqrt(stats[:, STAT_SUMSQ] / counted),
        max_error_m=stats[:, STAT_MAX].copy(),
        max_thrust_step_n=stats[:, STAT_DTHRUST].copy(),
        diverged_step=dstep,
        diverged_reason=dreason,
        final_state=state,
        dt_s=dt_s,
        engine=engine,
        extra={"estimate": ctrl[:, C_PHAT:C_PHAT + 6].copy(), "drone": err_tables.drone},
    )


def warm_up(precisions: tuple[str, ...] = ("float64",)) -> None:
    """Compile (or load from the on-disk cache) both numba kernel variants on a tiny problem.

    One variant records float64 frames (``simulate``), the other float32 frames
    (``fly_show``); call this at image build or server start to move the first-run
    compile time (several seconds each) out of the first request. ``precisions``: the
    kernels to warm; the opt-in float32 one is left out by default (a server that never
    flies it should not pay its compile at every start on a cold cache).
    """
    for precision in precisions:
        if precision not in PRECISIONS:
            raise ValueError(f"precisions: unknown {precision!r} (one of {', '.join(PRECISIONS)})")
    ref = TrackingReference.hover(np.zeros((1, 3)))
    for precision in precisions:
        simulate(ref, duration_s=0.002, engine="numba", output_every=1, precision=precision)
        simulate(ref, duration_s=0.002, engine="numba", output_every=1, precision=precision,
                 frames_out=np.zeros((3, 1, 3), np.float32))
