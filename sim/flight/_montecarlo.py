"""Monte-Carlo safety margin: fly a show K times with different seeds and report the flown separation.

:func:`monte_carlo` flies the plan ``runs`` times with seeds ``seed0 .. seed0 + runs - 1``
(every per-drone random component of a flight is seeded by ``FlightOptions.seed``), on the
local engine or on a Dask cluster, and reduces each flight as soon as it ends to a few
small arrays (:class:`RunStats`): the closest pair of every recorded frame folded into the
minimum per plan segment (takeoff, each transition and hold, landing) and per time bin, the
largest flown horizontal and vertical speed per time bin, and every drone's largest
deviation from its planned position (the engine's ``tracking_max_m``, over every 1 ms step).
Only one run's flown arrays exist at a time (local) or per worker (Dask); the result holds
``O(K·(segments + bins) + N)`` numbers, whatever the show's length.

What is reported (:meth:`MonteCarloResult.to_json`), for the whole show and per segment:

* the distribution of the flown minimum separation over the runs (quantiles, mean, sd);
* the probability that some pair comes closer than ``min_distance_m`` (less the flight
  tolerance :data:`~sim.flight._result.FLOWN_DISTANCE_TOLERANCE_M`, as the single flight's
  verdict) and closer than ``collision_distance_m``, each with its exact binomial
  (Clopper-Pearson, 1934) confidence interval: the runs are independent Bernoulli trials;
* the worst pairs and when, each drone's largest deviation (over all runs);
* the extra spacing each segment needs at the chosen ``confidence``: how far below
  ``min_distance_m`` the ``1 - confidence`` quantile of the flown minimum falls. The quantile is
  the smaller of the empirical one (exact only with ``runs >= 1 / (1 - confidence)``; fewer
  runs make it the sample minimum, an optimistic estimate, flagged ``empirical_exact: false``)
  and a normal fit ``mean - z·sd``: a planner adding this to the segment's spacing keeps
  ``min_distance_m`` at that confidence, assuming the flight errors do not grow with spacing.

Engines: with ``engine="dask"`` the *runs* (not the drones) are the tasks: each worker flies
whole runs with the local numba kernel and reduces them itself, so only the small
:class:`RunStats` cross the network. A drone's flight does not depend on which process or
how many threads fly it, and every reduction is order-independent (minima, maxima, integer
counts, arrays indexed by run), so both engines give identical numbers for the same seeds.
"""

from __future__ import annotations

import math
import queue
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np
from scipy import stats as sps

from sim.flight._errors import ERROR_PRESETS, error_preset
from sim.flight._options import FlightOptions
from sim.flight._result import FLOWN_DISTANCE_TOLERANCE_M, FlightResult
from sim.flight._runner import fly_local
from sim.flight.engines._state import GROUND_STRIKE_M as GROUND_STRIKE_M  # moved to the engines; old path kept
from sim.geometry import _FORWARD, _cells_closest
from sim.plan._plan import ShowPlan

__all__ = [
    "DEFAULT_COLLISION_DISTANCE_M",
    "DEFAULT_FLIGHT_PRESET",
    "PRESETS",
    "MonteCarloResult",
    "RunStats",
    "binomial_interval",
    "frame_min_distances",
    "monte_carlo",
    "options_for_preset",
    "planned_closest",
    "reduce_flight",
    "single_flight_options",
]

#: Error-model presets of issue 20 (the names of ``sim.flight.ERROR_PRESETS``).
PRESETS: tuple[str, ...] = tuple(ERROR_PRESETS)
#: The error preset a single flight flies unless told otherwise (``swarmshow simulate SHOW``, the API's
#: simulate job, the editor): RTK GNSS and light wind (2 m/s at 10 m), the conditions show drones are
#: normally flown in. "ideal" reports a tracking error of a fraction of a millimetre, which tells a
#: designer nothing (issue 20); "gusty-rtk" is the stress case, one choice away. A Monte-Carlo defaults to it too
#: (the API, the CLI, the editor): run k of a default Monte-Carlo is then the default single flight of seed0 + k.
DEFAULT_FLIGHT_PRESET = "calm-rtk"
#: Centre distance below which two drones count as colliding (m): a show drone is about 0.3-0.5 m
#: across with its guards, so two centres 1 m apart leave a hand's width once both sway.
DEFAULT_COLLISION_DISTANCE_M = 1.0
#: Most time bins of the separation band and the speed curves (a 10-minute show: one per second).
MAX_TIME_BINS = 600
#: Edges of the deviation histogram (m): log-spaced from 0.1 mm to 100 m.
DEVIATION_EDGES_M = np.geomspace(1e-4, 1e2, 61)
#: Quantiles of the flown minimum separation over the runs that the report lists.
QUANTILES = (0.0, 0.01, 0.05, 0.25, 0.5, 0.75, 0.95, 1.0)


