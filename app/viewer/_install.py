"""Wire the viewer into the app: lifespan start/stop, the relay routes and ``POST /api/shows/{id}/playback``.

:func:`install` is the ``app.viewer`` extension run by ``create_app`` (see
``app.server._app.EXTENSIONS``): it adds the routes and appends a startup
hook (a :class:`Viewer` on a free loopback port, stored as
``app.state.viewer``) and a shutdown hook (stops it) to the app's lifespan.
"""

from __future__ import annotations

import asyncio
import functools
import logging
import threading
from typing import Any, Literal

from fastapi import APIRouter, Body, FastAPI, Request
from pydantic import BaseModel, ConfigDict, Field, field_validator

from app.api.models import Problem
from app.viewer._clock import clock_router
from app.viewer._marks import check_report_json
from app.viewer._relay import viewer_router
from app.viewer._viewer import MAX_SHOWS, Viewer
from formations import DroneGroups, Lights, check_group_names, groups_problem, lights_problem

Source = Literal["planned", "simulated"]
log = logging.getLogger("swarmshow.viewer")


class PlaybackRequest(BaseModel):
    """Body of ``POST /api/shows/{id}/playback``."""

    model_config = ConfigDict(extra="forbid")
    source: Source = "planned"
    job_id: str | None = Field(None, max_length=64, description=(
        "With source 'simulated': a simulation job of this show (POST /api/shows/{id}/simulate), whose flight "
        "(its preset and seed) is played, or a Monte-Carlo job (POST /api/shows/{id}/montecarlo) whose run "
        "`run` is; without it the default single flight (default preset, seed 0) plays."))
    run: int | None = Field(None, ge=0, description=(
        "With a Monte-Carlo `job_id`: the run to play (0-based; seed = seed0 + run)."))


class SeekRequest(BaseModel):
    """Body of ``POST /api/viewer/{token}/seek``: a time, or a formation whose hold to jump to."""

    model_config = ConfigDict(extra="forbid")
    time_s: float | None = Field(None, ge=0, le=1e6, description="Show time, seconds (clamped to the show).")
    formation: int | None = Field(None, ge=0, le=100_000, description="Jump to the start of this formation's hold.")


class LightsRequest(BaseModel):
    """Body of ``POST /api/viewer/{token}/lights``: the editor's current (unsaved) light design."""

    model_config = ConfigDict(extra="forbid")
    lights: Lights | None = Field(None, description="Groups and effect stack as in the show file (None: no effects).")
    groups: DroneGroups | None = Field(None, description="The show's drone groups (its top-level 'groups'), which "
                                       "group targets resolve as well as lights.groups.")

    @field_validator("groups")
    @classmethod
    def _groups_ok(cls, value: dict[str, list[int]] | None) -> dict[str, list[int]] | None:
        return None if value is None else check_group_names(value)


class LightsOut(BaseModel):
    """What that browser's playback now paints."""

    show: str | None
    effects: int = Field(description="Effects painted (enabled, with some opacity).")
    revision: int = Field(description="How many effect stacks this playback has been given.")


class SeekOut(BaseModel):
    """Where that browser's playback now is."""

    time_s: float
    show: str | None


class PlaybackOut(BaseModel):
    """What the viewer now shows."""

    show_id: str
    revision: int
    name: str
    source: Source
    drones: int
    duration_s: float
    viewer_url: str
    cached: bool
    problems: list[Problem] = Field(default_factory=list, description=(
        "What makes the show unflyable as designed although it plays (a transition forced shorter than the "
        "limits allow, named as the exports' 422 names it); the viewer draws the check's violations in red."))


def _label(record: Any) -> str:
    """Registry name of a stored show: its name and id (names need not be unique)."""
    return f"{record.name} [{record.id[:8]}]"


