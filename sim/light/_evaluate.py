"""LED colours per drone per frame: the plan's base colours with the show's effect stack on top.

Everything is vectorised over drones and frames: an effect is evaluated only on the frames of
its time range and the drones of its target, in (T, n) blocks of float32 (colour channels last),
so a 5,000-drone, 10-minute show at 25 fps costs a few passes over memory per effect. Blend
modes and targets are defined in :mod:`formations._effects`.
"""

from __future__ import annotations

import base64
import io
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from formations import ShowFile
from formations._effects import (
    MAX_VIDEO_FPS,
    MAX_VIDEO_FRAMES,
    MAX_VIDEO_WIDTH_PX,
    ChaseKind,
    ImageKind,
    LightEffect,
    Lights,
    RampKind,
    SolidKind,
    SparkleKind,
    StrobeKind,
    SweepKind,
    TargetBox,
    TargetDrones,
    TargetFormation,
    TargetGroup,
    TargetPlane,
    TargetPoints,
    VideoKind,
)
from formations._show import hex_to_rgb
from sim.light import _kernels as _k
from sim.plan import ShowPlan

#: Largest decoded image frame, pixels (a 4K frame); bigger ones are scaled down on decoding.
MAX_IMAGE_PIXELS = 3840 * 2160

_M64 = np.uint64(0xFFFFFFFFFFFFFFFF)


def mix64(x: np.ndarray) -> np.ndarray:
    """SplitMix64's finaliser (Steele, Lea & Flood, 2014) on uint64 arrays: a well-mixed hash."""
    x = x.astype(np.uint64, copy=True)
    with np.errstate(over="ignore"):
        x ^= x >> np.uint64(30)
        x *= np.uint64(0xBF58476D1CE4E5B9)
        x ^= x >> np.uint64(27)
        x *= np.uint64(0x94D049BB133111EB)
        x ^= x >> np.uint64(31)
    return x


def uniform_hash(seed: int, drone: np.ndarray, slot: np.ndarray) -> np.ndarray:
    """A uniform number in [0, 1) for each (seed, drone, slot), broadcast; repeatable.

    ``mix64(mix64(seed << 32 | drone) + slot)`` (mod 2^64, slot as two's-complement uint64);
    the top 53 bits give the fraction.
    """
    d = np.asarray(drone).astype(np.int64).astype(np.uint64)
    s = np.asarray(slot).astype(np.int64).astype(np.uint64)
    with np.errstate(over="ignore"):
        h = mix64(mix64((np.uint64(seed) << np.uint64(32)) | d) + s)
    return (h >> np.uint64(11)).astype(np.float64) / float(2**53)


def _stops(colors: list[str]) -> np.ndarray:
    return hex_to_rgb(colors).astype(np.float32)


def _formation_windows(plan: ShowPlan) -> dict[str, list[tuple[float, float]]]:
    """Formation name -> [(start of the transition into it, end of its hold)], seconds."""
    out: dict[str, list[tuple[float, float]]] = {}
    start: float | None = None
    for seg in plan.segments:
        if seg.kind == "transition":
            start = seg.start_s
        elif seg.kind == "hold":
            out.setdefault(seg.label, []).append((seg.start_s if start is None else start, seg.end_s))
            start = None
    return out


def _idle_windows(plan: ShowPlan) -> list[tuple[float, float, np.ndarray]]:
    """[(start of the transition into a subset formation, end of its hold, (m,) its idle drones)], seconds.

    Drones that do not fly a formation (issue 21: subset formations, ``goal_index`` -1) are dark there,
    and effects leave them dark.
    """
    ends = {seg.index - 1: seg.end_s for seg in plan.segments if seg.kind == "hold"}
    out = []
    for tr in plan.transitions:
        idle = np.flatnonzero(tr.goal_index < 0)
        if len(idle) and tr.segment in ends:
            out.append((tr.start_s, ends[tr.segment], idle))
    return out


def _drones_at_points(plan: ShowPlan, formation: str, points: list[int]) -> np.ndarray:
    """(m,) sorted drones that CAPT sent to ``points`` of the first formation named ``formation``."""
    for tr in plan.transitions:
        if tr.to_name == formation:
            return np.flatnonzero(np.isin(tr.goal_index, np.asarray(points, dtype=np.int64)))
    return np.zeros(0, dtype=np.int64)


