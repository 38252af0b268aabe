"""``swarmshow formation shape|text|image|svg|mesh|repair ...``: formation points as JSON.

The output is ``PointSet.to_json()``: ``{"points": [[x, y, z], ...], "colors": [...],
"min_spacing_m": float}`` (metres) plus ``"name"`` after the source (the file's stem, the text, the
shape's kind; :func:`formations.source_name`), written to ``-o FILE`` or stdout (``-o -`` or no ``-o``).
A formation that cannot keep the spacing exits 2 with the largest N that fits.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from app.cli._common import EXIT_FAILED, EXIT_OK, CliError, output_path, read_bounded, write_atomically


def _center(text: str) -> tuple[float, float, float]:
    """``"X,Y,Z"`` metres -> three finite floats (argparse type)."""
    try:
        parts = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected X,Y,Z in metres, got {text!r}") from None
    if len(parts) != 3 or not all(math.isfinite(v) for v in parts):
        raise argparse.ArgumentTypeError(f"expected three finite numbers X,Y,Z, got {text!r}")
    return parts


def _param(text: str) -> tuple[str, Any]:
    """``k=v`` -> (k, v); v is read as JSON (numbers, true/false) and otherwise kept as text."""
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        return key, json.loads(value)
    except json.JSONDecodeError:
        return key, value


def _common(p: argparse.ArgumentParser, *, color: bool = True, plane: bool = True) -> None:
    p.add_argument("-n", type=int, required=True, metavar="N", help="number of points")
    p.add_argument("--center", type=_center, default=(0.0, 0.0, 30.0), metavar="X,Y,Z",
                   help="centre, metres (default 0,0,30)")
    if plane:
        p.add_argument("--plane", choices=("xz", "xy", "yz"), default="xz",
                       help="plane of a 2-D drawing: xz faces the audience, xy is parallel to the ground")
    p.add_argument("--min-spacing-m", type=float, default=3.0, help="minimum distance between points (default 3)")
    if color:
        p.add_argument("--color", default=None, metavar="#RRGGBB", help="LED colour of every point")
    p.add_argument("-o", "--output", default="-", metavar="OUT", help="output JSON file ('-' = stdout, the default)")


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``formation`` command and its sources."""
    from formations.sources import SHAPE_KINDS

    p = sub.add_parser("formation", help="generate formation points (shape, text, image, SVG, mesh or point file) "
                       "or repair spacing")
    fsub = p.add_subparsers(dest="source", metavar="SOURCE")
    fsub.required = True

    q = fsub.add_parser("shape", help="a preset shape: " + ", ".join(SHAPE_KINDS))
    q.add_argument("kind", choices=SHAPE_KINDS, metavar="KIND", help=" | ".join(SHAPE_KINDS))
    q.add_argument("--size-m", type=float, default=20.0, help="overall extent, metres (default 20)")
    q.add_argument("--param", type=_param, action="append", default=[], metavar="K=V",
                   help="shape parameter, e.g. sides=6, points=5, inner_ratio=0.5, turns=3, radius_m=5, filled=false")
    _common(q)
    q.set_defaults(func=_shape)

    q = fsub.add_parser("text", help="text rendered with DejaVu Sans Bold ('\\n' starts a new line)")
    q.add_argument("text", metavar="TEXT")
    q.add_argument("--height-m", type=float, default=10.0, help="height of the text block, metres (default 10)")
    _common(q)
    q.set_defaults(func=_text)

    q = fsub.add_parser("image", help="points over the bright or opaque pixels of a PNG/JPEG, in their colours")
    q.add_argument("file", metavar="FILE")
    q.add_argument("--width-m", type=float, default=40.0, help="width of the image, metres (default 40)")
    q.add_argument("--mode", choices=("auto", "bright", "alpha"), default="auto",
                   help="pixels to fill: auto (opaque if transparent, else bright), bright or alpha")
    _common(q, color=False)
    q.set_defaults(func=_image)

    q = fsub.add_parser("svg", help="points along the paths of an SVG, in their stroke colours")
    q.add_argument("file", metavar="FILE")
    q.add_argument("--width-m", type=float, default=40.0, help="width of the drawing, metres (default 40)")
    _common(q)
    q.set_defaults(func=_svg)

    q = fsub.add_parser("mesh", help="points from an OBJ/PLY/STL/glTF/GLB mesh (vertices, surface or volume) "
                        "or a Skybrush CSV / XYZ(RGB) point file, in the file's colours")
    q.add_argument("file", metavar="FILE")
    q.add_argument("-n", "--drones", dest="n", type=int, required=True, metavar="N", help="number of points")
    q.add_argument("--mode", choices=("vertices", "surface", "volume"), default="surface",
                   help="mesh vertices, even points over the surface (default) or a filled volume")
    q.add_argument("--size", "--size-m", dest="size_m", type=float, default=None, metavar="M",
                   help="largest side of the bounding box, metres (default: the smallest that keeps the spacing; "
                   "point files keep their own metres)")
    q.add_argument("--format", default=None, choices=("obj", "ply", "stl", "glb", "gltf", "csv", "xyz"),
                   help="file format (default: from the extension)")
    q.add_argument("--up", choices=("auto", "y", "z"), default="auto",
                   help="the file's up axis (auto: +Y for glTF/GLB, +Z otherwise)")
    q.add_argument("--center", type=_center, default=(0.0, 0.0, 30.0), metavar="X,Y,Z",
                   help="centre, metres (default 0,0,30)")
    q.add_argument("--min-spacing-m", type=float, default=3.0, help="minimum distance between points (default 3)")
    q.add_argument("--color", default="#ffffff", metavar="#RRGGBB", help="colour of points the file gives none")
    q.add_argument("-o", "--output", default="-", metavar="OUT", help="output JSON file ('-' = stdout, the default)")
    q.set_defaults(func=_mesh)

    q = fsub.add_parser("repair", help="spread points of a JSON point set that are closer than the minimum spacing "
                        "(exit 1 if it cannot be reached)")
    q.add_argument("input", metavar="IN", help='JSON with "points" (and optional "colors"), e.g. a formation output')
    q.add_argument("--min-spacing-m", type=float, default=3.0, help="minimum distance between points (default 3)")
    q.add_argument("-o", "--output", default="-", metavar="OUT", help="output JSON file ('-' = stdout, the default)")
    q.set_defaults(func=_repair)


