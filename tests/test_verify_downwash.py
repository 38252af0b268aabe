"""Downwash during takeoff and landing: the exact ellipsoid check against closed forms and dense sampling."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formations import parse_show
from sim import check_plan, plan_show
from sim.plan._trajectory import TrajectoryBuilder, rest_to_rest_quintic_coeffs
from sim.verify import downwash_violations, window_close_pairs
from sim.verify._downwash import scaled_motion
from tests.conftest import make_show, ring
from tests.test_verify_exact import random_piecewise


def ellipsoid_sampled(motion, r: float, c: float, t0: float, t1: float, samples: int) -> np.ndarray:
    """Brute force: (N, N) sampled minimum of sqrt((dx² + dy²)/r² + dz²/c²) over [t0, t1]."""
    t = np.linspace(t0, t1, samples)
    p = motion.evaluate(t, derivatives=0).positions_m
    d = p[:, :, None, :] - p[:, None, :, :]
    e = np.sqrt((d[..., 0] ** 2 + d[..., 1] ** 2) / r**2 + d[..., 2] ** 2 / c**2)
    return np.asarray(e.min(axis=0))


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(2, 10), r=st.floats(0.5, 6.0), ratio=st.floats(1.0, 4.0))
def test_scaled_search_matches_dense_sampling_of_the_ellipsoid(seed: int, n: int, r: float, ratio: float) -> None:
    motion = random_piecewise(seed, n, spread=6.0)
    c = r * ratio
    sampled = ellipsoid_sampled(motion, r, c, motion.start_s, motion.end_s, 20_001)
    got = window_close_pairs(scaled_motion(motion, r, c), motion.start_s, motion.end_s, 1.0)
    found = {(int(a), int(b)): float(d) for a, b, d in zip(got.i, got.j, got.dist_m, strict=True)}
    for (a, b), d in found.items():
        assert d <= sampled[a, b] + 1e-9  # exact minimum <= every sample
    i, j = np.triu_indices(n, 1)
    must = {(int(a), int(b)) for a, b in zip(i, j, strict=True) if sampled[a, b] < 1.0 - 1e-6}
    assert must <= set(found)


def _two_drone_show(**extra: float):
    return parse_show({
        "format": "swarmshow/1", "name": "dw", "drones": 2,
        "home": {"grid": {"rows": 1, "cols": 2, "spacing_m": 3.0}},
        "settings": {"min_distance_m": 3.0, **extra},
        "formations": [{"name": "pair", "hold_s": 1.0, "points": [[-3.0, 0.0, 20.0], [3.0, 0.0, 20.0]]}],
    })


def test_planned_takeoff_and_landing_keep_every_drone_out_of_the_downwash() -> None:
    """Default ellipsoid (r = min_distance_m): everyone climbs and sinks at one altitude, so nobody is ever
    above anyone; the check finds no downwash violation on a real plan."""
    show = make_show([{"name": "ring", "hold_s": 2.0, "points": ring(12, 12.0)}], drones=12, rows=3, cols=4)
    plan = plan_show(show)
    found, total = downwash_violations(plan)
    assert total == 0 and not found
    assert check_plan(plan).ok


def test_staggered_climb_under_a_drone_is_reported_with_the_closed_form_depth() -> None:
    """Drone 0 climbs 10 m first, then drone 1 (3 m to the side) climbs under it. With r = 5, c = 10 the
    scaled distance is sqrt(3²/5² + dz²/10²), smallest (0.6) whenever they are level (on the ground, or when
    drone 1 arrives level with drone 0)."""
    plan = plan_show(_two_drone_show(downwash_radius_m=5.0, downwash_height_m=10.0))
    seg = next(s for s in plan.segments if s.kind == "takeoff")
    home = plan.knot_positions_m[0]
    up = home + np.array([0.0, 0.0, 10.0])
    b = TrajectoryBuilder(home, 0.0)
    dur = np.array([4.0, 0.0])
    b.append(dur, rest_to_rest_quintic_coeffs(home, np.where((dur > 0)[:, None], up, home), dur))
    b.hold_until(np.array([4.0, 4.0]))
    dur = np.array([0.0, 4.0])
    now = b.positions_m
    b.append(dur, rest_to_rest_quintic_coeffs(now, up, dur))
    # the rest of the plan as planned, from the end of this takeoff
    rest = plan.motion
    b.hold_until(np.full(2, plan.duration_s))
    fake = dataclasses.replace(
        plan, segments=(dataclasses.replace(seg, duration_s=8.0),) + plan.segments[1:],
        trajectories=b.build(end_s=plan.duration_s),
    )
    assert rest.drone_count == 2
    found, _ = downwash_violations(fake)
    # (the fake plan then hovers side by side through the landing segment too, reported there)
    (v,) = [f for f in found if f.segment == seg.index]
    assert v.kind == "downwash" and v.drones == [0, 1]  # drone 1 is below drone 0
    assert v.value == pytest.approx(0.6, abs=1e-9)
    assert min(abs(v.time_s - 0.0), abs(v.time_s - 8.0)) < 1e-3  # level on the ground, or level at 10 m
    sampled = ellipsoid_sampled(fake.motion, 5.0, 10.0, 0.0, 8.0, 8001)
    assert v.value <= sampled[0, 1] + 1e-12 and sampled[0, 1] == pytest.approx(0.6, abs=1e-6)


def test_a_downwash_wider_than_the_home_grid_fails_the_check_with_a_fix() -> None:
    """r = 4 m over a 3 m home grid: at one altitude the neighbours are 3/4 of the radius apart."""
    report = check_plan(plan_show(_two_drone_show(downwash_radius_m=4.0)))
    dw = [v for v in report.violations if v.kind == "downwash"]
    assert not report.ok and len(dw) == 2  # once in takeoff, once in landing
    assert all(v.value == pytest.approx(0.75, abs=1e-9) for v in dw)
    groups = [g for g in report.by_transition if any(v.kind == "downwash" for v in g.violations)]
    assert {g.kind for g in groups} == {"takeoff", "landing"}
    assert all(any("downwash" in f for f in g.fixes) for g in groups)


def test_downwash_settings_defaults_and_hash_stability() -> None:
    show = _two_drone_show()
    assert show.settings.downwash_axes_m == (3.0, 7.5)  # r = min_distance_m, c = 2.5 r (Preiss et al. 2017)
    assert "downwash" not in show.canonical_json()  # left out: older shows keep their content hash
    assert _two_drone_show(downwash_radius_m=2.0).settings.downwash_axes_m == (2.0, 5.0)


@settings(max_examples=4, deadline=None)
@given(seed=st.integers(0, 1000), n=st.sampled_from([16, 30, 48]))
def test_planned_takeoff_and_landing_never_put_a_drone_above_another(seed: int, n: int) -> None:
    """A very tall ellipsoid (c = 500 m, r = the home spacing) flags any drone anywhere above another within
    r horizontally: the planner's takeoff and landing (one shared profile, everyone level, spread grids
    included) never do that, on dense shows drawn at exactly the minimum distance."""
    from sim.bench._dense import dense_show

    show = dense_show(n, formations=2, seed=seed, downwash_height_m=500.0)
    plan = plan_show(show)
    found, total = downwash_violations(plan)
    assert total == 0, found[:3]
