"""Access to the per-app services (created in the app's lifespan) from request handlers."""

from __future__ import annotations

import asyncio
import functools
import hashlib
from collections.abc import Callable
from typing import Any, TypeVar

from fastapi import Request

from app.jobs import JobManager
from app.settings import AppSettings
from app.store import ShowStore

T = TypeVar("T")


def store(request: Request) -> ShowStore:
    """The show store."""
    return request.app.state.store


def jobs(request: Request) -> JobManager:
    """The job manager (worker pool, jobs, result cache)."""
    return request.app.state.jobs


def settings(request: Request) -> AppSettings:
    """The server settings."""
    return request.app.state.settings


async def write(request: Request, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> T:
    """Run a store write on the app's one store thread.

    Writes wait for an fsync; one dedicated thread keeps that off the event loop
    without a crowd of threads contending for the store's lock and the GIL.
    """
    loop = asyncio.get_running_loop()
    return await loop.run_in_executor(request.app.state.store_writer, functools.partial(fn, *args, **kwargs))


async def run(request: Request, fn: Callable[..., T], /, *args: Any) -> T:
    """Run ``fn(*args)`` in the interactive worker pool under its time budget; stopped if the client leaves."""
    return await jobs(request).run(fn, *args, gone=request.is_disconnected)


def client_id(request: Request) -> str:
    """Who is asking, for the per-client job limit and for sharing identical jobs.

    The session cookie when there is one (a browser behind the token), else the
    ``X-Swarmshow-Client`` header (a random id a client may send to keep its tabs or
    scripts apart), else the peer address.
    """
    from app.web import COOKIE

    cookie = request.cookies.get(COOKIE)
    if cookie:
        return "session:" + hashlib.sha256(cookie.encode()).hexdigest()[:16]
    given = request.headers.get("x-swarmshow-client", "").strip()
    if given:
        return "client:" + given[:64]
    return "addr:" + (request.client.host if request.client else "")
