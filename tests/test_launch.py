"""Launch layouts (issue 21 item 4, issue 15 item 5): launch boxes, home CSV, takeoff and landing in waves,
and the parked-drone rules of the exact check, against brute force and dense sampling."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import sim.plan._plan as plan_module
from formations import (
    HomeCsvError,
    ShowValidationError,
    home_points_from_csv,
    home_points_to_csv,
    parse_show,
)
from sim import check_plan, plan_show
from sim.plan import _waves
from sim.plan._schedule import round_up, sync_min_duration
from sim.verify import downwash_violations
from sim.verify._parked import rest_times
from tests.conftest import fibonacci_sphere, make_show, ring

PER_BOX, BOX_SPACING = 8, 0.8


def boxes_show(*, drones: int = 48, rows: int = 2, cols: int = 3, centre_spacing: float = 6.0, **settings):
    """``drones`` drones in boxes of 8 (4 x 2 at 0.8 m), boxes on a rows x cols grid."""
    pts_a = np.round(ring(drones, 30.0), 6).tolist()
    pts_b = np.round(fibonacci_sphere(drones, 20.0), 6).tolist()
    return parse_show({
        "format": "swarmshow/1", "name": "boxed", "drones": drones,
        "home": {"boxes": {"per_box": PER_BOX, "cols": 4, "spacing_m": BOX_SPACING,
                           "grid": {"rows": rows, "cols": cols, "spacing_m": centre_spacing}}},
        "settings": settings,
        "formations": [{"name": "ring", "hold_s": 3.0, "points": pts_a, "color": "#ff0000"},
                       {"name": "ball", "hold_s": 3.0, "points": pts_b, "color": "#00ff00"}],
    })


@pytest.fixture(scope="module")
def boxed():
    show = boxes_show()
    return show, plan_show(show)


# ------------------------------------------------------------------ the show file

def test_boxes_lay_out_each_box_at_its_spacing_and_boxes_apart(boxed):
    show, _ = boxed
    home = show.home_positions_m
    box = show.all_home_boxes[: show.drones]
    assert len(home) == 48 and np.bincount(box).tolist() == [8] * 6
    d = np.linalg.norm(home[:, None, :] - home[None, :, :], axis=2)
    same = box[:, None] == box[None, :]
    off = ~np.eye(len(home), dtype=bool)
    assert d[same & off].min() == pytest.approx(BOX_SPACING)
    assert d[~same].min() >= show.settings.min_distance_m


@pytest.mark.parametrize("home, path", [
    ({"boxes": {"per_box": 8, "spacing_m": 0.8, "grid": {"rows": 2, "cols": 3, "spacing_m": 4.0}}},
     "home.boxes.grid.spacing_m"),
    ({"boxes": {"per_box": 8, "spacing_m": 0.8, "centers": [[0, 0], [20, 0], [22, 0], [40, 0], [60, 0], [80, 0]]}},
     "home.boxes.centers[2]"),
    ({"boxes": {"per_box": 8, "spacing_m": 0.05, "grid": {"rows": 2, "cols": 3, "spacing_m": 6.0}}},
     "home.boxes.spacing_m"),
    ({"boxes": {"per_box": 4, "spacing_m": 0.8, "grid": {"rows": 2, "cols": 3, "spacing_m": 6.0}}},
     "home.boxes.grid"),
    ({"boxes": {"per_box": 8, "spacing_m": 0.8}}, "home.boxes"),
    # hostile: 64 x 20,000 x 20,000 homes are refused by count before any position is computed
    ({"boxes": {"per_box": 64, "spacing_m": 0.8, "grid": {"rows": 20000, "cols": 20000, "spacing_m": 6.0}}},
     "home.boxes.grid"),
    ({"boxes": {"per_box": 8, "spacing_m": 0.8, "grid": {"rows": 1, "cols": 6, "spacing_m": 900.0}}},
     "home.boxes.grid.spacing_m"),
    ({"boxes": {"per_box": 0, "spacing_m": 0.8, "grid": {"rows": 2, "cols": 3, "spacing_m": 6.0}}},
     "home.boxes.per_box"),
    ({"boxes": {"per_box": 8, "spacing_m": 0.8, "grid": {"rows": 2, "cols": 3, "spacing_m": 6.0},
                "colour": 1}}, "home.boxes.colour"),
])
def test_bad_boxes_are_rejected_naming_the_field(home, path):
    doc = boxes_show().model_dump(mode="json", exclude_none=True)
    doc["home"] = home
    with pytest.raises(ShowValidationError) as err:
        parse_show(doc)
    assert err.value.errors[0]["path"] == path, err.value.errors


def test_boxes_must_clear_a_wider_downwash_between_boxes():
    with pytest.raises(ShowValidationError) as err:
        boxes_show(downwash_radius_m=4.0)  # boxes 3.6 m apart at the closest
    assert err.value.errors[0]["path"] == "home.boxes.grid.spacing_m"
    assert "downwash" in err.value.errors[0]["msg"]


# ------------------------------------------------------------------ CSV

def test_home_csv_round_trips_and_reads_skybrush_and_plain_rows():
    rng = np.random.default_rng(3)
    pts = np.column_stack([rng.uniform(-50, 50, (20, 2)), np.zeros(20)])
    text = home_points_to_csv(pts)
    back, names = home_points_from_csv(text.encode())
    np.testing.assert_array_equal(np.array(back), pts)
    assert names[0] == "Drone 1" and len(names) == 20
    plain, names = home_points_from_csv("1,2\n3.5,4,0.25\n\n")
    assert plain == [[1.0, 2.0, 0.0], [3.5, 4.0, 0.25]] and names == ["", ""]
    named, names = home_points_from_csv("Name,x,y,z\nA,1,2,0\nB,4,2,0\n")
    assert named == [[1.0, 2.0, 0.0], [4.0, 2.0, 0.0]] and names == ["A", "B"]
    # The points make a show that validates like typed points.
    doc = boxes_show().model_dump(mode="json", exclude_none=True)
    doc["home"] = {"points": home_points_from_csv(home_points_to_csv(
        np.array([[x * 3.0, y * 3.0, 0.0] for x in range(8) for y in range(6)])))[0]}
    assert parse_show(doc).home_positions_m.shape == (48, 3)


@pytest.mark.parametrize("data, words", [
    ("1,2\n3,x\n", "line 2"),
    ("1,2,3,4\n", "line 1"),
    ("Name,x,y,z\nA,1,nan,0\n", "line 2"),
    (b"\xff\xfe1,2\n", "UTF-8"),
    ("Name,x,y,z\n", "no home points"),
    ("1,2\n" * 100_001, "rows"),
])
def test_hostile_home_csv_says_where(data, words):
    with pytest.raises(HomeCsvError) as err:
        home_points_from_csv(data)
    assert words in str(err.value)


def test_home_csv_with_classic_mac_line_ends_reads_its_rows():
    # A lone carriage return ends a row (old spreadsheets write them); it raised csv.Error, a 500 in
    # POST /api/formations/home-csv (found by the API fuzz test with b"0,0\r1\n").
    assert home_points_from_csv(b"1,2\r3,4,0.5\r")[0] == [[1.0, 2.0, 0.0], [3.0, 4.0, 0.5]]
    with pytest.raises(HomeCsvError, match="line 2"):
        home_points_from_csv(b"0,0\r1\n")


@settings(max_examples=300, deadline=None)
@given(data=st.one_of(st.binary(max_size=80), st.text(alphabet="0123456789.,-\r\n\"\x00 abNe", max_size=60)))
def test_any_home_csv_reads_or_says_why(data):
    # Whatever the upload holds, the reader returns points or raises HomeCsvError (a 422), nothing else.
    try:
        points, names = home_points_from_csv(data)
    except HomeCsvError:
        return
    assert len(points) == len(names) > 0 and all(len(p) == 3 for p in points)


# ------------------------------------------------------------------ waves

def chromatic_number(n: int, pairs: np.ndarray) -> int:
    """Brute force: the fewest colours of a proper colouring."""
    for k in range(1, n + 1):
        for colours in itertools.product(range(k), repeat=n):
            if all(colours[a] != colours[b] for a, b in pairs):
                return k
    return n


@pytest.mark.parametrize("seed", range(6))
def test_wave_colouring_is_proper_and_minimal_on_small_layouts(seed):
    rng = np.random.default_rng(seed)
    # Two boxes of 4 plus random loose points: small enough for the brute-force chromatic number.
    homes = [[x * 0.8, y * 0.8, 0.0] for x in range(2) for y in range(2)]
    homes += [[5.0 + x * 0.8, y * 0.8, 0.0] for x in range(2) for y in range(2)]
    homes += [[*rng.uniform(-4, 8, 2), 0.0] for _ in range(int(rng.integers(0, 2)))]
    homes_m = np.array(homes)
    pairs = _waves.conflict_pairs(homes_m, 3.0)
    wave = _waves.colour_waves(len(homes_m), pairs)
    assert all(wave[a] != wave[b] for a, b in pairs)
    d = np.linalg.norm(homes_m[:, None, :2] - homes_m[None, :, :2], axis=2)
    brute = np.argwhere(np.triu(d < 3.0 * (1 - 1e-9), 1))
    assert {tuple(p) for p in pairs.tolist()} == {tuple(p) for p in brute.tolist()}
    assert wave.max() + 1 == chromatic_number(len(homes_m), pairs)


def test_boxed_show_takes_off_in_waves_one_box_mate_after_another(boxed):
    show, plan = boxed
    tw = plan.launch.takeoff
    assert tw is not None and tw.count == PER_BOX  # a box is a clique: 8 waves are the minimum
    box = show.all_home_boxes[:48]
    for b in range(6):
        assert sorted(tw.wave[box == b].tolist()) == list(range(PER_BOX))  # one drone of each box per wave
    lift, touch = rest_times(plan.motion)
    take = plan.segments[0]
    assert take.kind == "takeoff"
    starts = [lift[tw.wave == k] for k in range(tw.count)]
    assert all(np.ptp(s) == 0 for s in starts)  # a wave leaves together
    assert np.all(np.diff([s[0] for s in starts]) > 0)  # waves leave one after another
    # At the end of takeoff every pair keeps min_distance_m (the first transition starts safe).
    up = plan.knot_positions_m[1]
    d = np.linalg.norm(up[:, None] - up[None], axis=2) + np.eye(48) * 1e9
    assert d.min() >= show.settings.min_distance_m
    assert plan.launch.landing is not None and plan.launch.landing.count == PER_BOX


def test_boxed_show_passes_the_exact_check_with_no_violation(boxed):
    _, plan = boxed
    report = check_plan(plan)
    assert report.ok and report.violations_total == 0, [v.message for v in report.violations[:5]]
    assert report.min_distance_m >= plan.settings.min_distance_m * (1 - 1e-9)


@pytest.mark.parametrize("extra", [{"landing": "own_home"}, {"time_law": "quintic"}])
def test_boxed_show_other_modes_pass_the_exact_check(extra):
    show = boxes_show(drones=24, rows=1, cols=3, **extra)
    plan = plan_show(show)
    report = check_plan(plan)
    assert report.violations_total == 0, [v.message for v in report.violations[:5]]
    if extra.get("landing") == "own_home":
        np.testing.assert_allclose(plan.knot_positions_m[-1], show.home_positions_m, atol=1e-9)


def test_sparse_grid_keeps_everyone_climbing_at_once():
    show = make_show([{"name": "ring", "hold_s": 2.0, "points": ring(12, 12.0)}], drones=12, rows=3, cols=4)
    plan = plan_show(show)
    assert plan.launch is None
    take = plan.segments[0]
    assert take.kind == "takeoff" and plan.segments[1].kind == "transition"
    up = plan.knot_positions_m[1]
    assert np.ptp(up[:, 2]) == 0 and up[0, 2] == pytest.approx(show.settings.takeoff_altitude_m)
    # one shared profile: the window is the synchronised minimum of the climb (to the lifted or spread grid)
    d = up - plan.knot_positions_m[0]
    assert take.duration_s == pytest.approx(round_up(sync_min_duration(d, plan_module._limits(show.settings))))
    t = np.linspace(take.start_s, take.end_s, 50)
    p = plan.evaluate(t).positions_m
    assert np.ptp(p[:, :, 2], axis=1).max() < 1e-9  # one altitude for all at every instant
    lift_s, _ = rest_times(plan.motion)
    assert np.all(lift_s == 0.0)


# ------------------------------------------------------------------ parked rules against dense sampling

def sampled_rules(plan, samples: int = 6001) -> dict[str, np.ndarray]:
    """Brute force over dense samples of the takeoff and landing windows, parked status by position:
    (N, N) minimum distance over instants where both fly or one flies and they are of different boxes,
    the same for the downwash ellipsoid, and the clearance ellipsoid over instants where one of two
    box mates is parked."""
    s = plan.settings
    r, c = s.downwash_axes_m
    rc = plan.launch.box_clearance_m
    n = plan.drone_count
    out = {k: np.full((n, n), np.inf) for k in ("dist", "wash", "clear")}
    for seg in plan.segments:
        if seg.kind not in ("takeoff", "landing"):
            continue
        t = np.linspace(seg.start_s, seg.end_s, samples)
        p = plan.evaluate(t).positions_m
        ref = p[0] if seg.kind == "takeoff" else p[-1]
        at_home = np.all(np.abs(p - ref[None]) < 1e-12, axis=2)  # (T, N)
        # parked: at home and not yet left (takeoff) / never to leave again (landing)
        parked = np.logical_and.accumulate(at_home, axis=0) if seg.kind == "takeoff" else \
            np.logical_and.accumulate(at_home[::-1], axis=0)[::-1]
        box = plan.launch.start_box if seg.kind == "takeoff" else plan.launch.end_box
        same = (box[:, None] >= 0) & (box[:, None] == box[None, :])
        d = p[:, :, None, :] - p[:, None, :, :]
        dist = np.linalg.norm(d, axis=3)
        wash = np.sqrt((d[..., 0] ** 2 + d[..., 1] ** 2) / r**2 + d[..., 2] ** 2 / c**2)
        clear = np.sqrt((d[..., 0] ** 2 + d[..., 1] ** 2) / rc**2 + d[..., 2] ** 2 / c**2)
        both_parked = parked[:, :, None] & parked[:, None, :]
        one_parked = parked[:, :, None] ^ parked[:, None, :]
        usual = ~both_parked & ~(same[None] & one_parked)
        mates = same[None] & one_parked
        for key, val, where in (("dist", dist, usual), ("wash", wash, usual), ("clear", clear, mates)):
            out[key] = np.minimum(out[key], np.where(where, val, np.inf).min(axis=0))
    for v in out.values():
        np.fill_diagonal(v, np.inf)
    return out


def test_parked_rules_match_dense_sampling_on_the_boxed_plan():
    show = boxes_show(drones=16, rows=1, cols=2)
    plan = plan_show(show)
    brute = sampled_rules(plan)
    assert brute["dist"].min() >= show.settings.min_distance_m * (1 - 1e-6)
    assert brute["wash"].min() >= 1 - 1e-6 and brute["clear"].min() >= 1 - 1e-6
    # ...and the sampling sees the close pairs the rules exempt: box mates parked side by side at 0.8 m.
    assert np.isfinite(brute["clear"]).any()
    assert check_plan(plan).violations_total == 0


def _over_the_neighbour(real):
    """A broken planner: the first wave hovers 3 m up, one box spacing to the side (over a parked box mate)."""
    def waves(homes, lim, **kw):
        w = real(homes, lim, **kw)
        if w is None or kw.get("landing"):
            return w
        sched = w.schedule
        b = sched.b_m.copy()
        first = np.flatnonzero(w.wave == 0)
        box_centre = homes[(first // PER_BOX)[:, None] * PER_BOX + np.arange(PER_BOX)[None, :], 0].mean(axis=1)
        b[first, 0] += np.where(box_centre >= homes[first, 0], 1.0, -1.0) * BOX_SPACING  # towards a box mate
        b[w.wave == 0, 2] = 3.0
        # the later waves wait until the first has arrived over its neighbour
        late = np.where(w.wave > 0, float(sched.arrive_s[first].max()), 0.0)
        from dataclasses import replace
        return replace(w, schedule=replace(sched, b_m=b, depart_s=sched.depart_s + late,
                                           arrive_s=sched.arrive_s + late, window_s=sched.window_s + late.max(),
                                           sync_s=sched.window_s + late.max()))
    return waves


def test_a_drone_over_its_parked_box_mate_is_found_as_dense_sampling_finds_it(monkeypatch):
    monkeypatch.setattr(plan_module, "takeoff_waves", _over_the_neighbour(_waves.takeoff_waves))
    plan = plan_show(boxes_show(drones=16, rows=1, cols=2))
    brute = sampled_rules(plan)
    report = check_plan(plan)
    assert report.violations_total <= len(report.violations)  # every violation listed
    found = {tuple(sorted(v.drones)) for v in report.violations if v.kind in ("downwash", "min_distance")}
    must = {tuple(sorted(map(int, p))) for key, lim in (("dist", plan.settings.min_distance_m), ("wash", 1.0),
                                                         ("clear", 1.0))
            for p in np.argwhere(np.triu(brute[key] < lim * (1 - 1e-6), 1))}
    assert must and must <= found
    # Every reported pair is close in the sampling too (exact minimum <= samples, nearly equal).
    near = {tuple(sorted(map(int, p))) for key, lim in (("dist", plan.settings.min_distance_m), ("wash", 1.0),
                                                         ("clear", 1.0))
            for p in np.argwhere(np.triu(brute[key] < lim * (1 + 1e-3), 1))}
    assert found <= near
    assert (brute["clear"] < 1 - 1e-6).any()  # rule 2 (over a parked box mate) is exercised


def test_waves_leaving_together_are_caught(monkeypatch):
    """Without wave offsets box mates climb side by side at 0.8 m: min_distance and downwash violations."""
    monkeypatch.setattr(_waves, "_offsets", lambda dur, curves, gap: np.zeros(len(dur)))
    plan = plan_show(boxes_show(drones=16, rows=1, cols=2))
    brute = sampled_rules(plan)
    listed, total = downwash_violations(plan, max_listed=1 << 30)
    found = {tuple(sorted(v.drones)) for v in listed}
    must = {tuple(sorted(map(int, p))) for p in np.argwhere(np.triu(brute["wash"] < 1 - 1e-6, 1))}
    near = {tuple(sorted(map(int, p))) for p in np.argwhere(np.triu(brute["wash"] < 1 + 1e-3, 1))}
    assert must and must <= found <= near and total == len(listed)


@settings(max_examples=6, deadline=None)
@given(per_box=st.integers(2, 8), spacing=st.floats(0.4, 1.5), rows=st.integers(1, 2), cols=st.integers(1, 3),
       law=st.sampled_from(["min_time", "quintic"]), landing=st.sampled_from(["any_home", "own_home"]))
def test_random_box_layouts_plan_and_pass_the_exact_check(per_box, spacing, rows, cols, law, landing):
    """Any box pattern and placement the show file accepts plans to 0 violations (waves when needed)."""
    pattern_cols = max(1, int(np.ceil(np.sqrt(per_box))))
    extent = (pattern_cols - 1) * spacing
    n = per_box * rows * cols
    show = parse_show({
        "format": "swarmshow/1", "name": "random boxes", "drones": n,
        "home": {"boxes": {"per_box": per_box, "spacing_m": round(spacing, 3),
                           "grid": {"rows": rows, "cols": cols, "spacing_m": round(extent + 3.5, 3)}}},
        "settings": {"time_law": law, "landing": landing},
        "formations": [{"name": "ring", "hold_s": 2.0, "points": np.round(ring(n, max(6.0, 0.6 * n)), 6).tolist()}],
    })
    plan = plan_show(show)
    report = check_plan(plan)
    assert report.violations_total == 0, [v.message for v in report.violations[:3]]
    conflicts = len(_waves.conflict_pairs(show.home_positions_m, 3.0))
    assert (plan.launch.takeoff is not None) == (conflicts > 0)


def test_too_many_waves_for_the_ceiling_is_a_plan_error_naming_the_field():
    show = boxes_show(drones=16, rows=1, cols=2, downwash_height_m=20.0)  # 8 layers 22 m apart: up to 164 m
    with pytest.raises(plan_module.PlanError) as err:
        plan_show(show)
    assert err.value.path == "home.boxes.per_box" and "8 takeoff waves" in str(err.value)


@pytest.mark.parametrize("others", ["hold", "park", "land"])
def test_subset_formations_on_launch_boxes(others):
    """Others holding or parking fly safe beside the waves; landing mid-show onto box homes (not yet in
    waves) is refused naming the field rather than planned unsafe."""
    doc = boxes_show(drones=16, rows=1, cols=2).model_dump(mode="json", exclude_none=True)
    few = dict(doc["formations"][1], name="few", drones={"count": 8}, others=others)
    doc["formations"].insert(1, few)
    show = parse_show(doc)
    if others == "land":
        with pytest.raises(plan_module.PlanError) as err:
            plan_show(show)
        assert err.value.path == "formations[1].others"
        return
    report = check_plan(plan_show(show))
    assert report.violations_total == 0, [v.message for v in report.violations[:3]]
