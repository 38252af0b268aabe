"""Light effects over time: the show file's ``lights`` block (pydantic v2 models).

A show's LEDs are the plan's base colours (each formation's point colours, fading linearly
through transitions) with a *stack* of effects painted over them, bottom first. Every effect
has a time range ``[start_s, end_s)``, linear fades in and out, a blend mode, a target (which
drones it touches) and a kind (what colour it paints). The evaluator is :mod:`sim.light`;
these models only describe and validate.

Blend of an effect colour ``e`` with opacity ``a`` (fade envelope x target x image alpha) over
the colour ``r`` below it, channels in [0, 1]:

* ``replace``: r + a (e - r)
* ``add``: min(1, r + a e)
* ``multiply``: r (1 - a + a e)
* ``max``: r + a (max(r, e) - r)

Targets: ``all``; ``formation`` (every drone, while the show is at that formation: from the
start of the transition into it to the end of its hold); ``drones`` (indices); ``points`` (the
drones assigned to some points of a formation: the editor's selection); ``group`` (a
name from ``lights.groups``, a list of drone indices); ``box`` (drones inside an axis-aligned
box at that instant); ``plane`` (drones on the side of a plane its normal points to).
Targets and kinds that read positions (``box``, ``plane``, ``sweep``, ``image``, ``video``) read
each drone's planned position at each instant, so they follow formations that move during
their hold (``Formation.motion``); ``points`` names drones (those assigned to the points), so
the light stays on the same drones as their points move.

Kinds: ``solid``; ``ramp`` (colours evenly spaced in time over the effect); ``sweep`` (a
periodic gradient moving along an axis or out from a centre at ``speed_mps``); ``chase`` (a
pulse or cosine wave running along an order of the drones); ``sparkle`` (seeded random
flashes); ``strobe``; ``image`` (a PNG/JPEG or a sequence of them projected onto a rectangle
facing the audience, who look along +y: each drone takes the pixel it covers); ``video`` (the
same projection of an embedded video, decoded with PyAV).
"""

from __future__ import annotations

import base64
import binascii
import re
from functools import lru_cache
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

_HEX = r"^#[0-9a-fA-F]{6}$"
Color = Annotated[str, Field(pattern=_HEX, examples=["#ff8800"])]
Point3 = Annotated[list[float], Field(min_length=3, max_length=3)]

#: Most effects one show may stack (each costs a pass over every drone and frame).
MAX_EFFECTS = 200
#: Most colour stops in a ramp or a sweep.
MAX_STOPS = 64
#: Most images in one image sequence.
MAX_IMAGE_FRAMES = 600
#: Largest encoded image (one frame), bytes of base64 text; the show file's 20 MB bounds the total.
MAX_IMAGE_CHARS = 4_000_000
#: Most pixels of one image frame (decoded RGBA costs 4 bytes a pixel; a small PNG can hold a huge image).
MAX_IMAGE_PIXELS = 4096 * 4096
#: Most pixels of all image frames of a show together (256 MB decoded).
MAX_SHOW_IMAGE_PIXELS = 64 * 1024 * 1024
#: Most video effects in a show (each decodes to at most MAX_VIDEO_FRAMES small frames).
MAX_VIDEOS = 4
#: Largest embedded video, characters of base64 (about 12 MB of video; the show file's limit is 20 MB).
MAX_VIDEO_CHARS = 16_000_000
#: Highest rate a video is sampled at, frames per second.
MAX_VIDEO_FPS = 25.0
#: Widest (and tallest) a decoded video frame is kept, pixels.
MAX_VIDEO_WIDTH_PX = 192
#: Most frames kept of one video (a minute at 25 fps; longer videos loop their first minute).
MAX_VIDEO_FRAMES = 1500
#: Most named drone groups.
MAX_GROUPS = 200
#: Longest effect, seconds (a day, as a hold).
MAX_TIME_S = 86_400.0

