"""``qgc-plan`` and ``qgc-wpl``: one QGroundControl mission per drone, in a zip.

Each drone's mission, in WGS84 coordinates from ``--origin LAT,LON,ALT`` and
``--heading DEG`` (exact conversion, see :mod:`app.exports._geodesy`):

1. ``MAV_CMD_NAV_TAKEOFF`` (22) straight up to the takeoff altitude above its home;
2. ``MAV_CMD_NAV_WAYPOINT`` (16) at the end of every transition, i.e. at each
   formation position, with param1 = hold time at the formation (seconds; 0 for
   the approach to the landing grid);
3. ``MAV_CMD_NAV_LAND`` (21) at its landing position.

All items use ``MAV_FRAME_GLOBAL`` (0): altitudes are absolute, ``ALT`` plus
the ellipsoidal height above the origin. The waypoints fix where and how long
each drone holds; a waypoint mission does not reproduce the plan's
synchronised timing, which needs a show-capable autopilot (use ``skyc``).

``.plan`` (QGroundControl's JSON plan, ``fileType: "Plan"``, ``version: 1``):
``mission`` (``version`` 2) with ``SimpleItem`` items carrying ``params[7]``
(yaw ``null`` = unchanged, as QGroundControl writes NaN), ``plannedHomePosition``
[lat, lon, alt], ``firmwareType`` 3 (ArduPilot), ``vehicleType`` 2
(quadrotor), ``cruiseSpeed`` / ``hoverSpeed`` (the show's horizontal speed
limit); ``geoFence`` (version 2) with one inclusion polygon around the show's
footprint plus a margin; ``rallyPoints`` (version 2, none).

``.waypoints`` (``QGC WPL 110`` text, read by QGroundControl, Mission Planner
and pymavlink's ``MAVWPLoader``): line 0 is the home position, then the items
above; tab-separated ``index current frame command p1 p2 p3 p4 lat lon alt
autocontinue``.
"""

from __future__ import annotations

import json

import numpy as np

from app.exports._archive import ZipBuilder, base_manifest, safe_stem
from app.exports._core import ExportContext, ExportError, ExportResult, require_planned
from app.exports._geodesy import local_to_geodetic

MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_LAND = 21
MAV_CMD_NAV_TAKEOFF = 22
MAV_FRAME_GLOBAL = 0
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_TYPE_QUADROTOR = 2
#: Margin of the geofence polygon around the show's footprint, metres (at least).
FENCE_MARGIN_M = 10.0

_README = """\
QGroundControl missions (one per drone) made by swarmshow: {kind}.

Origin (x = y = z = 0): latitude {lat:.8f}, longitude {lon:.8f}, altitude {alt:.3f} m;
the show's +y axis points at bearing {heading:.3f} degrees (clockwise from true north).
Local coordinates are converted to WGS84 exactly (ENU -> ECEF -> geodetic);
altitudes are absolute (MAV_FRAME_GLOBAL): the origin altitude plus the height
above it.

Each mission: NAV_TAKEOFF to the takeoff altitude, NAV_WAYPOINT at each
formation position with param1 = hold time (s), NAV_LAND at the landing position.
A waypoint mission fixes positions and hold times but not the synchronised
timing of the plan: fly real shows with a show-capable autopilot (.skyc).
"""


def _origin(ctx: ExportContext) -> tuple[float, float, float]:
    if ctx.options.origin is None:
        raise ExportError(
            f"format {ctx.fmt!r} needs the show's place on Earth: set its origin (latitude, longitude, "
            "altitude) and heading in the show settings"
        )
    return ctx.options.origin


def mission_waypoints(plan) -> tuple[list[int], list[float]]:
    """Knot indices of each drone's mission items and their hold times.

    Returns:
        ``knots``: [home, takeoff end, each transition end..., landing end]
        and ``holds`` (seconds) for each transition end.
    """
    segs = plan.segments
    knots = [0]
    holds: list[float] = []
    for seg in segs:
        if seg.kind == "takeoff":
            knots.append(seg.index + 1)
        elif seg.kind == "transition":
            knots.append(seg.index + 1)
            nxt = segs[seg.index + 1] if seg.index + 1 < len(segs) else None
            holds.append(float(nxt.duration_s) if nxt is not None and nxt.kind == "hold" else 0.0)
    knots.append(len(segs))
    return knots, holds


def _geodetic_items(ctx: ExportContext):
    plan = ctx.plan
    origin = _origin(ctx)
    knots, holds = mission_waypoints(plan)
    pts = plan.knot_positions_m[knots]  # (W, N, 3)
    lat, lon, alt = local_to_geodetic(pts, origin=origin, heading_deg=ctx.options.heading_deg)
    commands = [MAV_CMD_NAV_TAKEOFF] + [MAV_CMD_NAV_WAYPOINT] * len(holds) + [MAV_CMD_NAV_LAND]
    p1 = [0.0, *holds, 0.0]
    return origin, lat, lon, alt, commands, p1


