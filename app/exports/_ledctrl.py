"""Skybrush ``ledctrl`` light programs fitted to the evaluated colours: fades and holds, not frames.

The bytecode (Skybrush's published ``ledctrl`` format, as pyledctrl's ``CommandCode`` lists it;
written here from that format, no code taken): one opcode byte, then its arguments; colours are
three bytes r, g, b; durations are unsigned LEB128 varints in frames of 1/50 s.

=====  ===================  =================================================
0x00   END
0x02   SLEEP d              keep the colour for d frames
0x04   SET_COLOR r g b d    set the colour, keep it for d frames
0x05   SET_GRAY v d         r = g = b = v
0x06   SET_BLACK d
0x07   SET_WHITE d
0x08   FADE_TO_COLOR r g b d  linear fade from the current colour over d frames
0x09   FADE_TO_GRAY v d
0x0A   FADE_TO_BLACK d
0x0B   FADE_TO_WHITE d
=====  ===================  =================================================

:func:`fit_fades` turns a drone's colour track sampled at 50 Hz (0-255 floats) into integer
keyframes joined by straight lines that stay within ``tolerance`` of every sample: greedy, each
segment as long as the cone of slopes through all its samples (per channel) stays open and an
integer end colour lies inside it (the "swinging door" of process-historian compression,
Bristol 1990, with integer ends). With ``tolerance`` 0.5 the replayed program rounds to within
1 colour level of the effect stack at every frame. :func:`encode_keyframes` writes holds as
SLEEP (or folded into the SET before them) and slopes as FADE.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numba as nb
import numpy as np

from app.exports._core import ExportError

if TYPE_CHECKING:
    from formations import ShowFile
    from sim import ShowPlan

#: Light-program frame rate (``ledctrl`` durations are in frames), frames per second.
LIGHT_FPS = 50
#: Largest deviation of the fitted program from the colour track, colour levels (0-255).
TOLERANCE_LEVELS = 0.5

OP_END = 0x00
OP_SLEEP = 0x02
OP_SET_COLOR = 0x04
OP_SET_GRAY = 0x05
OP_SET_BLACK = 0x06
OP_SET_WHITE = 0x07
OP_FADE_TO_COLOR = 0x08
OP_FADE_TO_GRAY = 0x09
OP_FADE_TO_BLACK = 0x0A
OP_FADE_TO_WHITE = 0x0B


@nb.njit(cache=True, nogil=True)
def _fit(track: np.ndarray, tol: float, out_f: np.ndarray, out_c: np.ndarray) -> int:  # pragma: no cover
    """Keyframes of one track (F, 3) into out_f (F,), out_c (F, 3); returns their count."""
    n = track.shape[0]
    qi = np.empty(3)
    for c in range(3):
        qi[c] = min(255.0, max(0.0, np.floor(track[0, c] + 0.5)))
    out_f[0] = 0
    out_c[0] = qi
    count = 1
    i = 0
    lo = np.empty(3)
    hi = np.empty(3)
    q = np.empty(3)
    best_q = np.empty(3)
    while i < n - 1:
        lo[:] = -np.inf
        hi[:] = np.inf
        best_j = i + 1
        for c in range(3):
            best_q[c] = min(255.0, max(0.0, np.floor(track[i + 1, c] + 0.5)))
        for j in range(i + 1, n):
            length = j - i
            empty = False
            for c in range(3):
                lo[c] = max(lo[c], (track[j, c] - tol - qi[c]) / length)
                hi[c] = min(hi[c], (track[j, c] + tol - qi[c]) / length)
                if lo[c] > hi[c]:
                    empty = True
            if empty:
                break
            ok = True
            for c in range(3):
                a = np.ceil(qi[c] + lo[c] * length - 1e-9)
                b = np.floor(qi[c] + hi[c] * length + 1e-9)
                if a > b:
                    ok = False
                    break
                q[c] = min(max(np.floor(track[j, c] + 0.5), a), b)
            if ok:
                best_j = j
                best_q[:] = q
        out_f[count] = best_j
        out_c[count] = best_q
        count += 1
        i = best_j
        qi[:] = best_q
    return count


def fit_fades(track: np.ndarray, tolerance: float = TOLERANCE_LEVELS) -> tuple[np.ndarray, np.ndarray]:
    """Integer keyframes of a colour track.

    Args:
        track: (F, 3) colours at frames 0..F-1, 0-255 floats.
        tolerance: largest allowed deviation at any frame, colour levels.

    Returns:
        ``(frames (K,) int64, colors (K, 3) int64)``: frame 0 first, frame F-1 last; between two
        keyframes the colour is the straight line between them (within ``tolerance`` of the track).
    """
    tr = np.ascontiguousarray(track, dtype=np.float64)
    if tr.ndim != 2 or tr.shape[1] != 3 or not len(tr):
        raise ValueError(f"track must be (F, 3) with F >= 1, got {tr.shape}")
    out_f = np.empty(len(tr), dtype=np.int64)
    out_c = np.empty((len(tr), 3))
    k = _fit(tr, float(tolerance), out_f, out_c)
    return out_f[:k].copy(), out_c[:k].astype(np.int64)


def varuint(value: int) -> bytes:
    """Unsigned LEB128: 7 bits per byte, low first, high bit set on all but the last."""
    out = bytearray()
    while True:
        byte = value & 0x7F
        value >>= 7
        if value:
            out.append(byte | 0x80)
        else:
            out.append(byte)
            return bytes(out)


@nb.njit(cache=True, inline="always")
def _put_varuint(buf: np.ndarray, at: int, value: int) -> int:  # pragma: no cover - compiled
    while True:
        byte = value & 0x7F
        value >>= 7
        if value:
            buf[at] = byte | 0x80
            at += 1
        else:
            buf[at] = byte
            return at + 1


@nb.njit(cache=True, inline="always")
def _put_op(buf: np.ndarray, at: int, fade: bool, r: int, g: int, b: int,
            frames: int) -> int:  # pragma: no cover - compiled
    """SET / FADE of a colour, in the shortest form (black, white and greys need no three bytes)."""
    if r == g and g == b:
        if r == 0:
            buf[at] = OP_FADE_TO_BLACK if fade else OP_SET_BLACK
            return _put_varuint(buf, at + 1, frames)
        if r == 255:
            buf[at] = OP_FADE_TO_WHITE if fade else OP_SET_WHITE
            return _put_varuint(buf, at + 1, frames)
        buf[at] = OP_FADE_TO_GRAY if fade else OP_SET_GRAY
        buf[at + 1] = r
        return _put_varuint(buf, at + 2, frames)
    buf[at] = OP_FADE_TO_COLOR if fade else OP_SET_COLOR
    buf[at + 1] = r
    buf[at + 2] = g
    buf[at + 3] = b
    return _put_varuint(buf, at + 4, frames)


@nb.njit(cache=True, inline="always")
def _same(colors: np.ndarray, a: int, b: int) -> bool:  # pragma: no cover - compiled
    return bool(colors[a, 0] == colors[b, 0] and colors[a, 1] == colors[b, 1] and colors[a, 2] == colors[b, 2])


@nb.njit(cache=True, nogil=True)
def _encode(frames: np.ndarray, colors: np.ndarray, buf: np.ndarray) -> int:  # pragma: no cover - compiled
    """Bytecode of the keyframes into buf; returns its length. Runs of holds fold into the SET at the
    start or become one SLEEP after a fade; every change of colour is a FADE."""
    k_count = frames.shape[0]
    # Holds at the start fold into the first SET.
    k = 1
    while k < k_count and _same(colors, k, 0):
        k += 1
    at = _put_op(buf, 0, False, colors[0, 0], colors[0, 1], colors[0, 2], frames[k - 1] - frames[0])
    while k < k_count:
        at = _put_op(buf, at, True, colors[k, 0], colors[k, 1], colors[k, 2], frames[k] - frames[k - 1])
        j = k + 1
        while j < k_count and _same(colors, j, k):
            j += 1
        if j > k + 1:
            buf[at] = OP_SLEEP
            at = _put_varuint(buf, at + 1, frames[j - 1] - frames[k])
        k = j
    buf[at] = OP_END
    return at + 1


def encode_keyframes(frames: np.ndarray, colors: np.ndarray) -> bytes:
    """Bytecode for straight lines between keyframes: SET the first colour, then per keyframe a hold
    (its frames folded into the SET or the hold before it, else a SLEEP) or a FADE; END.

    Args:
        frames: (K,) strictly increasing keyframe frames, the first 0.
        colors: (K, 3) keyframe colours, integers 0-255.
    """
    f = np.ascontiguousarray(frames, dtype=np.int64)
    c = np.ascontiguousarray(colors, dtype=np.int64)
    if len(f) == 0 or c.shape != (len(f), 3) or np.any(np.diff(f) <= 0) or c.min() < 0 or c.max() > 255:
        raise ValueError("keyframes must be increasing frames with (K, 3) colours in 0-255")
    buf = np.empty(16 * len(f) + 16, dtype=np.uint8)  # per keyframe a FADE (<= 9 bytes) and a SLEEP (<= 6)
    return buf[: _encode(f, c, buf)].tobytes()


def fitted_program(track: np.ndarray, tolerance: float = TOLERANCE_LEVELS) -> bytes:
    """The light program of one drone's colour track (F, 3) at 50 Hz, 0-255 floats."""
    frames, colors = fit_fades(track, tolerance)
    return encode_keyframes(frames, colors)