_CONFIG = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, frozen=True)
_DATA_URL = re.compile(r"^data:image/(png|jpeg|jpg);base64,")
_VIDEO_URL = re.compile(r"^data:video/(mp4|webm|ogg|quicktime);base64,")
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")


# ------------------------------------------------------------------------------------- targets


class TargetAll(BaseModel):
    """Every drone."""

    model_config = _CONFIG
    kind: Literal["all"] = "all"


class TargetFormation(BaseModel):
    """Every drone, while the show is at formation ``formation`` (its transition in and its hold)."""

    model_config = _CONFIG
    kind: Literal["formation"]
    formation: str = Field(min_length=1, max_length=200, description="Name of a formation of the show.")


class TargetDrones(BaseModel):
    """The drones with these indices (0-based)."""

    model_config = _CONFIG
    kind: Literal["drones"]
    indices: Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=1, max_length=20_000)]


class TargetPoints(BaseModel):
    """The drones that fly to these points (indices into its ``points``) of formation ``formation`` (the
    first of that name): the editor's selection. The drones are found in the plan's assignment and
    stay the target for the effect's whole time range."""

    model_config = _CONFIG
    kind: Literal["points"]
    formation: str = Field(min_length=1, max_length=200)
    indices: Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=1, max_length=100_000)]


class TargetGroup(BaseModel):
    """The drones of the named group in the show's ``groups`` (or, in older files, ``lights.groups``).

    Extension point: groups are plain index lists today; a group defined some other way
    (by formation points, by tag) only has to resolve to indices in ``sim.light``.
    """

    model_config = _CONFIG
    kind: Literal["group"]
    group: str = Field(min_length=1, max_length=200)


class TargetBox(BaseModel):
    """Drones inside the axis-aligned box [min_m, max_m] at each instant, metres."""

    model_config = _CONFIG
    kind: Literal["box"]
    min_m: Point3
    max_m: Point3

    @model_validator(mode="after")
    def _ordered(self) -> TargetBox:
        if any(a > b for a, b in zip(self.min_m, self.max_m, strict=True)):
            raise PydanticCustomError("box_empty", "the box needs min_m <= max_m on every axis")
        return self


class TargetPlane(BaseModel):
    """Drones on the side of the plane through ``point_m`` that ``normal`` points to: (p - point)·n >= 0."""

    model_config = _CONFIG
    kind: Literal["plane"]
    point_m: Point3
    normal: Point3

    @field_validator("normal")
    @classmethod
    def _nonzero(cls, value: list[float]) -> list[float]:
        if sum(v * v for v in value) < 1e-18:
            raise PydanticCustomError("normal_zero", "the plane's normal must not be the zero vector")
        return value


Target = Annotated[
    TargetAll | TargetFormation | TargetDrones | TargetPoints | TargetGroup | TargetBox | TargetPlane,
    Field(discriminator="kind"),
]


# --------------------------------------------------------------------------------------- kinds


class SolidKind(BaseModel):
    """One colour."""

    model_config = _CONFIG
    kind: Literal["solid"]
    color: Color


class RampKind(BaseModel):
    """Colours evenly spaced in time from ``start_s`` to ``end_s``, faded linearly between them."""

    model_config = _CONFIG
    kind: Literal["ramp"]
    colors: Annotated[list[Color], Field(min_length=2, max_length=MAX_STOPS)]


class SweepKind(BaseModel):
    """A periodic gradient that moves through the fleet.

    The phase of a drone at p is ``(s(p) - speed_mps (t - start_s)) / length_m`` where s is
    the distance along ``axis`` (``linear``) or from ``center_m`` (``radial``); the colour is
    the gradient through ``colors`` (evenly spaced, wrapping from the last back to the first)
    at the phase's fractional part.
    """

    model_config = _CONFIG
    kind: Literal["sweep"]
    colors: Annotated[list[Color], Field(min_length=2, max_length=MAX_STOPS)]
    mode: Literal["linear", "radial"] = "linear"
    axis: Point3 = Field(default_factory=lambda: [1.0, 0.0, 0.0], description="Direction of a linear sweep.")
    center_m: Point3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="Centre of a radial sweep, metres.")
    length_m: float = Field(20.0, gt=0, le=100_000, description="Length of one period of the gradient, metres.")
    speed_mps: float = Field(10.0, ge=-10_000, le=10_000, description="Speed of the gradient, m/s.")

    @field_validator("axis")
    @classmethod
    def _nonzero(cls, value: list[float]) -> list[float]:
        if sum(v * v for v in value) < 1e-18:
            raise PydanticCustomError("axis_zero", "the sweep axis must not be the zero vector")
        return value


