"""Drone groups and subset formations (issue 21 item 3): validation, drone choice, planning, exact check.

Independent computations: brute force over every drone subset and permutation for the count choice,
dense sampling of every pair for separation, positions read straight off the plan for holding drones.
"""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from formations import ShowValidationError, parse_show
from sim import PlanError, check_plan, plan_show
from sim.plan._subset import choose_drones, park_slots
from tests.conftest import ring

MIN_D = 3.0


def _doc(formations: list[dict], *, drones: int = 9, groups: dict | None = None, lights: dict | None = None,
         rows: int = 3, cols: int = 3) -> dict:
    doc: dict = {
        "format": "swarmshow/1", "name": "subset", "drones": drones,
        "home": {"grid": {"rows": rows, "cols": cols, "spacing_m": 4.0}},
        "settings": {"min_distance_m": MIN_D},
        "formations": formations,
    }
    if groups is not None:
        doc["groups"] = groups
    if lights is not None:
        doc["lights"] = lights
    return doc


def _pts(a: np.ndarray) -> list[list[float]]:
    return np.round(np.asarray(a, dtype=float), 6).tolist()


def _line(n: int, z: float = 30.0, y: float = 0.0, gap: float = 5.0) -> np.ndarray:
    return np.column_stack([(np.arange(n) - (n - 1) / 2) * gap, np.full(n, y), np.full(n, z)])


def _subset_show(others: str | None = "hold", *, use: dict | None = None, drones: int = 9) -> dict:
    """All drones on a ring, then a subset on a line in front, then all on the ring again."""
    sub: dict = {"name": "line", "hold_s": 3.0, "points": _pts(_line(4, y=-20.0)), "color": "#00ff00",
                 "drones": use or {"group": "front"}}
    if others is not None:
        sub["others"] = others
    return _doc([
        {"name": "ring", "hold_s": 2.0, "points": _pts(ring(drones, 12.0, (0, 0, 30))), "color": "#ff0000"},
        sub,
        {"name": "ring2", "hold_s": 2.0, "points": _pts(ring(drones, 14.0, (0, 0, 32))), "color": "#0000ff"},
    ], drones=drones, groups={"front": [0, 2, 4, 6], "back": [1, 3]})


