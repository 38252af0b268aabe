"""Security headers on every answer, and refusal of cross-site writes.

* ``X-Content-Type-Options: nosniff``, ``Referrer-Policy: no-referrer`` everywhere;
* a strict ``Content-Security-Policy``: the editor loads only its own files
  (no inline script or style); viser's client page inlines its bundle, styles
  and fonts, builds web workers from blobs, compiles WebAssembly and evaluates
  generated code (Chromium reports it without ``'unsafe-eval'``), so ``/viser/``
  gets exactly those allowances; API answers may not be framed or
  run anything; the interactive API docs (FastAPI's, from a CDN) keep what they
  need. Only same-origin pages may frame the app (the editor's 3D preview).
* No CORS headers are ever sent, so browsers keep other sites from reading answers.
  Browsers still *send* some cross-site writes without asking (a form posting
  text/plain), so a write whose ``Origin`` (or ``Sec-Fetch-Site``) says it comes
  from another site is refused with 403 before it reaches a handler. Without
  this, any web page a designer visits could create shows on their loopback server.
"""

from __future__ import annotations

import json
from urllib.parse import urlsplit

from starlette.types import ASGIApp, Message, Receive, Scope, Send

EDITOR_CSP = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; "
    "font-src 'self'; media-src 'self' blob:; connect-src 'self'; frame-src 'self'; worker-src 'self'; "
    "object-src 'none'; "
    "base-uri 'none'; form-action 'self'; frame-ancestors 'self'"
)
VISER_CSP = (
    "default-src 'self'; script-src 'self' 'unsafe-inline' 'unsafe-eval' 'wasm-unsafe-eval' blob:; "
    "style-src 'self' 'unsafe-inline'; img-src 'self' data: blob:; font-src 'self' data:; "
    "connect-src 'self' data: blob:; worker-src 'self' blob:; object-src 'none'; base-uri 'none'; "
    "form-action 'self'; frame-ancestors 'self'"
)
API_CSP = "default-src 'none'; frame-ancestors 'none'"
DOCS_CSP = (
    "default-src 'self'; script-src 'self' 'unsafe-inline' https://cdn.jsdelivr.net; "
    "style-src 'self' 'unsafe-inline' https://cdn.jsdelivr.net; img-src 'self' data: https://fastapi.tiangolo.com; "
    "worker-src 'self' blob:; object-src 'none'; base-uri 'none'; frame-ancestors 'none'"
)
_DOCS = ("/api/docs", "/api/redoc", "/api/docs/oauth2-redirect")
_SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


def csp_for(path: str) -> str:
    """The ``Content-Security-Policy`` of an answer at ``path``."""
    if path in _DOCS:
        return DOCS_CSP
    if path == "/viser" or path.startswith("/viser/"):
        return VISER_CSP
    if path.startswith("/api/") or path == "/api":
        return API_CSP
    return EDITOR_CSP


def _header(scope: Scope, name: bytes) -> str | None:
    for key, value in scope.get("headers", ()):
        if key == name:
            return value.decode("latin-1")
    return None


def cross_site(scope: Scope) -> bool:
    """True when the browser says the request comes from another site (never for non-browser clients)."""
    if (_header(scope, b"sec-fetch-site") or "").lower() == "cross-site":
        return True
    origin = _header(scope, b"origin")
    if origin is None:
        return False
    host = (_header(scope, b"host") or "").lower()
    if origin == "null":
        return True  # sandboxed frames, file:// pages and data: URLs: never our editor
    return urlsplit(origin).netloc.lower() != host


class SecurityHeadersMiddleware:
    """Pure ASGI middleware adding the headers above and refusing cross-site writes (403)."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "websocket" and _header(scope, b"origin") is not None and cross_site(scope):
            # A websocket is never subject to CORS: without this check any page could drive the viewer.
            await receive()
            await send({"type": "websocket.close", "code": 1008})
            return
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        extra = [
            (b"x-content-type-options", b"nosniff"),
            (b"referrer-policy", b"no-referrer"),
            (b"content-security-policy", csp_for(scope["path"]).encode()),
            (b"x-frame-options", b"SAMEORIGIN"),
        ]
        if scope["method"] not in _SAFE_METHODS and cross_site(scope):
            body = json.dumps({"detail": "cross-site request refused"}).encode()
            await send({"type": "http.response.start", "status": 403, "headers": [
                (b"content-type", b"application/json"), (b"content-length", str(len(body)).encode()), *extra]})
            await send({"type": "http.response.body", "body": body})
            return

        async def with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                present = {k.lower() for k, _ in message.get("headers", ())}
                message = {**message, "headers": [*message.get("headers", ()),
                                                  *(h for h in extra if h[0] not in present)]}
            await send(message)

        await self.app(scope, receive, with_headers)
