"""``qgc-plan`` and ``qgc-wpl``: one QGroundControl mission per drone, in a zip.

Each drone's mission, in WGS84 coordinates from the show's place on Earth
(``settings.geo`` or ``--origin LAT,LON[,ALT]`` and ``--heading DEG``; exact
conversion, see :mod:`app.exports._geodesy`):

1. ``MAV_CMD_NAV_TAKEOFF`` (22) straight up to the takeoff altitude above its home;
2. ``MAV_CMD_NAV_WAYPOINT`` (16) at the takeoff's top, param1 = hold (s);
3. per leg: ``MAV_CMD_DO_CHANGE_SPEED`` (178; param1 1 = ground speed, param2 the
   speed in m/s, param3 -1 = throttle unchanged) then ``MAV_CMD_NAV_WAYPOINT`` at
   the formation position with param1 = hold (whole seconds);
4. ``MAV_CMD_NAV_LAND`` (21) at its landing position.

Speeds and holds are timed so each drone keeps the plan's timing as well as a
waypoint mission can, against a kinematic replay of ArduCopter's waypoint
navigation at its default parameters (:mod:`app.exports._wpnav`); the replay also
looks for pairs closer than ``min_distance_m`` where the plan keeps them apart,
and the export names them (warnings, ``manifest.json`` ``replay``, README).

Navigation items use ``MAV_FRAME_GLOBAL`` (0): altitudes are absolute, ``ALT`` plus
the ellipsoidal height above the origin; ``DO_CHANGE_SPEED`` uses
``MAV_FRAME_MISSION`` (2).

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
from dataclasses import dataclass

import numpy as np

from app.exports._archive import ZipBuilder, base_manifest, safe_stem
from app.exports._core import ExportContext, ExportError, ExportResult, require_planned
from app.exports._geodesy import local_to_geodetic
from app.exports._wpnav import Mission, close_pairs, time_mission

MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_LAND = 21
MAV_CMD_NAV_TAKEOFF = 22
MAV_CMD_DO_CHANGE_SPEED = 178
MAV_FRAME_GLOBAL = 0
MAV_FRAME_MISSION = 2
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_TYPE_QUADROTOR = 2
#: Margin of the geofence polygon around the show's footprint, metres (at least).
FENCE_MARGIN_M = 10.0
#: Close pairs listed in the manifest (all are counted).
MAX_LISTED_PAIRS = 1000
#: Replayed lateness at a formation worth a warning, seconds.
LATE_WARN_S = 1.0

_README = """\
QGroundControl missions (one per drone) made by swarmshow: {kind}.

Origin (x = y = z = 0): latitude {lat:.8f}, longitude {lon:.8f}, altitude {alt:.3f} m;
the show's +y axis points at bearing {heading:.3f} degrees (clockwise from true north).
Local coordinates are converted to WGS84 exactly (local -> ENU -> ECEF -> geodetic);
altitudes are absolute (MAV_FRAME_GLOBAL): the origin altitude plus the height
above it.

