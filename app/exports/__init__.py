"""Exports that real drone tools load: show JSON, Skybrush CSV and ``.skyc``,
Crazyswarm polynomial trajectories, QGroundControl missions, sampled waypoints.

Tracks (:class:`PlanTrack`, :class:`FlightTrack`) sample the plan or the flown
flight at any time; the live viewer (``app.viewer``) plays them and the
``viser-html`` format records them into a self-contained HTML file.

Formats are registered in :data:`EXPORT_FORMATS` (format name -> lazy
``"module:function"``); an exporter takes an :class:`ExportContext` and returns
an :class:`ExportResult`. :func:`export_show` is the entry point.
:func:`render_safety_report` draws a Monte-Carlo result (``sim.flight.monte_carlo``) as
HTML or PDF.
"""

from __future__ import annotations

from app.exports._archive import drone_file_stems as drone_file_stems
from app.exports._archive import safe_stem as safe_stem
from app.exports._core import MAX_HEADING_DEG as MAX_HEADING_DEG
from app.exports._core import ExportContext as ExportContext
from app.exports._core import ExportError as ExportError
from app.exports._core import ExportOptions as ExportOptions
from app.exports._core import ExportResult as ExportResult
from app.exports._core import check_heading as check_heading
from app.exports._core import parse_origin as parse_origin
from app.exports._formats import EXPORT_FORMATS as EXPORT_FORMATS
from app.exports._formats import check_export_options as check_export_options
from app.exports._formats import export_plan as export_plan
from app.exports._formats import export_show as export_show
from app.exports._safety_report import REPORT_FORMATS as REPORT_FORMATS
from app.exports._safety_report import render_safety_report as render_safety_report
from app.exports._tracks import FlightTrack as FlightTrack
from app.exports._tracks import Frame as Frame
from app.exports._tracks import PlanTrack as PlanTrack
from app.exports._tracks import Source as Source
from app.exports._tracks import Track as Track
from app.exports._tracks import framing_camera as framing_camera
from app.exports._tracks import make_track as make_track
from app.exports._tracks import show_bounds as show_bounds

__all__ = [
    "MAX_HEADING_DEG",
    "check_heading",
    "check_export_options",
    "parse_origin",
    "EXPORT_FORMATS",
    "REPORT_FORMATS",
    "render_safety_report",
    "FlightTrack",
    "Frame",
    "PlanTrack",
    "Source",
    "Track",
    "framing_camera",
    "make_track",
    "show_bounds",
    "ExportContext",
    "ExportError",
    "ExportOptions",
    "ExportResult",
    "drone_file_stems",
    "export_plan",
    "export_show",
    "safe_stem",
]
