"""Helpers shared by the command modules: errors, show loading, JSON output, progress."""

from __future__ import annotations

import errno
import json
import os
import select
import stat
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2


def show_library_notes() -> None:
    """Print the ``sim`` packages' warnings on stderr, one ``swarmshow: ...`` line each (idempotent).

    Why: a first flight on a cold numba cache compiles the flight kernel for minutes, and the
    library says so as a warning (``sim.flight.engines._numba.COMPILE_NOTE``); without a handler it
    would reach stderr only through logging's last-resort handler, unprefixed. The handler is sim's
    (:func:`sim.flight._notes.say_notes`, which Dask workers use too: one handler, one line). It imports
    sim (about a second): ``app.cli.main`` calls this only for the commands that compute with it.
    """
    from sim.flight._notes import say_notes

    say_notes()


class CliError(Exception):
    """A one-line reason shown on stderr; ``exit_code`` is 2 (bad input) unless given."""

    def __init__(self, message: str, *, exit_code: int = EXIT_USAGE) -> None:
        super().__init__(message)
        self.exit_code = exit_code


#: Seconds a pipe or device given as input may take to deliver its bytes.
READ_TIMEOUT_S = 30.0


def read_bounded(path: str, limit: int, *, what: str = "file", timeout_s: float = READ_TIMEOUT_S) -> bytes:
    """The bytes of ``path``, refused past ``limit`` without reading further.

    Pipes and devices are read too (``<(cat show.json)``), but never hang: the file is
    opened non-blocking (a FIFO without a writer would block ``open`` forever) and read
    with ``select`` under ``timeout_s``; ``/dev/zero`` stops at the limit.

    Raises:
        CliError: missing, a directory, unreadable, a symlink loop, too large or too slow.
    """
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except FileNotFoundError:
        raise CliError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise CliError(f"{path}: is a directory") from None
    except OSError as exc:  # ELOOP (a symlink loop), EACCES, ENAMETOOLONG, ...
        raise CliError(f"{path}: {exc.strerror or exc}") from None
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise CliError(f"{path}: is a directory")
        chunks: list[bytes] = []
        size, deadline = 0, time.monotonic() + timeout_s
        while size <= limit:
            try:
                # A FIFO that no writer has opened reads as end of file at once (non-blocking open).
                chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            except BlockingIOError:  # a pipe whose writer has not written yet
                ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
                if not ready:
                    raise CliError(f"{path}: nothing to read for {timeout_s:g} s") from None
                continue
            except OSError as exc:
                raise CliError(f"{path}: {exc.strerror or exc}") from None
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if size > limit:
            raise CliError(f"{path}: the {what} is larger than the limit of {limit} bytes")
        return b"".join(chunks)
    finally:
        os.close(fd)


def output_path(text: str) -> Path:
    """An output argument (``-o OUT``) as a path; a name ending in ``/`` names a directory, which must exist
    (``Path`` drops the slash, and ``out/`` was written as a *file* called ``out``).

    Raises:
        CliError: a directory name that is not an existing directory.
    """
    if text.endswith(("/", os.sep)) and not Path(text).is_dir():
        raise CliError(f"{text}: no such directory")
    return Path(text)


def write_atomically(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` via a temporary file in the same directory, an fsync and a rename.

    A reader never sees a half-written file; a full disk (or any failure) leaves the previous
    file, if any, untouched and no temporary behind; a symlink at ``path`` is replaced, never
    written through to its target.

    Raises:
        CliError: the directory is not writable, the disk is full, ...
    """
    try:
        fd, tmp = tempfile.mkstemp(prefix=".swarmshow-", suffix=".tmp", dir=path.parent)
    except OSError as exc:
        raise CliError(f"{path}: cannot write: {exc.strerror or exc}") from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        reason = "the disk is full" if exc.errno in (errno.ENOSPC, errno.EFBIG, errno.EDQUOT) else exc.strerror
        raise CliError(f"{path}: cannot write: {reason or exc}; nothing was written") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def load_show_arg(path: str):  # -> formations.ShowFile (import kept lazy for start-up time)
    """Read (bounded, see :func:`read_bounded`) and validate a show file; ``-`` reads standard input (so that
    ``swarmshow home SHOW --boxes 10 | swarmshow check -`` composes). Bad input becomes a ``CliError`` (exit 2)."""
    from formations import MAX_SHOW_FILE_BYTES, ShowValidationError, parse_show

    label = "stdin" if path == "-" else path
    if path == "-" and not _stdin_open():
        raise CliError("stdin: is closed; pipe a show file in (swarmshow home SHOW | swarmshow check -) or give "
                       "its path")
    try:
        data = read_bounded("/dev/stdin" if path == "-" else path, MAX_SHOW_FILE_BYTES, what="show file")
    except CliError as exc:
        if path != "-":
            raise
        raise CliError(str(exc).replace("/dev/stdin", label, 1)) from None
    if not data.strip():
        raise CliError(f"{label}: is empty; expected a show file (JSON)")
    try:
        return parse_show(data)
    except ShowValidationError as exc:
        raise CliError(f"{label}: {exc.one_line()}") from exc


def _stdin_open() -> bool:
    """Whether this process has a standard input to read: ``<&-`` closes it, and Python then starts with
    ``sys.stdin`` None (and ``/dev/stdin`` names no file: "no such file" misled)."""
    if sys.stdin is None:
        return False
    try:
        os.fstat(0)
    except OSError:
        return False
    return True


def count(n: int, noun: str) -> str:
    """``"1 drone"``, ``"100 drones"``: a count with its noun in the right number."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def print_json(obj: Any) -> None:
    """Print one JSON object on stdout (numpy scalars and arrays are converted)."""
    print(json.dumps(obj, default=_json_default, allow_nan=False))


def _json_default(obj: Any) -> Any:
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


@contextmanager
def progress_bar(desc: str, *, enabled: bool = True) -> Iterator[Callable[[float], None]]:
    """Yield ``update(fraction)`` drawing a tqdm bar on stderr (hidden when not a TTY or disabled).

    The callback signature matches the ``progress`` arguments of the planning
    and simulation functions: a float in [0, 1].
    """
    from tqdm import tqdm

    bar = tqdm(
        total=1000,
        desc=desc,
        file=sys.stderr,
        disable=not enabled or not sys.stderr.isatty(),
        bar_format="{desc}: {percentage:3.0f}%|{bar}| {elapsed}<{remaining}",
        leave=False,
    )
    last = [0]

    def update(fraction: float) -> None:
        target = int(round(min(max(fraction, 0.0), 1.0) * 1000))
        if target > last[0]:
            bar.update(target - last[0])
            last[0] = target

    try:
        yield update
    finally:
        bar.close()