Each mission: NAV_TAKEOFF to the takeoff altitude; a NAV_WAYPOINT there (hold);
per formation DO_CHANGE_SPEED (ground speed for the leg) and a NAV_WAYPOINT with
param1 = hold time (whole seconds: ArduPilot truncates the hold to whole seconds,
so the holds are the nearest whole second to the plan's departure and the next
leg's speed absorbs the rest); NAV_LAND at the landing position.

Timing: speeds and holds are chosen against a replay at ArduCopter's default
waypoint parameters (WPNAV_SPEED 1000, WPNAV_SPEED_UP 250, WPNAV_SPEED_DN 150,
WPNAV_ACCEL 250, WPNAV_ACCEL_Z 100, WPNAV_JERK 1): keep those parameters. Start
every drone's mission at the same instant. In the replay each drone reaches each
formation at most {late:.2f} s after the plan (and at most {early:.2f} s early,
waiting out the difference); a real flight adds GPS and wind error.

{safety}
"""


def _origin(ctx: ExportContext) -> tuple[float, float, float]:
    if ctx.options.origin is None:
        raise ExportError(
            f"format {ctx.fmt!r} needs the show's place on Earth: set its origin (latitude, longitude, "
            "altitude) and heading in the show settings",
            field="origin",
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


def timed_mission(ctx: ExportContext) -> Mission:
    """Every drone's mission timed against ArduCopter's WPNAV defaults (:mod:`app.exports._wpnav`)."""
    plan = ctx.plan
    legs = [s for s in plan.segments if s.kind in ("takeoff", "transition", "landing")]
    knots = [0] + [s.index + 1 for s in legs]
    return time_mission(
        plan.knot_positions_m[knots],
        np.array([s.start_s for s in legs]),
        np.array([s.end_s for s in legs]),
        ctx.show.settings.max_speed_xy_mps,
    )


@dataclass
class Items:
    """Mission items after home, the same commands for every drone (I items, N drones)."""

    command: np.ndarray  # (I,)
    frame: np.ndarray  # (I,)
    params: np.ndarray  # (I, N, 4): param1-4
    lat: np.ndarray  # (I, N) degrees (0 for DO commands)
    lon: np.ndarray
    alt: np.ndarray  # metres
    home: tuple[np.ndarray, np.ndarray, np.ndarray]  # (N,) each


def _geodetic_items(ctx: ExportContext, mission: Mission) -> tuple[tuple[float, float, float], Items]:
    """NAV_TAKEOFF, a waypoint at its top (hold), then per leg DO_CHANGE_SPEED + NAV_WAYPOINT (hold), NAV_LAND."""
    origin = _origin(ctx)
    pts = mission.points_m  # (W+1, N, 3): home, takeoff top, formations..., landing approach, landing
    lat, lon, alt = local_to_geodetic(pts, origin=origin, heading_deg=ctx.options.heading_deg)
    w, n = pts.shape[0] - 1, pts.shape[1]
    command, frame, params, la, lo, al = [], [], [], [], [], []
    zeros = np.zeros(n)

    def nav(cmd: int, k: int, hold: np.ndarray) -> None:
        command.append(cmd)
        frame.append(MAV_FRAME_GLOBAL)
        params.append(np.stack([hold, zeros, zeros, zeros], axis=1))
        la.append(lat[k])
        lo.append(lon[k])
        al.append(alt[k])

    nav(MAV_CMD_NAV_TAKEOFF, 1, zeros)
    nav(MAV_CMD_NAV_WAYPOINT, 1, mission.holds_s[0])
    for k in range(1, w - 1):
        command.append(MAV_CMD_DO_CHANGE_SPEED)
        frame.append(MAV_FRAME_MISSION)
        # param1 1: ground speed; param2 the speed (m/s); param3 -1: throttle unchanged.
        params.append(np.stack([np.ones(n), np.round(mission.speeds_mps[k], 4), -np.ones(n), zeros], axis=1))
        la.append(zeros)
        lo.append(zeros)
        al.append(zeros)
        nav(MAV_CMD_NAV_WAYPOINT, k + 1, mission.holds_s[k])
    nav(MAV_CMD_NAV_LAND, w, zeros)
    items = Items(np.array(command), np.array(frame), np.stack(params), np.stack(la), np.stack(lo), np.stack(al),
                  (lat[0], lon[0], alt[0]))
    return origin, items


def replay_report(ctx: ExportContext, mission: Mission) -> dict:
    """Replay the missions; warn (naming pairs) where they lose min_distance_m or the plan's timing."""
    s = ctx.show.settings
    names = ctx.drone_names
    pairs, dt = close_pairs(mission, ctx.plan, s.min_distance_m)
    late = mission.arrive_s - mission.plan_arrive_s[:, None]
    # Formations only: the takeoff and the landing are flown at fixed vertical speeds.
    worst = float(late[1:-1].max(initial=0.0))
    w = mission.wpnav
    report = {
        "model": "straight legs, jerk-limited S-curves, rest at every waypoint; ArduCopter defaults",
        "wpnav": {"WPNAV_SPEED_cms": w.speed_mps * 100, "WPNAV_SPEED_UP_cms": w.speed_up_mps * 100,
                  "WPNAV_SPEED_DN_cms": w.speed_dn_mps * 100, "WPNAV_ACCEL_cmss": w.accel_mps2 * 100,
                  "WPNAV_ACCEL_Z_cmss": w.accel_z_mps2 * 100, "WPNAV_JERK_msss": w.jerk_mps3},
        "sample_interval_s": dt,
        "worst_arrival_late_s": round(worst, 3),
        "worst_arrival_early_s": round(float(-late[1:-1].min(initial=0.0)), 3),
        "min_distance_m": s.min_distance_m,
        "close_pairs": [{"drones": [names[i], names[j]], "distance_m": round(d, 3), "time_s": round(t, 2)}
                        for i, j, d, t in pairs[:MAX_LISTED_PAIRS]],
        "close_pair_count": len(pairs),
    }
    if pairs:
        shown = "; ".join(f"{names[i]} and {names[j]} {d:.2f} m at {t:.1f} s" for i, j, d, t in pairs[:5])
        more = f" and {len(pairs) - 5} more" if len(pairs) > 5 else ""
        ctx.warn(
            f"{ctx.fmt}: replayed as waypoint missions at ArduCopter's default WPNAV parameters, {len(pairs)} pair(s) "
            f"come closer than min_distance_m {s.min_distance_m:g} m where the plan keeps them apart: {shown}{more} "
            "(manifest.json 'replay'); fly this show with .skyc"
        )
    if worst > LATE_WARN_S:
        ctx.warn(f"{ctx.fmt}: at ArduCopter's default WPNAV limits some drones reach a formation up to {worst:.1f} s "
                 "after the plan (a leg too fast for the waypoint limits)")
    return report


def _fence(ctx: ExportContext, origin) -> list[list[float]]:
    """Inclusion polygon (lat, lon) around the horizontal footprint of every knot, plus a margin."""
    xy = ctx.plan.knot_positions_m[..., :2].reshape(-1, 2)
    margin = max(FENCE_MARGIN_M, 2.0 * ctx.show.settings.min_distance_m)
    (x0, y0), (x1, y1) = xy.min(axis=0) - margin, xy.max(axis=0) + margin
    corners = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
    lat, lon, _ = local_to_geodetic(corners, origin=origin, heading_deg=ctx.options.heading_deg)
    return [[round(float(a), 10), round(float(b), 10)] for a, b in zip(lat, lon, strict=True)]


def require_still_holds(ctx: ExportContext) -> None:
    """A waypoint mission holds each formation still: refuse a show whose formations move during a hold."""
    moving = [k for k, f in enumerate(ctx.show.formations) if f.motion is not None]
    if moving:
        raise ExportError(
            f"formations[{moving[0]}].motion: a waypoint mission holds every formation still, so it cannot carry "
            f"a formation that moves during its hold ({len(moving)} do); export .skyc, Skybrush CSV or "
            f"waypoints CSV instead, or remove the motion"
        )


def export_qgc_plan(ctx: ExportContext) -> ExportResult:
    """Build the zip of QGroundControl ``.plan`` files (see the module docstring)."""
    require_planned(ctx)
    require_still_holds(ctx)
    mission = timed_mission(ctx)
    origin, it = _geodetic_items(ctx, mission)
    ctx.progress(0.15)
    fence = {"version": 2, "circles": [], "polygons": [{"inclusion": True, "polygon": _fence(ctx, origin),
                                                         "version": 1}]}
    speed = ctx.show.settings.max_speed_xy_mps
    names = ctx.drone_names
    z = ZipBuilder()
    n = ctx.show.drones
    la, lo, al = np.round(it.lat, 10), np.round(it.lon, 10), np.round(it.alt, 4) + 0.0
    home = (np.round(it.home[0], 10), np.round(it.home[1], 10), np.round(it.home[2], 4) + 0.0)
    params = it.params + 0.0
    is_nav = it.frame == MAV_FRAME_GLOBAL
    for i in range(n):
        items = []
        for j, cmd in enumerate(it.command.tolist()):
            p = params[j, i].tolist()
            items.append({
                "type": "SimpleItem",
                "autoContinue": True,
                "command": cmd,
                "doJumpId": j + 1,
                "frame": int(it.frame[j]),
                # yaw (param4) null = unchanged, as QGroundControl writes NaN, for navigation items.
                "params": [p[0], p[1], p[2], None, float(la[j, i]), float(lo[j, i]), float(al[j, i])]
                if is_nav[j] else [p[0], p[1], p[2], p[3], 0, 0, 0],
            })
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
                "plannedHomePosition": [float(home[0][i]), float(home[1][i]), float(home[2][i])],
                "items": items,
            },
            "geoFence": fence,
            "rallyPoints": {"version": 2, "points": []},
        }
        z.add(f"{names[i]}.plan", json.dumps(doc, indent=2, allow_nan=False) + "\n")
        if i % 256 == 255:
            ctx.progress(0.15 + 0.5 * (i + 1) / n)
    _finish(ctx, z, "qgc-plan", origin, mission)
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}-qgc-plan.zip", media_type="application/zip", content=z.finish(),
        warnings=list(ctx.warnings),
    )


