"""Jobs: state and result, server-sent progress events, cancellation."""

from __future__ import annotations

import json
from collections.abc import AsyncIterator
from typing import Literal

from fastapi import APIRouter, Request, Response
from fastapi.responses import StreamingResponse

from app import tasks
from app.api import deps
from app.api.errors import ApiError, job_body
from app.api.models import JobList, JobOut, error_responses
from app.jobs import JobManager

router = APIRouter(tags=["jobs"])

#: Seconds between keep-alive comments on an idle event stream (proxies drop silent connections).
HEARTBEAT_S = 15.0


@router.get("/jobs", response_model=JobList, summary="List jobs")
async def list_jobs(request: Request) -> JobList:
    """Jobs the server remembers (the newest first; results omitted, read them per job)."""
    jobs = deps.jobs(request).list()
    return JobList(items=[JobOut(**job_body(j.snapshot(with_result=False))) for j in reversed(jobs)])


@router.get("/jobs/{job_id}", response_model=JobOut, summary="Read a job", responses=error_responses(404))
async def get_job(request: Request, job_id: str) -> JobOut:
    """State (queued, running, done, failed, cancelled), progress 0..1, and the result or why it failed."""
    return JobOut(**job_body(deps.jobs(request).get(job_id).snapshot()))


@router.delete(
    "/jobs/{job_id}", response_model=JobOut, summary="Cancel a job", responses=error_responses(404, 409)
)
def cancel_job(request: Request, job_id: str) -> JobOut:
    """Cancel a queued or running job; it reads ``cancelled`` at once and its worker stops at its next
    progress report. A job that is already done or failed gets 409; cancelling twice is harmless."""
    return JobOut(**job_body(deps.jobs(request).cancel(job_id).snapshot()))


@router.get(
    "/jobs/{job_id}/report.{fmt}",
    summary="The safety report of a Monte-Carlo job (HTML or PDF)",
    response_class=Response,
    responses={200: {"description": "The report.", "content": {"text/html": {}, "application/pdf": {}}},
               **error_responses(404, 409)},
)
async def job_report(request: Request, job_id: str, fmt: Literal["html", "pdf"], download: bool = False) -> Response:
    """Draw the safety report of a finished Monte-Carlo job (``POST /api/shows/{id}/montecarlo``):
    minimum separation over time with the runs' band, deviation histogram, speeds against the
    limits, per-segment margins and the worst pairs. ``html`` is one self-contained page (inline
    SVG); ``pdf`` a printable file. ``download=true`` sends it as an attachment."""
    job = deps.jobs(request).get(job_id)
    if job.kind != "montecarlo":
        raise ApiError(404, f"job {job_id!r} is a {job.kind} job; safety reports come from Monte-Carlo jobs")
    snap = job.snapshot()
    result = snap.get("result")
    if snap["state"] != "done" or not isinstance(result, dict) or "montecarlo" not in result:
        raise ApiError(409, f"job {job_id!r} is {snap['state']}; the report needs a finished job", state=snap["state"])
    content = await deps.run(request, tasks.safety_report_task, result["montecarlo"], fmt)
    media = {"html": "text/html; charset=utf-8", "pdf": "application/pdf"}[fmt]
    headers = {"Content-Disposition": f'{"attachment" if download or fmt == "pdf" else "inline"}; '
                                      f'filename="safety-report-{job_id}.{fmt}"'}
    return Response(content, media_type=media, headers=headers)


_EVENTS_DOC = """Server-sent events (`text/event-stream`) following the job until it ends:

* `event: progress` with `data: {"id", "state", "progress", ...}` whenever state or progress change;
* then one final `event: done`, `failed` or `cancelled` carrying the whole job (result or error);
* `: keep-alive` comments every 15 s while nothing changes.

Each event has an increasing `id`; the stream closes after the final event.
"""


@router.get(
    "/jobs/{job_id}/events",
    summary="Follow a job's progress (server-sent events)",
    description=_EVENTS_DOC,
    response_class=StreamingResponse,
    responses={
        200: {"description": "An event stream.", "content": {"text/event-stream": {"example": (
            'id: 3\nevent: progress\ndata: {"id": "9c1e...", "state": "running", "progress": 0.42}\n\n'
            'id: 9\nevent: done\ndata: {"id": "9c1e...", "state": "done", "progress": 1.0, "result": {}}\n\n')}}},
        **error_responses(404),
    },
)
async def job_events(request: Request, job_id: str) -> StreamingResponse:
    """Stream the job's progress as server-sent events."""
    jobs = deps.jobs(request)
    jobs.get(job_id)  # 404 before the stream starts
    return StreamingResponse(
        _events(jobs, job_id),
        media_type="text/event-stream",
        headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"},
    )


async def _events(jobs: JobManager, job_id: str) -> AsyncIterator[str]:
    yield "retry: 2000\n\n"
    seq = 0
    async for snap in jobs.watch(job_id, heartbeat_s=HEARTBEAT_S):
        if snap is None:
            yield ": keep-alive\n\n"
            continue
        snap = job_body(snap)
        terminal = snap["state"] in ("done", "failed", "cancelled")
        if not terminal:
            snap = {k: snap[k] for k in ("id", "kind", "state", "progress", "show_id", "cached")}
        seq += 1
        yield f"id: {seq}\nevent: {snap['state'] if terminal else 'progress'}\ndata: {json.dumps(snap)}\n\n"
