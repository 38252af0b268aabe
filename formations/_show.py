"""The show file (``"format": "swarmshow/1"``): pydantic v2 models and loading.

Units: metres in ENU (x east, y north, z up), seconds, metres per second,
metres per second squared; colours ``#rrggbb``.

Structural rules (types, ranges, unknown fields, non-finite numbers) are
pydantic's; rules that relate fields to each other (point counts against the
drone count, altitudes against ``max_altitude_m``, spacing against
``min_distance_m``) run in one after-validator so that no invalid ``ShowFile``
can exist. Every rejection carries the JSON path of the offending value.
"""

from __future__ import annotations

import hashlib
import json
import re
from functools import cached_property
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    ValidationError,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from formations._effects import KINDS, TARGETS, DroneGroups, Lights, check_group_names, groups_problem, lights_problem
from formations._launch import LaunchBoxes, boxes_problem
from formations._motion import Motion, motion_problem
from formations._points import closest_pair
from formations._points import rgb_to_hex as rgb_to_hex  # one implementation, re-exported here

#: Context key of a model validator's ``PydanticCustomError`` naming the field it blames (a rule across fields
#: of one object is reported at that field, not at the object: ``settings.takeoff_altitude_m``, not ``settings``).
FIELD_CTX = "at_field"

#: Most drones a show may have. The largest show flown so far had 15,947 drones;
#: 20,000 leaves headroom while bounding memory (a 20k x 20k cost matrix is never built).
MAX_DRONES = 20_000
#: Most points one formation may hold (extra points beyond the drone count stay dark).
MAX_FORMATION_POINTS = 100_000
#: Most formations one show may hold.
MAX_FORMATIONS = 500
#: Largest show file accepted, bytes (DESIGN: 20 MB).
MAX_SHOW_FILE_BYTES = 20 * 1024 * 1024
#: Longest name (show or formation), characters.
MAX_NAME_CHARS = 200
#: Most home positions per drone (grid cells or points): landing may use any of them, so planning
#: work grows with their number; a 1-drone show with a 20,000 x 20,000 grid must not be accepted.
HOME_SLOTS_PER_DRONE = 4
#: Home positions always allowed, whatever the drone count (a 1-drone show may sit on a 4 x 4 grid).
MIN_HOME_SLOTS = 16
#: Default half-width of the show area, metres (``settings.max_horizontal_extent_m``): every point's
#: x and y lie within +-this of the origin. The exact check's work grows with the area over the
#: minimum distance; one point at x = 1e9 m made it build about 3e8 search trees.
DEFAULT_HORIZONTAL_EXTENT_M = 2_000.0
#: Highest ``settings.max_altitude_m`` a show may set, metres.
MAX_CEILING_M = 10_000.0
#: Range of the show origin's altitude above mean sea level, metres (``settings.geo.origin_alt_m``): the
#: Dead Sea shore (-430 m) to above the highest launch site; the exports' ``origin`` option shares it
#: (``app.exports``), so a place the show file refuses is not accepted as an export option either.
MIN_ORIGIN_ALT_M = -1_000.0
MAX_ORIGIN_ALT_M = 10_000.0
#: Largest show area a show file may ask for, metres (half-width).
MAX_HORIZONTAL_EXTENT_M = 20_000.0
#: Shortest hold or forced transition, seconds: a subnormal 1e-320 is "> 0" but no real duration.
MIN_DURATION_S = 0.01
#: Latest cue time a formation may be pinned to, seconds (a day).
MAX_SHOW_TIME_S = 86_400.0
#: Smallest limit values (speeds m/s, acceleration m/s^2, distances m): tinier ones turn a metre of
#: travel into years of show (and as many samples in an export).
MIN_LIMIT = 0.1

SHOW_FORMAT = "swarmshow/1"

_HEX_COLOR = re.compile(r"^#[0-9a-fA-F]{6}$")
_CONTROL_CHARS = re.compile(r"[\x00-\x1f\x7f]")

_CONFIG = ConfigDict(
    extra="forbid",
    strict=True,  # "3.0" is not a number; true is not 1
    allow_inf_nan=False,
    frozen=True,
    revalidate_instances="never",
)

Point3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Color = Annotated[str, Field(pattern=_HEX_COLOR.pattern, examples=["#ff8800"])]


class _ArrayCachingModel(BaseModel):
    """Base for models that cache numpy views in ``cached_property``.

    pydantic's ``__eq__`` compares ``__dict__``, where the cached arrays live, and an
    array comparison has no truth value; equality is defined on the fields instead.
    """

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return self.model_dump() == other.model_dump()

    __hash__ = None  # type: ignore[assignment]  # mutable-looking list fields; never hashed


def _check_name(value: str) -> str:
    if not value.strip():
        raise PydanticCustomError("name_empty", "must not be empty or blank")
    if _CONTROL_CHARS.search(value):
        raise PydanticCustomError("name_control", "must not contain control characters (NUL, newline, ...)")
    return value


Name = Annotated[str, Field(min_length=1, max_length=MAX_NAME_CHARS)]


