"""Mapping of failures to HTTP answers; every error body has a ``detail``.

422 bodies always list ``{"loc", "path", "msg", "where"}`` problems, whether the request
failed FastAPI's parameter validation or the show file's own rules: ``where`` says the
field in the designer's words (``formations.plain_words``, the one place that words a
path; the editor shows it as it comes), and a field inside a formation also says
``where_in_formation`` (for that formation's card). Job and task
errors carry a kind (:class:`app.jobs.ErrorKind`, :class:`app.tasks.FailureKind`);
:data:`STATUS_OF_KIND` is the one place that turns kinds into HTTP statuses. Any
other exception is a bug: its traceback is logged with a request id, and the
client gets ``{"detail": "internal error", "request_id": ...}``, never its text.
"""

from __future__ import annotations

import json
import logging
import secrets
import sqlite3
from typing import TYPE_CHECKING, Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse

from app.api.models import error_responses as error_responses  # documented next to the handlers
from app.jobs import ErrorKind, JobFinished, JobNotFound, JobsBusy, TaskError
from app.store import RevisionConflict, ShowNotFound, StoreError
from app.tasks import FailureKind, TaskFailure, path_loc
from formations import plain_words

if TYPE_CHECKING:
    from app.store import ShowRecord

#: HTTP status of each job / task error kind (499: the client closed the request, nginx's code).
STATUS_OF_KIND: dict[str, int] = {
    ErrorKind.CANCELLED: 499,
    ErrorKind.TIMEOUT: 504,
    ErrorKind.WORKER_DIED: 500,
    ErrorKind.FAILED: 500,
    ErrorKind.INTERRUPTED: 503,
    FailureKind.INVALID: 422,
    FailureKind.TOO_LARGE: 413,
    FailureKind.UNAVAILABLE: 503,
    FailureKind.NOT_FOUND: 404,
    FailureKind.NOT_IMPLEMENTED: 501,
}


def status_of(kind: str | None) -> int:
    """The HTTP status of an error kind (500 for an unknown one)."""
    return STATUS_OF_KIND.get(str(kind), 500)


def job_body(snapshot: dict[str, Any]) -> dict[str, Any]:
    """A job snapshot as the API answers it: its error also carries the HTTP ``status`` of its kind."""
    error = snapshot.get("error")
    if error is not None and "status" not in error:
        error = {**error, "status": status_of(error.get("kind"))}
        if "detail" in error:
            error["detail"] = with_words(error["detail"])
        snapshot = {**snapshot, "error": error}
    return snapshot


def disk_full(exc: BaseException) -> bool:
    """True when ``exc`` (or what caused it) says the disk or the database is full."""
    seen: BaseException | None = exc
    while seen is not None:
        text = str(seen).lower()
        if isinstance(seen, OSError) and seen.errno == 28:  # ENOSPC
            return True
        if isinstance(seen, sqlite3.OperationalError) and ("full" in text or "disk i/o" in text):
            return True
        seen = seen.__cause__ or seen.__context__
    return False

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


def with_words(problems: Any) -> Any:
    """``problems`` (a 422 ``detail``) with each problem saying ``where`` in plain words, when it does not yet.

    A problem made knowing the show (its validation, a plan's refusal) already says it, formations named;
    the others are worded from their path alone. A path inside the request's ``show`` (``PUT``'s
    ``{"revision", "show"}``) is worded as the show's own field. Anything but a list of problems is as it is.
    """
    if not isinstance(problems, list):
        return problems
    out = []
    for p in problems:
        if isinstance(p, dict) and "msg" in p and "where" not in p:
            path = str(p.get("path") or "")
            p = {**p, **plain_words(path.removeprefix("show.") if path != "show" else "")}
        out.append(p)
    return out


def show_problems(errors: list[dict[str, Any]], *, prefix: tuple[str | int, ...] = ()) -> list[dict[str, Any]]:
    """``ShowValidationError.errors`` as API problems located in the request body under ``prefix``.

    A show-level rule (a group index out of range, a point above the ceiling) reports an empty or coarse
    ``loc`` but the exact ``path``: the ``loc`` is then taken from the path, so that both name the same field.
    """
    out = []
    for err in errors:
        path = ".".join(p for p in (loc_path(prefix), err.get("path") or "") if p)
        loc = list(err.get("loc", ()))
        from_path = path_loc(err.get("path") or "")
        if len(from_path) > len(loc):
            loc = from_path
        words: dict[str, Any] = {k: err[k] for k in ("where", "where_in_formation") if k in err}
        out.append({"loc": ["body", *prefix, *loc], "path": path, "msg": err["msg"], **words})
    return with_words(out)


