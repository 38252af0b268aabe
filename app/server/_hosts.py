"""DNS-rebinding guard: without a token, answer only requests addressed to a loopback name.

A web page on ``attacker.example`` whose DNS record is switched to 127.0.0.1 after
loading runs in the browser *same-origin* with its own name: the Origin check of
:mod:`app.server._headers` sees ``Origin == Host`` and lets it read and write every
show, and open the ``/viser`` websocket. The browser still sends the attacker's name
in ``Host``, so a tokenless server (which only listens on loopback) refuses any
``Host`` that is not a loopback name or address (any port), and any ``Origin`` that
is not one either, over HTTP and websockets. With a token the token rules apply and
this guard is not installed (a token is required anyway off loopback).
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from urllib.parse import urlsplit

from starlette.types import ASGIApp, Receive, Scope, Send

from app.server._exposure import is_loopback

_REFUSED = json.dumps({"detail": "host not allowed: this server answers only loopback names "
                                 "(127.0.0.1, localhost, [::1]) unless it has a token"}).encode()


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope.get("headers", ()):
        if key == name:
            return value.decode("latin-1")
    return None


def host_name(netloc: str) -> str | None:
    """The host of ``host[:port]`` (``[v6]:port`` too), lower case; None when malformed."""
    try:
        parts = urlsplit("//" + netloc.strip())
        name = parts.hostname
        _ = parts.port  # raises on a non-numeric or out-of-range port
    except ValueError:
        return None
    if not name or parts.username is not None or parts.password is not None or parts.path:
        return None
    return name.lower()


def host_allowed(netloc: str | None, extra: Iterable[str] = ()) -> bool:
    """True for a missing ``Host`` (HTTP/1.0 clients), a loopback name or address, or one of ``extra``."""
    if netloc is None:
        return True
    name = host_name(netloc)
    return name is not None and (is_loopback(name) or name in extra)


def origin_allowed(origin: str | None, extra: Iterable[str] = ()) -> bool:
    """True without an ``Origin`` (non-browser clients) or for an http(s) origin on a loopback name."""
    if origin is None:
        return True
    try:
        parts = urlsplit(origin.strip())
    except ValueError:
        return False
    return parts.scheme in ("http", "https") and host_allowed(parts.netloc, extra)


class LoopbackHostMiddleware:
    """Pure ASGI middleware: 421 (HTTP) or a refused handshake (websocket) for a non-loopback Host/Origin."""

    def __init__(self, app: ASGIApp, *, extra_hosts: Iterable[str] = ()) -> None:
        self.app = app
        self.extra = frozenset(h.strip().lower() for h in extra_hosts if h.strip())

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        if host_allowed(_header(scope, b"host"), self.extra) and origin_allowed(_header(scope, b"origin"),
                                                                                 self.extra):
            await self.app(scope, receive, send)
            return
        if scope["type"] == "http":
            # 421 Misdirected Request: the request was not meant for this server (RFC 9110, 15.5.20).
            await send({"type": "http.response.start", "status": 421, "headers": [
                (b"content-type", b"application/json"), (b"content-length", str(len(_REFUSED)).encode()),
                (b"cache-control", b"no-store")]})
            await send({"type": "http.response.body", "body": _REFUSED})
            return
        message = await receive()  # websocket.connect
        if message["type"] == "websocket.connect":
            await send({"type": "websocket.close", "code": 1008})
