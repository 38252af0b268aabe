"""Monte-Carlo safety margin (sim.flight.monte_carlo): statistics against independent computations.

* the Clopper-Pearson interval against scipy's exact binomial test;
* the per-frame closest pair against brute force (every pair, scipy's pdist), with dead drones left out;
* one flight's reduction (per segment, per time bin, speeds, deviations) against brute force
  over its recorded frames, segments taken from the plan's segment times;
* K runs: each run's flown minimum equals a separate single flight with that seed (the flight's
  own flown-distance fold), the probabilities count those runs, local and Dask give the same numbers.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats as sps
from scipy.spatial.distance import pdist, squareform

from sim import plan_show
from sim.flight import (
    FLOWN_DISTANCE_TOLERANCE_M,
    FlightOptions,
    binomial_interval,
    fly_show,
    monte_carlo,
    options_for_preset,
)
from sim.flight._montecarlo import frame_min_distances, reduce_flight, time_bin_starts
from tests.conftest import make_show


@given(n=st.integers(1, 400), data=st.data(), conf=st.sampled_from([0.8, 0.9, 0.95, 0.99, 0.999]))
@settings(max_examples=60, deadline=None)
def test_binomial_interval_matches_scipy_exact(n: int, data: st.DataObject, conf: float) -> None:
    x = data.draw(st.integers(0, n))
    lo, hi = binomial_interval(x, n, conf)
    ref = sps.binomtest(x, n).proportion_ci(confidence_level=conf, method="exact")
    assert lo == pytest.approx(ref.low, abs=1e-9)
    assert hi == pytest.approx(ref.high, abs=1e-9)
    assert lo <= x / n <= hi


def test_frame_min_distances_brute_force() -> None:
    rng = np.random.default_rng(3)
    pos = rng.uniform(-20, 20, size=(30, 40, 3)).astype(np.float32)
    d, i, j = frame_min_distances(pos)
    for f in range(pos.shape[0]):
        m = squareform(pdist(pos[f].astype(np.float64)))
        np.fill_diagonal(m, np.inf)
        a, b = np.unravel_index(np.argmin(m), m.shape)
        assert d[f] == pytest.approx(m[a, b], rel=1e-12)
        assert {i[f], j[f]} == {a, b}
    # A "dead" drone placed on top of another is ignored when left out of the alive set.
    pos[:, 5] = pos[:, 7]
    dead = np.full(40, -1)
    dead[5] = 0
    d2, i2, j2 = frame_min_distances(pos, dead)
    assert np.all(d2 > 0) and not np.any(i2 == 5) and not np.any(j2 == 5)
    # Drone 7 stops counting from step 100 (frame 10 at 10 steps per frame) on.
    dead[7] = 100
    d3, i3, j3 = frame_min_distances(pos, dead, every=10)
    for f in range(pos.shape[0]):
        keep = np.flatnonzero((dead < 0) | (dead > f * 10))
        m = squareform(pdist(pos[f, keep].astype(np.float64)))
        np.fill_diagonal(m, np.inf)
        a, b = np.unravel_index(np.argmin(m), m.shape)
        assert d3[f] == pytest.approx(m[a, b], rel=1e-12) and {i3[f], j3[f]} == {keep[a], keep[b]}


def test_non_finite_drones_are_left_out() -> None:
    """A drone whose state went NaN has no position (distance) and no speed in those frames."""
    from sim.flight._montecarlo import _frame_speeds

    rng = np.random.default_rng(5)
    pos = rng.uniform(-20, 20, size=(12, 25, 3))
    pos[4:, 3] = np.nan
    d, i, j = frame_min_distances(pos)
    for f in range(12):
        keep = np.isfinite(pos[f]).all(axis=1)
        assert d[f] == pytest.approx(pdist(pos[f][keep]).min(), rel=1e-12)
    assert not np.isin(3, i[4:]) and not np.isin(3, j[4:])
    vxy, vz = _frame_speeds(pos, 0.04)
    assert np.isfinite(vxy).all() and np.isfinite(vz).all()
    ref = np.abs(np.diff(np.delete(pos, 3, axis=1)[4:, :, 2], axis=0)).max(axis=1) / 0.04
    assert np.all(vz[5:] >= ref - 1e-9)


def test_time_bins_cover_every_frame() -> None:
    for n, b in [(1, 600), (10, 600), (15001, 600), (601, 600), (7, 3)]:
        s = time_bin_starts(n, b)
        assert s[0] == 0 and np.all(np.diff(s) > 0) and s[-1] < n and s.size == min(n, b)


def test_reduce_flight_matches_brute_force(plan12) -> None:
    flight = fly_show(plan12, FlightOptions(disturbance="wind", mismatch=0.05, seed=4))
    stats = reduce_flight(plan12, flight, run=2, seed=4, max_bins=17)
    pos = flight.positions_m.astype(np.float64)
    t = flight.times_s
    brute = np.array([pdist(p).min() for p in pos])
    # Whole show: the run's minimum is the flight's own flown-distance fold.
    assert stats.min_distance_m == pytest.approx(flight.flown_min_distance_m, rel=1e-12)
    assert stats.min_distance_m == pytest.approx(brute.min(), rel=1e-12)
    assert stats.pair == flight.flown_min_distance_pair
    # Per segment, frames assigned by the plan's segment start and end times.
    for p, seg in enumerate(plan12.segments):
        last = p == len(plan12.segments) - 1
        inside = (t >= seg.start_s) & ((t < seg.end_s) | last)
        if not inside.any():
            assert math.isinf(stats.segment_min_m[p])
            continue
        k = np.flatnonzero(inside)[np.argmin(brute[inside])]
        assert stats.segment_min_m[p] == pytest.approx(brute[k], rel=1e-12)
        assert stats.segment_time_s[p] == pytest.approx(t[k])
        a, b = stats.segment_pair[p]  # a pair at that distance (a home grid has ties)
        assert a < b and np.linalg.norm(pos[k, a] - pos[k, b]) == pytest.approx(brute[k], rel=1e-12)
    # Per time bin (17 bins over the frames) and the speeds from frame differences.
    edges = np.linspace(0, t.size, 18).astype(int)
    v = np.diff(pos, axis=0) / (t[1] - t[0])
    vxy = np.r_[0.0, np.hypot(v[..., 0], v[..., 1]).max(axis=1)]
    vz = np.r_[0.0, np.abs(v[..., 2]).max(axis=1)]
    vxy[0], vz[0] = vxy[1], vz[1]
    for b in range(17):
        sl = slice(edges[b], edges[b + 1])
        assert stats.bin_min_m[b] == pytest.approx(brute[sl].min(), rel=1e-12)
        assert stats.bin_speed_xy_mps[b] == pytest.approx(vxy[sl].max(), rel=1e-5)
        assert stats.bin_speed_z_mps[b] == pytest.approx(vz[sl].max(), rel=1e-5, abs=1e-9)
    np.testing.assert_array_equal(stats.deviation_max_m, flight.tracking_max_m)


def test_monte_carlo_runs_equal_single_flights(plan12) -> None:
    base = options_for_preset("gusty-rtk", FlightOptions())
    runs, seed0 = 4, 10
    mc = monte_carlo(plan12, base, runs=runs, seed0=seed0, confidence=0.9, collision_distance_m=2.5, max_bins=50)
    singles = [fly_show(plan12, base.with_(seed=seed0 + k)) for k in range(runs)]
    flown = np.array([s.flown_min_distance_m for s in singles])
    got = np.array([r["min_distance_m"] for r in mc.runs])
    np.testing.assert_allclose(got, flown, rtol=1e-12)
    assert [r["seed"] for r in mc.runs] == list(range(seed0, seed0 + runs))
    assert [tuple(r["pair"]) for r in mc.runs] == [s.flown_min_distance_pair for s in singles]
    # Per-drone largest deviation: the maximum over the runs of each flight's tracking maximum.
    np.testing.assert_array_equal(mc.deviation_max_m, np.max([s.tracking_max_m for s in singles], axis=0))
    assert mc.deviation_counts.sum() == runs * plan12.drone_count

    j = mc.to_json()
    limit = plan12.settings.min_distance_m
    below = int(np.count_nonzero(flown < limit - FLOWN_DISTANCE_TOLERANCE_M))
    pb = j["show_min"]["p_below_min_distance"]
    assert (pb["runs_below"], pb["runs"]) == (below, runs)
    assert (pb["ci_low"], pb["ci_high"]) == pytest.approx(binomial_interval(below, runs, 0.9))
    pc = j["show_min"]["p_collision"]
    assert pc["runs_below"] == int(np.count_nonzero(flown < 2.5))
    q = j["show_min"]["flown_min_m"]["quantiles"]
    assert q["0"] == pytest.approx(flown.min()) and q["0.5"] == pytest.approx(np.median(flown))
    # Extra spacing: how far the (1 - confidence) quantile falls below the limit, never negative.
    ex = j["show_min"]["extra_spacing"]
    normal = flown.mean() - sps.norm.ppf(0.9) * flown.std(ddof=1)
    assert ex["normal_m"] == pytest.approx(normal)
    assert ex["empirical_m"] == pytest.approx(np.sort(flown)[0])  # 4 runs at 10 %: the smallest
    assert ex["empirical_exact"] is False
    assert ex["extra_m"] == pytest.approx(max(0.0, limit - min(normal, flown.min())))
    # Segments: the whole-show minimum is the smallest segment minimum of each run.
    seg = np.array([[s["flown_min_m"]["quantiles"].get("0", np.inf) for s in j["segments"]]])
    assert np.nanmin(seg) == pytest.approx(flown.min())
    np.testing.assert_allclose(np.min(mc.segment_min_m, axis=1), flown, rtol=1e-12)
    # Band: per time bin, the minimum, quantiles and maximum over the runs of each run's bin minimum.
    assert min(v for v in j["band"]["min_m"] if v is not None) == pytest.approx(flown.min())
    for key, q in (("q05_m", 0.05), ("median_m", 0.5), ("q95_m", 0.95)):
        np.testing.assert_allclose(j["band"][key], np.quantile(mc.bin_min_m, q, axis=0), rtol=1e-12)
    np.testing.assert_allclose(j["band"]["max_m"], mc.bin_min_m.max(axis=0), rtol=1e-12)
    assert j["worst_pairs"][0]["distance_m"] == pytest.approx(flown.min())
    # Bounded memory: nothing in the result is a per-frame, per-drone array.
    for name, value in vars(mc).items():
        if isinstance(value, np.ndarray):
            assert value.size <= runs * max(len(plan12.segments), 50) * 2 + plan12.drone_count + 100, name


def test_monte_carlo_rejects_bad_arguments(plan12) -> None:
    with pytest.raises(ValueError, match="runs"):
        monte_carlo(plan12, runs=0)
    with pytest.raises(ValueError, match="confidence"):
        monte_carlo(plan12, runs=1, confidence=1.0)
    with pytest.raises(ValueError, match="collision_distance_m"):
        monte_carlo(plan12, runs=1, collision_distance_m=0.0)
    with pytest.raises(ValueError, match="unknown preset 'windy'"):
        options_for_preset("windy")


def test_a_lone_drone_gives_json_without_infinities() -> None:
    """No pair at all: distances are absent (None), never inf/NaN in the JSON."""
    import json

    show = make_show([{"name": "dot", "hold_s": 1.0, "points": [[0.0, 0.0, 10.0]], "color": "#ffffff"}],
                     drones=1, rows=1, cols=1)
    j = monte_carlo(plan_show(show), runs=2).to_json()
    json.dumps(j, allow_nan=False)
    assert j["show_min"]["flown_min_m"]["quantiles"] == {} and j["show_min"]["p_below_min_distance"]["runs_below"] == 0
    assert all(r["min_distance_m"] is None for r in j["run_list"]) and j["worst_pairs"] == []


def test_progress_rises_to_one(plan12) -> None:
    seen: list[float] = []
    monte_carlo(plan12, FlightOptions(), runs=2, progress=seen.append)
    assert seen == sorted(seen) and seen[-1] == 1.0 and len(seen) > 3


def test_dask_gives_identical_numbers(plan12) -> None:
    distributed = pytest.importorskip("distributed")
    base = options_for_preset("gusty-rtk")
    local = monte_carlo(plan12, base, runs=3, seed0=7, max_bins=40).to_json()
    with distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, host="127.0.0.1", dashboard_address=None,
    ) as cluster, distributed.Client(cluster, set_as_default=False) as client:
        seen: list[float] = []
        remote = monte_carlo(plan12, base.with_(engine="dask", scheduler=client), runs=3, seed0=7, max_bins=40,
                             progress=seen.append).to_json()
    for j in (local, remote):
        j.pop("wall_time_s")
        j.pop("engine")
        for r in j["run_list"]:
            r.pop("wall_time_s")
            r.pop("flight_wall_time_s")
        j["show_min"]["worst_run"].pop("wall_time_s", None)  # the same dict as its run_list row
        j["show_min"]["worst_run"].pop("flight_wall_time_s", None)
    assert remote == local
    assert seen[-1] == 1.0


def test_a_drone_that_flies_into_the_ground_counts_as_diverged(plan12) -> None:
    """QA: a calm-RTK Monte-Carlo run of a 9-drone show had drone 4 lose height control in the landing and fly to
    z = -24 m, 'below the ground', with 'diverged 0' in the safety report (its tracking error stayed under the
    25 m runaway limit). The flight itself stops such a drone ("ground", engines._state); the reduction takes the
    flight's reasons as they are (no second rule of its own) and counts the crashed drone in the separation
    before the frame of its crash, not from it on (as a runaway)."""
    from dataclasses import replace

    from sim.flight.engines._state import GROUND_STRIKE_M

    flight = fly_show(plan12, FlightOptions())
    assert flight.diverged == []
    pos = flight.positions_m.copy()
    t = flight.times_s
    n_frames = t.size
    dive = np.arange(n_frames) >= n_frames // 2
    pos[dive, 3, 2] = -np.linspace(0.1, 30.0, dive.sum())  # drone 3 dives through the ground
    first = int(np.flatnonzero(pos[:, 3, 2] < -GROUND_STRIKE_M)[0])
    pos[first + 1:, 3] = pos[first + 1:, 5]  # ... and, being gone, may sit on drone 5 without counting
    crashed = replace(flight, positions_m=pos, diverged=[(3, float(t[first]), "ground")])
    stats = reduce_flight(plan12, crashed)
    assert stats.diverged == [(3, pytest.approx(float(t[first])), "ground")]
    others = np.delete(np.arange(pos.shape[1]), 3)
    brute = np.array([pdist(p[others if f >= first else slice(None)].astype(np.float64)).min()
                      for f, p in enumerate(pos)])
    assert stats.min_distance_m == pytest.approx(brute.min(), rel=1e-9) and stats.min_distance_m > 0
    # The reduction has no ground rule of its own: positions the flight did not stop are not re-judged.
    assert reduce_flight(plan12, replace(flight, positions_m=pos)).diverged == []


def test_drones_that_lose_their_thrust_stop_at_the_ground_in_the_flight(plan12) -> None:
    """A flown show has a ground: with the battery sagging to 10 % of the thrust (thrust-to-weight 2 -> 0.2)
    every drone falls, and the flight itself (not only the Monte-Carlo reduction) stops each one "ground",
    after its thrust-to-weight fell below 1, at a frame where it is below -GROUND_STRIKE_M. (The runaway
    limit is moved out of the way: the show flies at 20-30 m, so a falling drone is 25 m off first.)"""
    from sim.flight import ErrorModel
    from sim.flight.engines._state import GROUND_STRIKE_M

    half = plan12.duration_s / 2
    sag = ErrorModel(name="flat", battery_sag=0.9, battery_duration_s=half)
    flight = fly_show(plan12, FlightOptions(errors=sag, output_hz=1000.0, divergence_limit_m=1000.0))
    assert sorted(d for d, _, _ in flight.diverged) == list(range(plan12.drone_count))
    lift_lost_s = half * (1.0 - 1.0 / 2.0) / 0.9  # 2 (1 - 0.9 t / half) = 1
    for d, t_s, why in flight.diverged:
        assert why == "ground" and t_s > lift_lost_s
        f = int(round(t_s * 1000.0))
        # Frame f is the state step f starts from: the first one below the strike depth.
        assert flight.positions_m[f, d, 2] < -GROUND_STRIKE_M + 1e-6
        assert flight.positions_m[f - 1, d, 2] >= -GROUND_STRIKE_M - 1e-6
    assert reduce_flight(plan12, flight).diverged == flight.diverged