def options_for_preset(name: str, base: FlightOptions | None = None) -> FlightOptions:
    """``base`` flying with the error-model preset ``name`` (one of :data:`PRESETS`).

    The one place that maps a preset onto flight options: the preset's per-drone error models
    (:func:`sim.flight.error_preset`), seeded per drone by ``base.seed``.

    Raises:
        ValueError: an unknown preset (names it and the known ones).
    """
    base = base or FlightOptions()
    if name not in PRESETS:
        raise ValueError(f"unknown preset {name!r} (expected one of {', '.join(PRESETS)})")
    # The per-drone, seeded error models (sim.flight._errors) carry everything a preset means; the
    # fleet-wide gusts and mismatch are switched off so they do not count twice.
    return base.with_(errors=error_preset(name), disturbance="none", mismatch=0.0)


def single_flight_options(name: str, base: FlightOptions | None = None) -> FlightOptions:
    """The options of one flight of ``base`` under the error-model preset ``name``, seed ``base.seed``.

    Exactly run ``k`` of :func:`monte_carlo` with ``seed0 + k == base.seed`` (the same
    :func:`options_for_preset`; a run only skips the colours and the per-frame distance pass,
    which change nothing flown), so a seed seen in a Monte-Carlo report flies again alone.
    With ``"ideal"`` the fleet-wide ``base.disturbance`` (the paper's, seeded gusts) still applies:
    the ideal vehicle in the old disturbances; any other preset carries its own wind, so a
    fleet-wide disturbance beside it would count the wind twice.

    Raises:
        ValueError: an unknown preset, or a fleet-wide disturbance with a preset other than
            "ideal" (names ``disturbance``).
    """
    base = base or FlightOptions()
    if name == "ideal":
        return options_for_preset(name, base).with_(disturbance=base.disturbance, mismatch=base.mismatch)
    if base.disturbance != "none":
        raise ValueError(f"disturbance {base.disturbance!r} goes only with preset 'ideal': preset {name!r} "
                         "brings its own wind field")
    return options_for_preset(name, base)


def binomial_interval(successes: int, trials: int, confidence: float) -> tuple[float, float]:
    """Exact two-sided (Clopper & Pearson, 1934) interval of a binomial proportion.

    ``[B(α/2; x, n-x+1), B(1-α/2; x+1, n-x)]`` with ``B`` the beta quantile, ``α = 1 - confidence``;
    0 and 1 at the ends (``x = 0``, ``x = n``). ``(0, 1)`` without trials.
    """
    if trials <= 0:
        return 0.0, 1.0
    x, n, alpha = int(successes), int(trials), 1.0 - float(confidence)
    lo = 0.0 if x == 0 else float(sps.beta.ppf(alpha / 2.0, x, n - x + 1))
    hi = 1.0 if x == n else float(sps.beta.ppf(1.0 - alpha / 2.0, x + 1, n - x))
    return lo, hi


def time_bin_starts(n_frames: int, max_bins: int = MAX_TIME_BINS) -> np.ndarray:
    """First frame of each time bin, ``(B,)`` with ``B = min(n_frames, max_bins)`` (frames split evenly)."""
    b = max(1, min(int(n_frames), int(max_bins)))
    return np.unique(np.linspace(0, n_frames, b + 1)[:-1].astype(np.int64))


