"""CPU-heavy work run in the worker processes (planning, checking, flying, sampling, exporting).

Every function here is top level (picklable by name) and takes plain data: the
show as its JSON text, options as dicts. Known failures are raised as
:class:`TaskFailure` (HTTP status + detail), because library exceptions with
keyword arguments (``PlanError.path``, ``FormationError.max_n``) lose them when
pickled back to the server process.

Long tasks report progress through a queue shared with the server and stop at
their next progress report once their cancel event is set.
"""

from __future__ import annotations

import os
import time
from typing import Any

#: Fraction of a simulation job spent planning (the flight is the rest).
PLAN_SHARE = 0.05


class TaskFailure(Exception):
    """A task failed for a reason the client should see: ``status`` (HTTP) and ``detail`` (JSON-safe)."""

    def __init__(self, status: int, detail: Any) -> None:
        super().__init__(status, detail)

    @property
    def status(self) -> int:
        """HTTP status the API answers with (422 bad input, 413 too large, 500 internal)."""
        return int(self.args[0])

    @property
    def detail(self) -> Any:
        """A message or a list of ``{loc, path, msg}`` problems."""
        return self.args[1]

    def __str__(self) -> str:
        d = self.detail
        if isinstance(d, list) and d and isinstance(d[0], dict):
            first = d[0]
            return f"{first['path']}: {first['msg']}" if first.get("path") else str(first.get("msg"))
        return str(d)


class TaskCancelled(Exception):
    """Raised inside a task by its progress callback after the job was cancelled."""


class Progress:
    """Progress callback of one job: relays fractions to the server, stops the task when cancelled.

    Reports are throttled (every 1 % or 0.25 s) so that a tight loop calling back
    does not flood the queue; the cancel flag is polled at most every 50 ms because
    each poll is a round trip to the manager process.
    """

    def __init__(self, job_id: str, queue: Any, cancel: Any) -> None:
        self.job_id, self._queue, self._cancel = job_id, queue, cancel
        self._sent, self._sent_at, self._polled_at = -1.0, 0.0, 0.0

    def started(self) -> None:
        """Tell the server the task is running (it may have waited in the pool's queue)."""
        self.check_cancelled(force=True)
        self._queue.put((self.job_id, "running", 0.0))

    def check_cancelled(self, *, force: bool = False) -> None:
        """Raise :class:`TaskCancelled` if the job was cancelled."""
        now = time.monotonic()
        if force or now - self._polled_at >= 0.05:
            self._polled_at = now
            if self._cancel.is_set():
                raise TaskCancelled(self.job_id)

    def __call__(self, fraction: float) -> None:
        self.check_cancelled()
        f = min(max(float(fraction), 0.0), 1.0)
        now = time.monotonic()
        if f - self._sent >= 0.01 or (f > self._sent and now - self._sent_at >= 0.25):
            self._sent, self._sent_at = f, now
            self._queue.put((self.job_id, "progress", f))

    def scaled(self, start: float, stop: float) -> Any:
        """A callback mapping [0, 1] onto [start, stop] of this job."""
        return lambda f: self(start + (stop - start) * float(f))


#: Scheduling niceness of the worker processes: jobs are batch work, and the event loop's requests
#: (each a millisecond or two) must not wait behind a simulation that keeps every core busy.
WORKER_NICE = 10


def worker_init() -> None:
    """Run once in each worker process: end with the server, and run at a lower CPU priority."""
    die_with_parent()
    try:
        os.nice(WORKER_NICE)
    except (AttributeError, OSError):  # not on this platform, or not permitted: run at normal priority
        pass


def die_with_parent() -> None:
    """Have Linux kill this process when the server process dies (SIGKILL, out of memory), so that a
    crashed server leaves no orphaned workers holding memory; elsewhere a no-op."""
    import ctypes
    import signal
    import sys

    if not sys.platform.startswith("linux"):
        return
    parent = os.getppid()
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != parent:  # the server died before the request took effect
        os._exit(1)


def warm_up() -> int:
    """Import the heavy modules once so that the first real job does not pay for it."""
    import formations  # noqa: F401
    import sim  # noqa: F401

    return os.getpid()


