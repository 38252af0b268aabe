"""Bearer-token access control for ``/api`` and ``/viser`` (HTTP and websocket), and the session cookie.

With ``SWARMSHOW_TOKEN`` set, a request to ``/api`` or ``/viser`` passes with
``Authorization: Bearer <token>`` or with the cookie ``POST /api/session`` sets
(an iframe, an ``EventSource`` and a websocket cannot send headers). Anything
else gets the same 401 whatever was wrong, so a caller learns nothing about the
token. Tokens and cookie signatures are compared with :func:`hmac.compare_digest`.

The cookie holds ``<expiry>.<HMAC-SHA256(token, expiry)>``: nothing to store on
the server, it dies with its expiry, and changing the token revokes every cookie.
"""

from __future__ import annotations

import json
from collections.abc import Iterable

from starlette.types import ASGIApp, Receive, Scope, Send

# The token and cookie primitives live one layer down, shared with the API's session route.
from app.web import COOKIE as COOKIE
from app.web import bearer_ok as bearer_ok
from app.web import session_ok as session_ok
from app.web import session_value as session_value

#: Paths that need the token (the editor's static files at ``/`` are public).
PROTECTED = ("/api", "/viser")
#: The one path that takes the token in its body to set the cookie.
SESSION_PATH = "/api/session"

_DENIED = json.dumps({"detail": "unauthorized"}).encode()


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope.get("headers", ()):
        if key == name:
            return value.decode("latin-1")
    return None


def _cookies(scope: Scope) -> Iterable[tuple[str, str]]:
    raw = _header(scope, b"cookie") or ""
    for part in raw.split(";"):
        name, _, value = part.strip().partition("=")
        if name:
            yield name, value


def authorized(scope: Scope, *, token: str) -> bool:
    """True when the request carries the token or a valid session cookie."""
    if bearer_ok(_header(scope, b"authorization"), token=token):
        return True
    return any(name == COOKIE and session_ok(value, token=token) for name, value in _cookies(scope))


def needs_token(path: str) -> bool:
    """True for ``/api...`` and ``/viser...`` paths except the session endpoint itself."""
    if path.rstrip("/") == SESSION_PATH:
        return False
    return any(path == p or path.startswith(p + "/") for p in PROTECTED)


class TokenMiddleware:
    """Pure ASGI middleware: 401 (HTTP) or a refused handshake (websocket) without the token."""

    def __init__(self, app: ASGIApp, *, token: str) -> None:
        self.app, self.token = app, token

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket") or not needs_token(scope["path"]):
            await self.app(scope, receive, send)
            return
        if authorized(scope, token=self.token):
            await self.app(scope, receive, send)
            return
        if scope["type"] == "http":
            await _deny_http(send)
        else:
            await _deny_websocket(scope, receive, send)


_DENY_HEADERS = [
    (b"content-type", b"application/json"),
    (b"content-length", str(len(_DENIED)).encode()),
    (b"www-authenticate", b'Bearer realm="swarmshow"'),
    (b"cache-control", b"no-store"),
]


async def _deny_http(send: Send) -> None:
    await send({"type": "http.response.start", "status": 401, "headers": _DENY_HEADERS})
    await send({"type": "http.response.body", "body": _DENIED})


async def _deny_websocket(scope: Scope, receive: Receive, send: Send) -> None:
    message = await receive()  # websocket.connect
    if message["type"] != "websocket.connect":
        return
    if "websocket.http.response" in scope.get("extensions", {}):
        # The server can answer the handshake with a real HTTP 401.
        await send({"type": "websocket.http.response.start", "status": 401, "headers": _DENY_HEADERS})
        await send({"type": "websocket.http.response.body", "body": _DENIED})
        return
    # Otherwise closing before accepting makes the server refuse the handshake (HTTP 403).
    await send({"type": "websocket.close", "code": 1008})
