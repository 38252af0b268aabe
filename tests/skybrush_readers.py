"""Independent ports of the Skybrush readers, for the export tests (no Skybrush code is vendored).

Skybrush Server, libskybrush, ``@skybrush/show-format`` and Skybrush Studio are GPL-3.0:
nothing here is copied from them. These are clean re-implementations, written from the
published behaviour of those readers, of the steps that decide what a drone flies:

* :func:`server_binary_trajectory` - Skybrush Server's .skyc -> binary (``.skyb``)
  trajectory conversion: per-drone scale ``ceil((ceil(max|coord|·1000) + 1) / 32768)``
  over the points *and* control points, coordinates stored as int16 in units of
  ``scale`` mm truncated toward zero (``int()``), segment durations as uint16
  milliseconds ``floor(round(t1 - t0, 3)·1000)``, segments longer than 65 s split,
  per-axis formats constant / linear / cubic Bézier (0, 1, 3 stored coordinates).
* :class:`LibskybrushPlayer` - libskybrush's trajectory player on those bytes, in
  float32 as the firmware computes: segment start ``start_ms / 1000.0f``,
  ``rel_t = (t - start) / duration``, the Bézier converted to a polynomial in rel_t.
* :func:`show_format_positions` - the ``@skybrush/show-format`` loader (Live, Viewer):
  the show.json Bézier points evaluated in doubles, in normalised time between points.
* :func:`studio_csv_import` - Skybrush Studio for Blender's zipped-CSV importer
  (``parse_compressed_csv_zip`` + ``Trajectory.resample_in_place`` + keyframes and the
  light-effect image): rows ``ms,x,y,z,r,g,b``, positions linearly resampled on
  ``arange(first, last, 1/fps)`` (which leaves out the last instant), colours held from
  each row to the next, one pixel per Blender frame.
"""

from __future__ import annotations

import csv
import io
import math
import re
import struct
import zipfile

import numpy as np

MAX_SEGMENT_S = 65.0


# ---------------------------------------------------------------- server: show.json -> binary


def _scale(points: list) -> int:
    coords = [abs(v) for _, p, ctrl in points for q in [p, *ctrl] for v in q]
    extremum = math.ceil(max(coords) * 1000) if coords else 0
    return math.ceil((extremum + 1) / 32768)


def server_binary_trajectory(points: list) -> bytes:
    """The trajectory block the server writes for one drone's show.json ``points``."""
    scale = _scale(points)
    assert scale < 128, "too large an area for the binary format"
    per_mm = 1000.0 / scale

    def q(p) -> tuple[int, int, int]:
        return int(p[0] * per_mm), int(p[1] * per_mm), int(p[2] * per_mm)

    out = bytearray([scale])
    out += struct.pack("<hhhh", *q(points[0][1]), 0)
    prev_t, start = points[0][0], points[0][1]
    for t, p, ctrl in points[1:]:
        dt = round(t - prev_t, 3)
        assert dt > 0, f"time must move forward at t = {t}"
        pieces = [(dt, [start, *ctrl, p])]
        if dt > MAX_SEGMENT_S:  # split into equal parts (de Casteljau); durations at fractional ms
            raise AssertionError("segments over 65 s are split at fractional milliseconds; the exporter avoids them")
        for seg_dt, cps in pieces:
            qs = [q(c) for c in cps]
            header = 0
            body = b""
            for axis in range(3):
                first, *rest = (c[axis] for c in qs)
                if all(v == first for v in rest):
                    fmt, stored = 0, []
                elif len(rest) == 1:
                    fmt, stored = 1, rest
                elif len(rest) == 3:
                    fmt, stored = 2, rest
                else:  # quadratic: promoted to cubic by the server; the exporter never writes one
                    raise AssertionError(f"{len(rest) - 1} control point(s)")
                header |= fmt << (2 * axis)
                body += b"".join(struct.pack("<h", v) for v in stored)
            out += struct.pack("<BH", header, math.floor(seg_dt * 1000)) + body
        prev_t, start = t, p
    return bytes(out)


# ---------------------------------------------------------------- libskybrush: the drone's player


class LibskybrushPlayer:
    """Positions (metres) from a binary trajectory block, evaluated in float32."""

    def __init__(self, block: bytes) -> None:
        f32 = np.float32
        scale = f32(block[0] & 0x7F)
        off = 1
        x, y, z, _yaw = struct.unpack_from("<hhhh", block, off)
        off += 8
        start = np.array([x, y, z], dtype=f32) * scale
        self.start = start
        starts_ms, durations_ms, polys = [], [], []
        t_ms = 0
        while off < len(block):
            header, dur = struct.unpack_from("<BH", block, off)
            off += 3
            end = start.copy()
            coeffs = np.zeros((3, 4), dtype=f32)
            for axis in range(3):
                fmt = (header >> (2 * axis)) & 3
                n = {0: 0, 1: 1, 2: 3, 3: 7}[fmt]
                assert fmt != 3, "poly7d not written by the server for these shows"
                vals = [f32(v) * scale for v in struct.unpack_from(f"<{n}h", block, off)]
                off += 2 * n
                b = [start[axis], *vals]
                # Bernstein -> power basis in rel_t (float32 arithmetic).
                if n == 0:
                    coeffs[axis, 0] = b[0]
                elif n == 1:
                    coeffs[axis, :2] = (b[0], b[1] - b[0])
                else:
                    b0, b1, b2, b3 = b
                    coeffs[axis] = (b0, f32(3) * (b1 - b0), f32(3) * (b0 - f32(2) * b1 + b2),
                                    b3 - b0 + f32(3) * (b1 - b2))
                end[axis] = b[-1]
            starts_ms.append(t_ms)
            durations_ms.append(dur)
            polys.append(coeffs)
            t_ms += dur
            start = end
        self.end = start
        self.starts_ms = np.array(starts_ms, dtype=np.int64)
        self.durations_ms = np.array(durations_ms, dtype=np.int64)
        self.polys = np.array(polys, dtype=f32).reshape(-1, 3, 4)
        self.total_ms = t_ms

    def positions(self, t_s: np.ndarray) -> np.ndarray:
        """(T, 3) metres at times ``t_s`` (seconds); held at the ends."""
        f32 = np.float32
        t = np.asarray(t_s, dtype=f32)
        out = np.empty((len(t), 3))
        start_s = self.starts_ms.astype(f32) / f32(1000.0)
        dur_s = self.durations_ms.astype(f32) / f32(1000.0)
        k = np.searchsorted(start_s, t, side="right") - 1
        before, after = k < 0, t >= f32(self.total_ms) / f32(1000.0)
        k = np.clip(k, 0, len(self.polys) - 1)
        rel = ((t - start_s[k]) / dur_s[k]).astype(f32)
        c = self.polys[k]  # (T, 3, 4)
        r = rel[:, None]
        val = ((c[:, :, 3] * r + c[:, :, 2]) * r + c[:, :, 1]) * r + c[:, :, 0]
        out[:] = val.astype(np.float64) / 1000.0
        out[before] = self.start.astype(np.float64) / 1000.0
        out[after] = self.end.astype(np.float64) / 1000.0
        return out