def _show(show_text: str):
    from formations import parse_show

    return parse_show(show_text)


def validate_task(data: bytes | dict[str, Any]) -> dict[str, Any]:
    """Validate a show file; returns the fields of :class:`app.store.ShowData`.

    Large show files are validated here, in a worker, so that seconds of parsing
    never hold the server's GIL.

    Raises:
        TaskFailure: 422 with ``ShowValidationError.errors``.
    """
    from app.store import ShowData
    from formations import ShowValidationError, parse_show

    try:
        show = parse_show(data)
    except ShowValidationError as exc:
        raise TaskFailure(422, exc.errors) from None
    d = ShowData.of(show)
    return {"text": d.text, "content_hash": d.content_hash, "name": d.name, "drones": d.drones,
            "formations": d.formations}


def _plan_failure(exc: Exception) -> TaskFailure:
    path = getattr(exc, "path", "") or ""
    problem: dict[str, Any] = {"loc": ["show", *_path_loc(path)], "path": path, "msg": str(exc)}
    if getattr(exc, "minimum_s", None) is not None:
        problem["minimum_s"] = exc.minimum_s  # type: ignore[attr-defined]
    return TaskFailure(422, [problem])


def _path_loc(path: str) -> list[str | int]:
    """'formations[2].transition_s' -> ['formations', 2, 'transition_s']."""
    out: list[str | int] = []
    for part in path.replace("[", ".[").split("."):
        if not part:
            continue
        out.append(int(part[1:-1]) if part.startswith("[") and part[1:-1].isdigit() else part)
    return out


def plan_summary(plan: Any) -> dict[str, Any]:
    """The plan's timeline: duration and every segment (kind, label, start, duration)."""
    return {
        "drones": plan.drone_count,
        "duration_s": plan.duration_s,
        "segments": [
            {"index": s.index, "kind": s.kind, "label": s.label, "start_s": s.start_s, "duration_s": s.duration_s}
            for s in plan.segments
        ],
    }


def check_task(show_text: str) -> dict[str, Any]:
    """Plan a show (forced durations flown as asked) and verify it exactly.

    Returns:
        ``{"plan": plan summary, "report": CheckReport JSON}``.
    """
    from sim import PlanError, check_plan, plan_show

    show = _show(show_text)
    try:
        plan = plan_show(show, enforce_limits=False)
    except PlanError as exc:
        raise _plan_failure(exc) from None
    report = check_plan(plan).to_json()
    _add_violation_points(plan, len(show.formations), report)
    return {"plan": plan_summary(plan), "report": report}


def _add_violation_points(plan: Any, formations: int, report: dict[str, Any]) -> None:
    """Give each violation ``points``: where its drones go in the formation of its segment (the
    editor selects them). Takeoff counts as the first formation, landing as the last."""
    into = sorted(plan.transitions, key=lambda t: t.segment)[:formations]  # one per formation, in order
    if not into:
        return
    grouped = [v for g in report.get("by_transition", []) for v in g.get("violations", [])]
    for v in [*report.get("violations", []), *grouped]:
        info = into[0]
        for t in into:
            if t.segment <= v["segment"]:
                info = t
        v["points"] = [int(info.goal_index[d]) for d in v["drones"]]


def simulate_task(show_text: str, options: dict[str, Any], job_id: str, queue: Any, cancel: Any) -> dict[str, Any]:
    """Plan a show and fly it in simulation, reporting progress; returns the flight summary.

    Raises:
        TaskCancelled: the job was cancelled.
        TaskFailure: the show cannot be planned, or the simulation is not available.
    """
    progress = Progress(job_id, queue, cancel)
    progress.started()
    from sim import PlanError, plan_show

    show = _show(show_text)
    try:
        plan = plan_show(show, progress=progress.scaled(0.0, PLAN_SHARE))
    except PlanError as exc:
        raise _plan_failure(exc) from None
    progress.check_cancelled(force=True)
    fly_show = _fly_show()
    try:
        result = fly_show(plan, **_flight_options(options), progress=progress.scaled(PLAN_SHARE, 1.0))
    except TaskCancelled:
        raise
    except ConnectionError as exc:
        # The Dask scheduler of SWARMSHOW_DASK_SCHEDULER is down or has no worker.
        progress.check_cancelled(force=True)
        raise TaskFailure(503, f"simulation cluster unavailable: {exc}") from None
    except ValueError as exc:
        # A wrapped cancellation still counts as one; anything else is a bad option.
        progress.check_cancelled(force=True)
        raise TaskFailure(422, [{"loc": ["body"], "path": "", "msg": str(exc)}]) from None
    except Exception:
        progress.check_cancelled(force=True)
        raise
    progress(1.0)
    return {"plan": plan_summary(plan), "flight": result.summary()}


