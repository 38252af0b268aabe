"""A real ``swarmshow serve`` process for live tests: start, wait until it answers, crash, stop."""

from __future__ import annotations

import atexit
import contextlib
import json
import os
import random
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import httpx
import pytest

#: Debian's chromium (``playwright install`` cannot download browsers here).
CHROMIUM = "/usr/bin/chromium"
#: Where browser tests put their screenshots (gitignored).
SHOTS = Path(__file__).resolve().parent / "screenshots"
#: Marks for a module of browser tests: skipped where chromium is missing.
BROWSER_MARKS = [
    pytest.mark.browser,
    pytest.mark.skipif(not Path(CHROMIUM).exists(), reason="needs Debian's chromium at /usr/bin/chromium"),
]


#: How long a browser test's ``expect(...)`` retries, milliseconds (Playwright's default is 5 s). A busy CI
#: machine takes longer than that to save, render or answer, and an assertion that waits for its condition
#: proves as much with more patience: the same as the pages' default timeout (``Page``, 15 s).
EXPECT_TIMEOUT_MS = 15_000

T = TypeVar("T")


def wait_until(what: str, fn: Callable[[], T], timeout_s: float = 60.0, interval_s: float = 0.05,
               sleep: Callable[[float], object] = time.sleep) -> T:
    """Poll ``fn`` until it returns a truthy value, which is returned; fail naming ``what`` and the last value.

    For conditions outside a page (the server, several pages, a computed reading): a test waits for what it
    means rather than sleeping for a time sized for a quiet machine. ``sleep`` waits between polls: pass
    ``lambda s: page.wait_for_timeout(1000 * s)`` when the condition needs Playwright's route handlers, which
    only run inside Playwright's own calls.
    """
    deadline = time.monotonic() + timeout_s
    while True:
        value = fn()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s:g} s waiting for {what} (last: {value!r})")
        sleep(interval_s)


def ephemeral_port_range() -> tuple[int, int]:
    """The kernel's range of ports it gives to outgoing connections (Linux's default when unreadable)."""
    try:
        low, high = (int(v) for v in Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split())
    except (OSError, ValueError):
        return 32768, 60999
    return low, high


def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now, below the kernel's ephemeral range.

    Why below: a test that restarts a server on its port while its clients keep reconnecting (the SIGKILL
    tests) found the port taken by a client. A connect() to a closed port inside the ephemeral range can be
    given that very port as its local one and connect to itself (TCP simultaneous open), holding it.
    """
    low, _ = ephemeral_port_range()
    rng = random.Random()
    for _ in range(500):
        port = rng.randrange(max(1024, low - 16384), low)
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    raise RuntimeError("no free port below the ephemeral range")


def swarmshow_command() -> list[str]:
    """The installed ``swarmshow`` next to this interpreter, or ``python -c`` running the CLI."""
    exe = shutil.which("swarmshow", path=str(Path(sys.executable).parent))
    return [exe] if exe else [sys.executable, "-c", "import sys; from app.cli import main; sys.exit(main())"]


class ServerProcess:
    """``swarmshow serve`` on a loopback port in its own process group (so a crash takes its workers too)."""

    def __init__(self, data_dir: Path, *, port: int | None = None, workers: int = 1, viewer: bool = False,
                 env: dict[str, str] | None = None) -> None:
        self.data_dir, self.port, self.workers = data_dir, port or free_port(), workers
        self.env = {**os.environ, "PYTHONUNBUFFERED": "1", "SWARMSHOW_VIEWER": "true" if viewer else "false",
                    **(env or {})}
        self.proc: subprocess.Popen | None = None
        self.log = data_dir / "server.log"

    @property
    def base(self) -> str:
        """The server's base URL."""
        return f"http://127.0.0.1:{self.port}"

    def start(self, *, wait: bool = True, timeout_s: float = 60.0) -> float:
        """Start the server; returns the seconds until ``/api/health`` answered (0 if not waited for)."""
        t0 = time.monotonic()
        with open(self.log, "ab") as log:
            self.proc = subprocess.Popen(
                [*swarmshow_command(), "serve", "--port", str(self.port), "--data-dir", str(self.data_dir),
                 "--workers", str(self.workers)],
                stdout=log, stderr=subprocess.STDOUT, env=self.env, start_new_session=True,
            )
        if not wait:
            return 0.0
        self.wait_ready(timeout_s=timeout_s)
        return time.monotonic() - t0

    def wait_ready(self, *, timeout_s: float = 60.0, headers: dict[str, str] | None = None) -> None:
        """Wait until ``/api/health`` answers (any status below 500)."""
        deadline = time.monotonic() + timeout_s
        while True:
            try:
                if httpx.get(f"{self.base}/api/health", timeout=1, headers=headers).status_code < 500:
                    return
            except httpx.TransportError:
                pass
            if self.proc is None or self.proc.poll() is not None or time.monotonic() > deadline:
                raise AssertionError(f"server did not start: {self.log.read_text(errors='replace')[-3000:]}")
            time.sleep(0.03)

    def crash(self) -> None:
        """SIGKILL the server and every process it started (its worker pool and manager)."""
        if self.proc is None:
            return
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait()
        self.proc = None

    def stop(self) -> None:
        """Stop the server gracefully (SIGINT), or crash it if it does not stop in 30 s."""
        if self.proc is None:
            return
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            pass
        self.crash()


