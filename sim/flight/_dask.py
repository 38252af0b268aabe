"""The distributed flight engine: shards of drones flown on a Dask ``distributed`` cluster.

Drones fly independently given the plan (the disturbances depend on time only, the
wind is one field over the whole fleet), so a show splits over drones without any
communication during the flight. :func:`fly_show_dask` cuts the plan's drones into
contiguous shards, runs the local numba engine (:func:`sim.flight._runner.fly_local` with
``drones=shard``) on each shard as one task, gathers the per-shard arrays and merges
them into one :class:`~sim.flight._result.FlightResult`. Each drone's trajectory is computed
by the same kernel from the same inputs whatever shard it is in, so the merged arrays
equal the local engine's bit for bit (on workers with the same CPU features: numba
compiles for the host CPU). The flown minimum distance needs every drone of a frame,
so the shards skip it and it is computed once, after merging, over all drones.

What is shipped: the :class:`~sim.plan._plan.ShowPlan` (knots, colours and every drone's
polynomial pieces, ``plan.motion``: 144 bytes per piece, tens of MB at 16,000 drones) goes
to the cluster once, as the result of a tiny task whose specification holds it; the shard
tasks depend on it, so each worker fetches it once from a peer, and if the worker holding
it dies the scheduler simply recomputes it (scattered data could not be recovered). Each
shard task carries only its drone indices and the flight options, and returns positions
and colours (float32, 24 bytes per drone per frame) plus per-drone statistics.

Fault tolerance: a worker that dies mid-task (killed, out of memory, node lost) makes
the scheduler reschedule its tasks on the remaining workers (up to
``distributed.scheduler.allowed-failures`` times per task); a task that raises is
retried ``retries`` times. Tasks are deterministic and keyed per run, so a retried or
recomputed shard gives the same arrays and no drone is lost or counted twice.

Progress: every shard reports its own completed fraction as a scheduler event (tagged
with the run's token, throttled); the client combines them weighted by shard size (a retried shard
never makes the total go back) and maps the final merge and distance pass onto the
last few per cent. If the caller's callback raises, every future of the run is
cancelled and the exception propagates; a running shard notices its cancellation at
its next chunk (``chunk_s`` of simulated time) and stops.
"""

from __future__ import annotations

import os
import queue
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from sim.flight._notes import say_notes
from sim.flight._options import FlightOptions
from sim.flight._result import FlightResult, fold_flown_distance, ordered_pair
from sim.flight._runner import fly_local
from sim.plan._plan import ShowPlan

__all__ = ["SchedulerUnreachableError", "connect_scheduler", "fly_show_dask"]

#: Share of the reported progress taken by the shard simulations (the rest is the merge).
SIM_SHARE = 0.97
#: Least time between two progress events of one shard (s): bounds the scheduler traffic.
EVENT_INTERVAL_S = 0.2
#: Frames per step of the flown-distance pass (progress granularity after merging).
DISTANCE_BLOCK_FRAMES = 50

#: Scheduler event topic of the shards' progress. One topic for every run (messages carry
#: the run's token): the scheduler keeps a bounded log per topic, forever, so a topic per
#: run would grow its memory with every flight.
PROGRESS_TOPIC = "swarmshow-flight-progress"

# Tasks of one worker process share it: the numba kernel is already parallel over the
# drones of a shard, and its default (workqueue) threading layer must not be entered by
# two threads at once, so a worker with several threads flies one shard at a time.
_ENGINE_LOCK = threading.Lock()


class SchedulerUnreachableError(ConnectionError):
    """The Dask scheduler could not be reached, or has no worker, within the timeout."""


class ShardCancelledError(RuntimeError):
    """Raised inside a shard task whose future was cancelled (the run was abandoned)."""


# ----------------------------------------------------------------------------------------
# Worker side
# ----------------------------------------------------------------------------------------
def _hold_plan(plan: ShowPlan) -> ShowPlan:
    """Identity task: puts the plan in worker memory once; recomputable if its holder dies."""
    return plan


def worker_notes() -> None:
    """Have this worker say the ``sim`` packages' warnings (the flight kernel's cold-cache compile note,
    ``sim.flight.engines._numba.COMPILE_NOTE``) as ``swarmshow: ...`` lines on its stderr (idempotent).

    Why: a Dask worker has no handler for them, so logging's last-resort handler printed the bare sentence,
    unlike every other line swarmshow prints. Nothing is added where a handler already hears them (the CLI's
    own process with an in-process cluster, a worker whose logging was configured): no line twice. The
    handler is the command line's own (:func:`sim.flight._notes.say_notes`).
    """
    say_notes(unless_heard=True)


