"""SVG sources: N points along the paths and shapes of an SVG drawing (metres).

The document is checked with ``defusedxml`` first (no DOCTYPE, entities or external
references: billion laughs and XXE are refused), then parsed with ``svgelements``.
"""

from __future__ import annotations

import io
import re
from typing import Any
from xml.etree.ElementTree import Element, ParseError

import numpy as np
import svgelements as se
from defusedxml import DefusedXmlException
from defusedxml.ElementTree import fromstring as safe_fromstring
from numpy.typing import ArrayLike

from formations._points import (
    FormationError,
    InputTooLargeError,
    PointSet,
    check_center,
    check_n,
    check_plane,
    check_positive,
    parse_color,
)
from formations._spacing import guarantee
from formations._strokes import resample_polylines
from formations._transforms import place_on_plane

#: Largest SVG accepted, bytes.
MAX_SVG_BYTES = 5 * 1024 * 1024
#: Most curve samples kept when flattening the drawing (bounds time and memory).
MAX_SVG_VERTICES = 2_000_000
#: Most numbers (coordinates) in path data and point lists: parsing cost grows with them, and
#: a drone drawing needs far fewer.
MAX_SVG_NUMBERS = 200_000
#: Each curve segment (Bézier, arc) is flattened into this many chords before arc-length
#: resampling: a half-circle arc then strays by 0.2 % of its radius, far below a drone spacing.
_CURVE_PIECES = 24
_WHITE = np.array([255, 255, 255], dtype=np.uint8)
_CURVE_T = np.linspace(0.0, 1.0, _CURVE_PIECES + 1)[1:]
_NUMBER = re.compile(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
#: Largest SVG coordinate accepted (user units); beyond it lengths overflow.
_MAX_COORD = 1e12


def check_svg_bytes(data: bytes) -> bytes:
    """Refuse oversize, non-XML or unsafe SVG bytes before any SVG parsing.

    Raises:
        InputTooLargeError: more than MAX_SVG_BYTES bytes.
        FormationError: not bytes, not well-formed XML, not an ``<svg>`` root, or a DOCTYPE,
            entity declaration or external reference is present.
    """
    if not isinstance(data, bytes | bytearray | memoryview):
        raise FormationError("SVG data must be bytes")
    raw = bytes(data)
    if len(raw) > MAX_SVG_BYTES:
        raise InputTooLargeError(f"SVG is {len(raw)} bytes; the limit is {MAX_SVG_BYTES} bytes")
    try:
        root = safe_fromstring(raw, forbid_dtd=True, forbid_entities=True, forbid_external=True)
    except DefusedXmlException as exc:
        raise FormationError(
            f"SVG refused: DOCTYPE, entity declarations and external references are not allowed ({exc})"
        ) from None
    except (ParseError, ValueError, UnicodeDecodeError) as exc:
        raise FormationError(f"could not decode the SVG: not well-formed XML ({exc})") from None
    if root.tag.rsplit("}", 1)[-1] != "svg":
        raise FormationError(f"not an SVG document (root element is <{root.tag}>)")
    _refuse_active_content(root)
    numbers = sum(
        len(_NUMBER.findall(el.get(attr, ""))) for el in root.iter() for attr in ("d", "points")
    )
    if numbers > MAX_SVG_NUMBERS:
        raise InputTooLargeError(f"the SVG's paths hold {numbers} coordinates; the limit is {MAX_SVG_NUMBERS}")
    expanded = _expanded_elements(root)
    if expanded > MAX_SVG_ELEMENTS:
        raise InputTooLargeError(
            f"the SVG expands to more than {MAX_SVG_ELEMENTS} elements (counting what <use> repeats); "
            f"the limit is {MAX_SVG_ELEMENTS}")
    return raw


#: Most elements an SVG may expand to, ``<use>`` copies counted: each costs about 0.2 ms to parse and
#: flatten, and 1.4 kB of nested ``<use>`` (5 levels x 10) expanded to 100,000 (37 s of CPU).
MAX_SVG_ELEMENTS = 20_000


def _expanded_elements(root: Element) -> int:
    """How many elements the document holds once every ``<use>`` is replaced by what it refers to,
    counted without expanding anything (memoised per id; stops early past the limit).

    Raises:
        FormationError: a ``<use>`` refers, directly or through others, to itself.
    """
    by_id = {el.get("id"): el for el in root.iter() if el.get("id")}
    memo: dict[int, int] = {}
    visiting: set[int] = set()

    def size(el: Element, depth: int) -> int:
        key = id(el)
        if key in memo:
            return memo[key]
        if key in visiting or depth > 200:
            raise FormationError("SVG refused: a <use> element refers to itself (directly or through others)")
        visiting.add(key)
        total = 1
        for child in el:
            total += size(child, depth + 1)
            if total > MAX_SVG_ELEMENTS:
                break
        if str(el.tag).rsplit("}", 1)[-1] == "use":
            ref = next((v for k, v in el.attrib.items() if k.rsplit("}", 1)[-1] == "href"), "").strip()
            target = by_id.get(ref[1:]) if ref.startswith("#") else None
            if target is not None:
                total += size(target, depth + 1)
        visiting.discard(key)
        memo[key] = min(total, MAX_SVG_ELEMENTS + 1)
        return memo[key]

    return size(root, 0)


#: Elements that run code or embed other documents; a drawing for drone points needs none of them.
_ACTIVE_ELEMENTS = frozenset({"script", "foreignObject", "iframe", "embed", "object", "handler", "listener"})


def _refuse_active_content(root: Any) -> None:
    """Refuse scripts, event handlers and references to anything outside the file.

    Nothing here would run them (the SVG is only sampled), but a file carrying them is not a plain
    drawing: refusing it says so plainly instead of silently dropping parts of it.

    Raises:
        FormationError: naming the first offending element or attribute.
    """
    for el in root.iter():
        tag = str(el.tag).rsplit("}", 1)[-1]
        if tag in _ACTIVE_ELEMENTS:
            raise FormationError(f"SVG refused: <{tag}> elements (scripts, embedded documents) are not allowed")
        for attr, value in el.attrib.items():
            name = attr.rsplit("}", 1)[-1]
            if name.lower().startswith("on"):
                raise FormationError(f"SVG refused: event handler attribute {name!r} on <{tag}> is not allowed")
            if name == "href" and not value.strip().startswith(("#", "data:")):
                raise FormationError(
                    f"SVG refused: external reference {value.strip()[:80]!r} on <{tag}> is not allowed")


def _element_color(element: se.Shape) -> np.ndarray:
    """The element's stroke colour, else its fill; white if neither is visible or if black
    (SVG's default fill, and a black LED is simply dark)."""
    for paint in (element.stroke, element.fill):
        if paint is not None and paint.value is not None and paint.alpha > 0:
            rgb = np.array([paint.red, paint.green, paint.blue], dtype=np.uint8)
            return _WHITE if not rgb.any() else rgb
    return _WHITE


def _flatten_subpath(sub: se.Subpath, budget: int) -> tuple[np.ndarray, bool]:
    """A subpath as a (k, 2) polyline in SVG user units, each curve split into _CURVE_PIECES
    chords. Returns (polyline, closed).

    Raises:
        InputTooLargeError: more than ``budget`` vertices.
    """
    pts: list[np.ndarray] = []
    closed = False
    count = 0
    for seg in sub:
        if seg.end is None or (seg.start is None and not isinstance(seg, se.Move)):
            continue
        if isinstance(seg, se.Move | se.Line | se.Close):
            closed = closed or isinstance(seg, se.Close)
            piece = np.array([[seg.end.x, seg.end.y]], dtype=np.float64)
        else:
            piece = np.asarray(seg.npoint(_CURVE_T), dtype=np.float64)
        count += len(piece)
        if count > budget:
            raise InputTooLargeError(f"the SVG's paths hold more than {MAX_SVG_VERTICES} curve samples")
        pts.append(piece)
    if not pts:
        return np.zeros((0, 2)), False
    poly = np.vstack(pts)
    if closed and len(poly) >= 2 and not np.array_equal(poly[0], poly[-1]):
        poly = np.vstack([poly, poly[:1]])
    return poly, closed


def svg_polylines(data: bytes) -> tuple[list[np.ndarray], np.ndarray]:
    """Parse an SVG into polylines (SVG user units, y down) and one colour per polyline.

    Every visible shape (path, rect, circle, ellipse, line, polyline, polygon), with its
    transforms applied, becomes one polyline per subpath.

    Returns:
        (polylines [(k, 2)], colours (P, 3) uint8).

    Raises:
        InputTooLargeError, FormationError: see :func:`check_svg_bytes`; also when the
            drawing has no paths or shapes with length.
    """
    raw = check_svg_bytes(data)
    try:
        doc = se.SVG.parse(io.BytesIO(raw), reify=True)
        shapes = [e for e in doc.elements() if isinstance(e, se.Shape)]
        paths = [abs(se.Path(e)) for e in shapes]
    except (ValueError, TypeError, AttributeError, IndexError, KeyError, ZeroDivisionError) as exc:
        raise FormationError(f"could not decode the SVG: {exc}") from None
    if not paths:
        raise FormationError("the SVG has no paths or shapes to place points on", max_n=0)
    polys: list[np.ndarray] = []
    colors: list[np.ndarray] = []
    total = 0
    for element, path in zip(shapes, paths, strict=True):
        rgb = _element_color(element)
        for sub in path.as_subpaths():
            poly, _ = _flatten_subpath(sub, MAX_SVG_VERTICES - total)
            total += len(poly)
            if len(poly) < 2 or not np.all(np.isfinite(poly)):
                continue
            if np.abs(poly).max() > _MAX_COORD:
                raise FormationError(f"the SVG has coordinates beyond {_MAX_COORD:g} user units")
            polys.append(poly)
            colors.append(rgb)
    lengths = [float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) for p in polys]
    if not polys or sum(lengths) <= 0.0:
        raise FormationError("the SVG has no paths or shapes with length to place points on", max_n=0)
    return polys, np.array(colors, dtype=np.uint8)