#: The fork server of :class:`ForkedServerProcess`: imports the code ``swarmshow serve`` imports, then
#: answers one JSON command a line on stdin: ``["start", argv, log, env]`` forks a child that runs the CLI
#: with ``argv`` and the environment ``env`` in a session of its own, its output appended to ``log``
#: (answers its pid); ``["poll", pid]`` answers its exit status or null while it runs; ``["wait", pid]`` its
#: exit status. The child's modules were imported under the fork server's environment (the test session's):
#: the server reads its own settings (``SWARMSHOW_*``) when it starts, not on import.
_FORK_SERVER = """
import json, os, sys
import uvicorn
import app.cli, app.cli._serve, app.server, app.server._exposure, app.server._http
app.cli.build_parser(["serve"])
for line in sys.stdin:
    cmd = json.loads(line)
    if cmd[0] == "start":
        sys.stdout.flush()
        pid = os.fork()
        if pid == 0:
            os.setsid()
            out = os.open(cmd[2], os.O_WRONLY | os.O_APPEND | os.O_CREAT)
            os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
            os.dup2(out, 1)
            os.dup2(out, 2)
            sys.stdout.reconfigure(line_buffering=True)
            os.environ.clear()
            os.environ.update(cmd[3])
            sys.exit(app.cli.main(cmd[1]))
        answer = pid
    else:
        done, status = os.waitpid(cmd[1], os.WNOHANG if cmd[0] == "poll" else 0)
        answer = os.waitstatus_to_exitcode(status) if done else None
    print(json.dumps(answer), flush=True)
"""


class _ForkServer:
    """The test session's one fork server (:data:`_FORK_SERVER`), started on first use, ended at exit."""

    def __init__(self) -> None:
        self.proc: subprocess.Popen[str] | None = None
        self.lock = threading.Lock()

    def ask(self, *cmd: Any) -> Any:
        with self.lock:
            if self.proc is None:
                self.proc = subprocess.Popen([sys.executable, "-c", _FORK_SERVER], stdin=subprocess.PIPE,
                                             stdout=subprocess.PIPE, text=True)
                atexit.register(self.close)
            assert self.proc.stdin is not None and self.proc.stdout is not None
            self.proc.stdin.write(json.dumps(cmd) + "\n")
            self.proc.stdin.flush()
            line = self.proc.stdout.readline()
            if not line:
                raise AssertionError(f"the fork server exited ({self.proc.wait()})")
            return json.loads(line)

    def close(self) -> None:
        with self.lock:
            if self.proc is None:
                return
            if self.proc.stdin is not None:
                self.proc.stdin.close()
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
            self.proc = None


_fork_server = _ForkServer()


class _ForkedChild:
    """A server forked by the fork server: the part of :class:`subprocess.Popen` that ServerProcess uses."""

    def __init__(self, pid: int) -> None:
        self.pid = pid
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            self.returncode = _fork_server.ask("poll", self.pid)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        if deadline is None and self.returncode is None:
            self.returncode = _fork_server.ask("wait", self.pid)
        while self.poll() is None:
            if deadline is not None and time.monotonic() > deadline:
                raise subprocess.TimeoutExpired("swarmshow serve", timeout or 0.0)
            time.sleep(0.02)
        return self.returncode  # type: ignore[return-value]

    def send_signal(self, sig: int) -> None:
        if self.returncode is None:
            os.kill(self.pid, sig)