def _fly_shard(plan: ShowPlan, drones: np.ndarray, options: FlightOptions, token: str, shard: int) -> FlightResult:
    """Fly one shard with the local numba engine (runs on a worker).

    Args:
        plan: The planned show.
        drones: Plan indices of the shard's drones.
        options: The run's options, with ``engine="numba"`` and no flown distance.
        token: Identifier of the run, sent with the progress events.
        shard: Index of the shard, echoed in its progress events.

    Returns:
        The shard's :class:`~sim.flight._result.FlightResult` (without the flown distance).
    """
    worker_notes()
    with _ENGINE_LOCK:
        return fly_local(plan, options, drones=drones, progress=task_progress(token, shard, "shard"))


def route_progress(client: Any, token: str, on_event: Callable[[int, float], None]) -> None:
    """Send the progress events that tasks tagged ``token`` log (:func:`task_progress`) to
    ``on_event(index, fraction)``, through the one topic handler this client subscribes."""
    with _ROUTES_LOCK:
        _ROUTES[token] = on_event
    # Subscribing again would replace the same handler (and log it): once per client is enough.
    if getattr(client, "_event_handlers", {}).get(PROGRESS_TOPIC) is not _route_event:
        client.subscribe_topic(PROGRESS_TOPIC, _route_event)


def task_progress(token: str, index: int, what: str) -> Callable[[float], None]:
    """A progress callback for the Dask task running now (shard or Monte-Carlo run ``index``).

    It logs ``[token, index, fraction]`` as a scheduler event at most every
    :data:`EVENT_INTERVAL_S` (and at 1.0), and raises :class:`ShardCancelledError` once the
    task's future was released or cancelled: the worker moves such a task to "cancelled" (or
    forgets it), and stopping here frees the worker within one chunk.
    """
    from distributed import get_worker

    worker = get_worker()
    key = worker.get_current_task()
    last = [-1.0]

    def progress(fraction: float) -> None:
        ts = worker.state.tasks.get(key)
        if ts is None or ts.state in ("cancelled", "released", "forgotten"):
            raise ShardCancelledError(f"{what} {index} cancelled")
        now = time.monotonic()
        if fraction >= 1.0 or now - last[0] >= EVENT_INTERVAL_S:
            last[0] = now
            worker.log_event(PROGRESS_TOPIC, [token, int(index), float(fraction)])

    return progress


def dask_setup(worker: Any) -> None:
    """Worker preload hook: ``dask worker ... --preload sim.flight._dask`` loads the kernels at start.

    The numba kernels are compiled once per machine into ``__pycache__`` (10-20 s) and
    loaded from there by every process (about a second); doing it when the worker starts
    keeps both out of the first shard. Without the preload the first shard pays it.
    """
    from sim.flight.engines._driver import warm_up

    worker_notes()
    warm_up()