def _dense_min_distance(plan, step_s: float = 0.02) -> float:
    """Brute force: the closest any two drones come over times sampled every ``step_s`` (all pairs)."""
    t = np.arange(0.0, plan.duration_s, step_s)
    best = np.inf
    for chunk in np.array_split(t, max(1, len(t) // 500)):
        p = plan.evaluate(chunk).positions_m
        d = np.linalg.norm(p[:, :, None, :] - p[:, None, :, :], axis=-1)
        n = d.shape[1]
        d[:, np.arange(n), np.arange(n)] = np.inf
        # Drones standing on the ground before takeoff / after touchdown sit on the home grid (>= 4 m).
        best = min(best, float(d.min()))
    return best


# ------------------------------------------------------------------ validation


@pytest.mark.parametrize("mutate, path, words", [
    (lambda d: d["formations"][1].__setitem__("drones", {"group": "nope"}), "formations[1].drones.group",
     "no drone group named 'nope'"),
    (lambda d: d["formations"][1].__setitem__("drones", {"count": 10}), "formations[1].drones.count",
     "more than drones = 9"),
    (lambda d: d["formations"][1].__setitem__("drones", {"count": 5}), "formations[1].drones.count",
     "more than the formation's 4 points"),
    (lambda d: d["groups"].__setitem__("front", [0, 9]), "groups.front", "out of range for 9 drones"),
    (lambda d: d["groups"].__setitem__("front", [0, 2, 2]), "groups.front", "listed twice"),
    (lambda d: d["groups"].__setitem__("front", [0, 1, 2, 3, 4]), "formations[1].points",
     "4 points for 5 drones"),
    (lambda d: d["formations"][1].__setitem__("drones", {"count": 0}), "formations[1].drones.count",
     "greater than or equal to 1"),
    (lambda d: d["formations"][1].__setitem__("drones", {"every": 1}), "formations[1].drones", "group"),
    (lambda d: d["formations"][1].__setitem__("others", "fly"), "formations[1].others", "hold"),
    (lambda d: d["formations"][0].__setitem__("others", "park"), "formations[0].others", "some of the drones"),
])
def test_bad_subsets_name_the_path(mutate, path, words):
    doc = _subset_show()
    mutate(doc)
    with pytest.raises(ShowValidationError) as info:
        parse_show(doc)
    first = info.value.errors[0]
    assert first["path"] == path, info.value.errors
    assert words in first["msg"]


def test_old_shows_keep_their_hash_and_lights_groups_load():
    """A show without the new fields dumps as before (no 'groups', no 'others'); lights.groups still loads."""
    doc = _doc([{"name": "ring", "hold_s": 2.0, "points": _pts(ring(9, 12.0)), "color": "#ff0000"}],
               lights={"groups": {"g": [0, 0, 1]}, "effects": [
                   {"target": {"kind": "group", "group": "g"}, "effect": {"kind": "solid", "color": "#00ff00"},
                    "start_s": 0.0, "end_s": 100.0}]})
    show = parse_show(doc)
    canon = json.loads(show.canonical_json())
    assert "groups" not in canon and "others" not in canon["formations"][0] and "drones" not in canon["formations"][0]
    assert show.drone_groups == {"g": [0, 0, 1]}


def test_a_group_defined_twice_differently_is_refused():
    doc = _subset_show()
    doc["lights"] = {"groups": {"front": [1]}, "effects": []}
    with pytest.raises(ShowValidationError) as info:
        parse_show(doc)
    assert info.value.errors[0]["path"] == "groups.front"


# ------------------------------------------------------------------ choosing the drones


@settings(max_examples=30, deadline=None)
@given(n=st.integers(2, 6), extra=st.integers(0, 2), seed=st.integers(0, 2**31 - 1), data=st.data())
def test_count_choice_is_the_brute_force_optimum(n, extra, seed, data):
    """Over every set of `count` drones and every injective map onto the points: no cheaper choice exists."""
    count = data.draw(st.integers(1, n))
    rng = np.random.default_rng(seed)
    starts = rng.uniform(-20, 20, (n, 3))
    points = rng.uniform(-20, 20, (count + extra, 3))
    drones, pidx = choose_drones(starts, points, count)
    assert len(drones) == count and len(set(pidx.tolist())) == count
    got = float(((starts[drones] - points[pidx]) ** 2).sum())
    best = min(
        float(((starts[list(ds)] - points[list(ps)]) ** 2).sum())
        for ds in itertools.combinations(range(n), count)
        for ps in itertools.permutations(range(len(points)), count)
    )
    assert got == pytest.approx(best, rel=1e-9, abs=1e-9)


def test_park_slots_lie_behind_and_apart():
    pts = _line(6, z=20.0, y=5.0)
    slots = park_slots(pts, 30, min_distance_m=MIN_D, floor_m=2.5, ceiling_m=40.0)
    assert slots.shape == (30, 3)
    assert np.all(slots[:, 1] >= pts[:, 1].max() + 2 * MIN_D - 1e-9)
    d = np.linalg.norm(slots[:, None] - slots[None], axis=-1) + np.eye(30) * 1e9
    assert d.min() >= MIN_D
    assert slots[:, 2].min() > 2.5 and slots[:, 2].max() < 40.0


# ------------------------------------------------------------------ planning and the exact check


@pytest.mark.parametrize("others", ["hold", "park", "land"])
def test_subset_formation_passes_the_exact_check(others):
    show = parse_show(_subset_show(others))
    plan = plan_show(show)
    report = check_plan(plan)
    assert report.ok, report.violations[:3]
    assert all(t.safe for t in plan.transitions)
    # Brute force agrees: every pair of drones, sampled densely over the whole show.
    assert _dense_min_distance(plan) >= MIN_D * (1 - 1e-6)

    hold = [s for s in plan.segments if s.kind == "hold"][1]
    into = plan.transitions[1]
    flying = np.array([0, 2, 4, 6])
    resting = np.setdiff1d(np.arange(9), flying)
    # The group flies: every point of the formation is occupied by one of its drones for the whole hold.
    t = np.linspace(hold.start_s, hold.end_s, 7)
    smp = plan.evaluate(t)
    pts = np.asarray(show.formations[1].points)
    on = np.linalg.norm(smp.positions_m[:, flying, None, :] - pts[None, None], axis=-1).argmin(-1)
    assert np.all(np.sort(on, axis=1) == np.arange(4))
    np.testing.assert_allclose(smp.positions_m[:, flying], pts[on], atol=1e-9)
    np.testing.assert_array_equal(into.goal_index[resting], -1)
    np.testing.assert_allclose(smp.colors_rgb[:, flying], np.tile([0.0, 1.0, 0.0], (7, 4, 1)))
    # The others are dark through the hold ...
    assert np.all(smp.colors_rgb[:, resting] == 0.0)
    before = plan.evaluate([into.start_s]).positions_m[0]
    if others == "hold":
        # ... and do not move at all from the end of the ring's hold to the end of the line's.
        tt = np.linspace(into.start_s, hold.end_s, 200)
        p = plan.evaluate(tt).positions_m[:, resting]
        np.testing.assert_allclose(p, np.broadcast_to(before[resting], p.shape), atol=1e-12)
    elif others == "park":
        # ... park in a layer behind the formation (away from the audience, +y).
        p = smp.positions_m[:, resting]
        assert np.all(p[:, :, 1] >= pts[:, 1].max() + 2 * MIN_D - 1e-9)
        assert np.ptp(p[:, :, 1]) < 1e-9  # one plane
    else:
        # ... stand on their own homes through the hold, and fly the next formation again.
        np.testing.assert_allclose(smp.positions_m[:, resting],
                                   np.broadcast_to(show.home_positions_m[resting], (7, len(resting), 3)), atol=1e-9)
        assert len(plan.grounded) == 1 and sorted(plan.grounded[0][2].tolist()) == resting.tolist()
        g0, g1, _ = plan.grounded[0]
        assert into.start_s < g0 < hold.start_s and g1 > hold.end_s
        last = [s for s in plan.segments if s.kind == "hold"][2]
        p = plan.evaluate([last.start_s]).positions_m[0]
        ring2 = np.asarray(show.formations[2].points)
        assert np.linalg.norm(p[:, None] - ring2[None], axis=-1).min(axis=1).max() < 1e-9


def test_count_subset_flies_the_nearest_drones_and_is_safe():
    show = parse_show(_subset_show(use={"count": 3}))
    plan = plan_show(show)
    assert check_plan(plan).ok
    into = plan.transitions[1]
    flying = np.flatnonzero(into.goal_index >= 0)
    assert len(flying) == 3
    start = plan.evaluate([into.start_s]).positions_m[0]
    pts = np.asarray(show.formations[1].points)
    got = float(((start[flying] - pts[into.goal_index[flying]]) ** 2).sum())
    best = min(float(((start[list(ds)] - pts[list(ps)]) ** 2).sum())
               for ds in itertools.combinations(range(9), 3) for ps in itertools.permutations(range(4), 3))
    assert got == pytest.approx(best)


def test_first_formation_may_be_a_subset():
    doc = _subset_show()
    doc["formations"] = doc["formations"][1:]
    show = parse_show(doc)
    plan = plan_show(show)
    assert check_plan(plan).ok
    assert _dense_min_distance(plan) >= MIN_D * (1 - 1e-6)
    # Drones 1 and 3 hold in the middle of the launch grid, in the group's way: the planner spreads the sets
    # apart and back (the fallback), and the holding drones are back above their homes for the hold.
    hold = [s for s in plan.segments if s.kind == "hold"][0]
    resting = np.setdiff1d(np.arange(9), [0, 2, 4, 6])
    p = plan.evaluate([hold.start_s, hold.end_s]).positions_m[:, resting]
    want = show.home_positions_m[resting] + [0, 0, show.settings.takeoff_altitude_m]
    np.testing.assert_allclose(p, np.broadcast_to(want, p.shape), atol=1e-9)


def test_stationary_drones_in_the_way_are_never_silently_accepted():
    """Holding drones parked across the flyers' straight lines: the plan is safe or says it is not."""
    doc = _doc([
        {"name": "wall", "hold_s": 1.0, "points": _pts(_line(9, z=30.0, gap=3.0)), "color": "#ff0000"},
        {"name": "far", "hold_s": 1.0, "points": _pts(_line(3, z=30.0, y=30.0, gap=3.0) + [0, 0, 0]),
         "drones": {"group": "ends"}},
    ], groups={"ends": [0, 4, 8]})
    plan = plan_show(parse_show(doc))
    report = check_plan(plan)
    unsafe = any(not t.safe for t in plan.transitions)
    assert report.ok or unsafe
    if report.ok:
        assert _dense_min_distance(plan) >= MIN_D * (1 - 1e-6)


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), others=st.sampled_from(["hold", "park", "land"]), size=st.integers(1, 6),
       by_count=st.booleans(), swap=st.booleans())
