"""The exact check of per-drone piecewise polynomials against independent computations.

Oracles: dense sampling of every pair (a sampled minimum bounds the exact one from
above, and from below up to the relative speed times half the step), closed forms
(straight constant-speed legs; the shared-β closed form of synchronised CAPT
segments), and the same exact kernel run on *all* pairs (so the candidate pruning
is tested on its own).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.cli import main as cli
from sim import check_plan, plan_show
from sim.plan._plan import trajectories_from_knots
from sim.plan._trajectory import Trajectories, TrajectoryBuilder, rest_to_rest_quintic_coeffs
from sim.verify import _poly, piece_extrema, segment_close_pairs, window_close_pairs
from tests.conftest import fibonacci_sphere, make_show, ring


def random_piecewise(seed: int, n: int, legs: int = 3, spread: float = 12.0) -> Trajectories:
    """n drones, each flying ``legs`` quintic legs with its own random waits (zero-length pieces included),
    some legs replaced by random cubic pieces; all end together."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-spread, spread, (n, 3))
    b = TrajectoryBuilder(pos, 0.0)
    for _ in range(legs):
        wait = rng.choice([0.0, 0.0, 0.7, 1.9], size=n) * rng.uniform(0.5, 1.5, n)
        b.hold_until(b.times_s + wait)  # staggered departures, zero-length where wait = 0
        start = b.positions_m
        goal = start + rng.normal(size=(n, 3)) * spread / 2
        dur = rng.uniform(1.0, 4.0, n)
        if rng.random() < 0.5:
            b.append(dur, rest_to_rest_quintic_coeffs(start, goal, dur))
        else:
            c = np.zeros((n, 3, 4))
            c[..., 0] = start
            c[..., 1:] = rng.normal(size=(n, 3, 3)) * np.array([2.0, 0.5, 0.1])
            b.append(dur, c)
        b.append(np.zeros(n), b.positions_m[..., None])  # an explicit zero-length piece
    b.hold_until(np.full(n, b.times_s.max() + 0.5))
    return b.build()


