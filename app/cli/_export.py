"""``swarmshow export SHOW --format FORMAT -o OUT``: write a show in a format flight tools load."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from app.cli._common import EXIT_OK, CliError, load_show_arg, output_path, progress_bar
from app.cli._common import write_atomically as write_atomically

# Formats that apply --scale / --offset, embed --audio, fly --source simulated: the API and the editor
# read the same lists (app.exports._core).
from app.exports._core import AUDIO_FORMATS as _AUDIO_FORMATS
from app.exports._core import (
    DEFAULT_FLIGHT_PRESET,
    FLIGHT_CONTROLLERS,
    FLIGHT_DISTURBANCES,
    FLIGHT_PRESETS,
    HEADINGLESS_FORMATS,
    MAX_SEED,
)
from app.exports._core import FLOWN_FORMATS as _FLOWN_FORMATS
from app.exports._core import ORIGIN_FORMATS as _ORIGIN_FORMATS
from app.exports._core import SAMPLED_FORMATS as _SAMPLED_FORMATS
from app.exports._core import SCALING_FORMATS as _SCALING_FORMATS

if TYPE_CHECKING:
    from app.media import AudioTrack


#: Shows with at least this many drones draw a progress bar (smaller ones finish in a blink).
_PROGRESS_MIN_DRONES = 200


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``export`` command."""
    from app.exports import EXPORT_FORMATS

    p = sub.add_parser(
        "export",
        help="export the show: show JSON, Skybrush CSV / .skyc, Crazyswarm, QGroundControl, sampled waypoints",
    )
    p.add_argument("show", metavar="SHOW", help="show file (JSON; - reads standard input)")
    p.add_argument("--format", "-f", required=True, metavar="FORMAT",
                   help=f"one of: {', '.join(EXPORT_FORMATS)}")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="output file ('-' for stdout; an existing directory receives the suggested file name)")
    from app.exports._skybrush_csv import DEFAULT_FPS as skybrush_fps
    from app.exports._waypoints_csv import DEFAULT_FPS as waypoints_fps

    p.add_argument("--fps", type=float, default=None, help="samples per second of sampled formats "
                   f"(skybrush-csv default {skybrush_fps:g}, waypoints-csv default {waypoints_fps:g}; lower for "
                   "shows past the 4 M-sample budget)")
    p.add_argument("--origin", default=None, metavar="LAT,LON[,ALT]",
                   help="WGS84 latitude, longitude (degrees) and altitude (m, default 0) of the show origin "
                   "(qgc-plan, qgc-wpl, skyc)")
    p.add_argument("--heading", type=float, default=None, metavar="DEG",
                   help="bearing of the show's +y axis, degrees clockwise from true north, within +-360 (default: "
                   "the show's settings.geo heading, else 0; without --origin it turns the show about its stored "
                   "origin)")
    p.add_argument("--source", choices=("planned", "simulated"), default="planned",
                   help=f"planned trajectory (default) or the simulated flight ({', '.join(_FLOWN_FORMATS)})")
    p.add_argument("--preset", choices=FLIGHT_PRESETS, default=None,
                   help=f"with --source simulated: the flight's error-model preset (default {DEFAULT_FLIGHT_PRESET}, "
                   "as swarmshow simulate)")
    p.add_argument("--seed", type=int, default=None,
                   help="with --source simulated: the flight's seed (default 0; the same seed flies the same flight "
                   "as swarmshow simulate --seed)")
    p.add_argument("--controller", choices=FLIGHT_CONTROLLERS, default=None,
                   help="with --source simulated: the flight's controller (default ismc; baseline: cascaded PD), "
                   "as swarmshow simulate --controller")
    p.add_argument("--disturbance", choices=FLIGHT_DISTURBANCES, default=None,
                   help="with --source simulated: the fleet-wide disturbance, only with --preset ideal (implied "
                   "without --preset), as swarmshow simulate --disturbance")
    p.add_argument("--audio", default=None, metavar="FILE",
                   help="the show's music (WAV, MP3, OGG or FLAC): embedded by skyc (media.audio) and viser-html")
    p.add_argument("--scale", type=float, default=1.0, metavar="FACTOR",
                   help="scale positions by FACTOR (crazyswarm: an outdoor show indoors, e.g. 0.02; default 1)")
    p.add_argument("--offset", default=None, metavar="X,Y,Z",
                   help="add X,Y,Z metres after scaling (crazyswarm: the show origin in the mocap frame)")
    p.set_defaults(func=_export)


def load_audio_arg(path: str) -> AudioTrack:
    """``--audio FILE`` as an ``app.media.AudioTrack``, checked by decoding it; a bad file is a :class:`CliError`."""
    from app.media import MAX_AUDIO_BYTES, MEDIA_TYPES, AudioError, AudioTrack, decode

    file = Path(path)
    try:
        size = file.stat().st_size
        if size > MAX_AUDIO_BYTES:
            raise CliError(f"--audio: {path} is {size} bytes; the limit is {MAX_AUDIO_BYTES}")
        data = file.read_bytes()
    except OSError as exc:
        raise CliError(f"--audio: cannot read {path}: {exc.strerror}") from exc
    try:
        dec = decode(data)
    except AudioError as exc:
        raise CliError(f"--audio: {path}: {exc.msg}") from exc
    return AudioTrack(data=data, container=dec.container, media_type=MEDIA_TYPES[dec.container],
                      filename=file.name, duration_s=dec.duration_s)


