"""Counter-based random numbers: a drone's draws depend on (seed, drone, stream, counter) only.

The error models (:mod:`sim.flight._errors`) need per-drone random streams that do
not depend on which other drones are flown with it, in which Dask shard, or in which
time chunk: a stateful generator advanced drone by drone (or chunk by chunk) would
give a drone different numbers in a shard than in a whole-fleet run. So every value
is a pure function of its key, hashed with SplitMix64 (Steele, Lea & Flood 2014,
"Fast splittable pseudorandom number generators"; the finaliser is Stafford's
"Mix13"), turned into uniforms from the top 53 bits and into normals by Box-Muller
(1958). Vectorised over any broadcast shape of drones and counters.

The hashing and the uniforms run compiled, one pass per element (numpy's version made a
dozen uint64 temporaries per call, and the flight's GNSS tables draw ~10⁵ normals per
chunk); both are exact integer and power-of-two arithmetic, so they are the same bits. The
logarithm and cosine of Box-Muller stay numpy's own, on purpose: numpy's float64 log is its
AVX-512 routine where the CPU has one, which differs from libm's (what compiled code calls)
in the last bit for ~0.3 % of arguments, and a seed must keep meaning the same numbers.
"""

from __future__ import annotations

import math
from typing import Any

import numba
import numpy as np
from numpy.typing import ArrayLike

__all__ = ["STREAMS", "box_muller_inplace", "hashed_normal", "hashed_uniform", "uniform_pairs", "uniform_pairs_grid"]

#: Stream numbers, one per random quantity (never reuse one for another quantity).
STREAMS = {
    "mass": 1, "inertia": 2, "thrust": 3, "sag": 4, "clock": 5,
    "gnss_bias": 6, "gnss_walk": 7, "gnss_white": 8, "gnss_step": 9,
}

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)
_INV_2_53 = 1.0 / 9007199254740992.0


@numba.njit(inline="always", cache=True)
def _mix(z: Any) -> Any:  # pragma: no cover - compiled
    """SplitMix64's finaliser (bijective on uint64; wraps on purpose)."""
    z = (z ^ (z >> _S30)) * _M1
    z = (z ^ (z >> _S27)) * _M2
    return z ^ (z >> _S31)


