"""Self-contained HTML playback of a show, built with viser's scene serializer.

viser records scene messages through ``server.get_scene_serializer()``: the
current scene is snapshotted, every later scene update is appended with the
recording clock, and ``insert_sleep`` advances that clock. ``as_html()`` then
zstd-compresses the msgpack recording, base64-encodes it into
``window.__VISER_EMBED_DATA__`` and injects it into viser's client build,
which is one ``index.html`` with every script, style and asset inlined. The
client, seeing embedded data, plays it with its own play/pause, speed and
scrub bar, looping at the end; it needs no server and nothing from the
internet, so the file opens from ``file://``.

Size: each keyframe carries the drones' positions (float16, 6 bytes/drone:
the show is centred on the origin first, so float16's relative precision gives
about 3 cm at 60 m) and, only when they change, their colours (uint8, 3
bytes/drone). A 1000-drone, 3-minute show at the default 15 keyframes/s is
2700 x 6 kB before compression; zstd and base64 bring it to about 11 MB of
HTML (a 5-minute one measured 18 MB), well under the 50 MB budget. Longer or
larger shows get a lower keyframe rate automatically (``RAW_BUDGET_BYTES``).
"""

from __future__ import annotations

import contextlib
import io
from typing import Any

import numpy as np
import viser

from app.exports._archive import safe_stem
from app.exports._core import ExportContext, ExportError, ExportResult
from app.exports._media import html_with_audio
from app.exports._tracks import framing_camera, make_track, show_bounds
from sim import ShowPlan
from sim.geometry import closest_pair

#: Default keyframe rate of the export, frames per second.
DEFAULT_EXPORT_FPS = 15.0
#: Budget for the positions and colours recorded, bytes (before compression and base64).
RAW_BUDGET_BYTES = 60_000_000
#: Most keyframes of one export: each costs about 0.4 ms of scene serialisation whatever the drone
#: count (fps=100 on a 2,500 s show took 97 s), so the frame count is budgeted as well as the bytes.
MAX_KEYFRAMES = 20_000
DARK_LED_FLOOR = 0.2


class ExportBudgetError(ValueError):
    """The requested keyframe rate would exceed the export's byte or keyframe budget."""


def _auto_fps(drones: int, duration_s: float, requested: float | None) -> float:
    """The requested rate (refused when over the budget), or the default lowered to fit it.

    Raises:
        ExportBudgetError: ``requested`` would record more than :data:`RAW_BUDGET_BYTES` or
            :data:`MAX_KEYFRAMES`.
    """
    per_frame = max(drones, 1) * 9.0  # float16 xyz + uint8 rgb
    span_s = max(duration_s, 1e-3)
    fit = min(RAW_BUDGET_BYTES / (per_frame * span_s), (MAX_KEYFRAMES - 2) / span_s)
    if requested is not None:
        if not requested > 0:
            raise ExportBudgetError(f"fps must be > 0, got {requested}")
        if requested > fit:
            raise ExportBudgetError(
                f"fps {requested:g} over {duration_s:g} s for {drones} drones exceeds the export budget "
                f"({MAX_KEYFRAMES} keyframes, {RAW_BUDGET_BYTES // 1_000_000} MB); use fps <= {fit:.3g}")
        return float(requested)
    return float(min(DEFAULT_EXPORT_FPS, fit))


