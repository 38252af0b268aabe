"""Background jobs on a bounded worker-process pool, with progress, cancellation and a result cache.

* **Pools.** Two :class:`~concurrent.futures.ProcessPoolExecutor` (``spawn`` start
  method: forking a process that runs threads and an event loop is unsafe): the
  *batch* pool flies simulation jobs at a lower CPU priority; the *interactive*
  pool runs what a request awaits (checks, formations, exports, large saves, viewer
  planning), so that one client's 64 queued simulations never delay another's
  check. CPU-heavy work never runs in the server process, whose GIL the event loop
  and the viewer thread need.
* **Budgets.** Every interactive task runs under :func:`app.tasks.budgeted`: it stops
  after ``task_timeout_s`` or as soon as its client has gone (a shared-memory flag
  per task slot); one that does not stop is ended with its worker. Jobs fail after
  ``job_timeout_s``. At most ``max_interactive_tasks`` interactive tasks wait at once,
  and a client may have ``max_jobs_per_client`` jobs (then :class:`JobsBusy`).
* **Errors.** A failed job's ``error`` carries a ``kind`` (:class:`ErrorKind`, or a
  :class:`app.tasks.FailureKind` the task gave); the API maps kinds to HTTP statuses,
  this module knows none. Interactive tasks raise :class:`TaskError` likewise.
* **Progress.** Workers put ``(job_id, "running" | "progress", fraction)`` (or ``"note"``, a line
  of text until the next progress, e.g. that the flight kernel compiles) on one
  queue owned by a :mod:`multiprocessing` manager; a relay thread in the server
  applies them to the jobs. Every change bumps ``Job.version``, which is what the
  server-sent event stream watches.
* **Cancellation.** Each job has a manager ``Event``. A queued job is removed from
  the pool's queue; a running one sees the event at its next progress report and
  raises :class:`app.tasks.TaskCancelled`. The job reads ``cancelled`` at once
  either way, and the late result, if any, is dropped.
* **Cache.** Results are keyed by (kind, show content hash, options, version, code digest): in memory
  (LRU) in front of the store's ``results`` table, so an unchanged show is not
  recomputed, not even after a restart. An identical job of the same client already queued
  or running is shared instead of started twice (never across clients: one client's
  cancel must not stop another's job).
* **Records.** Every job's record (state, progress, error) is written to the store when
  it starts, changes state, every :data:`PERSIST_PROGRESS_S` of progress, and when it
  ends; after a crash or a restart the ids still answer, and the jobs that were queued
  or running are marked failed with kind ``interrupted``.
* **Settings.** The manager gets the server's :class:`~app.settings.AppSettings` at
  construction; workers never read the environment.
"""

from __future__ import annotations

import asyncio
import functools
import hashlib
import json
import logging
import multiprocessing
import secrets
import sqlite3
import threading
import time
from collections import OrderedDict
from collections.abc import AsyncIterator, Awaitable, Callable
from concurrent.futures import CancelledError, Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from enum import StrEnum
from multiprocessing.managers import SyncManager
from typing import Any

from app import tasks
from app.settings import AppSettings
from app.store import ShowStore
from app.version import __version__, code_digest

log = logging.getLogger("swarmshow.jobs")

#: Seconds a timed-out task gets to notice its cancel event before its worker process is ended.
TIMEOUT_GRACE_S = 5.0
#: Seconds between two writes of a running job's progress to the store (each write is an fsync).
PERSIST_PROGRESS_S = 2.0


class JobState(StrEnum):
    """Life cycle of a job: queued -> running -> done | failed | cancelled."""

    QUEUED = "queued"
    RUNNING = "running"
    DONE = "done"
    FAILED = "failed"
    CANCELLED = "cancelled"


TERMINAL = frozenset({JobState.DONE, JobState.FAILED, JobState.CANCELLED})


class ErrorKind(StrEnum):
    """Why a job or an interactive task did not finish with a result (besides a task's own
    :class:`app.tasks.FailureKind`)."""

    CANCELLED = "cancelled"  # by its client, or its client has gone
    TIMEOUT = "timeout"  # over its time budget
    WORKER_DIED = "worker_died"  # its worker process was killed (out of memory, a signal)
    FAILED = "failed"  # a bug: the traceback is in the server log
    INTERRUPTED = "interrupted"  # the server stopped (crashed, restarted) while the job was queued or running


