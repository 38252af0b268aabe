"""The viewer's clock over HTTP, so that the editor's music plays in sync with the 3D view (issue 18).

viser's browser page runs no code of ours, so the sound is played by the editor page: it reads the
clock of the playbacks showing its show (``GET /api/viewer/clock``) and follows them (start, stop,
seek, speed), and it drives them from its own music lane (``POST /api/viewer/transport``).
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

from fastapi import APIRouter, Query, Request
from pydantic import BaseModel, ConfigDict, Field


class ClockOut(BaseModel):
    """The clock of a playback: show time, whether it runs, speed; ``show`` None when none shows it."""

    show: str | None
    time_s: float
    playing: bool
    speed: float
    duration_s: float | None


class TransportIn(BaseModel):
    """Body of ``POST /api/viewer/transport``: any of seek, play / pause, speed."""

    model_config = ConfigDict(extra="forbid")
    show_id: str | None = Field(None, max_length=64, description="Only the playbacks showing this show.")
    time_s: float | None = Field(None, ge=0, le=86_400, description="Seek to this show time, seconds.")
    playing: bool | None = Field(None, description="Play (true) or pause (false).")
    speed: float | None = Field(None, ge=0.25, le=8, description="Playback speed factor.")
    sender: str | None = Field(None, min_length=1, max_length=64,
                               description="Who sends it (an editor tab's lane); with ``seq``, see there.")
    seq: int | None = Field(None, ge=0, le=2**53, description=(
        "The sender's request number, increasing: a request that arrives after a later one of the same sender "
        "is ignored (two requests in flight travel on separate connections and can arrive in either order)."))


#: Senders whose last request number is remembered (the least recently heard of are forgotten first).
MAX_SENDERS = 1024


def _playbacks(viewer: Any, show_id: str | None) -> list[Any]:
    """The playbacks showing ``show_id`` (registry names end with ``[id8]``), or all of them."""
    pbs = list(viewer.playbacks)
    if not show_id:
        return pbs
    tag = f"[{show_id[:8]}]"
    return [pb for pb in pbs if (pb.current or "").endswith(tag)]


def clock_router() -> APIRouter:
    """``GET /viewer/clock`` and ``POST /viewer/transport`` (include with prefix ``/api``)."""
    from app.api.models import error_responses

    router = APIRouter(tags=["viewer"])
    # The last request number applied per sender (only the event loop touches it).
    last_seq: OrderedDict[str, int] = OrderedDict()

    def viewer_of(request: Request) -> Any:
        # No viewer (switched off): no playback shows anything, so nothing plays (not an error).
        return getattr(request.app.state, "viewer", None)

    def clock(viewer: Any, show_id: str | None) -> ClockOut:
        pbs = [] if viewer is None else _playbacks(viewer, show_id)
        # A running playback is the one the user watches; else the newest browser's (the editor's frame).
        pb = next((p for p in pbs if p.playing), pbs[-1] if pbs else None)
        if pb is None:
            return ClockOut(show=None, time_s=0.0, playing=False, speed=1.0, duration_s=None)
        track = getattr(pb, "_track", None)
        return ClockOut(show=pb.current, time_s=float(pb.time_s), playing=bool(pb.playing), speed=float(pb.speed),
                        duration_s=None if track is None else float(track.duration_s))

    @router.get("/viewer/clock", response_model=ClockOut, summary="The 3D viewer's playback clock",
                responses=error_responses(422))
    async def get_clock(
        request: Request, show_id: str | None = Query(None, max_length=64, description="Of this show's playbacks.")
    ) -> ClockOut:
        """Show time, play state and speed of the viewer's playback of ``show_id`` (the editor's sound follows it)."""
        return clock(viewer_of(request), show_id)

    @router.post("/viewer/transport", response_model=ClockOut, summary="Seek, play or pause the 3D viewer",
                 responses=error_responses(422))
    async def transport(request: Request, body: TransportIn) -> ClockOut:
        """Apply a seek, play / pause and speed to the playbacks of ``show_id`` (all when not given)."""
        viewer = viewer_of(request)
        if body.sender is not None and body.seq is not None:
            last = last_seq.get(body.sender)
            if last is not None and body.seq <= last:
                return clock(viewer, body.show_id)  # overtaken by a later request: that one stands
            last_seq[body.sender] = body.seq
            last_seq.move_to_end(body.sender)
            while len(last_seq) > MAX_SENDERS:
                last_seq.popitem(last=False)
        for pb in [] if viewer is None else _playbacks(viewer, body.show_id):
            if body.speed is not None:
                pb.set_speed(body.speed)
            if body.time_s is not None:
                pb.seek(body.time_s)
            if body.playing is True:
                pb.play()
            elif body.playing is False:
                pb.pause()
        return clock(viewer, body.show_id)

    return router


__all__ = ["ClockOut", "TransportIn", "clock_router"]
