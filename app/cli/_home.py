"""``swarmshow home SHOW (--csv FILE | --boxes PER_BOX ...) [-o OUT]``: set a show's launch layout."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from app.cli._common import EXIT_OK, CliError, load_show_arg, output_path, read_bounded, write_atomically


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``home`` command."""
    p = sub.add_parser("home", help="set a show's home positions from a CSV file or launch boxes (writes the show)")
    p.add_argument("show", metavar="SHOW", help="show file (JSON; - reads standard input)")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--csv", metavar="FILE", help="home points: Skybrush 'Name,x,y,z' rows or plain 'x,y[,z]' rows")
    src.add_argument("--boxes", metavar="PER_BOX", type=int, help="launch boxes holding PER_BOX drones each")
    p.add_argument("--box-cols", type=int, default=None, help="drones per row inside a box (default: ~sqrt)")
    p.add_argument("--box-spacing", type=float, default=0.8, help="drone spacing inside a box, m (default 0.8)")
    p.add_argument("--rows", type=int, default=None, help="rows of boxes (default: as square as fits)")
    p.add_argument("--cols", type=int, default=None, help="columns of boxes")
    p.add_argument("--grid-spacing", type=float, default=6.0, help="distance between box centres, m (default 6)")
    p.add_argument("-o", "--output", metavar="OUT", help="write the show here (default: stdout)")
    p.set_defaults(func=_home)


def _home(args: argparse.Namespace) -> int:
    import math

    from formations import (
        MAX_HOME_CSV_BYTES,
        HomeCsvError,
        ShowValidationError,
        dump_show,
        home_points_from_csv,
        parse_show,
    )

    show = load_show_arg(args.show)
    home: dict[str, Any]
    if args.csv is not None:
        try:
            points, _ = home_points_from_csv(read_bounded(args.csv, MAX_HOME_CSV_BYTES, what="home CSV"))
        except HomeCsvError as exc:
            raise CliError(f"{args.csv}: {exc}") from exc
        home = {"points": points}
    else:
        for flag, value in (("--rows", args.rows), ("--cols", args.cols), ("--box-cols", args.box_cols)):
            if value is not None and value < 1:  # an explicit 0 must not read as "not given" below
                raise CliError(f"{flag} must be >= 1, got {value}")
        boxes = max(1, math.ceil(show.drones / max(args.boxes, 1)))
        cols = args.cols or (math.ceil(boxes / args.rows) if args.rows else math.ceil(math.sqrt(boxes)))
        rows = args.rows or math.ceil(boxes / cols)
        box: dict[str, Any] = {"per_box": args.boxes, "spacing_m": args.box_spacing,
                               "grid": {"rows": rows, "cols": cols, "spacing_m": args.grid_spacing}}
        if args.box_cols is not None:
            box["cols"] = args.box_cols
        home = {"boxes": box}
    doc = show.model_dump(mode="json", exclude_none=True)
    doc["home"] = home
    try:
        new = parse_show(doc)
    except ShowValidationError as exc:
        raise CliError(exc.one_line()) from exc
    text = dump_show(new) + "\n"
    if args.output:
        write_atomically(output_path(args.output), text.encode())
    else:
        sys.stdout.write(text)
    return EXIT_OK
