"""Cue times: fitting a transition into the window between two pinned show times.

A formation pinned to ``arrive_at_s`` must be reached exactly then, so the transition into it
lasts ``arrive_at_s - t0`` (``t0``: when the previous hold ends). :func:`fit_transition` re-times
the planner's own (safe) transition to that window:

* a single-leg transition is re-planned with the window as its forced duration: every drone's
  profile stretches (or squeezes) and the per-drone delays are re-placed inside the window, each
  pair certified again (:func:`sim.plan._schedule.schedule_transition`, its delays kept inside the
  window);
* a longer window for a multi-leg (layered) transition keeps its legs and adds a rest leg at the
  start: the drones stay in the previous formation a little longer, then fly the certified legs,
  so the formation still appears exactly at its cue;
* a window shorter than the limits allow, or in which no safe timing is found, does not fit:
  :func:`earliest_window` then gives the shortest window (on the planner's 0.1 s grid) that was
  verified to fit, for the message that names the earliest feasible cue time.
"""

from __future__ import annotations

from sim.plan._schedule import (
    Limits,
    TransitionPlan,
    round_up,
    schedule_transition,
    sync_min_duration,
    synchronised,
)

#: Times closer than this are equal, seconds.
TIME_EPS_S = 1e-6
#: Bisection steps spent looking for the earliest feasible window (each one plans the transition).
EARLIEST_STEPS = 6


def _forced(tp: TransitionPlan, window_s: float, lim: Limits, min_distance_m: float,
            label: str) -> TransitionPlan | None:
    """``tp`` flown as one leg in exactly ``window_s`` (delays only inside it), or None if not safe so."""
    a_m, b_m = tp.legs[0].a_m, tp.legs[-1].b_m
    sched = schedule_transition(a_m, b_m, lim, min_distance_m=min_distance_m, duration_s=window_s,
                                max_delay_s=0.0, label=label)
    if sched.unresolved or sched.window_s > window_s + TIME_EPS_S:
        return None
    return TransitionPlan((sched,), tp.goal_index, sched.resolution, window_s)


def limits_minimum_s(tp: TransitionPlan, lim: Limits) -> float:
    """The shortest window the speed, acceleration and jerk limits allow for flying ``tp`` as one leg, seconds."""
    return round_up(sync_min_duration(tp.legs[-1].b_m - tp.legs[0].a_m, lim))


def fit_transition(tp: TransitionPlan, window_s: float, lim: Limits, *, min_distance_m: float,
                   label: str = "") -> TransitionPlan | None:
    """``tp`` re-timed to last exactly ``window_s`` seconds, or None when it cannot be (module docstring).

    Args:
        tp: the planner's transition (its natural, shortest safe timing).
        window_s: the window between the pinned times, seconds.
        lim: limits and time law.
        min_distance_m: Δ, metres.
        label: transition name for messages.
    """
    natural = tp.window_s
    if abs(window_s - natural) <= TIME_EPS_S:
        return tp
    if window_s < limits_minimum_s(tp, lim) - TIME_EPS_S:
        return None
    if len(tp.legs) == 1 or window_s < natural:
        fitted = _forced(tp, window_s, lim, min_distance_m, label)
        if fitted is not None:
            return fitted
    if window_s > natural:
        # Wait in the start formation (a rest is safe: the drones are where the previous hold left them).
        a_m = tp.legs[0].a_m
        rest = synchronised(a_m, a_m, lim, window_s - natural)
        overlaps = (0.0, *tp.overlaps_s) if tp.overlaps_s else ()  # the legs keep their certified overlaps
        return TransitionPlan((rest, *tp.legs), tp.goal_index, tp.resolution, tp.sync_s, tp.expansion,
                              overlaps_s=overlaps)
    return None


def earliest_window(tp: TransitionPlan, lim: Limits, *, min_distance_m: float, label: str = "") -> float:
    """The shortest window (seconds, on the 0.1 s grid) verified to fit ``tp``: between the limits' minimum
    and the planner's natural window, by bisection over :data:`EARLIEST_STEPS` forced re-plans."""
    natural = tp.window_s
    lo = limits_minimum_s(tp, lim)
    if lo >= natural - TIME_EPS_S:
        return natural
    if _forced(tp, lo, lim, min_distance_m, label) is not None:
        return lo
    hi = natural  # fits (it is the planner's own timing)
    for _ in range(EARLIEST_STEPS):
        mid = round_up(0.5 * (lo + hi))
        if mid >= hi - TIME_EPS_S or mid <= lo + TIME_EPS_S:
            break
        if _forced(tp, mid, lim, min_distance_m, label) is not None:
            hi = mid
        else:
            lo = mid
    return hi


__all__ = ["earliest_window", "fit_transition", "limits_minimum_s"]