class ChaseKind(BaseModel):
    """A light running along an order of the drones, ``period_s`` per lap.

    A drone's place q in [0, 1) is its rank in ``order`` (drone index, or position along x, y
    or z at the effect's start) over the count. ``pulse``: brightness 1 - d / width, d the
    cyclic distance between q and the head ``(t - start_s) / period_s`` (0 beyond ``width``);
    ``wave``: (1 + cos 2π (q - head)) / 2.
    """

    model_config = _CONFIG
    kind: Literal["chase"]
    color: Color
    order: Literal["index", "x", "y", "z"] = "index"
    shape: Literal["pulse", "wave"] = "pulse"
    period_s: float = Field(2.0, ge=0.02, le=MAX_TIME_S)
    width: float = Field(0.1, gt=0, le=1.0, description="Half-width of a pulse, as a fraction of the order.")


class SparkleKind(BaseModel):
    """Random flashes: each drone's time is cut into slots of ``flash_s`` (offset per drone), and
    a slot flashes with probability ``density`` (a hash of seed, drone and slot, so repeatable).
    A flash rises and falls linearly over its slot."""

    model_config = _CONFIG
    kind: Literal["sparkle"]
    color: Color
    density: float = Field(0.2, ge=0, le=1)
    flash_s: float = Field(0.3, ge=0.02, le=60)
    seed: int = Field(0, ge=0, le=2**31 - 1)


class StrobeKind(BaseModel):
    """On for the first ``duty`` of every period of 1 / ``frequency_hz``, off for the rest."""

    model_config = _CONFIG
    kind: Literal["strobe"]
    color: Color
    frequency_hz: float = Field(4.0, gt=0, le=25, description="Flashes per second (at most 25: half of 50 Hz).")
    duty: float = Field(0.5, gt=0, lt=1)


def _check_camera(camera_m: list[float] | None, center_m: list[float]) -> None:
    if camera_m is not None and not camera_m[1] < center_m[1]:
        raise PydanticCustomError(
            "camera_behind", "camera_m y {cy} must be in front of the picture (less than center_m y {py})",
            {"cy": camera_m[1], "py": center_m[1]},
        )


