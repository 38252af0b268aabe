"""``swarmshow serve`` and ``swarmshow demo``: run the web server (API, editor, viewer)."""

from __future__ import annotations

import argparse
import errno
import socket
import sys
from pathlib import Path
from typing import Any

from app.cli._common import EXIT_OK, CliError


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``serve`` and ``demo`` commands."""
    for name, help_text in (
        ("serve", "run the web server: REST API under /api, the editor at /"),
        ("demo", "run the web server with the bundled 100-drone demo show in the store"),
    ):
        p = sub.add_parser(name, help=help_text)
        p.add_argument("--host", default=None, help="address to listen on (default 127.0.0.1; "
                       "SWARMSHOW_HOST)")
        p.add_argument("--port", type=int, default=None, help="TCP port (default 8000; SWARMSHOW_PORT)")
        p.add_argument("--data-dir", default=None, metavar="DIR",
                       help="directory of the show store (default ./data; SWARMSHOW_DATA_DIR)")
        p.add_argument("--workers", type=int, default=None, help="worker processes (default min(2, CPUs))")
        p.set_defaults(func=_serve, seed_demo=(name == "demo"))


def _settings(args: argparse.Namespace):
    from pydantic import ValidationError

    from app.settings import AppSettings

    given = {k: v for k, v in (("host", args.host), ("port", args.port), ("data_dir", args.data_dir),
                               ("workers", args.workers)) if v is not None}
    try:
        return AppSettings(**given)
    except ValidationError as exc:
        err = exc.errors()[0]
        field = ".".join(map(str, err["loc"]))
        # The flag the operator typed, else the environment variable the value came from.
        where = f"--{field.replace('_', '-')}" if field in given else f"SWARMSHOW_{field.upper()}"
        raise CliError(f"{where}: {err['msg']}") from None


def _check_store(settings: Any) -> None:
    """Open (creating) the show store now, so that a data directory that cannot be made or written is one line
    naming ``--data-dir``, rather than a traceback in the server's start-up after it said it was serving."""
    from app.store import ShowStore, StoreError

    try:
        ShowStore(settings.db_path).close()
    except (StoreError, OSError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise CliError(f"--data-dir {settings.data_dir}: cannot use it for the show store: {reason}") from None


def seed_demo(data_dir: Path) -> tuple[str, bool]:
    """Store the bundled demo show unless a show with the same content is there; returns (id, added)."""
    from app.store import ShowStore, StoreError
    from formations._demo import load_demo_show

    show = load_demo_show()
    try:
        store = ShowStore(data_dir / "swarmshow.sqlite3")
    except StoreError as exc:
        raise CliError(str(exc)) from None
    try:
        existing = store.find_by_hash(show.content_hash())
        if existing is not None:
            return existing.id, False
        return store.create(show).id, True
    finally:
        store.close()


def _check_port(host: str, port: int) -> None:
    """Fail with a one-line reason now rather than after the app has started."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind((host, port))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise CliError(f"{host}:{port} is already in use (try --port)") from None
            raise CliError(f"cannot listen on {host}:{port}: {exc.strerror}") from None


def _serve(args: argparse.Namespace) -> int:
    import uvicorn

    from app.server import create_app
    from app.server._exposure import exposure_problem

    settings = _settings(args)
    problem = exposure_problem(settings)
    if problem is not None:
        raise CliError(problem)
    _check_port(settings.host, settings.port)
    _check_store(settings)
    shown_host = "127.0.0.1" if settings.host in ("0.0.0.0", "::", "") else settings.host
    url = f"http://{'[' + shown_host + ']' if ':' in shown_host else shown_host}:{settings.port}"
    if args.seed_demo:
        show_id, added = seed_demo(settings.data_dir)
        print(f"demo show {'added' if added else 'already in the store'}: {url}/api/shows/{show_id}", file=sys.stderr)
    print(f"swarmshow {'demo' if args.seed_demo else 'server'}: {url}/  (API docs: {url}/api/docs)",
          flush=True)
    from app.server._http import protocol_class

    uvicorn.run(create_app(settings), host=settings.host, port=settings.port, log_level="info",
                access_log=settings.access_log, http=protocol_class(settings.header_timeout_s),
                timeout_keep_alive=settings.timeout_keep_alive_s, timeout_graceful_shutdown=5)
    return EXIT_OK
