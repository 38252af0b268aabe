"""HTTP pieces shared by the server's middleware and the API's routes (one layer below both).

* the session token and cookie: :func:`bearer_ok`, :func:`session_value`,
  :func:`session_ok` and the cookie's name :data:`COOKIE` (used by
  ``app.server``'s token middleware and by ``POST /api/session``);
* :class:`BodyTooLarge`, the 413 raised by ``app.server``'s body-limit
  middleware while a body arrives and by the API's routes after parsing.

Keeping them here lets ``app.server`` import ``app.api`` (it mounts the routes)
without ``app.api`` importing ``app.server`` back.
"""

from __future__ import annotations

import hashlib
import hmac
import time

from starlette.exceptions import HTTPException

#: Name of the session cookie.
COOKIE = "swarmshow_session"


def bearer_ok(header: str | None, *, token: str) -> bool:
    """True when ``header`` is ``Bearer <token>`` (constant-time comparison)."""
    if not header:
        return False
    scheme, _, given = header.partition(" ")
    if scheme.lower() != "bearer":
        return False
    return hmac.compare_digest(given.strip().encode(), token.encode())


def session_value(*, token: str, ttl_s: int, now: float | None = None) -> str:
    """A cookie value valid for ``ttl_s`` seconds, signed with the token.

    The value is ``<expiry>.<HMAC-SHA256(token, expiry)>``: nothing to store on the
    server, it dies with its expiry, and changing the token revokes every cookie.
    """
    expiry = str(int((time.time() if now is None else now) + ttl_s))
    return f"{expiry}.{_sign(token, expiry)}"


def session_ok(value: str | None, *, token: str, now: float | None = None) -> bool:
    """True when ``value`` is an unexpired cookie signed with ``token``."""
    if not value:
        return False
    expiry, _, signature = value.partition(".")
    if not expiry.isdigit() or not hmac.compare_digest(signature.encode(), _sign(token, expiry).encode()):
        return False
    return int(expiry) > (time.time() if now is None else now)


def _sign(token: str, expiry: str) -> str:
    return hmac.new(token.encode(), f"swarmshow-session:{expiry}".encode(), hashlib.sha256).hexdigest()


class BodyTooLarge(HTTPException):
    """413 (an ``HTTPException`` so that FastAPI's body parsing passes it through untouched)."""

    def __init__(self, what: str, limit: int, *, size: int | None = None) -> None:
        got = f"is {size} bytes" if size is not None else "is larger"
        super().__init__(413, f"request body {got}; the limit for {what} is {_human(limit)} ({limit} bytes)")


def _human(n: int) -> str:
    return f"{n / 2**20:g} MB" if n >= 2**20 else f"{n / 2**10:g} KB"
