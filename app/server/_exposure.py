"""Who may reach the server: loopback by default; any other address only with a token."""

from __future__ import annotations

import ipaddress

from app.settings import AppSettings

#: Names that always resolve to this machine.
LOOPBACK_NAMES = frozenset({"localhost", "localhost.localdomain", "ip6-localhost"})


def is_loopback(host: str) -> bool:
    """True when ``host`` (an address or a name) only listens on this machine."""
    name = host.strip().strip("[]").lower()
    if name in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False  # a host name other than localhost: it may resolve to anything


def exposure_problem(settings: AppSettings) -> str | None:
    """Why the server must not start with these settings, or None.

    Binding a non-loopback address (``0.0.0.0``, a LAN address, a host name) makes
    every show reachable by others, so it needs ``SWARMSHOW_TOKEN``.
    """
    if is_loopback(settings.host) or settings.token is not None:
        return None
    return (
        f"refusing to listen on {settings.host}: other machines could reach it. Set SWARMSHOW_TOKEN "
        "(at least 16 characters, e.g. from `python -c \"import secrets; print(secrets.token_urlsafe())\"`) "
        "and clients send it as 'Authorization: Bearer <token>', or listen on 127.0.0.1"
    )
