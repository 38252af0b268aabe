"""Sampling the plan (or the simulated flight) at a frame rate, a block of drones at a time."""

from __future__ import annotations

import math
import queue
import threading
from collections.abc import Iterator

import numpy as np

from app.exports._archive import ZipBuilder
from app.exports._core import MAX_SAMPLES, ExportContext, ExportError
from app.exports._text import fixed_point_rows

#: Drones per block: small enough to stay in cache, large enough to amortise numpy call overhead.
BLOCK_DRONES = 16


def sample_times_ms(duration_s: float, fps: float) -> np.ndarray:
    """Integer-millisecond sample times 0, 1/fps, ... and the end of the show, (T,) int64.

    Times are rounded to whole milliseconds *before* the plan is evaluated, so a
    file that stores milliseconds holds the exact position at its own time stamp
    (for 3 fps, 333 ms rather than 333.33 ms rounded afterwards).
    """
    n = int(np.floor(duration_s * fps + 1e-9)) + 1
    t = np.rint(np.arange(n) * (1000.0 / fps)).astype(np.int64)
    end = int(np.rint(duration_s * 1000.0))
    t = t[t < end]
    return np.append(t, end)


def frame_count(duration_s: float, fps: float) -> int:
    """How many sample times :func:`sample_times_ms` gives (at most; computed without building them)."""
    return int(np.floor(duration_s * fps + 1e-9)) + 2


def default_fps(ctx: ExportContext, default: float, *, extra_rows: int = 0) -> float:
    """``default`` frames per second, or for a show too large for it the highest whole rate within
    :data:`MAX_SAMPLES` (at least 1), with a warning giving what the lower rate costs."""
    duration = ctx.plan.duration_s
    drones = max(ctx.show.drones, 1)
    if (frame_count(duration, default) + extra_rows) * drones <= MAX_SAMPLES:
        return default
    fps = float(max(1, int((MAX_SAMPLES / drones - 2 - extra_rows) / max(duration, 1e-9))))
    dt = 1.0 / fps
    chord_mm = ctx.show.settings.max_accel_mps2 * dt * dt / 8.0 * 1000.0
    ctx.warn(
        f"{ctx.fmt}: {ctx.show.drones} drones x {duration:.0f} s at the default {default:g} fps exceed the "
        f"{MAX_SAMPLES:,}-sample limit; wrote {fps:g} fps, so straight lines between rows stray up to "
        f"~{chord_mm:.0f} mm from the plan and colour fades step every {dt * 1000:.0f} ms (use .skyc, or "
        "crazyswarm, for exact trajectories)"
    )
    return fps


def check_sample_count(ctx: ExportContext, n_times: int) -> None:
    """Refuse exports that would hold more than :data:`MAX_SAMPLES` samples."""
    total = n_times * ctx.show.drones
    if total > MAX_SAMPLES:
        # The highest rate that fits, rounded down: frame_count() frames plus at most one extra row (the
        # Skybrush CSV's closing row), so (duration * fps + 3) * drones <= MAX_SAMPLES.
        most = (MAX_SAMPLES / max(ctx.show.drones, 1) - 3.0) / max(ctx.plan.duration_s, 1e-9)
        hint = (f"use fps <= {math.floor(most * 1e4) / 1e4:.4f}".rstrip("0").rstrip(".") if most >= 1e-4
                else "too many drones for a sampled export; use .skyc or crazyswarm")
        raise ExportError(
            f"{ctx.show.drones} drones x {n_times} frames = {total} samples exceeds the limit of {MAX_SAMPLES}; "
            f"{hint}", field="fps"
        )


