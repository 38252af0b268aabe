"""What every format shares: the options, the result, and the context an exporter gets.

The context hands the exporter the show, the validated options, and the plan
and simulated flight, both computed on first use (the ``show`` format needs
neither; only ``--source simulated`` needs the flight). The registry of formats
and :func:`export_show` live one layer up, in :mod:`app.exports._formats`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from formations import MAX_ORIGIN_ALT_M, MIN_ORIGIN_ALT_M

if TYPE_CHECKING:
    from app.media import AudioTrack
    from formations import ShowFile
    from sim import ShowPlan

ProgressFn = Callable[[float], None]
Source = Literal["planned", "simulated"]

#: Highest sampling rate accepted, frames per second (a flight controller rarely wants more).
MAX_FPS = 1000.0
#: Most (drone, time) samples one sampled export may hold: writing a sample costs about 2 us (waypoints
#: CSV), so 4 M keep an export under about 10 s of CPU (it allowed 200 M, minutes and gigabytes).
MAX_SAMPLES = 4_000_000
#: Largest position scale factor accepted (``crazyswarm``).
MAX_SCALE = 10.0
#: Largest position offset accepted, metres per axis (``crazyswarm``).
MAX_OFFSET_M = 10_000.0
#: Largest flight seed (the API's simulation seed bound, ``app.api.models.MAX_SEED``).
MAX_SEED = 2**31 - 1
#: The error-model presets a flown export can fly and a single flight's default one (copied from
#: ``sim.flight.PRESETS`` / ``DEFAULT_FLIGHT_PRESET`` so that validating options does not import the
#: simulation; a test keeps them equal).
FLIGHT_PRESETS: tuple[str, ...] = ("ideal", "calm-rtk", "gusty-rtk", "gps-only")
DEFAULT_FLIGHT_PRESET = "calm-rtk"
#: ``sim.flight.CONTROLLERS`` / ``DISTURBANCES`` (copied for the same reason; the same test keeps them equal).
FLIGHT_CONTROLLERS: tuple[str, ...] = ("ismc", "baseline")
FLIGHT_DISTURBANCES: tuple[str, ...] = ("none", "paper", "wind")

#: Which formats take the options that only some formats use. A format given one it does not use refuses
#: it (``ExportError`` naming the option) rather than drop it without a word: a show "scaled for indoors"
#: written at full size, a "simulated" file holding the plan. The CLI, the API and the editor
#: (``frontend/js/exportcheck.js``; a test keeps them equal) read these.
SCALING_FORMATS: tuple[str, ...] = ("crazyswarm",)
FLOWN_FORMATS: tuple[str, ...] = ("skybrush-csv", "waypoints-csv", "viser-html")
#: Formats that sample the trajectories at ``fps`` (the others hold them exactly: polynomials, Bézier curves,
#: waypoints where the plan rests).
SAMPLED_FORMATS: tuple[str, ...] = ("skybrush-csv", "waypoints-csv", "viser-html")
AUDIO_FORMATS: tuple[str, ...] = ("skyc", "viser-html")
#: Formats that place the show on Earth at ``origin`` (the .skyc's location, QGroundControl's WGS84 waypoints);
#: the others hold local metres and refuse an origin given to them (the stored ``settings.geo`` is not given).
ORIGIN_FORMATS: tuple[str, ...] = ("skyc", "qgc-plan", "qgc-wpl")


class ExportError(ValueError):
    """An export cannot be made as asked (bad option, unknown format, unplannable show).

    The message is one line meant for the user; the API maps it to HTTP 422 naming
    ``field`` (the option at fault, e.g. ``"origin"``; None when it is the show itself)
    and the command line to exit code 2.
    """

    def __init__(self, message: str, *, field: str | None = None) -> None:
        super().__init__(message)
        self.field = field


@dataclass(frozen=True)
class ExportOptions:
    """Options shared by the formats (each format reads the ones it needs).

    Attributes:
        fps: sampling rate of the sampled formats, frames per second; ``None``
            means the format's default (4 for ``skybrush-csv``, 10 for
            ``waypoints-csv``).
        origin: ``(latitude_deg, longitude_deg, altitude_m)`` of the show's
            local origin (x = y = z = 0) on WGS84; needed by ``qgc-plan`` and
            ``qgc-wpl``.
        heading_deg: compass bearing of the show's +y axis, degrees clockwise
            from true north (0: +y points north, +x east).
        source: ``"planned"`` (the exact plan) or ``"simulated"`` (the flown
            trajectory of the flight simulation; sampled formats only).
        audio: the show's music (``.skyc`` and ``viser-html`` embed it; issue 18).
        scale: factor applied to every position (``crazyswarm``: fly an outdoor
            show indoors, e.g. 0.02), in (0, 10]; times are kept, speeds scale with it.
        offset_m: (x, y, z) metres added after scaling (``crazyswarm``: where the
            show's origin lies in the motion-capture frame).
        preset: with ``source="simulated"``, the error-model preset of the flight (one of
            :data:`FLIGHT_PRESETS`; ``None``: :data:`DEFAULT_FLIGHT_PRESET`), as the single flight
            ``sim.flight.single_flight_options(preset, ...)`` the editor's simulation panel flies.
        seed: with ``source="simulated"``, the flight's seed (``None``: 0): Monte-Carlo run ``k`` of
            ``seed0`` with ``seed0 + k == seed``.
        controller: with ``source="simulated"``, the flight's controller (one of :data:`FLIGHT_CONTROLLERS`;
            ``None``: ``"ismc"``), as the simulation panel's.
        disturbance: with ``source="simulated"``, the fleet-wide disturbance (one of
            :data:`FLIGHT_DISTURBANCES`; ``None``: ``"none"``); only with preset ``"ideal"``, which it implies
            when no preset is given (as ``app.api.models.SimulateOptions``).
    """

    fps: float | None = None
    origin: tuple[float, float, float] | None = None
    heading_deg: float = 0.0
    source: Source = "planned"
    audio: AudioTrack | None = None
    scale: float = 1.0
    offset_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    preset: str | None = None
    seed: int | None = None
    controller: str | None = None
    disturbance: str | None = None

    def __post_init__(self) -> None:
        if self.fps is not None:
            fps = _number(self.fps, "fps")
            if not 0 < fps <= MAX_FPS:
                raise ExportError(f"fps must be in (0, {MAX_FPS:g}], got {self.fps!r}", field="fps")
            object.__setattr__(self, "fps", fps)
        if self.origin is not None:
            try:
                lat, lon, alt = (float(v) for v in self.origin)
            except (TypeError, ValueError) as exc:
                raise ExportError(f"origin must be (latitude, longitude, altitude), got {self.origin!r}",
                                  field="origin") from exc
            if not all(math.isfinite(v) for v in (lat, lon, alt)):
                raise ExportError(f"origin must be finite, got {self.origin!r}", field="origin")
            if not -90.0 <= lat <= 90.0:
                raise ExportError(f"origin latitude must be in [-90, 90] degrees, got {lat}", field="origin")
            if not -180.0 <= lon <= 180.0:
                raise ExportError(f"origin longitude must be in [-180, 180] degrees, got {lon}", field="origin")
            if not MIN_ORIGIN_ALT_M <= alt <= MAX_ORIGIN_ALT_M:
                # The show file's own bounds (settings.geo.origin_alt_m): one place on Earth, one range.
                raise ExportError(f"origin altitude must be in [{MIN_ORIGIN_ALT_M:g}, {MAX_ORIGIN_ALT_M:g}] m "
                                  f"(as the show file's settings.geo.origin_alt_m), got {alt:g}", field="origin")
            object.__setattr__(self, "origin", (lat, lon, alt))
        heading = check_heading(self.heading_deg)
        object.__setattr__(self, "heading_deg", heading % 360.0)
        scale = _number(self.scale, "scale")
        if not 0.0 < scale <= MAX_SCALE:
            raise ExportError(f"scale must be in (0, {MAX_SCALE:g}], got {self.scale!r}", field="scale")
        object.__setattr__(self, "scale", scale)
        try:
            offset = tuple(_number(v, "offset") for v in self.offset_m)
        except TypeError as exc:
            raise ExportError(f"offset must be (x, y, z) metres, got {self.offset_m!r}", field="offset") from exc
        if len(offset) != 3 or max(abs(v) for v in offset) > MAX_OFFSET_M:
            raise ExportError(f"offset must be three numbers (x, y, z) within +-{MAX_OFFSET_M:g} m, "
                              f"got {self.offset_m!r}", field="offset")
        object.__setattr__(self, "offset_m", offset)
        if self.source not in ("planned", "simulated"):
            raise ExportError(f"source must be 'planned' or 'simulated', got {self.source!r}", field="source")
        self._check_flight()

    def _check_flight(self) -> None:
        """The flight's preset and seed: known, in range, and only for a flown (simulated) source."""
        for name, value in (("preset", self.preset), ("seed", self.seed), ("controller", self.controller),
                            ("disturbance", self.disturbance)):
            if value is not None and self.source != "simulated":
                raise ExportError(f"{name} chooses the simulated flight; it is only used with source 'simulated'",
                                  field=name)
        if self.preset is not None and self.preset not in FLIGHT_PRESETS:
            raise ExportError(f"preset must be one of {', '.join(FLIGHT_PRESETS)}, got {self.preset!r}",
                              field="preset")
        for name, value, known in (("controller", self.controller, FLIGHT_CONTROLLERS),
                                   ("disturbance", self.disturbance, FLIGHT_DISTURBANCES)):
            if value is not None and value not in known:
                raise ExportError(f"{name} must be one of {', '.join(known)}, got {value!r}", field=name)
        if self.disturbance not in (None, "none") and self.preset not in (None, "ideal"):
            raise ExportError(f"disturbance {self.disturbance!r} goes only with preset 'ideal': preset "
                              f"{self.preset!r} brings its own wind field", field="disturbance")
        if self.seed is not None:
            if isinstance(self.seed, bool) or not isinstance(self.seed, int | np.integer):
                raise ExportError(f"seed must be a whole number, got {self.seed!r}", field="seed")
            if not 0 <= self.seed <= MAX_SEED:
                raise ExportError(f"seed must be in [0, {MAX_SEED}], got {self.seed!r}", field="seed")
            object.__setattr__(self, "seed", int(self.seed))

    @property
    def flight_preset(self) -> str:
        """The error-model preset a flown export flies (:data:`DEFAULT_FLIGHT_PRESET` unless chosen)."""
        if self.preset is not None:
            return self.preset
        # A disturbance without a preset flies the ideal vehicle in it (as the simulation's request does).
        return "ideal" if self.disturbance not in (None, "none") else DEFAULT_FLIGHT_PRESET

    @property
    def flight_seed(self) -> int:
        """The seed a flown export flies (0 unless chosen)."""
        return self.seed if self.seed is not None else 0

    def fps_or(self, default: float) -> float:
        """``fps`` if given, else ``default`` (frames per second)."""
        return float(self.fps) if self.fps is not None else float(default)