class ImageKind(BaseModel):
    """Images projected onto the audience's view: the rectangle ``width_m`` x ``height_m`` centred on
    ``center_m`` in the x-z plane (the front view; the audience looks along +y). A drone inside it
    takes the colour of the pixel it covers (alpha as opacity); one outside is untouched. With
    ``camera_m`` (the audience's eye) each drone is first projected through the camera onto the
    picture's plane y = center_m[1], so the picture looks undistorted from there; drones at or
    behind the camera's y are untouched.
    ``frames`` are PNG/JPEG data URLs, shown at ``fps`` (and looped) from ``start_s``."""

    model_config = _CONFIG
    kind: Literal["image"]
    frames: Annotated[list[str], Field(min_length=1, max_length=MAX_IMAGE_FRAMES)]
    fps: float = Field(10.0, gt=0, le=60)
    center_m: Point3
    width_m: float = Field(gt=0, le=100_000)
    height_m: float = Field(gt=0, le=100_000)
    camera_m: Point3 | None = Field(
        None, description="Audience camera, metres: drones are projected through it onto the picture's plane "
        "(y = center_m[1]); None: straight along +y (the front view).")

    @model_validator(mode="after")
    def _camera_in_front(self) -> ImageKind:
        _check_camera(self.camera_m, self.center_m)
        return self

    @field_validator("frames")
    @classmethod
    def _data_urls(cls, value: list[str]) -> list[str]:
        for k, text in enumerate(value):
            if len(text) > MAX_IMAGE_CHARS:
                raise PydanticCustomError(
                    "image_too_large", "frame {k} is {n} characters; the limit is {limit}",
                    {"k": k, "n": len(text), "limit": MAX_IMAGE_CHARS},
                )
            m = _DATA_URL.match(text)
            if m is None:
                raise PydanticCustomError(
                    "image_url", "frame {k} must be a data:image/png or data:image/jpeg base64 URL", {"k": k}
                )
            try:
                head = base64.b64decode(text[m.end():m.end() + 16], validate=True)
            except (binascii.Error, ValueError):
                raise PydanticCustomError("image_base64", "frame {k} is not valid base64", {"k": k}) from None
            if not (head.startswith(b"\x89PNG") or head.startswith(b"\xff\xd8")):
                raise PydanticCustomError("image_format", "frame {k} is neither a PNG nor a JPEG", {"k": k})
            w, h = image_size(text)
            if w * h > MAX_IMAGE_PIXELS:
                raise PydanticCustomError(
                    "image_pixels", "frame {k} is {w} x {h} pixels; the limit is {limit} pixels",
                    {"k": k, "w": w, "h": h, "limit": MAX_IMAGE_PIXELS},
                )
        return value


class VideoKind(BaseModel):
    """A video projected like ``image``: the frame shown at ``t - start_s`` into the video (looped),
    decoded with PyAV (FFmpeg) at up to :data:`MAX_VIDEO_FPS` frames per second and scaled down to
    at most :data:`MAX_VIDEO_WIDTH_PX` pixels wide (a drone covers far more than a pixel of it).
    ``video`` is a ``data:video/...;base64,`` URL (MP4, WebM, Ogg, QuickTime)."""

    model_config = _CONFIG
    kind: Literal["video"]
    video: str
    center_m: Point3
    width_m: float = Field(gt=0, le=100_000)
    height_m: float = Field(gt=0, le=100_000)
    camera_m: Point3 | None = Field(None, description="Audience camera, metres (as for ``image``).")

    @model_validator(mode="after")
    def _camera_in_front(self) -> VideoKind:
        _check_camera(self.camera_m, self.center_m)
        return self

    @field_validator("video")
    @classmethod
    def _video_url(cls, value: str) -> str:
        if len(value) > MAX_VIDEO_CHARS:
            raise PydanticCustomError("video_too_large", "the video is {n} characters of base64; the limit is "
                                      "{limit}", {"n": len(value), "limit": MAX_VIDEO_CHARS})
        m = _VIDEO_URL.match(value)
        if m is None:
            raise PydanticCustomError("video_url", "must be a data:video/mp4 (webm, ogg, quicktime) base64 URL")
        try:
            raw = base64.b64decode(value[m.end():], validate=True)
        except (binascii.Error, ValueError):
            raise PydanticCustomError("video_base64", "the video is not valid base64") from None
        problem = probe_video(raw)
        if problem is not None:
            raise PydanticCustomError("video_decode", "cannot read the video: {why}", {"why": problem})
        return value


@lru_cache(maxsize=256)
def image_size(data_url: str) -> tuple[int, int]:
    """(width, height) of a PNG/JPEG data URL, from its header only (no pixels decoded)."""
    import io

    from PIL import Image, UnidentifiedImageError

    try:
        raw = base64.b64decode(data_url.split(",", 1)[1], validate=True)
        with Image.open(io.BytesIO(raw)) as im:
            return int(im.width), int(im.height)
    except (UnidentifiedImageError, OSError, ValueError) as exc:  # binascii.Error is a ValueError
        raise PydanticCustomError("image_decode", "cannot read the image: {why}", {"why": str(exc)[:200]}) from None


