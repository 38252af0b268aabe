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
from pydantic import BaseModel, ConfigDict

from app.viewer._relay import viewer_router
from app.viewer._viewer import MAX_SHOWS, Viewer

Source = Literal["planned", "simulated"]
log = logging.getLogger("swarmshow.viewer")


class PlaybackRequest(BaseModel):
    """Body of ``POST /api/shows/{id}/playback``."""

    model_config = ConfigDict(extra="forbid")
    source: Source = "planned"


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


def _label(record: Any) -> str:
    """Registry name of a stored show: its name and id (names need not be unique)."""
    return f"{record.name} [{record.id[:8]}]"


class _Loader:
    """Plans (and flies) stored shows for the viewer, remembering the last result per show revision."""

    def __init__(self, app: FastAPI, viewer: Viewer) -> None:
        self.app, self.viewer = app, viewer
        self._lock = threading.Lock()
        # (show id) -> (content hash, plan, flight or None)
        self._cache: dict[str, tuple[str, Any, Any]] = {}

    def load(self, show_id: str, source: Source = "planned") -> tuple[Any, Any, bool]:
        """Plan (and for ``simulated`` fly) the stored show and put it in the viewer.

        Called from a thread; the planning and the flight run in the job manager's interactive pool
        under its time budget, never in the server process.

        Returns:
            ``(record, plan, cached)``.
        """
        from app import tasks

        jobs = self.app.state.jobs
        record = self.app.state.store.get(show_id)
        label = _label(record)
        with self._lock:
            hit = self._cache.get(show_id)
            plan, flight = (hit[1], hit[2]) if hit and hit[0] == record.content_hash else (None, None)
        cached = plan is not None and (source == "planned" or flight is not None)
        viewer = self.viewer
        try:
            if source == "simulated" and flight is None:
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
            self._cache[show_id] = (record.content_hash, plan, flight)
            while len(self._cache) > MAX_SHOWS:
                del self._cache[next(iter(self._cache))]
        viewer.load(plan, name=label, flight=flight, source=source)
        return record, plan, cached

    def catalog(self) -> dict[str, str]:
        """``{show id: label}`` of the stored shows (the selector's list); drafts cannot be planned, so
        they are left out."""
        records, _ = self.app.state.store.list(limit=200)
        return {r.id: _label(r) for r in records if not r.draft}


def playback_router() -> APIRouter:
    """``POST /shows/{show_id}/playback`` (include with prefix ``/api``)."""
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
        source: Source = (body or PlaybackRequest()).source
        # TaskFailure / TaskError raised by the load reach the app's handlers (422, 413, 504, ...).
        record, plan, cached = await asyncio.to_thread(loader.load, show_id, source)
        return PlaybackOut(
            show_id=record.id, revision=record.revision, name=record.name, source=source,
            drones=plan.drone_count, duration_s=plan.duration_s, viewer_url="/viser/", cached=cached,
        )

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
    app.state.startup.append(_start)
    app.state.shutdown.append(_stop)


#: Alias matching the brief's name.
install_viewer = install

__all__ = ["PlaybackOut", "PlaybackRequest", "install", "install_viewer", "playback_router"]
