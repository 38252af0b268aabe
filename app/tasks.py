"""CPU-heavy work run in the worker processes (planning, checking, flying, sampling, exporting).

Every function here is top level (picklable by name) and takes plain data: the
show as its JSON text, options as dicts. Known failures are raised as
:class:`TaskFailure` (a :class:`FailureKind` + detail; the API maps kinds to HTTP
statuses), because library exceptions with keyword arguments (``PlanError.path``,
``FormationError.max_n``) lose them when pickled back to the server process.
Nothing here reads the environment: what the server's settings decide (the Dask
scheduler, time budgets) arrives as arguments.

Long tasks report progress through a queue shared with the server and stop at
their next progress report once their cancel event is set. Interactive tasks run
under :func:`budgeted`: a timer interrupts them when their time budget is spent or
their client has gone.
"""

from __future__ import annotations

import json
import logging
import os
import signal
import time
from collections.abc import Iterator
from contextlib import contextmanager
from enum import StrEnum
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from app.store import ShowData

#: Fraction of a simulation job spent planning (the flight is the rest).
PLAN_SHARE = 0.05
#: Most trajectory samples (drones x recorded frames) a simulation may keep: 20 M samples are about
#: 1 GB of positions, colours and errors in the worker (``output_hz=1000`` on a 1,000-drone 10-minute
#: show asked for 600 M and was killed at 3 GB).
MAX_OUTPUT_SAMPLES = 20_000_000
#: Most drone-seconds the 3D viewer flies inside one request (the numba engine does about 18,000 per
#: second on an idle core at 1 kHz, so this stays well inside the interactive time budget).
MAX_VIEWER_FLIGHT_DRONE_S = 300_000
#: Most drone-seconds of flight one Monte-Carlo job may ask for (drones x show seconds x runs): a
#: 1,000-drone 10-minute show 20 times is 1.2e7 (benchmarks/bench_montecarlo.py times it).
MAX_MONTECARLO_DRONE_S = 30_000_000
#: Seconds between two looks of :func:`budgeted` at the clock and the cancel flag.
BUDGET_TICK_S = 0.05


class FailureKind(StrEnum):
    """Why a task refused its input; the API maps each to an HTTP status."""

    INVALID = "invalid"  # 422: the input (a show, an option) breaks a rule
    TOO_LARGE = "too_large"  # 413: the input, or the work it implies, is over a limit
    UNAVAILABLE = "unavailable"  # 503: a service the task needs (the Dask cluster) is down
    NOT_FOUND = "not_found"  # 404: no such source or format
    NOT_IMPLEMENTED = "not_implemented"  # 501: not in this installation


class TaskFailure(Exception):
    """A task failed for a reason the client should see: ``kind`` and ``detail`` (JSON-safe)."""

    def __init__(self, kind: FailureKind | str, detail: Any) -> None:
        super().__init__(str(FailureKind(kind)), detail)

    @property
    def kind(self) -> FailureKind:
        """What went wrong (see :class:`FailureKind`)."""
        return FailureKind(self.args[0])

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


class TaskTimeout(Exception):
    """Raised inside a task by :func:`budgeted` when its time budget is spent."""

    def __init__(self, budget_s: float) -> None:
        super().__init__(budget_s)
        self.budget_s = budget_s

    def __str__(self) -> str:
        return f"took longer than its time budget of {self.budget_s:g} s"


#: Cancel flags of the interactive pool's task slots (shared memory, set by the server), or None.
_FLAGS: Any = None
#: When each slot's task started (``time.monotonic()``, system-wide on Linux; 0: not running), or None.
_STARTS: Any = None


def interactive_init(flags: Any, starts: Any = None, memory_bytes: int | None = None) -> None:
    """Initializer of the interactive pool's workers: end with the server, keep the cancel flags.

    They run at normal CPU priority, above the batch workers (:data:`WORKER_NICE`), so that a check
    or a formation never waits behind simulations for the CPU.
    """
    global _FLAGS, _STARTS
    die_with_parent()
    limit_memory(memory_bytes)
    _FLAGS, _STARTS = flags, starts