#: Largest |heading_deg| an export takes, degrees (the API's query bound too): a bearing beyond a full turn
#: either way is a typo (400 for 40), not a direction.
MAX_HEADING_DEG = 360.0
#: Altitude of an origin given as 'latitude,longitude' alone, metres (the API's default as well).
DEFAULT_ORIGIN_ALT_M = 0.0
#: How an origin is written on the command line and in the API's query.
ORIGIN_SYNTAX = "'latitude,longitude' or 'latitude,longitude,altitude_m'"


#: Formats that ignore ``heading_deg``: the show file keeps its heading in ``settings.geo``.
HEADINGLESS_FORMATS: tuple[str, ...] = ("show",)


def check_unused_options(fmt: str, *, scale: bool = False, offset: bool = False, fps: bool = False,
                         origin: bool = False, heading: bool = False) -> None:
    """Refuse an option given to a format that does not use it (each flag: given, and for ``scale`` / ``offset``
    not the identity): ``scale`` / ``offset`` outside :data:`SCALING_FORMATS`, ``fps`` outside
    :data:`SAMPLED_FORMATS`, ``origin`` outside :data:`ORIGIN_FORMATS`, ``heading`` in
    :data:`HEADINGLESS_FORMATS`. The API, the CLI and :func:`export_plan` alike.

    Raises:
        ExportError: naming the option.
    """
    if heading and fmt in HEADINGLESS_FORMATS:
        raise ExportError(f"heading_deg is not used by format {fmt!r} (the show file keeps its heading in "
                          "settings.geo); drop it", field="heading_deg")
    for name, given, users, what in (
        ("scale", scale, SCALING_FORMATS, "positions of an indoor show"),
        ("offset", offset, SCALING_FORMATS, "positions of an indoor show"),
        ("fps", fps, SAMPLED_FORMATS, "the formats that sample; the others hold the exact trajectories"),
        ("origin", origin, ORIGIN_FORMATS, "the formats that place the show on Earth; the others hold local metres"),
    ):
        if given and fmt not in users:
            raise ExportError(f"{name} is not used by format {fmt!r} (only by {', '.join(users)}: {what}); drop it",
                              field=name)