def _read(path: str, limit: int) -> bytes:
    """The file's bytes, refused past ``limit`` without reading further (a pipe or a device never
    hangs, see :func:`app.cli._common.read_bounded`)."""
    return read_bounded(path, limit)


def _write(obj: dict[str, Any], output: str) -> None:
    text = json.dumps(obj, allow_nan=False)
    if output == "-":
        print(text)
        return
    # Atomic, and a symlink at OUT is replaced, never written through to its target.
    write_atomically(output_path(output), (text + "\n").encode("utf-8"))
    n, d = len(obj["points"]), obj.get("min_spacing_m")
    spacing = f", min spacing {d:.3f} m" if d is not None else ""
    print(f"wrote {n} points{spacing} to {output}", file=sys.stderr)


#: The flag that sets each source's size, named when its points leave the space any show may use.
_SIZE_FLAG = {"shape": "--size-m", "text": "--height-m", "image": "--width-m", "svg": "--width-m", "mesh": "--size"}


def _check_bounds(points_m: Any, args: argparse.Namespace) -> None:
    """Refuse points no show could use, as the API does (``app.tasks._check_formation_result``): below the
    ground, above the highest ceiling a show may have, or outside the largest show area. The message names
    ``--center`` when the centre itself is outside, else the source's size flag.

    Raises:
        CliError: naming the flag to change.
    """
    import numpy as np

    from formations._show import MAX_CEILING_M, MAX_HORIZONTAL_EXTENT_M

    pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
    if not pts.size:
        return
    if not np.isfinite(pts).all():
        problem = "some points are not finite numbers"
    elif pts[:, 2].min() < 0 or pts[:, 2].max() > MAX_CEILING_M:
        problem = (f"points reach altitudes {pts[:, 2].min():.4g} .. {pts[:, 2].max():.4g} m, outside "
                   f"[0, {MAX_CEILING_M:g}] m")
    elif np.abs(pts[:, :2]).max() > MAX_HORIZONTAL_EXTENT_M:
        problem = (f"points reach {np.abs(pts[:, :2]).max():.4g} m from the origin, outside the largest show "
                   f"area +-{MAX_HORIZONTAL_EXTENT_M:g} m")
    else:
        return
    centre = np.asarray(getattr(args, "center", (0.0, 0.0, 0.0)), dtype=np.float64)
    centre_out = not 0.0 <= centre[2] <= MAX_CEILING_M or np.abs(centre[:2]).max() > MAX_HORIZONTAL_EXTENT_M
    flag = "--center" if centre_out else _SIZE_FLAG.get(args.source, "--size-m")
    raise CliError(f"{args.source}: {problem}; change {flag} (lower the size or move the centre)")


