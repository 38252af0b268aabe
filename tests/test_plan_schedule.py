"""Per-drone timing: certified pair checks, pruning, spreading and whole dense shows safe by construction.

Independent references: brute force over all pairs, dense sampling of the plan's motion with a
Lipschitz bound between samples, and the closed-form shared-β minimum.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.bench._dense import dense_show
from sim.plan import PlanError, _schedule, plan_show
from sim.plan._pairs import close_path_pairs, pairs_conflicts
from sim.plan._plan import trajectories_from_knots
from sim.plan._schedule import Limits, own_profiles, schedule_transition, spread, sync_conflicts
from sim.plan._timelaw import Profiles, evaluate_profiles
from tests.conftest import fibonacci_sphere, make_show, ring

LIM = Limits(v_xy=10.0, v_z=2.0, a=4.0, j=10.0)


def brute_segment_distance(a0, a1, b0, b1, n=201):
    """Minimum distance between two segments by a dense grid over both parameters."""
    s = np.linspace(0, 1, n)
    p = a0[None] + s[:, None] * (a1 - a0)[None]
    q = b0[None] + s[:, None] * (b1 - b0)[None]
    return float(np.min(np.linalg.norm(p[:, None] - q[None], axis=2)))


@settings(max_examples=12, deadline=None)
@given(n=st.integers(2, 14), spread_m=st.floats(2, 30), travel=st.floats(0, 40), r=st.floats(0.5, 5),
       seed=st.integers(0, 2**31 - 1))
def test_path_pruning_misses_no_pair(n, spread_m, travel, r, seed) -> None:
    rng = np.random.default_rng(seed)
    a = rng.uniform(-spread_m, spread_m, (n, 3))
    b = a + rng.normal(size=(n, 3)) * travel
    found = {tuple(p) for p in close_path_pairs(a, b, r)}
    for i in range(n):
        for j in range(i + 1, n):
            d = brute_segment_distance(a[i], b[i], a[j], b[j])
            step = max(np.linalg.norm(b[i] - a[i]), np.linalg.norm(b[j] - a[j])) / 200
            if d < r - step - 1e-9:  # surely within r (the grid overestimates by <= one step)
                assert (i, j) in found
            if (i, j) in found:
                assert d < r + 1e-9 + step


def test_sync_conflicts_match_the_closed_form_over_all_pairs() -> None:
    rng = np.random.default_rng(3)
    a = rng.uniform(-20, 20, (80, 3))
    b = a + rng.normal(size=(80, 3)) * 15
    i, j = np.triu_indices(80, 1)
    off = a[j] - a[i]
    c = (b[j] - b[i]) - off
    cc = (c * c).sum(1)
    s = np.clip(-(off * c).sum(1) / cc, 0, 1)
    d = np.linalg.norm(off + s[:, None] * c, axis=1)
    expected = {(int(p), int(q)) for p, q, x in zip(i, j, d, strict=True) if x < 4.0}
    got = {tuple(int(v) for v in p) for p in sync_conflicts(a, b, 4.0)}
    assert got == expected



def _closed_form_conflicts(a: np.ndarray, b: np.ndarray, required: float) -> set[tuple[int, int]]:
    """All pairs, brute force: the closed-form minimum of |Δa + s·Δd| over s in [0, 1]."""
    n = len(a)
    i, j = np.triu_indices(n, 1)
    off = a[j] - a[i]
    c = (b[j] - b[i]) - off
    cc = (c * c).sum(1)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(cc > 0, np.clip(-(off * c).sum(1) / cc, 0, 1), 0.0)
    d = np.linalg.norm(off + s[:, None] * c, axis=1)
    return {(int(p), int(q)) for p, q, x in zip(i, j, d, strict=True) if x < required}


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 60), move=st.floats(0.0, 60.0),
       lattice=st.booleans(), threads=st.booleans())
def test_sync_conflicts_match_brute_force_on_random_and_lattice_sets(seed, n, move, lattice, threads) -> None:
    """The sliced k-d-tree search misses no pair and adds none, also on lattices exactly at the distance
    (the planner's case: ties at Δ against the required Δ·(1 - 5e-10)), for sets that do not move, and
    with the slices searched on threads."""
    rng = np.random.default_rng(seed)
    if lattice:
        a = np.column_stack([np.arange(n) % 5, (np.arange(n) // 5) % 5, np.arange(n) // 25]) * 3.0
        b = a[rng.permutation(n)] + rng.choice([0.0, move], 3)
    else:
        a = rng.uniform(-20, 20, (n, 3))
        b = a + rng.normal(size=(n, 3)) * move
    required = 3.0 * (1 - 5e-10)
    saved = _schedule.PARALLEL_MIN_WORK
    _schedule.PARALLEL_MIN_WORK = 0 if threads else saved
    try:
        got = {tuple(int(v) for v in p) for p in sync_conflicts(a, b, required)}
    finally:
        _schedule.PARALLEL_MIN_WORK = saved
    assert got == _closed_form_conflicts(a, b, required)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 12))
def test_certified_pair_check_agrees_with_dense_sampling(seed, n) -> None:
    """Random legs and timings: every certified-safe pair is safe when sampled densely, every
    reported conflict is a real one at the reported time."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(-8, 8, (n, 3)) + np.array([0, 0, 30])
    b = a + rng.normal(size=(n, 3)) * 6
    d_m = b - a
    own, peak = own_profiles(d_m, LIM)
    breaks = np.concatenate([own.breaks_s[:1], own.breaks_s])  # row 0 unused here
    coeffs = np.concatenate([own.coeffs[:1], own.coeffs])
    peaks = np.concatenate([peak[:1], peak])
    dur = own.breaks_s[:, -1]
    dep = rng.uniform(0, 3, n)
    scale = rng.uniform(1, 1.6, n)
    arr = dep + dur * scale
    pairs = np.array([(i, j) for i in range(n) for j in range(i + 1, n)], dtype=np.int64)
    required = 3.0
    flags, times = pairs_conflicts(pairs, a, d_m, breaks, coeffs, np.arange(n) + 1, dep, scale, arr, peaks,
                                   np.linalg.norm(d_m, axis=1), required)
    t = np.linspace(0, arr.max() + 0.5, 30001)
    prof = Profiles(own.breaks_s, own.coeffs)
    pos = a[None] + evaluate_profiles(prof, (t[:, None] - dep[None]) / scale[None])[..., None] * d_m[None]
    for k, (i, j) in enumerate(pairs):
        dist = np.linalg.norm(pos[:, i] - pos[:, j], axis=1)
        if not flags[k]:
            assert dist.min() >= required - 1e-6
        else:
            u = (np.array([times[k]]) - dep) / scale
            p = a + evaluate_profiles(prof, u)[:, None] * d_m
            assert np.linalg.norm(p[i] - p[j]) < required


@pytest.mark.parametrize("kind", ["square", "hex", "ball", "ground"])
def test_spread_only_moves_pairs_apart_and_reaches_k_delta(kind: str) -> None:
    delta, k = 3.0, float(np.sqrt(2))
    if kind == "square":
        g = np.stack(np.meshgrid(np.arange(7), np.arange(6)), -1).reshape(-1, 2) * delta
        pts = np.c_[g[:, 0], np.zeros(len(g)), g[:, 1] + 20]
    elif kind == "hex":
        jj, ii = np.meshgrid(np.arange(6), np.arange(7), indexing="ij")
        u = (ii + 0.5 * (jj % 2)) * delta
        v = jj * delta * np.sqrt(3) / 2
        pts = np.c_[u.ravel(), np.zeros(u.size), v.ravel() + 20]
    elif kind == "ball":
        g = np.stack(np.meshgrid(*[np.arange(4)] * 3), -1).reshape(-1, 3) * delta
        pts = g + np.array([0, 0, 20])
    else:
        g = np.stack(np.meshgrid(np.arange(8), np.arange(5)), -1).reshape(-1, 2) * delta
        pts = np.c_[g, np.full(len(g), 10.0)]
    out = spread(pts, k, delta, 1000.0)
    assert out is not None
    i, j = np.triu_indices(len(pts), 1)
    before = np.linalg.norm(pts[i] - pts[j], axis=1)
    assert np.linalg.norm(out[i] - out[j], axis=1).min() >= k * delta - 1e-9
    for s in np.linspace(0, 1, 41)[1:]:
        now = pts + s * (out - pts)
        after = np.linalg.norm(now[i] - now[j], axis=1)
        assert np.all(after >= before - 1e-9)  # nondecreasing along the way
        before = after


def sampled_min_distance(plan, dt=0.02):
    """Brute force over all pairs at every sample, and a Lipschitz lower bound between samples."""
    t = np.arange(0.0, plan.duration_s + dt, dt)
    smp = plan.motion.evaluate(t, derivatives=1)
    p = smp.positions_m
    n = p.shape[1]
    i, j = np.triu_indices(n, 1)
    d = np.linalg.norm(p[:, i] - p[:, j], axis=2)
    speed = np.linalg.norm(smp.velocities_mps, axis=2)
    v_rel = np.maximum(speed[:-1, i] + speed[:-1, j], speed[1:, i] + speed[1:, j]) + 2 * 4.0 * dt
    lb = 0.5 * (d[:-1] + d[1:]) - v_rel * dt / 2
    return float(d.min()), float(lb.min()), smp


def check_limits_and_holds(plan, smp, dt=0.02) -> None:
    st = plan.settings
    v = smp.velocities_mps
    assert np.hypot(v[..., 0], v[..., 1]).max() <= st.max_speed_xy_mps * (1 + 1e-6)
    assert np.abs(v[..., 2]).max() <= st.max_speed_z_mps * (1 + 1e-6)
    acc = plan.motion.evaluate(np.arange(0.0, plan.duration_s, dt)).accelerations_mps2
    assert np.linalg.norm(acc, axis=2).max() <= st.max_accel_mps2 * (1 + 1e-6)
    # Holds are exact: every drone rests on its formation point for hold_s.
    for name, seg in plan.formation_segments():
        k = seg.index
        pts = plan.knot_positions_m[k]
        tt = np.linspace(seg.start_s, seg.end_s, 7)
        sm = plan.motion.evaluate(tt)
        assert np.abs(sm.positions_m - pts[None]).max() < 1e-9, name
        assert np.abs(sm.velocities_mps).max() < 1e-9


@pytest.mark.parametrize("n, law", [(30, "min_time"), (56, "min_time"), (30, "quintic")])
def test_dense_show_is_safe_by_construction(n: int, law: str) -> None:
    """Formations drawn at exactly min_distance_m: no pair ever closer, limits kept, holds exact."""
    show = dense_show(n, formations=4, time_law=law)
    plan = plan_show(show)
    assert all(not tr.unresolved for tr in plan.transitions)
    sampled, certified, smp = sampled_min_distance(plan)
    delta = show.settings.min_distance_m
    assert sampled >= delta * (1 - 1e-9)
    assert certified >= delta - 0.35  # the Lipschitz bound's slack at dt = 0.02 s
    check_limits_and_holds(plan, smp)
    # Window boundaries: every drone rests at its knot.
    at = plan.motion.evaluate(plan.knot_times_s)
    assert np.abs(at.positions_m - plan.knot_positions_m).max() < 1e-8
    for tr in plan.transitions:
        assert np.all(tr.depart_s >= tr.start_s - 1e-9) and np.all(tr.arrive_s <= tr.start_s + tr.duration_s + 1e-9)
        assert tr.stagger_s >= 0


def test_quintic_mode_reproduces_the_shared_quintic_plan(small_show) -> None:
    """CAPT-safe shows: the quintic time law gives exactly the knot-based shared quintic of the paper."""
    show = small_show.model_copy(update={"settings": small_show.settings.model_copy(update={"time_law": "quintic"})})
    plan = plan_show(show)
    assert all(tr.resolution == "none" for tr in plan.transitions)
    ref = trajectories_from_knots(plan.knot_times_s, plan.knot_positions_m)
    t = np.linspace(0, plan.duration_s, 3001)
    a, b = plan.motion.evaluate(t), ref.evaluate(t)
    assert np.abs(a.positions_m - b.positions_m).max() < 1e-9
    assert np.abs(a.velocities_mps - b.velocities_mps).max() < 1e-9
    # Today's durations: peak-exact quintic bounds rounded up to 0.1 s.
    for tr in plan.transitions:
        assert tr.duration_s == tr.min_duration_s


def test_min_time_is_faster_than_the_quintic(small_show) -> None:
    fast = plan_show(small_show)
    slow = plan_show(small_show.model_copy(
        update={"settings": small_show.settings.model_copy(update={"time_law": "quintic"})}))
    assert fast.duration_s < 0.8 * slow.duration_s
    sampled, _, smp = sampled_min_distance(fast)
    assert sampled >= 3.0
    check_limits_and_holds(fast, smp)


def test_own_home_landing_returns_every_drone_home() -> None:
    show = dense_show(30, formations=2, landing="own_home")
    plan = plan_show(show)
    assert np.abs(plan.knot_positions_m[-1] - show.home_positions_m).max() < 1e-9
    assert np.array_equal(plan.transitions[-1].goal_index, np.arange(30))
    assert not plan.transitions[-1].unresolved
    sampled, _, smp = sampled_min_distance(plan)
    assert sampled >= 3.0 * (1 - 1e-9)
    check_limits_and_holds(plan, smp)


def test_a_forced_transition_that_cannot_be_made_safe_is_reported() -> None:
    """Forced duration (one leg, no spreading): conflicts that delays cannot fix are named, with a real time."""
    pts = ring(12, 3.0001 / (2 * np.sin(np.pi / 12)), center=(0, 0, 20))
    show = make_show(
        [{"name": "ring", "hold_s": 1.0, "points": pts},
         {"name": "ball", "hold_s": 1.0, "points": fibonacci_sphere(12, 3.5, center=(0, 0, 20)),
          "transition_s": 3.0}],
        drones=12, rows=3, cols=4, spacing_m=3.0, min_distance_m=3.0,
    )
    plan = plan_show(show, enforce_limits=False)
    tr = plan.transitions[1]
    sampled, _, _ = sampled_min_distance(plan)
    if sampled >= 3.0 * (1 - 1e-9):
        assert not tr.unresolved
        return
    assert tr.unresolved and tr.resolution == "unresolved"
    for u in tr.unresolved:
        assert len(u.drones) == 2 and "space" in u.fix
        assert tr.start_s <= u.time_s <= tr.start_s + tr.duration_s
        p = plan.motion.evaluate([u.time_s]).positions_m[0]
        assert np.linalg.norm(p[u.drones[0]] - p[u.drones[1]]) < 3.0


def test_a_forced_duration_below_the_minimum_still_raises(small_show) -> None:
    f = small_show.formations[0].model_copy(update={"transition_s": 0.5})
    show = small_show.model_copy(update={"formations": [f, small_show.formations[1]]})
    with pytest.raises(PlanError) as e:
        plan_show(show)
    assert e.value.path == "formations[0].transition_s" and e.value.minimum_s > 0.5


def test_schedule_delays_resolve_a_crossing() -> None:
    """Two drones swapping through each other's path: one waits or slows, both stay >= Δ."""
    a = np.array([[0.0, 0, 20], [10.0, 0.5, 20]])
    b = np.array([[10.0, 0, 20], [0.0, 0.5, 20]])
    sched = schedule_transition(a, b, LIM, min_distance_m=3.0)
    prof = sched.drone_profiles()
    t = np.linspace(0, sched.window_s, 20001)
    s = evaluate_profiles(prof, t[:, None] - sched.depart_s[None])
    p = a[None] + s[..., None] * (b - a)[None]
    d = np.linalg.norm(p[:, 0] - p[:, 1], axis=1)
    if sched.unresolved:
        assert d.min() < 3.0
    else:
        assert d.min() >= 3.0 - 1e-6


def lattice_formation(rng: np.random.Generator, n: int, delta: float, kind: int) -> np.ndarray:
    """n points of a random lattice patch at exactly delta: square or hex in a random vertical plane, or cubic."""
    if kind == 2:
        side = int(np.ceil(n ** (1 / 3))) + 1
        g = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3).astype(float)
        pts = g[rng.permutation(len(g))[:n]] * delta
    else:
        side = int(np.ceil(np.sqrt(n))) + 2
        jj, ii = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
        if kind == 0:
            uv = np.c_[ii.ravel(), jj.ravel()] * delta
        else:
            uv = np.c_[(ii + 0.5 * (jj % 2)).ravel(), jj.ravel() * np.sqrt(3) / 2] * delta
        uv = uv[np.argsort(np.hypot(*(uv - uv.mean(0)).T), kind="stable")[:n]]
        yaw = rng.uniform(0, np.pi)
        pts = np.c_[uv[:, 0] * np.cos(yaw), uv[:, 0] * np.sin(yaw), uv[:, 1]]
    shift = np.array([rng.uniform(-10, 10), rng.uniform(-10, 10), 25 + np.ptp(pts[:, 2])])
    return pts - pts.mean(0) + shift


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(4, 24), forms=st.integers(1, 3))
def test_random_dense_shows_are_safe(seed: int, n: int, forms: int) -> None:
    """Hypothesis over random lattice formations drawn at exactly Δ: no unresolved conflict, never closer than Δ."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    # 3 m plus 1 µm per metre: make_show rounds coordinates to 1 µm, which must not push a pair below 3 m.
    fs = [{"name": f"f{k}", "hold_s": 1.0, "points": lattice_formation(rng, n, 3.000003, int(rng.integers(0, 3)))}
          for k in range(forms)]
    show = make_show(fs, drones=n, rows=side, cols=side, spacing_m=3.0, max_altitude_m=500.0)
    plan = plan_show(show)
    assert all(not tr.unresolved for tr in plan.transitions)
    sampled, _, smp = sampled_min_distance(plan)
    assert sampled >= 3.0 * (1 - 1e-9)
    check_limits_and_holds(plan, smp)


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 80), r=st.floats(0.5, 6.0), seed=st.integers(0, 2**31 - 1))
def test_dsatur_colouring_is_proper_against_all_pairs(n: int, r: float, seed: int) -> None:
    from sim.plan._schedule import _greedy_colours

    pts = np.random.default_rng(seed).uniform(-10, 10, (n, 3))
    colour = _greedy_colours(pts, r)
    i, j = np.triu_indices(n, 1)
    close = np.linalg.norm(pts[i] - pts[j], axis=1) <= r
    assert np.all(colour[i[close]] != colour[j[close]])  # brute force over every pair
    degree = np.bincount(np.r_[i[close], j[close]], minlength=n)
    assert colour.max(initial=0) <= degree.max(initial=0)  # at most max degree + 1 colours


def test_dsatur_three_colours_a_hexagonal_lattice_and_two_a_square_one() -> None:
    """The triangular lattice's chromatic number is 3 (plain greedy used 4); a square lattice without its
    diagonals (exactly √2·Δ apart, allowed to share a layer) is bipartite."""
    from sim.plan._schedule import _greedy_colours

    delta = 3.0
    jj, ii = np.meshgrid(np.arange(12), np.arange(12), indexing="ij")
    hexa = np.c_[((ii + 0.5 * (jj % 2)) * delta).ravel(), (jj * delta * np.sqrt(3) / 2).ravel(), np.zeros(ii.size)]
    assert _greedy_colours(hexa, np.sqrt(2) * delta * (1 - 1e-9)).max() + 1 == 3
    sq = np.c_[ii.ravel() * delta, jj.ravel() * delta, np.zeros(ii.size)]
    assert _greedy_colours(sq, np.sqrt(2) * delta * (1 - 1e-9)).max() + 1 == 2


@pytest.mark.parametrize("bottom, floor", [(20.0, 2.5), (3.0, 2.5), (1.0, 2.5)])
def test_spread_of_a_3d_set_is_a_similarity_about_the_centroid_above_the_floor(bottom: float, floor: float) -> None:
    delta, k = 3.0, float(np.sqrt(2))
    g = np.stack(np.meshgrid(*[np.arange(4)] * 3), -1).reshape(-1, 3) * delta
    pts = g + np.array([0, 0, bottom])
    out = spread(pts, k, delta, 1000.0, floor_m=floor)
    assert out is not None
    i, j = np.triu_indices(len(pts), 1)
    np.testing.assert_allclose(np.linalg.norm(out[i] - out[j], axis=1),
                               k * np.linalg.norm(pts[i] - pts[j], axis=1), rtol=1e-12)  # distances x k
    assert out[:, 2].min() >= min(floor, bottom) - 1e-9  # never below the floor (or below where it was)
    centre = pts[:, 2].mean()
    if bottom - (k - 1) * (centre - bottom) >= floor:  # room below: the centroid stays, least vertical motion
        assert out[:, 2].mean() == pytest.approx(centre)
        assert np.abs(out[:, 2] - pts[:, 2]).max() == pytest.approx((k - 1) * (pts[:, 2].max() - centre))