def test_random_small_subset_shows_check_like_dense_sampling(seed, others, size, by_count, swap):
    """Random group (or count) and line formation between two full ones: the exact check and brute-force
    sampling agree on safety, and the flying drones are the group's (or `size` of them)."""
    rng = np.random.default_rng(seed)
    group = sorted(rng.choice(9, size, replace=False).tolist())
    pts = _line(size, z=float(rng.uniform(20, 40)), y=float(rng.uniform(-30, 30)), gap=float(rng.uniform(3.5, 8)))
    use = {"count": size} if by_count else {"group": "g"}
    doc = _doc([
        {"name": "ring", "hold_s": 1.0, "points": _pts(ring(9, 12.0, (0, 0, 30))), "color": "#ff0000"},
        {"name": "sub", "hold_s": 1.0, "points": _pts(pts), "drones": use, "others": others},
        {"name": "ring2", "hold_s": 1.0, "points": _pts(ring(9, 13.0, (0, 5, 35))), "color": "#0000ff"},
    ], groups={"g": group})
    rest = sorted(set(range(9)) - set(group))
    if swap and rest:
        # Then the complement flies a line of its own while the first group lands (a swap through the ground).
        doc["groups"]["h"] = rest
        doc["formations"].insert(2, {"name": "sub2", "hold_s": 1.0, "drones": {"group": "h"}, "others": "land",
                                     "points": _pts(_line(len(rest), z=32.0, y=float(rng.uniform(-30, 30))))})
    plan = plan_show(parse_show(doc))
    flying = np.flatnonzero(plan.transitions[1].goal_index >= 0)
    if by_count or size == 9:
        assert len(flying) == size
    else:
        assert flying.tolist() == group
    report = check_plan(plan)
    dense = _dense_min_distance(plan, step_s=0.05)
    if all(t.safe for t in plan.transitions):
        assert report.ok, report.violations[:3]
        assert dense >= MIN_D * (1 - 1e-6)
    if dense < MIN_D * (1 - 1e-3):
        assert not report.ok  # the exact check never misses what sampling sees


