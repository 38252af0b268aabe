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
    ChaseKind,
    ImageKind,
    LightEffect,
    Lights,
    RampKind,
    SolidKind,
    SparkleKind,
    StrobeKind,
    SweepKind,
    TargetAll,
    TargetBox,
    TargetDrones,
    TargetFormation,
    TargetGroup,
    TargetPlane,
)
from formations._show import hex_to_rgb
from sim.plan import ShowPlan

#: Most (frame, drone) cells evaluated at once: bounds memory to a few hundred MB whatever the show.
BLOCK_CELLS = 2_000_000
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


def _decode_frames(kind: ImageKind) -> list[np.ndarray]:
    """The image frames as (H, W, 4) float32 RGBA in [0, 1]."""
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
            frames.append(np.asarray(im.convert("RGBA"), dtype=np.float32) / 255.0)
    return frames


@dataclass
class _Prepared:
    """An effect with what its evaluation needs precomputed (all drones)."""

    fx: LightEffect
    rows: np.ndarray | None  # targeted drones (sorted), None: all
    windows: list[tuple[float, float]] | None  # formation target: when it applies
    rank: np.ndarray | None = None  # chase: each drone's place in [0, 1)
    stops: np.ndarray | None = None  # (K, 3) colours
    color: np.ndarray | None = None  # (3,) colour
    images: list[np.ndarray] | None = None