def export_qgc_wpl(ctx: ExportContext) -> ExportResult:
    """Build the zip of ``QGC WPL 110`` waypoint files (see the module docstring)."""
    require_planned(ctx)
    require_still_holds(ctx)
    mission = timed_mission(ctx)
    origin, it = _geodetic_items(ctx, mission)
    ctx.progress(0.15)
    names = ctx.drone_names
    n = ctx.show.drones
    w = len(it.command) + 1
    cmd = np.r_[MAV_CMD_NAV_WAYPOINT, it.command]
    current = np.r_[1, np.zeros(w - 1, int)]
    frame = np.r_[MAV_FRAME_GLOBAL, it.frame]
    lat = np.concatenate([it.home[0][None], it.lat])
    lon = np.concatenate([it.home[1][None], it.lon])
    alt = np.concatenate([it.home[2][None], it.alt])
    params = np.concatenate([np.zeros((1, n, 4)), it.params]) + 0.0
    row = "%d\t%d\t%d\t%d\t%.6f\t%.6f\t%.6f\t%.6f\t%.10f\t%.10f\t%.4f\t1\n"
    z = ZipBuilder()
    for i in range(n):
        cols = [np.arange(w), current, frame, cmd, params[:, i, 0], params[:, i, 1], params[:, i, 2],
                params[:, i, 3], lat[:, i], lon[:, i], alt[:, i]]
        flat = [v for r in zip(*(c.tolist() for c in cols), strict=True) for v in r]
        z.add(f"{names[i]}.waypoints", "QGC WPL 110\n" + (row * w) % tuple(flat))
        if i % 256 == 255:
            ctx.progress(0.15 + 0.5 * (i + 1) / n)
    _finish(ctx, z, "qgc-wpl", origin, mission)
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}-qgc-wpl.zip", media_type="application/zip", content=z.finish(),
        warnings=list(ctx.warnings),
    )


