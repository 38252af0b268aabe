"""Image and SVG sources: exact N, spacing (brute force), colours, placement, size limits,
undecodable input, and refusal of DOCTYPE / entities (billion laughs, XXE) before parsing."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
import svgelements
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image, ImageDraw
from scipy.spatial.distance import pdist

from formations.sources import (
    MAX_IMAGE_BYTES,
    MAX_IMAGE_PIXELS,
    MAX_SVG_BYTES,
    FormationError,
    InputTooLargeError,
    image_points,
    svg_points,
)


def min_dist(points: np.ndarray) -> float:
    return float(pdist(points).min()) if len(points) > 1 else math.inf


def png(im: Image.Image, fmt: str = "PNG") -> bytes:
    buf = io.BytesIO()
    im.save(buf, fmt)
    return buf.getvalue()


def disk_png(size: int = 200, radius: int = 80) -> bytes:
    im = Image.new("RGB", (size, size), "black")
    ImageDraw.Draw(im).ellipse(
        [size / 2 - radius, size / 2 - radius, size / 2 + radius, size / 2 + radius], fill="white"
    )
    return png(im)


# -- image -----------------------------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 250), width=st.floats(20.0, 120.0), spacing=st.floats(1.0, 6.0))
def test_image_exact_n_and_spacing(n, width, spacing):
    data = disk_png()
    try:
        ps = image_points(data, n, width_m=width, min_spacing_m=spacing)
    except FormationError as exc:
        assert exc.max_n is not None and 1 <= exc.max_n < n
        fit = image_points(data, exc.max_n, width_m=width, min_spacing_m=spacing)
        assert len(fit) == exc.max_n and min_dist(fit.points_m) >= spacing
        with pytest.raises(FormationError):
            image_points(data, exc.max_n + 1, width_m=width, min_spacing_m=spacing)
        return
    assert len(ps) == n and min_dist(ps.points_m) >= spacing


def test_image_points_lie_on_the_bright_disk_and_are_even():
    # 200 px image 40 m wide: the disk has radius 80 px = 16 m.
    ps = image_points(disk_png(), 60, width_m=40.0, center_m=(0, 0, 40), min_spacing_m=2.0)
    pts = ps.points_m
    r = np.hypot(pts[:, 0], pts[:, 2] - 40.0)
    assert r.max() <= 16.0 + 0.3
    assert set(ps.hex_colors()) == {"#ffffff"}
    # Even, not clumped: nearest-neighbour distances within a factor ~1.6 of each other.
    from scipy.spatial import cKDTree

    d, _ = cKDTree(pts).query(pts, k=2)
    assert d[:, 1].max() < 1.6 * d[:, 1].min()
    # Spread over the whole disk (farther than half the radius from the centre, both sides).
    assert (pts[:, 0] > 8).any() and (pts[:, 0] < -8).any()


def test_image_colours_from_pixels_and_alpha_mode():
    im = Image.new("RGBA", (100, 50), (0, 0, 0, 0))
    draw = ImageDraw.Draw(im)
    draw.rectangle([0, 0, 49, 49], fill=(255, 0, 0, 255))
    draw.rectangle([50, 0, 99, 49], fill=(0, 0, 255, 255))
    ps = image_points(png(im), 40, width_m=100.0, center_m=(0, 0, 50), min_spacing_m=3.0)
    pts, cols = ps.points_m, ps.hex_colors()
    for p, c in zip(pts, cols, strict=True):
        assert c == ("#ff0000" if p[0] < 0 else "#0000ff")
    # A transparent dark square on an opaque background: alpha mode uses the opaque pixels only.
    im2 = Image.new("RGBA", (60, 60), (0, 0, 0, 0))
    ImageDraw.Draw(im2).rectangle([20, 20, 39, 39], fill=(10, 200, 10, 255))
    ps2 = image_points(png(im2), 9, width_m=60.0, center_m=(0, 0, 50), mode="alpha", min_spacing_m=2.0)
    assert np.all(np.abs(ps2.points_m[:, [0, 2]] - [0, 50]) <= 10.0 + 1e-9)
    assert set(ps2.hex_colors()) == {"#0ac80a"}


def test_image_deterministic_and_jpeg():
    data = png(Image.open(io.BytesIO(disk_png())).convert("RGB"), "JPEG")
    a = image_points(data, 30, width_m=40.0)
    b = image_points(data, 30, width_m=40.0)
    assert np.array_equal(a.points_m, b.points_m) and len(a) == 30


def test_image_too_many_points_names_max_n():
    with pytest.raises(FormationError) as info:
        image_points(disk_png(), 2000, width_m=40.0, min_spacing_m=3.0)
    max_n = info.value.max_n
    # The disk's area is 256 pi m^2; a hexagonal packing at 3 m holds at most ~ area / (3^2 sqrt(3)/2) + boundary.
    assert max_n is not None and 10 < max_n < 256 * math.pi / (9 * math.sqrt(3) / 2) * 1.3
    assert len(image_points(disk_png(), max_n, width_m=40.0, min_spacing_m=3.0)) == max_n


def test_image_rejections():
    with pytest.raises(FormationError, match="decode"):
        image_points(b"not an image at all", 5)
    with pytest.raises(FormationError, match="no bright"):
        image_points(png(Image.new("RGB", (20, 20), "black")), 5)
    big = png(Image.new("1", (8000, MAX_IMAGE_PIXELS // 8000 + 1)))
    with pytest.raises(InputTooLargeError, match="pixels"):
        image_points(big, 5)
    with pytest.raises(InputTooLargeError, match="bytes"):
        image_points(b"\x89PNG" + bytes(MAX_IMAGE_BYTES), 5)


# -- SVG -------------------------------------------------------------------------------------

SVG_NS = 'xmlns="http://www.w3.org/2000/svg"'


def svg(body: str, view: str = "0 0 100 100") -> bytes:
    return f'<svg {SVG_NS} viewBox="{view}">{body}</svg>'.encode()


def test_svg_line_sampled_evenly_along_length():
    ps = svg_points(svg('<path d="M 0 50 L 100 50" stroke="#00ff00"/>'), 10, width_m=50.0,
                    center_m=(0, 0, 30), min_spacing_m=1.0)
    pts = ps.points_m[np.argsort(ps.points_m[:, 0])]
    assert np.allclose(pts[:, 2], 30.0) and np.allclose(pts[:, 1], 0.0)
    # Open stroke: positions (j + 1/2) * 5 m along a 50 m line centred on x = 0.
    assert np.allclose(pts[:, 0], -25.0 + 5.0 * (np.arange(10) + 0.5))
    assert set(ps.hex_colors()) == {"#00ff00"}


def test_svg_circle_and_y_axis_flip():
    # A circle and a small square in the SVG's top-left corner (SVG y points down).
    body = '<circle cx="50" cy="50" r="40" stroke="red" fill="none"/><rect x="0" y="0" width="5" height="5"/>'
    ps = svg_points(svg(body), 40, width_m=90.0, center_m=(0, 0, 50), min_spacing_m=2.0, color="#123456")
    assert set(ps.hex_colors()) == {"#123456"}
    pts = ps.points_m
    # The bounding box is SVG (0..90, 0..90) -> 90 m, centred on (45, 45): the circle's centre lands at
    # x = 5, z = 45 and the square (SVG top-left) at the top-left, x < -40, z > 85.
    d = np.hypot(pts[:, 0] - 5.0, pts[:, 2] - 45.0)
    circle, square = pts[d < 50.0], pts[d >= 50.0]
    assert np.allclose(d[d < 50.0], 40.0, rtol=2e-3)
    assert len(circle) > len(square) >= 1
    assert np.all(square[:, 0] <= -40.0 + 1e-9) and np.all(square[:, 2] >= 85.0 - 1e-9)
    assert np.allclose(pts[:, 1], 0.0)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(1, 200), width=st.floats(10.0, 200.0), spacing=st.floats(0.5, 6.0))
def test_svg_exact_n_and_spacing(n, width, spacing):
    body = ('<path d="M 10 10 C 40 90 60 -30 90 60" stroke="blue" fill="none"/>'
            '<polygon points="20,80 50,95 80,80" stroke="yellow" fill="none"/>')
    data = svg(body)
    try:
        ps = svg_points(data, n, width_m=width, min_spacing_m=spacing)
    except FormationError as exc:
        assert exc.max_n is not None and 1 <= exc.max_n < n
        fit = svg_points(data, exc.max_n, width_m=width, min_spacing_m=spacing)
        assert len(fit) == exc.max_n and min_dist(fit.points_m) >= spacing
        with pytest.raises(FormationError):
            svg_points(data, exc.max_n + 1, width_m=width, min_spacing_m=spacing)
        return
    assert len(ps) == n and min_dist(ps.points_m) >= spacing


def test_svg_count_shared_by_length_with_colours_and_transforms():
    body = ('<g transform="translate(5,5)"><line x1="0" y1="0" x2="75" y2="0" stroke="#ff0000"/></g>'
            '<line x1="0" y1="40" x2="25" y2="40" stroke="#0000ff"/>')
    ps = svg_points(svg(body), 20, width_m=80.0, min_spacing_m=1.0)
    cols = ps.hex_colors()
    assert cols.count("#ff0000") == 15 and cols.count("#0000ff") == 5
    # A group rotation turns a horizontal line vertical (zero width: the height becomes width_m).
    vert = svg_points(svg('<g transform="rotate(90 50 50)"><path d="M 0 50 L 100 50" stroke="red"/></g>'),
                      8, width_m=40.0, center_m=(0, 0, 40), min_spacing_m=1.0).points_m
    assert np.allclose(vert[:, 0], 0.0, atol=1e-9)
    assert np.ptp(vert[:, 2]) == pytest.approx(40.0 * 7 / 8)


def test_svg_deterministic():
    data = svg('<path d="M 10 10 Q 50 90 90 10" stroke="white"/>')
    assert np.array_equal(svg_points(data, 15).points_m, svg_points(data, 15).points_m)


BILLION_LAUGHS = b"""<?xml version="1.0"?>
<!DOCTYPE lolz [
 <!ENTITY lol "lol">
 <!ENTITY lol2 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
]>
<svg xmlns="http://www.w3.org/2000/svg"><text>&lol3;</text><path d="M0 0 L 10 10"/></svg>"""

XXE = b"""<?xml version="1.0"?>
<!DOCTYPE svg [<!ENTITY xxe SYSTEM "file:///etc/passwd">]>
<svg xmlns="http://www.w3.org/2000/svg"><text>&xxe;</text><path d="M0 0 L 10 10"/></svg>"""

EXTERNAL_DTD = b"""<?xml version="1.0"?>
<!DOCTYPE svg PUBLIC "-//W3C//DTD SVG 1.1//EN" "http://www.w3.org/Graphics/SVG/1.1/DTD/svg11.dtd">
<svg xmlns="http://www.w3.org/2000/svg"><path d="M0 0 L 10 10"/></svg>"""


@pytest.mark.parametrize("data", [BILLION_LAUGHS, XXE, EXTERNAL_DTD], ids=["billion-laughs", "xxe", "dtd"])
def test_svg_doctype_and_entities_refused_before_parsing(data, monkeypatch):
    def parse_must_not_run(*args, **kwargs):
        raise AssertionError("svgelements was reached")

    monkeypatch.setattr(svgelements.SVG, "parse", parse_must_not_run)
    with pytest.raises(FormationError, match="DOCTYPE"):
        svg_points(data, 5)


def test_svg_rejections():
    with pytest.raises(InputTooLargeError, match="bytes"):
        svg_points(svg("<!--" + " " * MAX_SVG_BYTES + "-->"), 5)
    with pytest.raises(FormationError, match="well-formed"):
        svg_points(b"\xff\xfe\x00garbage", 5)
    with pytest.raises(FormationError, match="not an SVG"):
        svg_points(b"<html><body/></html>", 5)
    with pytest.raises(FormationError, match="no paths"):
        svg_points(svg("<text>only text</text>"), 5)
    with pytest.raises(FormationError, match="#rrggbb"):
        svg_points(svg('<path d="M0 0 L 10 10"/>'), 5, color="blue")
    with pytest.raises(FormationError) as info:
        svg_points(svg('<path d="M0 0 L 100 0"/>'), 100, width_m=30.0, min_spacing_m=3.0)
    assert info.value.max_n == 10  # 30 m line, points at (j + 1/2) * 30 / k m: k <= 10


def test_svg_crossing_paths_are_repaired_and_max_n_is_tight():
    # Two diagonals crossing at the centre: the points next to the crossing are spread apart.
    data = b'<svg xmlns="http://www.w3.org/2000/svg"><path d="M0 0 L100 100 M0 100 L 100 0" stroke="red"/></svg>'
    ps = svg_points(data, 60, width_m=100.0, min_spacing_m=3.0)
    assert len(ps) == 60 and min_dist(ps.points_m) >= 3.0
    # Still on the two diagonals (|x| = |z - 30| up to the repair's shift of at most one spacing).
    off = np.abs(np.abs(ps.points_m[:, 0]) - np.abs(ps.points_m[:, 2] - 30.0)) / math.sqrt(2)
    assert off.max() <= 3.0
    with pytest.raises(FormationError) as info:
        svg_points(data, 500, width_m=100.0, min_spacing_m=3.0)
    max_n = info.value.max_n
    # Two 141.4 m diagonals at 3 m hold about 2 * 141.4 / 3 = 94 points.
    assert 85 <= max_n <= 95
    assert len(svg_points(data, max_n, width_m=100.0, min_spacing_m=3.0)) == max_n
    with pytest.raises(FormationError):
        svg_points(data, max_n + 1, width_m=100.0, min_spacing_m=3.0)


def test_svg_too_many_coordinates_refused_before_parsing(monkeypatch):
    from formations.sources import MAX_SVG_NUMBERS

    def parse_must_not_run(*args, **kwargs):
        raise AssertionError("svgelements was reached")

    monkeypatch.setattr(svgelements.SVG, "parse", parse_must_not_run)
    d = "M 0 0 " + "L 1 2 " * (MAX_SVG_NUMBERS // 2 + 1)
    with pytest.raises(InputTooLargeError, match="coordinates"):
        svg_points(svg(f'<path d="{d}"/>'), 5)