# ------------------------------------------------------------------ lights and exports


def _fx_solid(target: dict, color: str = "#ffffff") -> dict:
    return {"target": target, "effect": {"kind": "solid", "color": color}, "start_s": 0.0, "end_s": 500.0}


def test_light_targets_resolve_show_groups_and_older_lights_groups():
    """A group target paints exactly the group's drones, whether the group is the show's or (older) the lights'."""
    from sim.light import show_colors

    doc = _subset_show()
    doc["formations"] = [doc["formations"][0]]
    doc["lights"] = {"groups": {"old": [5, 8]}, "effects": [
        _fx_solid({"kind": "group", "group": "back"}, "#ff00ff"), _fx_solid({"kind": "group", "group": "old"},
                                                                             "#00ffff")]}
    show = parse_show(doc)
    plan = plan_show(show)
    hold = [s for s in plan.segments if s.kind == "hold"][0]
    c = show_colors(show, plan, [hold.start_s + 1.0])[0]
    np.testing.assert_allclose(c[[1, 3]], [[1, 0, 1]] * 2, atol=1e-6)
    np.testing.assert_allclose(c[[5, 8]], [[0, 1, 1]] * 2, atol=1e-6)
    np.testing.assert_allclose(c[[0, 2, 4, 6, 7]], [[1, 0, 0]] * 5, atol=1e-6)  # the ring's own red
    # An unknown group names the field.
    doc["lights"]["effects"][0]["target"]["group"] = "missing"
    with pytest.raises(ShowValidationError) as info:
        parse_show(doc)
    assert info.value.errors[0]["path"] == "lights.effects[0].target.group"


