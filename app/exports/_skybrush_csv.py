"""``skybrush-csv``: a zip with one CSV per drone, as Skybrush Studio's CSV importer reads it.

Each file (``drone_001.csv``, ...; names made of ``[A-Za-z0-9.+-]`` and the
``_`` that Skybrush's own exporter substitutes for anything else) starts with the header
``Time [msec],x [m],y [m],z [m],Red,Green,Blue`` followed by one row per frame:
integer milliseconds from 0, positions in metres with 3 decimals, LED colour
channels 0-255. Frames are at ``--fps`` (default 4) plus the last instant of
the show; positions are the plan's exact positions at each row's time stamp.

The archive holds nothing but the CSVs: Skybrush Studio's importers read every
member as a drone (the file stem becomes its name), so the manifest (show,
duration, fps, source) is stored as the zip comment. Format as written by
Skybrush Studio for Blender's own CSV exporter (``export_to_csv.py``).
"""

from __future__ import annotations

from app.exports._archive import ZipBuilder, base_manifest, safe_stem
from app.exports._core import ExportContext, ExportResult
from app.exports._sampling import check_sample_count, frame_count, sample_times_ms, write_sample_csvs
from app.exports._text import column_bytes

HEADER = "Time [msec],x [m],y [m],z [m],Red,Green,Blue\n"
DEFAULT_FPS = 4.0


def export_skybrush_csv(ctx: ExportContext) -> ExportResult:
    """Build the Skybrush CSV zip (see the module docstring)."""
    fps = ctx.options.fps_or(DEFAULT_FPS)
    check_sample_count(ctx, frame_count(ctx.plan.duration_s, fps))  # before any array is built
    times_ms = sample_times_ms(ctx.plan.duration_s, fps)
    z = ZipBuilder()
    write_sample_csvs(
        ctx, z, times_s=times_ms / 1000.0, time_column=column_bytes(times_ms, 0), header=HEADER.encode()
    )
    # Skybrush Studio's importers parse every member of the zip as a drone CSV, so the
    # manifest goes into the archive comment instead of a file.
    z.set_comment(
        base_manifest(ctx, fmt="skybrush-csv", fps=fps, source=ctx.options.source, columns=HEADER.strip().split(","))
    )
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}-skybrush.zip",
        media_type="application/zip",
        content=z.finish(),
    )