class Geofence(BaseModel):
    """An axis-aligned horizontal box, metres in show coordinates: x in [x_min_m, x_max_m], y in [y_min_m, y_max_m].

    The audience-side no-fly zone is everything outside it (typically y < y_min_m, in front of the show).
    """

    model_config = _CONFIG

    x_min_m: float = Field(ge=-100_000, le=100_000)
    x_max_m: float = Field(ge=-100_000, le=100_000)
    y_min_m: float = Field(ge=-100_000, le=100_000)
    y_max_m: float = Field(ge=-100_000, le=100_000)

    @model_validator(mode="after")
    def _ordered(self) -> Geofence:
        if not (self.x_min_m < self.x_max_m and self.y_min_m < self.y_max_m):
            # Named by the bound that does not exceed its minimum (the first such axis).
            field = "x_max_m" if not self.x_min_m < self.x_max_m else "y_max_m"
            raise PydanticCustomError("geofence_empty", "the geofence needs x_min_m < x_max_m and y_min_m < y_max_m",
                                      {FIELD_CTX: field})
        return self


class GeoPlacement(BaseModel):
    """The show's origin on Earth (WGS84) and the compass heading of its +y axis, for geographic exports."""

    model_config = _CONFIG

    origin_lat_deg: float = Field(ge=-90, le=90, description="Latitude of the origin, degrees.")
    origin_lon_deg: float = Field(ge=-180, le=180, description="Longitude of the origin, degrees.")
    origin_alt_m: float = Field(0.0, ge=MIN_ORIGIN_ALT_M, le=MAX_ORIGIN_ALT_M,
                                description="Altitude of the origin above MSL, metres.")
    heading_deg: float = Field(0.0, ge=0, lt=360, description="Compass heading of +y, degrees clockwise from north.")


#: Vertical over horizontal semi-axis of the default downwash ellipsoid (Preiss et al. 2017: 0.3 / 0.12 m).
DOWNWASH_HEIGHT_RATIO = 2.5


class Settings(BaseModel):
    """Show-wide limits (defaults: Skybrush's, a de facto standard)."""

    model_config = _CONFIG

    min_distance_m: float = Field(3.0, ge=MIN_LIMIT, le=100,
                                  description="Minimum distance between any two drones, metres.")
    max_speed_xy_mps: float = Field(10.0, ge=MIN_LIMIT, le=100, description="Peak horizontal speed, m/s.")
    max_speed_z_mps: float = Field(2.0, ge=MIN_LIMIT, le=100, description="Peak vertical speed, m/s.")
    max_accel_mps2: float = Field(4.0, ge=MIN_LIMIT, le=100, description="Peak acceleration magnitude, m/s^2.")
    max_altitude_m: float = Field(150.0, gt=0, le=MAX_CEILING_M, description="Highest allowed altitude, metres.")
    takeoff_altitude_m: float = Field(10.0, ge=MIN_LIMIT, le=10_000,
                                      description="Altitude of the vertical takeoff, metres.")
    max_jerk_mps3: float = Field(
        10.0, ge=MIN_LIMIT, le=1000,
        description="Peak jerk of the minimum-time time law, m/s^3 (PX4's auto-mission jerk is 4-8 m/s^3).",
    )
    max_descent_speed_mps: float | None = Field(
        None, ge=MIN_LIMIT, le=100, description="Peak descent speed, m/s (default: max_speed_z_mps, as for climbing).",
    )
    time_law: Literal["min_time", "quintic"] = Field(
        "min_time",
        description="'min_time': jerk-limited minimum-time S-curve per drone (default); "
        "'quintic': the paper's shared rest-to-rest quintic.",
    )
    landing: Literal["any_home", "own_home"] = Field(
        "any_home", description="'any_home': each drone lands on the nearest free home (CAPT); "
        "'own_home': every drone lands where it took off.",
    )
    # None (left out of the file) means the default, so that shows written before this setting keep
    # their canonical JSON and content hash.
    max_horizontal_extent_m: float | None = Field(
        None, ge=1, le=MAX_HORIZONTAL_EXTENT_M,
        description=f"Half-width of the show area, metres: every x and y (home and formations) lies within "
        f"+-this of the origin (default {DEFAULT_HORIZONTAL_EXTENT_M:g}).",
    )

    # Downwash (issue 15): below a drone its rotor wash reaches further than sideways. Modelled as the
    # axis-aligned ellipsoid of Preiss, Hönig, Ayanian & Sukhatme, "Downwash-aware trajectory planning
    # for large quadrotor teams", IROS 2017: drone j is in i's downwash when
    # (dx² + dy²)/r² + dz²/c² < 1. Their Crazyflie values are r = 0.12 m, c = 0.3 m (c = 2.5 r);
    # the defaults keep that ratio at r = min_distance_m. Checked exactly during takeoff and landing.
    downwash_radius_m: float | None = Field(
        None, ge=MIN_LIMIT, le=100,
        description="Horizontal radius of the downwash ellipsoid, metres (default: min_distance_m).",
    )
    downwash_height_m: float | None = Field(
        None, ge=MIN_LIMIT, le=1000,
        description="Vertical half-height of the downwash ellipsoid, metres (default: 2.5 x its radius, "
        "Preiss et al. 2017).",
    )

    @property
    def downwash_axes_m(self) -> tuple[float, float]:
        """(horizontal radius, vertical half-height) of the downwash ellipsoid, metres, defaults applied."""
        r = self.downwash_radius_m if self.downwash_radius_m is not None else self.min_distance_m
        c = self.downwash_height_m if self.downwash_height_m is not None else DOWNWASH_HEIGHT_RATIO * r
        return float(r), float(c)

    # Issue 17: an altitude floor, a geofence and the show's place on Earth (all checked or used by name).
    min_altitude_m: float = Field(
        2.5, ge=0, le=10_000,
        description="Lowest altitude outside takeoff and landing, metres (Skybrush's minimum navigation altitude).",
    )
    geofence: Geofence | None = Field(
        None, description="Horizontal box the drones stay inside from takeoff to touchdown (the audience is outside).",
    )
    geo: GeoPlacement | None = Field(None, description="Where the show's origin is on Earth, for geographic exports.")

    @property
    def horizontal_extent_m(self) -> float:
        """``max_horizontal_extent_m``, or its default when not given."""
        return self.max_horizontal_extent_m or DEFAULT_HORIZONTAL_EXTENT_M

    @model_validator(mode="after")
    def _floor_below_ceiling(self) -> Settings:
        if self.min_altitude_m >= self.max_altitude_m:
            raise PydanticCustomError(
                "floor_above_ceiling",
                "min_altitude_m {floor} must be below max_altitude_m {ceiling}",
                {"floor": self.min_altitude_m, "ceiling": self.max_altitude_m, FIELD_CTX: "min_altitude_m"},
            )
        return self

    @model_validator(mode="after")
    def _takeoff_below_ceiling(self) -> Settings:
        if self.takeoff_altitude_m > self.max_altitude_m:
            raise PydanticCustomError(
                "takeoff_above_ceiling",
                "takeoff_altitude_m {takeoff} is above max_altitude_m {ceiling}",
                {"takeoff": self.takeoff_altitude_m, "ceiling": self.max_altitude_m, FIELD_CTX: "takeoff_altitude_m"},
            )
        return self


