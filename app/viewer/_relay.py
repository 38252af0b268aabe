"""One port: serve viser's client at ``/viser/`` and relay its websocket to the loopback viser server.

viser's client derives its websocket URL from the page's own address: it
takes ``location.href``, swaps ``http`` for ``ws``, drops the query and one
trailing slash, so the page ``/viser/`` connects to ``ws://host/viser``. The
relay accepts there (and at ``/viser/`` for clients given ``?websocket=``-style
URLs with the slash), opens a websocket to ``ws://127.0.0.1:<viser port>``
offering the browser's ``viser-v<version>`` subprotocol, accepts the browser
with the subprotocol viser chose, and then copies frames both ways until either
side closes. Closing codes (viser's 1002 on a version mismatch) are passed on.

The client build is one self-contained ``index.html`` (scripts, styles, fonts
and the default environment map inlined), so nothing on the page comes from
the internet.
"""

from __future__ import annotations

import asyncio
import contextlib
import gzip
from collections.abc import Callable
from functools import cache
from pathlib import Path

import viser
import websockets
from fastapi import APIRouter, HTTPException, Request, WebSocket
from fastapi.responses import FileResponse, RedirectResponse, Response
from starlette.websockets import WebSocketDisconnect, WebSocketState
from websockets.asyncio.client import connect

from app.viewer._viewer import Viewer

#: viser's bundled client build.
CLIENT_BUILD_DIR = Path(viser.__file__).resolve().parent / "client" / "build"

ViewerRef = Viewer | Callable[[], Viewer | None] | None


@cache
def _index_html() -> tuple[bytes, bytes]:
    """The client page, raw and gzip-compressed (it is ~0.8 MB; compressed once per process)."""
    raw = (CLIENT_BUILD_DIR / "index.html").read_bytes()
    return raw, gzip.compress(raw, compresslevel=9)


def _resolve(ref: ViewerRef, app_state: object) -> Viewer | None:
    if isinstance(ref, Viewer):
        return ref
    if callable(ref):
        return ref()
    return getattr(app_state, "viewer", None)


def viewer_router(viewer: ViewerRef = None) -> APIRouter:
    """Routes serving viser's client at ``/viser/`` and relaying ``/viser`` to the viewer.

    Args:
        viewer: the :class:`Viewer`, a function returning it (it may start later,
            in the app's lifespan), or None to use ``app.state.viewer``.

    Returns:
        A router to include at the app's root.
    """
    router = APIRouter(tags=["viewer"])

    @router.get("/viser", include_in_schema=False)
    async def viser_redirect(request: Request) -> RedirectResponse:
        query = request.url.query
        return RedirectResponse("/viser/" + (f"?{query}" if query else ""), status_code=307)

    @router.get("/viser/", include_in_schema=False)
    async def viser_page(request: Request) -> Response:
        raw, packed = _index_html()
        headers = {"Cache-Control": "no-cache", "Vary": "Accept-Encoding"}
        if "gzip" in request.headers.get("accept-encoding", ""):
            headers["Content-Encoding"] = "gzip"
            return Response(packed, media_type="text/html; charset=utf-8", headers=headers)
        return Response(raw, media_type="text/html; charset=utf-8", headers=headers)

    @router.get("/viser/{path:path}", include_in_schema=False)
    async def viser_asset(path: str) -> FileResponse:
        # The current build is a single page; this serves any file a future build adds next to it.
        # A NUL or an over-long name makes the OS call fail (ValueError, ENAMETOOLONG): still just 404,
        # never a 500 whose traceback names the install path.
        if "\x00" in path or len(path) > 1024 or any(len(part) > 255 for part in path.split("/")):
            raise HTTPException(status_code=404, detail="not found")
        try:
            target = (CLIENT_BUILD_DIR / path).resolve()
            found = target.is_file() and CLIENT_BUILD_DIR in target.parents
        except (OSError, ValueError):
            found = False
        if not found:
            raise HTTPException(status_code=404, detail="not found")
        return FileResponse(target)

    async def relay(websocket: WebSocket) -> None:
        target = _resolve(viewer, websocket.app.state)
        if target is None:
            await websocket.close(code=1013, reason="viewer not running")
            return
        offered = [
            p.strip() for p in websocket.headers.get("sec-websocket-protocol", "").split(",") if p.strip()
        ]
        wanted = [p for p in offered if p.startswith("viser-v")]
        try:
            upstream = await connect(
                f"ws://127.0.0.1:{target.port}",
                subprotocols=wanted or None,  # type: ignore[arg-type]
                max_size=None,
                compression=None,
                # viser pings its own clients; a second keepalive layer only adds traffic.
                ping_interval=None,
                open_timeout=10,
            )
        except (OSError, websockets.exceptions.WebSocketException, TimeoutError):
            await websocket.close(code=1011, reason="viewer unavailable")
            return
        await websocket.accept(subprotocol=upstream.subprotocol)

        async def downstream() -> None:
            async for message in upstream:
                if isinstance(message, bytes):
                    await websocket.send_bytes(message)
                else:
                    await websocket.send_text(message)

        async def upstream_pump() -> None:
            while True:
                message = await websocket.receive()
                if message["type"] == "websocket.disconnect":
                    return
                if message.get("bytes") is not None:
                    await upstream.send(message["bytes"])
                elif message.get("text") is not None:
                    await upstream.send(message["text"])

        tasks = [asyncio.create_task(downstream()), asyncio.create_task(upstream_pump())]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for task in tasks:
                task.cancel()
            for task in tasks:
                with contextlib.suppress(asyncio.CancelledError, WebSocketDisconnect,
                                         websockets.exceptions.ConnectionClosed, RuntimeError):
                    await task
            await upstream.close()
            if websocket.application_state == WebSocketState.CONNECTED:
                code = upstream.close_code if upstream.close_code not in (None, 1005, 1006) else 1000
                with contextlib.suppress(RuntimeError, WebSocketDisconnect):
                    await websocket.close(code=code, reason=upstream.close_reason or "")

    router.add_api_websocket_route("/viser", relay)
    router.add_api_websocket_route("/viser/", relay)
    return router


__all__ = ["CLIENT_BUILD_DIR", "viewer_router"]
