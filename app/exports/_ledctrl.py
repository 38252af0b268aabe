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


def _set(rgb: tuple[int, int, int], frames: int) -> bytes:
    r, g, b = rgb
    if r == g == b:
        if r == 0:
            return bytes((OP_SET_BLACK,)) + varuint(frames)
        if r == 255:
            return bytes((OP_SET_WHITE,)) + varuint(frames)
        return bytes((OP_SET_GRAY, r)) + varuint(frames)
    return bytes((OP_SET_COLOR, r, g, b)) + varuint(frames)


def _fade(rgb: tuple[int, int, int], frames: int) -> bytes:
    r, g, b = rgb
    if r == g == b:
        if r == 0:
            return bytes((OP_FADE_TO_BLACK,)) + varuint(frames)
        if r == 255:
            return bytes((OP_FADE_TO_WHITE,)) + varuint(frames)
        return bytes((OP_FADE_TO_GRAY, r)) + varuint(frames)
    return bytes((OP_FADE_TO_COLOR, r, g, b)) + varuint(frames)


def encode_keyframes(frames: np.ndarray, colors: np.ndarray) -> bytes:
    """Bytecode for straight lines between keyframes: SET the first colour, then per keyframe a hold
    (its frames folded into the SET or the hold before it, else a SLEEP) or a FADE; END.

    Args:
        frames: (K,) strictly increasing keyframe frames, the first 0.
        colors: (K, 3) keyframe colours, integers 0-255.
    """
    ops: list[list] = []  # ["set" | "sleep" | "fade", rgb, frames]
    first = tuple(int(v) for v in colors[0])
    ops.append(["set", first, 0])
    current = first
    for k in range(1, len(frames)):
        dur = int(frames[k] - frames[k - 1])
        rgb = tuple(int(v) for v in colors[k])
        if rgb == current:
            if ops[-1][0] in ("set", "sleep"):
                ops[-1][2] += dur
            else:
                ops.append(["sleep", rgb, dur])
        else:
            ops.append(["fade", rgb, dur])
            current = rgb
    code = bytearray()
    for op, rgb, dur in ops:
        if op == "set":
            code += _set(rgb, dur)
        elif op == "sleep":
            code += bytes((OP_SLEEP,)) + varuint(dur)
        else:
            code += _fade(rgb, dur)
    code.append(OP_END)
    return bytes(code)


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


__all__ += ["BLOCK_DRONES", "show_light_programs"]