def frame_min_distances(
    positions_m: np.ndarray, dead_from_step: np.ndarray | None = None, every: int = 1
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The closest pair of every frame (exact, the cell search of :func:`sim.geometry.closest_pair`).

    One compiled pass over all frames (:func:`_frames_closest`): the per-frame Python calls it
    replaces cost as much as the cell search itself at 1,000 drones (issue 20).

    Args:
        positions_m: ``(T, N, 3)`` positions (m), float32 or float64.
        dead_from_step: Optional ``(N,)`` step each drone stopped counting at (-1: never); drone
            ``a`` counts in frame ``f`` while ``dead_from_step[a] < 0 or dead_from_step[a] > f * every``.
        every: Control steps per frame.

    Returns:
        ``(distance_m (T,), i (T,), j (T,))``, i < j indices into the N drones (inf, -1, -1
        where fewer than two drones count). Drones with a non-finite position in a frame
        have no position there and are left out.
    """
    pos = np.ascontiguousarray(positions_m)
    if pos.dtype not in (np.float32, np.float64):
        pos = pos.astype(np.float64)
    n = pos.shape[1]
    dead = np.full(n, -1, dtype=np.int64) if dead_from_step is None else np.asarray(dead_from_step, np.int64)
    if dead.shape != (n,):
        raise ValueError(f"dead_from_step must be ({n},), got {dead.shape}")
    d, ii, jj = _frames_closest(pos, np.ascontiguousarray(dead), int(every), _FORWARD)
    return d, ii, jj


@numba.njit(cache=True, nogil=True)
def _frames_closest(
    pos: np.ndarray, dead: np.ndarray, every: int, forward: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """:func:`frame_min_distances`'s loop: gather each frame's counted, finite drones, find their closest pair.

    The same search as :func:`sim.geometry.closest_pair` (its cell pass, its exactness rule),
    with the last frame's distance (plus a little) as the cell size: one O(N) pass as a rule.
    """
    t_count, n = pos.shape[0], pos.shape[1]
    d = np.full(t_count, np.inf)
    ii = np.full(t_count, -1, dtype=np.int64)
    jj = np.full(t_count, -1, dtype=np.int64)
    buf = np.empty((n, 3))
    idx = np.empty(n, dtype=np.int64)
    hint = -1.0
    for f in range(t_count):
        m = 0
        for a in range(n):
            if dead[a] >= 0 and dead[a] <= f * every:
                continue
            x, y, z = float(pos[f, a, 0]), float(pos[f, a, 1]), float(pos[f, a, 2])
            if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
                continue
            buf[m, 0], buf[m, 1], buf[m, 2] = x, y, z
            idx[m] = a
            m += 1
        if m < 2:
            continue
        pts = np.ascontiguousarray(buf[:m])
        extent = 0.0
        for c in range(3):
            extent = max(extent, pts[:, c].max() - pts[:, c].min())
        if extent == 0.0:
            d[f], ii[f], jj[f] = 0.0, idx[0], idx[1]
            hint = 0.0
            continue
        floor = extent * 1e-6
        h = hint * 1.05 + 1e-3 if hint >= 0.0 else extent / np.sqrt(m)
        h = max(h, floor)
        while True:
            i, j, dist = _cells_closest(pts, h, forward)
            if dist < h:
                break
            h = dist * (1.0 + 1e-9) + floor if np.isfinite(dist) else h * 4.0
        a0, b0 = idx[i], idx[j]
        d[f], ii[f], jj[f] = dist, min(a0, b0), max(a0, b0)
        hint = dist
    return d, ii, jj


@dataclass
class RunStats:
    """One flight reduced (what a run keeps once its flown arrays are dropped).

    Attributes:
        run: Index of the run (0-based).
        seed: Its seed.
        min_distance_m: Flown minimum separation over the show (m).
        pair: The two drones (plan indices, smaller first).
        time_s: When (s).
        segment_min_m: ``(P,)`` flown minimum per plan segment (m; inf for a segment no frame falls in).
        segment_pair: ``(P, 2)`` its pair (plan indices; -1 where none).
        segment_time_s: ``(P,)`` when (s; NaN where none).
        bin_min_m: ``(B,)`` flown minimum per time bin (m).
        bin_speed_xy_mps: ``(B,)`` largest horizontal speed of any drone per time bin (m/s, from frames).
        bin_speed_z_mps: ``(B,)`` largest vertical speed of any drone per time bin (m/s).
        deviation_max_m: ``(N,)`` each drone's largest distance from its planned position (m).
        diverged: ``[(drone, time_s, reason)]``: the flight's (``"ground"`` for a drone the flight
            stopped more than :data:`~sim.flight.engines._state.GROUND_STRIKE_M` below the show's ground).
        wall_time_s: Wall-clock time of the flight and its reduction (s).
        flight_wall_time_s: Of that, the engine's loop alone (``FlightResult.wall_time_s``: the
            kernel and the per-chunk tables); the rest is setup and reduction (s).
    """

    run: int
    seed: int
    min_distance_m: float
    pair: tuple[int, int]
    time_s: float
    segment_min_m: np.ndarray
    segment_pair: np.ndarray
    segment_time_s: np.ndarray
    bin_min_m: np.ndarray
    bin_speed_xy_mps: np.ndarray
    bin_speed_z_mps: np.ndarray
    deviation_max_m: np.ndarray
    diverged: list[tuple[int, float, str]] = field(default_factory=list)
    wall_time_s: float = 0.0
    flight_wall_time_s: float = 0.0


def _frame_speeds(positions_m: np.ndarray, frame_dt_s: float, block: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """Largest horizontal and vertical speed per frame, ``(T,)`` each, from backward differences (m/s).

    Differences of 25 Hz frames average the speed over 40 ms: peaks shorter than that are
    smoothed (the planned limits hold over whole seconds, so this is what is compared).
    """
    t_count = positions_m.shape[0]
    vxy = np.zeros(t_count)
    vz = np.zeros(t_count)
    for f0 in range(1, t_count, block):
        f1 = min(f0 + block, t_count)
        dp = (positions_m[f0:f1].astype(np.float64) - positions_m[f0 - 1:f1 - 1]) / frame_dt_s  # (b, N, 3)
        dp[~np.isfinite(dp)] = 0.0  # a drone with a non-finite state has no speed
        vxy[f0:f1] = np.max(np.hypot(dp[..., 0], dp[..., 1]), axis=1, initial=0.0)
        vz[f0:f1] = np.max(np.abs(dp[..., 2]), axis=1, initial=0.0)
    if t_count > 1:
        vxy[0], vz[0] = vxy[1], vz[1]
    return vxy, vz


def _segment_fold(
    plan: ShowPlan, times_s: np.ndarray, d: np.ndarray, ii: np.ndarray, jj: np.ndarray, ids: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per plan segment: the smallest frame distance, its pair (plan ids) and time."""
    p_count = len(plan.segments)
    seg = plan.segment_index(times_s)
    seg_min = np.full(p_count, np.inf)
    seg_pair = np.full((p_count, 2), -1, dtype=np.int64)
    seg_time = np.full(p_count, np.nan)
    # Frames are in time order, so each segment's frames are one contiguous run.
    bounds = np.searchsorted(seg, np.arange(p_count + 1), side="left")
    for p in range(p_count):
        a, b = bounds[p], bounds[p + 1]
        if b <= a:
            continue
        k = a + int(np.argmin(d[a:b]))
        if np.isfinite(d[k]):
            seg_min[p] = d[k]
            seg_pair[p] = sorted((int(ids[ii[k]]), int(ids[jj[k]])))
            seg_time[p] = times_s[k]
    return seg_min, seg_pair, seg_time


