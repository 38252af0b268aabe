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

The plan's straight-line quintic segments are split into n equal-time pieces,
each the cubic Hermite interpolant of the time law β (exact position and
velocity at every piece boundary, so the curve is C¹). All drones share β, so
one cubic per piece serves the whole fleet: the control points are
p0 + b·Δp with b the Bézier ordinates of the cubic. n is the smallest count
for which the largest move of the segment stays within :data:`TOLERANCE_M`
of the plan. Drones that do not move in a segment get one constant point,
and runs of constant points are merged.

Lights are Skybrush / ``ledctrl`` light-program bytecode (pyledctrl's
``CommandCode``): ``SET_COLOR r g b duration`` (0x04), ``FADE_TO_COLOR r g b
duration`` (0x08, linear) and ``END`` (0x00), durations as unsigned LEB128
varints in frames of 1/50 s. The plan fades colours linearly between knots,
which ``FADE_TO_COLOR`` reproduces exactly up to the 20 ms frame grid.
"""

from __future__ import annotations

import base64
import json
import math
from functools import cache

import numpy as np

from app.exports._archive import ZipBuilder, safe_stem
from app.exports._core import ExportContext, ExportResult, require_planned

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


def _beta(tau: np.ndarray) -> np.ndarray:
    return tau**3 * (10.0 + tau * (-15.0 + 6.0 * tau))


def _beta_d(tau: np.ndarray) -> np.ndarray:
    return 30.0 * tau**2 * (1.0 - tau) ** 2


@cache
def hermite_pieces(n: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Cubic Bézier ordinates approximating β on n equal pieces of [0, 1].

    Returns:
        ``ends`` (n,) β at each piece's end, ``controls`` (n, 2) the two inner
        Bézier ordinates, and the largest |cubic - β| over [0, 1]
        (dimensionless: multiply by the move length for metres).
    """
    a = np.arange(n) / n
    b = np.arange(1, n + 1) / n
    h = 1.0 / n
    b0, b3 = _beta(a), _beta(b)
    b1 = b0 + h * _beta_d(a) / 3.0
    b2 = b3 - h * _beta_d(b) / 3.0
    u = np.linspace(0.0, 1.0, 129)[None, :]
    cubic = (
        (1 - u) ** 3 * b0[:, None] + 3 * (1 - u) ** 2 * u * b1[:, None] + 3 * (1 - u) * u**2 * b2[:, None]
        + u**3 * b3[:, None]
    )
    err = float(np.abs(cubic - _beta(a[:, None] + u * h)).max())
    return b3, np.stack([b1, b2], axis=1), err


def pieces_for(length_m: float, tolerance_m: float = TOLERANCE_M) -> int:
    """Smallest n with ``length_m`` × (Hermite error of n pieces) <= ``tolerance_m``."""
    if length_m <= 0:
        return 1
    # Hermite cubic error <= h⁴/384·max|β''''| = 360/384·h⁴: start there, then confirm numerically.
    n = max(1, math.ceil((360.0 / 384.0 * length_m / tolerance_m) ** 0.25) - 1)
    while hermite_pieces(n)[2] * length_m > tolerance_m:
        n += 1
    return n


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
    """Per-drone (times, positions, controls, has_controls) after merging constant runs."""
    times = plan.knot_times_s
    P = plan.knot_positions_m
    n = plan.drone_count
    t_parts, p_parts, c_parts, has_parts, move_parts = [], [], [], [], []
    for k, seg in enumerate(plan.segments):
        T = times[k + 1] - times[k]
        if not T > 0:
            continue
        dp = P[k + 1] - P[k]
        lengths = np.linalg.norm(dp, axis=1)
        moving = lengths > 0
        m = 1 if seg.kind == "hold" or not moving.any() else pieces_for(float(lengths.max()))
        ends, ctrl, _ = hermite_pieces(m)
        t_parts.append(np.broadcast_to(times[k] + T * np.arange(1, m + 1) / m, (n, m)))
        p_parts.append(P[k][:, None, :] + ends[None, :, None] * dp[:, None, :])  # (n, m, 3)
        c_parts.append(P[k][:, None, None, :] + ctrl[None, :, :, None] * dp[:, None, None, :])  # (n, m, 2, 3)
        # A drone at rest in this segment keeps only the segment's last point, without controls.
        keep = np.ones((n, m), bool)
        keep[~moving, :-1] = False
        has_parts.append(np.broadcast_to(moving[:, None], (n, m)))
        move_parts.append(keep)
    t_all = np.concatenate(t_parts, axis=1)
    p_all = np.concatenate(p_parts, axis=1)
    c_all = np.concatenate(c_parts, axis=1)
    has_all = np.concatenate(has_parts, axis=1)
    keep_all = np.concatenate(move_parts, axis=1)
    out_t, out_p, out_c, out_h = [], [], [], []
    for i in range(n):
        kt = keep_all[i]
        t, p, c, h = t_all[i, kt], p_all[i, kt], c_all[i, kt], has_all[i, kt]
        # Point j is redundant if it and the next are both constant (no controls): the line stays still.
        static = ~h
        drop = np.zeros(len(t), bool)
        drop[:-1] = static[:-1] & static[1:]
        sel = ~drop
        out_t.append(t[sel])
        out_p.append(p[sel])
        out_c.append(c[sel])
        out_h.append(h[sel])
    return out_t, out_p, out_c, out_h


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
    drones = []
    for i in range(plan.drone_count):
        t = np.round(times[i], _TIME_DECIMALS).tolist()
        p = (np.round(positions[i], _POS_DECIMALS) + 0.0).tolist()
        c = (np.round(controls[i], _POS_DECIMALS) + 0.0).tolist()
        h = has[i].tolist()
        points = [[0.0, home[i].tolist(), []]]
        points += [[tj, pj, cj if hj else []] for tj, pj, cj, hj in zip(t, p, c, h, strict=True)]
        lights = base64.b64encode(light_program(frames, colors[:, i])).decode("ascii")
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
    z.add("show.json", json.dumps(doc, separators=(",", ":"), allow_nan=False))
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}.skyc",
        media_type="application/zip",
        content=z.finish(),
    )