def dense_pair_minima(motion: Trajectories, t0: float, t1: float, samples: int) -> tuple[np.ndarray, float]:
    """Brute force: (N, N) sampled minimum distance of every pair, and the sampling step."""
    t = np.linspace(t0, t1, samples)
    n = motion.drone_count
    best = np.full((n, n), np.inf)
    for chunk in np.array_split(t, max(1, samples // 2000)):
        p = motion.evaluate(chunk, derivatives=0).positions_m
        d = np.linalg.norm(p[:, :, None, :] - p[:, None, :, :], axis=-1).min(axis=0)
        best = np.minimum(best, d)
    return best, float(t[1] - t[0])


def max_speed(motion: Trajectories) -> float:
    ext = piece_extrema(motion)
    return float(np.hypot(ext.speed_xy_mps, ext.speed_z_mps).max())


def all_pairs_exact(motion: Trajectories, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The exact kernel on every pair, no pruning: (i, j, minimum distance)."""
    i, j = np.triu_indices(motion.drone_count, 1)
    m = len(i)
    d2, tm = np.empty(m), np.empty(m)
    _poly.pair_minima(i.astype(np.int64), j.astype(np.int64), np.full(m, t0), np.full(m, t1), np.full(m, np.inf),
                      motion.breaks_s, motion.coeffs_m, _poly.W, d2, tm)
    return i, j, np.sqrt(d2)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 14), radius=st.floats(1.0, 10.0))
def test_pair_minima_match_dense_sampling_on_staggered_piecewise_plans(seed: int, n: int, radius: float) -> None:
    motion = random_piecewise(seed, n)
    t0, t1 = motion.start_s, motion.end_s
    sampled, dt = dense_pair_minima(motion, t0, t1, 40_001)
    slack = 2 * max_speed(motion) * dt / 2  # two drones, each at most v·dt/2 from the nearest sample
    got = window_close_pairs(motion, t0, t1, radius)
    found = {(int(a), int(b)): (float(d), float(t)) for a, b, d, t in zip(*got, strict=True)}
    for (a, b), (d, t) in found.items():
        assert d <= sampled[a, b] + 1e-9  # the exact minimum is at most any sample
        assert d >= sampled[a, b] - slack - 1e-9
        p = motion.evaluate([t], derivatives=0).positions_m[0]
        assert np.linalg.norm(p[a] - p[b]) == pytest.approx(d, abs=1e-7)  # attained where reported
    # every pair the samples show within the radius (with margin) is found
    i, j = np.triu_indices(n, 1)
    must = {(int(a), int(b)) for a, b in zip(i, j, strict=True) if sampled[a, b] < radius - 1e-6}
    assert must <= set(found)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 40), radius=st.floats(0.5, 8.0),
       spread=st.floats(3.0, 40.0))
def test_candidate_pruning_never_misses_a_pair(seed: int, n: int, radius: float, spread: float) -> None:
    """Pruned search == the exact kernel run on all pairs (same pairs within the radius, same minima)."""
    motion = random_piecewise(seed, n, spread=spread)
    t0, t1 = motion.start_s, motion.end_s
    i, j, d = all_pairs_exact(motion, t0, t1)
    expected = {(int(a), int(b)): float(x) for a, b, x in zip(i, j, d, strict=True) if x <= radius}
    got = window_close_pairs(motion, t0, t1, radius)
    found = {(int(a), int(b)): float(x) for a, b, x in zip(got.i, got.j, got.dist_m, strict=True)}
    strict = {k for k, v in expected.items() if v < radius * (1 - 1e-9)}
    assert strict <= set(found)
    assert set(found) <= set(expected) | {k for k in found if abs(found[k] - radius) < 1e-7}
    for k in strict:
        assert found[k] == pytest.approx(expected[k], abs=1e-9)


def test_crossing_lines_closed_form() -> None:
    """Two drones on straight constant-speed legs, the second departing 1.3 s late: the minimum of
    |a + t·c| for the linear relative motion is known in closed form."""
    p0, v0 = np.array([-20.0, 0.0, 30.0]), np.array([4.0, 0.0, 0.0])
    p1, v1 = np.array([0.0, -15.0, 31.0]), np.array([0.0, 3.0, 0.2])
    delay, dur = 1.3, 10.0
    b = TrajectoryBuilder(np.stack([p0, p1]), 0.0)
    b.hold_until(np.array([0.0, delay]))  # drone 0: a zero-length piece; drone 1 waits
    lin = np.zeros((2, 3, 2))
    lin[:, :, 0] = np.stack([p0, p1])
    lin[:, :, 1] = np.stack([v0, v1])
    b.append(np.full(2, dur), lin)
    b.hold_until(np.full(2, delay + dur + 1.0))
    motion = b.build()
    # Closed form on [delay, dur] where both move: offset(t) = (p1 + v1 (t - delay)) - (p0 + v0 t).
    a = p1 - v1 * delay - p0
    c = v1 - v0
    t_star = float(np.clip(-(a @ c) / (c @ c), delay, dur))
    d_star = float(np.linalg.norm(a + t_star * c))
    got = window_close_pairs(motion, motion.start_s, motion.end_s, 50.0)
    assert list(got.i) == [0] and list(got.j) == [1]
    assert got.dist_m[0] == pytest.approx(d_star, abs=1e-9)
    # (a minimum is flat: the value is exact to ~1e-13 relative, its time only to about the square root)
    assert got.time_s[0] == pytest.approx(t_star, abs=1e-4)


def test_shared_quintic_plans_agree_with_the_closed_form_oracle() -> None:
    """Today's plans (one shared quintic β per segment): per segment, the exact piecewise search
    finds exactly the pairs and minima of CAPT's closed form over β (an independent computation)."""
    show = make_show(
        [
            {"name": "ring", "hold_s": 2.0, "points": ring(20, 9.6)},
            {"name": "ball", "hold_s": 2.0, "points": fibonacci_sphere(20, 6.0, center=(4, 2, 30))},
        ],
        drones=20, rows=4, cols=5, spacing_m=3.0,
    )
    # Re-timed as the first wave planned every show: one shared quintic per window between the
    # same knots, which is what the closed form over β describes.
    planned = plan_show(show)
    plan = dataclasses.replace(
        planned, trajectories=trajectories_from_knots(planned.knot_times_s, planned.knot_positions_m)
    )
    P = plan.knot_positions_m
    for k, seg in enumerate(plan.segments):
        if seg.kind == "hold":
            continue
        oracle = segment_close_pairs(P[k], P[k + 1], 6.0)
        got = window_close_pairs(plan.motion, seg.start_s, seg.end_s, 6.0)
        want = {(int(a), int(b)): float(d) for a, b, d in zip(oracle.i, oracle.j, oracle.dist, strict=True)
                if d < 6.0 - 1e-9}
        have = {(int(a), int(b)): float(d) for a, b, d in zip(got.i, got.j, got.dist_m, strict=True)}
        assert set(want) <= set(have)
        for key, d in want.items():
            assert have[key] == pytest.approx(d, abs=1e-8)
    report = check_plan(plan)
    for tr in report.transitions:
        k = tr.segment
        oracle = segment_close_pairs(P[k], P[k + 1], 20.0)
        assert tr.capt.exact_min_distance_m == pytest.approx(float(oracle.dist.min()), abs=1e-8)


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 8))
def test_peaks_match_dense_sampling(seed: int, n: int) -> None:
    motion = random_piecewise(seed, n)
    ext = piece_extrema(motion)
    t = np.linspace(motion.start_s, motion.end_s, 100_001)
    dt = t[1] - t[0]
    smp = motion.evaluate(t)
    v, a, z = smp.velocities_mps, smp.accelerations_mps2, smp.positions_m[..., 2]
    # sampled values never beat the exact extrema; the extrema are within a step's change of the samples
    # A bound on |jerk| from the coefficients (Σ_k k(k-1)(k-2)|c_k|·L^(k-3) per axis), for the tolerance only.
    c, length = motion.coeffs_m, np.diff(motion.breaks_s, axis=1)[..., None, None]
    k = np.arange(c.shape[-1])
    jerk = float(np.sqrt(3) * (np.abs(c[..., 3:]) * (k * (k - 1) * (k - 2))[3:] * length ** (k[3:] - 3)).sum(-1).max())
    acc_max = float(np.linalg.norm(a, axis=-1).max()) + jerk * dt
    speed_max = float(np.linalg.norm(v, axis=-1).max()) + acc_max * dt
    checks = [
        (ext.speed_xy_mps.max(), np.hypot(v[..., 0], v[..., 1]).max(), acc_max * dt),
        (ext.speed_z_mps.max(), np.abs(v[..., 2]).max(), acc_max * dt),
        (ext.accel_mps2.max(), np.linalg.norm(a, axis=-1).max(), jerk * dt),
        (ext.z_max_m.max(), z.max(), speed_max * dt),
        (-ext.z_min_m.min(), -z.min(), speed_max * dt),
    ]
    for exact, sampled, slack in checks:
        assert exact >= sampled - 1e-9
        assert exact <= sampled + slack + 1e-9
    # each extremum is attained at its reported time (the worst speed_xy piece, say)
    i, p = np.unravel_index(int(np.argmax(ext.speed_xy_mps)), ext.speed_xy_mps.shape)
    # (on the piece itself: these random pieces may end with a velocity jump at the break)
    c = motion.coeffs_m[i, p]
    u = ext.speed_xy_t[i, p] - motion.breaks_s[i, p]
    s = np.polynomial.polynomial.polyval(u, (c[:, 1:] * np.arange(1, c.shape[1])).T)
    assert np.hypot(s[0], s[1]) == pytest.approx(ext.speed_xy_mps[i, p], rel=1e-9, abs=1e-9)


def test_bernstein_minimum_of_known_polynomials() -> None:
    """(u - 0.3)²·(u - 1.7)² + 2 on [0, 2]: minimum 2 at u = 0.3 and 1.7; u⁴ - u on [0, 1]: at (1/4)^(1/3)."""
    def minimise(a: np.ndarray, length: float) -> tuple[float, float]:
        full = np.zeros(_poly.NB + 1)
        full[: len(a)] = a
        bern = np.empty(_poly.NB + 1)
        _poly.to_bernstein(full, length, _poly.W, bern)
        v, x = _poly.bernstein_min(bern, np.inf, np.empty((64, _poly.NB + 1)), np.empty(64), np.empty(64))
        return v, x * length

    q = np.polynomial.polynomial.polyfromroots([0.3, 0.3, 1.7, 1.7])
    q[0] += 2.0
    v, u = minimise(q, 2.0)
    assert v == pytest.approx(2.0, abs=1e-12) and min(abs(u - 0.3), abs(u - 1.7)) < 1e-5
    v, u = minimise(np.array([0.0, -1.0, 0.0, 0.0, 1.0]), 1.0)
    u_star = 0.25 ** (1 / 3)
    assert u == pytest.approx(u_star, abs=1e-6) and v == pytest.approx(u_star**4 - u_star, abs=1e-12)


# ---- the report, grouped per transition ---------------------------------------------------------


@pytest.fixture
def tight_plan():
    """Formations drawn at exactly 3 m: synchronised CAPT lines bring some drones closer than 3 m."""
    show = make_show([{"name": "ring", "hold_s": 1.0, "points": ring(30, 3.0001 / (2 * np.sin(np.pi / 30)))},
                      {"name": "ball", "hold_s": 1.0, "points": fibonacci_sphere(30, 8.0, center=(0, 0, 40))}],
                     drones=30, rows=5, cols=6, spacing_m=3.0, time_law="quintic")
    # Flown as the first wave planned it (one shared quintic per window, no per-drone timing),
    # which the planner now avoids: the check must still catch and group what that leaves.
    planned = plan_show(show)
    return show, dataclasses.replace(
        planned, trajectories=trajectories_from_knots(planned.knot_times_s, planned.knot_positions_m)
    )


def test_report_groups_violations_per_transition_worst_first(tight_plan) -> None:
    _, plan = tight_plan
    report = check_plan(plan)
    assert not report.ok
    groups = report.by_transition
    kinds = [g.kind for g in groups]
    assert kinds[0] == "takeoff" and kinds[-1] == "landing" and kinds.count("transition") == 3
    assert sum(g.violations_total for g in groups) == report.violations_total
    for g in groups:
        assert g.ok == (g.violations_total == 0)
        d = [v.value for v in g.violations if v.kind == "min_distance"]
        assert d == sorted(d)
        assert all(v.segment == g.segment for v in g.violations)
        if d:
            assert g.min_distance_m == pytest.approx(d[0])
            assert g.fixes, "a failing transition says what would fix it"
    worst = report.worst_transitions()
    assert not worst[0].ok and worst[0].min_distance_m == pytest.approx(report.min_distance_m)
    # the transitions into formations name the formation they lead into
    assert [g.formation for g in groups if g.kind == "transition"] == [0, 1, -1]
    # per transition minimum = the CAPT premise's exact minimum
    by_seg = {g.segment: g for g in groups}
    for tr in report.transitions:
        assert by_seg[tr.segment].min_distance_m == pytest.approx(tr.capt.exact_min_distance_m)


def test_report_carries_the_planners_stagger_and_fixes(tight_plan) -> None:
    """The planner's stagger, resolution and unresolved records show per transition (the fix text is
    the planner's, not invented), and a plain plan reports exactly what its planner recorded."""
    from sim.plan._plan import UnresolvedConflict

    _, plan = tight_plan
    fix = UnresolvedConflict(drones=(3, 4), time_s=12.5, reason="no delay keeps them apart",
                             fix="move point 4 of 'ring'")
    trs = tuple(dataclasses.replace(t, stagger_s=2.5 + k, resolution="delays", unresolved=(fix,) if k == 0 else ())
                for k, t in enumerate(plan.transitions))
    report = check_plan(dataclasses.replace(plan, transitions=trs, trajectories=plan.motion))
    first = next(g for g in report.by_transition if g.kind == "transition")
    assert first.stagger_s == 2.5 and first.resolution == "delays"
    assert first.unresolved[0].fix == "move point 4 of 'ring'" and first.unresolved[0].drones == [3, 4]
    assert first.fixes[0] == "move point 4 of 'ring'"
    assert report.transitions[1].stagger_s == 3.5
    plain = check_plan(plan)
    recorded = {t.segment: (t.stagger_s, t.resolution) for t in plan.transitions}
    for g in plain.by_transition:
        if g.segment in recorded:
            assert g.stagger_s == pytest.approx(recorded[g.segment][0])
            assert g.resolution == recorded[g.segment][1]


def test_no_fix_offered_that_cannot_work(tight_plan) -> None:
    """A distance violation of synchronised straight lines is never 'fixed' by a longer transition (the
    geometry does not depend on the duration): such a fix is not offered; a forced too-short one is."""
    show, plan = tight_plan
    report = check_plan(plan)
    for g in report.by_transition:
        if any(v.kind == "min_distance" for v in g.violations):
            assert not any("duration" in f for f in g.fixes)
    doc = show.model_dump(mode="json", exclude_none=True)
    doc["formations"][1]["transition_s"] = 1.0
    from formations import parse_show

    forced = check_plan(plan_show(parse_show(doc), enforce_limits=False))
    g = next(g for g in forced.by_transition if g.formation == 1 and g.kind == "transition")
    assert any(v.kind == "transition_duration" for v in g.violations)
    assert any("formations[1].transition_s" in f for f in g.fixes)


def test_cli_prints_the_grouped_view_worst_first(tmp_path, tight_plan, capsys) -> None:
    from formations import dump_show

    show, _ = tight_plan
    # A forced transition far too short for the limits: unsafe whatever the planner does.
    show = show.model_copy(update={"formations": [show.formations[0],
                                                  show.formations[1].model_copy(update={"transition_s": 2.0})]})
    f = tmp_path / "show.json"
    f.write_text(dump_show(show))
    assert cli(["check", str(f)]) == 1
    out = capsys.readouterr().out
    assert "per transition" in out.lower()
    lines = [ln for ln in out.splitlines() if ln.startswith("  ✗") or ln.startswith("  ✓")]
    assert lines and lines[0].startswith("  ✗")
    assert cli(["check", str(f), "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert {"from", "to", "violations", "violations_total", "min_distance_m", "stagger_s", "resolution",
            "unresolved", "fixes"} <= set(doc["by_transition"][0])
    assert doc["violations_total"] == sum(g["violations_total"] for g in doc["by_transition"])


@pytest.mark.timeout(120)
def test_window_past_the_last_break_terminates_and_sees_the_rest() -> None:
    """A window ending an ulp after the drones' last break (summed durations round below the
    show's knot time) must end: past its last break a drone rests where it is."""
    from sim.plan import TrajectoryBuilder
    from sim.verify._check import window_close_pairs

    b = TrajectoryBuilder(np.array([[0.0, 0.0, 10.0], [4.0, 0.0, 10.0]]))
    for _ in range(3):  # 0.1 + 0.1 + 0.1 = 0.30000000000000004: the sum itself, not 0.3, is the end
        b.append(np.full(2, 0.1), np.concatenate([b.positions_m[..., None], np.zeros((2, 3, 1))], axis=-1))
    motion = b.build()
    end = float(np.nextafter(motion.end_s, np.inf))
    got = window_close_pairs(motion, 0.0, end + 1e-9, 5.0)
    assert got.dist_m.tolist() == pytest.approx([4.0])