def export_viser_html(
    plan: ShowPlan,
    *,
    flight: Any = None,
    source: str | None = None,
    fps: float | None = None,
    dark_mode: bool = True,
    closest_pair_line: bool = True,
    lights: Any = None,
) -> bytes:
    """A self-contained HTML page that plays the show offline in 3D.

    Args:
        plan: the show's plan.
        flight: optional simulated flight (``times_s``, ``positions_m``, ``colors_rgb``).
        source: ``"planned"`` or ``"simulated"``; default simulated when a flight is given.
        fps: keyframes per second; default 10, lowered automatically for very large shows.
        dark_mode: night-sky colours.
        closest_pair_line: also record the closest pair and its distance at each keyframe.
        lights: the show's light effects (a ``sim.light.LightStack``), painted over the colours.

    Returns:
        The HTML document, UTF-8.
    """
    src = source or ("simulated" if flight is not None else "planned")
    _auto_fps(plan.drone_count, plan.duration_s, fps)  # refuse an over-budget rate before any work
    track = make_track(plan, flight, src, lights)  # type: ignore[arg-type]
    rate = _auto_fps(track.drone_count, track.duration_s, fps)
    times = np.arange(int(np.floor(track.duration_s * rate + 1e-9)) + 1) / rate
    if times[-1] < track.duration_s:
        times = np.append(times, track.duration_s)

    lo, hi = show_bounds(plan, flight)
    # Recorded positions are relative to the show's centre (float16 is relative
    # precision), and the drones' node is placed at the centre.
    center = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2])
    spacing = float(plan.settings.min_distance_m)

    # viser prints a banner on start; an export is a library call, keep stdout clean.
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        scene = server.scene
        scene.set_up_direction("+z")
        span = float(np.max(hi[:2] - lo[:2])) + 40.0
        size = 50.0 * np.ceil(span / 50.0)
        scene.add_grid(
            "/ground", width=size, height=size, plane="xy", cell_size=5.0, section_size=50.0,
            cell_color=(60, 60, 70), section_color=(110, 110, 125), shadow_opacity=0.0,
            position=(float(center[0]), float(center[1]), 0.0),
        )
        scene.add_point_cloud(
            "/home_grid", plan.knot_positions_m[0].astype(np.float32), (90, 90, 100),
            point_size=0.25 * spacing, point_shape="square", precision="float32",
        )
        position, look_at = framing_camera(lo, hi, fov_rad=server.initial_camera.fov)
        server.initial_camera.far = 5000.0
        server.initial_camera.position = tuple(position)
        server.initial_camera.look_at = tuple(look_at)

        first = track.frame(0.0)  # the scene snapshot the recording starts from
        drones = scene.add_point_cloud(
            "/drones", (first.positions_m - center).astype(np.float16),
            _led_uint8(first.colors_rgb), point_size=float(np.clip(0.45 * spacing, 0.5, 2.5)),
            point_shape="circle", precision="float16", position=tuple(center),
        )
        pair_line = label = None
        if closest_pair_line and track.drone_count >= 2:
            pair_line = scene.add_line_segments(
                "/closest_pair/line", np.zeros((1, 2, 3), np.float32), (255, 60, 60),
                thickness=3.0, thickness_units="screen",
            )
            label = scene.add_label("/closest_pair/label", "", anchor="bottom-center")

        serializer = server.get_scene_serializer()
        hint: float | None = None
        chunk = max(1, 4_000_000 // max(track.drone_count, 1))  # ~100 MB of float64 per batch
        for c0 in range(0, len(times), chunk):
            batch = times[c0:c0 + chunk]
            positions, colors, speeds = track.sample(batch)
            relative = (positions - center).astype(np.float16)
            leds = _led_uint8(colors)
            for k, t in enumerate(batch):
                drones.points = relative[k]
                drones.colors = leds[k]  # unchanged colours send nothing
                if pair_line is not None and label is not None:
                    # Bound on the closest distance from the previous keyframe (see Viewer.render).
                    bound = None if hint is None else hint * 1.01 + 2.0 * speeds[k] / rate + 1e-3
                    i, j, d = closest_pair(positions[k], hint_m=bound)
                    hint = d
                    ends = positions[k, [i, j]]
                    pair_line.points = ends[None].astype(np.float32)
                    label.text = f"{d:.2f} m"
                    label.position = tuple(ends.mean(axis=0) + [0.0, 0.0, 1.0])
                if c0 + k + 1 < len(times):
                    serializer.insert_sleep(float(times[c0 + k + 1] - t))
        html = serializer.as_html(dark_mode=dark_mode)
    finally:
        with contextlib.redirect_stdout(io.StringIO()):
            server.stop()
    return html.encode("utf-8")


def _led_uint8(colors_rgb: np.ndarray) -> np.ndarray:
    """LED colours as uint8, unlit ones lifted to a visible grey."""
    return (np.clip(DARK_LED_FLOOR + (1.0 - DARK_LED_FLOOR) * colors_rgb, 0.0, 1.0) * 255.0).astype(np.uint8)


def export_viser_html_file(ctx: ExportContext) -> ExportResult:
    """``viser-html`` entry of :data:`app.exports.EXPORT_FORMATS`: an ``ExportContext`` -> ``ExportResult``."""
    options = ctx.options
    flight = ctx.flight if options.source == "simulated" else None
    ctx.progress(0.8 if flight is not None else 0.1)
    try:
        from sim.light import LightStack

        html = export_viser_html(ctx.plan, flight=flight, source=options.source, fps=options.fps,
                                 lights=LightStack.from_show(ctx.show, ctx.plan))
    except ExportBudgetError as exc:
        raise ExportError(str(exc)) from None
    html = html_with_audio(html, options.audio)  # issue 18: the music plays with the recording
    ctx.progress(1.0)
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}.html",
        media_type="text/html; charset=utf-8",
        content=html,
        warnings=list(ctx.warnings),
    )


__all__ = ["DEFAULT_EXPORT_FPS", "MAX_KEYFRAMES", "ExportBudgetError", "export_viser_html", "export_viser_html_file"]
