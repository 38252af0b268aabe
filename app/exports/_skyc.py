"""``skyc``: a Skybrush compiled show (zip with ``show.json`` at its root), format version 1.

``show.json``::

    {"version": 1,
     "settings": {"cues": {"version": 1, "items": [{"name", "time"}, ...]},
                  "validation": {"maxAltitude", "maxVelocityXY", "maxVelocityZ", ["maxVelocityZUp"],
                                 "maxAccelerationXY", "maxAccelerationZ", "minDistance",
                                 "minNavAltitude", "maxYawRate"}},
     "swarm": {"drones": [{"type": "generic",
                           "settings": {"name", "home": [x, y, z],
                                        "trajectory": {"version": 1, "points": [...]},
                                        "lights": {"version": 1, "data": base64}}}]},
     "environment": {"type": "outdoor", "location": {"origin": [lat·1e7, lon·1e7, amsl_mm],
                                                     "orientation": deg}},
     "meta": {"title", "generator", "segments": {"takeoff": [t0, t1], "show": [...], "landing": [...]}}}

Frame: Skybrush's show frame is X front, Y left, Z up, and ``location.orientation``
is the compass bearing of +X. Our x, y, z are written unchanged and the orientation
is the heading + 90° (see :mod:`app.exports._frames`); ``location`` is written when
the show has a place on Earth (``settings.geo`` or ``--origin``).

Trajectory points are ``[t, [x, y, z], [control points]]``: the curve from
the previous point to this one is a Bézier curve in normalised time with 0
(straight line), 1 or 2 control points; the first point has none. Times are
strictly increasing seconds, **whole milliseconds**: Skybrush Server converts the
show to its binary format (durations in integer milliseconds, coordinates int16 at
a per-drone scale of 1, 2, ... mm) for libskybrush, the drone's player, so a time
between milliseconds would be cut and the drone's clock would drift from the plan's.
The server computes each duration as ``floor(round(t1 - t0, 3) · 1000)``, which
loses a millisecond for about 1 % of whole-millisecond durations (1001 ms reads
1000.9999999999999): such a segment is written as two segments whose durations
survive. Segments are at most :data:`MAX_SEGMENT_MS` long (the server splits longer
ones at fractional milliseconds).

Every drone is written from its own polynomial pieces (``plan.motion``: its own
break times, so staggered departures and arrivals are kept): runs of constant
pieces merge into one; each piece of degree <= 3 is one cubic Bézier (the cubic
Hermite interpolant of a cubic is the cubic itself: control points p0 + h·v0/3 and
p1 - h·v1/3); a piece of degree 4 or 5 is split into m equal-time parts, m the
smallest count whose error bound (:func:`hermite_error_bound`) stays within
:data:`TOLERANCE_M`. Cut times are then rounded to whole milliseconds and each part
is the cubic Hermite interpolant of its piece between its rounded times (exact
position and velocity at every stamp, so the curve is C¹ and on time). Pieces of
degree <= 1 need no control points (a straight line in normalised time is linear
in time); parts shorter than half a millisecond vanish.

Lights are Skybrush / ``ledctrl`` light-program bytecode (pyledctrl's
``CommandCode``): ``SET_COLOR r g b duration`` (0x04), ``FADE_TO_COLOR r g b
duration`` (0x08, linear) and ``END`` (0x00), durations as unsigned LEB128
varints in frames of 1/50 s. The plan fades colours linearly between knots,
which ``FADE_TO_COLOR`` reproduces exactly up to the 20 ms frame grid. A show with light effects
(issue 18) gets each drone's colours fitted as fades and holds instead (:mod:`app.exports._ledctrl`).
"""

from __future__ import annotations

import base64
import functools
import gc
import json
import math
from typing import Any

import numpy as np

from app.exports._archive import ZipBuilder, safe_stem
from app.exports._core import ExportContext, ExportResult, require_planned
from app.exports._frames import skybrush_orientation_deg
from app.exports._ledctrl import show_light_programs
from app.exports._ledctrl import varuint as _varuint
from app.exports._media import add_skyc_audio
from sim.plan import horner

