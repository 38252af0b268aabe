"""uvicorn's h11 protocol with a header-read timeout (slow-loris connections are closed).

uvicorn closes an idle keep-alive connection after ``timeout_keep_alive``, but a
connection that sends its request line and headers a byte at a time is never timed
out: 1,520 of them held every file descriptor of a server. Here every connection
must finish its request headers within ``header_timeout_s`` of connecting (or of its
previous response), or it is closed. A connection upgraded to a websocket has finished
its headers: its timer is cancelled at the upgrade.
"""

from __future__ import annotations

import asyncio
from typing import Any

from uvicorn.protocols.http.h11_impl import H11Protocol


def protocol_class(header_timeout_s: float) -> type[H11Protocol]:
    """An :class:`H11Protocol` subclass closing connections whose headers take over ``header_timeout_s``."""

    class HeaderTimeoutH11Protocol(H11Protocol):
        _header_timer: asyncio.TimerHandle | None = None
        _armed_cycle: Any = None

        def _arm(self) -> None:
            self._disarm()
            self._armed_cycle = self.cycle
            self._header_timer = self.loop.call_later(header_timeout_s, self._headers_too_slow)

        def _disarm(self) -> None:
            if self._header_timer is not None:
                self._header_timer.cancel()
                self._header_timer = None

        def _headers_too_slow(self) -> None:
            self._header_timer = None
            if self.cycle is self._armed_cycle and not self.transport.is_closing():
                self.transport.close()

        def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
            super().connection_made(transport)
            self._arm()

        def data_received(self, data: bytes) -> None:
            super().data_received(data)
            if self.cycle is not self._armed_cycle:  # a whole request line and headers arrived
                self._disarm()

        def handle_websocket_upgrade(self, event: Any) -> None:
            # The upgrade hands the transport to a websocket protocol and never starts a request
            # cycle, so data_received above does not disarm the timer: left armed it closed every
            # websocket (the 3D view's) header_timeout_s after it opened, and viser's client came
            # back as a new client with a fresh playback (issue 17, bug 5).
            self._disarm()
            super().handle_websocket_upgrade(event)

        def on_response_complete(self) -> None:
            super().on_response_complete()
            if not self.transport.is_closing():
                self._arm()  # the next request on this keep-alive connection gets the same deadline

        def connection_lost(self, exc: Exception | None) -> None:
            self._disarm()
            super().connection_lost(exc)

    return HeaderTimeoutH11Protocol
