"""Shape presets: exact N, spacing >= the minimum (brute force), closed forms, max_n, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import pdist

from formations.sources import (
    MAX_POINTS,
    SHAPE_KINDS,
    FormationError,
    PointSet,
    generate_shape,
)


def min_dist(points: np.ndarray) -> float:
    return float(pdist(points).min()) if len(points) > 1 else math.inf


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    kind=st.sampled_from(SHAPE_KINDS),
    n=st.integers(1, 400),
    size=st.floats(5.0, 200.0),
    spacing=st.floats(0.5, 6.0),
    plane=st.sampled_from(["xz", "xy", "yz"]),
)
def test_exact_n_and_spacing_or_max_n(kind, n, size, spacing, plane):
    try:
        ps = generate_shape(kind, n, size_m=size, min_spacing_m=spacing, plane=plane)
    except FormationError as exc:
        assert exc.max_n is not None and 1 <= exc.max_n < n
        assert f"largest N that fits is {exc.max_n}" in str(exc)
        fit = generate_shape(kind, exc.max_n, size_m=size, min_spacing_m=spacing, plane=plane)
        assert len(fit) == exc.max_n
        assert min_dist(fit.points_m) >= spacing
        # Bisection guarantees the neighbour above does not fit.
        with pytest.raises(FormationError):
            generate_shape(kind, exc.max_n + 1, size_m=size, min_spacing_m=spacing, plane=plane)
        return
    assert isinstance(ps, PointSet)
    assert ps.points_m.shape == (n, 3) and ps.colors_rgb.shape == (n, 3)
    assert min_dist(ps.points_m) >= spacing
    assert np.all(np.isfinite(ps.points_m))


@pytest.mark.parametrize("kind", SHAPE_KINDS)
def test_deterministic_and_coloured(kind):
    a = generate_shape(kind, 50, size_m=60.0, color="#12ab34")
    b = generate_shape(kind, 50, size_m=60.0, color="#12ab34")
    assert np.array_equal(a.points_m, b.points_m)
    assert a.hex_colors() == ["#12ab34"] * 50


@pytest.mark.parametrize("kind", SHAPE_KINDS)
def test_centred_and_within_size(kind):
    c = np.array([5.0, -7.0, 40.0])
    ps = generate_shape(kind, 40, size_m=60.0, center_m=c, plane="xz")
    pts = ps.points_m
    # Every kind fits inside a box of its size about the centre (helix: its height).
    assert np.all(np.abs(pts - c) <= 30.0 + 1e-6)
    if kind not in ("sphere", "helix", "cube"):
        assert np.allclose(pts[:, 1], c[1])  # x-z plane: y constant


def test_circle_closed_form():
    n, size = 36, 50.0
    pts = generate_shape("circle", n, size_m=size, center_m=(1, 2, 40), plane="xz").points_m
    rel = pts - [1, 2, 40]
    assert np.allclose(np.hypot(rel[:, 0], rel[:, 2]), size / 2)
    assert np.allclose(rel[:, 1], 0.0)
    # Evenly spaced: every neighbour chord is 2 r sin(pi / n).
    ang = np.sort(np.arctan2(rel[:, 2], rel[:, 0]))
    assert np.allclose(np.diff(ang), 2 * np.pi / n)
    assert min_dist(pts) == pytest.approx(size * math.sin(math.pi / n))


def test_ring_in_ground_plane():
    pts = generate_shape("circle", 20, size_m=40.0, center_m=(0, 0, 25), plane="xy").points_m
    assert np.allclose(pts[:, 2], 25.0)
    assert np.allclose(np.hypot(pts[:, 0], pts[:, 1]), 20.0)


def test_sphere_on_surface_and_even():
    n, size = 300, 60.0
    pts = generate_shape("sphere", n, size_m=size, center_m=(0, 0, 50)).points_m
    r = np.linalg.norm(pts - [0, 0, 50], axis=1)
    assert np.allclose(r, size / 2)
    # Even spread: nearest-neighbour distances vary little (a random spread would not).
    from scipy.spatial import cKDTree

    d, _ = cKDTree(pts).query(pts, k=2)
    nn = d[:, 1]
    assert nn.min() > 0.6 * nn.mean()
    # Balanced hemispheres.
    assert abs(int((pts[:, 2] > 50).sum()) - n // 2) <= 1


def test_grid_spacing_closed_form():
    pts = generate_shape("grid", 25, size_m=20.0, center_m=(0, 0, 30), plane="xz").points_m
    assert sorted(set(np.round(pts[:, 0], 9))) == pytest.approx([-10, -5, 0, 5, 10])
    assert sorted(set(np.round(pts[:, 2], 9))) == pytest.approx([20, 25, 30, 35, 40])
    assert min_dist(pts) == pytest.approx(5.0)


def test_polygon_and_star_vertices_present():
    hexagon = generate_shape("polygon", 12, size_m=20.0, center_m=(0, 0, 30), sides=6).points_m
    a = np.pi / 2 + 2 * np.pi * np.arange(6) / 6
    verts = np.c_[10 * np.cos(a), np.zeros(6), 30 + 10 * np.sin(a)]
    for v in verts:
        assert np.min(np.linalg.norm(hexagon - v, axis=1)) < 1e-9
    star = generate_shape("star", 30, size_m=60.0, center_m=(0, 0, 30), points=5, inner_ratio=0.4).points_m
    r = np.hypot(star[:, 0], star[:, 2] - 30)
    # Tips and inner corners are pinned; every edge point lies between the two radii.
    assert r.max() == pytest.approx(30.0)
    assert r.min() == pytest.approx(0.4 * 30.0)


def test_helix_closed_form():
    pts = generate_shape("helix", 30, size_m=40.0, center_m=(0, 0, 50), turns=2.0, radius_m=8.0).points_m
    assert np.allclose(np.hypot(pts[:, 0], pts[:, 1]), 8.0)
    assert pts[:, 2].min() == pytest.approx(30.0) and pts[:, 2].max() == pytest.approx(70.0)


def test_cube_lattice_and_shell():
    full = generate_shape("cube", 27, size_m=20.0, center_m=(0, 0, 30)).points_m
    assert min_dist(full) == pytest.approx(10.0)
    assert len({tuple(p) for p in np.round(full, 6)}) == 27
    shell = generate_shape("cube", 26, size_m=20.0, center_m=(0, 0, 30), filled=False).points_m
    # A 3x3x3 shell has no centre point.
    assert np.min(np.linalg.norm(shell - [0, 0, 30], axis=1)) >= 10.0 - 1e-9


def test_too_many_points_error_names_max_n():
    with pytest.raises(FormationError) as info:
        generate_shape("circle", 100, size_m=40.0, min_spacing_m=3.0)
    # Circumference 40 pi = 125.7 m holds floor(pi / asin(3 / 40)) points at >= 3 m chords.
    expected = math.floor(math.pi / math.asin(3.0 / 40.0))
    assert info.value.max_n == expected
    assert str(expected) in str(info.value)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"kind": "blob"}, "kind must be one of"),
        ({"n": 0}, "between 1 and"),
        ({"n": MAX_POINTS + 1}, "between 1 and"),
        ({"n": 2.5}, "integer"),
        ({"size_m": -1.0}, "size_m"),
        ({"size_m": float("nan")}, "size_m"),
        ({"min_spacing_m": 0.0}, "min_spacing_m"),
        ({"plane": "zz"}, "plane"),
        ({"center_m": (0, 0)}, "center_m"),
        ({"color": "red"}, "#rrggbb"),
        ({"kind": "polygon", "sides": 2}, "sides"),
        ({"kind": "star", "inner_ratio": 1.5}, "inner_ratio"),
        ({"kind": "circle", "sides": 5}, "unknown parameter"),
        ({"kind": "cube", "filled": "yes"}, "filled"),
    ],
)
def test_bad_arguments(kwargs, match):
    args = {"kind": "circle", "n": 10, "size_m": 40.0, **kwargs}
    kind, n = args.pop("kind"), args.pop("n")
    with pytest.raises(FormationError, match=match):
        generate_shape(kind, n, **args)


def test_to_json_round_trip():
    ps = generate_shape("heart", 30, size_m=50.0, color="#ff0000")
    doc = ps.to_json()
    assert len(doc["points"]) == 30 and doc["colors"] == ["#ff0000"] * 30
    assert doc["min_spacing_m"] == pytest.approx(min_dist(np.array(doc["points"])))
    assert generate_shape("sphere", 1).to_json()["min_spacing_m"] is None