class _Loader:
    """Plans (and flies) stored shows for the viewer, remembering the last result per show revision."""

    def __init__(self, app: FastAPI, viewer: Viewer) -> None:
        self.app, self.viewer = app, viewer
        self._lock = threading.Lock()
        # (show id) -> ((content hash, (job id, Monte-Carlo run or None) or None), plan, flight or None)
        self._cache: dict[str, tuple[tuple[str, tuple[str, int | None] | None], Any, Any]] = {}
        # (content hash) -> check report JSON of its plan
        self._reports: dict[str, Any] = {}

    def load(
        self, show_id: str, source: Source = "planned", run: tuple[str, int | None] | None = None
    ) -> tuple[Any, Any, bool]:
        """Plan (and for ``simulated`` fly) the stored show and put it in the viewer.

        Called from a thread; the planning and the flight run in the job manager's interactive pool
        under its time budget, never in the server process. ``run`` = ``(job id, k)`` flies run k of
        a Monte-Carlo job of this show instead of the default single flight; ``(job id, None)`` flies
        the flight of a simulation job of this show (its preset and seed).

        Returns:
            ``(record, plan, cached)``.
        """
        from app import tasks

        jobs = self.app.state.jobs
        record = self.app.state.store.get(show_id)
        label = _label(record)
        job_kind, run_options = (self._run_options(record, run) if run is not None and source == "simulated"
                                 else ("", None))
        # The cached flight is the one of this content and this run (None: the default flight).
        key = (record.content_hash, None if run_options is None else run)
        with self._lock:
            hit = self._cache.get(show_id)
            plan, flight = (hit[1], hit[2]) if hit and hit[0] == key else (None, None)
            if hit and hit[0][0] == record.content_hash and plan is None:
                plan = hit[1]  # same show, another flight: the plan still holds
        cached = plan is not None and (source == "planned" or flight is not None)
        viewer = self.viewer
        try:
            if run_options is not None and flight is None and job_kind == "simulate":
                viewer.set_busy(f"Simulating {record.name} ({run_options.get('preset')}, seed "
                                f"{run_options.get('seed', 0)})", 0.0)
                options = tasks.flight_options(run_options, jobs.settings.dask_scheduler)
                plan, flight = jobs.run_sync(tasks.viewer_flight_task, record.json, options)
            elif run_options is not None and flight is None:
                assert run is not None and run[1] is not None
                viewer.set_busy(f"Flying run {run[1]} of {record.name}", 0.0)
                plan, flight = jobs.run_sync(tasks.viewer_montecarlo_run_task, record.json, run_options, run[1])
            elif source == "simulated" and flight is None:
                viewer.set_busy(f"Simulating {record.name}", 0.0)
                options = tasks.flight_options({}, jobs.settings.dask_scheduler)
                # Interactive pool and budget: a request waits for it (a long show answers 504, the job
                # API flies it without a time budget).
                plan, flight = jobs.run_sync(tasks.viewer_flight_task, record.json, options)
            elif plan is None:
                viewer.set_busy(f"Planning {record.name}", 0.0)
                plan = jobs.run_sync(tasks.viewer_plan_task, record.json)
        finally:
            viewer.set_busy(None)
        with self._lock:
            self._cache.pop(show_id, None)
            self._cache[show_id] = (key, plan, flight)
            while len(self._cache) > MAX_SHOWS:
                del self._cache[next(iter(self._cache))]
        report = self._reports.get(record.content_hash)
        viewer.load(plan, name=label, flight=flight, source=source, report=report,
                    lights=_lights(record.json, plan))
        if report is None:
            # The exact check runs in a worker after the show is on screen; its violations appear when it is done.
            threading.Thread(target=self._check, args=(record.content_hash, label, plan), daemon=True,
                             name="viewer-check").start()
        return record, plan, cached

    def _check(self, content_hash: str, label: str, plan: Any) -> None:
        try:
            report = self.app.state.jobs.run_sync(check_report_json, plan)
        except Exception as exc:  # the show still plays, only without its violations drawn
            log.warning("viewer: cannot check %s: %s", label, exc)
            return
        with self._lock:
            self._reports[content_hash] = report
            while len(self._reports) > MAX_SHOWS:
                del self._reports[next(iter(self._reports))]
        self.viewer.set_report(label, report)

    def _run_options(self, record: Any, run: tuple[str, int | None]) -> tuple[str, dict[str, Any]]:
        """The kind and options of a simulation or Monte-Carlo job of ``record``'s show, checked for
        playing its flight (``run[1]`` None) or run ``run[1]``.

        Raises:
            JobNotFound: no such job (404).
            ApiError: 422 naming ``job_id`` (not a simulation or Monte-Carlo job of this show) or ``run``
                (out of range, missing for a Monte-Carlo job, or given for a simulation's one flight).
        """
        from app.api.errors import ApiError

        job = self.app.state.jobs.get(run[0])
        if job.kind not in ("simulate", "montecarlo") or job.content_hash != record.content_hash:
            raise ApiError(422, [{"loc": ["body", "job_id"], "path": "job_id", "msg": (
                f"job {run[0]!r} is not a simulation or Monte-Carlo job of this show as it is now")}])
        if job.kind == "simulate":
            if run[1] is not None:
                raise ApiError(422, [{"loc": ["body", "run"], "path": "run", "msg": (
                    "a simulation job flew one flight: leave run out (run picks a Monte-Carlo job's run)")}])
            return job.kind, dict(job.options)
        runs = int(job.options.get("runs", 0))
        if run[1] is None or not 0 <= run[1] < runs:
            raise ApiError(422, [{"loc": ["body", "run"], "path": "run",
                                  "msg": f"run must be in 0..{runs - 1} (the job flew {runs} runs)"}])
        return job.kind, dict(job.options)

    def catalog(self) -> dict[str, str]:
        """``{show id: label}`` of the stored shows (the selector's list); drafts cannot be planned, so
        they are left out."""
        records, _ = self.app.state.store.list(limit=200)
        return {r.id: _label(r) for r in records if not r.draft}


