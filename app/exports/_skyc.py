"""``skyc``: a Skybrush compiled show (zip with ``show.json`` at its root), format version 1.

``show.json``::

    {"version": 1,
     "settings": {"cues": {"version": 1, "items": []},
                  "validation": {"minDistance", "maxVelocityXY", "maxVelocityZ",
                                 "maxAccelerationXY", "maxAccelerationZ", "maxAltitude"}},
     "swarm": {"drones": [{"type": "generic",
                           "settings": {"name", "home": [x, y, z],
                                        "trajectory": {"version": 1, "points": [...]},
                                        "lights": {"version": 1, "data": base64}}}]},
     "environment": {"type": "outdoor"},
     "meta": {"title", "generator", "segments": {"takeoff": [t0, t1], "show": [...], "landing": [...]}}}

Trajectory points are ``[t, [x, y, z], [control points]]``: the curve from
the previous point to this one is a Bézier curve in normalised time with 0
(straight line), 1 or 2 control points; the first point has none. Times are
strictly increasing seconds.

Every drone is written from its own polynomial pieces (``plan.motion``: its own
break times, so staggered departures and arrivals are kept): each piece of
degree <= 3 is one cubic Bézier, exactly (the cubic Hermite interpolant of a
cubic is the cubic itself: control points p0 + h·v0/3 and p1 - h·v1/3); a
piece of degree 4 or 5 is split into m equal-time parts, each its cubic
Hermite interpolant (exact position and velocity at every boundary, so the
curve is C¹), m the smallest count whose error bound (:func:`hermite_error_bound`)
stays within :data:`TOLERANCE_M`. Pieces of degree <= 1 need no control points
(a straight line in normalised time is linear in time); zero-length pieces are
dropped, and runs of constant points are merged.

Lights are Skybrush / ``ledctrl`` light-program bytecode (pyledctrl's
``CommandCode``): ``SET_COLOR r g b duration`` (0x04), ``FADE_TO_COLOR r g b
duration`` (0x08, linear) and ``END`` (0x00), durations as unsigned LEB128
varints in frames of 1/50 s. The plan fades colours linearly between knots,
which ``FADE_TO_COLOR`` reproduces exactly up to the 20 ms frame grid. A show with light effects
(issue 18) gets each drone's colours fitted as fades and holds instead (:mod:`app.exports._ledctrl`).
"""

from __future__ import annotations

import base64
import json

import numpy as np

from app.exports._archive import ZipBuilder, safe_stem
from app.exports._core import ExportContext, ExportResult, require_planned
from app.exports._media import add_skyc_audio
from app.exports._ledctrl import show_light_programs
from sim.plan import horner

#: Largest deviation of the Bézier curves from the plan, metres (the issue allows 1 cm).
TOLERANCE_M = 0.002
#: Drones Skybrush's viewer displays.
SKYBRUSH_VIEWER_MAX_DRONES = 5000
#: Light-program frame rate (``ledctrl`` durations are in frames), frames per second.
LIGHT_FPS = 50
OP_END = 0x00
OP_SET_COLOR = 0x04
OP_FADE_TO_COLOR = 0x08
# Decimals kept in show.json: 1 µs for times (piece boundaries must not move), 0.1 mm for positions.
_TIME_DECIMALS = 6
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


def _varuint(value: int) -> bytes:
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


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


