"""Cue times (issue 18): formations pinned to arrive / leave at show times.

Independent references: the timeline computed by hand from the pins, the hold lengths and the
unpinned plan's own transition lengths; positions sampled at the pinned times (every drone on
its formation point); dense sampling for the separation and the limits of stretched transitions.
"""

from __future__ import annotations

import numpy as np
import pytest

from formations import ShowValidationError, parse_show
from sim.bench._dense import dense_show
from sim.plan import PlanError, plan_show
from sim.verify import check_plan
from tests.conftest import fibonacci_sphere, make_show, ring
from tests.test_plan_schedule import check_limits_and_holds, sampled_min_distance


def small(**pins) -> dict:
    """The 16-drone ring -> sphere -> ring show as a dict, with ``{formation index}_{field}`` pins."""
    forms = [
        {"name": "ring", "hold_s": 2.0, "points": ring(16, 12.0), "color": "#ff0000"},
        {"name": "sphere", "hold_s": 3.0, "points": fibonacci_sphere(16, 9.0), "color": "#00ff00"},
        {"name": "ring 2", "hold_s": 4.0, "points": ring(16, 12.0, center=(0.0, 0.0, 40.0)), "color": "#0000ff"},
    ]
    for key, value in pins.items():
        k, field = key.split("_", 1)
        forms[int(k.lstrip("f"))][field] = value
    return forms


def build(forms):
    return make_show(forms, drones=16, rows=4, cols=4, spacing_m=4.5)


def expected_timeline(forms, natural_s: list[float], takeoff_s: float) -> list[tuple[float, float]]:
    """(arrival, departure) of each formation from the pins, holds and natural transition lengths."""
    out = []
    t = takeoff_s
    for f, nat in zip(forms, natural_s, strict=True):
        arrive = f.get("arrive_at_s", t + nat)
        leave = f.get("leave_at_s", arrive + f["hold_s"])
        out.append((arrive, leave))
        t = leave
    return out


def holds(plan):
    return [(seg.start_s, seg.end_s) for _, seg in plan.formation_segments()]


@pytest.mark.parametrize("pins", [
    {"f0_arrive_at_s": 45.0},
    {"f1_arrive_at_s": 60.0, "f1_leave_at_s": 70.0},
    {"f0_leave_at_s": 50.0, "f2_arrive_at_s": 80.0},
    {"f0_arrive_at_s": 40.0, "f0_leave_at_s": 44.5, "f1_arrive_at_s": 58.25, "f2_leave_at_s": 100.0},
])
def test_pinned_cue_times_match_the_timeline_computed_by_hand(pins):
    free = plan_show(build(small()))
    natural = [t.duration_s for t in free.transitions[:3]]
    takeoff = free.segments[0].duration_s
    forms = small(**pins)
    plan = plan_show(build(forms))
    want = expected_timeline(forms, natural, takeoff)
    assert np.allclose(holds(plan), want, atol=1e-9), (holds(plan), want)
    # At each pinned arrival every drone is on its formation point, and not before.
    for k, (arrive, _leave) in enumerate(want):
        seg = plan.formation_segments()[k][1]
        at = plan.motion.evaluate([arrive]).positions_m[0]
        assert np.abs(at - plan.knot_positions_m[seg.index]).max() < 1e-9
        before = plan.motion.evaluate([arrive - 0.2]).positions_m[0]
        assert np.abs(before - plan.knot_positions_m[seg.index]).max() > 1e-3
    # Stretched transitions stay safe and within every limit (checked exactly and by sampling).
    report = check_plan(plan)
    assert report.ok, report
    sampled, _, smp = sampled_min_distance(plan, dt=0.05)
    assert sampled >= 3.0 * (1 - 1e-9)
    check_limits_and_holds(plan, smp, dt=0.05)


def test_hold_editing_still_moves_unpinned_formations():
    base = plan_show(build(small(f2_arrive_at_s=90.0)))
    longer = small(f2_arrive_at_s=90.0)
    longer[0]["hold_s"] = 5.0
    plan = plan_show(build(longer))
    # The first hold grows by 3 s, the second formation moves 3 s later, the pinned one stays.
    assert holds(plan)[0][1] - holds(base)[0][1] == pytest.approx(3.0)
    assert holds(plan)[1][0] - holds(base)[1][0] == pytest.approx(3.0)
    assert holds(plan)[2][0] == holds(base)[2][0] == pytest.approx(90.0)