def _flight_options(options: dict[str, Any]) -> dict[str, Any]:
    """``options`` with the Dask engine swapped in for the local one when the server has a scheduler.

    The setting is read here, in the worker process (which inherits the server's
    environment), so that ``SWARMSHOW_DASK_SCHEDULER`` switches every simulation job;
    an explicit ``numpy`` (reference) engine is left alone.
    """
    from app.settings import AppSettings

    scheduler = (AppSettings().dask_scheduler or "").strip()
    if not scheduler or options.get("engine", "numba") not in ("numba", "local"):
        return dict(options)
    return {**options, "engine": "dask", "scheduler": scheduler}


def _fly_show() -> Any:
    """``fly_show`` from wherever the simulation package exposes it."""
    import importlib

    for name in ("sim", "sim.flight", "sim.flight._runner"):
        try:
            fn = getattr(importlib.import_module(name), "fly_show", None)
        except ImportError:
            continue
        if fn is not None:
            return fn
    raise TaskFailure(501, "flight simulation is not available in this installation")


def formation_task(source: str, params: dict[str, Any], data: bytes | None = None) -> dict[str, Any]:
    """Build formation points from a shape, text, image or SVG.

    Returns:
        ``PointSet.to_json()`` (points, colors, min_spacing_m) plus ``count``.

    Raises:
        TaskFailure: 413 for an oversized image or SVG, 422 when the points cannot be built
            (``max_n`` says how many would fit, when known).
    """
    from formations import sources
    from formations._points import FormationError, InputTooLargeError

    try:
        if source == "shape":
            p = dict(params)
            kind, n = p.pop("kind"), p.pop("n")
            extra = p.pop("params", None) or {}
            points = sources.generate_shape(kind, n, **p, **extra)
        elif source == "text":
            p = dict(params)
            points = sources.text_points(p.pop("text"), p.pop("n"), **p)
        elif source == "image":
            p = dict(params)
            points = sources.image_points(data or b"", p.pop("n"), **p)
        elif source == "svg":
            p = dict(params)
            points = sources.svg_points(data or b"", p.pop("n"), **p)
        else:
            raise TaskFailure(404, f"unknown formation source {source!r}")
    except InputTooLargeError as exc:
        raise TaskFailure(413, str(exc)) from None
    except FormationError as exc:
        problem: dict[str, Any] = {"loc": ["body"], "path": "", "msg": str(exc)}
        if getattr(exc, "max_n", None) is not None:
            problem["max_n"] = exc.max_n
        raise TaskFailure(422, [problem]) from None
    out = points.to_json()
    out["count"] = len(out["points"])
    return out


def export_task(show_text: str, fmt: str, options: dict[str, Any]) -> dict[str, Any]:
    """Export a show with :func:`app.exports.export_show`.

    Returns:
        ``{"filename", "media_type", "content" (bytes), "warnings"}``.
    """
    from app import exports

    show = _show(show_text)
    try:
        res = exports.export_show(show, fmt, **options)
    except exports.ExportError as exc:
        raise TaskFailure(422, [{"loc": ["query"], "path": "", "msg": str(exc)}]) from None
    except Exception as exc:
        from sim import PlanError

        if isinstance(exc, PlanError):
            raise _plan_failure(exc) from None
        raise
    return {
        "filename": res.filename,
        "media_type": res.media_type,
        "content": bytes(res.content),
        "warnings": list(res.warnings or []),
    }
