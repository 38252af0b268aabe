"""Rigid and scaling transforms of point sets, and placing 2-D drawings in 3-D (metres, radians)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from formations._points import FormationError, as_points, check_center, check_plane

_AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


def _about(pts: np.ndarray, about: ArrayLike | None) -> np.ndarray:
    if about is None:
        return pts.mean(axis=0) if len(pts) else np.zeros(3)
    return check_center(about, name="about")


def scale(points: ArrayLike, factor: float | ArrayLike, *, about: ArrayLike | None = None) -> np.ndarray:
    """Scale (N, 3) points by ``factor`` (scalar or per-axis (3,)) about ``about``.

    Args:
        points: (N, 3) metres.
        factor: scale factor, scalar or (3,) per axis; finite.
        about: fixed point in metres; None = the centroid.

    Returns:
        (N, 3) float64 metres.
    """
    pts = as_points(points)
    f = np.asarray(factor, dtype=np.float64)
    if f.shape not in ((), (3,)) or not np.all(np.isfinite(f)):
        raise FormationError(f"factor must be a finite number or three numbers, got {factor!r}")
    c = _about(pts, about)
    out: np.ndarray = (pts - c) * f + c
    return out


def rotation_matrix(angle_rad: float, axis: str | ArrayLike = "z") -> np.ndarray:
    """3x3 right-handed rotation by ``angle_rad`` about ``axis`` ("x", "y", "z" or a 3-vector)."""
    if isinstance(axis, str):
        if axis not in _AXES:
            raise FormationError(f"axis must be 'x', 'y', 'z' or a 3-vector, got {axis!r}")
        k = np.array(_AXES[axis])
    else:
        k = np.asarray(axis, dtype=np.float64)
        norm = float(np.linalg.norm(k)) if k.shape == (3,) else 0.0
        if not np.isfinite(norm) or norm == 0.0:
            raise FormationError(f"axis must be a non-zero finite 3-vector, got {axis!r}")
        k = k / norm
    a = float(angle_rad)
    if not np.isfinite(a):
        raise FormationError(f"angle_rad must be finite, got {angle_rad!r}")
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    out: np.ndarray = np.eye(3) + np.sin(a) * kx + (1.0 - np.cos(a)) * (kx @ kx)
    return out


def rotate(
    points: ArrayLike,
    angle_rad: float,
    *,
    axis: str | ArrayLike = "z",
    about: ArrayLike | None = None,
) -> np.ndarray:
    """Rotate (N, 3) points by ``angle_rad`` (right-handed) about an axis through ``about``.

    Args:
        points: (N, 3) metres.
        angle_rad: rotation angle, radians.
        axis: "x", "y", "z" or a 3-vector direction.
        about: a point on the axis, metres; None = the centroid.

    Returns:
        (N, 3) float64 metres.
    """
    pts = as_points(points)
    r = rotation_matrix(angle_rad, axis)
    c = _about(pts, about)
    out: np.ndarray = (pts - c) @ r.T + c
    return out


def translate(points: ArrayLike, offset: ArrayLike) -> np.ndarray:
    """Shift (N, 3) points by ``offset`` (3,) metres."""
    pts = as_points(points)
    out: np.ndarray = pts + check_center(offset, name="offset")
    return out


def place_on_plane(
    points_2d: ArrayLike, *, plane: str = "xz", center_m: ArrayLike = (0.0, 0.0, 0.0)
) -> np.ndarray:
    """Map (N, 2) plane coordinates (u right, v up) to (N, 3) world metres.

    "xz": u -> x (east), v -> z (up), the vertical plane facing an audience to the south;
    "xy": u -> x, v -> y (north), parallel to the ground; "yz": u -> y, v -> z.
    ``center_m`` is the world position of the plane origin (u, v) = (0, 0).
    """
    uv = as_points(points_2d, name="points_2d", dims=(2,))
    plane = check_plane(plane)
    c = check_center(center_m)
    out = np.tile(c, (len(uv), 1))
    cols = {"xz": (0, 2), "xy": (0, 1), "yz": (1, 2)}[plane]
    out[:, cols[0]] += uv[:, 0]
    out[:, cols[1]] += uv[:, 1]
    return out
