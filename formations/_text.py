"""Text sources: N points spread evenly over text rendered with FreeType (metres).

The font ships with an installed package (DejaVu Sans Bold from matplotlib, or a copy in
``formations/data``), so nothing is downloaded.
"""

from __future__ import annotations

import math
import re
from functools import lru_cache
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike
from PIL import Image, ImageDraw, ImageFont

from formations._image import MAX_CANDIDATE_PIXELS, mask_candidates, sample_mask
from formations._points import (
    FormationError,
    PointSet,
    check_center,
    check_n,
    check_plane,
    check_positive,
    parse_color,
)
from formations._spacing import ensure_spacing, no_fit_error, sample_candidates
from formations._transforms import place_on_plane

#: Font file used to render text (bold strokes are wide enough to read at drone spacing).
FONT_FILE = "DejaVuSans-Bold.ttf"
#: Longest text accepted, characters, and most lines.
MAX_TEXT_CHARS = 1000
MAX_TEXT_LINES = 50
#: Rendering resolution: pixels per minimum spacing, and the fewest pixels of ink height
#: (below that the glyph shapes themselves are lost).
_PX_PER_SPACING = 8.0
_MIN_INK_PX = 64
#: Font size (pixels) of the measuring pass that fixes the scale of the final rendering.
_REF_SIZE = 32
#: Line gap as a fraction of the font size.
_LINE_GAP = 0.25
#: Control characters other than the newline are refused.
_BAD_CHARS = re.compile(r"[\x00-\x09\x0b-\x1f\x7f]")


def font_path() -> Path:
    """Path of the TrueType font: ``formations/data/FONT_FILE`` if present, else matplotlib's copy."""
    local = Path(__file__).with_name("data") / FONT_FILE
    if local.is_file():
        return local
    import matplotlib

    path = Path(matplotlib.get_data_path()) / "fonts" / "ttf" / FONT_FILE
    if not path.is_file():  # pragma: no cover - matplotlib always ships DejaVu
        raise FormationError(f"font {FONT_FILE} not found (looked in formations/data and matplotlib)")
    return path


@lru_cache(maxsize=16)
def _font(size_px: int) -> ImageFont.FreeTypeFont:
    return ImageFont.truetype(str(font_path()), size_px)


def check_text(text: object) -> str:
    """Validate text: a non-empty string of at most MAX_TEXT_CHARS characters and
    MAX_TEXT_LINES lines; ``\\r\\n``/``\\r`` become ``\\n`` and tabs four spaces."""
    if not isinstance(text, str):
        raise FormationError(f"text must be a string, got {type(text).__name__}")
    t = text.replace("\r\n", "\n").replace("\r", "\n").replace("\t", "    ")
    if _BAD_CHARS.search(t):
        raise FormationError("text must not contain control characters other than newlines")
    if not t.strip():
        raise FormationError("text is empty", max_n=0)
    if len(t) > MAX_TEXT_CHARS:
        raise FormationError(f"text has {len(t)} characters; the limit is {MAX_TEXT_CHARS}")
    if t.count("\n") + 1 > MAX_TEXT_LINES:
        raise FormationError(f"text has {t.count(chr(10)) + 1} lines; the limit is {MAX_TEXT_LINES}")
    return t


def _render(text: str, size_px: int) -> np.ndarray:
    """Boolean ink mask of ``text`` at ``size_px`` (lines centred), cropped to the ink."""
    font = _font(size_px)
    gap = max(1, round(_LINE_GAP * size_px))
    probe = ImageDraw.Draw(Image.new("L", (1, 1)))
    left, top, right, bottom = probe.multiline_textbbox((0, 0), text, font=font, spacing=gap, align="center")
    pad = 2
    w, h = int(math.ceil(right - left)) + 2 * pad, int(math.ceil(bottom - top)) + 2 * pad
    im = Image.new("L", (max(w, 1), max(h, 1)), 0)
    ImageDraw.Draw(im).multiline_text(
        (pad - left, pad - top), text, fill=255, font=font, spacing=gap, align="center"
    )
    mask = np.asarray(im) >= 128
    rows, cols = np.nonzero(mask.any(axis=1))[0], np.nonzero(mask.any(axis=0))[0]
    if rows.size == 0:
        return np.zeros((0, 0), dtype=bool)
    return mask[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]