def _decode_frames(kind: ImageKind) -> list[np.ndarray]:
    """The image frames as (H, W, 4) uint8 RGBA."""
    from PIL import Image

    frames = []
    for url in kind.frames:
        raw = base64.b64decode(url.split(",", 1)[1])
        with Image.open(io.BytesIO(raw)) as opened:
            opened.draft("RGB", (3840, 2160))  # JPEG: decode at reduced size when huge
            im: Image.Image = opened
            if im.width * im.height > MAX_IMAGE_PIXELS:
                scale = (MAX_IMAGE_PIXELS / (im.width * im.height)) ** 0.5
                im = im.resize((max(1, int(im.width * scale)), max(1, int(im.height * scale))))
            frames.append(np.asarray(im.convert("RGBA"), dtype=np.uint8))
    return frames


def decode_video(kind: VideoKind) -> tuple[list[np.ndarray], float]:
    """A video's frames sampled at up to ``MAX_VIDEO_FPS`` as (H, W, 4) uint8 RGBA, at most
    ``MAX_VIDEO_WIDTH_PX`` wide and ``MAX_VIDEO_FRAMES`` many, and their rate (frames per second).

    Frame k is the last decoded frame whose timestamp is at or before k / rate (PyAV / FFmpeg
    decode; the stream's own timestamps, so variable frame rates play at their real times).
    """
    import av

    raw = base64.b64decode(kind.video.split(",", 1)[1])
    frames: list[np.ndarray] = []
    with av.open(io.BytesIO(raw), mode="r") as container:
        stream = container.streams.video[0]
        native = float(stream.average_rate) if stream.average_rate else MAX_VIDEO_FPS
        rate = min(native, MAX_VIDEO_FPS)
        width = stream.codec_context.width or MAX_VIDEO_WIDTH_PX
        height = stream.codec_context.height or MAX_VIDEO_WIDTH_PX
        scale = min(1.0, MAX_VIDEO_WIDTH_PX / width, MAX_VIDEO_WIDTH_PX / height)
        size = (max(1, round(width * scale)), max(1, round(height * scale)))
        last: np.ndarray | None = None
        for frame in container.decode(video=0):
            t = float(frame.time) if frame.time is not None else len(frames) / rate
            image = frame.to_ndarray(format="rgba", width=size[0], height=size[1])
            # Fill every sample time up to this frame's with the frame before it, then this one.
            while last is not None and len(frames) < MAX_VIDEO_FRAMES and (len(frames)) / rate < t - 1e-6:
                frames.append(last)
            if len(frames) >= MAX_VIDEO_FRAMES:
                break
            last = image
        if last is not None and len(frames) < MAX_VIDEO_FRAMES:
            frames.append(last)
    if not frames:
        raise ValueError("the video has no frames")
    return frames, rate


