"""Blended legs (sim/plan/_blend.py): certified limits and separation against independent computations.

References: dense sampling of the scalar profiles and of the blended motion, brute-force grids for the
box minimisation, the plain sum of the legs' profiles (evaluate_profiles) for the blended pieces, the
polynomial pieces' own jerk, and the exact verifier on whole dense shows.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.bench._dense import dense_show
from sim.plan import _blend, plan_show
from sim.plan._blend import (
    SAFE_CHUNK,
    SUB_WINDOW_S,
    Junction,
    _box_min_sq,
    _box_min_sq_one,
    blend_overlaps,
    blended_pieces,
    profile_range,
)
from sim.plan._schedule import Limits, round_up, sync_min_duration, synchronised
from sim.plan._timelaw import evaluate_profiles
from sim.plan._trajectory import TrajectoryBuilder
from sim.verify import check_plan

LIM = Limits(v_xy=10.0, v_z=2.0, a=4.0, j=10.0)


def _leg(a: np.ndarray, b: np.ndarray, lim: Limits = LIM, extra_s: float = 0.0):
    return synchronised(a, b, lim, round_up(sync_min_duration(b - a, lim)) + extra_s)


@settings(max_examples=25, deadline=None)
@given(length=st.floats(0.2, 40.0), extra=st.floats(0.0, 5.0), order=st.integers(0, 3),
       t0=st.floats(0.0, 1.0), width=st.floats(0.01, 1.0))
def test_profile_range_contains_dense_samples_and_is_tight(length, extra, order, t0, width) -> None:
    """The exact range of s^(q) over an interval contains every sampled value and is reached by them."""
    leg = _leg(np.zeros((1, 3)), np.array([[length, 0.0, 0.0]]), extra_s=extra)
    prof = leg.profiles
    dur = float(prof.breaks_s[0, -1])
    lo_t, hi_t = t0 * dur, min(dur, t0 * dur + width * dur)
    lo, hi = profile_range(prof.breaks_s[0], prof.coeffs[0], lo_t, hi_t, order)
    u = np.linspace(lo_t, hi_t, 4001)
    # Sample strictly inside each piece for the jerk (a step function: the one-sided values at breaks count).
    vals = evaluate_profiles(prof, u[:, None], order)[:, 0]
    tol = 1e-9 * max(1.0, abs(lo), abs(hi))
    assert vals.min() >= lo - tol and vals.max() <= hi + tol
    if order < 3:  # continuous: dense samples come close to the exact extremes
        span = max(hi - lo, 1e-12)
        assert vals.min() <= lo + 1e-2 * span + tol and vals.max() >= hi - 1e-2 * span - tol


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_box_minimum_matches_a_brute_force_grid(seed) -> None:
    """min over the box of |r0 + u·c1 + w·c2|²: never above a fine grid's minimum, and within its resolution."""
    rng = np.random.default_rng(seed)
    k = 20
    r0, c1, c2 = rng.normal(0, 3, (k, 3)), rng.normal(0, 3, (k, 3)), rng.normal(0, 3, (k, 3))
    c2[:3] = c1[:3] * rng.normal(size=(3, 1))  # parallel directions: a singular Hessian
    c1[3] = 0.0
    lo1, lo2 = sorted(rng.uniform(0, 1, 2)), sorted(rng.uniform(0, 1, 2))
    got = _box_min_sq(r0, c1, c2, (lo1[0], lo1[1]), (lo2[0], lo2[1]))
    u = np.linspace(lo1[0], lo1[1], 301)
    w = np.linspace(lo2[0], lo2[1], 301)
    sq = np.zeros((k, len(u), len(w)))  # |r0 + u·c1 + w·c2|² on the grid, one axis at a time (no (k, 301, 301, 3))
    for a in range(3):
        sq += (r0[:, a, None, None] + u[None, :, None] * c1[:, a, None, None]
               + w[None, None, :] * c2[:, a, None, None]) ** 2
    grid = sq.reshape(k, -1).min(axis=1)
    assert np.all(got <= grid + 1e-9)
    step = max(lo1[1] - lo1[0], lo2[1] - lo2[0]) / 300
    bound = (np.linalg.norm(c1, axis=1) + np.linalg.norm(c2, axis=1)) * step
    assert np.all(np.sqrt(grid) - np.sqrt(np.maximum(got, 0)) <= bound + 1e-9)


