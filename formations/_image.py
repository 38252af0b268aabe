"""Image sources: points spread over the bright (or opaque) pixels of a PNG/JPEG (metres)."""

from __future__ import annotations

import io
import math
import warnings

import numpy as np
from numpy.typing import ArrayLike
from PIL import Image, ImageOps, UnidentifiedImageError

from formations._points import (
    FormationError,
    InputTooLargeError,
    PointSet,
    check_center,
    check_n,
    check_plane,
    check_positive,
)
from formations._spacing import (
    ensure_spacing,
    farthest_point_order,
    no_fit_error,
    sample_candidates,
)
from formations._transforms import place_on_plane

#: Largest image accepted, pixels (checked from the header before decoding).
MAX_IMAGE_PIXELS = 40_000_000
#: Largest upload accepted, bytes.
MAX_IMAGE_BYTES = 50 * 1024 * 1024
#: Image formats accepted.
IMAGE_FORMATS: tuple[str, ...] = ("PNG", "JPEG")
#: Pixel modes of image_points.
IMAGE_MODES: tuple[str, ...] = ("auto", "bright", "alpha")
#: Most candidate pixels sampled (the image is reduced above this).
MAX_CANDIDATE_PIXELS = 250_000
#: The working resolution keeps between these many pixels per minimum spacing.
_MIN_PX_PER_SPACING = 4.0
_MAX_PX_PER_SPACING = 12.0
#: A pixel is "bright" if its largest channel reaches this, "opaque" if its alpha does.
THRESHOLD = 128

# Pillow refuses (DecompressionBombError) images over twice this at open time.
if Image.MAX_IMAGE_PIXELS is None or Image.MAX_IMAGE_PIXELS > MAX_IMAGE_PIXELS:
    Image.MAX_IMAGE_PIXELS = MAX_IMAGE_PIXELS


def working_size(width: int, height: int, *, width_m: float, min_spacing_m: float) -> tuple[int, int]:
    """Resolution (w, h) the image is sampled at: 4-12 pixels per minimum spacing, at most
    MAX_CANDIDATE_PIXELS pixels; the original size when it is already in that range."""
    lo = math.ceil(_MIN_PX_PER_SPACING * width_m / min_spacing_m)
    hi = math.floor(_MAX_PX_PER_SPACING * width_m / min_spacing_m)
    cap = math.floor(math.sqrt(MAX_CANDIDATE_PIXELS * width / height))
    w = width
    if w < lo:
        w = lo
    elif w > hi:
        w = max(hi, 1)
    w = max(1, min(w, cap))
    if w == width:
        return width, height
    return w, max(1, round(height * w / width))


