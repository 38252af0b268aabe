"""``create_app(settings)``: the FastAPI application (REST API under ``/api``, the editor at ``/``).

Services live for the app's lifespan: the show store and the job manager (its
worker pool) start before the first request and stop after the last. Other
services plug in without touching this module's logic:

* ``app.state.startup`` / ``app.state.shutdown``: lists of callables
  ``(app) -> None`` (or awaitables), run in order after the store and the jobs
  are up, and in reverse order before they stop;
* :data:`EXTENSIONS`: modules whose ``install(app)`` runs in :func:`create_app`
  (before the editor's catch-all mount) to add routes and hooks; the 3D viewer
  (``app.viewer``) is meant to be one.
"""

from __future__ import annotations

import asyncio
import importlib
import inspect
import logging
import re
from collections.abc import AsyncIterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from fastapi import FastAPI
from fastapi.openapi.utils import get_openapi
from fastapi.responses import HTMLResponse
from fastapi.staticfiles import StaticFiles

from app.api import audio, formations, health, jobs, session, shows
from app.api.errors import install_error_handlers
from app.api.models import ShowUpdate
from app.jobs import JobManager
from app.server._auth import TokenMiddleware
from app.server._headers import SecurityHeadersMiddleware
from app.server._hosts import LoopbackHostMiddleware
from app.server._limits import ENVELOPE_BYTES, BodyLimit, BodyLimitMiddleware
from app.settings import AppSettings
from app.store import ShowStore
from app.version import __version__
from formations import MAX_HOME_CSV_BYTES

log = logging.getLogger("swarmshow.server")

#: Modules with an ``install(app: FastAPI) -> None`` run by :func:`create_app`, in order.
EXTENSIONS: tuple[str, ...] = ("app.viewer",)

_DESCRIPTION = """Design, plan, verify, fly and export drone light shows.

* Every show has a `revision`; `PUT` must send the revision it read, and a stale one gets **409**
  with `current_revision` (never a silent overwrite).
* Invalid input gets **422** whose `detail` lists `{loc, path, msg}`: `path` is the JSON path of the
  field inside the body (`formations[2].hold_s`).
* Uploads over the limits get **413**: show file 20 MB, image 40 megapixels (50 MB), SVG 5 MB.
* With a server token (`SWARMSHOW_TOKEN`), every request needs `Authorization: Bearer <token>` or the
  cookie set by `POST /api/session`; otherwise **401**.
* A full job queue (or a client's `SWARMSHOW_MAX_JOBS_PER_CLIENT` jobs) answers **429** with `Retry-After`;
  a job running longer than `SWARMSHOW_JOB_TIMEOUT_S` fails (kind `timeout`, status 504 in its error).
  Interactive work (check, formations, exports) has its own worker pool and a time budget
  (`SWARMSHOW_TASK_TIMEOUT_S`: **504**); work over a size limit is refused before it starts (**413**/**422**).
* Without a token, only loopback `Host` and `Origin` names are answered (**421** otherwise).
* An unexpected error answers **500** `{"detail": "internal error", "request_id": ...}`; a full disk **507**.
* Heavy work (checks, simulations, formation sampling, exports) runs in worker processes; simulations are
  jobs (`202`) with progress as server-sent events. Results are cached by the show's content hash.
"""


@asynccontextmanager
async def _lifespan(app: FastAPI) -> AsyncIterator[None]:
    settings: AppSettings = app.state.settings
    store = await asyncio.to_thread(ShowStore, settings.db_path, keep_revisions=settings.keep_revisions)
    manager = JobManager(store=store, settings=settings)
    # An earlier server's unfinished jobs read "interrupted" before the first request is answered (a few
    # ms of SQLite); the pool starts in the background: the API answers (and the store serves) a few
    # hundred ms sooner after a restart; the first job waits for it (JobManager.wait_started).
    await asyncio.to_thread(manager.recover)
    starting = asyncio.get_running_loop().run_in_executor(None, manager.start)
    writer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="swarmshow-store")
    app.state.store, app.state.jobs, app.state.store_writer = store, manager, writer
    started: list[Any] = []
    try:
        for hook in app.state.startup:
            await _call(hook, app)
            started.append(hook)
        yield
    finally:
        for hook in reversed(app.state.shutdown):
            try:
                await _call(hook, app)
            except Exception:
                log.exception("shutdown hook %r failed", hook)
        try:
            await starting
        except Exception:
            log.exception("the job manager failed to start")
        await asyncio.to_thread(manager.close)
        writer.shutdown(wait=True)
        await asyncio.to_thread(store.close)


async def _call(hook: Any, app: FastAPI) -> None:
    result = hook(app)
    if inspect.isawaitable(result):
        await result


def _static_dir(settings: AppSettings) -> Path | None:
    if settings.static_dir is not None:
        return settings.static_dir
    here = Path(__file__).resolve().parent.parent
    for candidate in (here / "static", here.parent / "frontend"):
        if (candidate / "index.html").is_file():
            return candidate
    return None