def reduce_flight(
    plan: ShowPlan, result: FlightResult, *, run: int = 0, seed: int = 0, max_bins: int = MAX_TIME_BINS
) -> RunStats:
    """Reduce one flight to its :class:`RunStats` (the flown arrays can be dropped afterwards).

    Drones count in the separation until the step they diverged at, as in the single flight.
    """
    times = result.times_s
    pos = result.positions_m
    ids = result.drone_ids
    n_frames = times.size
    frame_dt = float(times[1] - times[0]) if n_frames > 1 else 1.0
    every = max(int(round(frame_dt / result.dt_s)), 1)
    where = {int(d): k for k, d in enumerate(ids)}
    dstep = np.full(ids.size, -1, dtype=np.int64)
    diverged = list(result.diverged)
    for drone, t, _reason in diverged:
        dstep[where[drone]] = int(round(t / result.dt_s))
    d, ii, jj = frame_min_distances(pos, dstep, every)
    vxy, vz = _frame_speeds(pos, frame_dt)
    starts = time_bin_starts(n_frames, max_bins)
    seg_min, seg_pair, seg_time = _segment_fold(plan, times, d, ii, jj, ids)
    k = int(np.argmin(d)) if n_frames else 0
    found = n_frames > 0 and np.isfinite(d[k])
    pair = (int(ids[ii[k]]), int(ids[jj[k]])) if found else (-1, -1)
    return RunStats(
        run=int(run), seed=int(seed),
        min_distance_m=float(d[k]) if found else float("inf"),
        pair=(min(pair), max(pair)),
        time_s=float(times[k]) if found else float("nan"),
        segment_min_m=seg_min, segment_pair=seg_pair, segment_time_s=seg_time,
        bin_min_m=np.minimum.reduceat(d, starts) if n_frames else np.zeros(0),
        bin_speed_xy_mps=np.maximum.reduceat(vxy, starts) if n_frames else np.zeros(0),
        bin_speed_z_mps=np.maximum.reduceat(vz, starts) if n_frames else np.zeros(0),
        deviation_max_m=np.asarray(result.tracking_max_m, dtype=np.float64).copy(),
        diverged=diverged,
        wall_time_s=float(result.wall_time_s),
        flight_wall_time_s=float(result.wall_time_s),
    )


def _run_options(options: FlightOptions, seed: int) -> FlightOptions:
    """A run's options: its seed, the local kernel, no flown-distance pass (the reduction does it)."""
    engine = "numba" if options.engine == "dask" else options.engine
    return options.with_(engine=engine, seed=int(seed), scheduler=None, shards=None, flown_distance=False,
                         colors=False)


def fly_run(
    plan: ShowPlan, options: FlightOptions, run: int, seed: int, *, max_bins: int = MAX_TIME_BINS,
    progress: Callable[[float], None] | None = None,
) -> RunStats:
    """Fly and reduce one run in this process (the worker side of both engines)."""
    start = time.perf_counter()
    result = fly_local(plan, _run_options(options, seed), progress=progress)
    out = reduce_flight(plan, result, run=run, seed=seed, max_bins=max_bins)
    out.wall_time_s = time.perf_counter() - start
    return out


