"""``qgc-plan`` and ``qgc-wpl``: one QGroundControl mission per drone, in a zip, plus the WPNAV parameters.

Each drone's mission flies its own planned motion (:mod:`app.exports._wpnav`: a waypoint
wherever the plan brings it to rest, sub-legs where its planned path is not straight), in
WGS84 coordinates from the show's place on Earth (``settings.geo`` or ``--origin
LAT,LON,ALT`` and ``--heading DEG``; exact conversion, see :mod:`app.exports._geodesy`):

1. ``MAV_CMD_NAV_DELAY`` (93; param1 seconds) when its takeoff wave leaves after the start,
   then ``MAV_CMD_NAV_TAKEOFF`` (22) straight up to the takeoff's top;
2. per leg: ``MAV_CMD_NAV_DELAY`` (the wait until the plan's departure, to the millisecond,
   at least 0.1 s), ``MAV_CMD_DO_CHANGE_SPEED`` (178; param1 1 = ground, 2 = climb,
   3 = descent speed, param2 m/s, param3 -1 = throttle unchanged) for each speed that
   changes, then ``MAV_CMD_NAV_WAYPOINT`` (16, hold 0) at the leg's end;
3. ``MAV_CMD_NAV_DELAY`` then ``MAV_CMD_NAV_LAND`` (21) at its landing position.

The missions are timed against a kinematic replay of ArduCopter's waypoint navigation at
the WPNAV parameters in ``wpnav.parm`` (the show's own limits: the defaults cannot fly a
show's transitions in time), which also looks for pairs closer than ``min_distance_m``
where the plan keeps them apart; the export names any (warnings, ``manifest.json``
``replay``, README) and says to fly .skyc instead.

**Item limits.** ArduPilot stores 15-byte mission items: about 700 on boards that keep the
mission in 16 kB FRAM (Pixhawk 1 / Cube: ``MIS_TOTAL`` up to 724), many more on boards
with the mission on the SD card (``BRD_SD_MISSION``). A mission longer than
:data:`MAX_ITEMS` items is written with a warning naming the longest.

Navigation items use ``MAV_FRAME_GLOBAL`` (0): altitudes are absolute, ``ALT`` plus the
ellipsoidal height above the origin; ``DO_CHANGE_SPEED`` and ``NAV_DELAY`` use
``MAV_FRAME_MISSION`` (2).

``.plan`` (QGroundControl's JSON plan, ``fileType: "Plan"``, ``version: 1``):
``mission`` (``version`` 2) with ``SimpleItem`` items carrying ``params[7]`` (yaw ``null``
= unchanged, as QGroundControl writes NaN), ``plannedHomePosition`` [lat, lon, alt],
``firmwareType`` 3 (ArduPilot), ``vehicleType`` 2 (quadrotor), ``cruiseSpeed`` /
``hoverSpeed`` (the show's horizontal speed limit); ``geoFence`` (version 2) with one
inclusion polygon around the show's footprint plus a margin; ``rallyPoints`` (version 2,
none).

``.waypoints`` (``QGC WPL 110`` text, read by QGroundControl, Mission Planner and
pymavlink's ``MAVWPLoader``): line 0 is the home position, then the items above;
tab-separated ``index current frame command p1 p2 p3 p4 lat lon alt autocontinue``.

``wpnav.parm`` (Mission Planner / MAVProxy parameter file, ``NAME,VALUE`` lines, read by
pymavlink's ``mavparm``): WPNAV_SPEED, _SPEED_UP, _SPEED_DN, _ACCEL, _ACCEL_Z, _JERK, and
LAND_SPEED_HIGH 0 / LAND_SPEED so NAV_LAND descends at WPNAV_SPEED_DN to the ground (a descent
limit over 2 m/s is flown at 2 m/s below LAND_ALT_LOW, slower than the replay).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np

from app.exports._archive import ZipBuilder, base_manifest, safe_stem
from app.exports._core import ExportContext, ExportError, ExportResult, require_planned
from app.exports._geodesy import local_to_geodetic
from app.exports._wpnav import Mission, Wpnav, close_pairs, plan_legs, time_mission

MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_LAND = 21
MAV_CMD_NAV_TAKEOFF = 22
MAV_CMD_NAV_DELAY = 93
MAV_CMD_DO_CHANGE_SPEED = 178
MAV_FRAME_GLOBAL = 0
MAV_FRAME_MISSION = 2
MAV_AUTOPILOT_ARDUPILOTMEGA = 3
MAV_TYPE_QUADROTOR = 2
#: DO_CHANGE_SPEED speed types (MAVLink SPEED_TYPE).
SPEED_TYPE_GROUND, SPEED_TYPE_CLIMB, SPEED_TYPE_DESCENT = 1, 2, 3
#: Margin of the geofence polygon around the show's footprint, metres (at least).
FENCE_MARGIN_M = 10.0
#: Close pairs listed in the manifest (all are counted).
MAX_LISTED_PAIRS = 1000
#: Replayed lateness at a waypoint worth a warning, seconds.
LATE_WARN_S = 1.0
#: Items per mission past which the export warns (ArduPilot boards keeping missions in FRAM hold ~700).
MAX_ITEMS = 700
#: How far a planned path may stray from its waypoint legs, as shares of min_distance_m, tried in turn
#: while the replay loses pairs: a curved (blended) path cut finely is flown with a stop at every cut,
#: which makes the drone late; cut coarsely it strays from the plan's path. The first is the common case
#: (straight legs: no cut at all).
PATH_TOLERANCE_SHARES = (0.03, 0.1, 0.33)

_README = """\
QGroundControl missions (one per drone) made by swarmshow: {kind}.

