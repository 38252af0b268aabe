"""The ``swarmshow`` command line.

Exit codes: 0 success, 1 the show is unsafe / the check failed,
2 bad input or usage (with a one-line reason on stderr).

Each command lives in its own ``_<name>.py`` module exposing
``register(subparsers)``; the module adds its parser and sets ``func`` to a
callable ``(args) -> int``.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

from app.cli._common import CliError

# Order is the order shown by ``swarmshow --help``.
_COMMAND_MODULES: tuple[str, ...] = (
    "app.cli._validate",
    "app.cli._check",
    "app.cli._simulate",
    "app.cli._bench",
    "app.cli._formation",
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
    "export": "app.cli._export",
    "serve": "app.cli._serve",
    "demo": "app.cli._serve",
}


def _modules_for(argv: Sequence[str] | None) -> tuple[str, ...]:
    """The command modules to register: the named command's alone, or all of them (help, typos)."""
    args = list(sys.argv[1:] if argv is None else argv)
    first = next((a for a in args if not a.startswith("-")), None)
    if first in _COMMANDS and not any(a in ("-h", "--help") for a in args[: args.index(first)]):
        return (_COMMANDS[first],)
    return _COMMAND_MODULES


def build_parser(argv: Sequence[str] | None = ()) -> argparse.ArgumentParser:
    """Return the top-level parser with the commands registered.

    Args:
        argv: the arguments about to be parsed; when they name a command only its
            module is imported and registered. The default ``()`` registers every
            command (``swarmshow --help`` lists them all).
    """
    parser = argparse.ArgumentParser(
        prog="swarmshow",
        description="Design, plan, verify, fly and export drone light shows.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in _modules_for(argv):
        importlib.import_module(name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns (and exits with) the process exit code."""
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    try:
        code = int(args.func(args))
    except CliError as exc:
        print(f"swarmshow: error: {exc}", file=sys.stderr)
        code = exc.exit_code
    except KeyboardInterrupt:
        print("swarmshow: interrupted", file=sys.stderr)
        code = 130
    if argv is None:
        sys.exit(code)
    return code
