"""Counter-based random numbers: a drone's draws depend on (seed, drone, stream, counter) only.

The error models (:mod:`sim.flight._errors`) need per-drone random streams that do
not depend on which other drones are flown with it, in which Dask shard, or in which
time chunk: a stateful generator advanced drone by drone (or chunk by chunk) would
give a drone different numbers in a shard than in a whole-fleet run. So every value
is a pure function of its key, hashed with SplitMix64 (Steele, Lea & Flood 2014,
"Fast splittable pseudorandom number generators"; the finaliser is Stafford's
"Mix13"), turned into uniforms from the top 53 bits and into normals by Box-Muller
(1958). Vectorised over any broadcast shape of drones and counters.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["STREAMS", "hashed_normal", "hashed_uniform"]

#: Stream numbers, one per random quantity (never reuse one for another quantity).
STREAMS = {
    "mass": 1, "inertia": 2, "thrust": 3, "sag": 4, "clock": 5,
    "gnss_bias": 6, "gnss_walk": 7, "gnss_white": 8, "gnss_step": 9,
}

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _mix(z: Any) -> np.ndarray:
    """SplitMix64's finaliser (bijective on uint64; wraps on purpose)."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    out: np.ndarray = np.asarray(z ^ (z >> np.uint64(31)))
    return out


def _hash(seed: int, drone: ArrayLike, stream: int, counter: ArrayLike, lane: int) -> np.ndarray:
    with np.errstate(over="ignore"):
        h = _mix(np.uint64(seed & 0xFFFFFFFFFFFFFFFF) * _GOLDEN + np.uint64(stream))
        h = _mix(h ^ (np.asarray(drone, dtype=np.uint64) * _GOLDEN))
        h = _mix(h ^ (np.asarray(counter, dtype=np.uint64) * _GOLDEN + np.uint64(lane)))
    return h


def hashed_uniform(seed: int, drone: ArrayLike, stream: int, counter: ArrayLike, lane: int = 0) -> np.ndarray:
    """Uniforms in (0, 1), one per broadcast element of ``drone`` and ``counter``.

    Args:
        seed: The run's seed (any int; taken modulo 2⁶⁴).
        drone: Drone indices in the plan (ints ≥ 0), any shape.
        stream: The quantity (:data:`STREAMS`).
        counter: Position in the stream (e.g. epoch × 3 + axis), broadcast with ``drone``.
        lane: Sub-stream (Box-Muller uses lanes 0 and 1).
    """
    h = _hash(seed, drone, stream, counter, lane)
    out: np.ndarray = ((h >> np.uint64(11)).astype(np.float64) + 0.5) * (1.0 / 9007199254740992.0)
    return out


def hashed_normal(seed: int, drone: ArrayLike, stream: int, counter: ArrayLike) -> np.ndarray:
    """Standard normals keyed like :func:`hashed_uniform` (Box-Muller, cosine branch)."""
    u1 = hashed_uniform(seed, drone, stream, counter, 0)
    u2 = hashed_uniform(seed, drone, stream, counter, 1)
    out: np.ndarray = np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)
    return out