def _blended_motion(legs, overlaps):
    builder = TrajectoryBuilder(legs[0].a_m, 0.0)
    for dur, c3 in blended_pieces(legs, overlaps):
        builder.append(np.full(len(legs[0].a_m), dur), c3)
    return builder.build()


def _random_legs(rng: np.random.Generator, n: int):
    a = np.column_stack([np.arange(n) * 3.0, np.zeros(n), np.full(n, 20.0)])
    b = a + np.column_stack([np.zeros(n), rng.choice([-1.0, 0.0, 1.0], n) * rng.uniform(1, 3), np.zeros(n)])
    c = b + rng.normal(0, 1, (n, 3)) * np.array([6.0, 6.0, 2.0]) + rng.normal(0, 4, 3)
    d = c + rng.normal(0, 1.0, (n, 3))
    return a, b, c, d


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 8), share=st.sampled_from([0.5, 0.7, 1.0]))
def test_blended_motion_is_the_sum_of_the_legs_and_keeps_the_certified_limits(seed, n, share) -> None:
    """Blended pieces equal A + Σ s_k(t - o_k)·D_k; sampled speed, acceleration, jerk within the limits; the
    pairs the certificate accepts keep the distance in dense samples."""
    rng = np.random.default_rng(seed)
    a, b, c, d = _random_legs(rng, n)
    part = Limits(v_xy=10.0, v_z=2.0, a=4.0 * share, j=10.0 * share)
    legs = (_leg(a, b, part), _leg(b, c, part), _leg(c, d, part))
    required = 1.0
    overlaps = blend_overlaps(legs, LIM, required)
    assert overlaps[0] + overlaps[1] <= legs[1].window_s + 1e-9
    motion = _blended_motion(legs, overlaps)
    end = sum(leg.window_s for leg in legs) - sum(overlaps)
    assert motion.end_s == pytest.approx(end)
    t = np.linspace(0.0, end, 3001)
    smp = motion.evaluate(t)
    offsets = [0.0, legs[0].window_s - overlaps[0], legs[0].window_s + legs[1].window_s - sum(overlaps)]
    ref = np.broadcast_to(a, smp.positions_m.shape).copy()
    for o, leg in zip(offsets, legs, strict=True):
        s = evaluate_profiles(leg.profiles, (t - o)[:, None], 0)[:, :1]
        ref += s[..., None] * (leg.b_m - leg.a_m)[None]
    assert np.abs(smp.positions_m - ref).max() < 1e-8
    assert np.abs(smp.positions_m[-1] - d).max() < 1e-8
    v = smp.velocities_mps
    assert np.hypot(v[..., 0], v[..., 1]).max() <= LIM.v_xy * (1 + 1e-6)
    assert np.abs(v[..., 2]).max() <= LIM.v_z * (1 + 1e-6)
    assert np.linalg.norm(smp.accelerations_mps2, axis=2).max() <= LIM.a * (1 + 1e-6)
    jerk = _piece_jerk_max(motion)
    assert jerk <= LIM.j * (1 + 1e-6)
    # Separation: where the legs alone keep `required`, the blended motion does too (the certificate).
    alone = [_pair_min(np.stack([leg.a_m + s * (leg.b_m - leg.a_m) for s in np.linspace(0, 1, 201)])) for leg in legs]
    if min(alone) >= required:
        assert _pair_min(smp.positions_m) >= required * (1 - 1e-9)