def parse_origin(text: str) -> tuple[float, float, float]:
    """``"LAT,LON"`` or ``"LAT,LON,ALT"`` -> floats, as the API's ``origin`` (``app.exports.parse_origin``: the
    altitude defaults to 0 m); a malformed value is a :class:`CliError`."""
    from app.exports import ExportError
    from app.exports import parse_origin as shared

    try:
        return shared(text)
    except ExportError as exc:
        raise CliError(f"--{exc}") from None


def check_heading_arg(value: float) -> float:
    """``--heading`` checked as the API checks ``heading_deg`` (``app.exports.check_heading``: within +-360
    degrees); a bad value is a :class:`CliError`."""
    from app.exports import ExportError, check_heading

    try:
        return check_heading(value)
    except ExportError as exc:
        raise CliError(str(exc).replace("heading_deg", "--heading", 1)) from None


def parse_offset(text: str) -> tuple[float, float, float]:
    """``"X,Y,Z"`` -> floats; a malformed value is a :class:`CliError`."""
    parts = text.split(",")
    try:
        x, y, z = (float(v) for v in parts)
    except ValueError as exc:
        raise CliError(f"--offset must be three numbers X,Y,Z (metres), got {text!r}") from exc
    return x, y, z


def _export(args: argparse.Namespace) -> int:
    from app.exports import EXPORT_FORMATS, ExportError, export_show

    if args.format not in EXPORT_FORMATS:
        raise CliError(f"unknown format {args.format!r}; one of: {', '.join(EXPORT_FORMATS)}")
    # An option the format does not use would be dropped without a word (a show "scaled for indoors" written
    # at full size): refuse it, as --source simulated is refused for the exact formats.
    # 0,0,0 moves nothing, as --scale 1 (app.exports.check_export_options: the library's and the API's rule too).
    offset_m = parse_offset(args.offset) if args.offset is not None else (0.0, 0.0, 0.0)
    unused = [(flag, formats) for flag, given, formats in (
        ("--scale", args.scale != 1.0, _SCALING_FORMATS), ("--offset", any(offset_m), _SCALING_FORMATS),
        ("--fps", args.fps is not None, _SAMPLED_FORMATS),
        ("--origin", args.origin is not None, _ORIGIN_FORMATS),
        ("--audio", args.audio is not None, _AUDIO_FORMATS)) if given and args.format not in formats]
    if unused:
        flag, users = unused[0]
        raise CliError(f"{flag} is not used by format {args.format!r} (only by {', '.join(users)}); drop it")
    if args.heading is not None and args.format in HEADINGLESS_FORMATS:
        raise CliError(f"--heading is not used by format {args.format!r} (the show file keeps its heading in "
                       "settings.geo); drop it")
    for flag, value in (("--preset", args.preset), ("--seed", args.seed), ("--controller", args.controller),
                        ("--disturbance", args.disturbance)):
        if value is not None and args.source != "simulated":
            raise CliError(f"{flag} chooses the simulated flight; it is only used with --source simulated")
    if args.seed is not None and not 0 <= args.seed <= MAX_SEED:
        raise CliError(f"--seed must be in [0, {MAX_SEED}], got {args.seed}")
    origin = parse_origin(args.origin) if args.origin is not None else None
    if args.heading is not None:
        check_heading_arg(args.heading)
    target = _target_dir_check(args.output)
    show = load_show_arg(args.show)
    audio = load_audio_arg(args.audio) if args.audio is not None else None
    try:
        with progress_bar(f"export {args.format}", enabled=show.drones >= _PROGRESS_MIN_DRONES) as update:
            result = export_show(
                show,
                args.format,
                fps=args.fps,
                origin=origin,
                heading_deg=args.heading,
                source=args.source,
                progress=update,
                audio=audio,
                scale=args.scale,
                offset_m=offset_m,
                preset=args.preset,
                seed=args.seed,
                controller=args.controller,
                disturbance=args.disturbance,
            )
    except ExportError as exc:
        msg = str(exc)
        if args.origin is None and "place on Earth" in msg:
            # The command line's way to give it, beside the show's settings.geo.
            msg += " (settings.geo), or pass --origin LAT,LON[,ALT] [--heading DEG]"
        raise CliError(msg) from exc
    for warning in result.warnings:
        print(f"swarmshow: warning: {warning}", file=sys.stderr)
    if target is None:
        sys.stdout.buffer.write(result.content)
        sys.stdout.buffer.flush()
        return EXIT_OK
    path = target / result.filename if target.is_dir() else target
    write_atomically(path, result.content)
    print(f"wrote {path} ({len(result.content)} bytes)", file=sys.stderr)
    return EXIT_OK


def _target_dir_check(output: str) -> Path | None:
    """Validate ``-o`` before doing any work: ``None`` for stdout, else the path."""
    if output == "-":
        return None
    path = output_path(output)
    if path.is_dir():
        return path
    parent = path.parent
    if not parent.is_dir():
        raise CliError(f"{output}: directory {str(parent)!r} does not exist")
    if path.exists() and not path.is_file():
        raise CliError(f"{output}: exists and is not a regular file")
    return path
