"""``GET /api/health``: liveness for load balancers and the Docker HEALTHCHECK."""

from __future__ import annotations

from fastapi import APIRouter, Request

from app.api import deps
from app.api.models import HealthOut
from app.version import __version__

router = APIRouter(tags=["health"])


@router.get("/health", response_model=HealthOut, summary="Server status")
async def health(request: Request) -> HealthOut:
    """The server answers, its show store is open and its worker pools run (``busy``: saturated)."""
    jobs = deps.jobs(request)
    return HealthOut(
        status="busy" if jobs.saturated() else "ok",
        version=__version__,
        schema_version=deps.store(request).schema_version,
        workers=jobs.workers,
        interactive_workers=jobs.interactive_workers,
        jobs_pending=jobs.pending(),
        interactive_pending=jobs.interactive_busy(),
    )