class ForkedServerProcess(ServerProcess):
    """:class:`ServerProcess` whose servers are forked from one process that has imported the server's code
    (the fork server, :data:`_FORK_SERVER`), so that a start costs the server's own start-up (store, worker
    pools, port) but not the seconds of importing its Python modules again. For tests of what a running server
    does (browser tests, a server crashed and restarted 50 times); the real ``swarmshow serve`` start-up is
    what :class:`ServerProcess` runs. The forked server runs the CLI's ``main(["serve", ...])`` with this
    object's environment, in a session of its own (:meth:`crash` kills it with its worker processes)."""

    def start(self, *, wait: bool = True, timeout_s: float = 60.0) -> float:
        t0 = time.monotonic()
        argv = ["serve", "--port", str(self.port), "--data-dir", str(self.data_dir), "--workers", str(self.workers)]
        self.proc = _ForkedChild(_fork_server.ask("start", argv, str(self.log), self.env))  # type: ignore[assignment]
        if not wait:
            return 0.0
        self.wait_ready(timeout_s=timeout_s)
        return time.monotonic() - t0


@contextlib.contextmanager
def running_server(data_dir: Path, *, forked: bool = False, **kwargs: Any) -> Iterator[str]:
    """A started :class:`ServerProcess` (keyword arguments as its constructor's; ``forked``: a
    :class:`ForkedServerProcess`); yields its base URL."""
    srv = (ForkedServerProcess if forked else ServerProcess)(data_dir, **kwargs)
    srv.start()
    try:
        yield srv.base
    finally:
        srv.stop()


def server_for(name: str, **kwargs: Any) -> Any:
    """A module-scoped ``server`` fixture for a browser test module: :func:`running_server` (keyword
    arguments as :class:`ServerProcess`'s) on a fresh data directory of its own, named after ``name``;
    its value is the base URL. Use it at module level as ``server = server_for("x-data", viewer=True)``.
    The server is forked (:class:`ForkedServerProcess`): the browser tests test the running server, and
    each module's start no longer imports the server's code again."""

    @pytest.fixture(scope="module", name="server")
    def _server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
        with running_server(tmp_path_factory.mktemp(name), forked=True, **kwargs) as base:
            yield base

    return _server


class _Chromiums:
    """The test session's one Playwright driver and its chromium browsers, one for each set of command-line
    arguments: launched on first use and reused by the browser modules after it (a driver and browser start
    took about 2 s of each module's setup), launched again if it crashed (disconnected), so a crash still
    stays with the module it happened in. Playwright's sync API allows one driver a thread: every browser of
    the session comes from this one. Closed by :func:`close_chromiums` at the end of the session."""

    def __init__(self) -> None:
        self.driver: Any = None
        self.browsers: dict[tuple[str, ...], Any] = {}

    def get(self, args: tuple[str, ...]) -> Any:
        from playwright import sync_api

        sync_api.expect.set_options(timeout=EXPECT_TIMEOUT_MS)
        if self.driver is None:
            self.driver = sync_api.sync_playwright().start()
        b = self.browsers.get(args)
        if b is None or not b.is_connected():
            b = self.driver.chromium.launch(executable_path=CHROMIUM, headless=True, args=list(args))
            self.browsers[args] = b
        return b

    def close(self) -> None:
        for b in self.browsers.values():
            with contextlib.suppress(Exception):  # one that crashed is gone already
                b.close()
        self.browsers.clear()
        if self.driver is not None:
            self.driver.stop()
            self.driver = None


_chromiums = _Chromiums()


def close_chromiums() -> None:
    """Close the session's browsers and Playwright driver (tests/conftest.py, at the end of the session)."""
    _chromiums.close()


@contextlib.contextmanager
def chromium_browser(*args: str) -> Iterator[Any]:
    """Debian's chromium under Playwright, headless, with extra command-line ``args``; ``expect(...)``
    retries for :data:`EXPECT_TIMEOUT_MS`. The session's browser for these ``args`` (:class:`_Chromiums`);
    the contexts (and their pages) opened while it is held are closed on exit, as closing a browser of its
    own did: nothing one module leaves open (a page playing in 3D) runs on beside the next."""
    b = _chromiums.get(tuple(args))
    before = set(b.contexts)
    try:
        yield b
    finally:
        if b.is_connected():
            for ctx in b.contexts:
                if ctx not in before:
                    ctx.close()