@dataclass
class MonteCarloResult:
    """The folded runs of :func:`monte_carlo` (see the module docstring; :meth:`to_json` for the report).

    Attributes:
        runs: ``[(run, seed, min m, pair, time s, diverged count, wall s)]`` in run order.
        segment_min_m: ``(K, P)`` flown minimum per run and segment (m).
        segment_pair: ``(K, P, 2)`` their pairs.
        segment_time_s: ``(K, P)`` their times (s).
        bin_min_m: ``(K, B)`` flown minimum per run and time bin (m).
        bin_speed_xy_mps: ``(B,)`` largest horizontal speed per bin over every run (m/s).
        bin_speed_z_mps: ``(B,)`` largest vertical speed per bin over every run (m/s).
        deviation_max_m: ``(N,)`` each drone's largest deviation over every run (m).
        deviation_counts: ``(len(DEVIATION_EDGES_M) - 1,)`` histogram of every run's per-drone
            largest deviation (values outside the edges are clipped into the end bins).
        diverged: ``[(run, drone, time_s, reason)]``.
    """

    plan: ShowPlan
    options: FlightOptions
    seed0: int
    run_count: int
    confidence: float
    collision_distance_m: float
    preset: str | None
    bin_starts_s: np.ndarray
    bin_ends_s: np.ndarray
    planned_segment_min_m: np.ndarray
    planned_bin_min_m: np.ndarray
    runs: list[dict[str, Any]]
    segment_min_m: np.ndarray
    segment_pair: np.ndarray
    segment_time_s: np.ndarray
    bin_min_m: np.ndarray
    bin_speed_xy_mps: np.ndarray
    bin_speed_z_mps: np.ndarray
    deviation_max_m: np.ndarray
    deviation_counts: np.ndarray
    diverged: list[tuple[int, int, float, str]]
    engine: str
    wall_time_s: float = 0.0

    @property
    def min_distance_limit_m(self) -> float:
        """The show's minimum distance (m)."""
        return float(self.plan.settings.min_distance_m)

    def _probability(self, minima: np.ndarray, threshold_m: float) -> dict[str, Any]:
        """Runs whose minimum fell below ``threshold_m``: count, estimate, Clopper-Pearson interval."""
        x = int(np.count_nonzero(minima < threshold_m))
        n = int(minima.size)
        lo, hi = binomial_interval(x, n, self.confidence)
        return {"threshold_m": threshold_m, "runs_below": x, "runs": n, "p": x / n if n else None,
                "ci_low": lo, "ci_high": hi, "confidence": self.confidence, "method": "clopper-pearson"}

    def required_extra_spacing(self, minima: np.ndarray) -> dict[str, Any]:
        """How much spacing is missing at ``confidence`` given the runs' flown minima (m; see module)."""
        finite = minima[np.isfinite(minima)]
        limit = self.min_distance_limit_m
        if finite.size == 0:
            return {"extra_m": 0.0, "quantile_m": None, "empirical_m": None, "normal_m": None,
                    "empirical_exact": False}
        level = 1.0 - self.confidence
        empirical = float(np.quantile(finite, level, method="inverted_cdf"))
        sd = float(np.std(finite, ddof=1)) if finite.size > 1 else 0.0
        normal = float(np.mean(finite) - sps.norm.ppf(self.confidence) * sd)
        q = min(empirical, normal)
        return {"extra_m": max(0.0, limit - q), "quantile_m": q, "empirical_m": empirical, "normal_m": normal,
                "empirical_exact": bool(finite.size * level >= 1.0)}

    def _distribution(self, minima: np.ndarray) -> dict[str, Any]:
        finite = minima[np.isfinite(minima)]
        if finite.size == 0:
            return {"quantiles": {}, "mean_m": None, "sd_m": None}
        return {
            "quantiles": {f"{q:g}": float(np.quantile(finite, q)) for q in QUANTILES},
            "mean_m": float(np.mean(finite)),
            "sd_m": float(np.std(finite, ddof=1)) if finite.size > 1 else 0.0,
        }

    def worst_pairs(self, count: int = 20) -> list[dict[str, Any]]:
        """The closest pairs of every run and segment, worst first, one row per (pair, segment)."""
        k_count, p_count = self.segment_min_m.shape
        order = np.argsort(self.segment_min_m, axis=None, kind="stable")
        rows: list[dict[str, Any]] = []
        seen: set[tuple[int, int, int]] = set()
        for flat in order:
            k, p = divmod(int(flat), p_count)
            d = float(self.segment_min_m[k, p])
            if not np.isfinite(d):
                break
            a, b = (int(v) for v in self.segment_pair[k, p])
            if (a, b, p) in seen:
                continue
            seen.add((a, b, p))
            rows.append({"drones": [a, b], "distance_m": d, "time_s": float(self.segment_time_s[k, p]),
                         "segment": p, "label": self.plan.segments[p].label, "run": k,
                         "seed": self.seed0 + k,
                         "runs_closest": int(np.count_nonzero((self.segment_pair[:, p, 0] == a)
                                                              & (self.segment_pair[:, p, 1] == b)))})
            if len(rows) >= count:
                break
        return rows

    def to_json(self) -> dict[str, Any]:
        """Everything the safety report draws, as JSON-safe values (no inf/NaN: None)."""
        limit = self.min_distance_limit_m
        near = limit - FLOWN_DISTANCE_TOLERANCE_M
        # Each run's whole-show minimum is its smallest segment minimum (inf without a pair).
        show_min = np.min(self.segment_min_m, axis=1, initial=np.inf)
        segments = []
        for p, s in enumerate(self.plan.segments):
            col = self.segment_min_m[:, p]
            k = int(np.argmin(col)) if col.size else 0
            segments.append({
                "index": p, "kind": s.kind, "label": s.label, "start_s": s.start_s, "duration_s": s.duration_s,
                "planned_min_m": _f(self.planned_segment_min_m[p]),
                "flown_min_m": self._distribution(col),
                "p_below_min_distance": self._probability(col, near),
                "p_collision": self._probability(col, self.collision_distance_m),
                "extra_spacing": self.required_extra_spacing(col),
                "worst": {"distance_m": _f(col[k]) if col.size else None,
                          "drones": [int(v) for v in self.segment_pair[k, p]] if col.size else None,
                          "time_s": _f(self.segment_time_s[k, p]) if col.size else None,
                          "run": k, "seed": self.seed0 + k},
            })
        worst_drones = np.argsort(-self.deviation_max_m, kind="stable")[:10]
        k_best = int(np.argmin(show_min)) if show_min.size else 0
        settings = self.plan.settings
        return {
            "kind": "montecarlo",
            "show": self.plan.show_name,
            "drones": self.plan.drone_count,
            "duration_s": self.plan.duration_s,
            "runs": self.run_count,
            "seed0": self.seed0,
            "preset": self.preset,
            "engine": self.engine,
            "controller": self.options.controller,
            # The fleet-wide disturbance flown (a preset's own wind is in its error models instead): what the
            # runs were flown in is part of what they say.
            "disturbance": (self.options.disturbance if isinstance(self.options.disturbance, str)
                            else self.options.disturbance.name),
            "confidence": self.confidence,
            "min_distance_m": limit,
            "flown_distance_tolerance_m": FLOWN_DISTANCE_TOLERANCE_M,
            "collision_distance_m": self.collision_distance_m,
            "limits": {"max_speed_xy_mps": settings.max_speed_xy_mps, "max_speed_z_mps": settings.max_speed_z_mps},
            "show_min": {
                "flown_min_m": self._distribution(show_min),
                "planned_min_m": _f(float(np.min(self.planned_segment_min_m, initial=np.inf))),
                "p_below_min_distance": self._probability(show_min, near),
                "p_collision": self._probability(show_min, self.collision_distance_m),
                "extra_spacing": self.required_extra_spacing(show_min),
                "worst_run": self.runs[k_best] if self.runs else None,
            },
            "segments": segments,
            "worst_pairs": self.worst_pairs(),
            "band": {
                "start_s": self.bin_starts_s.tolist(),
                "end_s": self.bin_ends_s.tolist(),
                "planned_min_m": [_f(v) for v in self.planned_bin_min_m],
                "min_m": [_f(v) for v in np.min(self.bin_min_m, axis=0)],
                "q05_m": [_f(v) for v in _quantile_rows(self.bin_min_m, 0.05)],
                "median_m": [_f(v) for v in _quantile_rows(self.bin_min_m, 0.5)],
                "q95_m": [_f(v) for v in _quantile_rows(self.bin_min_m, 0.95)],
                "max_m": [_f(v) for v in np.max(self.bin_min_m, axis=0)],
                "speed_xy_max_mps": self.bin_speed_xy_mps.tolist(),
                "speed_z_max_mps": self.bin_speed_z_mps.tolist(),
            },
            "deviation": {
                "edges_m": DEVIATION_EDGES_M.tolist(),
                "counts": self.deviation_counts.astype(int).tolist(),
                "per_drone_max_m": [_f(v) for v in self.deviation_max_m],
                "max_m": _f(float(np.max(self.deviation_max_m, initial=0.0))),
                "worst_drones": [{"drone": int(i), "max_m": _f(self.deviation_max_m[i])} for i in worst_drones],
            },
            "diverged": [{"run": k, "seed": self.seed0 + k, "drone": d, "time_s": t, "reason": r}
                         for k, d, t, r in self.diverged[:200]],
            "diverged_count": len(self.diverged),
            # By physical reason (engines._state): "overpowered" = blown off, lacking the authority
            # (wind beyond the drone's limits); "runaway" = unstable control or a tumble;
            # "non-finite" = the numbers broke down; "ground" = flew into the ground (the flight stops it).
            "diverged_by_reason": {r: sum(1 for *_, why in self.diverged if why == r)
                                   for r in sorted({why for *_, why in self.diverged})},
            "run_list": self.runs,
            "wall_time_s": self.wall_time_s,
        }