def _pair_min(pos: np.ndarray) -> float:
    diff = pos[:, :, None, :] - pos[:, None, :, :]
    dist = np.linalg.norm(diff, axis=-1)
    n = pos.shape[1]
    dist[:, np.arange(n), np.arange(n)] = np.inf
    return float(dist.min())


def _piece_jerk_max(motion) -> float:
    """Largest jerk magnitude of any piece, from the coefficients (6c3 + 24c4·u + 60c5·u², at both ends and
    11 inner points), over pieces of positive length."""
    c = motion.coeffs_m
    dur = np.diff(motion.breaks_s, axis=1)
    best = 0.0
    for f in np.linspace(0, 1, 13):
        u = (dur * f)[..., None]
        j = 6 * c[..., 3] + 24 * c[..., 4] * u + 60 * c[..., 5] * u**2
        mag = np.linalg.norm(j, axis=-1)
        best = max(best, float(mag[dur > 1e-12].max(initial=0.0)))
    return best


def test_a_junction_that_would_double_the_acceleration_is_refused() -> None:
    """Two full-limit legs in the same direction: overlapping them would add their accelerations."""
    a = np.zeros((1, 3)) + [0.0, 0.0, 20.0]
    b = a + [8.0, 0.0, 0.0]
    c = b + [8.0, 0.0, 0.0]
    junction = Junction(_leg(a, b), _leg(b, c), LIM, 1.0)
    # The decelerating end of leg 1 and the accelerating start of leg 2 overlap: the speed stays below the
    # cruise, but the jerks add (both +j along x at the junction) beyond j.
    assert not junction.within_limits(1)
    assert blend_overlaps((_leg(a, b), _leg(b, c)), LIM, 1.0) == (0.0,)
    # At half the limits each, any overlap is within the limits.
    half = Limits(v_xy=4.9, v_z=0.9, a=1.9, j=4.9)  # (just under half: the margin is relative)
    junction = Junction(_leg(a, b, half), _leg(b, c, half), LIM, 1.0)
    assert all(junction.within_limits(q) for q in range(1, junction.count + 1))


def test_an_overlap_that_collides_is_refused() -> None:
    """Drone 0 spreads away from drone 1's path, then moves through where drone 1 arrives: overlapping the
    legs would cut the corner into drone 1."""
    a = np.array([[0.0, 0.0, 20.0], [4.0, 0.0, 20.0]])
    b = np.array([[0.0, 4.0, 20.0], [4.0, 0.0, 20.0]])
    c = np.array([[8.0, 4.0, 20.0], [4.0, 0.0, 20.0]])
    legs = (_leg(a, b), _leg(b, c))
    junction = Junction(*legs, Limits(v_xy=np.inf, v_z=np.inf, a=np.inf, j=np.inf), 3.9)
    q = junction.count
    assert not junction.safe(q)  # the straight cut from (0, 0) to (8, 4) passes 1.8 m from drone 1
    # and the sampled blended motion indeed comes closer than 3.9 m at full overlap
    motion = _blended_motion(legs, (q * SUB_WINDOW_S,))
    pos = motion.evaluate(np.linspace(0, motion.end_s, 2001)).positions_m
    assert np.linalg.norm(pos[:, 0] - pos[:, 1], axis=1).min() < 3.9


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1))
def test_compiled_box_minimum_equals_the_vectorised_one(seed) -> None:
    """The compiled one-pair box minimum (used by Junction.safe) is the vectorised one, pair by pair."""
    rng = np.random.default_rng(seed)
    k = 20
    r0, c1, c2 = rng.normal(0, 3, (k, 3)), rng.normal(0, 3, (k, 3)), rng.normal(0, 3, (k, 3))
    c2[:3] = c1[:3] * rng.normal(size=(3, 1))
    c1[3] = 0.0
    c2[4] = 0.0
    lo1, lo2 = sorted(rng.uniform(0, 1, 2)), sorted(rng.uniform(0, 1, 2))
    want = _box_min_sq(r0, c1, c2, (lo1[0], lo1[1]), (lo2[0], lo2[1]))
    got = [_box_min_sq_one(r0[p], c1[p], c2[p], lo1[0], lo1[1], lo2[0], lo2[1]) for p in range(k)]
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def _safe_reference(junction: Junction, q: int) -> bool:
    """Junction.safe written with the vectorised box minimum over all candidate pairs (no pruning by
    distance, no refinement): unsafe iff some pair is below the distance on some single sub-window."""
    a, d1, d2 = junction.leg1.a_m, junction.d1, junction.d2
    b1, b2 = junction._boxes(q, 0)
    i, j = np.triu_indices(len(a), 1)
    r0, e1, e2 = a[j] - a[i], d1[j] - d1[i], d2[j] - d2[i]
    for c0 in range(0, q, SAFE_CHUNK):
        for k in range(c0, min(q, c0 + SAFE_CHUNK)):
            low = _box_min_sq(r0, e1, e2, (b1[k, 0], b1[k, 1]), (b2[k, 0], b2[k, 1]))
            if np.any(low < junction.required_m**2):
                return False
    return True


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 12), required=st.floats(0.5, 4.0),
       threads=st.booleans())