#: Largest deviation of the Bézier curves from the plan, metres. The drone's budget is 7 mm
#: (libskybrush after the server's conversion), of which the binary format's int16
#: coordinates take up to ~3.5 mm at scale 2 and ~5.2 mm at scale 3 (1 unit per axis,
#: truncated); the show-format loader's budget is 2 mm, of which the written decimals
#: take 0.09 mm. Parts grow like tolerance^(-1/4): 1.5 mm costs 8 % more points than 2 mm.
TOLERANCE_M = 0.0015
#: Most drones a .skyc may hold: Skybrush Live and Skybrush Viewer refuse larger shows.
SKYBRUSH_MAX_DRONES = 5000
#: Longest segment written, milliseconds: the server cuts longer ones (over 65 s) at fractional milliseconds.
MAX_SEGMENT_MS = 60_000
#: Studio's default for the yaw-rate limit (swarmshow drones do not yaw), degrees per second.
MAX_YAW_RATE_DEG_S = 30.0
#: Light-program frame rate (``ledctrl`` durations are in frames), frames per second.
LIGHT_FPS = 50
OP_END = 0x00
OP_SET_COLOR = 0x04
OP_FADE_TO_COLOR = 0x08
# Decimals kept in show.json: times are whole milliseconds, positions 0.1 mm.
_TIME_DECIMALS = 3
_POS_DECIMALS = 4


def hermite_error_bound(coeffs_m: np.ndarray, duration_s: np.ndarray, parts: np.ndarray) -> np.ndarray:
    """Bound on the distance (m) between pieces and their cubic Hermite interpolants on ``parts`` equal parts.

    For a quintic f re-expanded at a part's start (coefficients a_k) the Hermite
    error on a part of length h is exactly e(s) = s²(s-h)²·(a4 + 2h·a5 + a5·s)
    (e and e' vanish at both ends and e - f is cubic), so
    ||e|| <= h⁴/16 · max over the part's ends of ||a4 + 2h·a5 + a5·s|| (a norm of an
    affine function is convex). With a4 = c4 + 5·c5·u0 at part j (u0 = j·h) the ends
    are c4 + c5·h·(5j + 2) and c4 + c5·h·(5j + 3): over all parts, x = 2 and 5m - 2.

    Args:
        coeffs_m: (M, 3, D+1) pieces, ascending powers of local time (D <= 5).
        duration_s: (M,) piece lengths, seconds.
        parts: (M,) parts per piece (>= 1).
    """
    c4, c5 = coeffs_m[:, :, 4], coeffs_m[:, :, 5]
    h = (duration_s / parts)[:, None]
    lo = np.linalg.norm(c4 + 2.0 * h * c5, axis=1)
    hi = np.linalg.norm(c4 + (5.0 * parts[:, None] - 2.0) * h * c5, axis=1)
    return h[:, 0] ** 4 / 16.0 * np.maximum(lo, hi)


def subdivisions(coeffs_m: np.ndarray, duration_s: np.ndarray, tolerance_m: float = TOLERANCE_M) -> np.ndarray:
    """(M,) the smallest part count per piece whose :func:`hermite_error_bound` is within ``tolerance_m``.

    Pieces of degree <= 3 need one part (their Hermite cubic is exact).
    """
    m = np.ones(len(duration_s), dtype=np.int64)
    todo = np.flatnonzero(hermite_error_bound(coeffs_m, duration_s, m) > tolerance_m)
    while len(todo):
        # The bound falls like m⁻⁴ for large m: jump close to the answer, then step by one.
        ratio = hermite_error_bound(coeffs_m[todo], duration_s[todo], m[todo]) / tolerance_m
        m[todo] = np.maximum(m[todo] + 1, np.floor(m[todo] * ratio**0.25 * 0.9).astype(np.int64))
        todo = todo[hermite_error_bound(coeffs_m[todo], duration_s[todo], m[todo]) > tolerance_m]
    # Step back down where the jump overshot (the bound is not exactly m⁻⁴).
    while True:
        fewer = np.flatnonzero(m > 1)
        fewer = fewer[hermite_error_bound(coeffs_m[fewer], duration_s[fewer], m[fewer] - 1) <= tolerance_m]
        if not len(fewer):
            return m
        m[fewer] -= 1


def light_program(frames: np.ndarray, colors: np.ndarray) -> bytes:
    """Bytecode for colours fading linearly between knots.

    Args:
        frames: (K+1,) knot times in 1/50 s frames (non-decreasing integers).
        colors: (K+1, 3) knot colours, integers 0-255.
    """
    ops: list[list] = []  # [opcode, (r, g, b), frames]
    current = None
    for k in range(len(frames) - 1):
        dur = int(frames[k + 1] - frames[k])
        c0, c1 = tuple(int(v) for v in colors[k]), tuple(int(v) for v in colors[k + 1])
        if current != c0:
            ops.append([OP_SET_COLOR, c0, 0])
            current = c0
        if c1 == c0:
            if ops and ops[-1][0] == OP_SET_COLOR and ops[-1][1] == c0:
                ops[-1][2] += dur
            else:
                ops.append([OP_SET_COLOR, c0, dur])
        else:
            ops.append([OP_FADE_TO_COLOR, c1, dur])
            current = c1
    code = bytearray()
    for op, (r, g, b), dur in ops:
        code += bytes((op, r, g, b)) + _varuint(dur)
    code.append(OP_END)
    return bytes(code)


