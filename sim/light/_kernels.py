"""numba kernels of the light evaluator: one pass over (frames x drones) per effect, in place.

numpy needed a dozen temporaries of (T, n, 3) per effect (92 s for 5,000 drones x 15,000
frames); these loops read each cell once and write it once. The formulas are the ones of
:mod:`formations._effects` and :mod:`sim.light._evaluate` (the tests check them against a
scalar reference).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from sim.plan import position_at, step_piece

# Kind codes of the per-drone part of an effect (per-frame-only kinds are folded into the
# frame colour and the frame opacity before the kernel runs).
K_FLAT = 0  # colour and opacity per frame only: solid, ramp, strobe
K_SWEEP_LINEAR = 1
K_SWEEP_RADIAL = 2
K_CHASE_PULSE = 3
K_CHASE_WAVE = 4
K_SPARKLE = 5
K_IMAGE = 6

T_NONE = 0
T_BOX = 1
T_PLANE = 2

B_REPLACE = 0
B_ADD = 1
B_MULTIPLY = 2
B_MAX = 3


@nb.njit(cache=True, inline="always")
def _mix64(x: np.uint64) -> np.uint64:  # pragma: no cover - compiled
    x ^= x >> np.uint64(30)
    x *= np.uint64(0xBF58476D1CE4E5B9)
    x ^= x >> np.uint64(27)
    x *= np.uint64(0x94D049BB133111EB)
    x ^= x >> np.uint64(31)
    return x


@nb.njit(cache=True)
def hash01(seed: np.int64, drone: np.int64, slot: np.int64) -> float:  # pragma: no cover - compiled
    """``mix64(mix64(seed << 32 | drone) + slot) >> 11`` / 2^53 (see ``uniform_hash``)."""
    h = _mix64((np.uint64(seed) << np.uint64(32)) | np.uint64(drone))
    h = _mix64(h + np.uint64(slot))
    return float(h >> np.uint64(11)) / 9007199254740992.0


@nb.njit(cache=True, inline="always")
def _blend(mode: int, below: float, c: float, a: float) -> float:  # pragma: no cover - compiled
    if mode == 0:
        v = below + a * (c - below)
    elif mode == 1:
        v = below + a * c
    elif mode == 2:
        v = below * (1.0 - a + a * c)
    else:
        v = below + a * (max(below, c) - below)
    return min(1.0, max(0.0, v))


@nb.njit(cache=True, nogil=True)
def paint(
    out: np.ndarray,  # (T, n, 3) float32, painted in place
    pos: np.ndarray,  # (T, n, 3) float64 positions (ignored unless read)
    t_s: np.ndarray,  # (T,) times
    frames: np.ndarray,  # (F,) frames the effect covers
    frame_alpha: np.ndarray,  # (F,) envelope x opacity x (strobe) x (formation window)
    frame_rgb: np.ndarray,  # (F, 3) per-frame colour (solid, ramp, strobe, chase, sparkle)
    cols: np.ndarray,  # (m,) columns of out the effect targets
    ids: np.ndarray,  # (m,) their drone indices
    blend: int,
    kind: int,
    target: int,
    tprm: np.ndarray,  # box: lo(3), hi(3); plane: point(3), normal(3)
    kprm: np.ndarray,  # kind parameters (see LightStack._kernel_args)
    stops: np.ndarray,  # (K, 3) gradient stops
    rank: np.ndarray,  # (N,) chase places
    seed: np.int64,
    images: np.ndarray,  # (F_img, H, W, 4) uint8 RGBA
    image_size: np.ndarray,  # (F_img, 2) real (H, W) of each frame
) -> None:  # pragma: no cover - compiled
    n_stops = stops.shape[0]
    for a in range(frames.shape[0]):
        fa = frame_alpha[a]
        if fa <= 0.0:
            continue
        f = frames[a]
        t = t_s[f]
        since = t - kprm[0]
        img = 0
        if kind == K_IMAGE:
            img = np.int64(np.floor(since * kprm[1] + 1e-9)) % images.shape[0]
        for b in range(cols.shape[0]):
            i = cols[b]
            alpha = fa
            if target == T_BOX:
                inside = True
                for ax in range(3):
                    p = pos[f, i, ax]
                    if p < tprm[ax] or p > tprm[3 + ax]:
                        inside = False
                if not inside:
                    continue
            elif target == T_PLANE:
                s = 0.0
                for ax in range(3):
                    s += (pos[f, i, ax] - tprm[ax]) * tprm[3 + ax]
                if s < 0.0:
                    continue
            r = frame_rgb[a, 0]
            g = frame_rgb[a, 1]
            bl = frame_rgb[a, 2]
            if kind == K_SWEEP_LINEAR or kind == K_SWEEP_RADIAL:
                if kind == K_SWEEP_LINEAR:
                    along = pos[f, i, 0] * kprm[4] + pos[f, i, 1] * kprm[5] + pos[f, i, 2] * kprm[6]
                else:
                    dx = pos[f, i, 0] - kprm[4]
                    dy = pos[f, i, 1] - kprm[5]
                    dz = pos[f, i, 2] - kprm[6]
                    along = np.sqrt(dx * dx + dy * dy + dz * dz)
                phase = (along - kprm[2] * since) / kprm[3]
                x = (phase - np.floor(phase)) * n_stops
                k = min(max(np.int64(np.floor(x)), 0), n_stops - 1)
                w = x - k
                k1 = (k + 1) % n_stops
                r = stops[k, 0] * (1.0 - w) + stops[k1, 0] * w
                g = stops[k, 1] * (1.0 - w) + stops[k1, 1] * w
                bl = stops[k, 2] * (1.0 - w) + stops[k1, 2] * w
            elif kind == K_CHASE_PULSE or kind == K_CHASE_WAVE:
                rel = rank[ids[b]] - since / kprm[2]
                rel -= np.floor(rel)
                if kind == K_CHASE_WAVE:
                    alpha *= 0.5 * (1.0 + np.cos(2.0 * np.pi * rel))
                else:
                    alpha *= max(0.0, 1.0 - min(rel, 1.0 - rel) / kprm[3])
            elif kind == K_SPARKLE:
                d = ids[b]
                x = since / kprm[2] + hash01(seed, d, np.int64(-1))
                slot = np.floor(x)
                u = x - slot
                if hash01(seed, d, np.int64(slot)) < kprm[3]:
                    alpha *= 1.0 - abs(2.0 * u - 1.0)
                else:
                    continue
            elif kind == K_IMAGE:
                px = pos[f, i, 0]
                pz = pos[f, i, 2]
                if kprm[6] > 0.0:
                    # Through the camera (kprm[7:10]) onto the picture's plane y = kprm[10].
                    dy = pos[f, i, 1] - kprm[8]
                    if dy <= 0.0:
                        continue
                    s = (kprm[10] - kprm[8]) / dy
                    px = kprm[7] + s * (px - kprm[7])
                    pz = kprm[9] + s * (pz - kprm[9])
                u = (px - kprm[2]) / kprm[4]
                v = (kprm[3] - pz) / kprm[5]
                if u < 0.0 or u >= 1.0 or v < 0.0 or v >= 1.0:
                    continue
                h = image_size[img, 0]
                w_px = image_size[img, 1]
                row = min(np.int64(np.floor(v * h)), h - 1)
                col = min(np.int64(np.floor(u * w_px)), w_px - 1)
                r = images[img, row, col, 0] / 255.0
                g = images[img, row, col, 1] / 255.0
                bl = images[img, row, col, 2] / 255.0
                alpha *= images[img, row, col, 3] / 255.0
            if alpha <= 0.0:
                continue
            out[f, i, 0] = _blend(blend, out[f, i, 0], r, alpha)
            out[f, i, 1] = _blend(blend, out[f, i, 1], g, alpha)
            out[f, i, 2] = _blend(blend, out[f, i, 2], bl, alpha)


@nb.njit(cache=True, nogil=True)
def positions_at(breaks: np.ndarray, coeffs: np.ndarray, rows: np.ndarray, t_s: np.ndarray,
                 frames: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out[f, j] = position of drone rows[j] at t_s[f] for f in ``frames`` (in increasing time).

    Frame by frame (contiguous writes), each drone's piece kept in a cursor and stepped forward
    as time advances, as the viewer's playback kernel does; times outside a drone's pieces clamp
    to its first / last piece ends.
    """
    end = breaks.shape[1] - 1
    cursor = np.zeros(rows.shape[0], dtype=np.int64)
    for a in range(frames.shape[0]):
        f = frames[a]
        for j in range(rows.shape[0]):
            d = rows[j]
            t = min(max(t_s[f], breaks[d, 0]), breaks[d, end])
            p = step_piece(breaks, d, cursor[j], t)
            cursor[j] = p
            u = t - breaks[d, p]
            for ax in range(3):
                out[f, j, ax] = position_at(coeffs, d, p, ax, u)


@nb.njit(cache=True, nogil=True)
def base_into(knot_times: np.ndarray, knot_colors: np.ndarray, rows: np.ndarray, t_s: np.ndarray,
              out: np.ndarray) -> None:  # pragma: no cover - compiled
    """out[f, j] = the plan's colour of drone rows[j] at t_s[f]: linear between the knots around t
    (as ``ShowPlan.evaluate``: the segment of the last knot at or before t, clamped to the show)."""
    n_seg = knot_times.shape[0] - 1
    for f in range(t_s.shape[0]):
        t = t_s[f]
        k = np.searchsorted(knot_times, t, side="right") - 1
        k = min(max(k, 0), n_seg - 1)
        t0 = knot_times[k]
        span = knot_times[k + 1] - t0
        tau = (t - t0) / span if span > 0 else 0.0
        tau = min(1.0, max(0.0, tau))
        for j in range(rows.shape[0]):
            d = rows[j]
            for c in range(3):
                c0 = knot_colors[k, d, c]
                out[f, j, c] = c0 + tau * (knot_colors[k + 1, d, c] - c0)