Origin (x = y = z = 0): latitude {lat:.8f}, longitude {lon:.8f}, altitude {alt:.3f} m;
the show's +y axis points at bearing {heading:.3f} degrees (clockwise from true north).
Local coordinates are converted to WGS84 exactly (local -> ENU -> ECEF -> geodetic);
altitudes are absolute (MAV_FRAME_GLOBAL): the origin altitude plus the height
above it.

Before flying, load wpnav.parm into every drone (Mission Planner: Config > Full
Parameter List > Load from file; MAVProxy: param load wpnav.parm): {params}.
These are the show's own limits (WPNAV_ACCEL is max_accel_mps2 / sqrt 2, WPNAV_ACCEL_Z
max_accel_mps2: a steep diagonal leg may accelerate up to 1.22 x max_accel_mps2 along track);
ArduCopter's defaults (WPNAV_ACCEL_Z 1 m/s/s, WPNAV_JERK 1 m/s/s/s) cannot fly the show's
transitions in time, and drones that fall behind lose their separation.

Each mission follows its drone's own planned motion: a waypoint wherever the plan
brings the drone to rest (and sub-legs where the planned path is not straight, within
{tol:.2f} m), NAV_DELAY waits to the millisecond until the plan's departure (never
early), DO_CHANGE_SPEED ground / climb / descent speeds per leg (ArduCopter 4.2 or
later) so each leg arrives when the plan does; NAV_TAKEOFF (after a NAV_DELAY for later
takeoff waves) and NAV_LAND after a NAV_DELAY. At most {items} items per mission
(ArduPilot boards keeping the mission in FRAM hold about 700).

Timing: start every drone's mission at the same instant. In the replay each drone
reaches each waypoint at most {late:.2f} s after the plan (and at most {early:.2f} s
early, waiting out the difference); a real flight adds GPS and wind error.

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