def _body_limits(settings: AppSettings) -> tuple[list[BodyLimit], BodyLimit]:
    def limit(pattern: str, nominal: int, what: str) -> BodyLimit:
        return BodyLimit(re.compile(pattern), nominal + ENVELOPE_BYTES, what, nominal)

    limits = [
        limit(r"/api/shows(/[^/]+)?/?", settings.max_show_bytes, "a show file"),
        limit(r"/api/formations/image/?", settings.max_image_bytes, "an image"),
        limit(r"/api/formations/svg/?", settings.max_svg_bytes, "an SVG file"),
        limit(r"/api/formations/mesh/?", settings.max_mesh_bytes, "a mesh or point file"),
        limit(r"/api/formations/home-csv/?", MAX_HOME_CSV_BYTES, "a home CSV"),
        limit(r"/api/shows/[^/]+/audio/?", settings.max_audio_bytes, "an audio file ('file')"),
        # The editor's unsaved light design (images and videos included) for its 3D preview: a show's worth.
        limit(r"/api/viewer/[^/]+/lights/?", settings.max_show_bytes, "a show's lights"),
    ]
    return limits, BodyLimit(re.compile(""), 1024 * 1024, "this request", 1024 * 1024)


def create_app(settings: AppSettings | None = None) -> FastAPI:
    """Build the application (services start with its lifespan, e.g. under uvicorn or ``TestClient``).

    Args:
        settings: server settings (default: from ``SWARMSHOW_*`` environment variables).
    """
    settings = settings or AppSettings()
    app = FastAPI(
        title="swarmshow",
        version=__version__,
        description=_DESCRIPTION,
        openapi_url="/api/openapi.json",
        docs_url="/api/docs",
        redoc_url="/api/redoc",
        lifespan=_lifespan,
    )
    app.state.settings = settings
    app.state.startup = []
    app.state.shutdown = []
    install_error_handlers(app)
    limits, default = _body_limits(settings)
    # The last added runs first: headers on every answer, then the token, then the body limits.
    app.add_middleware(BodyLimitMiddleware, limits=limits, default=default)
    if settings.token is not None:
        app.add_middleware(TokenMiddleware, token=settings.token.get_secret_value())
    else:
        # No token: the server is on loopback, and only loopback names may address it (DNS rebinding).
        app.add_middleware(LoopbackHostMiddleware, extra_hosts=settings.allowed_hosts)
    app.add_middleware(SecurityHeadersMiddleware)
    for module in (health, shows, jobs, formations, session, audio):
        app.include_router(module.router, prefix="/api")
    for name in EXTENSIONS:
        importlib.import_module(name).install(app)
    app.openapi = lambda: _openapi(app)  # type: ignore[method-assign]
    _mount_editor(app, settings)
    return app


def _openapi(app: FastAPI) -> dict[str, Any]:
    """FastAPI's document plus the schemas that raw-body endpoints reference."""
    if app.openapi_schema is None:
        doc = get_openapi(
            title=app.title, version=app.version, description=app.description, routes=app.routes,
        )
        schemas = doc.setdefault("components", {}).setdefault("schemas", {})
        extra = ShowUpdate.model_json_schema(ref_template="#/components/schemas/{model}")
        for name, schema in extra.pop("$defs", {}).items():
            schemas.setdefault(name, schema)
        schemas["ShowUpdate"] = extra
        _use_our_422(doc)
        _list_export_formats(doc)
        app.openapi_schema = doc
    return app.openapi_schema


def _use_our_422(doc: dict[str, Any]) -> None:
    """Point FastAPI's default 422 answers at the body the error handlers actually send."""
    ours = {"$ref": "#/components/schemas/ValidationErrorOut"}
    for item in doc.get("paths", {}).values():
        for op in item.values():
            answer = op.get("responses", {}).get("422") if isinstance(op, dict) else None
            if answer is None:
                continue
            content = answer.setdefault("content", {}).setdefault("application/json", {})
            if content.get("schema", {}).get("$ref", "").endswith("/HTTPValidationError"):
                content["schema"] = ours
                answer["description"] = "Invalid input, with the field path and the reason."
    schemas = doc["components"]["schemas"]
    for name in ("HTTPValidationError", "ValidationError"):
        schemas.pop(name, None)


def _list_export_formats(doc: dict[str, Any]) -> None:
    """The export path's ``fmt`` is checked by hand (unknown -> 404); list the formats as its enum."""
    op = doc.get("paths", {}).get("/api/shows/{show_id}/export/{fmt}", {}).get("get", {})
    for param in op.get("parameters", []):
        if param.get("name") == "fmt":
            param["schema"] = {"type": "string", "enum": list(shows.export_formats()), "title": "Format"}


def _mount_editor(app: FastAPI, settings: AppSettings) -> None:
    static = _static_dir(settings)
    if static is not None:
        app.mount("/", StaticFiles(directory=static, html=True), name="editor")
        return

    @app.get("/", include_in_schema=False)
    def _no_editor() -> HTMLResponse:
        return HTMLResponse(
            "<!doctype html><title>swarmshow</title><h1>swarmshow</h1>"
            "<p>The editor is not installed. The API is documented at <a href='/api/docs'>/api/docs</a>.</p>"
        )