def budgeted(slot: int, budget_s: float, fn: Any, *args: Any) -> Any:
    """Run ``fn(*args)``, raising :class:`TaskTimeout` once ``budget_s`` is spent and
    :class:`TaskCancelled` once the server sets cancel flag ``slot`` (its client has gone).

    A ``SIGALRM`` interval timer looks every :data:`BUDGET_TICK_S`; Python raises from the handler in
    the task's own thread at its next bytecode, so pure-Python and numpy-level loops stop within a
    tick. A single C call that never returns is ended by the server killing the worker (the
    hard deadline in :class:`app.jobs.JobManager`).
    """
    started = time.monotonic()
    deadline = started + budget_s
    if _FLAGS is not None and 0 <= slot < len(_FLAGS) and _FLAGS[slot]:
        raise TaskCancelled(f"slot {slot}")  # its client left while it waited in the queue
    if _STARTS is not None and 0 <= slot < len(_STARTS):
        _STARTS[slot] = started

    def tick(_signum: int, _frame: Any) -> None:
        if _FLAGS is not None and 0 <= slot < len(_FLAGS) and _FLAGS[slot]:
            raise TaskCancelled(f"slot {slot}")
        if time.monotonic() > deadline:
            raise TaskTimeout(budget_s)

    previous = signal.signal(signal.SIGALRM, tick)
    signal.setitimer(signal.ITIMER_REAL, BUDGET_TICK_S, BUDGET_TICK_S)
    try:
        return fn(*args)
    except MemoryError:
        raise TaskFailure(FailureKind.TOO_LARGE, "the request needs more memory than a worker may use "
                          "(SWARMSHOW_WORKER_MEMORY_MB)") from None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0, 0.0)
        signal.signal(signal.SIGALRM, previous)
        if _STARTS is not None and 0 <= slot < len(_STARTS):
            _STARTS[slot] = 0.0


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

    def note(self, text: str) -> None:
        """Tell the server a one-line note for the job's status (``JobOut.note``)."""
        self._queue.put((self.job_id, "note", str(text)))

    def scaled(self, start: float, stop: float) -> Any:
        """A callback mapping [0, 1] onto [start, stop] of this job."""
        return lambda f: self(start + (stop - start) * float(f))


class _NoteHandler(logging.Handler):
    """Passes the ``sim`` packages' warnings to the job (the flight kernel's cold-cache compile note)."""

    def __init__(self, progress: Progress) -> None:
        super().__init__(logging.WARNING)
        self._progress = progress

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self._progress.note(record.getMessage())
        except Exception:  # logging's contract: a failing handler must not raise
            self.handleError(record)


@contextmanager
def library_notes(progress: Progress) -> Iterator[None]:
    """While a task runs, the ``sim`` packages' warnings become its job's note: a first flight on a
    cold numba cache compiles the flight kernel for minutes, and the job says so instead of sitting
    silent (``sim.flight.engines._numba.COMPILE_NOTE``)."""
    handler = _NoteHandler(progress)
    logger = logging.getLogger("sim")
    logger.addHandler(handler)
    try:
        yield
    finally:
        logger.removeHandler(handler)


#: Scheduling niceness of the worker processes: jobs are batch work, and the event loop's requests
#: (each a millisecond or two) must not wait behind a simulation that keeps every core busy.
WORKER_NICE = 10


def limit_memory(memory_bytes: int | None) -> None:
    """Cap this process's data (heap and private mappings, ``RLIMIT_DATA``): an allocation past it
    raises ``MemoryError`` in the task instead of the kernel's OOM killer ending the process, or the
    machine swapping."""
    if not memory_bytes:
        return
    try:
        import resource

        # The soft limit only: a child that must exceed it (numba compiling the flight kernel on a cold
        # cache, sim.flight.engines._numba) lifts its own soft limit to the hard one.
        _, hard = resource.getrlimit(resource.RLIMIT_DATA)
        resource.setrlimit(resource.RLIMIT_DATA, (memory_bytes, hard))
    except (ImportError, ValueError, OSError):  # not on this platform, or above the hard limit
        pass


def worker_init(memory_bytes: int | None = None) -> None:
    """Run once in each worker process: end with the server, cap its memory, run at a lower CPU priority."""
    die_with_parent()
    limit_memory(memory_bytes)
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