__all__ = [
    "LIGHT_FPS",
    "TOLERANCE_LEVELS",
    "encode_keyframes",
    "fit_fades",
    "fitted_program",
    "varuint",
]


#: Most (drone, 50 Hz frame) colours evaluated for one export's light programs: bounds its CPU (about
#: 50 s) and keeps 20,000 drones x 10 minutes possible.
MAX_LIGHT_CELLS = 600_000_000
#: Drones per block when evaluating colours for the light programs (bounds memory: a 10-minute show
#: at 50 Hz is 30,000 frames, so a block is about 25 MB of colours and 50 MB of positions).
BLOCK_DRONES = 64


def show_light_programs(
    show: ShowFile, plan: ShowPlan, progress: Callable[[float], None] | None = None
) -> list[bytes] | None:
    """Every drone's light program fitted to the effect stack at 50 Hz, or None when the show has no
    enabled effects (its colours are then the plan's knot fades, written exactly by the caller).

    Args:
        show: the ``formations.ShowFile``.
        plan: its ``sim.ShowPlan``.
        progress: optional callback with the fraction done.
    """
    from sim.light import LightStack, show_colors

    stack = LightStack.from_show(show, plan)
    if not stack:
        return None
    n_frames = int(np.ceil(plan.duration_s * LIGHT_FPS - 1e-9)) + 1
    if n_frames * plan.drone_count > MAX_LIGHT_CELLS:
        raise ExportError(
            f"{plan.drone_count} drones x {n_frames} light frames (50 Hz) = {n_frames * plan.drone_count} exceeds the "
            f"limit of {MAX_LIGHT_CELLS} for fitting light effects; shorten the show or remove its effects")
    times = np.minimum(np.arange(n_frames) / LIGHT_FPS, plan.duration_s)
    out: list[bytes] = []
    n = plan.drone_count
    for a in range(0, n, BLOCK_DRONES):
        b = min(a + BLOCK_DRONES, n)
        cols = show_colors(show, plan, times, drones=slice(a, b), stack=stack) * np.float32(255.0)
        out += [fitted_program(cols[:, j]) for j in range(b - a)]
        if progress is not None:
            progress(b / n)
    return out


__all__ += ["BLOCK_DRONES", "MAX_LIGHT_CELLS", "show_light_programs"]
