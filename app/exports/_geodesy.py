"""Local show coordinates <-> WGS84 latitude / longitude / height, exactly.

Method: the show's local frame (x, y, z metres, +y at compass bearing
``heading_deg``) is rotated into east-north-up at the origin, ENU is mapped to
Earth-centred Earth-fixed (ECEF) coordinates by the rotation at the origin's
geodetic latitude and longitude, and ECEF is converted to geodetic latitude,
longitude and ellipsoidal height with Bowring's method refined by fixed-point
iteration on the parametric latitude (three iterations reach well below a
micrometre anywhere on Earth and up to 100 km altitude). No flat-Earth
approximation: a point 1 km from the origin at z = 0 lies ~8 cm below the
origin's height, as it does on the ellipsoid.

Heights are ellipsoidal offsets from the origin's altitude: give ``ALT`` in
the datum the autopilot expects (AMSL for ``MAV_FRAME_GLOBAL``) and the small
geoid slope across a show site (millimetres per kilometre) is the only thing
ignored.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

#: WGS84 semi-major axis, metres.
WGS84_A = 6378137.0
#: WGS84 flattening.
WGS84_F = 1.0 / 298.257223563
WGS84_B = WGS84_A * (1.0 - WGS84_F)
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
_EP2 = WGS84_E2 / (1.0 - WGS84_E2)


def geodetic_to_ecef(lat_deg: ArrayLike, lon_deg: ArrayLike, h_m: ArrayLike) -> np.ndarray:
    """WGS84 geodetic (degrees, degrees, metres) to ECEF (..., 3) metres."""
    lat = np.radians(np.asarray(lat_deg, dtype=np.float64))
    lon = np.radians(np.asarray(lon_deg, dtype=np.float64))
    h = np.asarray(h_m, dtype=np.float64)
    sl, cl = np.sin(lat), np.cos(lat)
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * sl * sl)
    return np.stack(
        [(n + h) * cl * np.cos(lon), (n + h) * cl * np.sin(lon), (n * (1.0 - WGS84_E2) + h) * sl], axis=-1
    )


def ecef_to_geodetic(ecef: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ECEF (..., 3) metres to WGS84 (latitude deg, longitude deg, ellipsoidal height m)."""
    e = np.asarray(ecef, dtype=np.float64)
    x, y, z = e[..., 0], e[..., 1], e[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    beta = np.arctan2(z * WGS84_A, p * WGS84_B)  # parametric latitude, first guess (Bowring)
    for _ in range(3):
        lat = np.arctan2(z + _EP2 * WGS84_B * np.sin(beta) ** 3, p - WGS84_E2 * WGS84_A * np.cos(beta) ** 3)
        beta = np.arctan2((1.0 - WGS84_F) * np.sin(lat), np.cos(lat))
    sl = np.sin(lat)
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * sl * sl)
    # p·cosφ + z·sinφ - a²/N is well conditioned at every latitude, poles included.
    h = p * np.cos(lat) + z * sl - WGS84_A * WGS84_A / n
    return np.degrees(lat), np.degrees(lon), h


def _enu_basis(lat_deg: float, lon_deg: float) -> np.ndarray:
    """(3, 3) rows: unit east, north, up at the origin, in ECEF."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    return np.array([[-so, co, 0.0], [-sl * co, -sl * so, cl], [cl * co, cl * so, sl]])


def _heading_rotation(heading_deg: float) -> np.ndarray:
    """(3, 3) matrix taking local (x, y, z) to (east, north, up) for +y at bearing ``heading_deg``."""
    th = np.radians(heading_deg)
    s, c = np.sin(th), np.cos(th)
    # +y -> (sin θ, cos θ): bearing θ; +x -> (cos θ, -sin θ): bearing θ + 90°, to the right of +y.
    return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def local_to_geodetic(
    points_m: ArrayLike, *, origin: tuple[float, float, float], heading_deg: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Local show coordinates (..., 3) metres to WGS84 (latitude deg, longitude deg, height m).

    Args:
        points_m: local x, y, z (z up); +y points at compass bearing ``heading_deg``.
        origin: (latitude deg, longitude deg, altitude m) of the local origin.
        heading_deg: bearing of +y, degrees clockwise from true north.
    """
    lat0, lon0, h0 = origin
    enu = np.asarray(points_m, dtype=np.float64) @ _heading_rotation(heading_deg).T
    ecef = geodetic_to_ecef(lat0, lon0, h0) + enu @ _enu_basis(lat0, lon0)
    return ecef_to_geodetic(ecef)


def geodetic_to_local(
    lat_deg: ArrayLike,
    lon_deg: ArrayLike,
    h_m: ArrayLike,
    *,
    origin: tuple[float, float, float],
    heading_deg: float = 0.0,
) -> np.ndarray:
    """Inverse of :func:`local_to_geodetic`: WGS84 to local (..., 3) metres."""
    lat0, lon0, h0 = origin
    d = geodetic_to_ecef(lat_deg, lon_deg, h_m) - geodetic_to_ecef(lat0, lon0, h0)
    enu = d @ _enu_basis(lat0, lon0).T
    return enu @ _heading_rotation(heading_deg)
