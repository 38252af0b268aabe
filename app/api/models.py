"""Request and response models of the REST API (they make the OpenAPI document)."""

from __future__ import annotations

from typing import Any, Literal, cast

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from formations import ShowFile
from formations._shapes import SHAPE_KINDS, SHAPE_PARAMS
from sim import CheckReport
from sim.flight import DEFAULT_FLIGHT_PRESET, ControllerName, DisturbanceName  # the one list of names (FlightOptions)

Plane = Literal["xz", "xy", "yz"]


# -- errors -----------------------------------------------------------------------------------


class Problem(BaseModel):
    """One reason a request was rejected."""

    model_config = ConfigDict(extra="allow")

    loc: list[str | int] = Field(description="Where: 'body', 'query' or 'path', then the field's keys and indices.")
    path: str = Field(description="The field as a JSON path inside the body, e.g. 'formations[2].hold_s'.")
    msg: str = Field(description="Why it was rejected.")
    where: str | None = Field(None, description="The field in the designer's words, e.g. 'formation 3 \"Heart\", "
                              "hold (s)' (formations named, counted from 1).")
    where_in_formation: str | None = Field(None, description="For a field inside a formation: the words below "
                                           "it, e.g. 'hold (s)' or 'point 6, z'.")


class ValidationErrorOut(BaseModel):
    """422: the request is well-formed HTTP but its content is invalid."""

    detail: list[Problem]

    model_config = ConfigDict(json_schema_extra={"examples": [{"detail": [
        {"loc": ["body", "formations", 2, "hold_s"], "path": "formations[2].hold_s",
         "msg": "Input should be greater than 0"}]}]})


class ErrorOut(BaseModel):
    """Any other error: a one-line reason."""

    detail: str = Field(examples=["no show with id '5f2c0a9e1b7d4c3a'"])


class ConflictOut(BaseModel):
    """409: the show changed since the client read it (or the job already finished)."""

    detail: str
    current_revision: int | None = Field(None, description="The stored revision (for a show).")

    model_config = ConfigDict(json_schema_extra={"examples": [{
        "detail": "show '5f2c0a9e1b7d4c3a' is at revision 4, not 3: it was changed meanwhile; "
                  "reload it and apply your change again",
        "current_revision": 4}]})