def validate_task(data: bytes | dict[str, Any], draft: bool = False) -> dict[str, Any]:
    """Validate a show file; returns the fields of :class:`app.store.ShowData`.

    Large show files are validated here, in a worker, so that seconds of parsing
    never hold the server's GIL. With ``draft``, a show that is a JSON object but
    breaks the rules is returned as a draft (``problems`` lists what is wrong)
    instead of refused.

    Raises:
        TaskFailure: 422 with ``ShowValidationError.errors``.
    """

    d = validate_show_data(data, draft=draft)
    return {"text": d.text, "content_hash": d.content_hash, "name": d.name, "drones": d.drones,
            "formations": d.formations, "problems": d.problems}


def validate_show_data(data: bytes | dict[str, Any], *, draft: bool = False) -> ShowData:
    """:func:`validate_task`'s work, as :class:`app.store.ShowData` (also called in a thread)."""
    from app.store import ShowData
    from formations import ShowValidationError, parse_show

    try:
        return ShowData.of(parse_show(data))
    except ShowValidationError as exc:
        doc: Any = data
        if isinstance(data, bytes | bytearray):
            try:
                doc = json.loads(bytes(data).decode("utf-8"))
            except (UnicodeDecodeError, ValueError, RecursionError):
                # Not even JSON text: nothing a draft could keep, no formation to name.
                raise TaskFailure(FailureKind.INVALID, _worded(exc.errors, None)) from None
        if not draft:
            raise TaskFailure(FailureKind.INVALID, _worded(exc.errors, doc)) from None
        if not isinstance(doc, dict):
            raise TaskFailure(FailureKind.INVALID, [{"loc": [], "path": "", "msg": "a draft must be a JSON "
                                                     "object (a show file, however unfinished)"}]) from None
        return ShowData.draft(doc, exc.errors)


def _worded(errors: list[dict[str, Any]], doc: Any) -> list[dict[str, Any]]:
    """``ShowValidationError.errors``, each also saying where in plain words (``formations.plain_words``; the
    formations named from ``doc``, the document as sent)."""
    from formations import plain_words

    return [{**e, **plain_words(e.get("path") or "", doc)} for e in errors]


def _plan_failure(exc: Exception, show: Any = None) -> TaskFailure:
    """A plan's refusal as the 422 problem naming its field, in plain words too (``show``: the parsed show, so
    that its formations are named)."""
    from formations import plain_words

    path = getattr(exc, "path", "") or ""
    problem: dict[str, Any] = {"loc": ["show", *path_loc(path)], "path": path, "msg": str(exc),
                               **plain_words(path, show)}
    if getattr(exc, "minimum_s", None) is not None:
        problem["minimum_s"] = exc.minimum_s  # type: ignore[attr-defined]
    if getattr(exc, "earliest_s", None) is not None:
        problem["earliest_s"] = exc.earliest_s  # type: ignore[attr-defined]  # an infeasible cue time (issue 18)
    return TaskFailure(FailureKind.INVALID, [problem])


def forced_problems(plan: Any) -> list[dict[str, Any]]:
    """The transitions ``plan`` flies shorter than the limits allow (``ShowPlan.forced``), as the 422 problems
    that the exports give for them (``loc``, ``path``, ``msg``, ``minimum_s``, and ``where`` in plain words):
    what the 3D preview and a simulation say about a show they play as designed."""
    from formations import plain_words

    names = {"formations": [{"name": name} for name, _ in plan.formation_segments()]}
    return [{"loc": ["show", *path_loc(f.path)], "path": f.path, "msg": f.message, "minimum_s": f.minimum_s,
             **plain_words(f.path, names)} for f in getattr(plan, "forced", ())]


def path_loc(path: str) -> list[str | int]:
    """'formations[2].transition_s' -> ['formations', 2, 'transition_s'] (inverse of ``app.api.errors.loc_path``)."""
    out: list[str | int] = []
    for part in path.replace("[", ".[").split("."):
        if not part:
            continue
        out.append(int(part[1:-1]) if part.startswith("[") and part[1:-1].isdigit() else part)
    return out


