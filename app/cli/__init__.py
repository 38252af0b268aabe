"""The ``swarmshow`` command line.

Exit codes: 0 success, 1 the show is unsafe / the check failed,
2 bad input or usage (with a one-line reason on stderr).

Each command lives in its own ``_<name>.py`` module exposing
``register(subparsers)``; the module adds its parser and sets ``func`` to a
callable ``(args) -> int``.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import os
import sys
from collections.abc import Sequence
from typing import NoReturn

from app.cli._common import CliError, show_library_notes

#: Exit code when the reader of stdout went away (128 + SIGPIPE, as a shell reports a command the pipe ended).
EXIT_BROKEN_PIPE = 141

# Order is the order shown by ``swarmshow --help``.
_COMMAND_MODULES: tuple[str, ...] = (
    "app.cli._validate",
    "app.cli._check",
    "app.cli._simulate",
    "app.cli._bench",
    "app.cli._formation",
    "app.cli._home",
    "app.cli._export",
    "app.cli._serve",
)


#: Command -> the module that registers it, so that running one command imports only its
#: module (``swarmshow validate`` must not pay for the flight simulation or the exports).
_COMMANDS: dict[str, str] = {
    "validate": "app.cli._validate",
    "schema": "app.cli._validate",
    "check": "app.cli._check",
    "simulate": "app.cli._simulate",
    "bench": "app.cli._bench",
    "formation": "app.cli._formation",
    "home": "app.cli._home",
    "export": "app.cli._export",
    "serve": "app.cli._serve",
    "demo": "app.cli._serve",
}


#: The commands that run ``sim`` in this process (plan, check, fly): they print its warnings (``show_library_notes``,
#: which imports it, about a second); the others do not pay for it (serve and demo fly in spawned workers, whose
#: jobs carry the notes: ``app.tasks.library_notes``).
_SIM_COMMANDS: tuple[str, ...] = ("check", "simulate", "bench", "export")


def _modules_for(argv: Sequence[str] | None) -> tuple[str, ...]:
    """The command modules to register: the named command's alone, or all of them (help, typos)."""
    args = list(sys.argv[1:] if argv is None else argv)
    first = next((a for a in args if not a.startswith("-")), None)
    if first in _COMMANDS and not any(a in ("-h", "--help") for a in args[: args.index(first)]):
        return (_COMMANDS[first],)
    return _COMMAND_MODULES


class _Parser(argparse.ArgumentParser):
    """argparse with the project's usage errors: one line on stderr (no usage block), exit 2. The
    subcommands' parsers are of this class too (``add_subparsers`` uses the parent's class)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")


def build_parser(argv: Sequence[str] | None = ()) -> argparse.ArgumentParser:
    """Return the top-level parser with the commands registered.

    Args:
        argv: the arguments about to be parsed; when they name a command only its
            module is imported and registered. The default ``()`` registers every
            command (``swarmshow --help`` lists them all).
    """
    parser = _Parser(
        prog="swarmshow",
        description="Design, plan, verify, fly and export drone light shows.",
    )
    from app.version import __version__

    # Which swarmshow a bug report is about (it was a usage error: "the following arguments are required").
    parser.add_argument("--version", action="version", version=f"swarmshow {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in _modules_for(argv):
        importlib.import_module(name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns (and exits with) the process exit code."""
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    if args.command in _SIM_COMMANDS:
        show_library_notes()
    if sys.stdout is None:  # started with stdout closed (``>&-``): results must not vanish silently
        sys.stdout = _ClosedStdout()
    try:
        code = int(args.func(args))
        sys.stdout.flush()
    except CliError as exc:
        print(f"swarmshow: error: {exc}", file=sys.stderr)
        code = exc.exit_code
    except (BrokenPipeError, OSError) as exc:
        if not _stdout_failed(exc):
            raise
        # The reader went away (``swarmshow schema | head -1``): it has what it wanted, so end quietly with
        # 141 (128 + SIGPIPE, what a shell reports for a command killed by the pipe); a closed or full stdout
        # is still an error, said in one line.
        reader_gone = isinstance(exc, BrokenPipeError) or exc.errno == errno.EPIPE
        if not reader_gone:
            print(f"swarmshow: error: cannot write to stdout: {exc.strerror or exc}", file=sys.stderr)
        # Python would flush stdout again at exit and print a traceback: point it at /dev/null.
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
        code = EXIT_BROKEN_PIPE if reader_gone else 2
    except KeyboardInterrupt:
        print("swarmshow: interrupted", file=sys.stderr)
        code = 130
    if argv is None:
        sys.exit(code)
    return code


class _ClosedStdout:
    """Stands in for a closed stdout: any write is a one-line error (exit 2), not a silent loss."""

    def write(self, _text: str) -> int:
        raise CliError("stdout is closed; nothing was written")

    @property
    def buffer(self) -> _ClosedStdout:
        return self

    def flush(self) -> None:
        pass

    def fileno(self) -> int:
        raise OSError(errno.EBADF, "stdout is closed")

    def isatty(self) -> bool:
        return False


def _stdout_failed(exc: OSError) -> bool:
    """True when ``exc`` came from writing stdout (a closed pipe, a closed or full descriptor)."""
    return isinstance(exc, BrokenPipeError) or exc.errno in (errno.EPIPE, errno.EBADF, errno.ENOSPC)