def test_an_early_arrival_names_the_formation_and_the_earliest_feasible_time():
    free = plan_show(build(small()))
    start = free.transitions[1].start_s
    with pytest.raises(PlanError) as err:
        plan_show(build(small(f1_arrive_at_s=start + 1.0)))
    e = err.value
    assert e.path == "formations[1].arrive_at_s" and "'sphere'" in str(e) and "earliest feasible arrival" in str(e)
    natural_end = free.transitions[1].start_s + free.transitions[1].duration_s
    assert e.earliest_s is not None and start < e.earliest_s <= natural_end
    assert f"{e.earliest_s:.1f} s" in str(e)
    # The earliest time is feasible; 0.1 s earlier is not.
    plan = plan_show(build(small(f1_arrive_at_s=e.earliest_s)))
    assert holds(plan)[1][0] == pytest.approx(e.earliest_s)
    with pytest.raises(PlanError):
        plan_show(build(small(f1_arrive_at_s=round(e.earliest_s - 0.1, 6))))


def test_an_early_departure_names_the_earliest_leave_time():
    free = plan_show(build(small()))
    reached = holds(free)[0][0]
    with pytest.raises(PlanError) as err:
        plan_show(build(small(f0_leave_at_s=reached - 1.0)))
    assert err.value.path == "formations[0].leave_at_s" and "'ring'" in str(err.value)
    assert err.value.earliest_s == pytest.approx(reached + 0.01)


def test_a_layered_transition_pinned_later_waits_then_flies_its_certified_legs():
    show = dense_show(30, formations=3)
    free = plan_show(show)
    tr = free.transitions[1]
    assert tr.resolution == "layers"
    doc = show.model_dump(mode="json", exclude_none=True)
    target = tr.start_s + tr.duration_s + 4.0
    doc["formations"][1]["arrive_at_s"] = target
    plan = plan_show(parse_show(doc))
    assert holds(plan)[1][0] == pytest.approx(target)
    assert all(not t.unresolved for t in plan.transitions)
    sampled, _, smp = sampled_min_distance(plan, dt=0.05)
    assert sampled >= show.settings.min_distance_m * (1 - 1e-9)
    assert check_plan(plan).ok


@pytest.mark.parametrize("patch,path,words", [
    ({1: {"arrive_at_s": 50.0, "transition_s": 10.0}}, "formations[1]", "either 'transition_s' or 'arrive_at_s'"),
    ({1: {"arrive_at_s": 50.0, "leave_at_s": 49.0}}, "formations[1]", "after arrive_at_s"),
    ({0: {"leave_at_s": 60.0}, 1: {"arrive_at_s": 55.0}}, "formations[1].arrive_at_s", "must increase"),
    ({2: {"arrive_at_s": -1.0}}, "formations[2].arrive_at_s", "greater than or equal to 0"),
])
def test_bad_pins_are_refused_with_their_path(patch, path, words):
    forms = small()
    for k, fields in patch.items():
        forms[k].update(fields)
    for f in forms:
        f["points"] = np.asarray(f["points"]).tolist()
    doc = {"format": "swarmshow/1", "name": "t", "drones": 16,
           "home": {"grid": {"rows": 4, "cols": 4, "spacing_m": 4.5}}, "formations": forms}
    with pytest.raises(ShowValidationError) as err:
        parse_show(doc)
    first = err.value.errors[0]
    assert first["path"].startswith(path) and words in first["msg"], first


def test_check_answers_an_infeasible_cue_with_422_and_the_earliest_time(tmp_path):
    from fastapi.testclient import TestClient

    from app.server import create_app
    from app.settings import AppSettings
    from formations import dump_show

    free = plan_show(build(small()))
    start = free.transitions[1].start_s
    show = build(small(f1_arrive_at_s=start + 1.0))
    app = create_app(AppSettings(data_dir=tmp_path, workers=1, viewer=False))
    with TestClient(app, base_url="http://127.0.0.1") as client:
        sid = client.post("/api/shows", content=dump_show(show)).json()["id"]
        r = client.post(f"/api/shows/{sid}/check")
        assert r.status_code == 422, r.text
        problem = r.json()["detail"][0]
        assert problem["path"] == "formations[1].arrive_at_s" and "'sphere'" in problem["msg"]
        assert start < problem["earliest_s"] <= start + free.transitions[1].duration_s