class HomeGrid(BaseModel):
    """A rectangular ground grid, centred on ``center_m``; drone i starts at grid cell i (row-major)."""

    model_config = _CONFIG

    rows: int = Field(ge=1, le=MAX_DRONES)
    cols: int = Field(ge=1, le=MAX_DRONES)
    spacing_m: float = Field(3.0, ge=MIN_LIMIT, le=1000, description="Grid spacing, metres.")
    center_m: Annotated[list[float], Field(min_length=2, max_length=2)] = Field(
        default_factory=lambda: [0.0, 0.0], description="Grid centre [x, y], metres."
    )

    def positions_m(self) -> np.ndarray:
        """All rows*cols grid positions, (rows*cols, 3) metres, z = 0, row-major (y then x)."""
        xs = (np.arange(self.cols) - (self.cols - 1) / 2.0) * self.spacing_m + self.center_m[0]
        ys = (np.arange(self.rows) - (self.rows - 1) / 2.0) * self.spacing_m + self.center_m[1]
        gx, gy = np.meshgrid(xs, ys)
        return np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])


class HomeFromGrid(BaseModel):
    """``{"grid": {...}}``."""

    model_config = _CONFIG
    grid: HomeGrid


class HomeFromPoints(BaseModel):
    """``{"points": [[x, y, 0], ...]}``: explicit ground positions, metres."""

    model_config = _CONFIG
    points: Annotated[list[Point3], Field(min_length=1, max_length=MAX_FORMATION_POINTS)]


class HomeFromBoxes(BaseModel):
    """``{"boxes": {...}}``: launch boxes of several drones each (:mod:`formations._launch`)."""

    model_config = _CONFIG
    boxes: LaunchBoxes


class DronesFromGroup(BaseModel):
    """``{"group": name}``: exactly the drones of the show's group ``name`` fly this formation."""

    model_config = _CONFIG
    group: str = Field(min_length=1, max_length=200)


class DronesByCount(BaseModel):
    """``{"count": n}``: n drones fly this formation; the planner picks which (CAPT-optimal)."""

    model_config = _CONFIG
    count: int = Field(ge=1, le=MAX_DRONES)


def _drones_kind(value: Any) -> str | None:
    if isinstance(value, dict):
        return "group" if "group" in value else ("count" if "count" in value else None)
    if isinstance(value, DronesFromGroup):
        return "group"
    return "count" if isinstance(value, DronesByCount) else None


DroneSelection = Annotated[
    Annotated[DronesFromGroup, Tag("group")] | Annotated[DronesByCount, Tag("count")],
    Discriminator(_drones_kind, custom_error_type="drones_kind",
                  custom_error_message='drones must be {"group": name} or {"count": n}'),
]