def plan_summary(plan: Any) -> dict[str, Any]:
    """The plan's timeline: duration and every segment (kind, label, start, duration), and its assignment:
    for each formation in show order, the point each drone flies to (the editor's light preview places
    drone i on point ``assignment[k][i]`` of formation k, as the server's evaluator does)."""
    return {
        "drones": plan.drone_count,
        "duration_s": plan.duration_s,
        "segments": [
            {"index": s.index, "kind": s.kind, "label": s.label, "start_s": s.start_s, "duration_s": s.duration_s}
            for s in plan.segments
        ],
        "assignment": [tr.goal_index.tolist() for tr in plan.transitions[: len(plan.formation_segments())]],
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
        raise _plan_failure(exc, show) from None
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

    ``options`` are ``fly_show``'s keyword arguments as the server resolved them (see
    :func:`flight_options`).

    Raises:
        TaskCancelled: the job was cancelled.
        TaskFailure: the show cannot be planned, its recording would be too large, or the
            simulation cluster is not available.
    """
    progress = Progress(job_id, queue, cancel)
    progress.started()
    # A what-if: a transition forced shorter than the limits allow is flown as designed (``problems``
    # says which), as the check plans it, so that the designer sees what the drones would do.
    plan = _plan_job(show_text, progress, enforce_limits=False)
    check_output_samples(plan.drone_count, plan.duration_s, float(options.get("output_hz", 25.0)))
    fly_show = _fly_show()
    flight_options = single_flight_options(options)
    try:
        with library_notes(progress):
            result = fly_show(plan, flight_options, progress=progress.scaled(PLAN_SHARE, 1.0))
    except TaskCancelled:
        raise
    except ConnectionError as exc:
        # The Dask scheduler of SWARMSHOW_DASK_SCHEDULER is down or has no worker.
        progress.check_cancelled(force=True)
        raise TaskFailure(FailureKind.UNAVAILABLE, f"simulation cluster unavailable: {exc}") from None
    except Exception:
        # A wrapped cancellation still counts as one; anything else is a failure (options were
        # validated by the API before the job started, so it is not the client's input).
        progress.check_cancelled(force=True)
        raise
    progress(1.0)
    summary = result.summary()
    # What was flown, so that the designer can fly it again (the same seed flies the same flight).
    summary["preset"], summary["seed"] = flight_options.errors.name, flight_options.seed
    summary.update(_planned_closest(plan, result.times_s))
    return {"plan": plan_summary(plan), "flight": summary, "problems": forced_problems(plan)}


def _planned_closest(plan: Any, times_s: Any) -> dict[str, Any]:
    """The plan's closest pair at the flight's frames (``sim.flight.planned_closest``), beside the flown one."""
    from sim.flight import planned_closest

    return planned_closest(plan, times_s)


def single_flight_options(options: dict[str, Any]) -> Any:
    """The ``FlightOptions`` of a single flight from the API's ``SimulateOptions`` fields (as
    :func:`flight_options` resolved them): ``sim.flight.single_flight_options`` of its preset (default
    ``sim.flight.DEFAULT_FLIGHT_PRESET``, or ideal with a fleet-wide disturbance) and seed, which is
    run ``seed - seed0`` of a Monte-Carlo job with that preset and controller.

    Raises:
        TaskFailure: a disturbance beside a preset that brings its own wind (names ``disturbance``).
    """
    from sim.flight import DEFAULT_FLIGHT_PRESET, FlightOptions
    from sim.flight import single_flight_options as resolve

    disturbance = options.get("disturbance", "none")
    preset = options.get("preset") or ("ideal" if disturbance != "none" else DEFAULT_FLIGHT_PRESET)
    kwargs = {k: options[k] for k in ("engine", "controller", "output_hz", "scheduler", "precision")
              if k in options}
    try:
        return resolve(preset, FlightOptions(**kwargs, disturbance=disturbance, seed=int(options.get("seed", 0))))
    except ValueError as exc:
        field = "disturbance" if "disturbance" in str(exc) else "preset"
        raise TaskFailure(FailureKind.INVALID, [{"loc": ["body", field], "path": field, "msg": str(exc)}]) from None


def _plan_job(show_text: str, progress: Progress, *, enforce_limits: bool = True) -> Any:
    """Plan a job's show, the first :data:`PLAN_SHARE` of its progress; a show that cannot be
    planned is a :class:`TaskFailure` (``_plan_failure``), a cancellation stops here.
    ``enforce_limits``: as in ``plan_show`` (False: a transition forced too short is flown as asked)."""
    from sim import PlanError, plan_show

    show = _show(show_text)
    try:
        plan = plan_show(show, enforce_limits=enforce_limits, progress=progress.scaled(0.0, PLAN_SHARE))
    except PlanError as exc:
        raise _plan_failure(exc, show) from None
    progress.check_cancelled(force=True)
    return plan


def montecarlo_task(
    show_text: str, options: dict[str, Any], job_id: str, queue: Any, cancel: Any
) -> dict[str, Any]:
    """Plan a show and fly it ``runs`` times (``sim.flight.monte_carlo``), reporting progress.

    ``options``: the API's ``MonteCarloOptions`` fields, plus ``engine`` and ``scheduler`` as the
    server resolved them (:func:`flight_options`).

    Returns:
        ``{"plan": plan summary, "montecarlo": MonteCarloResult JSON}`` (the safety report's input).

    Raises:
        TaskCancelled: the job was cancelled.
        TaskFailure: the show cannot be planned, the work is over :data:`MAX_MONTECARLO_DRONE_S`
            (naming ``runs``), or the simulation cluster is not available.
    """
    progress = Progress(job_id, queue, cancel)
    progress.started()
    from sim.flight import FlightOptions, monte_carlo, options_for_preset

    plan = _plan_job(show_text, progress)
    runs = int(options["runs"])
    check_output_samples(plan.drone_count, plan.duration_s, 25.0)
    work = plan.drone_count * plan.duration_s * runs
    if work > MAX_MONTECARLO_DRONE_S:
        most = max(int(MAX_MONTECARLO_DRONE_S // max(plan.drone_count * plan.duration_s, 1e-9)), 0)
        raise TaskFailure(FailureKind.TOO_LARGE, [{
            "loc": ["body", "runs"], "path": "runs",
            "msg": f"{plan.drone_count} drones x {plan.duration_s:g} s x {runs} runs = {work:.3g} drone-seconds "
                   f"exceeds the limit of {MAX_MONTECARLO_DRONE_S:g}; use runs <= {most}"}])
    base = FlightOptions(engine=options.get("engine", "numba"), controller=options.get("controller", "ismc"),
                         scheduler=options.get("scheduler"), precision=options.get("precision", "float64"))
    try:
        with library_notes(progress):
            result = monte_carlo(
                plan, options_for_preset(options["preset"], base), runs=runs, seed0=int(options.get("seed0", 0)),
                confidence=float(options.get("confidence", 0.99)),
                collision_distance_m=float(options.get("collision_distance_m", 1.0)), preset=options["preset"],
                progress=progress.scaled(PLAN_SHARE, 1.0),
            )
    except TaskCancelled:
        raise
    except ConnectionError as exc:
        progress.check_cancelled(force=True)
        raise TaskFailure(FailureKind.UNAVAILABLE, f"simulation cluster unavailable: {exc}") from None
    except Exception:
        progress.check_cancelled(force=True)
        raise
    progress(1.0)
    report = result.to_json()
    report["show"] = plan.show_name
    return {"plan": plan_summary(plan), "montecarlo": report}


def safety_report_task(report: dict[str, Any], fmt: str) -> bytes:
    """Render a Monte-Carlo result as the safety report (``html`` or ``pdf``), in a worker."""
    from app.exports import render_safety_report

    return render_safety_report(report, fmt)


def check_output_samples(drones: int, duration_s: float, output_hz: float) -> None:
    """Refuse a simulation whose recording would hold more than :data:`MAX_OUTPUT_SAMPLES` samples.

    Raises:
        TaskFailure: ``too_large``, naming ``output_hz`` and the limit.
    """
    frames = int(duration_s * output_hz) + 2
    if drones * frames > MAX_OUTPUT_SAMPLES:
        most_hz = max(MAX_OUTPUT_SAMPLES / drones - 2, 0) / max(duration_s, 1e-9)
        raise TaskFailure(FailureKind.TOO_LARGE, [{
            "loc": ["body", "output_hz"], "path": "output_hz",
            "msg": f"{drones} drones x {frames} frames ({duration_s:g} s at {output_hz:g} Hz) = "
                   f"{drones * frames} samples exceeds the limit of {MAX_OUTPUT_SAMPLES}; "
                   f"use output_hz <= {most_hz:.3g}"}])


def flight_options(options: dict[str, Any], dask_scheduler: str | None) -> dict[str, Any]:
    """``options`` with the Dask engine swapped in for the local one when the server has a scheduler.

    Called in the server with its settings (workers never read the environment), so that
    ``SWARMSHOW_DASK_SCHEDULER`` (or ``AppSettings(dask_scheduler=...)``) switches every
    simulation job; an explicit ``numpy`` (reference) engine is left alone.
    """
    scheduler = (dask_scheduler or "").strip()
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
    raise TaskFailure(FailureKind.NOT_IMPLEMENTED, "flight simulation is not available in this installation")


def _formation_field(source: str, exc: Exception) -> str:
    """The request field a formation source's refusal is about, when the source did not say (mesh sources
    set ``exc.field``): a count that does not fit (``max_n`` > 0) is ``n``, anything else about the input is
    the text, the shape's ``params`` or the uploaded ``file``."""
    if (getattr(exc, "max_n", None) or 0) > 0:
        return "n"
    return {"text": "text", "shape": "params"}.get(source, "file")