def text_mask(text: str, *, height_m: float, min_spacing_m: float) -> tuple[np.ndarray, float]:
    """Render ``text`` to a boolean ink mask whose height stands for ``height_m``.

    The resolution gives about 8 pixels per minimum spacing (at least 64 pixels of ink
    height, at most MAX_CANDIDATE_PIXELS pixels in all).

    Returns:
        (mask (H, W) bool cropped to the ink, pixel size in metres).

    Raises:
        FormationError: the text has no visible glyphs.
    """
    ref = _render(text, _REF_SIZE)
    if ref.size == 0 or not ref.any():
        raise FormationError("the text has no visible glyphs", max_n=0)
    ink_h, ink_w = ref.shape
    want_px = max(_MIN_INK_PX, _PX_PER_SPACING * height_m / min_spacing_m)
    f = want_px / ink_h
    # Bound the work (and memory) for long text or tiny spacings.
    f = min(f, math.sqrt(MAX_CANDIDATE_PIXELS / (ink_h * ink_w)))
    size_px = max(4, round(_REF_SIZE * f))
    mask = _render(text, size_px)
    return mask, height_m / mask.shape[0]


def text_points(
    text: str,
    n: int,
    *,
    height_m: float = 10.0,
    center_m: ArrayLike = (0.0, 0.0, 30.0),
    plane: str = "xz",
    min_spacing_m: float = 3.0,
    color: str = "#ffffff",
) -> PointSet:
    """Spread ``n`` points evenly over ``text`` rendered in DejaVu Sans Bold.

    Points are picked among the glyph pixels by farthest-point sampling, which follows thin
    strokes evenly; if that cannot keep the spacing, a hexagonal lattice over the glyphs is
    tried (denser on thick strokes). Characters the font lacks render as its box glyph.
    Lines are centred; the ink's bounding box is ``height_m`` tall, centred on ``center_m``
    and drawn in ``plane``.

    Args:
        text: the text; ``\\n`` starts a new line (at most 1000 characters, 50 lines).
        n: number of points, 1..20000.
        height_m: height of the whole text block's ink, metres.
        center_m: centre of the text block, metres (x, y, z).
        plane: "xz" (vertical, facing the audience), "xy" (ground-parallel) or "yz".
        min_spacing_m: minimum distance between any two points, metres.
        color: LED colour "#rrggbb".

    Returns:
        PointSet of exactly ``n`` points.

    Raises:
        FormationError: bad argument, no visible glyphs, or ``n`` points do not fit
            (``max_n`` is the largest count that does).
    """
    t = check_text(text)
    n = check_n(n)
    height = check_positive(height_m, name="height_m")
    center = check_center(center_m)
    plane = check_plane(plane)
    s = check_positive(min_spacing_m, name="min_spacing_m")
    rgb_one = parse_color(color)
    mask, px_m = text_mask(t, height_m=height, min_spacing_m=s)
    what = f"the text at height {height:g} m"
    uv_all, _, _ = mask_candidates(mask, px_m)
    try:
        idx = np.sort(sample_candidates(uv_all, n, s, what=what))
    except FormationError as fps_error:
        rgb = np.broadcast_to(rgb_one, (*mask.shape, 3))
        try:
            return sample_mask(mask, rgb, n, px_m=px_m, center_m=center, plane=plane, min_spacing_m=s, what=what)
        except FormationError as lattice_error:
            best = max(fps_error.max_n or 0, lattice_error.max_n or 0)
            raise no_fit_error(what, n, s, best) from None
    pts = ensure_spacing(place_on_plane(uv_all[idx], plane=plane, center_m=center), s)
    if pts is None:  # pragma: no cover - sample_candidates keeps the spacing
        raise FormationError(f"{n} points do not fit {what}")
    return PointSet(pts, np.tile(rgb_one, (n, 1)))
