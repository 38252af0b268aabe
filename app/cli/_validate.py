"""``swarmshow validate SHOW`` and ``swarmshow schema``."""

from __future__ import annotations

import argparse
import json

from app.cli._common import EXIT_OK, CliError, load_show_arg, print_json


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``validate`` and ``schema`` commands."""
    p = sub.add_parser("validate", help="check that a show file is valid (exit 2 with the reason if not)")
    p.add_argument("show", metavar="SHOW", help="show file (JSON; - reads standard input)")
    p.add_argument("--json", action="store_true", help="print a JSON summary on stdout")
    p.set_defaults(func=_validate)

    p = sub.add_parser("schema", help="print the JSON Schema of the show file format")
    p.set_defaults(func=_schema)


def _validate(args: argparse.Namespace) -> int:
    from formations import ShowValidationError

    try:
        show = load_show_arg(args.show)
    except CliError as exc:
        problems = exc.__cause__.errors if isinstance(exc.__cause__, ShowValidationError) else None
        if problems is None:
            raise
        # The one-line reason names the first problem; every one of them is what this command is for.
        if args.json:
            print_json({"valid": False, "errors": [{"path": e["path"], "msg": e["msg"]} for e in problems]})
        elif len(problems) > 1:
            text = str(exc)  # "...: first problem (and N more problems)"
            raise CliError(f"{text[:-1]}; swarmshow validate --json lists them)" if text.endswith(")")
                           else f"{text} (swarmshow validate --json lists them all)") from exc
        raise
    summary = {
        "valid": True,
        "name": show.name,
        "drones": show.drones,
        "formations": len(show.formations),
        "content_hash": show.content_hash(),
    }
    if args.json:
        print_json(summary)
    else:
        print(f"{args.show}: valid ({show.drones} drones, {len(show.formations)} formations)")
    return EXIT_OK


def _schema(args: argparse.Namespace) -> int:
    from formations import show_json_schema

    print(json.dumps(show_json_schema(), indent=2))
    return EXIT_OK
