"""Parked drones in the exact check: which rules hold for pairs with a drone resting on its home.

A drone is *parked* while it rests on its home before its takeoff departure, or after its
landing touchdown (read off its own trajectory: before its first moving piece, after its last).
With launch boxes (:mod:`formations._launch`) the drones of one box sit closer than
``min_distance_m`` and leave (land) in waves (:mod:`sim.plan._waves`), so some of them are
parked while their box mates fly. The rules, as operators treat launch boxes:

1. **parked - parked:** nothing is checked. The ground layout is validated by the show file
   (inside a box the box spacing, between boxes and loose homes ``min_distance_m``), and drones
   with motors off do not collide.
2. **parked - airborne, same box:** no separation: operators set a box's drones out at the box
   spacing on purpose and a drone leaves (reaches) its own slot vertically. What is checked is
   that the airborne drone never passes *over* its parked box mate: it stays outside the
   *clearance ellipsoid* around it, of horizontal radius ``LaunchInfo.box_clearance_m`` (half
   the box spacing, at most the downwash radius) and the downwash half-height. The wash of a
   drone climbing beside a parked drone at the box spacing is what every box launch does; a
   drone above a parked one is what must not happen (its wash or its fall lands on it).
3. **parked - airborne, different boxes or loose homes:** the usual rules: ``min_distance_m``
   and the full downwash ellipsoid (the show file keeps drones of different boxes at least
   max(min_distance_m, downwash radius) apart on the ground).
4. **airborne - airborne:** the usual rules, also for two drones of one box.

**Exactness.** The windows' candidate searches run as before over the whole takeoff (landing)
window; only same-box pairs are then re-minimised exactly (:func:`sim.verify._poly.pair_minima`)
over the sub-intervals where each rule applies: both airborne
[max(lift-offs), min(touchdowns)] (rules 4) and one airborne [min, max] of the lift-offs and of
the touchdowns (rule 2). A sub-interval's minimum is >= the window's, so no pair that breaks a
rule in its sub-interval is missing from the candidates; and the clearance ellipsoid lies inside
the downwash ellipsoid, so the downwash candidates contain every clearance candidate.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from sim.plan._trajectory import Trajectories
from sim.verify import _poly

if TYPE_CHECKING:
    from sim.plan._plan import Segment, ShowPlan

#: Segment kinds in which drones may be parked.
PARKED_SEGMENTS = ("takeoff", "landing")


def rest_times(motion: Trajectories) -> tuple[np.ndarray, np.ndarray]:
    """(N,) lift-off (start of each drone's first moving piece) and (N,) touchdown (end of its last), s.

    A drone that never moves gets lift-off = touchdown = the end of the show (parked throughout).
    """
    b = motion.breaks_s
    moving = np.any(motion.coeffs_m[:, :, :, 1:] != 0.0, axis=(2, 3)) & (b[:, 1:] > b[:, :-1])
    any_move = moving.any(axis=1)
    first = np.argmax(moving, axis=1)
    last = moving.shape[1] - 1 - np.argmax(moving[:, ::-1], axis=1)
    rows = np.arange(len(b))
    end = b[:, -1]
    return np.where(any_move, b[rows, first], end), np.where(any_move, b[rows, last + 1], end)


def airborne_span(plan: ShowPlan, seg: Segment) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """For a takeoff or landing window with launch boxes: (box (N,), airborne from (N,), airborne to (N,))
    clipped to the window, seconds; None when rules 2 and 4 need nothing special (no boxes)."""
    launch = plan.launch
    if launch is None or seg.kind not in PARKED_SEGMENTS:
        return None
    box = launch.start_box if seg.kind == "takeoff" else launch.end_box
    if not np.any(box >= 0):
        return None
    lift, touch = rest_times(plan.motion)
    t0, t1 = seg.start_s, seg.end_s
    if seg.kind == "takeoff":
        return box, np.clip(lift, t0, t1), np.full(len(box), t1)
    return box, np.full(len(box), t0), np.clip(touch, t0, t1)


def _minima(motion: Trajectories, i: np.ndarray, j: np.ndarray, lo: np.ndarray, hi: np.ndarray,
            cutoff: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact minimum distance (inf on an empty interval) and its time of each pair over [lo, hi]."""
    m = len(i)
    d2 = np.full(m, np.inf)
    tm = np.zeros(m)
    ok = hi >= lo
    if ok.any():
        q = np.flatnonzero(ok)
        dq, tq = np.empty(len(q)), np.empty(len(q))
        _poly.pair_minima(i[q], j[q], lo[q], hi[q], np.full(len(q), cutoff**2), motion.breaks_s, motion.coeffs_m,
                          _poly.W, dq, tq)
        d2[q], tm[q] = dq, tq
    return np.sqrt(np.maximum(d2, 0.0)), tm


def same_box(span: tuple[np.ndarray, np.ndarray, np.ndarray], i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """(m,) True where pair (i, j) is two drones of one launch box."""
    box = span[0]
    out: np.ndarray = (box[i] >= 0) & (box[i] == box[j])
    return out


def both_airborne(span: tuple[np.ndarray, np.ndarray, np.ndarray], i: np.ndarray, j: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """[lo, hi] (m,) where both drones of each pair are airborne (hi < lo: never)."""
    _, a, b = span
    return np.maximum(a[i], a[j]), np.minimum(b[i], b[j])


def one_airborne(span: tuple[np.ndarray, np.ndarray, np.ndarray], i: np.ndarray, j: np.ndarray, seg: Segment
                 ) -> tuple[np.ndarray, np.ndarray]:
    """[lo, hi] (m,) where exactly one drone of each pair is airborne (between the lift-offs on
    takeoff, between the touchdowns on landing)."""
    _, a, b = span
    if seg.kind == "takeoff":
        return np.minimum(a[i], a[j]), np.maximum(a[i], a[j])
    return np.minimum(b[i], b[j]), np.maximum(b[i], b[j])


def restrict(motion: Trajectories, span: tuple[np.ndarray, np.ndarray, np.ndarray], i: np.ndarray,
             j: np.ndarray, dist: np.ndarray, time_s: np.ndarray, cutoff: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """Distances and times of the pairs with same-box pairs re-minimised over their both-airborne span
    (rule 4; inf where they are never both airborne). Other pairs unchanged."""
    sb = np.flatnonzero(same_box(span, i, j))
    dist, time_s = dist.copy(), time_s.copy()
    if len(sb):
        lo, hi = both_airborne(span, i[sb], j[sb])
        dist[sb], time_s[sb] = _minima(motion, i[sb], j[sb], lo, hi, cutoff)
    return dist, time_s


def clearance(clear_motion: Trajectories, span: tuple[np.ndarray, np.ndarray, np.ndarray], seg: Segment,
              i: np.ndarray, j: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rule 2: the exact minimum over the one-airborne span of each same-box pair, in clearance-ellipsoid
    units (``clear_motion`` scaled by the clearance radius and the downwash height; < 1 inside); inf for
    other pairs."""
    out, tm = np.full(len(i), np.inf), np.zeros(len(i))
    sb = np.flatnonzero(same_box(span, i, j))
    if len(sb):
        lo, hi = one_airborne(span, i[sb], j[sb], seg)
        out[sb], tm[sb] = _minima(clear_motion, i[sb], j[sb], lo, hi, 1.0)
    return out, tm


__all__ = ["PARKED_SEGMENTS", "airborne_span", "clearance", "restrict", "rest_times"]