def _lights(show_json: Any, plan: Any) -> Any:
    """The stored show's light effects over its plan (issue 18), or None when it has none."""
    from formations import parse_show
    from sim.light import LightStack

    stack = LightStack.from_show(parse_show(show_json), plan)
    return stack if stack else None


def _viewer_page(request: Request, token: str) -> Any:
    """The playback of the viewer page carrying ``token``, or a 404.

    With the viewer switched off there is no viewer page at all, so the answer is the same 404 as
    for an unknown token (not a 503: nothing is wrong with the server, the page does not exist)."""
    from app.api.errors import ApiError

    viewer: Viewer | None = getattr(request.app.state, "viewer", None)
    pb = None if viewer is None else viewer.playback_by_token(token[:64])
    if pb is None:
        raise ApiError(404, "no viewer page with this token (open or reload the 3D preview)")
    return pb


def playback_router() -> APIRouter:
    """``POST /shows/{show_id}/playback`` (include with prefix ``/api``)."""
    from app import tasks
    from app.api.models import error_responses

    router = APIRouter(tags=["viewer"])

    @router.post(
        "/shows/{show_id}/playback",
        response_model=PlaybackOut,
        summary="Show a show in the 3D viewer",
        responses=error_responses(404, 422, 503),
    )
    async def playback(
        request: Request, show_id: str, body: PlaybackRequest | None = Body(None)  # noqa: B008
    ) -> PlaybackOut:
        """Plan the stored show (and for ``simulated`` fly it) off the event loop and load it into the
        3D viewer at ``/viser/``; every connected browser sees it. Progress shows in the viewer."""
        from app.api.errors import ApiError, require_valid

        loader: _Loader | None = getattr(request.app.state, "viewer_loader", None)
        if loader is None:
            raise ApiError(503, "the 3D viewer is not running")
        require_valid(request.app.state.store.get(show_id), "shown in the 3D viewer")  # a draft: 422
        req = body or PlaybackRequest()
        source: Source = req.source
        run: tuple[str, int | None] | None = None
        if req.job_id is not None or req.run is not None:
            if source != "simulated" or req.job_id is None:
                field = "job_id" if req.job_id is None else "source"
                raise ApiError(422, [{"loc": ["body", field], "path": field,
                                      "msg": "job_id (and run, for a Monte-Carlo job) go with source 'simulated'"}])
            run = (req.job_id, req.run)
        # TaskFailure / TaskError raised by the load reach the app's handlers (422, 413, 504, ...).
        record, plan, cached = await asyncio.to_thread(loader.load, show_id, source, run)
        return PlaybackOut(
            show_id=record.id, revision=record.revision, name=record.name, source=source,
            drones=plan.drone_count, duration_s=plan.duration_s, viewer_url="/viser/", cached=cached,
            problems=[Problem(**p) for p in tasks.forced_problems(plan)],
        )

    @router.post(
        "/viewer/{token}/seek",
        response_model=SeekOut,
        summary="Move one browser's 3D playback (the editor's shared playhead)",
        responses=error_responses(404, 422),
    )
    async def seek(request: Request, token: str, body: SeekRequest) -> SeekOut:
        """Seek the playback of the viewer page carrying ``token`` (the editor reads it from its preview
        pane): to ``time_s``, or to the start of ``formation``'s hold. Other browsers are not touched."""
        from app.api.errors import ApiError

        pb = _viewer_page(request, token)
        if (body.time_s is None) == (body.formation is None):
            raise ApiError(422, "give exactly one of time_s and formation", field="body")
        if body.formation is not None:
            if pb.seek_formation(body.formation) is None:
                raise ApiError(422, f"formation {body.formation} is not in the show on screen", field="formation")
        else:
            pb.seek(float(body.time_s or 0.0))
        return SeekOut(time_s=pb.time_s, show=pb.current)

    @router.post(
        "/viewer/{token}/lights",
        response_model=LightsOut,
        summary="Preview an unsaved light design in one browser's 3D playback",
        responses=error_responses(404, 413, 422),
    )
    async def preview_lights(request: Request, token: str, body: LightsRequest) -> LightsOut:
        """Paint ``lights`` over the show on screen in the viewer page carrying ``token``, instead of the saved
        effects, until the show is loaded again (issue 18: effects previewed live in the 3D view while editing).
        The design is checked against the plan on screen like a show file's (422 naming the field under
        ``lights``); its size is the show file's limits (effects, images, videos), so its cost is bounded."""
        from app.api.errors import ApiError
        from sim.light import LightStack

        pb = _viewer_page(request, token)
        plan = pb.plan()
        if plan is None:
            raise ApiError(422, "no show on screen in this viewer page (open the preview first)", field="token")
        lights = body.lights
        if lights is not None:
            names = [seg.label for _, seg in plan.formation_segments()]
            if body.groups is not None:
                problem = groups_problem(body.groups, plan.drone_count)
                if problem is not None:
                    path = ".".join(str(p) for p in ("groups", *problem[0]))
                    raise ApiError(422, [{"loc": ["body", "groups", *problem[0]], "path": path, "msg": problem[1]}])
            problem = lights_problem(lights, plan.drone_count, names, show_groups=body.groups)
            if problem is not None:
                path = ".".join(f"[{p}]" if isinstance(p, int) else str(p) for p in ("lights", *problem[0]))
                raise ApiError(422, [{"loc": ["body", "lights", *problem[0]], "path": path.replace(".[", "["),
                                      "msg": problem[1]}])
        # Decoding images and videos is real work: off the event loop.
        stack = await asyncio.to_thread(LightStack, lights, plan, body.groups) if lights is not None else None
        if not pb.set_lights(plan, stack):
            raise ApiError(409, "the show on screen changed meanwhile; send the effects again")
        return LightsOut(show=pb.current, effects=stack.effect_count if stack else 0, revision=pb.lights_rev)

    return router