class Formation(_ArrayCachingModel):
    """One formation of the timeline: points (metres), colours, hold time (seconds).

    ``colors`` gives one colour per point; ``color`` one for all (default white).
    ``transition_s`` optionally fixes the duration of the transition *into* this
    formation; it must not be shorter than the minimum the limits allow.
    """

    model_config = _CONFIG

    name: Name
    hold_s: float = Field(ge=MIN_DURATION_S, le=86_400, description="Hold time at the formation, seconds.")
    points: Annotated[list[Point3], Field(min_length=1, max_length=MAX_FORMATION_POINTS)]
    colors: list[Color] | None = None
    color: Color | None = None
    source: dict[str, Any] | None = Field(
        None,
        description="How the editor made this formation (e.g. {kind: 'text', params: {...}}), so that it can be "
        "made again for another drone count; at most 4 KB of JSON.",
    )
    transition_s: float | None = Field(
        None, ge=MIN_DURATION_S, le=86_400, description="Duration of the transition into this formation, seconds."
    )
    # Issue 18: cue times. A pinned formation is reached (or left) at an absolute show time, seconds
    # from the start of takeoff; the planner stretches the transition into it (or the hold) to fit.
    arrive_at_s: float | None = Field(
        None, ge=0, le=MAX_SHOW_TIME_S,
        description="Show time at which the drones reach this formation (the transition into it ends), seconds.",
    )
    leave_at_s: float | None = Field(
        None, ge=0, le=MAX_SHOW_TIME_S,
        description="Show time at which the drones leave this formation (its hold ends; hold_s is then unused), "
        "seconds.",
    )
    # Issue 21: keyframed rotation, translation and scale of the whole formation during its hold
    # (formations._motion). The transition into it ends at the first key's pose, the one out of it
    # starts at the last key's.
    motion: Motion | None = Field(
        None, description="Keyframed similarity transform of the formation over its hold (rotate, translate, "
        "scale about a pivot); None: the formation holds still.",
    )

    # Issue 21: subset formations. None (left out) means every drone, as before.
    drones: DroneSelection | None = Field(
        None, description='Which drones fly this formation: {"group": name} (a show group) or {"count": n} '
        "(the planner picks the n nearest, CAPT-optimal); default every drone.",
    )
    # None (left out) means "hold", so that shows written before this field keep their content hash.
    others: Literal["hold", "park", "land"] | None = Field(
        None, description="What the drones not in this formation do (dark): 'hold' where they are (default), "
        "'park' in a vertical layer behind the formation (+y, away from the audience), or 'land' on their own "
        "home (taking off again for the next formation).",
    )

    @field_validator("name")
    @classmethod
    def _name_ok(cls, value: str) -> str:
        return _check_name(value)

    @field_validator("source")
    @classmethod
    def _source_small(cls, value: dict[str, Any] | None) -> dict[str, Any] | None:
        if value is not None and len(json.dumps(value)) > 4096:
            raise PydanticCustomError("source_too_large", "'source' is limited to 4096 characters of JSON")
        return value

    @model_validator(mode="after")
    def _colors_match(self) -> Formation:
        if self.colors is not None and self.color is not None:
            raise PydanticCustomError("color_conflict", "give either 'color' or 'colors', not both",
                                      {FIELD_CTX: "colors"})
        if self.colors is not None and len(self.colors) != len(self.points):
            raise PydanticCustomError(
                "colors_length",
                "'colors' has {n_colors} entries but 'points' has {n_points}",
                {"n_colors": len(self.colors), "n_points": len(self.points), FIELD_CTX: "colors"},
            )
        return self

    @model_validator(mode="after")
    def _pins_ok(self) -> Formation:
        if self.arrive_at_s is not None and self.transition_s is not None:
            raise PydanticCustomError(
                "pin_conflict", "give either 'transition_s' or 'arrive_at_s' (the arrival fixes the transition)",
                {FIELD_CTX: "arrive_at_s"},
            )
        if self.arrive_at_s is not None and self.leave_at_s is not None \
                and self.leave_at_s - self.arrive_at_s < MIN_DURATION_S - 1e-9:
            raise PydanticCustomError(
                "pin_order", "leave_at_s {leave} s must be at least {gap} s after arrive_at_s {arrive} s",
                {"leave": self.leave_at_s, "arrive": self.arrive_at_s, "gap": MIN_DURATION_S, FIELD_CTX: "leave_at_s"},
            )
        return self

    @cached_property
    def points_m(self) -> np.ndarray:
        """Formation points, (M, 3) float64 metres (read-only)."""
        arr = np.asarray(self.points, dtype=np.float64).reshape(-1, 3)
        arr.setflags(write=False)
        return arr

    @cached_property
    def colors_rgb(self) -> np.ndarray:
        """Point colours, (M, 3) float64 in [0, 1] (read-only)."""
        hexes = self.colors if self.colors is not None else [self.color or "#ffffff"] * len(self.points)
        arr = hex_to_rgb(hexes)
        arr.setflags(write=False)
        return arr


def hex_to_rgb(colors: list[str]) -> np.ndarray:
    """``#rrggbb`` strings -> (n, 3) float64 in [0, 1]."""
    if not colors:
        return np.zeros((0, 3))
    raw = bytes.fromhex("".join(c[1:] for c in colors))
    return np.frombuffer(raw, dtype=np.uint8).reshape(-1, 3).astype(np.float64) / 255.0


def _home_kind(value: Any) -> str | None:
    if isinstance(value, dict):
        return next((k for k in ("grid", "points", "boxes") if k in value), None)
    if isinstance(value, HomeFromGrid):
        return "grid"
    if isinstance(value, HomeFromBoxes):
        return "boxes"
    return "points" if isinstance(value, HomeFromPoints) else None


