"""Point sets, formation errors and argument validation shared by the formation sources.

Units: metres, ENU (x east, y north, z up); colours ``#rrggbb``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

#: Most points one formation source returns.
MAX_POINTS = 20_000
#: Planes a 2-D source may be drawn in ("xz" faces the audience, "xy" is parallel to the ground).
PLANES: tuple[str, ...] = ("xz", "xy", "yz")

_HEX = re.compile(r"^#[0-9a-fA-F]{6}$")


class FormationError(ValueError):
    """A formation cannot be built; ``max_n`` is the largest N that fits (None if unknown)."""

    def __init__(self, message: str, *, max_n: int | None = None) -> None:
        super().__init__(message)
        self.max_n = max_n


class InputTooLargeError(FormationError):
    """An uploaded image or SVG exceeds the size limits (the API maps this to HTTP 413)."""


@dataclass(frozen=True)
class PointSet:
    """N formation points and their LED colours.

    Attributes:
        points_m: (N, 3) float64 positions, metres (ENU).
        colors_rgb: (N, 3) uint8 colours.
    """

    points_m: np.ndarray
    colors_rgb: np.ndarray

    def __post_init__(self) -> None:
        pts = np.array(self.points_m, dtype=np.float64, copy=True).reshape(-1, 3)
        cols = np.array(self.colors_rgb, copy=True)
        if cols.shape != pts.shape:
            raise FormationError(
                f"colors_rgb shape {cols.shape} does not match points_m shape {pts.shape}"
            )
        if not np.all(np.isfinite(pts)):
            raise FormationError("points_m must be finite")
        cols = np.clip(cols, 0, 255).astype(np.uint8)
        pts.setflags(write=False)
        cols.setflags(write=False)
        object.__setattr__(self, "points_m", pts)
        object.__setattr__(self, "colors_rgb", cols)

    def __len__(self) -> int:
        return int(self.points_m.shape[0])

    def hex_colors(self) -> list[str]:
        """Return the colours as ``"#rrggbb"`` strings."""
        return rgb_to_hex(self.colors_rgb / 255.0)

    def min_spacing_m(self) -> float:
        """Return the exact nearest-pair distance in metres (``inf`` for fewer than 2 points)."""
        return nearest_pair_distance(self.points_m)

    def to_json(self) -> dict[str, Any]:
        """Return ``{"points": [[x, y, z], ...], "colors": [...], "min_spacing_m": float}``.

        ``min_spacing_m`` is ``None`` for a single point (JSON has no infinity).
        """
        d = self.min_spacing_m()
        return {
            "points": self.points_m.tolist(),
            "colors": self.hex_colors(),
            "min_spacing_m": float(d) if math.isfinite(d) else None,
        }


#: Largest point set :func:`closest_pair` sweeps; larger ones use scipy's k-d tree.
SWEEP_MAX_POINTS = 4096
#: Sweep direction of :func:`closest_pair` (normalised per dimension): irrational ratios, so
#: no lattice direction of a formation is parallel or perpendicular to it.
_SWEEP_DIRECTION = np.array([1.0, (math.sqrt(5.0) - 1.0) / 2.0, math.sqrt(2.0) - 1.0])


def closest_pair(points: ArrayLike) -> tuple[int, int, float]:
    """The closest pair of an (N, d) array: ``(i, j, distance_m)``, i < j; ``(-1, -1, inf)`` for N < 2.

    Exact, by a sweep along a fixed generic direction u: after sorting the projections
    on u, shift s pairs every point with the s-th next one, and a shift whose projected
    gaps all exceed the best distance so far ends the search (a pair's gap is at most its
    distance, and gaps only grow with s). A generic u, not a coordinate axis, keeps the
    grids and planes of formations from lining up along the sweep. Every step is
    vectorised over the points; a k-d tree would cost a scipy.spatial import (~0.3 s),
    which ``swarmshow validate`` avoids. The sweep costs about N times the number of points
    in a slab of the closest distance's width (a dense grid of N points: ~sqrt(N) shifts),
    so above :data:`SWEEP_MAX_POINTS` the k-d tree (N log N) takes over, where its import
    is small next to the work. Among equally close pairs the sweep returns the smallest
    ``(i, j)`` and the k-d tree the one of the smallest i, so messages naming them are
    stable. The per-frame search of playback and of the flown-distance check is the O(N)
    cell hash :func:`sim.geometry.closest_pair`.
    """
    pts = np.asarray(points, dtype=np.float64)
    n = pts.shape[0]
    if n < 2:
        return -1, -1, math.inf
    if n > SWEEP_MAX_POINTS:
        return _closest_pair_kdtree(pts)
    # Coincident points first (O(N log N)): the sweep would otherwise pair every copy of a
    # repeated point with every other, since their gaps (0) never exceed the best (0).
    _, first, inverse, counts = np.unique(pts, axis=0, return_index=True, return_inverse=True, return_counts=True)
    if counts.max() > 1:
        inverse = inverse.reshape(-1)
        dup = np.flatnonzero(counts[inverse] > 1)  # points that have a copy, in index order
        i = int(dup[0])
        j = int(np.flatnonzero(inverse == inverse[i])[1])
        return i, j, 0.0
    direction = _SWEEP_DIRECTION[: pts.shape[1]] / np.linalg.norm(_SWEEP_DIRECTION[: pts.shape[1]])
    proj = pts @ direction
    order = np.argsort(proj, kind="stable")
    p = pts[order]
    x = proj[order]
    best2, bi, bj = math.inf, -1, -1
    for s in range(1, n):
        # <=, not <: a pair exactly as close as the best may still be the smaller (i, j).
        idx = np.flatnonzero(x[s:] - x[:-s] <= math.sqrt(best2) if math.isfinite(best2) else np.ones(n - s, bool))
        if idx.size == 0:
            break
        d2 = np.sum((p[idx + s] - p[idx]) ** 2, axis=1)
        m = float(d2.min())
        if m > best2:
            continue
        hit = idx[d2 == m]
        a, b = order[hit], order[hit + s]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        k = int(np.lexsort((hi, lo))[0])
        if m < best2 or (int(lo[k]), int(hi[k])) < (bi, bj):
            best2, bi, bj = m, int(lo[k]), int(hi[k])
    return bi, bj, math.sqrt(best2)


def _closest_pair_kdtree(pts: np.ndarray) -> tuple[int, int, float]:
    """:func:`closest_pair` for large sets by a k-d tree's 2-nearest query (ties: the smallest i)."""
    from scipy.spatial import cKDTree  # ~0.3 s to import, paid only by shows with large formations

    dist, idx = cKDTree(pts).query(pts, k=2)
    i = int(np.argmin(dist[:, 1]))
    j = int(idx[i, 1])
    if j == i:  # exact duplicates tie at distance 0 and the tree may list the point itself second
        j = int(idx[i, 0])
    return min(i, j), max(i, j), float(dist[i, 1])