def test_effects_leave_drones_out_of_a_subset_formation_dark():
    from sim.light import show_colors

    doc = _subset_show()
    doc["lights"] = {"effects": [_fx_solid({"kind": "all"}, "#ffffff")]}
    show = parse_show(doc)
    plan = plan_show(show)
    hold = [s for s in plan.segments if s.kind == "hold"][1]
    t = np.linspace(hold.start_s, hold.end_s - 1e-6, 5)
    c = show_colors(show, plan, t)
    assert np.all(c[:, [1, 3, 5, 7, 8]] == 0.0)
    assert np.all(c[:, [0, 2, 4, 6]] == 1.0)
    # Before and after the subset formation the effect lights every drone.
    ring_hold = [s for s in plan.segments if s.kind == "hold"][0]
    assert np.all(show_colors(show, plan, [ring_hold.start_s + 0.5]) == 1.0)


def test_subset_show_exports_read_back_with_the_studio_importer():
    """Skybrush CSV of a subset show through Studio's importer: positions follow the plan, idle drones dark."""
    from app.exports import export_show
    from tests.skybrush_readers import studio_csv_import

    show = parse_show(_subset_show("park"))
    plan = plan_show(show)
    imported = studio_csv_import(export_show(show, "skybrush-csv", plan=plan).content, fps=25)
    assert len(imported) == 9
    hold = [s for s in plan.segments if s.kind == "hold"][1]
    for i, (_name, (times, pos, pixels)) in enumerate(imported.items()):
        ref = plan.evaluate(times, drones=np.array([i])).positions_m[:, 0]
        assert np.linalg.norm(pos - ref, axis=1).max() <= 0.005
        frames = np.arange(len(pixels)) / 25
        mid = (frames > hold.start_s + 0.1) & (frames < hold.end_s - 0.1)
        if i in (0, 2, 4, 6):
            np.testing.assert_allclose(pixels[mid], np.tile([0, 255, 0], (mid.sum(), 1)), atol=1)
        else:
            assert np.all(pixels[mid] == 0)


def test_api_names_the_path_of_a_bad_subset(tmp_path):
    from fastapi.testclient import TestClient

    from app.server import create_app
    from app.settings import AppSettings

    doc = _subset_show()
    doc["formations"][1]["drones"] = {"group": "nope"}
    with TestClient(create_app(AppSettings(data_dir=tmp_path, workers=1)), base_url="http://127.0.0.1") as c:
        r = c.post("/api/shows", json=doc)
        assert r.status_code == 422
        assert r.json()["detail"][0]["path"] == "formations[1].drones.group"
        assert c.post("/api/shows", json=_subset_show("park")).status_code in (200, 201)