class ShowFile(_ArrayCachingModel):
    """A whole show: drones, home positions, limits and the formation timeline."""

    model_config = ConfigDict(
        **_CONFIG,
        json_schema_extra={
            "examples": [
                {
                    "format": SHOW_FORMAT,
                    "name": "Demo",
                    "drones": 4,
                    "home": {"grid": {"rows": 2, "cols": 2, "spacing_m": 3.0}},
                    "settings": {"min_distance_m": 3.0},
                    "formations": [
                        {
                            "name": "square",
                            "hold_s": 5.0,
                            "points": [[0, 0, 20], [4, 0, 20], [0, 0, 24], [4, 0, 24]],
                            "color": "#ff0000",
                        }
                    ],
                }
            ]
        },
    )

    format: Literal["swarmshow/1"] = Field(description="Format tag; must be 'swarmshow/1'.")
    name: Name
    drones: int = Field(ge=1, le=MAX_DRONES, description=f"Number of drones (at most {MAX_DRONES}).")
    home: Annotated[
        Annotated[HomeFromGrid, Tag("grid")] | Annotated[HomeFromPoints, Tag("points")]
        | Annotated[HomeFromBoxes, Tag("boxes")],
        Discriminator(
            _home_kind,
            custom_error_type="home_kind",
            custom_error_message="home must be {\"grid\": {...}}, {\"points\": [...]} or {\"boxes\": {...}}",
        ),
    ] = Field(description="Ground start positions: a grid, explicit points or launch boxes (metres).")
    settings: Settings = Field(default_factory=Settings)
    # Issue 21: named drone groups (None, left out of the file, keeps older shows' hashes).
    groups: DroneGroups | None = Field(
        None, description="Named drone groups: name -> drone indices (0-based), e.g. by launch box or drone type. "
        "Formations may fly a group; light effects may target one.",
    )
    formations: Annotated[list[Formation], Field(min_length=1, max_length=MAX_FORMATIONS)]
    # Issue 18: light effects over the base colours (None, left out of the file, keeps older shows' hashes).
    lights: Lights | None = Field(None, description="Drone groups and the stack of light effects (see sim.light).")

    @field_validator("name")
    @classmethod
    def _name_ok(cls, value: str) -> str:
        return _check_name(value)

    @field_validator("groups")
    @classmethod
    def _groups_ok(cls, value: dict[str, list[int]] | None) -> dict[str, list[int]] | None:
        return None if value is None else check_group_names(value)

    @model_validator(mode="after")
    def _semantics(self) -> ShowFile:
        problem = _first_semantic_problem(self)
        if problem is not None:
            loc, message = problem
            raise PydanticCustomError("show_rule", "{path}: {message}", {"path": _path(loc), "message": message})
        return self

    @cached_property
    def home_positions_m(self) -> np.ndarray:
        """The first ``drones`` home positions, (N, 3) metres (drone i starts at row i)."""
        return self.all_home_positions_m[: self.drones]

    @cached_property
    def all_home_positions_m(self) -> np.ndarray:
        """Every home position (landing may use any of them), (H, 3) metres (read-only)."""
        if isinstance(self.home, HomeFromGrid):
            pts = self.home.grid.positions_m()
        elif isinstance(self.home, HomeFromBoxes):
            pts = self.home.boxes.positions_m()
        else:
            pts = np.array(self.home.points, dtype=np.float64)
        pts.setflags(write=False)
        return pts

    @cached_property
    def all_home_boxes(self) -> np.ndarray:
        """(H,) the launch box of every home position; -1 for a loose one (grid and points layouts)."""
        if isinstance(self.home, HomeFromBoxes):
            ids = self.home.boxes.box_ids()
        else:
            ids = np.full(len(self.all_home_positions_m), -1, dtype=np.int64)
        ids.setflags(write=False)
        return ids

    @property
    def drone_groups(self) -> dict[str, list[int]]:
        """Every named group: the show's ``groups`` over the older ``lights.groups`` (one lookup for all users)."""
        older = self.lights.groups if self.lights is not None else {}
        return {**older, **(self.groups or {})}

    def formation_drones(self, k: int) -> np.ndarray | int | None:
        """Who flies formation k: the group's drone indices (sorted, int64), a count, or None (every drone)."""
        sel = self.formations[k].drones
        if isinstance(sel, DronesFromGroup):
            drones = np.sort(np.asarray(self.drone_groups[sel.group], dtype=np.int64))
            return drones if len(drones) < self.drones else None  # validated unique: a group of all drones is all
        if isinstance(sel, DronesByCount):
            return sel.count if sel.count < self.drones else None
        return None

    def canonical_json(self) -> str:
        """Compact, key-sorted JSON of the show: identical for identical content."""
        return json.dumps(self.model_dump(mode="json", exclude_none=True), sort_keys=True, separators=(",", ":"))

    def content_hash(self) -> str:
        """SHA-256 hex digest of :meth:`canonical_json` (cache key for plans and simulations)."""
        return hashlib.sha256(self.canonical_json().encode()).hexdigest()


def _path(loc: tuple[str | int, ...]) -> str:
    """('formations', 2, 'points', 5) -> 'formations[2].points[5]'."""
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out


def _outside_area(pts: np.ndarray, extent_m: float) -> tuple[int, int, str] | None:
    """(point index, axis, reason) of the first point of ``pts`` (M, 3) whose x or y is outside
    +-``extent_m``, or None."""
    bad = np.abs(pts[:, :2]) > extent_m
    if not bad.any():
        return None
    i, axis = (int(v) for v in np.argwhere(bad)[0])
    return i, axis, (f"{'xy'[axis]} = {pts[i, axis]:g} m is outside the show area +-{extent_m:g} m "
                     "(settings.max_horizontal_extent_m)")


