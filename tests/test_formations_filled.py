"""Filled 2-D presets (disc, concentric rings, filled star, filled heart) against independent
inside tests, brute-force spacing, and how evenly they fill."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import pdist

from formations._points import FormationError
from formations._shapes import generate_shape

CENTER = np.array([5.0, 0.0, 40.0])


def _local(kind: str, n: int, size: float, **params) -> np.ndarray:
    """(n, 2) points in the shape's own plane (x, z of the default front plane), centred."""
    p = generate_shape(kind, n, size_m=size, center_m=CENTER, min_spacing_m=3.0, **params).points_m
    assert np.allclose(p[:, 1], 0.0)
    return (p - CENTER)[:, [0, 2]]


def _inside_star_polar(q: np.ndarray, size: float, tips: int, ratio: float) -> np.ndarray:
    """Star-shaped about its centre: inside iff the radius is within the boundary's along that ray."""
    theta = np.mod(np.arctan2(q[:, 1], q[:, 0]) - math.pi / 2, 2 * math.pi / tips)
    half = math.pi / tips
    # The edge from a tip (angle 0, radius R) to an inner vertex (angle half, radius rR), in polar form.
    R, r = size / 2, ratio * size / 2
    t = np.where(theta <= half, theta, 2 * half - theta)
    a, b = np.array([R, 0.0]), np.array([r * math.cos(half), r * math.sin(half)])
    d = np.column_stack([np.cos(t), np.sin(t)])
    e = b - a
    # Ray s·d hits a + u·e: s = cross(a, e) / cross(d, e).
    s = (a[0] * e[1] - a[1] * e[0]) / (d[:, 0] * e[1] - d[:, 1] * e[0])
    return np.hypot(q[:, 0], q[:, 1]) <= s + 1e-9


def _inside_heart(q: np.ndarray, size: float) -> np.ndarray:
    """The geometric heart as a square on its corner plus two discs on its upper sides (then fitted
    to an extent of ``size``): built independently of the generator's outline."""
    h = 1.0
    r = h / math.sqrt(2)
    # Unscaled: square with corners (0, 0) notch, (h, -h), (0, -2h) tip, (-h, -h); discs centred (±h/2, -h/2).
    lo = np.array([-h / 2 - r, -2 * h])
    hi = np.array([h / 2 + r, -h / 2 + r])
    scale = float((hi - lo).max())
    u = q / size * scale + (lo + hi) / 2
    square = (np.abs(u[:, 0]) + np.abs(u[:, 1] + h)) <= h + 1e-9
    right = np.hypot(u[:, 0] - h / 2, u[:, 1] + h / 2) <= r + 1e-9
    left = np.hypot(u[:, 0] + h / 2, u[:, 1] + h / 2) <= r + 1e-9
    discs = right | left
    return square | discs


@settings(max_examples=12, deadline=None)
@given(n=st.integers(2, 300), size=st.floats(60.0, 150.0))
def test_disc_and_rings_fill_the_disc(n: int, size: float) -> None:
    for kind in ("disc", "rings"):
        q = _local(kind, n, size)
        assert len(q) == n and pdist(q).min() >= 3.0 - 1e-9
        assert np.all(np.hypot(q[:, 0], q[:, 1]) <= size / 2 + 1e-6)
    rings = _local("rings", n, size)
    radii = np.hypot(rings[:, 0], rings[:, 1])
    step = radii[radii > 1e-6].min()
    assert np.allclose(radii / step, np.round(radii / step), atol=1e-6)  # on circles k·h


def test_filled_shapes_are_filled_not_outlines() -> None:
    """A filled disc has ~ a quarter of its points within half its radius (area ratio); an outline none."""
    q = _local("disc", 300, 100.0)
    inner = np.mean(np.hypot(q[:, 0], q[:, 1]) <= 25.0)
    assert 0.18 <= inner <= 0.32
    ring = _local("circle", 30, 100.0)
    assert np.all(np.hypot(ring[:, 0], ring[:, 1]) > 49.0)


@pytest.mark.parametrize("tips, ratio", [(5, 0.5), (6, 0.4), (3, 0.6)])
def test_filled_star_is_inside_the_star(tips: int, ratio: float) -> None:
    q = _local("filled_star", 150, 100.0, points=tips, inner_ratio=ratio)
    assert pdist(q).min() >= 3.0 - 1e-9
    assert _inside_star_polar(q, 100.0, tips, ratio).all()
    # It reaches into the tips: some point beyond the inner radius in every tip.
    ang = np.mod(np.arctan2(q[:, 1], q[:, 0]) - math.pi / 2 + math.pi / tips, 2 * math.pi) // (2 * math.pi / tips)
    far = np.hypot(q[:, 0], q[:, 1]) > ratio * 50.0
    assert set(ang[far].astype(int)) == set(range(tips))


def test_filled_heart_is_inside_the_heart() -> None:
    q = _local("filled_heart", 200, 90.0)
    assert pdist(q).min() >= 3.0 - 1e-9
    assert _inside_heart(q, 90.0).all()
    # Both lobes and the tip are used.
    assert (q[:, 0] < -20).any() and (q[:, 0] > 20).any() and (q[:, 1] < -30).any()


def test_too_many_points_say_the_largest_that_fits() -> None:
    with pytest.raises(FormationError) as exc:
        generate_shape("disc", 500, size_m=30.0, min_spacing_m=3.0)
    m = exc.value.max_n
    assert m is not None and 0 < m < 500
    generate_shape("disc", m, size_m=30.0, min_spacing_m=3.0)
    # A hexagonal packing of 3 m in a 30 m disc holds about π·15²/(√3/2·9) ≈ 90.
    assert 60 <= m <= 100


def _even_odd_every_edge(q: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """Brute-force even-odd rule: every point's rightward ray against every edge (m x V), counting an edge
    whose half-open y-range [min, max) holds the point's height and which lies right of it there."""
    a, b = vertices, np.roll(vertices, -1, axis=0)
    y = q[:, 1:2]
    spans = (np.minimum(a[:, 1], b[:, 1]) <= y) & (y < np.maximum(a[:, 1], b[:, 1]))
    with np.errstate(divide="ignore", invalid="ignore"):
        x_at = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    return (spans & (q[:, :1] < x_at)).sum(axis=1) % 2 == 1


@pytest.mark.parametrize("outline", ["heart", "star"])
def test_inside_polygon_is_the_even_odd_rule_on_every_edge(outline: str) -> None:
    """The filled shapes' inside test (edges paired only with the points at their heights) says what the
    even-odd rule over every edge says: on lattices, random points, points rounded onto shared heights, and
    the polygon's own vertices (rays through a vertex)."""
    from formations._shapes import _HEART, _hex_lattice, _inside_polygon, _star_vertices

    rng = np.random.default_rng(7)
    for size in (5.0, 37.3, 200.0):
        poly = _HEART * size if outline == "heart" else _star_vertices(size, 5, 0.5)
        for q in (_hex_lattice(size / 25, size / 2), rng.uniform(-size, size, (600, 2)),
                  np.round(rng.uniform(-size, size, (600, 2)), 1), poly.copy()):
            inside = _inside_polygon(q, poly)
            assert np.array_equal(inside, _even_odd_every_edge(q, poly))
            assert 0 < inside.sum() < len(q)