def test_junction_safe_matches_an_all_pairs_reference(seed, n, required, threads) -> None:
    """The compiled refinement (pruned candidates, halving; chunks in batches on threads or one by one)
    decides every overlap like the all-pairs, sub-window-by-sub-window reference: pruning, refinement and
    batching miss nothing and add nothing."""
    rng = np.random.default_rng(seed)
    a, b, c, _ = _random_legs(rng, n)
    junction = Junction(_leg(a, b), _leg(b, c), None, required)
    saved = _blend.PARALLEL_MIN_DRONES
    _blend.PARALLEL_MIN_DRONES = 0 if threads else saved
    try:
        for q in range(1, junction.count + 1):
            assert junction.safe(q) == _safe_reference(junction, q), q
    finally:
        _blend.PARALLEL_MIN_DRONES = saved


@pytest.mark.parametrize("n", [40, 100])
def test_dense_show_with_blended_legs_passes_the_exact_check_within_the_jerk_limit(n: int, monkeypatch) -> None:
    """A dense show plans with blended legs, passes the exact verifier, keeps the jerk limit on every piece,
    and is shorter than the same show flown leg after leg."""
    show = dense_show(n, formations=4)
    plan = plan_show(show)
    assert all(not tr.unresolved for tr in plan.transitions)
    report = check_plan(plan)
    assert report.violations_total == 0
    assert _piece_jerk_max(plan.motion) <= show.settings.max_jerk_mps3 * (1 + 1e-6)
    monkeypatch.setattr("sim.plan._schedule.BLEND_SHARES", ())
    unblended = plan_show(show)
    assert plan.duration_s < unblended.duration_s - 1.0


def test_a_pinned_arrival_later_than_a_blended_transition_keeps_its_overlaps() -> None:
    """A formation's arrive_at_s after the blended transition's natural end (issue 18's rest leg first):
    the drones arrive exactly then, the plan passes the exact check, and the legs stay blended."""
    from formations import parse_show

    show = dense_show(40, formations=2)
    natural = plan_show(show)
    into = natural.transitions[1]
    doc = show.model_dump(mode="json", exclude_none=True)
    pinned = into.start_s + into.duration_s + 3.0
    doc["formations"][1]["arrive_at_s"] = pinned
    plan = plan_show(parse_show(doc))
    tr = plan.transitions[1]
    assert tr.start_s + tr.duration_s == pytest.approx(pinned, abs=1e-9)
    assert check_plan(plan).violations_total == 0
    hold = [seg for name, seg in plan.formation_segments() if name == show.formations[1].name][0]
    at = plan.motion.evaluate(np.array([hold.start_s, hold.end_s])).positions_m
    assert np.abs(at - plan.knot_positions_m[hold.index][None]).max() < 1e-8
