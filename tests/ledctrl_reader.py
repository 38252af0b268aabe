"""An independent reader and player of Skybrush ``ledctrl`` light programs, for the tests.

Written from the published format (pyledctrl's ``CommandCode`` list and its executor's semantics),
sharing no code with the exporter: opcode byte, colours as three bytes, durations as unsigned
LEB128 varints in frames of 1/50 s. A SET holds its colour from the current time for its
duration; a FADE goes linearly from the colour at its start to its colour at its end.
"""

from __future__ import annotations

import numpy as np

FPS = 50


def _varuint(code: bytes, at: int) -> tuple[int, int]:
    value, shift = 0, 0
    while True:
        byte = code[at]
        at += 1
        value |= (byte & 0x7F) << shift
        shift += 7
        if byte < 0x80:
            return value, at


def parse(code: bytes) -> list[tuple[str, tuple[int, int, int] | None, int]]:
    """Commands as (``"set"`` | ``"fade"`` | ``"sleep"``, colour or None, frames), up to END."""
    out: list[tuple[str, tuple[int, int, int] | None, int]] = []
    at = 0
    while True:
        op = code[at]
        at += 1
        if op == 0x00:
            return out
        if op == 0x01:
            continue
        if op == 0x02:
            d, at = _varuint(code, at)
            out.append(("sleep", None, d))
        elif op in (0x04, 0x08):
            rgb = (code[at], code[at + 1], code[at + 2])
            d, at = _varuint(code, at + 3)
            out.append(("set" if op == 0x04 else "fade", rgb, d))
        elif op in (0x05, 0x09):
            v = code[at]
            d, at = _varuint(code, at + 1)
            out.append(("set" if op == 0x05 else "fade", (v, v, v), d))
        elif op in (0x06, 0x07, 0x0A, 0x0B):
            v = 0 if op in (0x06, 0x0A) else 255
            d, at = _varuint(code, at)
            out.append(("set" if op in (0x06, 0x07) else "fade", (v, v, v), d))
        else:
            raise ValueError(f"opcode {op:#04x} at byte {at - 1} is not handled by this reader")


def replay(code: bytes, n_frames: int) -> np.ndarray:
    """The colour at frames 0 .. n_frames-1, (n_frames, 3) floats 0-255 (the last colour held after END)."""
    out = np.zeros((n_frames, 3))
    color = np.zeros(3)
    t = 0
    for kind, rgb, d in parse(code):
        if kind == "set":
            assert rgb is not None
            color = np.array(rgb, dtype=float)
            out[t:t + d] = color
        elif kind == "sleep":
            out[t:t + d] = color
        else:
            assert rgb is not None
            target = np.array(rgb, dtype=float)
            k = np.arange(1, d + 1)[:, None]
            seg = color + (target - color) * k / d
            end = min(t + d + 1, n_frames)
            out[t + 1:end] = seg[: max(0, end - t - 1)]
            if t < n_frames:
                out[t] = color
            color = target
        t += d
    out[t:] = color
    return out
