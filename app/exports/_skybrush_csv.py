"""``skybrush-csv``: a zip with one CSV per drone, as Skybrush Studio's CSV importer reads it.

Each file (``drone_001.csv``, ...; names made of ``[A-Za-z0-9.+-]`` and the
``_`` that Skybrush's own exporter substitutes for anything else) starts with the header
``Time [msec],x [m],y [m],z [m],Red,Green,Blue`` followed by one row per frame:
integer milliseconds from 0, positions in metres with 3 decimals, LED colour
channels 0-255. Frames are at ``--fps`` plus the last instant of the show;
positions are the plan's exact positions at each row's time stamp. Frame: the
show's local x, y, z unchanged (Skybrush X, Y, Z; see :mod:`app.exports._frames`).

Defaults chosen for Studio's importer ("Import Skybrush zipped CSV",
``parse_compressed_csv_zip``), which (1) resamples each drone linearly onto the
Blender frame grid ``arange(first, last, 1/fps)``, (2) holds each row's colour
until the next row's frame in the light-effect image, and (3) leaves out the last
instant (``arange`` stops before it):

* :data:`DEFAULT_FPS` = 24, Blender's default frame rate: one row per Blender frame,
  so colour fades import as per-frame fades rather than steps, and straight lines
  between rows stay within a millimetre of the plan (chord error a·Δt²/8 <= 0.9 mm
  at 4 m/s²); shows too large for 24 fps within the sample budget get the highest
  rate that fits, with a warning giving the resulting accuracy.
* one extra row one frame after the end, holding the final position and colour, so
  the resampled grid reaches the end of the show (the drone lands in Studio).

The archive holds nothing but the CSVs: Skybrush Studio's importers read every
member as a drone (the file stem becomes its name), so the manifest (show,
duration, fps, source) is stored as the zip comment. Format as written by
Skybrush Studio for Blender's own CSV exporter (``export_to_csv.py``).
"""

from __future__ import annotations

import numpy as np

from app.exports._archive import ZipBuilder, base_manifest, safe_stem
from app.exports._core import ExportContext, ExportResult
from app.exports._sampling import check_sample_count, default_fps, frame_count, sample_times_ms, write_sample_csvs
from app.exports._text import column_bytes

HEADER = "Time [msec],x [m],y [m],z [m],Red,Green,Blue\n"
#: Blender's default scene frame rate: one CSV row per frame Studio imports.
DEFAULT_FPS = 24.0


def export_skybrush_csv(ctx: ExportContext) -> ExportResult:
    """Build the Skybrush CSV zip (see the module docstring)."""
    fps = ctx.options.fps if ctx.options.fps is not None else default_fps(ctx, DEFAULT_FPS, extra_rows=1)
    duration = ctx.plan.duration_s
    check_sample_count(ctx, frame_count(duration, fps) + 1)  # before any array is built
    times_ms = sample_times_ms(duration, fps)
    # Studio resamples on arange(first, last, 1/fps), which stops before the last row:
    # a row one frame after the end, holding the final state, keeps the end in.
    times_ms = np.append(times_ms, times_ms[-1] + max(1, round(1000.0 / fps)))
    z = ZipBuilder()
    write_sample_csvs(
        ctx, z, times_s=np.minimum(times_ms / 1000.0, duration), time_column=column_bytes(times_ms, 0),
        header=HEADER.encode(),
    )
    # Skybrush Studio's importers parse every member of the zip as a drone, so the
    # manifest goes into the archive comment instead of a file.
    z.set_comment(
        base_manifest(ctx, fmt="skybrush-csv", fps=fps, source=ctx.options.source,
                      columns=HEADER.strip().split(","),
                      last_row="one frame after the end, holding the final state (Studio drops the last row)",
                      **({"flight": ctx.flight_summary()} if ctx.options.source == "simulated" else {}))
    )
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}-skybrush.zip",
        media_type="application/zip",
        content=z.finish(),
    )
