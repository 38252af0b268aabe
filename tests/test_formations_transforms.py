"""Transforms against closed forms; spacing repair and fit-to-count against brute force."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import pdist
from scipy.spatial.transform import Rotation

from formations.sources import (
    FormationError,
    fit_to_count,
    generate_shape,
    place_on_plane,
    repair_spacing,
    rotate,
    rotation_matrix,
    scale,
    translate,
)


def min_dist(points: np.ndarray) -> float:
    return float(pdist(points).min()) if len(points) > 1 else math.inf


PTS = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0], [1.0, 1.0, 1.0]])


def test_translate():
    assert np.array_equal(translate(PTS, (1, -2, 3)), PTS + [1, -2, 3])
    with pytest.raises(FormationError):
        translate(PTS, (1, 2))


def test_scale_about_point_and_per_axis():
    about = np.array([1.0, 1.0, 1.0])
    out = scale(PTS, 2.0, about=about)
    assert np.allclose(out, about + 2.0 * (PTS - about))
    per_axis = scale(PTS, (1.0, 2.0, 3.0), about=(0, 0, 0))
    assert np.allclose(per_axis, PTS * [1, 2, 3])
    # Default: about the centroid, which stays put.
    assert np.allclose(scale(PTS, 5.0).mean(axis=0), PTS.mean(axis=0))
    with pytest.raises(FormationError):
        scale(PTS, float("inf"))


def test_rotate_quarter_turns():
    assert np.allclose(rotate([[1.0, 0, 0]], math.pi / 2, axis="z", about=(0, 0, 0)), [[0, 1, 0]])
    assert np.allclose(rotate([[0, 1.0, 0]], math.pi / 2, axis="x", about=(0, 0, 0)), [[0, 0, 1]])
    assert np.allclose(rotate([[0, 0, 1.0]], math.pi / 2, axis="y", about=(0, 0, 0)), [[1, 0, 0]])
    # About a point: that point is fixed.
    assert np.allclose(rotate([[2.0, 1, 0]], math.pi, axis="z", about=(1, 1, 0)), [[0, 1, 0]])


@settings(max_examples=30, deadline=None)
@given(
    axis=st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda a: np.linalg.norm(a) > 0.1),
    angle=st.floats(-2 * math.pi, 2 * math.pi),
)
def test_rotation_matches_scipy_and_is_rigid(axis, angle):
    k = np.array(axis) / np.linalg.norm(axis)
    r = rotation_matrix(angle, axis)
    assert np.allclose(r, Rotation.from_rotvec(angle * k).as_matrix(), atol=1e-12)
    out = rotate(PTS, angle, axis=axis)
    assert np.allclose(pdist(out), pdist(PTS))


def test_place_on_plane():
    uv = np.array([[1.0, 2.0], [-3.0, 0.5]])
    c = (10.0, 20.0, 30.0)
    assert np.allclose(place_on_plane(uv, plane="xz", center_m=c), [[11, 20, 32], [7, 20, 30.5]])
    assert np.allclose(place_on_plane(uv, plane="xy", center_m=c), [[11, 22, 30], [7, 20.5, 30]])
    assert np.allclose(place_on_plane(uv, plane="yz", center_m=c), [[10, 21, 32], [10, 17, 30.5]])
    with pytest.raises(FormationError):
        place_on_plane(uv, plane="ab")


@settings(max_examples=50, deadline=None)
@given(n=st.integers(10, 150), seed=st.integers(0, 10_000), spacing=st.floats(1.0, 5.0))
def test_repair_spreads_points_and_stays_near(n, seed, spacing):
    rng = np.random.default_rng(seed)
    # A roomy ring with a few points jittered onto their neighbours.
    ring = generate_shape("circle", n, size_m=n * spacing * 1.5 / math.pi, min_spacing_m=spacing).points_m
    pts = ring.copy()
    bad = rng.choice(n, size=max(1, n // 10), replace=False)
    pts[bad] = ring[(bad + 1) % n] + rng.normal(scale=0.05 * spacing, size=(len(bad), 3)) * [1, 0, 1]
    before = min_dist(pts)
    fixed, achieved = repair_spacing(pts, spacing)
    assert achieved == pytest.approx(min_dist(fixed))
    assert achieved > before
    assert achieved >= spacing
    # Stays near the drawing and in its plane (y constant for an x-z drawing).
    assert np.linalg.norm(fixed - pts, axis=1).max() <= spacing
    assert np.allclose(fixed[:, 1], pts[:, 1])


def test_repair_is_deterministic_and_handles_coincident_points():
    pts = np.zeros((4, 3)) + [0, 0, 30]
    pts[:, 0] = [0.0, 0.0, 0.0, 10.0]
    a, da = repair_spacing(pts, 2.0, seed=3)
    b, db = repair_spacing(pts, 2.0, seed=3)
    assert np.array_equal(a, b) and da == db
    assert da >= 2.0


def test_fit_to_count_grows_and_shrinks():
    drawn = np.c_[np.linspace(0, 100, 11), np.zeros(11), np.full(11, 30.0)]
    cols = np.tile([255, 0, 0], (11, 1))
    grown = fit_to_count(drawn, cols, 30, min_spacing_m=3.0)
    assert len(grown) == 30 and min_dist(grown.points_m) >= 3.0
    assert np.allclose(grown.points_m[:, 1:], [0, 30])  # still on the drawn line
    shrunk = fit_to_count(drawn, cols, 5, min_spacing_m=3.0)
    assert len(shrunk) == 5 and min_dist(shrunk.points_m) >= 3.0
    with pytest.raises(FormationError) as info:
        fit_to_count(drawn, cols, 200, min_spacing_m=3.0)
    assert info.value.max_n is not None and 30 <= info.value.max_n < 200
    assert len(fit_to_count(drawn, cols, info.value.max_n, min_spacing_m=3.0)) == info.value.max_n