def show_wpnav(settings) -> Wpnav:
    """The WPNAV parameters the missions are timed for: the show's limits.

    ArduCopter's along-track acceleration on a leg is min(WPNAV_ACCEL / horizontal share,
    WPNAV_ACCEL_Z / vertical share), whose largest value over all directions is
    √(WPNAV_ACCEL² + WPNAV_ACCEL_Z²). WPNAV_ACCEL_Z is max_accel_mps2 itself: the vertical
    takeoff and landing waves keep their planned vertical gaps only if they climb and descend
    as planned (at max_accel_mps2 / √2 the waves of a boxed launch came 8 cm too close).
    WPNAV_ACCEL is max_accel_mps2 / √2: horizontal legs accelerate a little slower than planned
    (a formation reached up to a quarter second late on the demo show) and no leg exceeds
    √1.5·max_accel_mps2 (a steep diagonal leg; the vertical and horizontal ones stay within it).
    """
    a = settings.max_accel_mps2
    descent = settings.max_descent_speed_mps if settings.max_descent_speed_mps is not None else settings.max_speed_z_mps
    return Wpnav(speed_mps=settings.max_speed_xy_mps, speed_up_mps=settings.max_speed_z_mps, speed_dn_mps=descent,
                 accel_mps2=a / math.sqrt(2.0), accel_z_mps2=a, jerk_mps3=settings.max_jerk_mps3)


def wpnav_parameters(w: Wpnav) -> dict[str, float]:
    """ArduCopter parameter values (their units: cm/s, cm/s², m/s³) of ``w``."""
    return {"WPNAV_SPEED": round(w.speed_mps * 100, 1), "WPNAV_SPEED_UP": round(w.speed_up_mps * 100, 1),
            "WPNAV_SPEED_DN": round(w.speed_dn_mps * 100, 1), "WPNAV_ACCEL": round(w.accel_mps2 * 100, 1),
            "WPNAV_ACCEL_Z": round(w.accel_z_mps2 * 100, 1), "WPNAV_JERK": round(w.jerk_mps3, 2)}


def landing_parameters(w: Wpnav) -> dict[str, float]:
    """NAV_LAND's descent at WPNAV_SPEED_DN all the way down, as the replay flies it: LAND_SPEED_HIGH 0
    (= WPNAV_SPEED_DN above LAND_ALT_LOW) and LAND_SPEED (below it; ArduCopter's range 30-200 cm/s)."""
    return {"LAND_SPEED_HIGH": 0.0, "LAND_SPEED": float(np.clip(round(w.speed_dn_mps * 100, 1), 30.0, 200.0))}


def _wpnav_of_parameters(p: dict[str, float]) -> Wpnav:
    """The limits the rounded parameter values give (the replay flies what the file says)."""
    return Wpnav(speed_mps=p["WPNAV_SPEED"] / 100, speed_up_mps=p["WPNAV_SPEED_UP"] / 100,
                 speed_dn_mps=p["WPNAV_SPEED_DN"] / 100, accel_mps2=p["WPNAV_ACCEL"] / 100,
                 accel_z_mps2=p["WPNAV_ACCEL_Z"] / 100, jerk_mps3=p["WPNAV_JERK"])


@dataclass
class Timed:
    """The missions chosen, the replay's lost pairs ``(i, j, distance_m, time_s)``, its sampling step and
    the path tolerance used (metres)."""

    mission: Mission
    pairs: list[tuple[int, int, float, float]]
    dt_s: float
    tol_m: float


def timed_mission(ctx: ExportContext) -> Timed:
    """Every drone's mission from its planned motion, timed at the show's WPNAV (:mod:`app.exports._wpnav`),
    and replayed; with the next path tolerance while pairs are lost, keeping the one that loses fewest."""
    s = ctx.show.settings
    w = _wpnav_of_parameters(wpnav_parameters(show_wpnav(s)))
    best: Timed | None = None
    for share in PATH_TOLERANCE_SHARES:
        tol = share * s.min_distance_m
        legs = plan_legs(ctx.plan, tol_m=tol)
        mission = time_mission(legs, w.speed_mps, w.speed_up_mps, w.speed_dn_mps, w)
        pairs, dt = close_pairs(mission, ctx.plan, s.min_distance_m)
        if best is None or len(pairs) < len(best.pairs):
            best = Timed(mission, pairs, dt, tol)
        # Safe, or no path was cut (straight legs: a coarser tolerance makes the same missions).
        if not pairs or int(legs.split.max(initial=1)) == 1:
            break
    assert best is not None
    return best


