"""The ``swarmshow`` command line.

Exit codes (DESIGN.md): 0 success, 1 the show is unsafe / the check failed,
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


def build_parser() -> argparse.ArgumentParser:
    """Return the top-level parser with every command registered."""
    parser = argparse.ArgumentParser(
        prog="swarmshow",
        description="Design, plan, verify, fly and export drone light shows.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in _COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns (and exits with) the process exit code."""
    parser = build_parser()
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
