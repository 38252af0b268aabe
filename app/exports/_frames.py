"""The one convention for frames and headings across every export.

Inside swarmshow every position is **ENU-like local metres**: x, y horizontal, z up,
relative to the show's origin; the show's ``heading_deg`` (``settings.geo.heading_deg``
or ``--heading``) is the compass bearing of +y, degrees clockwise from true north
(heading 0: x east, y north, z up, i.e. ENU). Each export states its frame:

==================  ===============================================================
format              frame written
==================  ===============================================================
``show``            the show file itself (local x, y, z; heading in settings.geo)
``waypoints-csv``   local x, y, z unchanged (README says so)
``skybrush-csv``    local x, y, z unchanged = Skybrush X, Y, Z (manifest: frame)
``skyc``            local x, y, z unchanged = Skybrush X, Y, Z; Skybrush's frame is
                    X front, Y left, Z up with ``environment.location.orientation``
                    the bearing of +X, so orientation = heading + 90°
                    (:func:`skybrush_orientation_deg`)
``crazyswarm``      local x, y, z, then ``scale`` and ``offset`` (indoor flying);
                    the Crazyflie's world frame is whatever the mocap defines
``qgc-plan/-wpl``   WGS84 latitude / longitude / absolute altitude: local -> ENU
                    (rotation by the heading, :func:`local_to_enu`) -> geodetic
==================  ===============================================================
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

#: Wording every archive's manifest uses for the local frame.
LOCAL_FRAME = "local metres: x, y horizontal, z up, from the show origin; +y at bearing heading_deg (0: ENU)"


def skybrush_orientation_deg(heading_deg: float) -> float:
    """Skybrush's ``orientation`` (bearing of its +X, degrees in [0, 360)) for our heading (bearing of +y).

    Our +x is 90° clockwise of +y, and Skybrush's +Y (left of +X) is 90°
    counter-clockwise of +X: with X = x and Y = y both frames agree when
    bearing(X) = heading + 90°.
    """
    return float((heading_deg + 90.0) % 360.0)


def local_to_enu(points_m: ArrayLike, heading_deg: float) -> np.ndarray:
    """Local (..., 3) metres to east-north-up (..., 3) metres for +y at bearing ``heading_deg``."""
    th = np.radians(heading_deg)
    s, c = np.sin(th), np.cos(th)
    p = np.asarray(points_m, dtype=np.float64)
    # +y -> (sin θ, cos θ) (bearing θ); +x -> (cos θ, -sin θ) (bearing θ + 90°).
    east = c * p[..., 0] + s * p[..., 1]
    north = -s * p[..., 0] + c * p[..., 1]
    return np.stack([east, north, p[..., 2]], axis=-1)