def svg_points(
    data: bytes,
    n: int,
    *,
    width_m: float = 40.0,
    center_m: ArrayLike = (0.0, 0.0, 30.0),
    plane: str = "xz",
    min_spacing_m: float = 3.0,
    color: str | None = None,
) -> PointSet:
    """Spread ``n`` points evenly by arc length along the paths and shapes of an SVG.

    The count is shared among subpaths by length. The drawing's bounding box is scaled to
    ``width_m`` wide (``width_m`` tall if it has no width), centred on ``center_m`` and drawn in
    ``plane`` (SVG's y axis, which points down, becomes "up"). Points too close where paths
    cross or touch are spread apart (no point moves by more than one minimum spacing).
    ``<text>`` elements are ignored (convert text to paths first), as are stroke widths.

    Args:
        data: SVG file bytes (at most 5 MB; no DOCTYPE or entities).
        n: number of points, 1..20000.
        width_m: width of the drawing, metres.
        center_m: centre of the drawing, metres (x, y, z).
        plane: "xz" (vertical, facing the audience), "xy" (ground-parallel) or "yz".
        min_spacing_m: minimum distance between any two points, metres.
        color: LED colour "#rrggbb" for every point; None = each element's stroke colour
            (else its fill; white if neither is visible, or black).

    Raises:
        InputTooLargeError: over the size limits.
        FormationError: bad argument, unsafe or undecodable SVG, no paths, or ``n`` points do
            not fit (``max_n`` is the largest count that does).
    """
    n = check_n(n)
    width = check_positive(width_m, name="width_m")
    center = check_center(center_m)
    plane = check_plane(plane)
    s = check_positive(min_spacing_m, name="min_spacing_m")
    one = None if color is None else parse_color(color)
    polys, colors = svg_polylines(data)
    allp = np.vstack(polys)
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    span = hi - lo
    # A drawing with no width (a vertical line, up to round-off in its transforms) is scaled by its height.
    f = width / (span[0] if span[0] > 1e-9 * span.max() else span[1])
    mid = (lo + hi) / 2.0
    # SVG y points down; the plane's v axis points up.
    flip = np.array([f, -f])
    world = [place_on_plane((p - mid) * flip, plane=plane, center_m=center) for p in polys]

    def raw(k: int) -> tuple[np.ndarray, np.ndarray]:
        pts, owner = resample_polylines(world, k)
        return pts, (np.tile(one, (k, 1)) if one is not None else colors[owner])

    return guarantee(raw, n, s, what=f"the SVG drawing at width {width:g} m", repair=True)
