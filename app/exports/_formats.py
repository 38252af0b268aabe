"""The format registry and the entry points :func:`export_show` / :func:`export_plan`.

Every format is a function ``export(ctx: ExportContext) -> ExportResult``
registered in :data:`EXPORT_FORMATS` by a lazy ``"module:function"`` string, so
that importing :mod:`app.exports` stays cheap (viser and the flight simulation
load only when their format is asked for) and a new format is one entry. The
registry sits above the format modules (they import only :mod:`app.exports._core`),
so the lazy strings point down and form no cycle.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from app.exports._core import (
    FLOWN_FORMATS,
    ExportContext,
    ExportError,
    ExportOptions,
    ExportResult,
    ProgressFn,
    Source,
    check_planned,
    check_unused_options,
)

if TYPE_CHECKING:
    from app.media import AudioTrack
    from formations import ShowFile
    from sim import ShowPlan

#: Format name -> ``"module:function"`` of its exporter (imported on first use).
EXPORT_FORMATS: dict[str, str] = {
    "show": "app.exports._show_json:export_show_json",
    "skybrush-csv": "app.exports._skybrush_csv:export_skybrush_csv",
    "skyc": "app.exports._skyc:export_skyc",
    "crazyswarm": "app.exports._crazyswarm:export_crazyswarm",
    "qgc-plan": "app.exports._qgc:export_qgc_plan",
    "qgc-wpl": "app.exports._qgc:export_qgc_wpl",
    "waypoints-csv": "app.exports._waypoints_csv:export_waypoints_csv",
    "viser-html": "app.exports._viser_html:export_viser_html_file",
}



def check_export_options(
    fmt: str,
    *,
    fps: float | None = None,
    origin: tuple[float, float, float] | None = None,
    heading_deg: float | None = None,
    source: Source = "planned",
    scale: float = 1.0,
    offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
    preset: str | None = None,
    seed: int | None = None,
    controller: str | None = None,
    disturbance: str | None = None,
) -> None:
    """Refuse the options :func:`export_show` would refuse for ``fmt`` (the same arguments, as given), before
    any planning: an option ``fmt`` does not use (``check_unused_options``: ``scale`` 1 and a zero ``offset_m``
    are the identity, as not given), a flown ``source`` for a format of the exact plan, any value out of range
    (``ExportOptions``). The one rule for the library, the command line and the API (whose ``show`` download is
    served from the store without an exporter, and asks this).

    Raises:
        ExportError: naming the option (``field``); an unknown format (no field).
    """
    if fmt not in EXPORT_FORMATS:
        raise ExportError(f"unknown export format {fmt!r}; one of: {', '.join(EXPORT_FORMATS)}")
    check_unused_options(fmt, scale=scale != 1.0, offset=any(v != 0.0 for v in offset_m), fps=fps is not None,
                         origin=origin is not None, heading=heading_deg is not None)
    if fmt not in FLOWN_FORMATS:
        check_planned(fmt, source)
    ExportOptions(fps=fps, origin=origin, heading_deg=0.0 if heading_deg is None else heading_deg, source=source,
                  scale=scale, offset_m=offset_m, preset=preset, seed=seed, controller=controller,
                  disturbance=disturbance)


def _load_exporter(fmt: str) -> Callable[[ExportContext], ExportResult]:
    target = EXPORT_FORMATS.get(fmt)
    if target is None:
        raise ExportError(f"unknown export format {fmt!r}; one of: {', '.join(EXPORT_FORMATS)}")
    module_name, _, func_name = target.partition(":")
    return getattr(importlib.import_module(module_name), func_name)


def export_show(
    show: ShowFile,
    fmt: str,
    *,
    fps: float | None = None,
    origin: tuple[float, float, float] | None = None,
    heading_deg: float | None = None,
    source: Source = "planned",
    plan: ShowPlan | None = None,
    flight: Any = None,
    drone_names: list[str] | None = None,
    progress: ProgressFn | None = None,
    audio: AudioTrack | None = None,
    scale: float = 1.0,
    offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0),
    preset: str | None = None,
    seed: int | None = None,
    controller: str | None = None,
    disturbance: str | None = None,
) -> ExportResult:
    """Export a show in one of :data:`EXPORT_FORMATS`.

    Args:
        show: a validated show file.
        fmt: format name, a key of :data:`EXPORT_FORMATS`.
        fps: sampling rate of sampled formats, frames per second (``None``: the format's default).
        origin: ``(latitude_deg, longitude_deg, altitude_m)`` of the local origin (QGroundControl formats).
        heading_deg: bearing of the show's +y axis, degrees clockwise from true north (None: the show's
            ``settings.geo.heading_deg``, else 0). Given without an ``origin``, it turns the show about its
            stored origin (it used to be replaced by the stored heading).
        source: ``"planned"`` or ``"simulated"`` (sampled formats only).
        plan: the show's plan if already computed (else planned here).
        flight: the simulated flight if already computed (else flown here when needed).
        drone_names: optional per-drone names (sanitised for use as file names).
        progress: optional callback receiving the fraction done in [0, 1].
        audio: the show's music (``skyc`` and ``viser-html`` embed it).
        scale: factor applied to positions (``crazyswarm``, indoor shows).
        offset_m: (x, y, z) metres added after scaling (``crazyswarm``).
        preset: with ``source="simulated"``, the flight's error-model preset (None: the single flight's
            default, ``calm-rtk``); ignored when ``flight`` is given.
        seed: with ``source="simulated"``, the flight's seed (None: 0).
        controller: with ``source="simulated"``, the flight's controller (None: "ismc").
        disturbance: with ``source="simulated"`` and preset "ideal", the fleet-wide disturbance (None: none).

    Returns:
        The exported file.

    Raises:
        ExportError: unknown format, bad option, or a show that cannot be planned.
    """
    # An origin given to a format that holds local metres would be dropped without a word; the stored
    # settings.geo filled in below is the show's own and not checked.
    if fmt in EXPORT_FORMATS:  # an unknown one is export_plan's to name
        check_export_options(fmt, fps=fps, origin=origin, heading_deg=heading_deg, source=source, scale=scale,
                             offset_m=offset_m, preset=preset, seed=seed, controller=controller,
                             disturbance=disturbance)
    geo = show.settings.geo
    if origin is None and geo is not None:
        # The show's stored place on Earth, with the heading the caller gave, if any.
        origin = (geo.origin_lat_deg, geo.origin_lon_deg, geo.origin_alt_m)
        heading_deg = geo.heading_deg if heading_deg is None else heading_deg
    options = ExportOptions(fps=fps, origin=origin, heading_deg=0.0 if heading_deg is None else heading_deg,
                            source=source, audio=audio,
                            scale=scale, offset_m=offset_m, preset=preset, seed=seed, controller=controller,
                            disturbance=disturbance)
    return export_plan(
        show, fmt, options=options, plan=plan, flight=flight, drone_names=drone_names, progress=progress
    )


def export_plan(
    show: ShowFile,
    fmt: str,
    *,
    options: ExportOptions | None = None,
    plan: ShowPlan | None = None,
    flight: Any = None,
    drone_names: list[str] | None = None,
    progress: ProgressFn | None = None,
) -> ExportResult:
    """Like :func:`export_show` with the options as one :class:`ExportOptions`."""
    exporter = _load_exporter(fmt)
    options = options if options is not None else ExportOptions()
    # Dropped without a word, a show "scaled for indoors" would be written at full size.
    geo = show.settings.geo
    stored = (geo.origin_lat_deg, geo.origin_lon_deg, geo.origin_alt_m) if geo is not None else None
    check_unused_options(fmt, scale=options.scale != 1.0, offset=any(v != 0.0 for v in options.offset_m),
                         fps=options.fps is not None,
                         origin=options.origin is not None and tuple(options.origin) != stored)
    if options.origin is None and geo is not None:
        # The show's stored place on Earth, unless the caller gave an origin of its own.
        options = dataclasses.replace(
            options, origin=(geo.origin_lat_deg, geo.origin_lon_deg, geo.origin_alt_m), heading_deg=geo.heading_deg
        )
    if drone_names is not None and len(drone_names) != show.drones:
        raise ExportError(f"drone_names has {len(drone_names)} names for {show.drones} drones")
    if plan is not None and plan.drone_count != show.drones:
        raise ExportError(f"the plan has {plan.drone_count} drones, the show {show.drones}")
    ctx = ExportContext(
        show, options, fmt=fmt, plan=plan, flight=flight, drone_names=drone_names, progress=progress
    )
    result = exporter(ctx)
    ctx.progress(1.0)
    if ctx.warnings:
        result = ExportResult(
            filename=result.filename,
            media_type=result.media_type,
            content=result.content,
            warnings=[*result.warnings, *(w for w in ctx.warnings if w not in result.warnings)],
        )
    return result