@numba.njit(cache=True, nogil=True)
def _uniform_pairs(
    seed: np.uint64, stream: np.uint64, drone: np.ndarray, counter: np.ndarray, u1: np.ndarray, u2: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """``u1[j], u2[j]`` = lanes 0 and 1 of (drone[j], counter[j]) (flat, equal lengths)."""
    h0 = _mix(seed * _GOLDEN + stream)
    for j in range(drone.shape[0]):
        hd = _mix(h0 ^ (np.uint64(drone[j]) * _GOLDEN))
        c = np.uint64(counter[j]) * _GOLDEN
        a = _mix(hd ^ c) >> _S11
        b = _mix(hd ^ (c + np.uint64(1))) >> _S11
        u1[j] = (float(a) + 0.5) * _INV_2_53
        u2[j] = (float(b) + 0.5) * _INV_2_53


@numba.njit(cache=True, nogil=True)
def _uniform_lane(
    seed: np.uint64, stream: np.uint64, drone: np.ndarray, counter: np.ndarray, lane: np.uint64, u: np.ndarray,
) -> None:  # pragma: no cover - compiled
    h0 = _mix(seed * _GOLDEN + stream)
    for j in range(drone.shape[0]):
        hd = _mix(h0 ^ (np.uint64(drone[j]) * _GOLDEN))
        a = _mix(hd ^ (np.uint64(counter[j]) * _GOLDEN + lane)) >> _S11
        u[j] = (float(a) + 0.5) * _INV_2_53


@numba.njit(cache=True, nogil=True)
def _uniform_pairs_grid(
    seed: np.uint64, stream: np.uint64, drone: np.ndarray, counter: np.ndarray, u1: np.ndarray, u2: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """``u1[r, i, k], u2[r, i, k]`` = lanes 0 and 1 of (drone[i], counter[r, k])."""
    h0 = _mix(seed * _GOLDEN + stream)
    for i in range(drone.shape[0]):
        hd = _mix(h0 ^ (np.uint64(drone[i]) * _GOLDEN))
        for r in range(counter.shape[0]):
            for k in range(counter.shape[1]):
                c = np.uint64(counter[r, k]) * _GOLDEN
                a = _mix(hd ^ c) >> _S11
                b = _mix(hd ^ (c + np.uint64(1))) >> _S11
                u1[r, i, k] = (float(a) + 0.5) * _INV_2_53
                u2[r, i, k] = (float(b) + 0.5) * _INV_2_53


def uniform_pairs_grid(
    seed: int, drone: np.ndarray, stream: int, counter: np.ndarray, u1: np.ndarray, u2: np.ndarray,
) -> None:
    """:func:`uniform_pairs` of every drone ``(N,)`` with every counter ``(R, K)`` into ``(R, N, K)`` buffers.

    The GNSS tables' layout (epochs, drones, axes), written in place so a caller can keep
    its buffers from chunk to chunk (a fresh megabyte costs ~1 ms of page faults here).
    """
    d = np.ascontiguousarray(drone, dtype=np.uint64)
    c = np.ascontiguousarray(counter, dtype=np.uint64)
    if c.ndim != 2 or d.ndim != 1 or u1.shape != (c.shape[0], d.shape[0], c.shape[1]) or u2.shape != u1.shape:
        raise ValueError(f"uniform_pairs_grid: drone {d.shape}, counter {c.shape}, buffers {u1.shape}, {u2.shape}")
    _uniform_pairs_grid(np.uint64(seed & 0xFFFFFFFFFFFFFFFF), np.uint64(stream), d, c, u1, u2)


def _keys(drone: ArrayLike, counter: ArrayLike) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
    """Flat uint64 keys of the broadcast of ``drone`` and ``counter`` (wrapping as numpy's cast does)."""
    d = np.asarray(drone, dtype=np.uint64)
    c = np.asarray(counter, dtype=np.uint64)
    shape = np.broadcast_shapes(d.shape, c.shape)
    return (np.ascontiguousarray(np.broadcast_to(d, shape)).reshape(-1),
            np.ascontiguousarray(np.broadcast_to(c, shape)).reshape(-1), shape)


def uniform_pairs(seed: int, drone: ArrayLike, stream: int, counter: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Lanes 0 and 1 of :func:`hashed_uniform` in one compiled pass: the two inputs of a Box-Muller normal."""
    d, c, shape = _keys(drone, counter)
    u1, u2 = np.empty(d.size), np.empty(d.size)
    _uniform_pairs(np.uint64(seed & 0xFFFFFFFFFFFFFFFF), np.uint64(stream), d, c, u1, u2)
    return u1.reshape(shape), u2.reshape(shape)


def box_muller_inplace(u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """``sqrt(-2 ln u1) cos(2π u2)`` into ``u1`` (returned; ``u2`` is overwritten).

    The same numpy operations on the same values, in the same order, as
    ``np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)``, without its four temporaries.
    """
    np.log(u1, out=u1)
    np.multiply(-2.0, u1, out=u1)
    np.sqrt(u1, out=u1)
    np.multiply(2.0 * math.pi, u2, out=u2)
    np.cos(u2, out=u2)
    np.multiply(u1, u2, out=u1)
    return u1


def hashed_uniform(seed: int, drone: ArrayLike, stream: int, counter: ArrayLike, lane: int = 0) -> np.ndarray:
    """Uniforms in (0, 1), one per broadcast element of ``drone`` and ``counter``.

    Args:
        seed: The run's seed (any int; taken modulo 2⁶⁴).
        drone: Drone indices in the plan (ints ≥ 0), any shape.
        stream: The quantity (:data:`STREAMS`).
        counter: Position in the stream (e.g. epoch × 3 + axis), broadcast with ``drone``.
        lane: Sub-stream (Box-Muller uses lanes 0 and 1).
    """
    d, c, shape = _keys(drone, counter)
    u = np.empty(d.size)
    _uniform_lane(np.uint64(seed & 0xFFFFFFFFFFFFFFFF), np.uint64(stream), d, c, np.uint64(lane), u)
    return u.reshape(shape)


def hashed_normal(seed: int, drone: ArrayLike, stream: int, counter: ArrayLike) -> np.ndarray:
    """Standard normals keyed like :func:`hashed_uniform` (Box-Muller, cosine branch)."""
    u1, u2 = uniform_pairs(seed, drone, stream, counter)
    return box_muller_inplace(u1, u2)