def _fence(ctx: ExportContext, origin) -> list[list[float]]:
    """Inclusion polygon (lat, lon) around the horizontal footprint of every knot, plus a margin."""
    xy = ctx.plan.knot_positions_m[..., :2].reshape(-1, 2)
    margin = max(FENCE_MARGIN_M, 2.0 * ctx.show.settings.min_distance_m)
    (x0, y0), (x1, y1) = xy.min(axis=0) - margin, xy.max(axis=0) + margin
    corners = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
    lat, lon, _ = local_to_geodetic(corners, origin=origin, heading_deg=ctx.options.heading_deg)
    return [[round(float(a), 10), round(float(b), 10)] for a, b in zip(lat, lon, strict=True)]


def export_qgc_plan(ctx: ExportContext) -> ExportResult:
    """Build the zip of QGroundControl ``.plan`` files (see the module docstring)."""
    require_planned(ctx)
    origin, lat, lon, alt, commands, p1 = _geodetic_items(ctx)
    fence = {"version": 2, "circles": [], "polygons": [{"inclusion": True, "polygon": _fence(ctx, origin),
                                                         "version": 1}]}
    speed = ctx.show.settings.max_speed_xy_mps
    names = ctx.drone_names
    z = ZipBuilder()
    n = ctx.show.drones
    la, lo, al = np.round(lat, 10), np.round(lon, 10), np.round(alt, 4) + 0.0
    for i in range(n):
        items = [
            {
                "type": "SimpleItem",
                "autoContinue": True,
                "command": cmd,
                "doJumpId": j + 1,
                "frame": MAV_FRAME_GLOBAL,
                "params": [p1[j], 0, 0, None, float(la[j + 1, i]), float(lo[j + 1, i]), float(al[j + 1, i])],
            }
            for j, cmd in enumerate(commands)
        ]
        doc = {
            "fileType": "Plan",
            "version": 1,
            "groundStation": "QGroundControl",
            "mission": {
                "version": 2,
                "firmwareType": MAV_AUTOPILOT_ARDUPILOTMEGA,
                "vehicleType": MAV_TYPE_QUADROTOR,
                "cruiseSpeed": speed,
                "hoverSpeed": speed,
                "plannedHomePosition": [float(la[0, i]), float(lo[0, i]), float(al[0, i])],
                "items": items,
            },
            "geoFence": fence,
            "rallyPoints": {"version": 2, "points": []},
        }
        z.add(f"{names[i]}.plan", json.dumps(doc, indent=2, allow_nan=False) + "\n")
        if i % 256 == 255:
            ctx.progress(0.2 + 0.75 * (i + 1) / n)
    _finish(ctx, z, "qgc-plan", origin)
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}-qgc-plan.zip", media_type="application/zip", content=z.finish()
    )


def export_qgc_wpl(ctx: ExportContext) -> ExportResult:
    """Build the zip of ``QGC WPL 110`` waypoint files (see the module docstring)."""
    require_planned(ctx)
    origin, lat, lon, alt, commands, p1 = _geodetic_items(ctx)
    names = ctx.drone_names
    n = ctx.show.drones
    w = len(commands) + 1
    cmd = np.array([MAV_CMD_NAV_WAYPOINT, *commands])
    current = np.r_[1, np.zeros(w - 1, int)]
    param1 = np.array([0.0, *p1])
    row = "%d\t%d\t%d\t%d\t%.6f\t0\t0\t0\t%.10f\t%.10f\t%.4f\t1\n"
    z = ZipBuilder()
    for i in range(n):
        cols = [np.arange(w), current, np.full(w, MAV_FRAME_GLOBAL), cmd, param1, lat[:, i], lon[:, i], alt[:, i]]
        flat = [v for r in zip(*(c.tolist() for c in cols), strict=True) for v in r]
        z.add(f"{names[i]}.waypoints", "QGC WPL 110\n" + (row * w) % tuple(flat))
        if i % 256 == 255:
            ctx.progress(0.2 + 0.75 * (i + 1) / n)
    _finish(ctx, z, "qgc-wpl", origin)
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}-qgc-wpl.zip", media_type="application/zip", content=z.finish()
    )


def _finish(ctx: ExportContext, z: ZipBuilder, fmt: str, origin) -> None:
    kind = "QGroundControl .plan files" if fmt == "qgc-plan" else "QGC WPL 110 .waypoints files"
    z.add_manifest(
        base_manifest(
            ctx,
            fmt=fmt,
            origin={"latitude_deg": origin[0], "longitude_deg": origin[1], "altitude_m": origin[2]},
            heading_deg=ctx.options.heading_deg,
            geodesy="WGS84; local -> ENU (heading rotation) -> ECEF -> geodetic (Bowring, iterated)",
            frame="MAV_FRAME_GLOBAL (absolute altitude)",
        ),
        _README.format(kind=kind, lat=origin[0], lon=origin[1], alt=origin[2], heading=ctx.options.heading_deg),
    )
