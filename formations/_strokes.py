"""Strokes: polylines resampled evenly by arc length (metres)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from formations._points import (
    FormationError,
    PointSet,
    as_points,
    check_center,
    check_n,
    check_plane,
    check_positive,
    solid_colors,
)
from formations._shapes import largest_remainder
from formations._spacing import guarantee
from formations._transforms import place_on_plane

#: Most strokes / vertices accepted in one call.
MAX_STROKES = 10_000
MAX_VERTICES = 1_000_000


def _is_closed(poly: np.ndarray) -> bool:
    return len(poly) >= 3 and bool(np.all(poly[0] == poly[-1]))


def resample_polylines(
    polylines: Sequence[np.ndarray], n: int
) -> tuple[np.ndarray, np.ndarray]:
    """Spread ``n`` points over polylines evenly by arc length.

    The count is shared among polylines by length (largest-remainder rounding). An open
    polyline with k points gets them at arc positions (j + 1/2) L / k (half a gap at each
    end, so touching strokes do not collide); a closed one (first vertex == last) at j L / k.

    Returns:
        (points (n, d), polyline index of each point (n,)).
    """
    lengths = np.array(
        [float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) if len(p) > 1 else 0.0
         for p in polylines]
    )
    if lengths.sum() <= 0.0:
        raise FormationError("the strokes have zero total length")
    counts = largest_remainder(lengths, n)
    out, owner = [], []
    for i, (poly, k) in enumerate(zip(polylines, counts, strict=True)):
        if k == 0:
            continue
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(poly, axis=0), axis=1))])
        j = np.arange(k)
        s = j * (cum[-1] / k) if _is_closed(poly) else (j + 0.5) * (cum[-1] / k)
        out.append(np.column_stack([np.interp(s, cum, poly[:, a]) for a in range(poly.shape[1])]))
        owner.append(np.full(k, i))
    return np.vstack(out), np.concatenate(owner)


def prepare_strokes(
    strokes: Sequence[ArrayLike],
    *,
    plane: str,
    center_m: ArrayLike | None,
    scale: float,
) -> list[np.ndarray]:
    """Validate strokes and map them to world metres ((k, 2) via ``plane``; (k, 3) as is),
    scaled about the origin by ``scale`` and, if ``center_m`` is given, moved so that their
    bounding-box centre is at ``center_m``."""
    if isinstance(strokes, np.ndarray) and strokes.ndim == 2:
        strokes = [strokes]
    if isinstance(strokes, str | bytes) or not isinstance(strokes, Sequence | np.ndarray):
        raise FormationError("strokes must be a list of polylines")
    if not 1 <= len(strokes) <= MAX_STROKES:
        raise FormationError(f"strokes must hold 1 to {MAX_STROKES} polylines, got {len(strokes)}")
    plane = check_plane(plane)
    f = check_positive(scale, name="scale")
    polys = [as_points(s, name=f"strokes[{i}]", dims=(2, 3)) for i, s in enumerate(strokes)]
    if len({p.shape[1] for p in polys}) != 1:
        raise FormationError("strokes must all be 2-D (plane coordinates) or all 3-D (metres)")
    if sum(len(p) for p in polys) > MAX_VERTICES:
        raise FormationError(f"strokes hold more than {MAX_VERTICES} vertices")
    if any(len(p) == 0 for p in polys):
        raise FormationError("every stroke needs at least one vertex")
    world = [
        place_on_plane(p * f, plane=plane) if p.shape[1] == 2 else p * f for p in polys
    ]
    if center_m is not None:
        c = check_center(center_m)
        allp = np.vstack(world)
        mid = (allp.min(axis=0) + allp.max(axis=0)) / 2
        world = [w - mid + c for w in world]
    return world


def stroke_points(
    strokes: Sequence[ArrayLike],
    n: int,
    *,
    min_spacing_m: float = 3.0,
    color: str = "#ffffff",
    plane: str = "xz",
    center_m: ArrayLike | None = None,
    scale: float = 1.0,
) -> PointSet:
    """Resample one or more drawn polylines to ``n`` evenly spaced points.

    Args:
        strokes: polylines, each (k, 2) plane coordinates in metres (u right, v up) or
            (k, 3) world metres; a stroke whose last vertex equals its first is closed.
        n: number of points, 1..20000, shared among strokes by length.
        min_spacing_m: minimum distance between any two points, metres.
        color: LED colour "#rrggbb".
        plane: plane of 2-D strokes ("xz", "xy", "yz"); the plane passes through the origin.
        center_m: if given, the drawing's bounding-box centre is moved here (metres).
        scale: factor applied to the stroke coordinates (about the origin) first.

    Raises:
        FormationError: bad argument, or the points cannot keep ``min_spacing_m``
            (``max_n`` is the largest count that does).
    """
    n = check_n(n)
    s = check_positive(min_spacing_m, name="min_spacing_m")
    one = solid_colors(1, color)
    world = prepare_strokes(strokes, plane=plane, center_m=center_m, scale=scale)

    def raw(k: int) -> tuple[np.ndarray, np.ndarray]:
        pts, _ = resample_polylines(world, k)
        return pts, np.repeat(one, k, axis=0)

    return guarantee(raw, n, s, what="the strokes", repair=True)
