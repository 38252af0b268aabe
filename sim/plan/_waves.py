"""Takeoff and landing in waves, for home layouts too dense to climb at once (launch boxes).

**When.** Drones that climb together on one vertical profile keep their ground offsets, so two of
them are safe iff their homes are at least the required separation apart horizontally:
``max(min_distance_m, downwash radius)`` (at equal altitude the downwash ellipsoid of Preiss et
al. 2017 reduces to its horizontal radius). The *home conflict graph* joins homes closer than
that. When it has no edge (every validated grid or point layout at the default downwash radius)
everybody climbs at once, exactly as before: :func:`takeoff_waves` returns None and the plan is
unchanged.

**Waves.** Otherwise the graph is coloured with DSatur (Brélaz 1979; :func:`sim.plan._schedule._dsatur`),
each colour a *wave* of drones that may climb together. Wave k climbs vertically over its own home
to its own *layer*: wave 0 (the first to leave) highest, wave W-1 lowest, layers ``gap·1.1``
apart with ``gap = max(min_distance_m, downwash half-height)``. A drone of a later wave therefore
only ever climbs *below* the drones that left before it, and stays at least ``gap`` below the
previous wave throughout (:func:`_offsets`: wave k leaves when the altitude it will reach at
every instant stays ``gap`` under where wave k-1 is by then), so it is never inside their
downwash ellipsoid (vertical offset >= half-height) and never closer than ``min_distance_m``;
drones of one wave keep their ground distance (>= the separation, by the colouring). Every drone
waits dark on its home until its wave leaves (*parked*, see :mod:`sim.verify._parked` for the
rules the exact check applies to parked drones). At the end of the takeoff window the drones
hover in layers over their homes, all pairs >= ``min_distance_m`` apart, and the first
transition starts from there as from the lifted grid.

**Landing** is the time reverse: the transition before landing ends in the layers over the
landing homes (coloured afresh: with ``any_home`` CAPT picks the homes), then the lowest layer
descends first and each higher wave follows, staying ``gap`` above the one below it.

Minimal waves: the number of waves is at least the largest clique of the conflict graph (all
drones of one box usually form one, so a box of 8 gives 8 waves); DSatur is exact on the
interval-like graphs of box patterns in the tests (compared with a brute-force colouring).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from sim.plan._schedule import Limits, Schedule, _dsatur, own_profiles, round_up
from sim.plan._timelaw import evaluate_profiles

#: Layers are this factor times the required vertical gap apart (margin for the sampled offsets).
LAYER_FACTOR = 1.1
#: Samples per profile when placing the waves' departures.
_SAMPLES = 4001
#: Departures are padded by this before rounding up to the window step, seconds.
_PAD_S = 0.05


@dataclass(frozen=True)
class Waves:
    """Takeoff (or landing) waves of N drones.

    ``wave`` (N,) each drone's wave (0 leaves first on takeoff, lands last on landing);
    ``layer_m`` (N,) its hover altitude above its home; ``schedule`` the motion home -> layer
    (takeoff) or layer -> home (landing), times local to the window start.
    """

    wave: np.ndarray
    count: int
    layer_m: np.ndarray
    schedule: Schedule

    @property
    def window_s(self) -> float:
        """Length of the takeoff (landing) window, seconds."""
        return float(self.schedule.window_s)

    def wave_times_s(self) -> list[tuple[float, float, int]]:
        """(start, end, drones) of each wave, local seconds, in the order the waves fly."""
        out = []
        for k in range(self.count):
            m = self.wave == k
            out.append((float(self.schedule.depart_s[m].min()), float(self.schedule.arrive_s[m].max()), int(m.sum())))
        return sorted(out)


def required_horizontal_m(min_distance_m: float, downwash_radius_m: float) -> float:
    """Ground distance two homes need to climb together, metres."""
    return max(min_distance_m, downwash_radius_m)


def conflict_pairs(homes_m: np.ndarray, need_m: float) -> np.ndarray:
    """(E, 2) pairs of homes closer than ``need_m`` horizontally (i < j)."""
    if len(homes_m) < 2:
        return np.zeros((0, 2), dtype=np.int64)
    pairs: np.ndarray = cKDTree(homes_m[:, :2]).query_pairs(need_m * (1 - 1e-9), output_type="ndarray")
    return pairs.astype(np.int64)


def colour_waves(n: int, pairs: np.ndarray) -> np.ndarray:
    """(n,) wave of each home: DSatur colouring of the conflict graph (adjacent homes differ)."""
    src = np.concatenate([pairs[:, 0], pairs[:, 1]])
    dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
    o = np.argsort(src, kind="stable")
    nbrs, starts = dst[o].astype(np.int64), np.searchsorted(src[o], np.arange(n + 1)).astype(np.int64)
    return np.asarray(_dsatur(starts, nbrs, n), dtype=np.int64)


def _climb_curves(heights_m: np.ndarray, lim: Limits, descend: bool) -> tuple[np.ndarray, np.ndarray, object]:
    """Per wave: durations (W,), the climb curve z_k(u) sampled (W, S) in metres on u = linspace(0, T_k),
    and the profiles. For a descent the curve is that of the time-reversed landing."""
    sign = -1.0 if descend else 1.0
    d = np.zeros((len(heights_m), 3))
    d[:, 2] = sign * heights_m
    prof, _ = own_profiles(d, lim)
    dur = prof.breaks_s[:, -1]
    u = np.linspace(0.0, 1.0, _SAMPLES)[None, :] * dur[:, None]
    s = evaluate_profiles(prof, u.T).T  # (W, S)
    if descend:  # reversed time: altitude above home at reversed time u is h·(1 - s(T - u))
        s = 1.0 - evaluate_profiles(prof, (dur[:, None] - u).T).T
    return dur, heights_m[:, None] * s, prof


def _offsets(dur_s: np.ndarray, curves_m: np.ndarray, gap_m: float) -> np.ndarray:
    """Departures (W,) of waves climbing top layer first, each staying ``gap_m`` below the previous.

    Wave k at local time u is at z_k(u); wave k-1 reaches altitude a at local time inv_{k-1}(a).
    Wave k may be at z_k(u) at show time δ_k + u only if wave k-1 is already above z_k(u) + gap,
    i.e. δ_k >= δ_{k-1} + inv_{k-1}(z_k(u) + gap) - u for every u (z monotone). Sampled densely,
    padded and rounded up; the exact check certifies the result.
    """
    w = len(dur_s)
    out = np.zeros(w)
    for k in range(1, w):
        prev = curves_m[k - 1]
        t_prev = np.linspace(0.0, dur_s[k - 1], _SAMPLES)
        need = curves_m[k] + gap_m
        u = np.linspace(0.0, dur_s[k], _SAMPLES)
        # first time wave k-1 reaches each needed altitude (prev is non-decreasing)
        inv = np.interp(need, np.maximum.accumulate(prev), t_prev, right=np.inf)
        out[k] = round_up(max(out[k - 1], out[k - 1] + float(np.max(inv - u)) + _PAD_S))
    return out


def layer_heights(count: int, base_m: float, gap_m: float) -> np.ndarray:
    """(count,) hover altitude above the home of each wave, metres: wave 0 highest, the last at ``base_m``."""
    return base_m + (count - 1 - np.arange(count)) * gap_m * LAYER_FACTOR


def wave_gap(min_distance_m: float, downwash_m: tuple[float, float]) -> float:
    """Vertical distance a wave keeps below the one before it, metres."""
    return max(min_distance_m, downwash_m[1])


def home_waves(homes_m: np.ndarray, *, min_distance_m: float, downwash_radius_m: float) -> np.ndarray | None:
    """(H,) wave of every home (DSatur), or None when all may climb at once."""
    pairs = conflict_pairs(homes_m, required_horizontal_m(min_distance_m, downwash_radius_m))
    return colour_waves(len(homes_m), pairs) if len(pairs) else None


def plan_waves(homes_m: np.ndarray, wave: np.ndarray, lim: Limits, base_m: float, gap_m: float, *,
               landing: bool, count: int | None = None) -> Waves:
    """The wave schedule of homes (N, 3) with waves (N,): climb (or descend) between home and layer.

    ``count``: the number of layers (default: ``wave.max() + 1``; more when ``wave`` is a subset of a
    colouring whose layers are already placed, e.g. the homes CAPT picked for landing).
    """
    count = int(wave.max()) + 1 if count is None else count
    heights = layer_heights(count, base_m, gap_m)
    dur, curves, prof = _climb_curves(heights, lim, descend=landing)
    dep = _offsets(dur, curves, gap_m)
    window = round_up(float(np.max(dep + dur)))
    if landing:  # time reverse: wave k descends during [window - dep_k - T_k, window - dep_k]
        # (a nanosecond early, so that summed piece durations never end past the window)
        dep = np.maximum(window - dep - dur - 1e-9, 0.0)
    layer = heights[wave]
    top = homes_m + np.column_stack([np.zeros((len(wave), 2)), layer])
    a, b = (top, homes_m) if landing else (homes_m, top)
    n = len(wave)
    return Waves(
        wave=wave, count=count, layer_m=layer,
        schedule=Schedule(
            a_m=a, b_m=b, depart_s=dep[wave], arrive_s=(dep + dur)[wave], prof_row=wave.copy(), scale=np.ones(n),
            profiles=prof,  # type: ignore[arg-type]
            sync_s=window, window_s=window, unresolved=(),
        ),
    )


def takeoff_waves(homes_m: np.ndarray, lim: Limits, *, min_distance_m: float, downwash_m: tuple[float, float],
                  base_m: float, landing: bool = False) -> Waves | None:
    """Waves for taking off from (or landing on) ``homes_m`` (N, 3), or None when all may climb at once.

    Args:
        homes_m: the drones' homes (takeoff) or landing homes, metres.
        lim: the plan's limits.
        min_distance_m: the separation.
        downwash_m: (radius, half-height) of the downwash ellipsoid, metres.
        base_m: the lowest layer's altitude above the homes (the takeoff altitude), metres.
        landing: descend from the layers instead of climbing to them.
    """
    wave = home_waves(homes_m, min_distance_m=min_distance_m, downwash_radius_m=downwash_m[0])
    if wave is None:
        return None
    return plan_waves(homes_m, wave, lim, base_m, wave_gap(min_distance_m, downwash_m), landing=landing)


__all__ = ["LAYER_FACTOR", "Waves", "colour_waves", "conflict_pairs", "home_waves", "layer_heights", "plan_waves",
           "required_horizontal_m", "takeoff_waves", "wave_gap"]
