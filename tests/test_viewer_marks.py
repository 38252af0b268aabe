"""The 3D view's marks: violations drawn on the drones around their time, the jump to the next one and to a
formation's hold, and the gap between the plan and a flight coloured by its size."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from app.viewer import Viewer
from app.viewer._marks import (
    Problem,
    active_problems,
    deviation_colors,
    problem_list,
    problem_segments,
)
from sim import check_plan, plan_show


@pytest.fixture
def plan(small_show):
    return plan_show(small_show)


@pytest.fixture
def viewer():
    v = Viewer(start_thread=False)
    yield v
    v.stop()


def _report(violations: list[dict]) -> dict:
    """A check report shaped like ``CheckReport.to_json()`` with these violations in one group."""
    return {"by_transition": [{"formation": 0, "violations": violations}], "violations": violations}


def test_problem_segments_join_the_pair_and_tick_single_drones():
    pos = np.array([[0.0, 0, 10], [1.0, 0, 10], [5.0, 5, 20], [9.0, 9, 9]])
    probs = [Problem(3.0, "min_distance", (0, 1), "too close", 0), Problem(3.0, "speed_xy", (2, 3), "fast", 0)]
    segs = problem_segments(probs, pos)
    assert segs.shape == (3, 2, 3)
    np.testing.assert_allclose(segs[0], pos[[0, 1]])
    for k, d in ((1, 2), (2, 3)):
        np.testing.assert_allclose(segs[k, 0], pos[d])
        np.testing.assert_allclose(segs[k, 1] - segs[k, 0], [0, 0, 2.0])
    assert problem_segments([], pos).shape == (0, 2, 3)
    # Only problems near the playhead are drawn, nearest first.
    near = active_problems([Problem(1.0, "x", (0,), "", 0), Problem(9.0, "x", (0,), "", 0),
                            Problem(4.5, "x", (1,), "", 0)], 4.0, window_s=1.5)
    assert [p.time_s for p in near] == [4.5]


def test_problem_list_reads_a_real_check_report(small_show):
    """From the real report of a show with a transition forced too short: every violation, in time order."""
    data = small_show.model_dump()
    data["formations"][1]["transition_s"] = 0.5
    show = type(small_show).model_validate(data)
    report = check_plan(plan_show(show, enforce_limits=False))
    listed = [v for g in report.by_transition for v in g.violations]
    assert not report.ok and listed
    probs = problem_list(report.to_json())
    assert len(probs) == len(listed)
    assert [p.time_s for p in probs] == sorted(v.time_s for v in listed)
    assert {p.kind for p in probs} == {v.kind for v in listed}


def test_viewer_draws_violations_at_their_time_and_jumps_to_them(viewer, plan):
    t_bad = 0.6 * plan.duration_s
    report = _report([{"kind": "min_distance", "drones": [0, 1], "time_s": t_bad, "value": 1.0, "limit": 2.0,
                       "segment": 1, "message": "#0 and #1 1.00 m apart"}])
    viewer.load(plan, name="a", report=report)
    assert not viewer._next_problem.disabled
    viewer.seek(0.0)
    viewer.render()
    assert viewer.last_problem_segments.shape == (0, 2, 3) and not viewer._problem_lines.visible
    assert viewer.next_problem() == pytest.approx(t_bad)
    viewer.render()
    # The mark joins drones 0 and 1 where the plan puts them at that time (independently evaluated).
    expected = plan.evaluate([t_bad]).positions_m[0][[0, 1]]
    np.testing.assert_allclose(viewer.last_problem_segments[0], expected, atol=1e-4)
    assert viewer._problem_lines.visible and "1.00 m apart" in viewer._problem_label.text
    assert "**Problems** 1" in viewer._readout.content
    # The toggle hides the marks.
    viewer._problems_cb.value = False
    viewer.render()
    assert not viewer._problem_lines.visible


def test_report_arrives_after_the_show(viewer, plan):
    viewer.load(plan, name="a")
    assert viewer._next_problem.disabled and viewer.next_problem() is None
    viewer.set_report("a", _report([{"kind": "altitude", "drones": [2], "time_s": 5.0, "value": 130.0,
                                     "limit": 120.0, "segment": 1, "message": "too high"}]))
    assert not viewer._next_problem.disabled and viewer.next_problem() == pytest.approx(5.0)
    viewer.render()
    pos = plan.evaluate([5.0]).positions_m[0][2]
    np.testing.assert_allclose(viewer.last_problem_segments[0], [pos, pos + [0, 0, 2.0]], atol=1e-4)


def test_seek_formation_goes_to_its_hold(viewer, plan):
    viewer.load(plan, name="a")
    holds = [seg for _, seg in plan.formation_segments()]
    for k, seg in enumerate(holds):
        assert viewer._main.seek_formation(k) == pytest.approx(seg.start_s)
        assert plan.segments[int(plan.segment_index(viewer.time_s + 1e-6))].kind == "hold"
    assert viewer._main.seek_formation(len(holds)) is None


def test_flown_beside_planned_colours_the_gap(viewer, plan):
    t = plan.sample_times(10.0)
    s = plan.evaluate(t)
    # Drone 0 flies 0.3 m east of its plan all show long, the others on it.
    offset = np.zeros_like(s.positions_m)
    offset[:, 0, 0] = 0.3
    flight = SimpleNamespace(times_s=t, positions_m=s.positions_m + offset, colors_rgb=s.colors_rgb)
    viewer.load(plan, name="a", flight=flight)
    assert plan.drone_count == 16  # the mean below: 0.3 m / 16, in millimetres (under 10 cm)
    viewer.seek(t[len(t) // 2])
    viewer.render()
    dev = viewer.last_deviation_m
    assert dev is not None and dev[0] == pytest.approx(0.3, abs=1e-6) and np.all(dev[1:] < 1e-6)
    assert viewer._gap_lines.visible and viewer._planned_ghost.visible
    assert "max 0.30 m (#0) · mean 18.75 mm" in viewer._readout.content
    cols = viewer._gap_lines.colors
    assert tuple(cols[1, 0]) == tuple(deviation_colors(np.array([0.0]), 1.0)[0])  # on the plan: green
    # The planned source shows no gap.
    viewer.set_source("planned")
    viewer.render()
    assert viewer.last_deviation_m is None and not viewer._gap_lines.visible


def test_deviation_colours_run_green_to_red():
    c = deviation_colors(np.array([0.0, 0.5, 1.0, 3.0]), 1.0)
    assert tuple(c[0]) == (0, 255, 38) and tuple(c[1]) == (255, 255, 38)
    assert tuple(c[2]) == tuple(c[3]) == (255, 0, 38)