def _first_semantic_problem(show: ShowFile) -> tuple[tuple[str | int, ...], str] | None:
    """The first cross-field rule the show breaks, as (JSON path, reason), or None."""
    s = show.settings
    n = show.drones
    tol = 1e-9  # points exactly min_distance apart are allowed despite float rounding

    slots = max(HOME_SLOTS_PER_DRONE * n, MIN_HOME_SLOTS)
    extent = s.horizontal_extent_m
    if isinstance(show.home, HomeFromGrid):
        g = show.home.grid
        if g.rows * g.cols < n:
            return ("home", "grid"), (
                f"grid of {g.rows} x {g.cols} = {g.rows * g.cols} positions is smaller than drones = {n}"
            )
        if g.rows * g.cols > slots:
            return ("home", "grid"), (
                f"grid of {g.rows} x {g.cols} = {g.rows * g.cols} positions is more than {slots} "
                f"(at most {HOME_SLOTS_PER_DRONE} per drone)"
            )
        for axis, count, centre in ((0, g.cols, g.center_m[0]), (1, g.rows, g.center_m[1])):
            half = (count - 1) / 2.0 * g.spacing_m
            if abs(centre) + half > extent:
                return ("home", "grid"), (
                    f"the grid reaches {'xy'[axis]} = {abs(centre) + half:g} m, outside the show area "
                    f"+-{extent:g} m (settings.max_horizontal_extent_m)"
                )
        if g.rows * g.cols > 1 and g.spacing_m < s.min_distance_m - tol:
            return ("home", "grid", "spacing_m"), (
                f"spacing {g.spacing_m} m is less than settings.min_distance_m {s.min_distance_m} m"
            )
    elif isinstance(show.home, HomeFromBoxes):
        problem = _boxes_problem(show.home.boxes, n, slots, s)
        if problem is not None:
            return problem
    else:
        pts = np.asarray(show.home.points, dtype=np.float64)
        if len(pts) < n:
            return ("home", "points"), f"{len(pts)} home points for drones = {n}; need at least {n}"
        if len(pts) > slots:
            return ("home", "points"), (
                f"{len(pts)} home points for drones = {n}; at most {slots} ({HOME_SLOTS_PER_DRONE} per drone)"
            )
        outside = _outside_area(pts, extent)
        if outside is not None:
            return ("home", "points", outside[0], outside[1]), outside[2]
        bad = np.flatnonzero((pts[:, 2] < 0) | (pts[:, 2] > s.max_altitude_m))
        if bad.size:
            return ("home", "points", int(bad[0]), 2), (
                f"altitude {pts[bad[0], 2]} m is outside [0, max_altitude_m {s.max_altitude_m}]"
            )
        if len(pts) > 1:
            i, j, d = closest_pair(pts)
            if d < s.min_distance_m - tol:
                return ("home", "points"), (
                    f"home points {i} and {j} are {d:.3f} m apart, closer than min_distance_m {s.min_distance_m} m"
                )

    if show.groups is not None:
        problem = groups_problem(show.groups, n)
        if problem is not None:
            return ("groups", *problem[0]), problem[1]
        if show.lights is not None:
            for name in show.groups:
                if name in show.lights.groups and show.lights.groups[name] != show.groups[name]:
                    return ("groups", name), (f"group {name!r} is also in lights.groups with other drones; "
                                              "keep one definition")
    groups = show.drone_groups
    for k, f in enumerate(show.formations):
        pts = f.points_m
        fly = n
        if f.others is not None and f.drones is None:
            return ("formations", k, "others"), (
                "'others' applies to a formation flown by some of the drones: give 'drones' "
                '({"group": name} or {"count": n}) or leave \'others\' out')
        if f.drones is not None and f.motion is not None:
            return ("formations", k, "motion"), (
                "a formation that moves during its hold is flown by every drone: leave out 'drones' or 'motion'")
        if isinstance(f.drones, DronesFromGroup):
            if f.drones.group not in groups:
                return ("formations", k, "drones", "group"), (
                    f"no drone group named {f.drones.group!r} in groups"
                    + (f" (groups: {', '.join(sorted(groups))})" if groups else " (the show has no groups)"))
            dup = groups_problem({f.drones.group: groups[f.drones.group]}, n)
            if dup is not None:
                return ("formations", k, "drones", "group"), dup[1]
            fly = len(groups[f.drones.group])
        elif isinstance(f.drones, DronesByCount):
            if f.drones.count > n:
                return ("formations", k, "drones", "count"), f"count {f.drones.count} is more than drones = {n}"
            if f.drones.count > len(pts):
                return ("formations", k, "drones", "count"), (
                    f"count {f.drones.count} is more than the formation's {len(pts)} points")
            fly = f.drones.count
        if len(pts) < fly:
            what = f" (group {f.drones.group!r})" if isinstance(f.drones, DronesFromGroup) else ""
            return ("formations", k, "points"), (
                f"{len(pts)} points for {fly} drones{what}; a formation needs at least as many points as drones"
            )
        outside = _outside_area(pts, extent)
        if outside is not None:
            return ("formations", k, "points", outside[0], outside[1]), outside[2]
        z = pts[:, 2]
        high = np.flatnonzero(z > s.max_altitude_m)
        if high.size:
            return ("formations", k, "points", int(high[0]), 2), (
                f"altitude {z[high[0]]} m is above max_altitude_m {s.max_altitude_m} m"
            )
        low = np.flatnonzero(z < 0)
        if low.size:
            # Name all of them at once: a scaled formation often has dozens underground.
            return ("formations", k, "points", int(low[0]), 2), (
                f"altitude {z[low[0]]} m is below the ground (0 m): {low.size} point{'s' if low.size > 1 else ''} "
                f"below 0 m, the lowest {z.min():.2f} m; raise the formation by at least {-z.min():.2f} m"
            )
        if len(pts) > 1:
            i, j, d = closest_pair(pts)
            if d < s.min_distance_m - tol:
                return ("formations", k, "points"), (
                    f"points {i} and {j} are {d:.3f} m apart, closer than min_distance_m {s.min_distance_m} m"
                )
        if f.motion is not None:
            fence = s.geofence
            descent = s.max_descent_speed_mps if s.max_descent_speed_mps is not None else s.max_speed_z_mps
            problem = motion_problem(
                f.motion, pts, f.hold_s if f.leave_at_s is None else None, min_distance_m=s.min_distance_m,
                closest_m=closest_pair(pts)[2] if len(pts) > 1 else float("inf"), floor_m=s.min_altitude_m,
                ceiling_m=s.max_altitude_m, extent_m=extent,
                fence=None if fence is None else (fence.x_min_m, fence.x_max_m, fence.y_min_m, fence.y_max_m),
                v_xy=s.max_speed_xy_mps, v_z=s.max_speed_z_mps, v_down=descent, a_max=s.max_accel_mps2,
            )
            if problem is not None:
                return ("formations", k, "motion", *problem[0]), problem[1]
    if show.lights is not None:
        problem = lights_problem(show.lights, n, [f.name for f in show.formations],
                                 [len(f.points) for f in show.formations], show.groups)
        if problem is not None:
            return ("lights", *problem[0]), problem[1]
    return _pin_order_problem(show)


