"""Strokes and text: exact N, spacing >= the minimum (brute force), even spread, max_n, errors."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.distance import pdist

from formations.sources import FormationError, stroke_points, text_points


def min_dist(points: np.ndarray) -> float:
    return float(pdist(points).min()) if len(points) > 1 else math.inf


# -- strokes ---------------------------------------------------------------------------------


def test_single_stroke_is_even_by_arc_length():
    # An L of total length 60 m drawn in the x-z plane.
    ps = stroke_points([[[0.0, 40.0], [0.0, 0.0], [20.0, 0.0]]], 12, min_spacing_m=3.0)
    pts = ps.points_m
    assert len(pts) == 12 and np.allclose(pts[:, 1], 0.0)
    # Arc positions (j + 1/2) * 5 m along the L: consecutive arc gaps of 5 m.
    arc = np.where(pts[:, 0] == 0.0, 40.0 - pts[:, 2], 40.0 + pts[:, 0])
    assert np.allclose(np.diff(arc), 5.0)
    assert arc[0] == pytest.approx(2.5)


def test_count_shared_by_length_and_closed_strokes():
    long = [[0.0, 0.0], [90.0, 0.0]]
    short = [[0.0, 20.0], [30.0, 20.0]]
    pts = stroke_points([long, short], 20, min_spacing_m=1.0).points_m
    assert int((pts[:, 2] == 0.0).sum()) == 15 and int((pts[:, 2] == 20.0).sum()) == 5
    square = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0], [0.0, 0.0]]
    closed = stroke_points([square], 8, min_spacing_m=1.0).points_m
    # Closed: every gap (including last -> first) is 40 / 8 = 5 m along the loop.
    assert min_dist(closed) == pytest.approx(5.0)


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 300),
    length=st.floats(5.0, 500.0),
    spacing=st.floats(0.5, 5.0),
    turns=st.integers(1, 4),
)
def test_strokes_exact_n_and_spacing(n, length, spacing, turns):
    # A zig-zag polyline of the given length.
    k = turns + 1
    xs = np.linspace(0.0, length / math.sqrt(2), k)
    zs = np.where(np.arange(k) % 2 == 0, 0.0, length / (math.sqrt(2) * turns))
    try:
        ps = stroke_points([np.c_[xs, zs]], n, min_spacing_m=spacing, center_m=(0, 0, 40))
    except FormationError as exc:
        assert exc.max_n is not None and 1 <= exc.max_n < n
        fit = stroke_points([np.c_[xs, zs]], exc.max_n, min_spacing_m=spacing, center_m=(0, 0, 40))
        assert len(fit) == exc.max_n and min_dist(fit.points_m) >= spacing
        with pytest.raises(FormationError):
            stroke_points([np.c_[xs, zs]], exc.max_n + 1, min_spacing_m=spacing, center_m=(0, 0, 40))
        return
    assert len(ps) == n and min_dist(ps.points_m) >= spacing


def test_stroke_errors():
    with pytest.raises(FormationError, match="zero total length"):
        stroke_points([[[1.0, 1.0], [1.0, 1.0]]], 3)
    with pytest.raises(FormationError, match="all be 2-D"):
        stroke_points([[[0.0, 0.0], [1.0, 0.0]], [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]], 3)
    with pytest.raises(FormationError, match="finite"):
        stroke_points([[[0.0, 0.0], [float("nan"), 0.0]]], 3)


# -- text ------------------------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(
    text=st.sampled_from(["HI", "A", "Hello", "SWARM\nSHOW", "42!"]),
    n=st.integers(1, 120),
    height=st.floats(8.0, 60.0),
    spacing=st.floats(1.0, 5.0),
)
def test_text_exact_n_and_spacing(text, n, height, spacing):
    try:
        ps = text_points(text, n, height_m=height, min_spacing_m=spacing)
    except FormationError as exc:
        assert exc.max_n is not None and 1 <= exc.max_n < n
        assert f"largest N that fits is {exc.max_n}" in str(exc)
        fit = text_points(text, exc.max_n, height_m=height, min_spacing_m=spacing)
        assert len(fit) == exc.max_n and min_dist(fit.points_m) >= spacing
        # Both samplers succeed exactly up to a threshold, so max_n is tight.
        with pytest.raises(FormationError):
            text_points(text, exc.max_n + 1, height_m=height, min_spacing_m=spacing)
        return
    assert len(ps) == n and min_dist(ps.points_m) >= spacing


def test_text_fills_its_box_and_is_deterministic():
    center = np.array([5.0, 0.0, 40.0])
    a = text_points("HI", 60, height_m=30.0, center_m=center, min_spacing_m=2.0, color="#ff8800")
    b = text_points("HI", 60, height_m=30.0, center_m=center, min_spacing_m=2.0, color="#ff8800")
    assert np.array_equal(a.points_m, b.points_m)
    assert a.hex_colors() == ["#ff8800"] * 60
    pts = a.points_m
    assert np.allclose(pts[:, 1], 0.0)
    # The ink box is 30 m tall, centred on the centre: points reach close to both ends.
    assert pts[:, 2].max() <= 55.0 + 1e-9 and pts[:, 2].min() >= 25.0 - 1e-9
    assert pts[:, 2].max() - pts[:, 2].min() > 30.0 - 4.0
    # "HI" is wider than tall; H's two bars: both the left and right edge are used.
    assert np.ptp(pts[:, 0]) > 30.0


def test_letter_i_is_a_vertical_bar():
    pts = text_points("I", 10, height_m=40.0, min_spacing_m=3.0).points_m
    # A bold I is about 0.15 of its height wide: all points share nearly one x.
    assert np.ptp(pts[:, 0]) < 0.25 * 40.0
    assert np.ptp(pts[:, 2]) > 0.7 * 40.0


def test_multiline_is_taller_per_character_than_one_line():
    one = text_points("ABCD", 40, height_m=20.0, min_spacing_m=1.0).points_m
    two = text_points("AB\nCD", 40, height_m=20.0, min_spacing_m=1.0).points_m
    # Same block height, half the line length: the two-line block is about half as wide.
    assert np.ptp(two[:, 0]) < 0.7 * np.ptp(one[:, 0])


def test_text_in_ground_plane():
    pts = text_points("OK", 20, height_m=20.0, center_m=(0, 0, 25), plane="xy").points_m
    assert np.allclose(pts[:, 2], 25.0)


@pytest.mark.parametrize(
    "text, match",
    [("", "empty"), ("   \n ", "empty"), ("a\x00b", "control"), ("x" * 1001, "limit"), (b"HI", "string"),
     ("\n".join("a" * 51), "lines")],
)
def test_text_rejections(text, match):
    with pytest.raises(FormationError, match=match):
        text_points(text, 5)


def test_text_too_many_points_names_max_n():
    with pytest.raises(FormationError) as info:
        text_points("HI", 500, height_m=10.0, min_spacing_m=3.0)
    max_n = info.value.max_n
    assert max_n is not None and 1 <= max_n < 500
    assert len(text_points("HI", max_n, height_m=10.0, min_spacing_m=3.0)) == max_n


@settings(max_examples=30, deadline=None)
@given(
    text=st.text(alphabet=st.sampled_from("ABCXYZabcxyz0189!?.,- \n"), min_size=1, max_size=20),
    n=st.integers(1, 60),
)
def test_arbitrary_text_gives_n_points_or_a_reason(text, n):
    try:
        ps = text_points(text, n, height_m=30.0, min_spacing_m=2.0)
    except FormationError as exc:
        assert exc.max_n is not None and exc.max_n < n
        if exc.max_n > 0:
            assert len(text_points(text, exc.max_n, height_m=30.0, min_spacing_m=2.0)) == exc.max_n
        else:
            assert "empty" in str(exc) or "no visible" in str(exc)
        return
    assert len(ps) == n and min_dist(ps.points_m) >= 2.0
