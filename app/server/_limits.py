"""Request body limits, enforced while the body arrives (before it is parsed or stored).

A declared ``Content-Length`` over the limit is refused at once; a body sent
without one (chunked) is counted and refused as soon as it passes the limit.
Either way the answer is 413 with the limit in the message.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.web import BodyTooLarge as BodyTooLarge  # shared with the API's routes

#: Room for a multipart envelope or the ``{"revision": n, "show": ...}`` wrapper around a file.
ENVELOPE_BYTES = 64 * 1024


@dataclass(frozen=True)
class BodyLimit:
    """A path pattern, the largest body it accepts, and the documented limit and the thing it
    limits (for the message; ``max_bytes`` may add room for an envelope around the file)."""

    pattern: re.Pattern[str]
    max_bytes: int
    what: str
    nominal_bytes: int



class BodyLimitMiddleware:
    """Pure ASGI middleware applying the first matching :class:`BodyLimit` (else ``default``)."""

    def __init__(self, app: ASGIApp, *, limits: list[BodyLimit], default: BodyLimit) -> None:
        self.app, self.limits, self.default = app, limits, default

    def limit_for(self, path: str) -> BodyLimit:
        """The limit that applies to ``path``."""
        return next((lim for lim in self.limits if lim.pattern.fullmatch(path)), self.default)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http" or scope["method"] in ("GET", "HEAD", "OPTIONS"):
            await self.app(scope, receive, send)
            return
        limit = self.limit_for(scope["path"])
        declared = _content_length(scope)
        if declared is not None and declared > limit.max_bytes:
            await _refuse(send, BodyTooLarge(limit.what, limit.nominal_bytes, size=declared))
            return
        received = 0

        async def counted() -> Message:
            nonlocal received
            message = await receive()
            if message["type"] == "http.request":
                received += len(message.get("body", b""))
                if received > limit.max_bytes:
                    raise BodyTooLarge(limit.what, limit.nominal_bytes)
            return message

        await self.app(scope, counted, send)


def _content_length(scope: Scope) -> int | None:
    for name, value in scope.get("headers", ()):
        if name == b"content-length":
            try:
                return int(value)
            except ValueError:
                return None
    return None


async def _refuse(send: Send, exc: BodyTooLarge) -> None:
    body = json.dumps({"detail": exc.detail}).encode()
    await send({
        "type": "http.response.start",
        "status": 413,
        "headers": [(b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()),
                    (b"connection", b"close")],
    })
    await send({"type": "http.response.body", "body": body})