def _boxes_problem(boxes: LaunchBoxes, n: int, slots: int, s: Settings
                   ) -> tuple[tuple[str | int, ...], str] | None:
    """Counts, show area and the spacing rule of :mod:`formations._launch` for a boxes layout."""
    total = boxes.box_count * boxes.per_box
    where = ("home", "boxes", "grid") if boxes.grid is not None else ("home", "boxes", "centers")
    if total < n:
        return where, (f"{boxes.box_count} boxes of {boxes.per_box} = {total} home positions is fewer than "
                       f"drones = {n}")
    if total > slots:
        return where, (f"{boxes.box_count} boxes of {boxes.per_box} = {total} home positions is more than {slots} "
                       f"(at most {HOME_SLOTS_PER_DRONE} per drone)")
    outside = _outside_area(boxes.positions_m(), s.horizontal_extent_m)
    if outside is not None:
        box = outside[0] // boxes.per_box
        return ((*where, "spacing_m") if boxes.grid is not None else (*where, box)), (
            f"box {box}: {outside[2]}")
    problem = boxes_problem(boxes, s.min_distance_m, s.downwash_axes_m[0])
    if problem is not None:
        return ("home", "boxes", *problem[0]), problem[1]
    return None


def _pin_order_problem(show: ShowFile) -> tuple[tuple[str | int, ...], str] | None:
    """Cue times must increase along the timeline (each later than every pin before it)."""
    last: tuple[float, str] | None = None
    for k, f in enumerate(show.formations):
        for field_name, t in (("arrive_at_s", f.arrive_at_s), ("leave_at_s", f.leave_at_s)):
            if t is None:
                continue
            if last is not None and t <= last[0]:
                return ("formations", k, field_name), (
                    f"{t:g} s is not after {last[1]} = {last[0]:g} s: cue times must increase along the timeline"
                )
            last = (t, f"formations[{k}].{field_name}")
    return None


class ShowValidationError(ValueError):
    """A show file was rejected. ``errors`` lists ``{"loc": (...), "path": str, "msg": str}``."""

    def __init__(self, errors: list[dict[str, Any]]) -> None:
        self.errors = errors
        super().__init__(self.one_line())

    def one_line(self) -> str:
        """The first problem as ``path: reason``, plus how many more there are."""
        if not self.errors:
            return "invalid show file"
        first = self.errors[0]
        head = f"{first['path']}: {first['msg']}" if first["path"] else first["msg"]
        more = len(self.errors) - 1
        return head + (f" (and {more} more problem{'s' if more > 1 else ''})" if more else "")

    @classmethod
    def from_pydantic(cls, exc: ValidationError, *, prefix: tuple[str | int, ...] = ()) -> ShowValidationError:
        """Convert pydantic's errors, moving our cross-field rules' paths into ``loc``."""
        out: list[dict[str, Any]] = []
        for err in exc.errors(include_url=False):
            loc = _drop_union_tag(prefix + tuple(err["loc"]))
            msg = err["msg"]
            ctx = err.get("ctx") or {}
            if err["type"] == "show_rule":
                path = ".".join(p for p in (_path(prefix), ctx["path"]) if p)
                out.append({"loc": loc, "path": path, "msg": ctx["message"]})
                continue
            if isinstance(ctx.get(FIELD_CTX), str):  # a rule across fields of one object names its field
                loc = (*loc, ctx[FIELD_CTX])
            # Unions report every branch; "home" is the only union and its branch names help.
            out.append({"loc": loc, "path": _path(loc), "msg": msg})
        return cls(out)


_EFFECT_TAGS = {("effect", k) for k in KINDS} | {("target", k) for k in TARGETS}


def _drop_union_tag(loc: tuple[str | int, ...]) -> tuple[str | int, ...]:
    """pydantic puts the union member's tag in the path (home.grid.grid.rows): drop it."""
    for i in range(len(loc) - 2):
        if loc[i] == "home" and loc[i + 1] in ("grid", "points", "boxes") and loc[i + 2] == loc[i + 1]:
            return loc[: i + 1] + loc[i + 2 :]
    # Subset formations: formations[k].drones.group.group -> formations[k].drones.group.
    for i in range(len(loc) - 2):
        if loc[i] == "drones" and loc[i + 1] in ("group", "count") and loc[i + 2] == loc[i + 1]:
            return loc[: i + 1] + loc[i + 2 :]
    # Light effects: lights.effects[k].effect.<kind>.field -> lights.effects[k].effect.field (and target).
    if loc[:1] == ("lights",):
        for i in range(len(loc) - 1):
            if (loc[i], loc[i + 1]) in _EFFECT_TAGS:
                return loc[: i + 1] + loc[i + 2 :]
    return loc