@dataclass
class Items:
    """Mission item slots after home (S slots, N drones): slot s is the same command for every drone,
    written for the drones where ``present[s]``."""

    command: np.ndarray  # (S,)
    frame: np.ndarray  # (S,)
    params: np.ndarray  # (S, N, 4): param1-4
    lat: np.ndarray  # (S, N) degrees (0 for DO commands and NAV_DELAY)
    lon: np.ndarray
    alt: np.ndarray  # metres
    present: np.ndarray  # (S, N) bool
    home: tuple[np.ndarray, np.ndarray, np.ndarray]  # (N,) each

    def counts(self) -> np.ndarray:
        """(N,) items per mission (home not counted)."""
        return self.present.sum(axis=0)


def _geodetic_items(ctx: ExportContext, mission: Mission) -> tuple[tuple[float, float, float], Items]:
    """The slots of every mission (module docstring), vectorised over drones."""
    origin = _origin(ctx)
    legs = mission.legs
    pts = mission.points_m  # (W+1, N, 3)
    lat, lon, alt = local_to_geodetic(pts, origin=origin, heading_deg=ctx.options.heading_deg)
    w, n = legs.depart_s.shape
    zeros, ones = np.zeros(n), np.ones(n)
    true = np.ones(n, dtype=bool)
    command, frame, params, la, lo, al, present = [], [], [], [], [], [], []

    def slot(cmd: int, frm: int, p: list[np.ndarray], k: int | None, where: np.ndarray) -> None:
        command.append(cmd)
        frame.append(frm)
        params.append(np.stack(p, axis=1))
        la.append(lat[k] if k is not None else zeros)
        lo.append(lon[k] if k is not None else zeros)
        al.append(alt[k] if k is not None else zeros)
        present.append(where)

    def delay(k: int, where: np.ndarray) -> None:
        # NAV_DELAY: param1 seconds; -1 in the time-of-day fields (hour, minute, second: unused).
        slot(MAV_CMD_NAV_DELAY, MAV_FRAME_MISSION, [mission.delay_s[k], -ones, -ones, -ones], None, where)

    delay(0, mission.delay_s[0] > 0)
    slot(MAV_CMD_NAV_TAKEOFF, MAV_FRAME_GLOBAL, [zeros] * 4, 1, true)
    # The speeds in force: the parameters' until a DO_CHANGE_SPEED; a command only where one changes
    # and the leg uses that axis (climb speed on climbing legs, descent speed on descending ones).
    cur = [np.full(n, mission.wpnav.speed_mps), np.full(n, mission.wpnav.speed_up_mps),
           np.full(n, mission.wpnav.speed_dn_mps)]
    for k in range(1, w - 1):
        real = legs.real[k]
        dz = pts[k + 1, :, 2] - pts[k, :, 2]
        horizontal = np.linalg.norm(pts[k + 1, :, :2] - pts[k, :, :2], axis=1) > 0
        delay(k, real)
        for q, (kind, speed, uses) in enumerate(((SPEED_TYPE_GROUND, mission.speed_xy_mps[k], horizontal),
                                                 (SPEED_TYPE_CLIMB, mission.speed_up_mps[k], dz > 0),
                                                 (SPEED_TYPE_DESCENT, mission.speed_dn_mps[k], dz < 0))):
            change = real & uses & (np.abs(speed - cur[q]) > 1e-9)
            cur[q] = np.where(change, speed, cur[q])
            slot(MAV_CMD_DO_CHANGE_SPEED, MAV_FRAME_MISSION, [np.full(n, float(kind)), speed, -ones, zeros], None,
                 change)
        slot(MAV_CMD_NAV_WAYPOINT, MAV_FRAME_GLOBAL, [zeros] * 4, k + 1, real)
    delay(w - 1, true)
    slot(MAV_CMD_NAV_LAND, MAV_FRAME_GLOBAL, [zeros] * 4, w, true)
    items = Items(np.array(command), np.array(frame), np.stack(params), np.stack(la), np.stack(lo), np.stack(al),
                  np.stack(present), (lat[0], lon[0], alt[0]))
    return origin, items