class LightStack:
    """A show's effect stack prepared against its plan; :meth:`apply` paints it over base colours.

    Args:
        lights: the show's ``lights`` (None: no effects).
        plan: the show's plan (segments for formation targets, positions for chase orders).
    """

    def __init__(self, lights: Lights | None, plan: ShowPlan) -> None:
        self.drone_count = plan.drone_count
        self._effects: list[_Prepared] = []
        windows = _formation_windows(plan)
        groups = lights.groups if lights is not None else {}
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
            p = _Prepared(fx, rows, win)
            k = fx.effect
            if isinstance(k, RampKind | SweepKind):
                p.stops = _stops(k.colors)
            elif isinstance(k, SolidKind | ChaseKind | SparkleKind | StrobeKind):
                p.color = _stops([k.color])[0]
            if isinstance(k, ChaseKind):
                p.rank = self._ranks(k, plan, fx.start_s)
            if isinstance(k, ImageKind):
                p.images = _decode_frames(k)
            self._effects.append(p)

    @classmethod
    def from_show(cls, show: ShowFile, plan: ShowPlan) -> LightStack:
        """The stack of ``show.lights`` over ``plan``."""
        return cls(show.lights, plan)

    def __bool__(self) -> bool:
        return bool(self._effects)

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
            (T, n, 3) float64 colours in [0, 1].
        """
        t = np.atleast_1d(np.asarray(times_s, dtype=np.float64))
        out = np.array(base_rgb, dtype=np.float32)
        if out.ndim != 3 or out.shape[0] != len(t) or out.shape[2] != 3:
            raise ValueError(f"base_rgb must be (T, n, 3) with T = {len(t)}, got {out.shape}")
        ids = np.arange(self.drone_count)[drones if drones is not None else slice(None)]
        if len(ids) != out.shape[1]:
            raise ValueError(f"base_rgb has {out.shape[1]} drones but drones selects {len(ids)}")
        if positions_m is None and self.needs_positions:
            raise ValueError("these effects need the drones' positions")
        for p in self._effects:
            self._paint(p, t, out, positions_m, ids)
        return out.astype(np.float64)

    def _paint(self, p: _Prepared, t: np.ndarray, out: np.ndarray, pos: np.ndarray | None, ids: np.ndarray) -> None:
        fx = p.fx
        frames = np.flatnonzero((t >= fx.start_s) & (t < fx.end_s))
        if not len(frames):
            return
        if p.rows is not None:
            cols = np.flatnonzero(np.isin(ids, p.rows))
            if not len(cols):
                return
        else:
            cols = None
        step = max(1, BLOCK_CELLS // max(out.shape[1] if cols is None else len(cols), 1))
        for a in range(0, len(frames), step):
            fr = frames[a:a + step]
            tt = t[fr]
            env = _envelope(fx, tt)  # (Tb,)
            if p.windows is not None:
                inside = np.zeros(len(tt), dtype=bool)
                for w0, w1 in p.windows:
                    inside |= (tt >= w0) & (tt < w1)
                env = env * inside
            sel = fr if cols is None else np.ix_(fr, cols)
            drone_ids = ids if cols is None else ids[cols]
            block_pos = None if pos is None else pos[sel]
            color, cover = self._kind(p, tt, drone_ids, block_pos)
            alpha = env[:, None].astype(np.float32) * np.float32(fx.opacity)
            if cover is not None:
                alpha = alpha * cover
            mask = _target_mask(fx, block_pos)
            if mask is not None:
                alpha = alpha * mask
            alpha = np.broadcast_to(alpha, (len(fr), len(drone_ids)))[..., None]
            below = out[sel]
            out[sel] = _blend(fx.blend, below, color, alpha)

    def _kind(
        self, p: _Prepared, t: np.ndarray, ids: np.ndarray, pos: np.ndarray | None
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """(colour broadcastable to (Tb, n, 3), coverage broadcastable to (Tb, n) or None)."""
        k, fx = p.fx.effect, p.fx
        if isinstance(k, SolidKind):
            assert p.color is not None
            return p.color[None, None, :], None
        if isinstance(k, RampKind):
            assert p.stops is not None
            s = np.clip((t - fx.start_s) / (fx.end_s - fx.start_s), 0.0, 1.0) * (len(p.stops) - 1)
            return _lerp_stops(p.stops, s, wrap=False)[:, None, :], None
        if isinstance(k, SweepKind):
            assert p.stops is not None and pos is not None
            if k.mode == "linear":
                d = np.asarray(k.axis) / np.linalg.norm(k.axis)
                along = pos @ d
            else:
                along = np.linalg.norm(pos - np.asarray(k.center_m), axis=-1)
            phase = (along - k.speed_mps * (t - fx.start_s)[:, None]) / k.length_m
            x = (phase - np.floor(phase)) * len(p.stops)
            return _lerp_stops(p.stops, x, wrap=True), None
        if isinstance(k, ChaseKind):
            assert p.color is not None and p.rank is not None
            head = (t - fx.start_s) / k.period_s
            rel = p.rank[ids][None, :] - head[:, None]
            rel -= np.floor(rel)  # in [0, 1)
            if k.shape == "wave":
                b = 0.5 * (1.0 + np.cos(2.0 * np.pi * rel))
            else:
                dist = np.minimum(rel, 1.0 - rel)
                b = np.clip(1.0 - dist / k.width, 0.0, 1.0)
            return p.color[None, None, :], b.astype(np.float32)
        if isinstance(k, SparkleKind):
            assert p.color is not None
            offset = uniform_hash(k.seed, ids, np.full(len(ids), -1))  # (n,) each drone's phase
            x = (t - fx.start_s)[:, None] / k.flash_s + offset[None, :]
            slot = np.floor(x)
            u = x - slot
            lit = uniform_hash(k.seed, ids[None, :], slot.astype(np.int64)) < k.density
            b = np.where(lit, 1.0 - np.abs(2.0 * u - 1.0), 0.0)
            return p.color[None, None, :], b.astype(np.float32)
        if isinstance(k, StrobeKind):
            assert p.color is not None
            x = (t - fx.start_s) * k.frequency_hz
            on = (x - np.floor(x)) < k.duty
            return p.color[None, None, :], on.astype(np.float32)[:, None]
        if isinstance(k, ImageKind):
            assert p.images is not None and pos is not None
            return _project(k, p.images, t - fx.start_s, pos)
        raise AssertionError(f"unknown effect kind {k!r}")  # pragma: no cover - the models are closed


def _needs_positions(fx: LightEffect) -> bool:
    return isinstance(fx.target, TargetBox | TargetPlane) or isinstance(fx.effect, SweepKind | ImageKind)


def _envelope(fx: LightEffect, t: np.ndarray) -> np.ndarray:
    """Fade-in x fade-out in [0, 1] at times t inside the effect (linear ramps)."""
    env = np.ones(len(t))
    if fx.fade_in_s > 0:
        env = np.minimum(env, (t - fx.start_s) / fx.fade_in_s)
    if fx.fade_out_s > 0:
        env = np.minimum(env, (fx.end_s - t) / fx.fade_out_s)
    return np.clip(env, 0.0, 1.0)


def _target_mask(fx: LightEffect, pos: np.ndarray | None) -> np.ndarray | None:
    """(Tb, n) float32 1/0 for position-dependent targets, else None."""
    t = fx.target
    if isinstance(t, TargetBox):
        assert pos is not None
        lo, hi = np.asarray(t.min_m), np.asarray(t.max_m)
        inside: np.ndarray = np.all((pos >= lo) & (pos <= hi), axis=-1)
        return inside.astype(np.float32)
    if isinstance(t, TargetPlane):
        assert pos is not None
        front: np.ndarray = (pos - np.asarray(t.point_m)) @ np.asarray(t.normal) >= 0.0
        return front.astype(np.float32)
    assert isinstance(t, TargetAll | TargetDrones | TargetGroup | TargetFormation)
    return None


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


def _project(kind: ImageKind, images: list[np.ndarray], since_s: np.ndarray,
             pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each drone's pixel of the frame shown at its time: (colour (Tb, n, 3), coverage (Tb, n)).

    The rectangle spans x in cx +- w/2 (left to right as the audience sees it) and z in
    cz +- h/2 (top row at the top); a drone at (x, z) covers pixel (floor(u W), floor(v H)) with
    u = (x - x_left) / w, v = (z_top - z) / h, when both are in [0, 1).
    """
    cx, _, cz = kind.center_m
    u = (pos[..., 0] - (cx - kind.width_m / 2.0)) / kind.width_m
    v = ((cz + kind.height_m / 2.0) - pos[..., 2]) / kind.height_m
    inside = (u >= 0) & (u < 1) & (v >= 0) & (v < 1)
    which = np.floor(since_s * kind.fps + 1e-9).astype(np.int64) % len(images)
    color = np.zeros(pos.shape[:2] + (3,), dtype=np.float32)
    cover = np.zeros(pos.shape[:2], dtype=np.float32)
    for f in np.unique(which):
        img = images[f]
        h, w = img.shape[:2]
        rows = np.flatnonzero(which == f)
        uu, vv = u[rows], v[rows]
        col = np.clip(np.floor(uu * w).astype(np.int64), 0, w - 1)
        row = np.clip(np.floor(vv * h).astype(np.int64), 0, h - 1)
        px = img[row, col]  # (r, n, 4)
        color[rows] = px[..., :3]
        cover[rows] = px[..., 3] * inside[rows]
    return color, cover