# ---------------------------------------------------------------- @skybrush/show-format


def show_format_positions(points: list, t_s: np.ndarray) -> np.ndarray:
    """(T, 3) metres: the show.json Bézier points evaluated in doubles, held at the ends."""
    times = np.array([p[0] for p in points], dtype=np.float64)
    t = np.asarray(t_s, dtype=np.float64)
    k = np.clip(np.searchsorted(times, t, side="right"), 1, len(times) - 1)
    out = np.empty((len(t), 3))
    for seg in np.unique(k):
        sel = k == seg
        (t0, p0, _), (t1, p1, ctrl) = points[seg - 1], points[seg]
        u = np.clip((t[sel] - t0) / (t1 - t0), 0.0, 1.0)[:, None]
        cps = [np.asarray(p0, float), *(np.asarray(c, float) for c in ctrl), np.asarray(p1, float)]
        deg = len(cps) - 1
        out[sel] = sum(math.comb(deg, i) * (1 - u) ** (deg - i) * u**i * cps[i] for i in range(deg + 1))
    out[t <= times[0]] = points[0][1]
    out[t >= times[-1]] = points[-1][1]
    return out


# ---------------------------------------------------------------- Skybrush Studio's CSV importer


def _natural_key(name: str) -> list:
    return [int(s) if s.isdigit() else s.lower() for s in re.split(r"(\d+)", name)]


def studio_csv_import(content: bytes, fps: int = 24) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """What Studio shows for each drone: ``(frame_times_s, positions (F, 3), pixel_colors (P, 3))``.

    Positions at Blender frames ``k`` (time k/fps from the first row) after resampling;
    colours one per frame from the first row's time (the light-effect image).
    """
    result = {}
    with zipfile.ZipFile(io.BytesIO(content)) as z:
        for member in sorted(z.namelist(), key=_natural_key):
            name = member.rsplit("/", 1)[-1].rsplit(".", 1)[0]
            assert name not in result, f"duplicate drone name {name}"
            rows = []
            header_passed = False
            for row in csv.reader(z.read(member).decode("ascii").splitlines()):
                if not row:
                    continue
                if not header_passed:
                    header_passed = True
                    tok = row[0].lower()
                    if tok.startswith("time_msec") or tok.startswith("time [msec]"):
                        continue
                t = float(row[0]) / 1000.0
                x, y, zz = (float(v) for v in row[1:4])
                r, g, b = (int(v) for v in row[4:7]) if len(row) > 4 else (255, 255, 255)
                rows.append((t, x, y, zz, r, g, b))
            if not rows:
                continue
            a = np.array(rows, dtype=np.float64)
            ts = a[:, 0]
            target = np.arange(ts[0], ts[-1], 1.0 / fps)
            pos = np.stack([np.interp(target, ts, a[:, i]) for i in (1, 2, 3)], axis=1)
            # Keyframes at round((t - t0)·fps), linear in between: at frame k, the resampled value.
            # Light image: colour of a row held until the next row's frame.
            t0 = ts[0]
            duration = int((ts[-1] - t0) * fps) + 1
            pixels: list = []
            color = a[0, 4:7]
            j_last = 0
            j_next = 0
            for k in range(1, len(a)):
                j_next = round((ts[k] - t0) * fps)
                pixels.extend([color] * (j_next - j_last))
                j_last = j_next
                color = a[k, 4:7]
            if j_next < duration:
                pixels.append(color)
            else:
                pixels[-1] = color
            result[name] = (target - t0, pos, np.array(pixels))
    return result


# ---------------------------------------------------------------- cues (Skybrush Live's cue list)


def show_cues(doc: dict) -> list[tuple[str, float]]:
    """The cue list of a show.json as Skybrush reads it: ``settings.cues`` version 1, ``items`` of
    ``{"name", "time"}`` (seconds), the layout Skybrush Studio for Blender writes from its timeline
    markers and Skybrush Server passes on to Live; a missing block is an empty list."""
    cues = doc.get("settings", {}).get("cues")
    if cues is None:
        return []
    assert cues["version"] == 1, cues
    out = []
    for item in cues["items"]:
        assert set(item) == {"name", "time"}, item
        assert isinstance(item["name"], str) and isinstance(item["time"], int | float)
        out.append((item["name"], float(item["time"])))
    return out
