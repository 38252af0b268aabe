"""``waypoints-csv``: a zip with one ``t,x,y,z,r,g,b`` CSV per drone, sampled at ``--fps``.

``t`` in seconds (3 decimals: the sample times are whole milliseconds), x, y, z
local metres (3 decimals; the frame of :mod:`app.exports._frames`: +y at the
heading), r, g, b LED channels 0-255. Samples come from
the plan (``--source planned``, exact at each row) or from the simulated
flight (``--source simulated``, the flown positions linearly interpolated
from the 1 kHz simulation: the single flight of ``--preset`` and ``--seed``, default calm-rtk, seed 0).
"""

from __future__ import annotations

from app.exports._archive import ZipBuilder, base_manifest, safe_stem
from app.exports._core import ExportContext, ExportResult
from app.exports._sampling import check_sample_count, default_fps, frame_count, sample_times_ms, write_sample_csvs
from app.exports._text import column_bytes

HEADER = "t,x,y,z,r,g,b\n"
DEFAULT_FPS = 10.0

_README = """\
Per-drone waypoints (one CSV per drone) made by swarmshow.

Columns: t (seconds from the start of the show), x, y, z (local metres from
the show origin, z up; +y at bearing {heading:g} degrees from true north, so x
east and y north when it is 0), r, g, b (LED colour, 0-255). {fps:g} samples
per second plus the final instant, from the {source} trajectory.
"""


def export_waypoints_csv(ctx: ExportContext) -> ExportResult:
    """Build the sampled waypoint zip (see the module docstring)."""
    fps = ctx.options.fps if ctx.options.fps is not None else default_fps(ctx, DEFAULT_FPS)
    check_sample_count(ctx, frame_count(ctx.plan.duration_s, fps))  # before flying or building any array
    if ctx.options.source == "simulated":
        _ = ctx.flight  # fly first, so progress and errors come before any writing
    times_ms = sample_times_ms(ctx.plan.duration_s, fps)
    z = ZipBuilder()
    write_sample_csvs(
        ctx,
        z,
        times_s=times_ms / 1000.0,
        time_column=column_bytes(times_ms / 1000.0, 3),
        header=HEADER.encode(),
        progress_from=0.8 if ctx.options.source == "simulated" else 0.1,
    )
    extra = {}
    if ctx.options.source == "simulated":
        extra["flight"] = ctx.flight_summary()
    z.add_manifest(
        base_manifest(
            ctx, fmt="waypoints-csv", fps=fps, source=ctx.options.source, columns=HEADER.strip().split(","), **extra
        ),
        _README.format(fps=fps, source=ctx.options.source, heading=ctx.options.heading_deg),
    )
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}-waypoints.zip",
        media_type="application/zip",
        content=z.finish(),
    )