def _drone_points(plan) -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Per-drone (times, positions, controls, has_controls) of the Bézier points after the home point.

    Every drone's own pieces, split as the module docstring says; constant runs merged.
    """
    motion = plan.motion
    breaks, coeffs = motion.breaks_s, motion.coeffs_m
    n = motion.drone_count
    drone, piece = np.nonzero(np.diff(breaks, axis=1) > 0)  # drone by drone, in time order
    c = coeffs[drone, piece]  # (M, 3, D+1)
    t0 = breaks[drone, piece]
    dur = breaks[drone, piece + 1] - t0
    nonzero = np.any(c != 0.0, axis=1)  # (M, D+1): which powers are used
    degree = np.where(nonzero.any(axis=1), c.shape[-1] - 1 - np.argmax(nonzero[:, ::-1], axis=1), 0)
    parts = np.where(degree <= 3, 1, subdivisions(c, dur))
    # One row per part: its piece, its index in the piece.
    row = np.repeat(np.arange(len(drone)), parts)
    j = np.arange(len(row)) - np.repeat(np.cumsum(parts) - parts, parts)
    h = dur[row] / parts[row]
    u0, u1 = j * h, (j + 1) * h
    cr = c[row]
    p0, v0 = horner(cr, u0[:, None]), horner(_derivative(cr), u0[:, None])
    p1, v1 = horner(cr, u1[:, None]), horner(_derivative(cr), u1[:, None])
    controls = np.stack([p0 + h[:, None] * v0 / 3.0, p1 - h[:, None] * v1 / 3.0], axis=1)  # (R, 2, 3)
    times = np.where(j == parts[row] - 1, t0[row] + dur[row], t0[row] + u1)
    has = degree[row] >= 2
    constant = degree[row] == 0
    d = drone[row]
    # A constant point followed by another constant point of the same drone is redundant:
    # the drone stays still across both.
    same_next = np.r_[d[1:] == d[:-1], False]
    keep = ~(constant & np.r_[constant[1:], False] & same_next)
    d, times, p1, controls, has = d[keep], times[keep], p1[keep], controls[keep], has[keep]
    # Times are written to 1 µs and must increase strictly: a point that would land on
    # the previous one's time stamp (a sub-microsecond piece) is dropped; the next curve
    # then starts less than a microsecond of motion early.
    stamps = np.round(times, _TIME_DECIMALS)
    first = np.r_[True, d[1:] != d[:-1]]
    previous = np.where(first, 0.0, np.r_[0.0, stamps[:-1]])
    keep = stamps > previous
    d, times, p1, controls, has = d[keep], times[keep], p1[keep], controls[keep], has[keep]
    cuts = np.cumsum(np.bincount(d, minlength=n))[:-1]
    return np.split(times, cuts), np.split(p1, cuts), np.split(controls, cuts), np.split(has, cuts)


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


def build_show_json(ctx: ExportContext) -> dict:
    """The ``show.json`` document of the ``.skyc`` (see the module docstring)."""
    from importlib.metadata import PackageNotFoundError, version

    plan = ctx.plan
    s = ctx.show.settings
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
        t = np.round(times[i], _TIME_DECIMALS).tolist()
        p = (np.round(positions[i], _POS_DECIMALS) + 0.0).tolist()
        c = (np.round(controls[i], _POS_DECIMALS) + 0.0).tolist()
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
            "cues": {"version": 1, "items": []},
            "validation": {
                "minDistance": s.min_distance_m,
                "maxVelocityXY": s.max_speed_xy_mps,
                "maxVelocityZ": s.max_speed_z_mps,
                "maxAccelerationXY": s.max_accel_mps2,
                "maxAccelerationZ": s.max_accel_mps2,
                "maxAltitude": s.max_altitude_m,
            },
        },
        "swarm": {"drones": drones},
        "environment": {"type": "outdoor"},
        "meta": {"title": ctx.show.name, "generator": generator, "segments": _segments_meta(plan)},
    }


def export_skyc(ctx: ExportContext) -> ExportResult:
    """Build the ``.skyc`` archive (see the module docstring)."""
    require_planned(ctx)
    if ctx.show.drones > SKYBRUSH_VIEWER_MAX_DRONES:
        ctx.warn(
            f"the show has {ctx.show.drones} drones; Skybrush Viewer displays at most {SKYBRUSH_VIEWER_MAX_DRONES}"
        )
    doc = build_show_json(ctx)
    z = ZipBuilder()
    add_skyc_audio(ctx, doc, z)  # issue 18: the show's music as media.audio
    z.add("show.json", json.dumps(doc, separators=(",", ":"), allow_nan=False))
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}.skyc",
        media_type="application/zip",
        content=z.finish(),
    )