@pytest.mark.parametrize("keep", [slice(0, 2), slice(1, 2)])
def test_others_land_when_the_subset_formation_is_first_or_last(keep):
    """Landing others before the show's landing (they take off again for it) or right after takeoff."""
    doc = _subset_show("land")
    doc["formations"] = doc["formations"][keep]
    show = parse_show(doc)
    plan = plan_show(show)
    report = check_plan(plan)
    assert report.ok, report.violations[:3]
    assert all(t.safe for t in plan.transitions)
    assert _dense_min_distance(plan) >= MIN_D * (1 - 1e-6)
    assert len(plan.grounded) == 1
    # Everyone is home at the end.
    np.testing.assert_allclose(np.sort(plan.knot_positions_m[-1][:, 2]), 0.0, atol=1e-9)


def test_downwash_is_checked_while_others_are_landed_mid_show():
    """A flyer hovering 4 m up, 4.2 m beside the homes of landed drones (downwash ellipsoid 5 m wide): the
    exact check names the pair during the mid-show landing; with the others holding aloft there is none."""
    def doc(others: str) -> dict:
        d = _doc([
            {"name": "ring", "hold_s": 1.0, "points": _pts(ring(9, 14.0, (0, 0, 30))), "color": "#ff0000"},
            {"name": "low", "hold_s": 2.0, "points": [[3.0, 3.0, 4.0], [-20.0, 30.0, 20.0], [0.0, 30.0, 20.0],
                                                     [20.0, 30.0, 20.0]],
             "drones": {"group": "g"}, "others": others},
        ], groups={"g": [0, 1, 2, 3]})
        d["home"]["grid"]["spacing_m"] = 6.0
        d["settings"]["downwash_radius_m"] = 5.0
        return d

    from sim.verify import downwash_violations

    landed = plan_show(parse_show(doc("land")))
    found, total = downwash_violations(landed)
    assert total >= 1
    hold = [s for s in landed.segments if s.kind == "hold"][1]
    flyer = int(np.flatnonzero(landed.transitions[1].goal_index == 0)[0])
    during = [v for v in found if "mid-show landing" in v.message]
    assert during and all(flyer in v.drones for v in during)
    g0, g1, _ = landed.grounded[0]
    assert all(g0 <= v.time_s <= g1 for v in during)
    # Brute force at the middle of the hold: the flyer is inside a landed drone's ellipsoid.
    p = landed.evaluate([hold.start_s + 1.0]).positions_m[0]
    landed_ids = np.flatnonzero(landed.transitions[1].goal_index < 0)
    dxy = np.hypot(*(p[landed_ids, :2] - p[flyer, :2]).T)
    dz = p[flyer, 2] - p[landed_ids, 2]
    assert np.min(dxy**2 / 25.0 + dz**2 / 12.5**2) < 1.0
    assert not check_plan(landed).ok
    assert downwash_violations(plan_show(parse_show(doc("hold"))))[1] == 0