class TaskError(RuntimeError):
    """An interactive task ended without a result: ``kind`` (an :class:`ErrorKind`) and a message."""

    def __init__(self, kind: ErrorKind, message: str) -> None:
        super().__init__(message)
        self.kind = kind


class JobNotFound(LookupError):
    """No job has this id (or it finished long ago and was forgotten)."""


class JobsBusy(RuntimeError):
    """Too many jobs are queued or running; try again later."""


class JobFinished(RuntimeError):
    """The job already finished; it cannot be cancelled."""

    def __init__(self, job: Job) -> None:
        super().__init__(f"job {job.id} already finished ({job.state})")
        self.job = job


@dataclass
class Job:
    """One background job; mutated only under the manager's lock."""

    id: str
    kind: str
    content_hash: str
    options: dict[str, Any]
    show_id: str | None = None
    show_revision: int | None = None
    state: JobState = JobState.QUEUED
    progress: float = 0.0
    result: Any = None
    error: dict[str, Any] | None = None
    cached: bool = False
    created_at: float = field(default_factory=time.time)
    started_at: float | None = None
    finished_at: float | None = None
    version: int = 0
    cache_key: str = ""
    client: str = ""
    note: str = ""
    persisted_at: float = field(default=0.0, repr=False)
    future: Future | None = field(default=None, repr=False)
    cancel_event: Any = field(default=None, repr=False)

    @property
    def terminal(self) -> bool:
        """True once the job is done, failed or cancelled."""
        return self.state in TERMINAL

    def snapshot(self, *, with_result: bool = True) -> dict[str, Any]:
        """A JSON-safe copy of the job (see ``app.server._models.JobOut``)."""
        return {
            "id": self.id,
            "kind": self.kind,
            "state": self.state.value,
            "progress": round(self.progress, 4),
            "show_id": self.show_id,
            "show_revision": self.show_revision,
            "content_hash": self.content_hash,
            "options": self.options,
            "cached": self.cached,
            "created_at": _iso(self.created_at),
            "started_at": _iso(self.started_at),
            "finished_at": _iso(self.finished_at),
            "result": self.result if with_result else None,
            "error": self.error,
            "note": self.note,
        }


def _iso(t: float | None) -> str | None:
    if t is None:
        return None
    return time.strftime("%Y-%m-%dT%H:%M:%S", time.gmtime(t)) + f".{int((t % 1) * 1e6):06d}Z"


def _parse_iso(text: str) -> float:
    """Inverse of :func:`_iso` (UTC)."""
    import calendar

    head, _, frac = text.rstrip("Z").partition(".")
    return calendar.timegm(time.strptime(head, "%Y-%m-%dT%H:%M:%S")) + (int(frac) / 1e6 if frac else 0.0)


def cache_key(kind: str, content_hash: str, options: dict[str, Any]) -> str:
    """Key of a result: kind, show content hash, and a digest of the options, the swarmshow version and
    the code (results cached on disk by an older planner or flight model are not served after an upgrade,
    nor after an edit that kept the version number)."""
    salted = {"options": options, "version": __version__, "code": code_digest()}
    opts = hashlib.sha256(json.dumps(salted, sort_keys=True, separators=(",", ":")).encode()).hexdigest()[:16]
    return f"{kind}:{content_hash}:{opts}"