def nearest_pair_distance(points: ArrayLike) -> float:
    """Exact nearest-pair distance of an (N, d) array in metres (``inf`` for N < 2)."""
    return closest_pair(points)[2]


def rgb_to_hex(rgb: ArrayLike) -> list[str]:
    """(N, 3) floats in [0, 1] -> ``"#rrggbb"`` strings (rounded to the nearest 1/255)."""
    u8 = np.clip(np.rint(np.asarray(rgb, dtype=np.float64) * 255.0), 0, 255).astype(np.uint8)
    return ["#" + row.tobytes().hex() for row in u8.reshape(-1, 3)]


def parse_color(color: str, *, name: str = "color") -> np.ndarray:
    """``"#rrggbb"`` -> (3,) uint8; anything else raises FormationError naming ``name``."""
    if not isinstance(color, str) or not _HEX.match(color):
        raise FormationError(f"{name} must be a colour '#rrggbb', got {color!r}")
    return np.array([int(color[i : i + 2], 16) for i in (1, 3, 5)], dtype=np.uint8)


def check_n(n: Any, *, name: str = "n") -> int:
    """Validate a point count: an int in [1, MAX_POINTS]."""
    if isinstance(n, bool) or not isinstance(n, int | np.integer):
        raise FormationError(f"{name} must be an integer, got {n!r}")
    if not 1 <= int(n) <= MAX_POINTS:
        raise FormationError(f"{name} must be between 1 and {MAX_POINTS}, got {n}")
    return int(n)


def check_positive(value: Any, *, name: str) -> float:
    """Validate a finite number > 0 (metres, ratios...)."""
    if isinstance(value, bool):
        raise FormationError(f"{name} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise FormationError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise FormationError(f"{name} must be finite and > 0, got {value!r}")
    return v


def check_plane(plane: Any) -> str:
    """Validate a plane name (one of PLANES)."""
    if plane not in PLANES:
        raise FormationError(f"plane must be one of {', '.join(PLANES)}, got {plane!r}")
    return str(plane)


def check_center(center: Any, *, name: str = "center_m") -> np.ndarray:
    """Validate a centre: three finite numbers (metres)."""
    try:
        c = np.asarray(center, dtype=np.float64)
    except (TypeError, ValueError):
        raise FormationError(f"{name} must be three numbers (x, y, z), got {center!r}") from None
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise FormationError(f"{name} must be three finite numbers (x, y, z), got {center!r}")
    return c


def solid_colors(n: int, color: str, *, name: str = "color") -> np.ndarray:
    """(n, 3) uint8 array of one colour."""
    return np.tile(parse_color(color, name=name), (n, 1))


def as_points(points: ArrayLike, *, name: str = "points", dims: Sequence[int] = (3,)) -> np.ndarray:
    """Validate an (N, d) finite float array with d in ``dims``."""
    try:
        arr = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise FormationError(f"{name} must be an array of numbers") from None
    if arr.ndim != 2 or arr.shape[1] not in dims:
        want = " or ".join(f"(N, {d})" for d in dims)
        raise FormationError(f"{name} must have shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise FormationError(f"{name} must be finite")
    return arr