def test_landed_drones_take_off_to_fly_the_next_subset_while_the_first_group_lands():
    doc = _doc([
        {"name": "ring", "hold_s": 1.0, "points": _pts(ring(9, 12.0, (0, 0, 30))), "color": "#ff0000"},
        {"name": "a", "hold_s": 1.0, "points": _pts(_line(4, y=-20.0)), "drones": {"group": "a"}, "others": "land"},
        {"name": "b", "hold_s": 1.0, "points": _pts(_line(5, y=-25.0, z=35.0)), "drones": {"group": "b"},
         "others": "land"},
    ], groups={"a": [0, 2, 4, 6], "b": [1, 3, 5, 7, 8]})
    plan = plan_show(parse_show(doc))
    assert check_plan(plan).ok
    assert _dense_min_distance(plan) >= MIN_D * (1 - 1e-6)
    assert [sorted(g[2].tolist()) for g in plan.grounded] == [[1, 3, 5, 7, 8], [0, 2, 4, 6]]
    hold_b = [s for s in plan.segments if s.kind == "hold"][2]
    p = plan.evaluate([hold_b.start_s + 0.5]).positions_m[0]
    np.testing.assert_allclose(p[[0, 2, 4, 6], 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(p[[1, 3, 5, 7, 8], 2], 35.0, atol=1e-9)


def test_a_moving_formation_cannot_be_a_subset():
    doc = _subset_show()
    doc["formations"][1]["motion"] = {"keys": [{"t_s": 0.0}, {"t_s": 2.0, "translate_m": [1.0, 0.0, 0.0]}]}
    with pytest.raises(ShowValidationError) as info:
        parse_show(doc)
    assert info.value.errors[0]["path"] == "formations[1].motion"


def _swap_doc(points: list[list[float]]) -> dict:
    """Ring (all 9), group a = 0, 2, 4, 6 on a line (the others land), then group b = 0, 2 on ``points`` (others
    land): drones 4 and 6 land in the swap while 1, 3, 5, 7 and 8 stay landed (the prepare-swap path)."""
    return _doc([
        {"name": "ring", "hold_s": 1.0, "points": _pts(ring(9, 12.0, (0, 0, 30))), "color": "#ff0000"},
        {"name": "a", "hold_s": 1.0, "points": _pts(_line(4, y=-20.0)), "drones": {"group": "a"}, "others": "land"},
        {"name": "b", "hold_s": 1.0, "points": points, "drones": {"group": "b"}, "others": "land"},
    ], groups={"a": [0, 2, 4, 6], "b": [0, 2]})


@pytest.mark.parametrize("who, aloft, near, words", [(4, True, [1.0, 0.0, 0.0], "waits to land over its home"),
                                                      (5, False, [0.0, 0.0, 2.6], "stays landed on its home")])
def test_swap_points_on_waiting_or_landed_drones_are_refused_naming_the_point(who, aloft, near, words, tmp_path,
                                                                              capsys):
    """In the swap, a point of the formation 1 m beside where lander 4 waits over its home (takeoff altitude),
    or 2.6 m above drone 5 standing on its home, cannot be kept: refused naming the point, as for other
    subset formations (before: planned, unsafe)."""
    show0 = parse_show(_swap_doc([[0.0, -30.0, 30.0], [10.0, -30.0, 30.0]]))
    home = np.asarray(show0.home_positions_m)
    waits = home[who] + [0.0, 0.0, show0.settings.takeoff_altitude_m if aloft else 0.0]
    bad = waits + np.asarray(near)
    doc = _swap_doc(_pts(np.array([[0.0, -30.0, 30.0], bad])))
    with pytest.raises(PlanError) as err:
        plan_show(parse_show(doc))
    assert err.value.path == "formations[2].points[1]"
    assert f"from drone {who}" in str(err.value) and words in str(err.value)
    # Independently: the point is closer than the minimum distance to that drone's waiting place.
    assert f"{np.linalg.norm(near):.3f} m" in str(err.value)
    # `swarmshow check`: one line naming the point, exit 2; the API's check task: a 422 problem at that loc.
    from app import tasks
    from app.cli import main as cli_main

    path = tmp_path / "swap.json"
    path.write_text(json.dumps(doc))
    assert cli_main(["check", str(path)]) == 2
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("swarmshow: error:")]
    assert len(lines) == 1 and "formations[2].points[1]" in lines[0]
    with pytest.raises(tasks.TaskFailure) as info:
        tasks.check_task(json.dumps(doc))
    (problem,) = info.value.detail
    assert problem["loc"][:5] == ["show", "formations", 2, "points", 1]
    # ... and the same formation 15 m away is planned and safe.
    ok = plan_show(parse_show(_swap_doc(_pts(np.array([[0.0, -30.0, 30.0], bad + [0.0, -15.0, 20.0]])))))
    assert check_plan(ok).ok