def formation_task(source: str, params: dict[str, Any], data: bytes | None = None) -> dict[str, Any]:
    """Build formation points from a shape, text, image, SVG or mesh / point file.

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
        elif source == "mesh":
            p = dict(params)
            points, size_m = sources.mesh_points(data or b"", p.pop("n"), **p)
        else:
            raise TaskFailure(FailureKind.NOT_FOUND, f"unknown formation source {source!r}")
    except InputTooLargeError as exc:
        raise TaskFailure(FailureKind.TOO_LARGE, str(exc)) from None
    except FormationError as exc:
        field = getattr(exc, "field", None) or _formation_field(source, exc)
        problem: dict[str, Any] = {"loc": ["body", field] if field else ["body"], "path": field or "",
                                   "msg": str(exc)}
        if getattr(exc, "max_n", None) is not None:
            problem["max_n"] = exc.max_n
        if getattr(exc, "fit_size_m", None) is not None:
            problem["fit_size_m"] = getattr(exc, "fit_size_m")  # noqa: B009 - set by MeshFitError only
        raise TaskFailure(FailureKind.INVALID, [problem]) from None
    _check_formation_result(source, points.points_m, params)
    out = points.to_json()
    out["count"] = len(out["points"])
    if source == "mesh":
        out["size_m"] = size_m
    return out


#: The request field that scales each formation source's points (what to lower when they reach too far).
_SIZE_FIELD = {"shape": "size_m", "text": "height_m", "image": "width_m", "svg": "width_m", "mesh": "size_m"}


def _check_formation_result(source: str, points_m: Any, params: dict[str, Any] | None = None) -> None:
    """Refuse a formation no show could use: non-finite points, below the ground or above the highest
    ceiling a show may have, or outside the largest show area (a 1 x 400,000 pixel image once gave
    points 8,000 km below the ground).

    The problem names the request field to change: ``center_m`` when the centre itself is outside those
    bounds, else the source's size (:data:`_SIZE_FIELD`); points that are not finite blame the input.

    Raises:
        TaskFailure: ``invalid``, naming the source, the bound and the field.
    """
    import numpy as np

    from formations._show import MAX_CEILING_M as ceiling_m
    from formations._show import MAX_HORIZONTAL_EXTENT_M
    pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
    problem = None
    if not np.isfinite(pts).all():
        problem = "some points are not finite numbers"
    elif pts.size and (pts[:, 2].min() < 0 or pts[:, 2].max() > ceiling_m):
        problem = (f"points reach altitudes {pts[:, 2].min():.4g} .. {pts[:, 2].max():.4g} m, outside "
                   f"[0, {ceiling_m:g}] m; lower the size or move the centre")
    elif pts.size and np.abs(pts[:, :2]).max() > MAX_HORIZONTAL_EXTENT_M:
        problem = (f"points reach {np.abs(pts[:, :2]).max():.4g} m from the origin, outside the largest show "
                   f"area +-{MAX_HORIZONTAL_EXTENT_M:g} m; lower the size or move the centre")
    if problem is None:
        return
    centre = np.asarray((params or {}).get("center_m") or (0.0, 0.0, 0.0), dtype=np.float64).reshape(-1)[:3]
    if not np.isfinite(pts).all():
        field = _formation_field(source, ValueError())
    elif centre.size == 3 and (not 0.0 <= centre[2] <= ceiling_m
                               or np.abs(centre[:2]).max() > MAX_HORIZONTAL_EXTENT_M):
        field = "center_m"
    else:
        field = _SIZE_FIELD.get(source, _formation_field(source, ValueError()))
    raise TaskFailure(FailureKind.INVALID, [{"loc": ["body", field], "path": field, "msg": f"{source}: {problem}"}])


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
        from sim import PlanError

        if isinstance(exc.__cause__, PlanError):  # the show cannot be planned: name its field as the check does
            raise _plan_failure(exc.__cause__, show) from None
        field = exc.field  # the query option at fault; None: the show (or the format) itself
        raise TaskFailure(FailureKind.INVALID, [{"loc": ["query", field] if field else ["query"],
                                                 "path": field or "", "msg": str(exc)}]) from None
    except Exception as exc:
        from sim import PlanError

        if isinstance(exc, PlanError):
            raise _plan_failure(exc, show) from None
        raise
    return {
        "filename": res.filename,
        "media_type": res.media_type,
        "content": bytes(res.content),
        "warnings": list(res.warnings or []),
    }


def viewer_plan_task(show_text: str) -> Any:
    """Plan a stored show for the 3D viewer (in a worker: the server process stays free of CPU work).

    As the check does: a transition forced shorter than the limits allow is flown as designed
    (``ShowPlan.forced``), so that the designer watches what the check reports, drawn by the viewer.

    Returns:
        The ``ShowPlan`` (pickled back to the server).

    Raises:
        TaskFailure: the show cannot be planned.
    """
    from sim import PlanError, plan_show

    show = _show(show_text)
    try:
        return plan_show(show, enforce_limits=False)
    except PlanError as exc:
        raise _plan_failure(exc, show) from None


def viewer_flight_task(show_text: str, options: dict[str, Any]) -> tuple[Any, Any]:
    """Plan and fly a stored show for the 3D viewer; returns ``(plan, flight)``.

    ``options``: a simulate job's (``SimulateOptions`` fields, :func:`single_flight_options`), so that the
    viewer plays the flight the job reported; ``{}`` flies the default preset with seed 0.

    Raises:
        TaskFailure: the show cannot be planned, or its recording would be too large.
    """
    plan = viewer_plan_task(show_text)
    check_output_samples(plan.drone_count, plan.duration_s, float(options.get("output_hz", 25.0)))
    _check_viewer_work(plan)
    return plan, _fly_show()(plan, single_flight_options(options))


def montecarlo_run_options(options: dict[str, Any], run: int) -> Any:
    """The ``FlightOptions`` of run ``run`` of a Monte-Carlo job with ``options`` (its API options).

    The run is flown by the local numba kernel: the same flight as on the job's engine (local or
    Dask), seed ``seed0 + run``, the job's preset and controller.
    """
    from sim.flight import FlightOptions, options_for_preset

    base = FlightOptions(controller=options.get("controller", "ismc"), seed=int(options.get("seed0", 0)) + int(run),
                         precision=options.get("precision", "float64"))
    return options_for_preset(options["preset"], base)


def viewer_montecarlo_run_task(show_text: str, options: dict[str, Any], run: int) -> tuple[Any, Any]:
    """Plan a stored show and fly run ``run`` of a Monte-Carlo job (its ``options``) for the 3D viewer.

    Returns:
        ``(plan, flight)``: the flight's ``positions_m`` are that run's flown trajectories.

    Raises:
        TaskFailure: the show cannot be planned, or its flight is over the viewer's limits.
    """
    from sim.flight import fly_show

    plan = viewer_plan_task(show_text)
    check_output_samples(plan.drone_count, plan.duration_s, 25.0)
    _check_viewer_work(plan)
    return plan, fly_show(plan, montecarlo_run_options(options, run))


def _check_viewer_work(plan: Any) -> None:
    """Refuse a flight over :data:`MAX_VIEWER_FLIGHT_DRONE_S` (a request waits for it)."""
    work = plan.drone_count * plan.duration_s
    if work > MAX_VIEWER_FLIGHT_DRONE_S:
        raise TaskFailure(FailureKind.TOO_LARGE, (
            f"{plan.drone_count} drones x {plan.duration_s:g} s = {work:.3g} drone-seconds of flight exceeds the "
            f"3D viewer's limit of {MAX_VIEWER_FLIGHT_DRONE_S} (a request waits for it); fly it as a job with "
            "POST /api/shows/{id}/simulate"))