def parse_show(data: bytes | str | dict[str, Any]) -> ShowFile:
    """Validate a show from JSON text/bytes or an already-parsed dict.

    Raises:
        ShowValidationError: with the JSON path and reason of every problem found
            (malformed JSON, non-UTF-8 bytes, too large, or any rule above).
    """
    if isinstance(data, bytes | bytearray):
        if len(data) > MAX_SHOW_FILE_BYTES:
            raise ShowValidationError(
                [{"loc": (), "path": "", "msg": f"show file is {len(data)} bytes; the limit is {MAX_SHOW_FILE_BYTES}"}]
            )
        try:
            data = bytes(data).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ShowValidationError(
                [{"loc": (), "path": "", "msg": f"not UTF-8 text (byte {exc.start})"}]
            ) from exc
    try:
        if isinstance(data, str):
            return ShowFile.model_validate_json(data)
        return ShowFile.model_validate(data)
    except ValidationError as exc:
        raise ShowValidationError.from_pydantic(exc) from exc


def load_show(path: str | Path) -> ShowFile:
    """Read and validate a show file from disk (see :func:`parse_show`)."""
    path = Path(path)
    size = path.stat().st_size
    if size > MAX_SHOW_FILE_BYTES:
        raise ShowValidationError(
            [{"loc": (), "path": "", "msg": f"show file is {size} bytes; the limit is {MAX_SHOW_FILE_BYTES}"}]
        )
    return parse_show(path.read_bytes())


def dump_show(show: ShowFile, *, indent: int | None = 2) -> str:
    """The show as JSON text (``None`` fields omitted), loadable by :func:`parse_show`."""
    return json.dumps(show.model_dump(mode="json", exclude_none=True), indent=indent)


def show_json_schema() -> dict[str, Any]:
    """JSON Schema of the show file format."""
    return ShowFile.model_json_schema()


_AXES = {0: "x", 1: "y", 2: "z"}
#: A field's unit suffix in plain words ('hold_s' -> 'hold (s)', not 'hold s').
_UNITS = {"s": "s", "m": "m", "mps": "m/s", "mps2": "m/s²", "mps3": "m/s³", "deg": "°", "rad": "rad", "hz": "Hz"}


def _plain_key(key: str) -> str:
    """A field name in words, its unit suffix in brackets: 'max_accel_mps2' -> 'max accel (m/s²)'."""
    stem, _, suffix = key.rpartition("_")
    if stem and suffix in _UNITS:
        return f"{stem.replace('_', ' ')} ({_UNITS[suffix]})"
    return key.replace("_", " ")
_NAMED_LISTS = {"formations": "formation", "points": "point", "colors": "colour", "lights": "light",
                "home": "home position", "effects": "light effect"}
#: Objects that hold one named list and add nothing a designer needs when a field follows:
#: 'lights.effects[0].end_s' is 'light effect 1, end (s)', not 'lights, effects, effects 1, end (s)'.
_SILENT_PARENTS = {"lights"}


def _said_alone(key: str) -> str:
    """A key with no index after it: a list's name as it is ('points'), any other field in words."""
    return key.replace("_", " ") if key in _NAMED_LISTS else _plain_key(key)


def plain_path(path: str, show: Any = None) -> str:
    """A show file path in plain words: 'formations[1].points[5][2]' -> 'formation 2 "Heart", point 6, z'.

    Indices count from 1 as people do; a formation is named when ``show`` (the document) has its name.
    A field that holds a list is said once, with its item's number ('effects[0]' -> 'light effect 1').
    """
    words: list[str] = []
    last = ""
    pending = ""  # the last key, said when no index follows it ("points" alone stays "points")
    node = show
    for key, index in re.findall(r"([A-Za-z_][A-Za-z0-9_]*)|\[(\d+)\]", path):
        if key:
            if pending and pending not in _SILENT_PARENTS:
                words.append(_said_alone(pending))
            last = pending = key
            node = _child(node, key)
            continue
        pending = ""
        i = int(index)
        node = node[i] if isinstance(node, list | tuple) and i < len(node) else None
        if last == "points" and words and words[-1].startswith("point "):
            words.append(_AXES.get(i, f"coordinate {i + 1}"))
            continue
        label = f"{_NAMED_LISTS.get(last, last.replace('_', ' '))} {i + 1}"
        name = _child(node, "name")
        if last == "formations" and isinstance(name, str):
            label += f' "{name}"'
        words.append(label)
    if pending:
        words.append(_said_alone(pending))
    return ", ".join(words) or "the show"


def _child(node: Any, key: str) -> Any:
    """``node[key]`` of a JSON document, or the field ``key`` of a validated model (``ShowFile``); else None."""
    if isinstance(node, dict):
        return node.get(key)
    if isinstance(node, BaseModel) and key in type(node).model_fields:
        return getattr(node, key)
    return None


_IN_FORMATION = re.compile(r"^formations\[(\d+)\]\.?(.*)$")


def plain_words(path: str, show: Any = None) -> dict[str, str]:
    """What a problem at ``path`` says in plain words: ``where`` (:func:`plain_path`) and, for a field inside a
    formation, ``where_in_formation``: the words below it, for the formation's own card ('hold (s)',
    'point 6, z'), which names the formation already.

    ``show`` is the document (a dict) or the validated :class:`ShowFile` (formations are named from it)."""
    out = {"where": plain_path(path, show)}
    m = _IN_FORMATION.match(path)
    if m and m.group(2):
        out["where_in_formation"] = plain_path(m.group(2))
    return out