def _finish(ctx: ExportContext, z: ZipBuilder, fmt: str, origin, mission: Mission) -> None:
    kind = "QGroundControl .plan files" if fmt == "qgc-plan" else "QGC WPL 110 .waypoints files"
    replay = replay_report(ctx, mission)
    ctx.progress(0.95)
    pairs = replay["close_pairs"]
    if pairs:
        listed = "\n".join(f"  {p['drones'][0]} and {p['drones'][1]}: {p['distance_m']:.2f} m at {p['time_s']:.1f} s"
                           for p in pairs[:20])
        safety = (f"WARNING: replayed at ArduCopter's default WPNAV parameters, {replay['close_pair_count']} pair(s) "
                  f"come closer than min_distance_m {replay['min_distance_m']:g} m where the plan keeps them "
                  f"apart (all in manifest.json 'replay'):\n{listed}\nFly this show with .skyc.")
    else:
        safety = (f"Replayed at ArduCopter's default WPNAV parameters (every {replay['sample_interval_s']:g} s), "
                  f"every pair the plan keeps {replay['min_distance_m']:g} m apart stays so.")
    z.add_manifest(
        base_manifest(
            ctx,
            fmt=fmt,
            origin={"latitude_deg": origin[0], "longitude_deg": origin[1], "altitude_m": origin[2]},
            geodesy="WGS84; local -> ENU (heading rotation) -> ECEF -> geodetic (Bowring, iterated)",
            frame="MAV_FRAME_GLOBAL (absolute altitude); DO_CHANGE_SPEED in MAV_FRAME_MISSION",
            replay=replay,
            warnings=list(ctx.warnings),
        ),
        _README.format(kind=kind, lat=origin[0], lon=origin[1], alt=origin[2], heading=ctx.options.heading_deg,
                       late=replay["worst_arrival_late_s"], early=replay["worst_arrival_early_s"], safety=safety),
    )