def draft_problems(record: ShowRecord) -> list[dict[str, Any]] | None:
    """A stored draft's problems, each with ``where`` (its path in plain words); None for a valid show."""
    if record.problems is None:
        return None
    problems: list[dict[str, Any]] = json.loads(record.problems)
    # Drafts stored before the words were kept with them are worded from their paths.
    return [{**plain_words(p.get("path", "")), **p} for p in problems]


def require_valid(record: ShowRecord, action: str) -> ShowRecord:
    """The record if its show is valid; a draft is refused with 422 naming what is wrong in plain words.

    Check, simulate, export and playback need a valid show: a draft is the user's unfinished work.
    """
    problems = draft_problems(record)
    if problems is None:
        return record
    first = problems[0]
    more = len(problems) - 1
    message = (f"show {record.name!r} is a draft and cannot be {action}: {first['where']}: {first['msg']}"
               + (f" (and {more} more problem{'s' if more > 1 else ''})" if more else "")
               + "; fix it and save it, then try again")
    detail = [{**p, "loc": ["show", *p.get("loc", [])]} for p in problems]
    raise ApiError(422, detail, draft=True, message=message)


def _validation_problems(exc: RequestValidationError) -> list[dict[str, Any]]:
    out = []
    for err in exc.errors():
        loc = list(err.get("loc", ()))
        # Body fields are named relative to the body; query/path parameters by their own name.
        rel = loc[1:] if loc and loc[0] in ("body", "query", "path", "header", "cookie") else loc
        out.append({"loc": loc, "path": loc_path(rel), "msg": err.get("msg", "invalid"), "type": err.get("type")})
    return with_words(out)


def _json(status: int, body: dict[str, Any], headers: dict[str, str] | None = None) -> JSONResponse:
    return JSONResponse(body, status_code=status, headers=headers)


def install_error_handlers(app: FastAPI) -> None:
    """Register the handlers that turn exceptions into the documented error bodies."""

    @app.exception_handler(ApiError)
    async def _api_error(_: Request, exc: ApiError) -> JSONResponse:
        return _json(exc.status, {"detail": with_words(exc.detail), **exc.extra}, exc.headers)

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
    async def _store(request: Request, exc: StoreError) -> JSONResponse:
        if disk_full(exc):
            return _json(507, {"detail": "the disk of the show store is full: nothing was changed; stored shows "
                                         "stay readable. Free some space and try again."})
        return _internal_error(request, exc)

    @app.exception_handler(sqlite3.OperationalError)
    async def _sqlite(request: Request, exc: sqlite3.OperationalError) -> JSONResponse:
        if disk_full(exc):
            return _json(507, {"detail": "the disk of the show store is full: nothing was changed; stored shows "
                                         "stay readable. Free some space and try again."})
        return _internal_error(request, exc)

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
        return _json(status_of(exc.kind), {"detail": with_words(exc.detail)})

    @app.exception_handler(TaskError)
    async def _task_error(request: Request, exc: TaskError) -> JSONResponse:
        if exc.kind in (ErrorKind.FAILED, ErrorKind.WORKER_DIED):
            log.error("%s %s: %s", request.method, request.url.path, exc)
        return _json(status_of(exc.kind), {"detail": str(exc), "kind": exc.kind.value})

    @app.exception_handler(RecursionError)
    async def _too_deep(_: Request, exc: RecursionError) -> JSONResponse:
        # Deeply nested JSON (or SVG) that a parser followed until the stack ran out: the input's fault.
        return _json(422, {"detail": [{"loc": ["body"], "path": "", "msg": "nested too deeply"}]})

    @app.exception_handler(Exception)
    async def _internal(request: Request, exc: Exception) -> JSONResponse:
        return _internal_error(request, exc)


def _internal_error(request: Request, exc: BaseException) -> JSONResponse:
    """A bug, not bad input: the traceback goes to the log under a request id the client is given."""
    request_id = secrets.token_hex(6)
    log.error("%s %s failed (request %s)", request.method, request.url.path, request_id, exc_info=exc)
    return _json(500, {"detail": "internal error", "request_id": request_id})