def check_heading(value: Any) -> float:
    """``value`` as a heading in degrees, within +-:data:`MAX_HEADING_DEG` (the API and the CLI share it).

    Raises:
        ExportError: not a finite number, or beyond a full turn (``field="heading_deg"``).
    """
    heading = _number(value, "heading_deg")
    if not -MAX_HEADING_DEG <= heading <= MAX_HEADING_DEG:
        raise ExportError(f"heading_deg must be in [-{MAX_HEADING_DEG:g}, {MAX_HEADING_DEG:g}] degrees, got {value!r}",
                          field="heading_deg")
    return heading


def parse_origin(text: str) -> tuple[float, float, float]:
    """An origin as text, ``"lat,lon"`` or ``"lat,lon,alt_m"``, as ``(lat, lon, alt_m)`` (altitude
    :data:`DEFAULT_ORIGIN_ALT_M` when left out): the API's ``origin`` query and the CLI's ``--origin`` alike.
    The ranges are :class:`ExportOptions`' to check.

    Raises:
        ExportError: not two or three finite numbers (``field="origin"``).
    """
    try:
        values = tuple(float(v) for v in str(text).split(","))
    except ValueError:
        values = ()
    if len(values) not in (2, 3) or not all(math.isfinite(v) for v in values):
        raise ExportError(f"origin must be {ORIGIN_SYNTAX}, got {text!r}", field="origin")
    lat, lon, *rest = values
    return lat, lon, rest[0] if rest else DEFAULT_ORIGIN_ALT_M