# ----------------------------------------------------------------------------------------
# Client side
# ----------------------------------------------------------------------------------------
@contextmanager
def connect_scheduler(scheduler: Any, timeout_s: float = 10.0) -> Iterator[Any]:
    """A connected ``distributed.Client`` for ``scheduler``, closed afterwards if made here.

    Args:
        scheduler: ``"tcp://HOST:PORT"``, ``"local"`` (an in-process ``LocalCluster`` on
            127.0.0.1, one single-threaded worker process per core) or a ``Client``
            (yielded as is, left open).
        timeout_s: How long to try to reach the scheduler, then to wait for a worker (s).

    Raises:
        SchedulerUnreachableError: No scheduler, or no worker, within ``timeout_s``.
        ValueError: ``scheduler`` is empty.
    """
    from distributed import Client, LocalCluster

    if isinstance(scheduler, Client):
        yield scheduler
        return
    if scheduler is None or not str(scheduler).strip():
        raise ValueError(
            "engine 'dask' needs a scheduler: an address tcp://HOST:PORT, 'local' for an "
            "in-process cluster, or a distributed.Client"
        )
    address = str(scheduler).strip()
    if address == "local":
        workers = max(1, os.cpu_count() or 1)
        # One single-threaded worker process per core, numba pinned to one thread each,
        # so that the workers do not oversubscribe the cores.
        with LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
            dashboard_address=None, env={"NUMBA_NUM_THREADS": "1"},
        ) as cluster, Client(cluster, set_as_default=False) as client:
            yield client
        return
    try:
        client = Client(address, timeout=timeout_s, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise SchedulerUnreachableError(
            f"cannot reach the Dask scheduler at {address} within {timeout_s:g} s ({exc})"
        ) from None
    try:
        try:
            client.wait_for_workers(1, timeout=timeout_s)
        except (OSError, TimeoutError) as exc:
            raise SchedulerUnreachableError(
                f"the Dask scheduler at {address} has no worker after {timeout_s:g} s ({exc})"
            ) from None
        yield client
    finally:
        client.close()


def _shard_count(shards: int | None, drones: int, threads: int) -> int:
    # Two shards per worker thread: a lost worker costs half as much recomputation and
    # the last shards finish closer together, for little per-task overhead.
    k = 2 * max(threads, 1) if shards is None else int(shards)
    if k < 1:
        raise ValueError(f"shards must be >= 1, got {shards}")
    return max(1, min(k, drones))


def fly_show_dask(
    plan: ShowPlan,
    options: FlightOptions | None = None,
    *,
    retries: int = 2,
    drones: slice | np.ndarray | None = None,
    progress: Callable[[float], None] | None = None,
    **kwargs: Any,
) -> FlightResult:
    """Fly ``plan`` on a Dask cluster, sharded over drones (see the module docstring).

    Args:
        plan: The planned show.
        options: The flight options (:class:`~sim.flight._options.FlightOptions`):
            ``scheduler`` is ``"tcp://HOST:PORT"`` of a running scheduler, ``"local"``
            for an in-process ``LocalCluster`` (one worker per core, loopback only), or
            a connected ``distributed.Client``; ``shards`` the number of tasks (default
            two per worker thread, at most one per drone); ``connect_timeout_s`` how
            long to try to reach the scheduler and to wait for a first worker (s).
        retries: Extra attempts of a task that raised (worker deaths are handled by
            the scheduler on top of this).
        drones: Optional subset (slice or index array) of the plan's drones to fly.
        progress: Called with the completed fraction in [0, 1] (increasing, ending at 1);
            if it raises, the run is cancelled and the exception propagates.
        **kwargs: Instead of ``options``, its fields as keywords (``engine`` is implied).

    Returns:
        A :class:`~sim.flight._result.FlightResult` with ``engine="dask"``.

    Raises:
        SchedulerUnreachableError: The scheduler or its workers could not be reached.
    """
    if options is None:
        options = FlightOptions.from_kwargs(**{"engine": "dask", **kwargs})
    elif kwargs:
        raise TypeError("give the flight options either as FlightOptions or as keywords, not both")
    # Each shard flies the local numba kernel (the same arrays, bit for bit) and skips the
    # flown distance, which needs every drone of a frame and is computed after the merge.
    shard_options = options.with_(engine="numba", scheduler=None, shards=None, flown_distance=False)
    ids = np.arange(plan.drone_count)
    if drones is not None:
        ids = ids[drones]
    with connect_scheduler(options.scheduler, options.connect_timeout_s) as client:
        start = time.perf_counter()
        threads = sum(client.nthreads().values())
        k = _shard_count(options.shards, ids.size, threads)
        parts = [p for p in np.array_split(ids, k) if p.size] or [ids]
        # One reporter for both phases, so the fractions stay strictly increasing.
        report = _Reporter(progress)
        results = _run_shards(client, plan, parts, shard_options, retries, lambda f: report(SIM_SHARE * f))
        address = client.scheduler.address
        workers = len(client.nthreads())
    merged = _merge(plan, ids, results, lambda f: report(SIM_SHARE + (1.0 - SIM_SHARE) * f))
    merged.wall_time_s = time.perf_counter() - start
    merged.extra.update({"scheduler": address, "shards": len(parts), "workers": workers})
    report(1.0)
    return merged


class _Reporter:
    """Forward only strictly increasing fractions in [0, 1] to ``callback`` (if any)."""

    def __init__(self, callback: Callable[[float], None] | None) -> None:
        self.callback = callback
        self.last = -1.0

    def __call__(self, fraction: float) -> None:
        f = min(max(float(fraction), 0.0), 1.0)
        if self.callback is not None and f > self.last:
            self.last = f
            self.callback(f)


# Progress handlers of the runs in this process, by run token (see ``_route_event``).
_ROUTES: dict[str, Callable[[int, float], None]] = {}
_ROUTES_LOCK = threading.Lock()


def _route_event(event: Any) -> None:
    """Hand a shard's progress event ``(time, [token, shard, fraction])`` to its run.

    Runs in the client's event-loop thread; events of other runs (other clients or
    processes flying at the same time) are ignored.
    """
    msg = event[1]
    if not isinstance(msg, (list, tuple)) or len(msg) != 3:
        return
    with _ROUTES_LOCK:
        handler = _ROUTES.get(str(msg[0]))
    if handler is not None:
        handler(int(msg[1]), float(msg[2]))


def _run_shards(
    client: Any, plan: ShowPlan, parts: list[np.ndarray], options: FlightOptions, retries: int,
    report: Callable[[float], None],
) -> list[FlightResult]:
    """Submit one task per shard, report progress as events arrive, gather in shard order."""
    token = uuid.uuid4().hex
    wake = threading.Event()
    events: queue.SimpleQueue[tuple[int, float]] = queue.SimpleQueue()

    def on_event(shard: int, fraction: float) -> None:
        events.put((shard, fraction))
        wake.set()

    route_progress(client, token, on_event)
    futures: list[Any] = []
    try:
        plan_future = client.submit(_hold_plan, plan, key=f"swarmshow-plan-{token}", pure=False)
        futures.append(plan_future)
        # Left to itself the scheduler puts every shard next to the plan they depend on,
        # on one worker, and relies on work stealing to spread them. Deal them out over
        # the worker threads instead; the restriction is loose, so a shard still moves
        # to another worker when its own dies, or is stolen by an idle one.
        slots = [addr for addr, n in sorted(client.nthreads().items()) for _ in range(max(int(n), 1))]
        shard_futures = [
            client.submit(
                _fly_shard, plan_future, part, options, token, i, key=f"swarmshow-shard-{token}-{i}",
                retries=retries, pure=False, workers=[slots[i % len(slots)]] if slots else None,
                allow_other_workers=True,
            )
            for i, part in enumerate(parts)
        ]
        futures.extend(shard_futures)
        for f in shard_futures:
            f.add_done_callback(lambda _f: wake.set())
        total = float(sum(p.size for p in parts))
        weight = [p.size / total for p in parts]
        done = [0.0] * len(parts)
        results: list[Any] = [None] * len(parts)
        pending = set(range(len(parts)))
        while pending:
            wake.wait(0.5)
            wake.clear()
            while True:
                try:
                    shard, fraction = events.get_nowait()
                except queue.Empty:
                    break
                if 0 <= shard < len(done):
                    # A retried shard starts again from 0: keep the best seen so the total
                    # never goes back.
                    done[shard] = max(done[shard], min(float(fraction), 1.0))
            for i in sorted(pending):
                if shard_futures[i].done():
                    results[i] = shard_futures[i].result()  # raises the task's error
                    pending.discard(i)
                    done[i] = 1.0
            report(sum(w * d for w, d in zip(weight, done, strict=True)))
        return results
    except BaseException:
        if futures:
            client.cancel(futures, force=True)
        raise
    finally:
        with _ROUTES_LOCK:
            _ROUTES.pop(token, None)
        for f in futures:
            f.release()


def _merge(
    plan: ShowPlan, ids: np.ndarray, results: list[FlightResult], report: Callable[[float], None]
) -> FlightResult:
    """Concatenate the shards' arrays in drone order and compute the flown distance over all."""
    first = results[0]
    times = first.times_s
    dt_s = first.dt_s
    positions = np.concatenate([r.positions_m for r in results], axis=1)
    colors = np.concatenate([r.colors_rgb for r in results], axis=1)
    diverged = [d for r in results for d in r.diverged]
    where = {int(d): i for i, d in enumerate(ids)}
    dstep = np.full(ids.size, -1, dtype=np.int64)
    for d, t, _reason in diverged:
        dstep[where[d]] = int(round(t / dt_s))

    # Same frame loop as the local engine (fly_local's on_chunk), over every drone.
    every = int(round((times[1] - times[0]) / dt_s)) if times.size > 1 else 1
    best: list[Any] = [float("inf"), -1, -1, float("nan")]
    n_frames = times.size
    for f0 in range(0, n_frames, DISTANCE_BLOCK_FRAMES):
        fold_flown_distance(best, range(f0, min(f0 + DISTANCE_BLOCK_FRAMES, n_frames)), positions=positions,
                             times=times, ids=ids, dstep=dstep, every=every)
        report(min(f0 + DISTANCE_BLOCK_FRAMES, n_frames) / n_frames * 0.999)

    return FlightResult(
        times_s=times,
        positions_m=positions,
        colors_rgb=colors,
        drone_ids=ids,
        tracking_rms_m=np.concatenate([r.tracking_rms_m for r in results]),
        tracking_max_m=np.concatenate([r.tracking_max_m for r in results]),
        max_thrust_step_n=np.concatenate([r.max_thrust_step_n for r in results]),
        flown_min_distance_m=float(best[0]),
        flown_min_distance_pair=ordered_pair(best),
        flown_min_distance_time_s=float(best[3]),
        min_distance_limit_m=float(plan.settings.min_distance_m),
        diverged=diverged,
        engine="dask",
        controller=first.controller,
        disturbance=first.disturbance,
        duration_s=first.duration_s,
        dt_s=dt_s,
    )
