"""Exact downwash check during takeoff and landing (Preiss et al. 2017's ellipsoid).

Drone j is in drone i's downwash when ``(dx² + dy²)/r² + dz²/c² < 1``, with the
offsets dx, dy, dz between them and the ellipsoid's horizontal radius r and vertical
half-height c (``Settings.downwash_axes_m``; J. A. Preiss, W. Hönig, N. Ayanian,
G. S. Sukhatme, "Downwash-aware trajectory planning for large quadrotor teams", IROS
2017, model a quadrotor's downwash by this axis-aligned ellipsoid; the relation is
symmetric, so "i above j" and "j below i" are the same event).

**Exactly like the distance.** Scaling every position by diag(1/r, 1/r, 1/c) maps the
ellipsoid to the unit ball, and each scaled trajectory is still a polynomial in t (the
coefficients scale per axis). The scaled squared distance is therefore a polynomial on
every part where both drones are on one piece, and
:func:`sim.verify.window_close_pairs` finds every pair whose scaled distance drops
below 1 with its exact minimum and time (its candidate search is metric-free: any
trajectories, any radius).

The check itself is :func:`sim.verify._check.downwash_violations`.

**Where.** During the ``takeoff`` and ``landing`` segments, where drones climb and sink
through each other's wash. (Formations may stack drones vertically at the minimum
distance by design, e.g. a filled ball, so holds and transitions are not checked.)
On a sparse home layout the planner's takeoff and landing move every drone on one shared
profile with a common vertical component: at every instant all drones are at one altitude,
so dz = 0 and the condition reduces to a horizontal distance >= r, which the home grid gives
whenever its spacing is >= r. Denser layouts (launch boxes) take off and land in waves to
altitude layers (:mod:`sim.plan._waves`), each wave at least the ellipsoid's half-height below
the one before; pairs with a drone parked on its home follow :mod:`sim.verify._parked`.
"""

from __future__ import annotations

import numpy as np

from sim.plan._trajectory import Trajectories

#: Segment kinds checked.
DOWNWASH_SEGMENTS = ("takeoff", "landing")


def scaled_motion(motion: Trajectories, radius_m: float, height_m: float) -> Trajectories:
    """The trajectories in ellipsoid units: x/r, y/r, z/c (each piece stays a polynomial)."""
    scale = np.array([1.0 / radius_m, 1.0 / radius_m, 1.0 / height_m])
    return Trajectories(motion.breaks_s, motion.coeffs_m * scale[None, None, :, None])


__all__ = ["DOWNWASH_SEGMENTS", "scaled_motion"]