def _stack_frames(frames: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Frames of different sizes in one zero-padded (F, H, W, 4) array, and their (F, 2) sizes."""
    sizes = np.array([f.shape[:2] for f in frames], dtype=np.int64)
    stack = np.zeros((len(frames), int(sizes[:, 0].max()), int(sizes[:, 1].max()), 4), dtype=np.uint8)
    for j, f in enumerate(frames):
        stack[j, : f.shape[0], : f.shape[1]] = f
    return stack, sizes


@dataclass
class _Prepared:
    """An effect with what its evaluation needs precomputed (all drones)."""

    fx: LightEffect
    rows: np.ndarray | None  # targeted drones (sorted), None: all
    windows: list[tuple[float, float]] | None  # formation target: when it applies
    rank: np.ndarray | None = None  # chase: each drone's place in [0, 1)
    stops: np.ndarray | None = None  # (K, 3) colours
    color: np.ndarray | None = None  # (3,) colour
    image_stack: tuple[np.ndarray, np.ndarray] | None = None  # (F, H, W, 4) padded frames, (F, 2) sizes
    video_fps: float = 0.0  # video: the rate its frames were sampled at


class LightStack:
    """A show's effect stack prepared against its plan; :meth:`apply` paints it over base colours.

    Args:
        lights: the show's ``lights`` (None: no effects).
        plan: the show's plan (segments for formation targets, positions for chase orders).
    """

    def __init__(self, lights: Lights | None, plan: ShowPlan, groups: dict[str, list[int]] | None = None) -> None:
        self.drone_count = plan.drone_count
        self._effects: list[_Prepared] = []
        self._idle = _idle_windows(plan)
        windows = _formation_windows(plan)
        # The show's groups (``groups``) over the older ``lights.groups``: one lookup (ShowFile.drone_groups).
        groups = {**(lights.groups if lights is not None else {}), **(groups or {})}
        for fx in lights.effects if lights is not None else []:
            if not fx.enabled or fx.opacity <= 0.0:
                continue
            t = fx.target
            rows: np.ndarray | None = None
            win: list[tuple[float, float]] | None = None
            if isinstance(t, TargetDrones):
                rows = np.unique(np.asarray(t.indices, dtype=np.int64))
            elif isinstance(t, TargetGroup):
                rows = np.unique(np.asarray(groups[t.group], dtype=np.int64))
            elif isinstance(t, TargetFormation):
                win = windows.get(t.formation, [])
            elif isinstance(t, TargetPoints):
                rows = _drones_at_points(plan, t.formation, t.indices)
            p = _Prepared(fx, rows, win)
            k = fx.effect
            if isinstance(k, RampKind | SweepKind):
                p.stops = _stops(k.colors)
            elif isinstance(k, SolidKind | ChaseKind | SparkleKind | StrobeKind):
                p.color = _stops([k.color])[0]
            if isinstance(k, ChaseKind):
                p.rank = self._ranks(k, plan, fx.start_s)
            if isinstance(k, ImageKind):
                p.image_stack = _stack_frames(_decode_frames(k))
            elif isinstance(k, VideoKind):
                frames, p.video_fps = decode_video(k)
                p.image_stack = _stack_frames(frames)
            self._effects.append(p)

    @classmethod
    def from_show(cls, show: ShowFile, plan: ShowPlan) -> LightStack:
        """The stack of ``show.lights`` over ``plan`` (group targets resolve the show's groups)."""
        return cls(show.lights, plan, show.drone_groups)

    def __bool__(self) -> bool:
        return bool(self._effects)

    @property
    def effect_count(self) -> int:
        """How many effects are painted (enabled, with some opacity)."""
        return len(self._effects)

    @property
    def needs_positions(self) -> bool:
        """Whether some effect reads drone positions (box / plane targets, sweeps, images)."""
        return any(_needs_positions(p.fx) for p in self._effects)

    def _ranks(self, kind: ChaseKind, plan: ShowPlan, start_s: float) -> np.ndarray:
        n = self.drone_count
        if kind.order == "index":
            return np.arange(n) / n
        axis = "xyz".index(kind.order)
        pos = plan.motion.evaluate([start_s], derivatives=0).positions_m[0, :, axis]
        rank = np.empty(n)
        rank[np.argsort(pos, kind="stable")] = np.arange(n)
        return rank / n

    def position_frames(self, times_s: np.ndarray) -> np.ndarray:
        """(T,) bool: the frames at which some effect reads positions."""
        need = np.zeros(len(times_s), dtype=bool)
        for p in self._effects:
            if _needs_positions(p.fx):
                need |= (times_s >= p.fx.start_s) & (times_s < p.fx.end_s)
        return need

    def active(self, t0_s: float, t1_s: float) -> bool:
        """Whether some effect overlaps [t0_s, t1_s]."""
        return any(p.fx.start_s <= t1_s and p.fx.end_s > t0_s for p in self._effects)

    def apply(
        self,
        times_s: ArrayLike,
        base_rgb: np.ndarray,
        positions_m: np.ndarray | None = None,
        drones: slice | np.ndarray | None = None,
    ) -> np.ndarray:
        """The colours with every effect painted over ``base_rgb``.

        Args:
            times_s: (T,) show times, seconds.
            base_rgb: (T, n, 3) base colours in [0, 1] of the drones ``drones``.
            positions_m: (T, n, 3) their positions, metres; needed when :attr:`needs_positions`.
            drones: which drones the n columns are (slice or index array; default all).

        Returns:
            (T, n, 3) float32 colours in [0, 1] (``base_rgb`` itself when it is float32: painted in place).
        """
        t = np.atleast_1d(np.asarray(times_s, dtype=np.float64))
        out = np.asarray(base_rgb, dtype=np.float32)
        if out.ndim != 3 or out.shape[0] != len(t) or out.shape[2] != 3:
            raise ValueError(f"base_rgb must be (T, n, 3) with T = {len(t)}, got {out.shape}")
        ids = np.arange(self.drone_count)[drones if drones is not None else slice(None)]
        if len(ids) != out.shape[1]:
            raise ValueError(f"base_rgb has {out.shape[1]} drones but drones selects {len(ids)}")
        if positions_m is None and self.needs_positions:
            raise ValueError("these effects need the drones' positions")
        kept = []
        for t0, t1, idle in self._idle if self._effects else []:
            frames = np.flatnonzero((t >= t0) & (t < t1))
            cols = np.flatnonzero(np.isin(ids, idle))
            if len(frames) and len(cols):
                kept.append((frames, cols, out[np.ix_(frames, cols)].copy()))
        for p in self._effects:
            self._paint(p, t, out, positions_m, ids)
        for frames, cols, base in kept:  # drones out of a subset formation stay as dark as the plan has them
            out[np.ix_(frames, cols)] = base
        return out

    def _paint(self, p: _Prepared, t: np.ndarray, out: np.ndarray, pos: np.ndarray | None, ids: np.ndarray) -> None:
        """Paint effect ``p`` into ``out`` (T, n, 3) float32 in place: per-frame parts in numpy, the
        per-drone part in :func:`sim.light._kernels.paint`."""
        fx = p.fx
        frames = np.flatnonzero((t >= fx.start_s) & (t < fx.end_s))
        if not len(frames):
            return
        cols = np.arange(len(ids)) if p.rows is None else np.flatnonzero(np.isin(ids, p.rows))
        if not len(cols):
            return
        tt = t[frames]
        alpha = _envelope(fx, tt) * fx.opacity
        if p.windows is not None:
            inside = np.zeros(len(tt), dtype=bool)
            for w0, w1 in p.windows:
                inside |= (tt >= w0) & (tt < w1)
            alpha = alpha * inside
        k = fx.effect
        rgb = np.zeros((len(tt), 3))
        kprm = np.zeros(12)
        kprm[0] = fx.start_s
        code = _k.K_FLAT
        if isinstance(k, SolidKind | ChaseKind | SparkleKind | StrobeKind):
            assert p.color is not None
            rgb[:] = p.color
        if isinstance(k, RampKind):
            assert p.stops is not None
            x = np.clip((tt - fx.start_s) / (fx.end_s - fx.start_s), 0.0, 1.0) * (len(p.stops) - 1)
            rgb = _lerp_stops(p.stops, x, wrap=False)
        elif isinstance(k, StrobeKind):
            x = (tt - fx.start_s) * k.frequency_hz
            alpha = alpha * ((x - np.floor(x)) < k.duty)
        elif isinstance(k, SweepKind):
            code = _k.K_SWEEP_LINEAR if k.mode == "linear" else _k.K_SWEEP_RADIAL
            vec = np.asarray(k.axis) / np.linalg.norm(k.axis) if k.mode == "linear" else np.asarray(k.center_m)
            kprm[2:7] = [k.speed_mps, k.length_m, *vec]
        elif isinstance(k, ChaseKind):
            code = _k.K_CHASE_WAVE if k.shape == "wave" else _k.K_CHASE_PULSE
            kprm[2:4] = [k.period_s, k.width]
        elif isinstance(k, SparkleKind):
            code = _k.K_SPARKLE
            kprm[2:4] = [k.flash_s, k.density]
        elif isinstance(k, ImageKind | VideoKind):
            code = _k.K_IMAGE
            cx, _, cz = k.center_m
            fps = k.fps if isinstance(k, ImageKind) else p.video_fps
            kprm[1:6] = [fps, cx - k.width_m / 2.0, cz + k.height_m / 2.0, k.width_m, k.height_m]
            if k.camera_m is not None:
                kprm[6:11] = [1.0, *k.camera_m, k.center_m[1]]
        tgt, tprm = _k.T_NONE, np.zeros(6)
        if isinstance(fx.target, TargetBox):
            tgt, tprm = _k.T_BOX, np.r_[fx.target.min_m, fx.target.max_m]
        elif isinstance(fx.target, TargetPlane):
            tgt, tprm = _k.T_PLANE, np.r_[fx.target.point_m, fx.target.normal]
        images, sizes = p.image_stack if p.image_stack is not None else (_NO_IMAGE, np.ones((1, 2), np.int64))
        _k.paint(
            out, pos if pos is not None else _NO_POS, t, frames, alpha.astype(np.float64), rgb.astype(np.float64),
            cols.astype(np.int64), ids[cols].astype(np.int64), _BLENDS[fx.blend], code, tgt, tprm, kprm,
            (p.stops if p.stops is not None else np.zeros((1, 3))).astype(np.float64),
            p.rank if p.rank is not None else np.zeros(1), np.int64(getattr(k, "seed", 0)), images, sizes,
        )


_BLENDS = {"replace": _k.B_REPLACE, "add": _k.B_ADD, "multiply": _k.B_MULTIPLY, "max": _k.B_MAX}
_NO_POS = np.zeros((1, 1, 3))
_NO_IMAGE = np.zeros((1, 1, 1, 4), dtype=np.uint8)


def _needs_positions(fx: LightEffect) -> bool:
    return isinstance(fx.target, TargetBox | TargetPlane) or isinstance(fx.effect, SweepKind | ImageKind | VideoKind)


def _envelope(fx: LightEffect, t: np.ndarray) -> np.ndarray:
    """Fade-in x fade-out in [0, 1] at times t inside the effect (linear ramps)."""
    env = np.ones(len(t))
    with np.errstate(over="ignore"):  # a subnormal fade length is a step
        return _ramps(fx, t, env)


def _ramps(fx: LightEffect, t: np.ndarray, env: np.ndarray) -> np.ndarray:
    if fx.fade_in_s > 0:
        env = np.minimum(env, (t - fx.start_s) / fx.fade_in_s)
    if fx.fade_out_s > 0:
        env = np.minimum(env, (fx.end_s - t) / fx.fade_out_s)
    out: np.ndarray = np.clip(env, 0.0, 1.0)
    return out


def _lerp_stops(stops: np.ndarray, x: np.ndarray, *, wrap: bool) -> np.ndarray:
    """Colours at fractional stop positions x (any shape) -> x.shape + (3,), float32.

    ``wrap``: x in [0, K) and the last stop fades back into the first; else x in [0, K-1].
    """
    k_count = len(stops)
    k = np.floor(x).astype(np.int64)
    k = np.clip(k, 0, k_count - 1 if wrap else k_count - 2)
    w = (x - k).astype(np.float32)[..., None]
    nxt = (k + 1) % k_count if wrap else k + 1
    out: np.ndarray = stops[k] * (1.0 - w) + stops[nxt] * w
    return out


def base_colors(plan: ShowPlan, times_s: ArrayLike, drones: slice | np.ndarray | None = None) -> np.ndarray:
    """The plan's own colours (linear fades between knots, as ``ShowPlan.evaluate``), (T, n, 3) float32
    in [0, 1]."""
    t = np.ascontiguousarray(np.atleast_1d(np.asarray(times_s, dtype=np.float64)))
    rows = np.arange(plan.drone_count)[slice(None) if drones is None else drones].astype(np.int64)
    out = np.empty((len(t), len(rows), 3), dtype=np.float32)
    _k.base_into(np.ascontiguousarray(plan.knot_times_s, dtype=np.float64),
                 np.ascontiguousarray(plan.knot_colors_rgb, dtype=np.float64), rows, t, out)
    return out


def plan_positions(plan: ShowPlan, times_s: np.ndarray, drones: slice | np.ndarray | None = None, *,
                   frames: np.ndarray | None = None) -> np.ndarray:
    """(T, n, 3) planned positions, metres, at the (increasing) ``times_s``; only ``frames`` filled
    (the rest zero) when given. A numba pass per drone stepping through its pieces."""
    t = np.ascontiguousarray(times_s, dtype=np.float64)
    rows = np.arange(plan.drone_count)[slice(None) if drones is None else drones].astype(np.int64)
    fr = np.arange(len(t)) if frames is None else np.asarray(frames, dtype=np.int64)
    if len(fr) > 1 and np.any(np.diff(t[fr]) < 0):
        order = fr[np.argsort(t[fr], kind="stable")]
    else:
        order = fr
    out = np.zeros((len(t), len(rows), 3))
    motion = plan.motion
    _k.positions_at(np.ascontiguousarray(motion.breaks_s), np.ascontiguousarray(motion.coeffs_m), rows, t,
                    order.astype(np.int64), out)
    return out


def show_colors(
    show: ShowFile,
    plan: ShowPlan,
    times_s: ArrayLike,
    *,
    drones: slice | np.ndarray | None = None,
    positions_m: np.ndarray | None = None,
    stack: LightStack | None = None,
) -> np.ndarray:
    """Every (selected) drone's LED colour at ``times_s``: base colours plus the effect stack.

    Args:
        show: the show (its ``lights``).
        plan: its plan.
        times_s: (T,) times, seconds.
        drones: a subset of drones (slice or index array), default all.
        positions_m: (T, n, 3) their positions if already known (evaluated from the plan otherwise,
            and only when an effect needs them).
        stack: a prepared :class:`LightStack` (saves decoding images again).

    Returns:
        (T, n, 3) float32 colours in [0, 1].
    """
    t = np.atleast_1d(np.asarray(times_s, dtype=np.float64))
    base = base_colors(plan, t, drones)
    st = stack if stack is not None else LightStack.from_show(show, plan)
    if not st or not st.active(float(t.min(initial=0.0)), float(t.max(initial=0.0))):
        return base
    if positions_m is None and st.needs_positions:
        # Only the frames some position-reading effect covers (the rest are never read).
        positions_m = plan_positions(plan, t, drones, frames=np.flatnonzero(st.position_frames(t)))
    return st.apply(t, base, positions_m, drones)


__all__ = ["LightStack", "base_colors", "mix64", "plan_positions", "show_colors", "uniform_hash"]
