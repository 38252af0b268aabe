"""The web server: the FastAPI application factory and its middleware."""

from __future__ import annotations

from app.server._app import EXTENSIONS as EXTENSIONS
from app.server._app import create_app as create_app

__all__ = ["EXTENSIONS", "create_app"]