def _run(build, args: argparse.Namespace, name: str | None = None) -> int:
    """Call a source; FormationError (with the largest N that fits) becomes a CliError, and so do points
    outside the space any show may use (:func:`_check_bounds`). ``name``: the formation's name after its
    source (:func:`formations.source_name`), added to the JSON."""
    from formations.sources import FormationError

    try:
        points = build()
    except FormationError as exc:
        raise CliError(str(exc)) from None
    _check_bounds(points.points_m, args)
    doc = points.to_json()
    if name is not None:
        doc["name"] = name
    _write(doc, args.output)
    return EXIT_OK


def _place(args: argparse.Namespace) -> dict[str, Any]:
    return {"center_m": args.center, "plane": args.plane, "min_spacing_m": args.min_spacing_m}


def _shape(args: argparse.Namespace) -> int:
    from formations import source_name
    from formations.sources import generate_shape

    params = dict(args.param)
    color = args.color or "#ffffff"
    return _run(lambda: generate_shape(args.kind, args.n, size_m=args.size_m, color=color, **_place(args), **params),
                args, source_name("shape", text=args.kind))


def _text(args: argparse.Namespace) -> int:
    from formations import source_name
    from formations.sources import text_points

    text = args.text.replace("\\n", "\n")
    color = args.color or "#ffffff"
    return _run(lambda: text_points(text, args.n, height_m=args.height_m, color=color, **_place(args)), args,
                source_name("text", text=text))


def _image(args: argparse.Namespace) -> int:
    from formations import source_name
    from formations.sources import MAX_IMAGE_BYTES, image_points

    data = _read(args.file, MAX_IMAGE_BYTES)
    return _run(lambda: image_points(data, args.n, width_m=args.width_m, mode=args.mode, **_place(args)), args,
                source_name("image", filename=args.file))


def _svg(args: argparse.Namespace) -> int:
    from formations import source_name
    from formations.sources import MAX_SVG_BYTES, svg_points

    data = _read(args.file, MAX_SVG_BYTES)
    return _run(lambda: svg_points(data, args.n, width_m=args.width_m, color=args.color, **_place(args)), args,
                source_name("svg", filename=args.file))


def _mesh(args: argparse.Namespace) -> int:
    from formations import source_name
    from formations.sources import MAX_MESH_BYTES, mesh_points

    ext = (args.format or Path(args.file).suffix.lstrip(".")).lower()
    ext = {"txt": "xyz", "xyzrgb": "xyz", "pts": "xyz"}.get(ext, ext)
    if ext not in ("obj", "ply", "stl", "glb", "gltf", "csv", "xyz"):
        raise CliError(f"{args.file}: unknown file format {ext!r}; give --format")
    data = _read(args.file, MAX_MESH_BYTES)
    return _run(lambda: mesh_points(data, args.n, file_type=ext, mode=args.mode, size_m=args.size_m,
                                    center_m=args.center, min_spacing_m=args.min_spacing_m, up=args.up,
                                    color=args.color)[0], args, source_name("mesh", filename=args.file))


def _repair(args: argparse.Namespace) -> int:
    import numpy as np

    from formations._points import parse_color
    from formations.sources import FormationError, PointSet, repair_spacing

    limit = 64 * 1024 * 1024
    raw = _read(args.input, limit)
    if len(raw) > limit:
        raise CliError(f"{args.input}: larger than {limit} bytes")
    try:
        doc = json.loads(raw)
        pts = np.asarray(doc["points"], dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points must be [[x, y, z], ...], got shape {pts.shape}")
        colors = doc.get("colors") or ["#ffffff"] * len(pts)
        rgb = np.array([parse_color(c, name=f"colors[{i}]") for i, c in enumerate(colors)]).reshape(-1, 3)
        fixed, achieved = repair_spacing(pts, args.min_spacing_m)
        out = PointSet(fixed, rgb).to_json()
    except (json.JSONDecodeError, UnicodeDecodeError, KeyError, TypeError, ValueError, AttributeError) as exc:
        if isinstance(exc, FormationError):
            raise CliError(f"{args.input}: {exc}") from None
        raise CliError(f"{args.input}: expected JSON with 'points' [[x, y, z], ...] and optional "
                       f"'colors' ['#rrggbb', ...] ({exc})") from None
    _write(out, args.output)
    if achieved < args.min_spacing_m:
        print(f"swarmshow: repair reached a minimum spacing of {achieved:.3f} m, below {args.min_spacing_m:g} m",
              file=sys.stderr)
        return EXIT_FAILED
    return EXIT_OK