def _blend(mode: str, below: np.ndarray, color: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """``below`` (Tb, n, 3) with ``color`` blended in at opacity ``alpha`` (Tb, n, 1), clipped to [0, 1]."""
    if mode == "replace":
        out = below + alpha * (color - below)
    elif mode == "add":
        out = below + alpha * color
    elif mode == "multiply":
        out = below * (1.0 - alpha + alpha * color)
    else:  # max
        out = below + alpha * (np.maximum(below, color) - below)
    clipped: np.ndarray = np.clip(out, 0.0, 1.0)
    return clipped


def base_colors(plan: ShowPlan, times_s: ArrayLike, drones: slice | np.ndarray | None = None) -> np.ndarray:
    """The plan's own colours (linear fades between knots), (T, n, 3) in [0, 1] (as ``ShowPlan.evaluate``)."""
    t = np.atleast_1d(np.asarray(times_s, dtype=np.float64))
    sel = slice(None) if drones is None else drones
    k = plan.segment_index(t)
    t0, t1 = plan.knot_times_s[k], plan.knot_times_s[k + 1]
    tau = np.clip((t - t0) / np.where(t1 > t0, t1 - t0, 1.0), 0.0, 1.0)[:, None, None]
    c = plan.knot_colors_rgb[:, sel]
    out: np.ndarray = c[k] + tau * (c[k + 1] - c[k])
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
        (T, n, 3) float64 colours in [0, 1].
    """
    t = np.atleast_1d(np.asarray(times_s, dtype=np.float64))
    base = base_colors(plan, t, drones)
    st = stack if stack is not None else LightStack.from_show(show, plan)
    if not st or not st.active(float(t.min(initial=0.0)), float(t.max(initial=0.0))):
        return base
    if positions_m is None and st.needs_positions:
        # Only the frames some position-reading effect covers (the rest are never read).
        need = st.position_frames(t)
        positions_m = np.zeros(base.shape)
        if need.any():
            positions_m[need] = plan.motion.evaluate(t[need], drones, derivatives=0).positions_m
    return st.apply(t, base, positions_m, drones)


__all__ = ["BLOCK_CELLS", "LightStack", "base_colors", "mix64", "show_colors", "uniform_hash"]
