"""Exports that real drone tools load: show JSON, Skybrush CSV and ``.skyc``,
Crazyswarm polynomial trajectories, QGroundControl missions, sampled waypoints.

Formats are registered in :data:`EXPORT_FORMATS` (format name -> lazy
``"module:function"``); an exporter takes an :class:`ExportContext` and returns
an :class:`ExportResult`. :func:`export_show` is the entry point.
"""

from __future__ import annotations

from app.exports._archive import drone_file_stems as drone_file_stems
from app.exports._archive import safe_stem as safe_stem
from app.exports._core import EXPORT_FORMATS as EXPORT_FORMATS
from app.exports._core import ExportContext as ExportContext
from app.exports._core import ExportError as ExportError
from app.exports._core import ExportOptions as ExportOptions
from app.exports._core import ExportResult as ExportResult
from app.exports._core import export_plan as export_plan
from app.exports._core import export_show as export_show

__all__ = [
    "EXPORT_FORMATS",
    "ExportContext",
    "ExportError",
    "ExportOptions",
    "ExportResult",
    "drone_file_stems",
    "export_plan",
    "export_show",
    "safe_stem",
]