def error_responses(*codes: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses`` entries for the given error status codes."""
    table: dict[int, dict[str, Any]] = {
        404: {"model": ErrorOut, "description": "No such show, job or format."},
        409: {"model": ConflictOut, "description": "Stale revision (or the job already finished)."},
        413: {"model": ErrorOut, "description": "Upload over the limit: show file 20 MB, image 40 MP, SVG 5 MB."},
        422: {"model": ValidationErrorOut, "description": "Invalid input, with the field path and the reason."},
        429: {"model": ErrorOut, "description": "Too many jobs queued; retry later (see Retry-After)."},
        503: {"model": ErrorOut, "description": "The service is not running (e.g. the 3D viewer is off)."},
    }
    return {code: table[code] for code in codes}


# -- health -----------------------------------------------------------------------------------


class HealthOut(BaseModel):
    """The server is up, its store open and its worker pool running."""

    status: Literal["ok", "busy"] = Field("ok", description="'busy' when the worker pools are saturated: new "
                                          "work waits (interactive tasks queued, or the job queue full).")
    version: str
    schema_version: int = Field(description="Schema version of the show store.")
    workers: int = Field(description="Worker processes for simulations.")
    interactive_workers: int = Field(0, description="Worker processes for interactive requests.")
    jobs_pending: int = Field(description="Jobs queued or running.")
    interactive_pending: int = Field(0, description="Interactive tasks queued or running.")


# -- shows ------------------------------------------------------------------------------------


class ShowSummary(BaseModel):
    """A stored show without its content."""

    id: str = Field(examples=["5f2c0a9e1b7d4c3a"])
    name: str
    revision: int = Field(ge=1, description="Increments on every change; send it back with PUT.")
    drones: int
    formations: int
    content_hash: str = Field(description="SHA-256 of the canonical show JSON (equal content, equal hash).")
    created_at: str = Field(examples=["2026-11-24T13:21:57.123456Z"])
    updated_at: str
    draft: bool = Field(False, description="Saved half-finished (``?draft=true``): check, simulate, export and "
                        "playback refuse it until it is saved valid.")
    problems: list[Problem] = Field(default_factory=list, description="What is wrong with a draft; each "
                                    "problem also says ``where`` in plain words (e.g. 'formation 2, point 6').")


class ShowOut(ShowSummary):
    """A stored show with its show file (for a draft: the document as saved, not validated)."""

    show: ShowFile | dict[str, Any] = Field(description="The show file; for a draft (``draft: true``) the "
                                            "JSON object as it was saved, which may break the show file's rules.")
    has_audio: bool = Field(False, description="Whether the show has music (``GET /api/shows/{id}/audio/info`` "
                            "describes it; without music that resource does not exist: 404).")


class ShowList(BaseModel):
    """One page of shows, most recently updated first."""

    items: list[ShowSummary]
    total: int
    limit: int
    offset: int


class RevisionOut(BaseModel):
    """One revision of a show (its show file is at ``GET /api/shows/{id}/revisions/{revision}``)."""

    revision: int = Field(ge=1)
    name: str
    content_hash: str
    drones: int
    formations: int
    created_at: str
    has_show: bool = Field(description="False once the text was pruned (only the newest revisions keep it).")
    draft: bool = Field(False, description="This revision was saved as a draft (it has problems).")


class RevisionList(BaseModel):
    """A page of a show's revisions, newest first."""

    show_id: str
    items: list[RevisionOut]
    total: int
    limit: int
    offset: int


class ShowUpdate(BaseModel):
    """PUT body: the revision the change is based on and the whole new show file."""

    revision: int = Field(ge=1, description="The revision you read; a stale one gets 409.")
    show: ShowFile


# -- check and jobs ---------------------------------------------------------------------------


class SegmentOut(BaseModel):
    """One show-wide segment of the plan."""

    index: int
    kind: Literal["takeoff", "transition", "hold", "landing"]
    label: str
    start_s: float
    duration_s: float


class PlanSummary(BaseModel):
    """The planned timeline."""

    drones: int
    duration_s: float
    segments: list[SegmentOut]
    assignment: list[list[int]] | None = Field(None, description=(
        "For each formation in show order: the point index each drone flies to (drone i -> point assignment[k][i]; "
        "-1: drone i does not fly that subset formation and is dark)."))


class CheckOut(BaseModel):
    """Plan summary and exact verification of the stored show."""

    show_id: str
    revision: int
    content_hash: str
    cached: bool = Field(description="True when the show was checked before and not recomputed.")
    plan: PlanSummary
    report: CheckReport


PresetName = Literal["ideal", "calm-rtk", "gusty-rtk", "gps-only"]
#: Largest seed of a flight or a Monte-Carlo job's first run (the editor's seed field has the same bound).
MAX_SEED = 2**31 - 1
PrecisionName = Literal["float64", "float32"]


class SimulateOptions(BaseModel):
    """How to fly the show in simulation: one flight under an error-model preset with a seed.

    The flight of ``preset`` and ``seed`` is run ``seed - seed0`` of a Monte-Carlo job with that preset and
    controller (``sim.flight.single_flight_options``): the same seed flies the same flight.
    """

    model_config = ConfigDict(extra="forbid")

    engine: Literal["numba", "numpy"] = Field("numba", description="Simulation engine.")
    controller: ControllerName = Field("ismc", description="Position and attitude controllers.")
    preset: PresetName | None = Field(None, description=(
        f"Error-model preset (per-drone GNSS/RTK error, clock offset, wind field, motor lag, spread, battery, drag). "
        f"Default {DEFAULT_FLIGHT_PRESET!r}, or 'ideal' when a disturbance other than 'none' is asked."))
    seed: int = Field(0, ge=0, le=MAX_SEED, description="Seed of every random error: the same seed, the same flight.")
    disturbance: DisturbanceName = Field("none", description=(
        "Fleet-wide external disturbance; only with preset 'ideal' (the other presets bring their own wind)."))
    output_hz: float = Field(25.0, gt=0, le=1000, description="Rate of the recorded trajectory, Hz.")
    precision: PrecisionName = Field(
        "float64", description="The numba kernel's arithmetic: float64 (default; agrees with the numpy reference "
        "to 1e-9) or float32 control laws (1.3-1.4x faster kernel, results differ at the rounding level).")

    @model_validator(mode="after")
    def _precision_needs_numba(self) -> SimulateOptions:
        if self.precision != "float64" and self.engine != "numba":
            raise ValueError("precision: float32 needs the numba engine (the numpy reference is float64)")
        return self

    @field_validator("disturbance")
    @classmethod
    def _one_wind(cls, value: str, info: ValidationInfo) -> str:
        preset = info.data.get("preset")
        if value != "none" and preset not in (None, "ideal"):
            raise ValueError(f"disturbance {value!r} goes only with preset 'ideal': preset {preset!r} brings its "
                             "own wind field")
        return value

    @model_validator(mode="after")
    def _default_preset(self) -> SimulateOptions:
        if self.preset is None:
            # The old request (a disturbance, no preset) still flies the ideal vehicle in that disturbance.
            self.preset = "ideal" if self.disturbance != "none" else cast(PresetName, DEFAULT_FLIGHT_PRESET)
        return self


#: Most Monte-Carlo runs one job may ask for (the work is also bounded by drones x duration x runs,
#: :data:`app.tasks.MAX_MONTECARLO_DRONE_S`).
MAX_MONTECARLO_RUNS = 200


class MonteCarloOptions(BaseModel):
    """How to fly the show K times for its safety margin (``sim.flight.monte_carlo``)."""

    model_config = ConfigDict(extra="forbid")

    runs: int = Field(20, ge=1, le=MAX_MONTECARLO_RUNS, description="K, the number of flights (seeds seed0..).")
    # The single flight's default (calm-rtk): a designer runs a Monte-Carlo to ask "will this show fly in the
    # conditions it is normally flown in?", and run k is then the default single flight of seed seed0 + k
    # (a seed seen in the report flies again alone). gusty-rtk is the stress case, one choice away (it was
    # the default here while the editor's menu, the CLI and single flights said calm-rtk).
    preset: PresetName = Field(cast(PresetName, DEFAULT_FLIGHT_PRESET), description=(
        f"Error-model preset (default {DEFAULT_FLIGHT_PRESET!r}, as a single flight; 'gusty-rtk' for the stress "
        "case)."))
    controller: ControllerName = Field("ismc", description="Position and attitude controllers.")
    precision: PrecisionName = Field("float64", description="The numba kernel's arithmetic (as for a simulation).")
    seed0: int = Field(0, ge=0, le=MAX_SEED, description="Seed of the first run.")
    confidence: float = Field(0.99, gt=0, lt=1, description="Level of the intervals and of the extra spacing.")
    collision_distance_m: float = Field(1.0, gt=0, le=100, description="Centre distance counted as a collision, m.")


class JobError(BaseModel):
    """Why a job failed or stopped."""

    model_config = ConfigDict(extra="allow")

    kind: str = Field(description="Why: cancelled, timeout, worker_died, failed (a bug; see the server log), "
                      "or the task's own reason: invalid, too_large, unavailable, not_found, not_implemented.")
    status: int = Field(description="The HTTP status the kind corresponds to (499: cancelled).")
    message: str
    detail: Any = None


class JobOut(BaseModel):
    """A background job."""

    id: str
    kind: str = Field(examples=["simulate"])
    state: Literal["queued", "running", "done", "failed", "cancelled"]
    progress: float = Field(ge=0, le=1)
    show_id: str | None
    show_revision: int | None
    content_hash: str
    options: dict[str, Any]
    cached: bool = Field(description="True when the result came from the cache (not recomputed).")
    created_at: str
    started_at: str | None
    finished_at: str | None
    result: dict[str, Any] | None = Field(description="When done: the plan summary and the flight summary.")
    error: JobError | None = Field(description="When failed or cancelled: why.")
    note: str = Field("", description="A one-line note from the running task, e.g. that the first flight on "
                      "this machine compiles the flight kernel (a minute or two of CPU, cached afterwards).")


class JobList(BaseModel):
    """Remembered jobs, newest first (results omitted)."""

    items: list[JobOut]


# -- formations -------------------------------------------------------------------------------


class _FormationBase(BaseModel):
    model_config = ConfigDict(extra="forbid")

    n: int = Field(ge=1, le=20_000, description="Number of points.")
    center_m: list[float] = Field([0.0, 0.0, 30.0], min_length=3, max_length=3, description="Centre (x, y, z), m.")
    plane: Plane = Field("xz", description="'xz' faces the audience; 'xy' is parallel to the ground.")
    min_spacing_m: float = Field(3.0, ge=0.01, le=100, description="Minimum distance between points, m.")


class ShapeRequest(_FormationBase):
    """A preset shape."""

    kind: Literal[SHAPE_KINDS] = Field(description="Shape preset.")  # type: ignore[valid-type]
    size_m: float = Field(20.0, ge=0.01, le=10_000, description="Diameter, side or height, m.")
    color: str = Field("#ffffff", pattern=r"^#[0-9a-fA-F]{6}$", description="LED colour.")
    params: dict[str, Any] = Field(
        default_factory=dict,
        description="Kind-specific: polygon sides; star points, inner_ratio; helix turns, radius_m; cube filled.",
    )

    @field_validator("params")
    @classmethod
    def _kind_params(cls, value: dict[str, Any], info: ValidationInfo) -> dict[str, Any]:
        # Checked here, not only by the generator: a key such as "n" or "size_m" would otherwise reach
        # generate_shape() twice as a keyword (a 500 the API fuzz found).
        kind = info.data.get("kind")
        if kind is None:
            return value
        accepted = SHAPE_PARAMS[kind]
        unknown = sorted(set(value) - set(accepted))
        if unknown:
            raise ValueError(f"unknown parameter {unknown[0]!r} for {kind} (accepted: {', '.join(accepted) or 'none'})")
        return value

    model_config = ConfigDict(extra="forbid", json_schema_extra={"examples": [
        {"kind": "star", "n": 50, "size_m": 40.0, "center_m": [0, 0, 40], "plane": "xz", "color": "#ffcc00",
         "params": {"points": 5}}]})


class TextRequest(_FormationBase):
    """Text drawn with the bundled font."""

    text: str = Field(min_length=1, max_length=1000, description="The text (newlines start new lines).")
    height_m: float = Field(10.0, ge=0.01, le=10_000, description="Letter height, m.")
    color: str = Field("#ffffff", pattern=r"^#[0-9a-fA-F]{6}$", description="LED colour.")

    model_config = ConfigDict(extra="forbid", json_schema_extra={"examples": [
        {"text": "HELLO", "n": 120, "height_m": 12.0, "center_m": [0, 0, 40], "color": "#00aaff"}]})


class HomePoints(BaseModel):
    """Home positions read from a CSV (``Name,x,y,z`` or ``x,y[,z]`` rows), metres, for ``home.points``."""

    points: list[list[float]]
    names: list[str] = Field(description="The Name column ('' where the file has none).")
    count: int
    min_spacing_m: float | None = Field(description="Nearest-pair distance, m (null for one point).")


class FormationPoints(BaseModel):
    """Formation points (metres, ENU) and their LED colours."""

    points: list[list[float]]
    colors: list[str]
    min_spacing_m: float | None = Field(description="Nearest-pair distance, m (null for one point).")
    count: int
    name: str = Field(description="A name after the source, for a formation that has none of the designer's: "
                      "the file's stem (image, SVG, mesh / point file), the text spelled, the shape's kind.")
    size_m: float | None = Field(None, description="Mesh / point-file sources: the size used (largest side "
                                 "of the bounding box), m.")