def replay_report(ctx: ExportContext, timed: Timed, items: Items) -> dict:
    """The replay's findings; warn (naming pairs) where the missions lose min_distance_m or the plan's timing."""
    s = ctx.show.settings
    names = ctx.drone_names
    mission, pairs, dt = timed.mission, timed.pairs, timed.dt_s
    legs = mission.legs
    late = (mission.arrive_s - legs.arrive_s)[1:-1][legs.real[1:-1]]
    worst = float(late.max(initial=0.0))
    counts = items.counts()
    report = {
        "model": "each drone's own planned motion as rest-to-rest legs (sub-legs where its path is not straight), "
                 "jerk-limited S-curves, per-leg ground / climb / descent speeds, NAV_DELAY waits; WPNAV as in "
                 "wpnav.parm",
        "wpnav": wpnav_parameters(mission.wpnav),
        "sample_interval_s": dt,
        "path_tolerance_m": round(timed.tol_m, 4),
        "path_deviation_m": round(legs.max_deviation_m, 4),
        "max_items": int(counts.max(initial=0)),
        "worst_arrival_late_s": round(worst, 3),
        "worst_arrival_early_s": round(float(-late.min(initial=0.0)), 3),
        "min_distance_m": s.min_distance_m,
        "close_pairs": [{"drones": [names[i], names[j]], "distance_m": round(d, 3), "time_s": round(t, 2)}
                        for i, j, d, t in pairs[:MAX_LISTED_PAIRS]],
        "close_pair_count": len(pairs),
    }
    if pairs:
        shown = "; ".join(f"{names[i]} and {names[j]} {d:.2f} m at {t:.1f} s" for i, j, d, t in pairs[:5])
        more = f" and {len(pairs) - 5} more" if len(pairs) > 5 else ""
        ctx.warn(
            f"{ctx.fmt}: replayed as waypoint missions at the WPNAV parameters of wpnav.parm, {len(pairs)} pair(s) "
            f"come closer than min_distance_m {s.min_distance_m:g} m where the plan keeps them apart: {shown}{more} "
            "(manifest.json 'replay'); this show is not safe as waypoint missions: fly it with .skyc"
        )
    if worst > LATE_WARN_S:
        ctx.warn(f"{ctx.fmt}: at the WPNAV limits of wpnav.parm some drones reach a waypoint up to {worst:.1f} s "
                 "after the plan (a leg too fast for the waypoint limits)")
    landing = [f.name for f in ctx.show.formations if f.others == "land" and f.drones is not None]
    if ctx.plan.grounded and landing:
        count = len(np.unique(np.concatenate([d for _, _, d in ctx.plan.grounded])))
        ctx.warn(f"{ctx.fmt}: {count} drones land mid-show (the others of formation(s) "
                 f"{', '.join(repr(x) for x in landing)}): their waypoints go down to their homes and back up, "
                 "which ArduCopter does not fly in AUTO (touching down idles the motors and no waypoint takes "
                 "off again); fly this show with .skyc, or let the others hold or park")
    if counts.max(initial=0) > MAX_ITEMS:
        i = int(counts.argmax())
        ctx.warn(f"{ctx.fmt}: {names[i]}'s mission has {int(counts[i])} items, more than the {MAX_ITEMS} that "
                 "ArduPilot boards keeping the mission in FRAM hold (store missions on the SD card: BRD_SD_MISSION)")
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
    timed = timed_mission(ctx)
    origin, it = _geodetic_items(ctx, timed.mission)
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
    commands = it.command.tolist()
    for i in range(n):
        items: list[dict[str, object]] = []
        for j in np.flatnonzero(it.present[:, i]).tolist():
            p = params[j, i].tolist()
            items.append({
                "type": "SimpleItem",
                "autoContinue": True,
                "command": commands[j],
                "doJumpId": len(items) + 1,
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
    _finish(ctx, z, "qgc-plan", origin, timed, it)
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}-qgc-plan.zip", media_type="application/zip", content=z.finish(),
        warnings=list(ctx.warnings),
    )


