"""Mapping of failures to HTTP answers; every error body has a ``detail``.

422 bodies always list ``{"loc", "path", "msg"}`` problems, whether the request
failed FastAPI's parameter validation or the show file's own rules.
"""

from __future__ import annotations

import logging
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from app.api.models import error_responses as error_responses  # documented next to the handlers
from app.jobs import JobFinished, JobNotFound, JobsBusy
from app.store import RevisionConflict, ShowNotFound, StoreError
from app.tasks import TaskFailure

log = logging.getLogger("swarmshow.api")


class ApiError(Exception):
    """An error answered as ``{"detail": detail, **extra}`` with ``status``."""

    def __init__(self, status: int, detail: Any, *, headers: dict[str, str] | None = None, **extra: Any) -> None:
        super().__init__(detail)
        self.status, self.detail, self.headers, self.extra = status, detail, headers, extra


def loc_path(loc: list[str | int] | tuple[str | int, ...]) -> str:
    """('formations', 2, 'hold_s') -> 'formations[2].hold_s'."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def show_problems(errors: list[dict[str, Any]], *, prefix: tuple[str | int, ...] = ()) -> list[dict[str, Any]]:
    """``ShowValidationError.errors`` as API problems located in the request body under ``prefix``."""
    out = []
    for err in errors:
        path = ".".join(p for p in (loc_path(prefix), err.get("path") or "") if p)
        out.append({"loc": ["body", *prefix, *err.get("loc", ())], "path": path, "msg": err["msg"]})
    return out


def _validation_problems(exc: RequestValidationError) -> list[dict[str, Any]]:
    out = []
    for err in exc.errors():
        loc = list(err.get("loc", ()))
        # Body fields are named relative to the body; query/path parameters by their own name.
        rel = loc[1:] if loc and loc[0] in ("body", "query", "path", "header", "cookie") else loc
        out.append({"loc": loc, "path": loc_path(rel), "msg": err.get("msg", "invalid"), "type": err.get("type")})
    return out


def _json(status: int, body: dict[str, Any], headers: dict[str, str] | None = None) -> JSONResponse:
    return JSONResponse(body, status_code=status, headers=headers)


def install_error_handlers(app: FastAPI) -> None:
    """Register the handlers that turn exceptions into the documented error bodies."""

    @app.exception_handler(ApiError)
    async def _api_error(_: Request, exc: ApiError) -> JSONResponse:
        return _json(exc.status, {"detail": exc.detail, **exc.extra}, exc.headers)

    @app.exception_handler(RequestValidationError)
    async def _request_invalid(_: Request, exc: RequestValidationError) -> JSONResponse:
        return _json(422, {"detail": _validation_problems(exc)})

    @app.exception_handler(ShowNotFound)
    async def _show_missing(_: Request, exc: ShowNotFound) -> JSONResponse:
        return _json(404, {"detail": str(exc)})

    @app.exception_handler(RevisionConflict)
    async def _conflict(_: Request, exc: RevisionConflict) -> JSONResponse:
        return _json(409, {"detail": str(exc), "current_revision": exc.current_revision},
                     {"ETag": f'"{exc.current_revision}"'})

    @app.exception_handler(StoreError)
    async def _store(_: Request, exc: StoreError) -> JSONResponse:
        return _json(500, {"detail": f"show store: {exc}"})

    @app.exception_handler(JobNotFound)
    async def _job_missing(_: Request, exc: JobNotFound) -> JSONResponse:
        return _json(404, {"detail": f"no job with id {exc.args[0]!r}"})

    @app.exception_handler(JobFinished)
    async def _job_finished(_: Request, exc: JobFinished) -> JSONResponse:
        return _json(409, {"detail": str(exc), "state": exc.job.state.value})

    @app.exception_handler(JobsBusy)
    async def _busy(_: Request, exc: JobsBusy) -> JSONResponse:
        return _json(429, {"detail": str(exc)}, {"Retry-After": "5"})

    @app.exception_handler(TaskFailure)
    async def _task_failed(_: Request, exc: TaskFailure) -> JSONResponse:
        return _json(exc.status, {"detail": exc.detail})

    @app.exception_handler(Exception)
    async def _internal(request: Request, exc: Exception) -> JSONResponse:
        # A bug, not bad input: say what broke (clients show it) and keep the traceback in the log.
        log.error("%s %s failed", request.method, request.url.path, exc_info=exc)
        return _json(500, {"detail": f"internal error ({type(exc).__name__}): {exc}"})
