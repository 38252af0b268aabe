"""Transition timing: the shortest duration that keeps every drone within the limits.

The paper's eq. 12 (T = max leg / v_max) bounds only the *average* speed. For the
rest-to-rest quintic the peaks are exact: a leg L flown in T peaks at
1.875·L/T in speed and (10/√3)·L/T² in acceleration, so the shortest admissible T
is the largest of three closed-form bounds over all drones.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from sim.plan._quintic import PEAK_ACCEL_FACTOR, PEAK_SPEED_FACTOR

#: Durations are rounded up to this step, seconds.
DURATION_STEP_S = 0.1


def exact_min_duration(
    starts: ArrayLike,
    ends: ArrayLike,
    *,
    max_speed_xy_mps: float,
    max_speed_z_mps: float,
    max_accel_mps2: float,
) -> float:
    """The unrounded shortest T (seconds) at which every leg respects the three peak limits.

    Args:
        starts, ends: (N, 3) leg start and end points, metres.
        max_speed_xy_mps, max_speed_z_mps: peak horizontal / vertical speed limits, m/s.
        max_accel_mps2: peak acceleration magnitude limit, m/s².
    """
    d = np.asarray(ends, dtype=np.float64) - np.asarray(starts, dtype=np.float64)
    if d.size == 0:
        return 0.0
    l_xy = float(np.max(np.hypot(d[:, 0], d[:, 1])))
    l_z = float(np.max(np.abs(d[:, 2])))
    l_3d = float(np.max(np.linalg.norm(d, axis=1)))
    return max(
        PEAK_SPEED_FACTOR * l_xy / max_speed_xy_mps,
        PEAK_SPEED_FACTOR * l_z / max_speed_z_mps,
        math.sqrt(PEAK_ACCEL_FACTOR * l_3d / max_accel_mps2),
    )


def round_up_duration(duration_s: float) -> float:
    """Round up to the next multiple of :data:`DURATION_STEP_S` (at least one step)."""
    steps = math.ceil(duration_s / DURATION_STEP_S - 1e-9)
    return max(1, steps) * DURATION_STEP_S


def min_transition_duration(starts: ArrayLike, ends: ArrayLike, **limits: float) -> float:
    """Shortest admissible duration (seconds), rounded up to 0.1 s; see :func:`exact_min_duration`."""
    return round(round_up_duration(exact_min_duration(starts, ends, **limits)), 10)
