"""Shape presets: grid, circle, polygon, star, heart, sphere, helix, cube; filled disc, rings, star, heart (metres)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from formations._points import (
    FormationError,
    PointSet,
    check_center,
    check_n,
    check_plane,
    check_positive,
    solid_colors,
)
from formations._spacing import guarantee
from formations._transforms import place_on_plane

SHAPE_KINDS: tuple[str, ...] = (
    "grid",
    "circle",
    "polygon",
    "star",
    "heart",
    "sphere",
    "helix",
    "cube",
    "disc",
    "rings",
    "filled_star",
    "filled_heart",
)
#: Kinds that are 3-D (they ignore ``plane``).
SHAPE_KINDS_3D: tuple[str, ...] = ("sphere", "helix", "cube")

#: Kind-specific parameters and their defaults.
SHAPE_PARAMS: dict[str, dict[str, Any]] = {
    "grid": {},
    "circle": {},
    "polygon": {"sides": 6},
    "star": {"points": 5, "inner_ratio": 0.5},
    "heart": {},
    "sphere": {},
    "helix": {"turns": 3.0, "radius_m": None},
    "cube": {"filled": True},
    "disc": {},
    "rings": {},
    "filled_star": {"points": 5, "inner_ratio": 0.5},
    "filled_heart": {},
}

_GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


def _closed_polyline_samples(vertices: np.ndarray, n: int) -> np.ndarray:
    """n points evenly spaced by arc length along a closed (k, d) polyline, from vertex 0."""
    closed = np.vstack([vertices, vertices[:1]])
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    s = np.arange(n) * (cum[-1] / n)
    return np.column_stack([np.interp(s, cum, closed[:, a]) for a in range(closed.shape[1])])


def largest_remainder(weights: np.ndarray, total: int) -> np.ndarray:
    """Split ``total`` into integers proportional to ``weights`` (largest-remainder rounding;
    ties go to the earlier entry)."""
    w = np.asarray(weights, dtype=np.float64)
    if total <= 0 or w.sum() <= 0:
        return np.zeros(len(w), dtype=np.int64)
    exact = w * (total / w.sum())
    base = np.floor(exact).astype(np.int64)
    rest = total - int(base.sum())
    order = np.lexsort((np.arange(len(w)), -(exact - base)))
    base[order[:rest]] += 1
    out: np.ndarray = base
    return out


def _pinned_samples(loop: np.ndarray, corners: np.ndarray, n: int) -> np.ndarray:
    """n points along a closed (k, 2) polyline with a point on every corner (vertex indices
    ``corners``, increasing, starting at 0) and the rest spread evenly by arc length between
    corners, shared by length. Falls back to plain arc-length spacing if n < len(corners)."""
    if n < len(corners):
        return _closed_polyline_samples(loop, n)
    closed = np.vstack([loop, loop[:1]])
    cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(closed, axis=0), axis=1))])
    bounds = np.append(cum[corners], cum[-1])
    lengths = np.diff(bounds)
    counts = largest_remainder(lengths, n - len(corners))
    seg = np.repeat(np.arange(len(corners)), counts + 1)
    start = np.concatenate([[0], np.cumsum(counts + 1)[:-1]])
    j = np.arange(n) - np.repeat(start, counts + 1)
    s = bounds[seg] + lengths[seg] * j / (counts[seg] + 1)
    return np.column_stack([np.interp(s, cum, closed[:, a]) for a in range(closed.shape[1])])


def _grid(n: int, size: float) -> np.ndarray:
    cols = math.ceil(math.sqrt(n))
    rows = math.ceil(n / cols)
    step = size / (cols - 1) if cols > 1 else 0.0
    i = np.arange(n)
    r, c = i // cols, i % cols
    # Centre the last, possibly partial, row.
    last = r == rows - 1
    in_last = n - (rows - 1) * cols
    u = (c - (cols - 1) / 2.0) * step
    u = np.where(last, (c - (in_last - 1) / 2.0) * step, u)
    v = ((rows - 1) / 2.0 - r) * step
    return np.column_stack([u, v])


def _circle(n: int, size: float) -> np.ndarray:
    a = math.pi / 2 + 2 * math.pi * np.arange(n) / n
    return np.column_stack([np.cos(a), np.sin(a)]) * (size / 2)


def _polygon(n: int, size: float, sides: int) -> np.ndarray:
    a = math.pi / 2 + 2 * math.pi * np.arange(sides) / sides
    verts = np.column_stack([np.cos(a), np.sin(a)]) * (size / 2)
    return _pinned_samples(verts, np.arange(sides), n)


def _star(n: int, size: float, points: int, inner_ratio: float) -> np.ndarray:
    k = 2 * points
    a = math.pi / 2 + 2 * math.pi * np.arange(k) / k
    r = np.where(np.arange(k) % 2 == 0, 1.0, inner_ratio) * (size / 2)
    verts = np.column_stack([r * np.cos(a), r * np.sin(a)])
    return _pinned_samples(verts, np.arange(k), n)


def _heart_outline() -> tuple[np.ndarray, np.ndarray]:
    """The classic geometric heart (a square on its corner with two semicircles on its upper
    sides), as a dense closed polyline scaled to an overall extent of 1 and centred; returns
    (loop, corner indices): the top notch (index 0) and the bottom tip, both right angles."""
    h = 1.0
    r = h / math.sqrt(2.0)
    k = 1024
    a = np.linspace(math.radians(135), math.radians(-45), k, endpoint=False)
    right = np.column_stack([h / 2 + r * np.cos(a), -h / 2 + r * np.sin(a)])
    t = np.linspace(0.0, 1.0, k // 2, endpoint=False)[:, None]
    down = np.array([h, -h]) + t * np.array([-h, -h])
    up = np.array([0.0, -2 * h]) + t * np.array([-h, h])
    b = np.linspace(math.radians(225), math.radians(45), k, endpoint=False)
    left = np.column_stack([-h / 2 + r * np.cos(b), -h / 2 + r * np.sin(b)])
    loop = np.vstack([right, down, up, left])
    lo, hi = loop.min(axis=0), loop.max(axis=0)
    loop = (loop - (lo + hi) / 2) / float((hi - lo).max())
    return loop, np.array([0, len(right) + len(down)])


_HEART, _HEART_CORNERS = _heart_outline()


def _heart(n: int, size: float) -> np.ndarray:
    return _pinned_samples(_HEART * size, _HEART_CORNERS, n)


def _inside_polygon(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """(m,) whether each 2-D point is inside the closed polygon (even-odd ray casting, vectorised).

    Only the (edge, point) pairs whose ray can cross are formed: edge a -> b crosses the ray of a
    point at height y exactly when min(a_y, b_y) <= y < max(a_y, b_y) (the half-open rule of
    ``(a_y > y) != (b_y > y)``), a contiguous run of the points sorted by y. A point's ray meets
    a few edges, so the work is O((m + V) log m) rather than the m x V of testing every edge (the
    3072-vertex heart outline: m x 3072 per lattice, seconds per filled heart).
    """
    x, y = points[:, 0], points[:, 1]
    a, b = vertices, np.roll(vertices, -1, axis=0)
    order = np.argsort(y, kind="stable")
    y_sorted = y[order]
    lo = np.searchsorted(y_sorted, np.minimum(a[:, 1], b[:, 1]), side="left")
    hi = np.searchsorted(y_sorted, np.maximum(a[:, 1], b[:, 1]), side="left")
    counts = hi - lo
    edge = np.repeat(np.arange(len(a)), counts)  # (pairs,) edge of each (edge, point) pair
    run_start = np.cumsum(counts) - counts
    point = order[lo[edge] + np.arange(len(edge)) - run_start[edge]]  # (pairs,) its point
    ae, be, yp = a[edge], b[edge], y[point]
    x_at = ae[:, 0] + (yp - ae[:, 1]) * (be[:, 0] - ae[:, 0]) / (be[:, 1] - ae[:, 1])
    hits = np.bincount(point[x[point] < x_at], minlength=len(points))
    return np.asarray(hits % 2 == 1, dtype=np.bool_)


def _hex_lattice(step: float, half: float) -> np.ndarray:
    """A hexagonal lattice of spacing ``step`` covering [-half, half]² (rows alternate by step/2)."""
    dy = step * math.sqrt(3.0) / 2.0
    rows = np.arange(-math.floor(half / dy), math.floor(half / dy) + 1) * dy
    cols = np.arange(-math.floor(half / step) - 1, math.floor(half / step) + 2) * step
    u = cols[None, :] + (np.arange(len(rows))[:, None] % 2) * step / 2.0
    v = np.broadcast_to(rows[:, None], u.shape)
    return np.column_stack([u.ravel(), v.ravel()])


def _fill(inside: Callable[[np.ndarray], np.ndarray], n: int, size: float) -> np.ndarray:
    """n points filling a region of extent ``size`` evenly: the sparsest hexagonal lattice with at
    least n points inside, thinned evenly in lattice order to exactly n (spacing never drops)."""
    if n == 1:
        return np.zeros((1, 2))
    half = size / 2.0

    def lattice(step: float) -> np.ndarray:
        pts = _hex_lattice(step, half)
        return np.asarray(pts[inside(pts)], dtype=np.float64)

    # First guess from the region's area (counted on a fine lattice), then walk to the sparsest fit.
    fine = size / 60.0
    area = max(len(lattice(fine)), 1) * fine * fine * math.sqrt(3.0) / 2.0
    step = math.sqrt(area * 2.0 / math.sqrt(3.0) / n)
    while len(lattice(step)) < n:
        step *= 0.97
    while len(lattice(step * 1.01)) >= n:
        step *= 1.01
    pts = lattice(step)
    keep = np.round(np.linspace(0, len(pts) - 1, n)).astype(np.intp)
    return pts[keep]


def _star_vertices(size: float, points: int, inner_ratio: float) -> np.ndarray:
    k = 2 * points
    a = math.pi / 2 + 2 * math.pi * np.arange(k) / k
    r = np.where(np.arange(k) % 2 == 0, 1.0, inner_ratio) * (size / 2)
    return np.column_stack([r * np.cos(a), r * np.sin(a)])


def _rings(n: int, size: float) -> np.ndarray:
    """Concentric rings k·h (k = 0..K) filling a disc of diameter ``size``: ring k holds at most
    ⌊2πk⌋ points h apart along it; the n points go to rings by circumference (largest remainder)."""
    if n == 1:
        return np.zeros((1, 2))
    cap = [1]
    while sum(cap) < n:
        k = len(cap)
        cap.append(math.floor(2 * math.pi * k))
    h = (size / 2.0) / (len(cap) - 1)
    weights = np.array([0.5, *range(1, len(cap))], dtype=np.float64)
    counts = np.minimum(largest_remainder(weights, n), cap)
    # Whatever the caps cut goes outwards, where rings have room.
    for k in range(len(cap) - 1, -1, -1):
        counts[k] += min(cap[k] - counts[k], n - int(counts.sum()))
    out = []
    for k, c in enumerate(counts):
        if c == 0:
            continue
        if k == 0:
            out.append(np.zeros((1, 2)))
            continue
        a = math.pi / 2 + 2 * math.pi * np.arange(c) / c
        out.append(np.column_stack([np.cos(a), np.sin(a)]) * (k * h))
    return np.vstack(out)


def _sphere(n: int, size: float) -> np.ndarray:
    if n == 1:
        return np.zeros((1, 3))
    i = np.arange(n)
    z = 1.0 - 2.0 * (i + 0.5) / n
    r = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
    phi = i * _GOLDEN_ANGLE
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z]) * (size / 2)


def _helix(n: int, size: float, turns: float, radius_m: float) -> np.ndarray:
    if n == 1:
        return np.zeros((1, 3))
    t = np.arange(n) / (n - 1)
    a = 2 * math.pi * turns * t
    return np.column_stack([radius_m * np.cos(a), radius_m * np.sin(a), (t - 0.5) * size])


def _cube_capacity(k: int, filled: bool) -> int:
    return k**3 if filled or k <= 2 else k**3 - (k - 2) ** 3


def _cube(n: int, size: float, filled: bool) -> np.ndarray:
    if n == 1:
        return np.zeros((1, 3))
    k = 2
    while _cube_capacity(k, filled) < n:
        k += 1
    g = np.arange(k)
    iz, iy, ix = np.meshgrid(g, g, g, indexing="ij")
    idx = np.column_stack([ix.ravel(), iy.ravel(), iz.ravel()])
    if not filled:
        idx = idx[np.any((idx == 0) | (idx == k - 1), axis=1)]
    idx = idx[:n]  # bottom layers first; the top layer may be partial
    step = size / (k - 1)
    return (idx - (k - 1) / 2.0) * step


def _params(kind: str, params: dict[str, Any], size: float) -> dict[str, Any]:
    allowed = SHAPE_PARAMS[kind]
    unknown = sorted(set(params) - set(allowed))
    if unknown:
        names = ", ".join(allowed) or "none"
        raise FormationError(f"unknown parameter {unknown[0]!r} for {kind} (accepted: {names})")
    p = {**allowed, **params}
    if kind == "polygon":
        p["sides"] = _int_param(p["sides"], "sides", 3, 1000)
    elif kind in ("star", "filled_star"):
        p["points"] = _int_param(p["points"], "points", 2, 1000)
        ratio = check_positive(p["inner_ratio"], name="inner_ratio")
        if ratio >= 1.0:
            raise FormationError(f"inner_ratio must be in (0, 1), got {ratio}")
        p["inner_ratio"] = ratio
    elif kind == "helix":
        p["turns"] = check_positive(p["turns"], name="turns")
        if p["turns"] > 1000:
            raise FormationError(f"turns must be at most 1000, got {p['turns']}")
        p["radius_m"] = (
            size / 4 if p["radius_m"] is None else check_positive(p["radius_m"], name="radius_m")
        )
    elif kind == "cube":
        if not isinstance(p["filled"], bool | np.bool_):
            raise FormationError(f"filled must be true or false, got {p['filled']!r}")
        p["filled"] = bool(p["filled"])
    return p


def _int_param(value: Any, name: str, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not lo <= value <= hi:
        raise FormationError(f"{name} must be an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


def shape_generator(
    kind: str, *, size_m: float, params: dict[str, Any]
) -> Callable[[int], np.ndarray]:
    """Return ``f(n) -> (n, 2 or 3)`` local coordinates (metres, centred on 0) for ``kind``."""
    p = params
    gens: dict[str, Callable[[int], np.ndarray]] = {
        "grid": lambda n: _grid(n, size_m),
        "circle": lambda n: _circle(n, size_m),
        "polygon": lambda n: _polygon(n, size_m, p.get("sides", 6)),
        "star": lambda n: _star(n, size_m, p.get("points", 5), p.get("inner_ratio", 0.5)),
        "heart": lambda n: _heart(n, size_m),
        "sphere": lambda n: _sphere(n, size_m),
        "helix": lambda n: _helix(n, size_m, p.get("turns", 3.0), p.get("radius_m", size_m / 4)),
        "cube": lambda n: _cube(n, size_m, p.get("filled", True)),
        "disc": lambda n: _fill(lambda q: np.hypot(q[:, 0], q[:, 1]) <= size_m / 2, n, size_m),
        "rings": lambda n: _rings(n, size_m),
        "filled_star": lambda n: _fill(
            lambda q: _inside_polygon(q, _star_vertices(size_m, p.get("points", 5), p.get("inner_ratio", 0.5))),
            n, size_m,
        ),
        "filled_heart": lambda n: _fill(lambda q: _inside_polygon(q, _HEART * size_m), n, size_m),
    }
    return gens[kind]


def generate_shape(
    kind: str,
    n: int,
    *,
    size_m: float = 20.0,
    center_m: ArrayLike = (0.0, 0.0, 30.0),
    plane: str = "xz",
    min_spacing_m: float = 3.0,
    color: str = "#ffffff",
    **params: Any,
) -> PointSet:
    """Generate ``n`` points of a preset shape keeping ``min_spacing_m``.

    Args:
        kind: one of SHAPE_KINDS. "grid" (near-square lattice), "circle" (ring), "polygon"
            (outline; ``sides``=6), "star" (outline; ``points``=5 tips, ``inner_ratio``=0.5),
            "heart" (outline), "sphere" (Fibonacci spread on the surface), "helix" (vertical
            axis; ``turns``=3, ``radius_m``=size/4), "cube" (lattice; ``filled``=True, else shell);
            filled 2-D: "disc", "rings" (concentric), "filled_star" (as "star"), "filled_heart"
            (hexagonal lattices thinned evenly to n).
        n: number of points, 1..20000.
        size_m: overall extent in metres (diameter, side or height).
        center_m: centre of the shape, metres (x, y, z).
        plane: "xz" (vertical, facing the audience), "xy" (ground-parallel) or "yz";
            ignored by the 3-D kinds.
        min_spacing_m: minimum distance between any two points, metres.
        color: LED colour "#rrggbb".
        **params: kind-specific parameters (see above).

    Returns:
        PointSet of exactly ``n`` points.

    Raises:
        FormationError: bad argument, or ``n`` points do not fit at ``size_m``
            (``max_n`` is the largest count that does).
    """
    if kind not in SHAPE_KINDS:
        raise FormationError(f"kind must be one of {', '.join(SHAPE_KINDS)}, got {kind!r}")
    n = check_n(n)
    size = check_positive(size_m, name="size_m")
    center = check_center(center_m)
    plane = check_plane(plane)
    s = check_positive(min_spacing_m, name="min_spacing_m")
    cols_one = solid_colors(1, color)
    p = _params(kind, params, size)
    gen = shape_generator(kind, size_m=size, params=p)

    def raw(k: int) -> tuple[np.ndarray, np.ndarray]:
        local = gen(k)
        pts = local + center if local.shape[1] == 3 else place_on_plane(
            local, plane=plane, center_m=center
        )
        return pts, np.repeat(cols_one, k, axis=0)

    return guarantee(raw, n, s, what=f"a {kind} of size {size:g} m")