def probe_video(raw: bytes) -> str | None:
    """Why ``raw`` is not a video PyAV can decode (None when it is): opens the container and decodes its
    first frame only, so a show file with a broken video is refused when it is loaded."""
    import io

    try:
        import av
    except ImportError:  # pragma: no cover - a runtime dependency
        return "video decoding needs PyAV (pip install av)"
    try:
        with av.open(io.BytesIO(raw), mode="r") as container:
            if not container.streams.video:
                return "it has no video stream"
            for _ in container.decode(video=0):
                return None
            return "it has no frames"
    except Exception as exc:
        return str(exc).splitlines()[0][:200] or type(exc).__name__


Kind = Annotated[
    SolidKind | RampKind | SweepKind | ChaseKind | SparkleKind | StrobeKind | ImageKind | VideoKind,
    Field(discriminator="kind"),
]
KINDS = ("solid", "ramp", "sweep", "chase", "sparkle", "strobe", "image", "video")
BLENDS = ("replace", "add", "multiply", "max")
TARGETS = ("all", "formation", "drones", "points", "group", "box", "plane")


class LightEffect(BaseModel):
    """One effect of the stack (see the module docstring)."""

    model_config = _CONFIG

    name: str = Field("", max_length=200)
    enabled: bool = True
    start_s: float = Field(ge=0, le=MAX_TIME_S, description="Start of the effect, seconds of show time.")
    end_s: float = Field(gt=0, le=MAX_TIME_S, description="End of the effect (exclusive), seconds.")
    fade_in_s: float = Field(0.0, ge=0, le=MAX_TIME_S)
    fade_out_s: float = Field(0.0, ge=0, le=MAX_TIME_S)
    blend: Literal["replace", "add", "multiply", "max"] = "replace"
    opacity: float = Field(1.0, ge=0, le=1)
    target: Target = Field(default_factory=TargetAll)
    effect: Kind

    @field_validator("name")
    @classmethod
    def _name_ok(cls, value: str) -> str:
        if _CONTROL.search(value):
            raise PydanticCustomError("name_control", "must not contain control characters")
        return value

    @model_validator(mode="after")
    def _times(self) -> LightEffect:
        if self.end_s <= self.start_s:
            raise PydanticCustomError(
                "effect_times", "end_s {end} must be after start_s {start}", {"end": self.end_s, "start": self.start_s}
            )
        if self.fade_in_s + self.fade_out_s > self.end_s - self.start_s + 1e-9:
            raise PydanticCustomError(
                "effect_fades", "fade_in_s + fade_out_s ({total}) is longer than the effect ({length} s)",
                {"total": self.fade_in_s + self.fade_out_s, "length": self.end_s - self.start_s},
            )
        return self


#: Named drone groups: name -> drone indices (0-based). One type for the show's top-level ``groups``
#: and the older ``lights.groups`` (both resolve through :func:`groups_problem` and the same lookup).
DroneGroups = dict[str, Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=1, max_length=20_000)]]


def check_group_names(value: dict[str, list[int]]) -> dict[str, list[int]]:
    """Field validator body for a :data:`DroneGroups` field: few groups, printable names."""
    if len(value) > MAX_GROUPS:
        raise PydanticCustomError("too_many_groups", "at most {n} groups", {"n": MAX_GROUPS})
    for name in value:
        if not name.strip() or _CONTROL.search(name) or len(name) > 200:
            raise PydanticCustomError("group_name", "group name {name!r} is empty, too long or has control "
                                      "characters", {"name": name})
    return value


def groups_problem(groups: dict[str, list[int]], drones: int, *,
                   unique: bool = True) -> tuple[tuple[str | int, ...], str] | None:
    """The first rule ``groups`` breaks against the drone count, as (path inside the groups, reason), or None:
    an index out of range or (``unique``: a group that formations fly must name each drone once) a drone
    listed twice in one group."""
    for name, idx in groups.items():
        bad = [i for i in idx if i >= drones]
        if bad:
            return (name,), f"drone index {bad[0]} is out of range for {drones} drones"
        if unique and len(set(idx)) != len(idx):
            seen: set[int] = set()
            for i in idx:
                if i in seen:
                    return (name,), f"drone {i} is listed twice in group {name!r}"
                seen.add(i)
    return None