def _number(value: Any, name: str) -> float:
    if isinstance(value, bool):
        raise ExportError(f"{name} must be a number, got {value!r}", field=name)
    try:
        x = float(value)
    except (TypeError, ValueError) as exc:
        raise ExportError(f"{name} must be a number, got {value!r}", field=name) from exc
    if not math.isfinite(x):
        raise ExportError(f"{name} must be finite, got {value!r}", field=name)
    return x


@dataclass(frozen=True)
class ExportResult:
    """One exported file.

    Attributes:
        filename: suggested file name (sanitised: letters, digits, ``._+-``).
        media_type: MIME type of ``content``.
        content: the file's bytes.
        warnings: one-line notes for the user (for example a drone needing more
            trajectory pieces than a Crazyflie holds).
    """

    filename: str
    media_type: str
    content: bytes = field(repr=False)
    warnings: list[str] = field(default_factory=list)


class ExportContext:
    """What an exporter gets: the show, the options, and the plan / flight on demand."""

    def __init__(
        self,
        show: ShowFile,
        options: ExportOptions,
        *,
        fmt: str,
        plan: ShowPlan | None = None,
        flight: Any = None,
        drone_names: list[str] | None = None,
        progress: ProgressFn | None = None,
    ) -> None:
        self.show = show
        self.options = options
        self.fmt = fmt
        self._plan = plan
        self._flight = flight
        self._flight_given = flight is not None
        self._drone_names = drone_names
        self._names_cache: list[str] | None = None
        self._progress = progress
        self.warnings: list[str] = []

    @property
    def plan(self) -> ShowPlan:
        """The show's plan (planned on first use; a show that cannot be planned raises :class:`ExportError`)."""
        if self._plan is None:
            from sim import PlanError, cached_plan_show

            try:
                self._plan = cached_plan_show(self.show, progress=lambda f: self.progress(0.1 * f))
            except PlanError as exc:
                raise ExportError(f"the show cannot be planned: {exc}") from exc
        return self._plan

    @property
    def flight(self) -> Any:
        """The simulated flight (``sim.flight.FlightResult``), flown on first use."""
        if self._flight is None:
            from sim.flight import FlightOptions, fly_show, single_flight_options

            # Record at least as often as the export samples, so interpolation adds nothing visible.
            output_hz = min(max(self.options.fps_or(25.0), 25.0), MAX_FPS)
            progress = (lambda f: self.progress(0.8 * f)) if self._progress is not None else None
            # The single flight of the designer's preset and seed (the editor's simulation panel, ``swarmshow
            # simulate --preset P --seed S``), not the ideal vehicle: what the file holds is what they watched.
            base = FlightOptions(output_hz=output_hz, seed=self.options.flight_seed,
                                 controller=self.options.controller or "ismc",
                                 disturbance=self.options.disturbance or "none")
            options = single_flight_options(self.options.flight_preset, base)
            self._flight = fly_show(self.plan, options, progress=progress)
        return self._flight

    def flight_summary(self) -> dict[str, Any]:
        """What the flown trajectories are, for a manifest: engine, controller, disturbance, the error preset
        and seed (when this export flew it; a flight handed in says only what it carries), worst RMS tracking."""
        flight = self.flight
        out: dict[str, Any] = {
            key: getattr(flight, key) for key in ("engine", "controller", "disturbance") if hasattr(flight, key)
        }
        if not self._flight_given:
            out["preset"], out["seed"] = self.options.flight_preset, self.options.flight_seed
        rms = getattr(flight, "tracking_rms_m", None)
        if rms is not None and len(rms):
            out["worst_tracking_rms_m"] = float(max(rms))
        return out

    @property
    def drone_names(self) -> list[str]:
        """Archive-safe, unique per-drone names (``drone_001`` ... unless names were given)."""
        from app.exports._archive import drone_file_stems

        if self._names_cache is None:
            self._names_cache = drone_file_stems(self.show.drones, self._drone_names)
        return self._names_cache

    def progress(self, fraction: float) -> None:
        """Report the fraction done in [0, 1] (no-op without a callback)."""
        if self._progress is not None:
            self._progress(min(max(float(fraction), 0.0), 1.0))

    def warn(self, message: str) -> None:
        """Record a one-line warning for the result."""
        self.warnings.append(message)


def require_planned(ctx: ExportContext) -> None:
    """Refuse ``source="simulated"`` in a format that exports the exact plan."""
    check_planned(ctx.fmt, ctx.options.source)


def check_planned(fmt: str, source: str) -> None:
    """Refuse ``source`` other than ``"planned"`` for ``fmt``, a format that exports the exact plan (the API's
    ``show`` download, served without an exporter, asks this too)."""
    if source != "planned":
        raise ExportError(f"format {fmt!r} exports the exact plan; --source simulated is only for "
                          f"{', '.join(FLOWN_FORMATS)}", field="source")