class JobManager:
    """The worker pool, the jobs and the result cache of one server."""

    def __init__(self, *, store: ShowStore, settings: AppSettings) -> None:
        self.store, self.settings = store, settings
        self.workers = settings.workers
        self.interactive_workers = settings.interactive_workers
        self.max_jobs_kept = settings.max_jobs_kept
        self.max_pending = settings.max_pending_jobs
        self.max_per_client = settings.max_jobs_per_client
        self.max_cached = settings.max_cached_results
        self.task_timeout_s = settings.task_timeout_s
        self._lock = threading.Lock()
        self._persist_lock = threading.Lock()
        self._jobs: OrderedDict[str, Job] = OrderedDict()
        self._inflight: dict[str, str] = {}
        self._memo: OrderedDict[str, Any] = OrderedDict()
        self._ctx = multiprocessing.get_context("spawn")
        self._manager: Any = None
        self._events: Any = None
        self._pool: ProcessPoolExecutor | None = None
        self._relay: threading.Thread | None = None
        self._closed = False
        self._started = threading.Event()
        self.timeout_s = settings.job_timeout_s
        self._watchdog: threading.Thread | None = None
        self._recovered = False  # the earlier server's unfinished jobs marked interrupted (recover)
        # Interactive tasks: one slot each (its cancel flag and budget); free slots are the admission limit.
        slots = settings.max_interactive_tasks
        self._flags: Any = None
        self._starts: Any = None
        self._free_slots: list[int] = list(range(slots))[::-1]
        self._slot_budget: dict[int, tuple[Future, float]] = {}  # slot -> (future, budget_s)
        self._ipool: ProcessPoolExecutor | None = None

    # -- life cycle -------------------------------------------------------------------------

    def start(self) -> None:
        """Mark jobs a previous server left unfinished as interrupted (unless :meth:`recover` did); start
        the manager process, the pools (warming every worker up) and the relay and watchdog threads."""
        self.recover()
        self._manager = SyncManager(ctx=self._ctx)
        self._manager.start(initializer=tasks.die_with_parent)
        self._events = self._manager.Queue()
        self._flags = self._ctx.RawArray("b", max(len(self._free_slots), 1))
        self._starts = self._ctx.RawArray("d", max(len(self._free_slots), 1))
        self._pool = self._new_pool()
        self._ipool = self._new_interactive_pool()
        for _ in range(self.workers):
            self._pool.submit(tasks.warm_up)
        for _ in range(self.interactive_workers):
            self._ipool.submit(tasks.warm_up)
        self._relay = threading.Thread(target=self._relay_loop, name="swarmshow-job-relay", daemon=True)
        self._relay.start()
        self._watchdog = threading.Thread(target=self._watchdog_loop, name="swarmshow-job-watchdog", daemon=True)
        self._watchdog.start()
        self._started.set()

    def wait_started(self, timeout_s: float = 120.0) -> None:
        """Block until :meth:`start` has finished (the server answers before its pool is up)."""
        if not self._started.wait(timeout_s):
            raise RuntimeError("the job manager did not start")

    def close(self) -> None:
        """Cancel every unfinished job and stop the pool, the relay thread and the manager."""
        if self._closed:
            return
        self._closed = True
        with self._lock:
            unfinished = [j for j in self._jobs.values() if not j.terminal]
            interactive_busy = len(self._free_slots) < self.settings.max_interactive_tasks
        for job in unfinished:
            self._cancel_job(job, reason="server shutting down")
        if self._flags is not None:
            for i in range(len(self._flags)):
                self._flags[i] = 1  # every interactive task stops at its next tick
        processes = []
        for pool in (self._pool, self._ipool):
            if pool is not None:
                processes += list(getattr(pool, "_processes", {}).values())
                pool.shutdown(wait=False, cancel_futures=True)
        # A worker deep in a long step (a big check) reports no progress; give it a moment, then stop it.
        # With no job and no interactive task out, a worker has nothing to finish (at most its warm-up's
        # imports, which never end early): a short grace for an idle one to take its exit sentinel, not the
        # 3 s that every stop of an idle server used to wait out (tests/test_jobs_close.py).
        grace_s = 3.0 if unfinished or interactive_busy else 0.25
        deadline = time.monotonic() + grace_s
        for p in processes:
            p.join(max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.terminate()
        if self._events is not None:
            try:
                self._events.put(None)
            except (OSError, EOFError):
                pass
        if self._relay is not None:
            self._relay.join(timeout=2.0)
        if self._manager is not None:
            self._manager.shutdown()

    def _new_pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=self.workers, mp_context=self._ctx, initializer=tasks.worker_init,
                                   initargs=(self.settings.worker_memory_mb << 20,))

    def _new_interactive_pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(max_workers=self.interactive_workers, mp_context=self._ctx,
                                   initializer=tasks.interactive_init,
                                   initargs=(self._flags, self._starts, self.settings.worker_memory_mb << 20))

    def _submit(self, fn: Callable[..., Any], *args: Any) -> Future:
        self.wait_started()
        if self._closed or self._pool is None:
            raise RuntimeError("the job manager is not running")
        try:
            return self._pool.submit(fn, *args)
        except BrokenProcessPool:
            # A worker died (killed, out of memory): replace the pool rather than fail forever.
            log.warning("worker pool broken; starting a new one")
            self._pool = self._new_pool()
            return self._pool.submit(fn, *args)

    def _watchdog_loop(self) -> None:
        """Fail jobs running longer than ``timeout_s``; stop a worker that ignores the cancel event."""
        stuck: list[tuple[Future, float]] = []
        period = min(1.0, self.timeout_s / 4, self.task_timeout_s / 4)
        while not self._closed:
            time.sleep(period)
            now = time.time()
            with self._lock:
                late = [j for j in self._jobs.values()
                        if j.state == JobState.RUNNING and j.started_at and now - j.started_at > self.timeout_s]
            for job in late:
                fut = job.future
                self._cancel_job(job, reason=f"timed out after {self.timeout_s:g} s (SWARMSHOW_JOB_TIMEOUT_S)",
                                 state=JobState.FAILED, kind=ErrorKind.TIMEOUT)
                if fut is not None:
                    stuck.append((fut, time.monotonic() + TIMEOUT_GRACE_S))
            overdue = [f for f, t in stuck if not f.done() and time.monotonic() > t]
            stuck = [(f, t) for f, t in stuck if not f.done() and f not in overdue]
            if overdue:
                # The task reports no progress (a numerical loop gone wrong): only ending its process stops it.
                log.warning("%d timed-out job(s) ignored cancellation; restarting the worker pool", len(overdue))
                self._recycle_pool()
            now_m = time.monotonic()
            with self._lock:
                late_tasks = [f for slot, (f, budget) in self._slot_budget.items()
                              if not f.done() and 0 < self._starts[slot] < now_m - budget - TIMEOUT_GRACE_S]
            if late_tasks:
                # A task stuck in one C call (no bytecode, so no timer tick): end its worker.
                log.warning("%d interactive task(s) over their hard deadline; restarting that pool", len(late_tasks))
                self._recycle_pool(self._ipool)

    def _recycle_pool(self, pool: ProcessPoolExecutor | None = None) -> None:
        pool = pool or self._pool
        if pool is None:
            return
        for p in list(getattr(pool, "_processes", {}).values()):
            if p.is_alive():
                p.terminate()

    # -- job records in the store ----------------------------------------------------------

    def _save(self, job: Job) -> None:
        """Write the job's current record to the store.

        Taking the record and writing it happen under one lock of their own (not the jobs' lock: a
        write waits for an fsync), so a late "running" can never overwrite a "done" written before it.
        """
        with self._persist_lock:
            with self._lock:
                snap = job.snapshot(with_result=False)
                snap.update(cache_key=job.cache_key, client=job.client)
                state = job.state.value
            self._persist(job.id, (json.dumps(snap), state))

    def _persist(self, job_id: str, record: tuple[str, str]) -> None:
        try:
            self.store.put_job(job_id, record[0], state=record[1], keep=self.max_jobs_kept)
        except Exception as exc:  # a full disk must not fail the job itself
            log.warning("job %s: record not written: %s", job_id, exc)

    def recover(self) -> None:
        """Mark the jobs a previous server left queued or running as failed (``interrupted``), once.

        The server calls this before it answers its first request and starts the pools in the
        background afterwards: a job id asked for in between must already read ``interrupted``, since
        a record still ``running`` is not shown (it could be this server's own job a moment before it
        is in memory) and would answer 404.
        """
        if not self._recovered:
            self._recovered = True
            self._mark_interrupted()

    def _mark_interrupted(self) -> None:
        try:
            records = self.store.unfinished_jobs()
        except Exception:
            log.exception("could not read the job records")
            return
        now = time.time()
        for text in records:
            rec = json.loads(text)
            rec.update(state=JobState.FAILED.value, finished_at=_iso(now), note="", error={
                "kind": ErrorKind.INTERRUPTED.value,
                "message": "the server stopped while this job was queued or running; start it again"})
            self._persist(rec["id"], (json.dumps(rec), rec["state"]))
        if records:
            log.warning("%d job(s) were interrupted by the last server stop", len(records))

    def _stored_job(self, job_id: str) -> Job | None:
        """A finished job of an earlier server, from its record (its result from the cache), or None."""
        try:
            text = self.store.get_job(job_id)
        except Exception:
            return None
        if text is None:
            return None
        rec = json.loads(text)
        job = Job(id=rec["id"], kind=rec["kind"], content_hash=rec["content_hash"], options=rec["options"],
                  show_id=rec.get("show_id"), show_revision=rec.get("show_revision"),
                  state=JobState(rec["state"]), progress=float(rec["progress"]), error=rec.get("error"),
                  cached=bool(rec.get("cached")), cache_key=rec.get("cache_key", ""), client=rec.get("client", ""))
        for name in ("created_at", "started_at", "finished_at"):
            value = rec.get(name)
            setattr(job, name, _parse_iso(value) if value else None)
        if job.state == JobState.DONE and job.cache_key:
            job.result = self.cached_result(job.cache_key)
        if not job.terminal:  # written by this server an instant ago and not yet in memory: not ours to show
            return None
        return job

    def _relay_loop(self) -> None:
        while True:
            try:
                item = self._events.get(timeout=0.5)
            except (OSError, EOFError, BrokenPipeError):
                return  # the manager is gone: shutting down
            except Exception:  # queue.Empty (re-raised by the proxy under its own name)
                if self._closed:
                    return
                continue
            if item is None:
                return
            job_id, what, value = item
            save = False
            with self._lock:
                job = self._jobs.get(job_id)
                if job is None or job.terminal:
                    continue
                was = job.state
                if what == "running" and job.state == JobState.QUEUED:
                    job.state, job.started_at = JobState.RUNNING, time.time()
                elif what == "note":
                    job.note = str(value)[:200]
                elif what == "progress":
                    # A note says what holds the progress up (a kernel compile): it holds until the
                    # task moves on.
                    if float(value) > job.progress:
                        job.note = ""
                    job.progress = max(job.progress, min(float(value), 1.0))
                    if job.state == JobState.QUEUED:
                        job.state, job.started_at = JobState.RUNNING, time.time()
                job.version += 1
                if job.state != was or time.monotonic() - job.persisted_at >= PERSIST_PROGRESS_S:
                    job.persisted_at = time.monotonic()
                    save = True
            if save:
                self._save(job)

    # -- synchronous tasks (awaited by a request) -------------------------------------------

    async def run(self, fn: Callable[..., Any], *args: Any, gone: Callable[[], Awaitable[bool]] | None = None,
                  budget_s: float | None = None) -> Any:
        """Run ``fn(*args)`` in the interactive pool under a time budget and await its result.

        Args:
            gone: polled while waiting; once it says the client has gone, the task is stopped.
            budget_s: the task's time budget (default ``task_timeout_s``).

        Raises:
            JobsBusy: ``max_interactive_tasks`` tasks are already waiting or running.
            TaskError: timed out, cancelled (its client left), or its worker died.
            app.tasks.TaskFailure: the task refused its input.
        """
        if not self._started.is_set():
            await asyncio.to_thread(self.wait_started)
        budget = float(budget_s or self.task_timeout_s)
        slot = self._take_slot()
        fut: Future | None = None
        try:
            fut = self._submit_interactive(slot, budget, fn, *args)
            waiting = asyncio.wrap_future(fut)
            # An abandoned task still ends (cancelled, with an error): retrieve it so that asyncio does not warn.
            waiting.add_done_callback(lambda f: f.cancelled() or f.exception())
            while True:
                done, _ = await asyncio.wait({waiting}, timeout=0.25 if gone is not None else None)
                if done:
                    break
                if gone is not None and await gone():
                    raise TaskError(ErrorKind.CANCELLED, "the client has gone")
            try:
                return waiting.result()
            except tasks.TaskTimeout as exc:
                raise TaskError(ErrorKind.TIMEOUT, f"{exc} (SWARMSHOW_TASK_TIMEOUT_S)") from None
            except tasks.TaskCancelled:
                raise TaskError(ErrorKind.CANCELLED, "cancelled") from None
            except (BrokenProcessPool, CancelledError):
                self._replace_broken_interactive_pool()
                raise TaskError(ErrorKind.WORKER_DIED, "the worker process died (killed, out of memory, or "
                                "ended for running over its time budget)") from None
        finally:
            self._release_slot(slot, fut)

    def run_sync(self, fn: Callable[..., Any], *args: Any, budget_s: float | None = None) -> Any:
        """:meth:`run` for a thread that is not the event loop's (the viewer's loader)."""
        self.wait_started()
        budget = float(budget_s or self.task_timeout_s)
        slot = self._take_slot()
        fut: Future | None = None
        try:
            fut = self._submit_interactive(slot, budget, fn, *args)
            try:
                return fut.result()
            except tasks.TaskTimeout as exc:
                raise TaskError(ErrorKind.TIMEOUT, f"{exc} (SWARMSHOW_TASK_TIMEOUT_S)") from None
            except (BrokenProcessPool, CancelledError):
                self._replace_broken_interactive_pool()
                raise TaskError(ErrorKind.WORKER_DIED, "the worker process died") from None
        finally:
            self._release_slot(slot, fut)

    def _take_slot(self) -> int:
        with self._lock:
            if not self._free_slots:
                raise JobsBusy(f"{self.settings.max_interactive_tasks} interactive requests are queued or "
                               "running (SWARMSHOW_MAX_INTERACTIVE_TASKS); try again shortly")
            slot = self._free_slots.pop()
        self._flags[slot] = 0
        self._starts[slot] = 0.0
        return slot

    def _release_slot(self, slot: int, fut: Future | None) -> None:
        """Free ``slot`` once its task is over; a task still queued or running is told to stop first."""
        def free(_: Any = None) -> None:
            with self._lock:
                self._slot_budget.pop(slot, None)
                self._free_slots.append(slot)

        if fut is None or fut.done():
            free()
            return
        self._flags[slot] = 1
        fut.cancel()
        fut.add_done_callback(free)

    def _submit_interactive(self, slot: int, budget_s: float, fn: Callable[..., Any], *args: Any) -> Future:
        if self._closed or self._ipool is None:
            raise RuntimeError("the job manager is not running")
        try:
            fut = self._ipool.submit(tasks.budgeted, slot, budget_s, fn, *args)
        except BrokenProcessPool:
            self._replace_broken_interactive_pool()
            fut = self._ipool.submit(tasks.budgeted, slot, budget_s, fn, *args)
        with self._lock:
            self._slot_budget[slot] = (fut, budget_s)
        return fut

    def _replace_broken_interactive_pool(self) -> None:
        with self._lock:
            pool = self._ipool
            if pool is None or self._closed or not getattr(pool, "_broken", False):
                return
            log.warning("interactive worker pool broken; starting a new one")
            self._ipool = self._new_interactive_pool()

    def interactive_busy(self) -> int:
        """Interactive tasks queued or running."""
        with self._lock:
            return self.settings.max_interactive_tasks - len(self._free_slots)

    def saturated(self) -> bool:
        """True when new work would wait: every interactive worker busy with others queued, or the job
        queue full."""
        return self.interactive_busy() > self.interactive_workers or self.pending() >= self.max_pending

    async def run_cached(
        self, kind: str, content_hash: str, options: dict[str, Any], fn: Callable[..., Any], *args: Any,
        gone: Callable[[], Awaitable[bool]] | None = None,
    ) -> tuple[Any, bool]:
        """Like :meth:`run`, through the result cache; returns ``(result, was_cached)``."""
        key = cache_key(kind, content_hash, options)
        hit = self.cached_result(key)  # a memory lookup or one indexed read: no thread needed
        if hit is not None:
            return hit, True
        result = await self.run(fn, *args, gone=gone)
        await asyncio.to_thread(self._remember, key, kind, content_hash, result)
        return result, False

    def cached_result(self, key: str) -> Any:
        """A cached result (memory, then the store), or None."""
        with self._lock:
            if key in self._memo:
                self._memo.move_to_end(key)
                return self._memo[key]
        text = self.store.get_result(key)
        if text is None:
            return None
        value = json.loads(text)
        self._memo_put(key, value)
        return value

    def _remember(self, key: str, kind: str, content_hash: str, result: Any) -> None:
        self._memo_put(key, result)
        try:
            self.store.put_result(
                key, kind=kind, content_hash=content_hash, text=json.dumps(result, allow_nan=False),
                keep=self.max_cached,
            )
        except (ValueError, TypeError, sqlite3.Error) as exc:
            # Not JSON-safe, or the disk is full: the result is still answered, only not kept on disk.
            log.warning("result of %s not cached on disk: %s", key, exc)

    def _memo_put(self, key: str, value: Any) -> None:
        with self._lock:
            self._memo[key] = value
            self._memo.move_to_end(key)
            while len(self._memo) > self.max_cached:
                self._memo.popitem(last=False)

    # -- background jobs --------------------------------------------------------------------

    def submit(
        self,
        kind: str,
        fn: Callable[..., Any],
        *,
        show_text: str,
        content_hash: str,
        options: dict[str, Any],
        show_id: str | None = None,
        show_revision: int | None = None,
        client: str = "",
        task_options: dict[str, Any] | None = None,
    ) -> Job:
        """Start a job ``fn(show_text, task_options, job_id, progress_queue, cancel_event)``.

        A result in the cache gives a job that is already done (``cached``); an
        identical job of the same ``client`` still queued or running is returned
        instead of a new one. ``options`` key the cache; ``task_options`` (default:
        ``options``) are what the task gets, resolved with the server's settings.

        Raises:
            JobsBusy: ``max_pending`` jobs, or ``max_jobs_per_client`` of this client, are queued or running.
        """
        key = cache_key(kind, content_hash, options)
        with self._lock:
            same = self._jobs.get(self._inflight.get(f"{client}|{key}", ""))
            if same is not None and not same.terminal:
                return same
        job = Job(
            id=secrets.token_hex(8), kind=kind, content_hash=content_hash, options=options,
            show_id=show_id, show_revision=show_revision, cache_key=key, client=client,
        )
        hit = self.cached_result(key)
        if hit is not None:
            now = time.time()
            job.state, job.progress, job.result, job.cached = JobState.DONE, 1.0, hit, True
            job.started_at = job.finished_at = now
            self._add(job)
            return job
        with self._lock:
            live = [j for j in self._jobs.values() if not j.terminal]
            mine = sum(1 for j in live if j.client == client)
        if len(live) >= self.max_pending:
            raise JobsBusy(f"{len(live)} jobs are queued or running; try again when some have finished")
        if mine >= self.max_per_client:
            raise JobsBusy(f"you have {mine} jobs queued or running, the limit per client "
                           "(SWARMSHOW_MAX_JOBS_PER_CLIENT); try again when some have finished")
        self.wait_started()
        job.cancel_event = self._manager.Event()
        self._add(job, inflight=True)
        try:
            job.future = self._submit(fn, show_text, options if task_options is None else task_options, job.id,
                                      self._events, job.cancel_event)
        except Exception:
            log.exception("job %s (%s) could not start", job.id, job.kind)
            self._finish(job, JobState.FAILED, error={"kind": ErrorKind.FAILED.value, "message": "could not start"})
            return job
        job.future.add_done_callback(functools.partial(self._on_done, job.id))
        return job

    def _add(self, job: Job, *, inflight: bool = False) -> None:
        with self._lock:
            self._jobs[job.id] = job
            job.persisted_at = time.monotonic()
            if inflight:
                self._inflight[f"{job.client}|{job.cache_key}"] = job.id
            excess = len(self._jobs) - self.max_jobs_kept
            if excess > 0:
                for old_id in [k for k, j in self._jobs.items() if j.terminal][:excess]:
                    del self._jobs[old_id]
        self._save(job)

    def _on_done(self, job_id: str, fut: Future) -> None:
        """Runs in the pool's management thread when a job's task ends."""
        with self._lock:
            job = self._jobs.get(job_id)
        if job is None:
            return
        try:
            result = fut.result()
        except CancelledError:
            self._finish(job, JobState.CANCELLED, error={"kind": ErrorKind.CANCELLED.value,
                                                         "message": "cancelled before it started"})
            return
        except tasks.TaskCancelled:
            self._finish(job, JobState.CANCELLED, error={"kind": ErrorKind.CANCELLED.value, "message": "cancelled"})
            return
        except tasks.TaskFailure as exc:
            self._finish(job, JobState.FAILED, error={"kind": exc.kind.value, "message": str(exc),
                                                      "detail": exc.detail})
            return
        except BrokenProcessPool:
            self._finish(job, JobState.FAILED, error={
                "kind": ErrorKind.WORKER_DIED.value, "message": "the worker process died (killed or out of memory)"})
            return
        except MemoryError:
            self._finish(job, JobState.FAILED, error={
                "kind": tasks.FailureKind.TOO_LARGE.value,
                "message": "the job needs more memory than a worker may use (SWARMSHOW_WORKER_MEMORY_MB)"})
            return
        except Exception:
            # A bug: the traceback goes to the log, the client gets no exception text.
            log.exception("job %s (%s) failed", job.id, job.kind)
            self._finish(job, JobState.FAILED, error={"kind": ErrorKind.FAILED.value,
                                                      "message": f"internal error (job {job.id}; see the server log)"})
            return
        try:
            self._remember(job.cache_key, job.kind, job.content_hash, result)
        except Exception:
            log.exception("could not cache the result of job %s", job.id)
        self._finish(job, JobState.DONE, result=result)

    def _finish(self, job: Job, state: JobState, *, result: Any = None, error: dict[str, Any] | None = None) -> None:
        with self._lock:
            if self._inflight.get(f"{job.client}|{job.cache_key}") == job.id:
                del self._inflight[f"{job.client}|{job.cache_key}"]
            if job.terminal:
                return  # cancelled meanwhile: the late result or error is dropped
            job.state, job.result, job.error = state, result, error
            # A note says what holds a running job up (a kernel compile); an ended job has nothing holding it.
            job.note = ""
            if state == JobState.DONE:
                job.progress = 1.0
            job.finished_at = time.time()
            job.started_at = job.started_at or job.finished_at
            job.version += 1
            job.future, job.cancel_event = None, None
        self._save(job)

    def get(self, job_id: str) -> Job:
        """The job. Raises :class:`JobNotFound`."""
        with self._lock:
            job = self._jobs.get(job_id)
        if job is None:
            job = self._stored_job(job_id)  # an earlier server's job, or one forgotten from memory
        if job is None:
            raise JobNotFound(job_id)
        return job

    def list(self) -> list[Job]:
        """Every remembered job, oldest first."""
        with self._lock:
            return list(self._jobs.values())

    def cancel(self, job_id: str) -> Job:
        """Cancel a queued or running job (a cancelled one is returned as is).

        Raises:
            JobNotFound: no such job.
            JobFinished: the job is already done or failed.
        """
        job = self.get(job_id)
        if job.state in (JobState.DONE, JobState.FAILED):
            raise JobFinished(job)
        self._cancel_job(job, reason="cancelled")
        return job

    def _cancel_job(self, job: Job, *, reason: str, state: JobState = JobState.CANCELLED,
                    kind: ErrorKind = ErrorKind.CANCELLED) -> None:
        event, fut = job.cancel_event, job.future
        if event is not None:
            try:
                event.set()
            except (OSError, EOFError):
                pass
        if fut is not None:
            fut.cancel()  # succeeds only while the task waits in the pool's queue
        self._finish(job, state, error={"kind": kind.value, "message": reason})

    def pending(self) -> int:
        """Jobs queued or running."""
        with self._lock:
            return sum(1 for j in self._jobs.values() if not j.terminal)

    async def watch(
        self, job_id: str, *, poll_s: float = 0.1, heartbeat_s: float | None = None
    ) -> AsyncIterator[dict[str, Any] | None]:
        """Yield a snapshot of the job whenever it changes, ending after a terminal state.

        With ``heartbeat_s``, ``None`` is yielded after that long without a change
        (so that a stream can send a keep-alive).

        Raises:
            JobNotFound: no such job.
        """
        last, quiet_since = -1, time.monotonic()
        while True:
            job = self.get(job_id)
            with self._lock:
                version, terminal = job.version, job.terminal
                snap = job.snapshot(with_result=terminal) if version != last else None
            if snap is not None:
                last, quiet_since = version, time.monotonic()
                yield snap
            elif heartbeat_s is not None and time.monotonic() - quiet_since >= heartbeat_s:
                quiet_since = time.monotonic()
                yield None
            if terminal:
                return
            await asyncio.sleep(poll_s)