class Lights(BaseModel):
    """The show's light design: named drone groups and the effect stack (bottom first).

    ``groups`` here is the older place for drone groups (kept so that older files load); new shows keep
    them in the show's top-level ``groups``, which light targets resolve as well.
    """

    model_config = _CONFIG

    groups: DroneGroups = Field(
        default_factory=dict, description="Named drone groups: name -> drone indices (0-based). Older files; "
        "new shows use the show's top-level 'groups'."
    )
    effects: Annotated[list[LightEffect], Field(max_length=MAX_EFFECTS)] = Field(default_factory=list)

    @field_validator("groups")
    @classmethod
    def _few_groups(cls, value: dict[str, list[int]]) -> dict[str, list[int]]:
        return check_group_names(value)


def lights_problem(
    lights: Lights, drones: int, formation_names: list[str], point_counts: list[int] | None = None,
    show_groups: dict[str, list[int]] | None = None,
) -> tuple[tuple[str | int, ...], str] | None:
    """The first rule ``lights`` breaks against the show (drone count, formation names, point
    counts and the show's top-level ``show_groups``), as (path inside ``lights``, reason), or None.
    Called by the show file's cross-field validator."""
    problem = groups_problem(lights.groups, drones, unique=False)  # older files: repeats were harmless
    if problem is not None:
        return ("groups", *problem[0]), problem[1]
    known = set(lights.groups) | set(show_groups or {})
    names = set(formation_names)
    pixels = 0
    videos = 0
    for k, fx in enumerate(lights.effects):
        if isinstance(fx.effect, ImageKind):
            pixels += sum(w * h for w, h in map(image_size, fx.effect.frames))
            if pixels > MAX_SHOW_IMAGE_PIXELS:
                return ("effects", k, "effect", "frames"), (
                    f"the show's images hold more than {MAX_SHOW_IMAGE_PIXELS} pixels together; use smaller "
                    "images or fewer frames")
        elif isinstance(fx.effect, VideoKind):
            videos += 1
            if videos > MAX_VIDEOS:
                return ("effects", k, "effect", "video"), f"at most {MAX_VIDEOS} video effects per show"
        t = fx.target
        if isinstance(t, TargetDrones):
            bad = [i for i in t.indices if i >= drones]
            if bad:
                return ("effects", k, "target", "indices"), f"drone index {bad[0]} is out of range for {drones} drones"
        elif isinstance(t, TargetGroup) and t.group not in known:
            return ("effects", k, "target", "group"), f"no drone group named {t.group!r} in groups"
        elif isinstance(t, TargetFormation | TargetPoints) and t.formation not in names:
            return ("effects", k, "target", "formation"), f"no formation named {t.formation!r}"
        if isinstance(t, TargetPoints) and point_counts is not None:
            m = point_counts[formation_names.index(t.formation)]
            bad = [i for i in t.indices if i >= m]
            if bad:
                return ("effects", k, "target", "indices"), (
                    f"point index {bad[0]} is out of range: formation {t.formation!r} has {m} points")
    return None


__all__ = [
    "DroneGroups",
    "check_group_names",
    "groups_problem",
    "BLENDS",
    "KINDS",
    "MAX_EFFECTS",
    "TARGETS",
    "ChaseKind",
    "ImageKind",
    "LightEffect",
    "Lights",
    "RampKind",
    "SolidKind",
    "SparkleKind",
    "StrobeKind",
    "SweepKind",
    "TargetAll",
    "TargetBox",
    "TargetDrones",
    "TargetFormation",
    "TargetGroup",
    "TargetPlane",
    "TargetPoints",
    "VideoKind",
    "lights_problem",
    "probe_video",
]