def export_qgc_wpl(ctx: ExportContext) -> ExportResult:
    """Build the zip of ``QGC WPL 110`` waypoint files (see the module docstring)."""
    require_planned(ctx)
    require_still_holds(ctx)
    timed = timed_mission(ctx)
    origin, it = _geodetic_items(ctx, timed.mission)
    ctx.progress(0.15)
    names = ctx.drone_names
    n = ctx.show.drones
    cmd = np.r_[MAV_CMD_NAV_WAYPOINT, it.command]
    frame = np.r_[MAV_FRAME_GLOBAL, it.frame]
    lat = np.concatenate([it.home[0][None], it.lat])
    lon = np.concatenate([it.home[1][None], it.lon])
    alt = np.concatenate([it.home[2][None], it.alt])
    params = np.concatenate([np.zeros((1, n, 4)), it.params]) + 0.0
    present = np.concatenate([np.ones((1, n), dtype=bool), it.present])
    row = "%d\t%d\t%d\t%d\t%.6f\t%.6f\t%.6f\t%.6f\t%.10f\t%.10f\t%.4f\t1\n"
    z = ZipBuilder()
    for i in range(n):
        rows = np.flatnonzero(present[:, i])
        w = len(rows)
        cols = [np.arange(w), np.r_[1, np.zeros(w - 1, int)], frame[rows], cmd[rows], params[rows, i, 0],
                params[rows, i, 1], params[rows, i, 2], params[rows, i, 3], lat[rows, i], lon[rows, i], alt[rows, i]]
        flat = [v for r in zip(*(c.tolist() for c in cols), strict=True) for v in r]
        z.add(f"{names[i]}.waypoints", "QGC WPL 110\n" + (row * w) % tuple(flat))
        if i % 256 == 255:
            ctx.progress(0.15 + 0.5 * (i + 1) / n)
    _finish(ctx, z, "qgc-wpl", origin, timed, it)
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}-qgc-wpl.zip", media_type="application/zip", content=z.finish(),
        warnings=list(ctx.warnings),
    )


def _finish(ctx: ExportContext, z: ZipBuilder, fmt: str, origin, timed: Timed, items: Items) -> None:
    kind = "QGroundControl .plan files" if fmt == "qgc-plan" else "QGC WPL 110 .waypoints files"
    replay = replay_report(ctx, timed, items)
    ctx.progress(0.95)
    parameters = {**replay["wpnav"], **landing_parameters(timed.mission.wpnav)}
    z.add("wpnav.parm", "".join(f"{k},{v:g}\n" for k, v in parameters.items()))
    pairs = replay["close_pairs"]
    if pairs:
        listed = "\n".join(f"  {p['drones'][0]} and {p['drones'][1]}: {p['distance_m']:.2f} m at {p['time_s']:.1f} s"
                           for p in pairs[:20])
        safety = (f"WARNING: replayed at the WPNAV parameters of wpnav.parm, {replay['close_pair_count']} pair(s) "
                  f"come closer than min_distance_m {replay['min_distance_m']:g} m where the plan keeps them "
                  f"apart (all in manifest.json 'replay'):\n{listed}\nThis show is not safe as waypoint missions: "
                  "fly it with .skyc.")
    else:
        safety = (f"Replayed at the WPNAV parameters of wpnav.parm (every {replay['sample_interval_s']:g} s), "
                  f"every pair the plan keeps {replay['min_distance_m']:g} m apart stays so.")
    z.add_manifest(
        base_manifest(
            ctx,
            fmt=fmt,
            origin={"latitude_deg": origin[0], "longitude_deg": origin[1], "altitude_m": origin[2]},
            geodesy="WGS84; local -> ENU (heading rotation) -> ECEF -> geodetic (Bowring, iterated)",
            frame="MAV_FRAME_GLOBAL (absolute altitude); DO_CHANGE_SPEED and NAV_DELAY in MAV_FRAME_MISSION",
            replay=replay,
            warnings=list(ctx.warnings),
        ),
        _README.format(kind=kind, lat=origin[0], lon=origin[1], alt=origin[2], heading=ctx.options.heading_deg,
                       params=", ".join(f"{k} {v:g}" for k, v in parameters.items()),
                       tol=replay["path_tolerance_m"], items=replay["max_items"],
                       late=replay["worst_arrival_late_s"], early=replay["worst_arrival_early_s"], safety=safety),
    )