async def _start(app: FastAPI) -> None:
    settings = getattr(app.state, "settings", None)
    if settings is not None and not settings.viewer:
        return  # switched off (tests that restart the server often): /viser closes with 1013, playback is 503
    # One playback per browser: a tab opening or scrubbing a show leaves the other tabs alone.
    viewer = await asyncio.to_thread(functools.partial(Viewer, per_client=True))
    loader = _Loader(app, viewer)
    app.state.viewer, app.state.viewer_loader = viewer, loader

    def load_from_selector(show_id: str) -> None:
        try:
            loader.load(show_id, "planned")
        except Exception as exc:  # a browser's pick must not kill the worker thread silently
            log.warning("viewer: cannot load show %s: %s", show_id, exc)

    viewer.set_catalog(loader.catalog, load_from_selector)


async def _stop(app: FastAPI) -> None:
    viewer: Viewer | None = getattr(app.state, "viewer", None)
    if viewer is not None:
        await asyncio.to_thread(viewer.stop)
        app.state.viewer = app.state.viewer_loader = None


def install(app: FastAPI) -> None:
    """Add the viewer to an app made by ``create_app``: routes now, the viser server in the lifespan."""
    app.include_router(viewer_router(None))
    app.include_router(playback_router(), prefix="/api")
    app.include_router(clock_router(), prefix="/api")  # issue 18: the editor's music follows the 3D view
    app.state.startup.append(_start)
    app.state.shutdown.append(_stop)


#: Alias matching the brief's name.
install_viewer = install

__all__ = [
    "LightsOut", "LightsRequest", "PlaybackOut", "PlaybackRequest", "SeekOut", "SeekRequest", "install",
    "install_viewer", "playback_router",
]