def _f(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def _quantile_rows(a: np.ndarray, q: float) -> np.ndarray:
    """Quantile over the runs (axis 0) of a ``(K, B)`` array, ignoring inf (NaN where all are inf)."""
    b = np.where(np.isfinite(a), a, np.nan)
    with np.errstate(all="ignore"):
        if b.shape[0] == 0 or np.isnan(b).all(axis=0).any():
            out = np.full(b.shape[1], np.nan)
            ok = ~np.isnan(b).all(axis=0)
            if ok.any() and b.shape[0]:
                out[ok] = np.nanquantile(b[:, ok], q, axis=0)
            return out
        return np.nanquantile(b, q, axis=0)


class _Accumulator:
    """Folds :class:`RunStats` in any order into arrays indexed by run (order-independent)."""

    def __init__(self, plan: ShowPlan, runs: int, bins: int) -> None:
        p_count, n = len(plan.segments), plan.drone_count
        self.segment_min = np.full((runs, p_count), np.inf)
        self.segment_pair = np.full((runs, p_count, 2), -1, dtype=np.int64)
        self.segment_time = np.full((runs, p_count), np.nan)
        self.bin_min = np.full((runs, bins), np.inf)
        self.speed_xy = np.zeros(bins)
        self.speed_z = np.zeros(bins)
        self.deviation_max = np.zeros(n)
        self.deviation_counts = np.zeros(len(DEVIATION_EDGES_M) - 1, dtype=np.int64)
        self.runs: list[dict[str, Any] | None] = [None] * runs
        self.diverged: list[tuple[int, int, float, str]] = []

    def add(self, s: RunStats) -> None:
        k = s.run
        self.segment_min[k] = s.segment_min_m
        self.segment_pair[k] = s.segment_pair
        self.segment_time[k] = s.segment_time_s
        self.bin_min[k] = s.bin_min_m
        np.maximum(self.speed_xy, s.bin_speed_xy_mps, out=self.speed_xy)
        np.maximum(self.speed_z, s.bin_speed_z_mps, out=self.speed_z)
        dev = np.nan_to_num(s.deviation_max_m, nan=np.inf)
        np.maximum(self.deviation_max, dev, out=self.deviation_max)
        clipped = np.clip(dev, DEVIATION_EDGES_M[0], DEVIATION_EDGES_M[-1])
        self.deviation_counts += np.histogram(clipped, bins=DEVIATION_EDGES_M)[0]
        self.diverged.extend((k, d, t, r) for d, t, r in s.diverged)
        self.runs[k] = {"run": k, "seed": s.seed, "min_distance_m": _f(s.min_distance_m),
                        "pair": list(s.pair), "time_s": _f(s.time_s), "diverged": len(s.diverged),
                        "wall_time_s": s.wall_time_s, "flight_wall_time_s": s.flight_wall_time_s}


def _planned_frames(plan: ShowPlan, times_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The plan's closest pair at each of ``times_s`` ``(T,)``: ``(distance_m, i, j)``, each ``(T,)``."""
    n = plan.drone_count
    d = np.empty(times_s.size)
    ii = np.empty(times_s.size, dtype=np.int64)
    jj = np.empty(times_s.size, dtype=np.int64)
    block = max(1, 2_000_000 // max(n, 1))  # bounds the evaluated positions to ~48 MB
    for f0 in range(0, times_s.size, block):
        pos = plan.motion.evaluate(times_s[f0:f0 + block], derivatives=0).positions_m
        d[f0:f0 + block], ii[f0:f0 + block], jj[f0:f0 + block] = frame_min_distances(pos)
    return d, ii, jj


def _planned_reference(plan: ShowPlan, times_s: np.ndarray, starts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The plan's own minimum per segment and per time bin, at the flight's frame times."""
    d, ii, jj = _planned_frames(plan, times_s)
    seg_min, _, _ = _segment_fold(plan, times_s, d, ii, jj, np.arange(plan.drone_count))
    return seg_min, np.minimum.reduceat(d, starts)


def planned_closest(plan: ShowPlan, times_s: np.ndarray) -> dict[str, Any]:
    """The plan's closest pair over the frame times ``times_s`` ``(T,)`` of a flight, as JSON-safe values.

    What the flown minimum separation is compared with: the same frames, the plan instead of the flight,
    so that the difference is what the flight's errors took from the margin (the exact check's minimum,
    continuous in time, can only be smaller).

    Returns:
        ``{"planned_min_distance_m", "planned_min_distance_pair", "planned_min_distance_time_s"}`` (None
        where fewer than two drones).
    """
    d, ii, jj = _planned_frames(plan, np.asarray(times_s, dtype=np.float64))
    k = int(np.argmin(d)) if d.size else 0
    if d.size == 0 or not np.isfinite(d[k]):
        return {"planned_min_distance_m": None, "planned_min_distance_pair": None, "planned_min_distance_time_s": None}
    return {"planned_min_distance_m": float(d[k]), "planned_min_distance_pair": [int(ii[k]), int(jj[k])],
            "planned_min_distance_time_s": float(times_s[k])}


def monte_carlo(
    plan: ShowPlan,
    options: FlightOptions | None = None,
    *,
    runs: int = 20,
    seed0: int = 0,
    confidence: float = 0.99,
    collision_distance_m: float = DEFAULT_COLLISION_DISTANCE_M,
    preset: str | None = None,
    max_bins: int = MAX_TIME_BINS,
    progress: Callable[[float], None] | None = None,
) -> MonteCarloResult:
    """Fly ``plan`` ``runs`` times with seeds ``seed0 .. seed0 + runs - 1`` and fold the runs.

    Args:
        plan: The planned show.
        options: How to fly (engine ``numba``/``numpy`` locally, one run after the other, or
            ``dask`` with ``scheduler``: one task per run). Its ``seed`` is replaced per run.
        runs: K, the number of flights (>= 1).
        seed0: Seed of the first run.
        confidence: Level of the intervals and of the extra spacing, in (0, 1).
        collision_distance_m: Centre distance counted as a collision (m), > 0.
        preset: The error-model preset ``options`` were made with (reported only).
        max_bins: Most time bins of the separation band.
        progress: Called with the completed fraction; raising from it stops the runs.

    Raises:
        ValueError: an argument out of range (names it).
        SchedulerUnreachableError: with ``engine="dask"``, no scheduler or worker answered.
    """
    options = options or FlightOptions()
    if not (isinstance(runs, int) and runs >= 1):
        raise ValueError(f"runs must be an integer >= 1, got {runs!r}")
    if not (0.0 < confidence < 1.0):
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    if not (math.isfinite(collision_distance_m) and collision_distance_m > 0):
        raise ValueError(f"collision_distance_m must be > 0, got {collision_distance_m}")
    start = time.perf_counter()
    every = max(int(round(1.0 / (options.output_hz * 1e-3))), 1)
    steps = int(round(plan.duration_s / 1e-3)) + 1
    times = np.arange((steps - 1) // every + 1) * every * 1e-3
    starts = time_bin_starts(times.size, max_bins)
    ends = np.append(times[starts[1:]], times[-1])
    report = _Monotone(progress)
    planned_seg, planned_bin = _planned_reference(plan, times, starts)
    report(0.01)
    acc = _Accumulator(plan, runs, starts.size)

    def on_run(done: float) -> None:
        report(0.01 + 0.99 * done / runs)

    if options.engine == "dask":
        _fly_dask(plan, options, runs, seed0, max_bins, acc, on_run)
    else:
        for k in range(runs):
            stats = fly_run(plan, options, k, seed0 + k, max_bins=max_bins,
                            progress=lambda f, k=k: on_run(k + f))  # type: ignore[misc]
            acc.add(stats)
            del stats
    report(1.0)
    return MonteCarloResult(
        plan=plan, options=options, seed0=int(seed0), run_count=runs, confidence=float(confidence),
        collision_distance_m=float(collision_distance_m), preset=preset,
        bin_starts_s=times[starts], bin_ends_s=ends,
        planned_segment_min_m=planned_seg, planned_bin_min_m=planned_bin,
        runs=[r for r in acc.runs if r is not None],
        segment_min_m=acc.segment_min, segment_pair=acc.segment_pair, segment_time_s=acc.segment_time,
        bin_min_m=acc.bin_min, bin_speed_xy_mps=acc.speed_xy, bin_speed_z_mps=acc.speed_z,
        deviation_max_m=acc.deviation_max, deviation_counts=acc.deviation_counts,
        diverged=sorted(acc.diverged), engine=options.engine,
        wall_time_s=time.perf_counter() - start,
    )


class _Monotone:
    """Forward only increasing fractions in [0, 1] to ``callback``."""

    def __init__(self, callback: Callable[[float], None] | None) -> None:
        self.callback, self.last = callback, -1.0

    def __call__(self, fraction: float) -> None:
        f = min(max(float(fraction), 0.0), 1.0)
        if self.callback is not None and f > self.last:
            self.last = f
            self.callback(f)


# ----------------------------------------------------------------------------------------
# Dask: one task per run
# ----------------------------------------------------------------------------------------
def _dask_run(plan: ShowPlan, options: FlightOptions, run: int, seed: int, max_bins: int, token: str) -> RunStats:
    """Fly and reduce one run on a worker, reporting progress as scheduler events."""
    from sim.flight import _dask

    _dask.worker_notes()  # a compile note as "swarmshow: ..." on the worker's stderr
    with _dask._ENGINE_LOCK:
        return fly_run(plan, options, run, seed, max_bins=max_bins, progress=_dask.task_progress(token, run, "run"))


def _fly_dask(
    plan: ShowPlan, options: FlightOptions, runs: int, seed0: int, max_bins: int, acc: _Accumulator,
    on_run: Callable[[float], None],
) -> None:
    """Submit one task per run, fold each result as it arrives, report the summed run fractions."""
    from sim.flight._dask import _ROUTES, _ROUTES_LOCK, _hold_plan, connect_scheduler, route_progress

    token = uuid.uuid4().hex
    events: queue.SimpleQueue[tuple[int, float]] = queue.SimpleQueue()
    wake = threading.Event()

    def on_event(run: int, fraction: float) -> None:
        events.put((run, fraction))
        wake.set()

    with connect_scheduler(options.scheduler, options.connect_timeout_s) as client:
        route_progress(client, token, on_event)
        futures: list[Any] = []
        try:
            plan_future = client.submit(_hold_plan, plan, key=f"swarmshow-mc-plan-{token}", pure=False)
            futures.append(plan_future)
            # The workers fly locally: no scheduler (a Client does not pickle) in what they get.
            local = options.with_(engine="numba", scheduler=None, shards=None)
            run_futures = [
                client.submit(_dask_run, plan_future, local, k, seed0 + k, max_bins, token,
                              key=f"swarmshow-mc-run-{token}-{k}", retries=2, pure=False)
                for k in range(runs)
            ]
            futures.extend(run_futures)
            for f in run_futures:
                f.add_done_callback(lambda _f: wake.set())
            done = [0.0] * runs
            pending = set(range(runs))
            while pending:
                for k in sorted(pending):
                    if run_futures[k].done():
                        acc.add(run_futures[k].result())  # raises the task's error
                        pending.discard(k)
                        done[k] = 1.0
                while True:
                    try:
                        k, fraction = events.get_nowait()
                    except queue.Empty:
                        break
                    if 0 <= k < runs:
                        done[k] = max(done[k], min(float(fraction), 1.0))
                on_run(sum(done) * (1.0 - 1e-6))
                if pending:
                    wake.wait(0.5)
                    wake.clear()
        except BaseException:
            client.cancel(futures, force=True)
            raise
        finally:
            with _ROUTES_LOCK:
                _ROUTES.pop(token, None)
            for f in futures:
                f.release()