def iter_samples(
    ctx: ExportContext, times_s: np.ndarray, *, block: int = BLOCK_DRONES
) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """Yield ``(first_drone, positions, colors)`` for consecutive blocks of drones.

    ``positions`` (n, T, 3) metres and ``colors`` (n, T, 3) in [0, 1] are drone-first.
    With ``source="simulated"`` the flown trajectory is linearly interpolated
    at ``times_s`` (the flight is sampled far faster than any export rate).
    """
    n = ctx.show.drones
    from sim.light import LightStack, show_colors

    # Issue 18: the show's light effects over the base colours (an empty stack changes nothing).
    stack = LightStack.from_show(ctx.show, ctx.plan)
    if ctx.options.source == "simulated":
        flight = ctx.flight
        ft = np.asarray(flight.times_s, dtype=np.float64)
        fpos = np.asarray(flight.positions_m)
        fcol = np.asarray(flight.colors_rgb)
        t = np.clip(times_s, ft[0], ft[-1])
        i = np.clip(np.searchsorted(ft, t, side="right") - 1, 0, len(ft) - 2) if len(ft) > 1 else np.zeros(len(t), int)
        span = ft[i + 1] - ft[i] if len(ft) > 1 else np.ones(len(t))
        w = np.where(span > 0, (t - ft[i]) / np.where(span > 0, span, 1.0), 0.0)[:, None, None]
        j = np.minimum(i + 1, len(ft) - 1)
        for a in range(0, n, block):
            b = min(a + block, n)
            pos = fpos[i, a:b] * (1.0 - w) + fpos[j, a:b] * w
            col = fcol[i, a:b] * (1.0 - w) + fcol[j, a:b] * w
            if stack:  # painted over the flown colours at the flown positions
                col = stack.apply(times_s, col, pos, slice(a, b))
            yield a, pos.transpose(1, 0, 2), col.transpose(1, 0, 2)
        return
    plan = ctx.plan
    # The same evaluation as ShowPlan.evaluate, but a block of drones at a time, positions
    # only: each drone on its own pieces (plan.motion), colours fading linearly over each
    # show-wide window.
    k0 = plan.segment_index(times_s)
    k1 = k0 + 1
    t0, t1 = plan.knot_times_s[k0], plan.knot_times_s[k1]
    tau = np.clip((times_s - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0, 1.0)[:, None, None]
    for a in range(0, n, block):
        b = min(a + block, n)
        pos = plan.motion.evaluate(times_s, slice(a, b), derivatives=0).positions_m
        if stack:
            col = show_colors(ctx.show, plan, times_s, drones=slice(a, b), positions_m=pos, stack=stack)
        else:
            C = plan.knot_colors_rgb[:, a:b]
            col = C[k0] + tau * (C[k1] - C[k0])
        yield a, pos.transpose(1, 0, 2), col.transpose(1, 0, 2)


def colors_to_bytes(colors: np.ndarray) -> np.ndarray:
    """Colours in [0, 1] to integers 0-255 (rounded, clipped), same shape."""
    return np.clip(np.rint(np.asarray(colors) * 255.0), 0, 255).astype(np.int64)


def write_sample_csvs(
    ctx: ExportContext,
    z: ZipBuilder,
    *,
    times_s: np.ndarray,
    time_column: np.ndarray,
    header: bytes,
    progress_from: float = 0.1,
) -> None:
    """Add one ``time,x,y,z,r,g,b`` CSV per drone to ``z`` (positions 3 decimals, colours 0-255).

    A worker thread samples and formats the next block of drones while this
    thread compresses the previous one into the archive: both numpy and zlib
    release the GIL, so the two overlap on a multi-core machine.

    Args:
        times_s: (T,) sample times, seconds.
        time_column: the time column pre-formatted by ``_text.column_bytes`` (T rows).
        header: the CSV header line.
        progress_from: progress fraction reported before the first block.
    """
    names = ctx.drone_names
    n = ctx.show.drones
    blocks: queue.Queue = queue.Queue(maxsize=2)
    stop = threading.Event()

    def produce() -> None:
        try:
            for first, pos, col in iter_samples(ctx, times_s):
                if stop.is_set():
                    return
                k = pos.shape[0]
                rgb = colors_to_bytes(col)
                texts = fixed_point_rows(
                    [np.tile(time_column, (k, 1))]
                    + [pos[..., a].ravel() for a in range(3)]
                    + [rgb[..., a].ravel() for a in range(3)],
                    [None, 3, 3, 3, 0, 0, 0],
                    groups=k,
                )
                blocks.put((first, texts))
            blocks.put(None)
        except BaseException as exc:  # handed to the main thread, which re-raises it
            blocks.put(exc)

    worker = threading.Thread(target=produce, name="swarmshow-export", daemon=True)
    worker.start()
    try:
        while (item := blocks.get()) is not None:
            if isinstance(item, BaseException):
                raise item
            first, texts = item
            for d, text in enumerate(texts):
                z.add(f"{names[first + d]}.csv", header + text)
            ctx.progress(progress_from + (0.95 - progress_from) * (first + len(texts)) / n)
    finally:
        stop.set()
        # Unblock a producer waiting on a full queue, then wait for it.
        while worker.is_alive():
            try:
                blocks.get(timeout=0.05)
            except queue.Empty:
                pass
        worker.join()