def mask_candidates(
    mask: np.ndarray, px_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixel centres of a (H, W) boolean mask as plane coordinates in metres.

    The image is centred on (0, 0); u grows to the right, v upwards (image rows go down).

    Returns:
        (uv (M, 2) metres, rows (M,), cols (M,)).
    """
    h, w = mask.shape
    rows, cols = np.nonzero(mask)
    u = (cols + 0.5 - w / 2.0) * px_m
    v = (h / 2.0 - rows - 0.5) * px_m
    return np.column_stack([u, v]), rows, cols


#: Most lattice points evaluated per spacing trial (bounds memory for tiny spacings).
_MAX_LATTICE = 400_000


def _lattice_in_mask(mask: np.ndarray, px_m: float, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Points of a hexagonal lattice of spacing ``h`` metres (anchored at the image centre)
    that fall on true pixels of ``mask``. Returns (uv (K, 2) metres, flat pixel indices (K,))."""
    rows_px, cols_px = mask.shape
    half_u, half_v = cols_px * px_m / 2.0, rows_px * px_m / 2.0
    dv = h * math.sqrt(3.0) / 2.0
    nj, ni = math.floor(half_v / dv), math.floor(half_u / h) + 1
    j = np.arange(-nj, nj + 1, dtype=np.float64)
    i = np.arange(-ni, ni + 1, dtype=np.float64)
    jj, ii = np.meshgrid(j, i, indexing="ij")
    u = (ii + 0.5 * (np.abs(jj) % 2)) * h
    v = jj * dv
    u, v = u.ravel(), v.ravel()
    col = np.floor(u / px_m + cols_px / 2.0).astype(np.int64)
    row = np.floor(rows_px / 2.0 - v / px_m).astype(np.int64)
    inside = (col >= 0) & (col < cols_px) & (row >= 0) & (row < rows_px)
    col, row, u, v = col[inside], row[inside], u[inside], v[inside]
    on = mask[row, col]
    return np.column_stack([u[on], v[on]]), (row * cols_px + col)[on]


def _lattice_size(mask: np.ndarray, px_m: float, h: float) -> float:
    rows_px, cols_px = mask.shape
    out: float = (cols_px * px_m / h + 3) * (rows_px * px_m / (h * math.sqrt(3.0) / 2.0) + 3)
    return out


def _lattice_pick(
    mask: np.ndarray, px_m: float, n: int, min_spacing_m: float
) -> tuple[tuple[np.ndarray, np.ndarray] | None, int]:
    """Hexagonal-lattice sampling: the largest lattice spacing >= the minimum (bisection)
    whose lattice puts >= n points on the mask, trimmed to n by farthest-point order.

    Returns (picked (uv, flat pixel indices) or None, how many points the lattice at the
    smallest tried spacing holds)."""
    h0 = min_spacing_m
    if _lattice_size(mask, px_m, h0) > _MAX_LATTICE:
        h0 *= math.sqrt(_lattice_size(mask, px_m, h0) / _MAX_LATTICE)
    uv, flat = _lattice_in_mask(mask, px_m, h0)
    capacity = len(uv)
    if capacity < n or n < 2:
        return None, capacity
    lo, hi = h0, max(mask.shape) * px_m * 2.0 + h0
    for _ in range(40):
        if hi - lo <= 1e-7 * lo:
            break
        mid = 0.5 * (lo + hi)
        cand = _lattice_in_mask(mask, px_m, mid)
        if len(cand[0]) >= n:
            lo, uv, flat = mid, cand[0], cand[1]
        else:
            hi = mid
    idx = np.sort(farthest_point_order(uv, n)[0])
    return (uv[idx], flat[idx]), capacity


def sample_mask(
    mask: np.ndarray,
    rgb: np.ndarray,
    n: int,
    *,
    px_m: float,
    center_m: np.ndarray,
    plane: str,
    min_spacing_m: float,
    what: str,
) -> PointSet:
    """Spread ``n`` points over the true pixels of ``mask`` (pixel size ``px_m`` metres,
    image centred on ``center_m``) and colour them from ``rgb`` (H, W, 3).

    Preferred: the densest hexagonal lattice (spacing >= the minimum, found by bisection)
    that still holds n points on the mask, trimmed by farthest-point order. Fallback (thin
    features): farthest-point sampling over the pixel centres. Both give even spacing.
    """
    picked, capacity = _lattice_pick(mask, px_m, n, min_spacing_m)
    if picked is not None:
        uv, flat = picked
        colors = rgb.reshape(-1, 3)[flat]
    else:
        uv_all, rows, cols = mask_candidates(mask, px_m)
        try:
            idx = sample_candidates(uv_all, n, min_spacing_m, what=what)
        except FormationError as exc:
            if exc.max_n is not None and capacity > exc.max_n:
                raise no_fit_error(what, n, min_spacing_m, capacity) from None
            raise
        uv, colors = uv_all[idx], rgb[rows[idx], cols[idx]]
    pts = ensure_spacing(place_on_plane(uv, plane=plane, center_m=center_m), min_spacing_m)
    if pts is None:  # pragma: no cover - both samplers keep the spacing
        raise FormationError(f"{n} points do not fit {what}")
    return PointSet(pts, colors)


def decode_image(data: bytes, *, target: tuple[float, float] | None = None) -> Image.Image:
    """Decode PNG/JPEG bytes safely to an RGBA image (EXIF orientation applied).

    Args:
        data: the file's bytes.
        target: optional (width_m, min_spacing_m) so that large JPEGs decode reduced.

    Raises:
        InputTooLargeError: more than MAX_IMAGE_BYTES bytes or MAX_IMAGE_PIXELS pixels
            (checked from the header, before decoding).
        FormationError: not a decodable PNG or JPEG.
    """
    if not isinstance(data, bytes | bytearray | memoryview):
        raise FormationError("image data must be bytes")
    if len(data) > MAX_IMAGE_BYTES:
        raise InputTooLargeError(
            f"image is {len(data)} bytes; the limit is {MAX_IMAGE_BYTES} bytes"
        )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            im = Image.open(io.BytesIO(bytes(data)), formats=list(IMAGE_FORMATS))
            w, h = im.size
            if w * h > MAX_IMAGE_PIXELS:
                raise InputTooLargeError(
                    f"image is {w}x{h} = {w * h} pixels; the limit is {MAX_IMAGE_PIXELS} pixels"
                )
            if w < 1 or h < 1:
                raise FormationError(f"image has no pixels ({w}x{h})")
            if target is not None and im.format == "JPEG":
                tw, th = working_size(w, h, width_m=target[0], min_spacing_m=target[1])
                im.draft("RGB", (tw, th))
            im.load()
            upright = ImageOps.exif_transpose(im) or im
            return upright.convert("RGBA")
    except Image.DecompressionBombError as exc:
        raise InputTooLargeError(f"image is too large: {exc}") from None
    except UnidentifiedImageError:
        raise FormationError("could not decode the image: not a PNG or JPEG file") from None
    except (OSError, SyntaxError, ValueError, EOFError, IndexError, TypeError) as exc:
        if isinstance(exc, FormationError):
            raise
        raise FormationError(f"could not decode the image: {exc}") from None


def image_mask(rgba: np.ndarray, mode: str) -> np.ndarray:
    """Boolean mask of the pixels to fill: "bright" (largest channel >= 128, opaque),
    "alpha" (alpha >= 128) or "auto" (alpha if any pixel is transparent, else bright)."""
    alpha = rgba[..., 3] >= THRESHOLD
    if mode == "auto":
        mode = "alpha" if not alpha.all() else "bright"
    if mode == "alpha":
        return alpha
    out: np.ndarray = alpha & (rgba[..., :3].max(axis=2) >= THRESHOLD)
    return out


def image_candidates(
    data: bytes, *, width_m: float, min_spacing_m: float, mode: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Decode, resample to the working size and mask an image.

    Returns:
        (mask (H, W) bool, rgb (H, W, 3) uint8, rgba (H, W, 4) uint8, pixel size in metres).
    """
    im = decode_image(data, target=(width_m, min_spacing_m))
    w, h = im.size
    tw, th = working_size(w, h, width_m=width_m, min_spacing_m=min_spacing_m)
    if (tw, th) != (w, h):
        resample = Image.Resampling.BOX if tw < w else Image.Resampling.NEAREST
        im = im.resize((tw, th), resample=resample)
    rgba = np.asarray(im, dtype=np.uint8)
    return image_mask(rgba, mode), rgba[..., :3], rgba, width_m / tw


def image_points(
    data: bytes,
    n: int,
    *,
    width_m: float = 40.0,
    center_m: ArrayLike = (0.0, 0.0, 30.0),
    plane: str = "xz",
    min_spacing_m: float = 3.0,
    mode: str = "auto",
) -> PointSet:
    """Spread ``n`` points evenly over the bright (or opaque) pixels of a PNG/JPEG image.

    Points are picked among the pixel centres by farthest-point sampling (even, not
    random clumps) and take their pixel's colour. The image is ``width_m`` wide, its centre
    at ``center_m``, drawn in ``plane``.

    Args:
        data: PNG or JPEG file bytes (at most 40 megapixels).
        n: number of points, 1..20000.
        width_m: width of the whole image, metres.
        center_m: centre of the image, metres (x, y, z).
        plane: "xz" (vertical, facing the audience), "xy" (ground-parallel) or "yz".
        min_spacing_m: minimum distance between any two points, metres.
        mode: "auto" (opaque pixels if the image has transparency, else bright pixels),
            "bright" (largest channel >= 128) or "alpha" (alpha >= 128).

    Raises:
        InputTooLargeError: the image is over the size limits.
        FormationError: bad argument, undecodable data, no bright/opaque pixels, or ``n``
            points do not fit (``max_n`` is the largest count that does).
    """
    n = check_n(n)
    width = check_positive(width_m, name="width_m")
    center = check_center(center_m)
    plane = check_plane(plane)
    s = check_positive(min_spacing_m, name="min_spacing_m")
    if mode not in IMAGE_MODES:
        raise FormationError(f"mode must be one of {', '.join(IMAGE_MODES)}, got {mode!r}")
    mask, rgb, _, px_m = image_candidates(data, width_m=width, min_spacing_m=s, mode=mode)
    if not mask.any():
        kind = "opaque" if mode == "alpha" else "bright or opaque"
        raise FormationError(f"the image has no {kind} pixels to place points on", max_n=0)
    return sample_mask(
        mask, rgb, n, px_m=px_m, center_m=center, plane=plane, min_spacing_m=s,
        what=f"the image at width {width:g} m",
    )