def _server_truncates(duration_ms: int) -> bool:
    """Whether Skybrush Server's .skyc-to-binary conversion stores ``duration_ms`` one millisecond short.

    The server takes a segment's duration as ``round(t1 - t0, 3)`` seconds and writes
    ``floor(duration·1000)`` milliseconds; for some whole-millisecond durations the
    binary double nearest to ``k/1000`` times 1000 falls just below ``k`` (1001 ms:
    1000.9999999999999), and every such segment would put the drone's clock 1 ms behind.
    """
    return math.floor(round(duration_ms / 1000.0, 3) * 1000.0) != duration_ms


@functools.cache
def _safe_split_ms() -> np.ndarray:
    """(MAX_SEGMENT_MS + 2,) per duration d (ms): 0 if the server keeps d, else a split a with a and d - a kept."""
    split = np.zeros(MAX_SEGMENT_MS + 2, dtype=np.int64)
    for d in range(1, MAX_SEGMENT_MS + 2):
        if _server_truncates(d):
            a = d // 2
            while _server_truncates(a) or _server_truncates(d - a):
                a -= 1
            split[d] = a
    return split


def _drone_points(plan) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Per-drone (times in whole ms, positions, controls, has_controls) of the Bézier points after the home point.

    Every drone's own pieces, constant runs merged, split as the module docstring says;
    the cut times are rounded to whole milliseconds *before* fitting, so each cubic
    interpolates the plan at the very time stamps the drone's clock uses.
    """
    motion = plan.motion
    breaks, coeffs = motion.breaks_s, motion.coeffs_m
    n = motion.drone_count
    drone, piece = np.nonzero(np.diff(breaks, axis=1) > 0)  # drone by drone, in time order
    c = coeffs[drone, piece]  # (M, 3, D+1)
    t0 = breaks[drone, piece]
    t1 = breaks[drone, piece + 1]
    nonzero = np.any(c != 0.0, axis=1)  # (M, D+1): which powers are used
    degree = np.where(nonzero.any(axis=1), c.shape[-1] - 1 - np.argmax(nonzero[:, ::-1], axis=1), 0)
    # A constant piece right after another constant piece of the same drone continues it
    # (the motion is continuous, so both hold the same position): one run, one piece.
    constant = degree == 0
    first = np.r_[True, drone[1:] != drone[:-1]] if len(drone) else np.zeros(0, bool)
    starts = np.flatnonzero(first | ~constant | ~np.r_[False, constant[:-1]])
    ends = np.r_[starts[1:] - 1, len(drone) - 1].astype(np.int64)
    drone, c, degree, t0, t1 = drone[starts], c[starts], degree[starts], t0[starts], t1[ends]
    dur = t1 - t0
    parts = np.where(degree <= 3, 1, subdivisions(c, dur))
    # The server splits segments over 65 s at fractional milliseconds: keep each below MAX_SEGMENT_MS.
    parts = np.maximum(parts, np.ceil(dur * 1000.0 / MAX_SEGMENT_MS).astype(np.int64))
    row = np.repeat(np.arange(len(drone)), parts)
    j = np.arange(len(row)) - np.repeat(np.cumsum(parts) - parts, parts)
    h = dur[row] / parts[row]
    start_ms = np.rint((t0[row] + j * h) * 1000.0).astype(np.int64)
    end_ms = np.where(j == parts[row] - 1, np.rint(t1[row] * 1000.0), np.rint((t0[row] + (j + 1) * h) * 1000.0))
    end_ms = end_ms.astype(np.int64)
    # Sub-millisecond parts vanish: the next part starts where they did, within a millisecond of motion.
    keep = end_ms > start_ms
    row, start_ms, end_ms = row[keep], start_ms[keep], end_ms[keep]
    # Durations the server would shorten by a millisecond become two parts it keeps.
    split = _safe_split_ms()[end_ms - start_ms]
    twice = np.repeat(np.arange(len(row)), 1 + (split > 0))
    second = np.r_[False, twice[1:] == twice[:-1]]
    first_of_two = np.r_[twice[1:] == twice[:-1], False]
    row, s_ms, e_ms, cut = row[twice], start_ms[twice], end_ms[twice], split[twice]
    s_ms = np.where(second, s_ms + cut, s_ms)
    e_ms = np.where(first_of_two, s_ms + cut, e_ms)
    # Fit each part: the cubic Hermite interpolant of its piece between the whole-ms stamps.
    cr = c[row]
    u0 = (s_ms / 1000.0 - t0[row])[:, None]
    u1 = (e_ms / 1000.0 - t0[row])[:, None]
    hp = ((e_ms - s_ms) / 1000.0)[:, None]
    dc = _derivative(cr)
    p0, v0, p1, v1 = horner(cr, u0), horner(dc, u0), horner(cr, u1), horner(dc, u1)
    controls = np.stack([p0 + hp * v0 / 3.0, p1 - hp * v1 / 3.0], axis=1)  # (R, 2, 3)
    has = degree[row] >= 2
    d = drone[row]
    cuts = np.cumsum(np.bincount(d, minlength=n))[:-1]
    # Rounded to the written decimals once for every drone (+ 0.0: no "-0.0").
    p1 = np.round(p1, _POS_DECIMALS) + 0.0
    controls = np.round(controls, _POS_DECIMALS) + 0.0
    return np.split(e_ms, cuts), np.split(p1, cuts), np.split(controls, cuts), np.split(has, cuts)


def _derivative(c: np.ndarray) -> np.ndarray:
    """Coefficients (..., D+1) of the time derivative, same ascending layout (zero-padded)."""
    k = np.arange(1, c.shape[-1], dtype=np.float64)
    return np.concatenate([c[..., 1:] * k, np.zeros_like(c[..., :1])], axis=-1)


def _segments_meta(plan) -> dict[str, list[float]]:
    segs = plan.segments
    takeoff_end = max((s.end_s for s in segs if s.kind == "takeoff"), default=0.0)
    holds = [s for s in segs if s.kind == "hold"]
    show_end = holds[-1].end_s if holds else takeoff_end
    r = lambda x: round(float(x), _TIME_DECIMALS)  # noqa: E731
    return {
        "takeoff": [0.0, r(takeoff_end)],
        "show": [r(takeoff_end), r(show_end)],
        "landing": [r(show_end), r(plan.duration_s)],
    }


def cue_list(ctx: ExportContext) -> dict[str, Any]:
    """``settings.cues``: the show's cues as Skybrush Live lists them (version 1, ``items`` of
    ``{"name", "time"}`` in seconds, the layout Skybrush Studio for Blender writes from its
    timeline markers, ``TimeMarkers.as_dict``).

    One cue per formation when the drones reach it (the start of its hold), named after the
    formation, and one named "<formation> ends" when a formation's departure is pinned
    (``leave_at_s``); a pinned time (``arrive_at_s`` / ``leave_at_s``, on the music) is
    written as the designer set it. Sorted by time, whole milliseconds (the trajectories'
    clock).
    """
    holds = [s for s in ctx.plan.segments if s.kind == "hold"]
    items: list[tuple[float, int, str]] = []
    for k, (f, seg) in enumerate(zip(ctx.show.formations, holds, strict=True)):
        start = f.arrive_at_s if f.arrive_at_s is not None else seg.start_s
        items.append((round(float(start), 3), 2 * k, f.name))
        if f.leave_at_s is not None:
            items.append((round(float(f.leave_at_s), 3), 2 * k + 1, f"{f.name} ends"))
    items.sort()
    return {"version": 1, "items": [{"name": name, "time": t} for t, _, name in items]}


def validation_settings(ctx: ExportContext) -> dict[str, float]:
    """The safety limits under the keys Skybrush Studio writes (``SafetyCheckParams.as_dict``).

    ``maxVelocityZ`` is the descent limit; ``maxVelocityZUp`` (written when climbing is
    limited differently) the climb limit, as Studio splits them.
    """
    s = ctx.show.settings
    descent = s.max_descent_speed_mps if s.max_descent_speed_mps is not None else s.max_speed_z_mps
    out = {
        "maxAltitude": round(s.max_altitude_m, 3),
        "maxVelocityXY": round(s.max_speed_xy_mps, 3),
        "maxVelocityZ": round(descent, 3),
        "maxAccelerationXY": round(s.max_accel_mps2, 3),
        "maxAccelerationZ": round(s.max_accel_mps2, 3),
        "minDistance": round(s.min_distance_m, 3),
        "minNavAltitude": round(s.min_altitude_m, 3),
        "maxYawRate": MAX_YAW_RATE_DEG_S,
    }
    if descent != s.max_speed_z_mps:
        out["maxVelocityZUp"] = round(s.max_speed_z_mps, 3)
    return out


def environment(ctx: ExportContext) -> dict:
    """``environment``: outdoor, and the show's place on Earth when it has one.

    ``location`` is what Studio writes (``ShowLocation.json``): ``origin`` = [latitude·10⁷,
    longitude·10⁷, AMSL altitude in mm] as integers, ``orientation`` = bearing of the
    Skybrush +X axis in degrees. Coordinates are written as they are (Skybrush X = our
    x, Y = our y, Z = our z): Skybrush's frame is X front, Y left, Z up, so with X at
    bearing heading + 90° (where our +x points) its Y lies at the heading, where our +y
    points (:func:`app.exports._frames.skybrush_orientation_deg`).
    """
    env: dict = {"type": "outdoor"}
    if ctx.options.origin is not None:
        lat, lon, alt = ctx.options.origin
        env["location"] = {
            "origin": [round(lat * 1e7), round(lon * 1e7), round(alt * 1e3)],
            "orientation": round(skybrush_orientation_deg(ctx.options.heading_deg), 3),
        }
    return env


def build_show_json(ctx: ExportContext) -> dict:
    """The ``show.json`` document of the ``.skyc`` (see the module docstring)."""
    from importlib.metadata import PackageNotFoundError, version

    plan = ctx.plan
    names = ctx.drone_names
    times, positions, controls, has = _drone_points(plan)
    ctx.progress(0.5)
    frames = np.rint(plan.knot_times_s * LIGHT_FPS).astype(np.int64)
    colors = np.clip(np.rint(plan.knot_colors_rgb * 255.0), 0, 255).astype(np.int64)
    home = np.round(plan.knot_positions_m[0], _POS_DECIMALS) + 0.0
    # Issue 18: with light effects, each drone's colours fitted as fades (app.exports._ledctrl).
    programs = show_light_programs(ctx.show, plan, lambda f: ctx.progress(0.5 + 0.4 * f))
    drones = []
    for i in range(plan.drone_count):
        t = (times[i] / 1000.0).tolist()  # whole ms: the shortest repr is exact to 3 decimals
        p = positions[i].tolist()  # rounded to _POS_DECIMALS by _drone_points
        c = controls[i].tolist()
        h = has[i].tolist()
        points = [[0.0, home[i].tolist(), []]]
        points += [[tj, pj, cj if hj else []] for tj, pj, cj, hj in zip(t, p, c, h, strict=True)]
        program = programs[i] if programs is not None else light_program(frames, colors[:, i])
        lights = base64.b64encode(program).decode("ascii")
        drones.append(
            {
                "type": "generic",
                "settings": {
                    "name": names[i],
                    "home": home[i].tolist(),
                    "trajectory": {"version": 1, "points": points},
                    "lights": {"version": 1, "data": lights},
                },
            }
        )
    try:
        generator = f"swarmshow {version('swarmshow')}"
    except PackageNotFoundError:
        generator = "swarmshow"
    return {
        "version": 1,
        "settings": {
            "cues": cue_list(ctx),
            "validation": validation_settings(ctx),
        },
        "swarm": {"drones": drones},
        "environment": environment(ctx),
        "meta": {"title": ctx.show.name, "generator": generator, "segments": _segments_meta(plan)},
    }


def export_skyc(ctx: ExportContext) -> ExportResult:
    """Build the ``.skyc`` archive (see the module docstring)."""
    require_planned(ctx)
    if ctx.show.drones > SKYBRUSH_MAX_DRONES:
        ctx.warn(
            f"the show has {ctx.show.drones:,} drones: Skybrush Live and Skybrush Viewer refuse .skyc files with "
            f"more than {SKYBRUSH_MAX_DRONES:,} drones, so this file will not load there; split the show into "
            f"groups of at most {SKYBRUSH_MAX_DRONES:,} drones"
        )
    if ctx.options.origin is None:
        ctx.warn(
            "the show has no place on Earth (settings.geo): the .skyc has no environment.location, so set the "
            "origin in Skybrush Live and its orientation to the show's heading + 90 degrees by hand"
        )
    # show.json is millions of small lists and floats, none in a cycle: the cyclic garbage
    # collector would rescan them over and over while they are built (half the CPU time
    # of a 5,000-drone export), so it pauses until the text is written.
    z = ZipBuilder()
    paused = gc.isenabled()
    gc.disable()
    try:
        doc = build_show_json(ctx)
        add_skyc_audio(ctx, doc, z)  # issue 18: the show's music as media.audio
        text = json.dumps(doc, separators=(",", ":"), allow_nan=False)
        del doc
    finally:
        if paused:
            gc.enable()
    z.add("show.json", text)
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}.skyc",
        media_type="application/zip",
        content=z.finish(),
    )
