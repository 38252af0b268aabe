"""``POST /api/session``: trade the bearer token for a short-lived cookie (iframes, EventSource, websockets).

Browsers cannot add an ``Authorization`` header to an iframe, an ``EventSource``
or a websocket; the editor calls this once after asking for the token, and the
viewer iframe, the progress stream and the viewer's websocket then carry the
cookie (HttpOnly: page scripts cannot read it; SameSite=Strict: other sites'
pages cannot make the browser send it).
"""

from __future__ import annotations

from fastapi import APIRouter, Request, Response
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field

from app.api import deps
from app.api.models import error_responses
from app.web import COOKIE, bearer_ok, session_value

router = APIRouter(tags=["session"])


class SessionIn(BaseModel):
    """The server's token, if not sent as ``Authorization: Bearer``."""

    model_config = ConfigDict(extra="forbid")

    token: str | None = Field(None, max_length=1024, description="The server's token (SWARMSHOW_TOKEN).")


def _denied() -> JSONResponse:
    return JSONResponse({"detail": "unauthorized"}, status_code=401,
                        headers={"WWW-Authenticate": 'Bearer realm="swarmshow"', "Cache-Control": "no-store"})


@router.post(
    "/session", status_code=204, response_class=Response, summary="Start a browser session (cookie)",
    responses={401: {"model": error_responses(404)[404]["model"], "description": "Wrong or missing token."}},
)
async def start_session(request: Request, body: SessionIn | None = None) -> Response:
    """Check the token (body ``{"token": ...}`` or the ``Authorization`` header) and set the session
    cookie, valid for ``SWARMSHOW_SESSION_TTL_S`` seconds. Without a server token this is a no-op (204)."""
    settings = deps.settings(request)
    if settings.token is None:
        return Response(status_code=204)
    token = settings.token.get_secret_value()
    header = request.headers.get("authorization")
    given = body.token if body is not None and body.token is not None else None
    ok = bearer_ok(f"Bearer {given}", token=token) if given is not None else bearer_ok(header, token=token)
    if not ok:
        return _denied()
    response = Response(status_code=204, headers={"Cache-Control": "no-store"})
    response.set_cookie(
        COOKIE, session_value(token=token, ttl_s=settings.session_ttl_s), max_age=settings.session_ttl_s,
        path="/", httponly=True, samesite="strict", secure=request.url.scheme == "https",
    )
    return response


@router.delete("/session", status_code=204, response_class=Response, summary="End the browser session")
async def end_session() -> Response:
    """Clear the session cookie."""
    response = Response(status_code=204)
    response.delete_cookie(COOKIE, path="/", httponly=True, samesite="strict")
    return response
