"""A transition forced shorter than the limits allow (QA): the check, the 3D preview and simulation take the show as
designed and say what is wrong; the exports that drones fly (and the Monte-Carlo safety report) refuse it naming the
field. Before, the check planned it but playback, simulate and every export refused it, so the designer could not
watch the problem the check listed."""

from __future__ import annotations

import time

import pytest

from formations import parse_show
from sim import PlanError, check_plan, plan_show
from tests.conftest import app_client
from tests.test_api_jobs import read_events
from tests.test_api_shows import show_doc

FIELD = "formations[1].transition_s"
LOC = ["show", "formations", 1, "transition_s"]


def forced_doc(name: str = "forced short") -> dict:
    """The API tests' 4-drone square, then the same square 20 m higher, forced to fly there in 0.2 s."""
    doc = show_doc(name)
    doc["formations"].append({**doc["formations"][0], "name": "lifted", "transition_s": 0.2,
                              "points": [[x, y, z + 20] for x, y, z in doc["formations"][0]["points"]]})
    return doc


client = app_client("data", workers=1)


@pytest.fixture(scope="module")
def forced(client) -> dict:
    r = client.post("/api/shows", json=forced_doc())
    assert r.status_code == 201, r.text
    return r.json()


def _minimum_s() -> float:
    """The shortest duration the limits allow, from the planner's own refusal (the independent source)."""
    with pytest.raises(PlanError) as info:
        plan_show(parse_show(forced_doc()))
    assert info.value.path == FIELD
    return float(info.value.minimum_s)


def _names_the_field(problems: list[dict]) -> dict:
    assert len(problems) == 1, problems
    p = problems[0]
    assert p["path"] == FIELD and p["loc"] == LOC, p
    assert "shorter than the minimum" in p["msg"] and "'square' -> 'lifted'" in p["msg"], p
    assert p["minimum_s"] == pytest.approx(_minimum_s()), p
    return p


def test_check_reports_the_forced_transition(client, forced):
    r = client.post(f"/api/shows/{forced['id']}/check")
    assert r.status_code == 200, r.text
    report = r.json()["report"]
    assert not report["ok"]
    assert any(v["kind"] == "transition_duration" for v in report["violations"])


def test_playback_plays_the_show_as_designed_with_its_problems(client, forced):
    r = client.post(f"/api/shows/{forced['id']}/playback", json={"source": "planned"})
    assert r.status_code == 200, r.text
    body = r.json()
    _names_the_field(body["problems"])
    # The viewer plays the plan the check verified (flown as forced) and draws that check's violations.
    expected = plan_show(parse_show(forced_doc()), enforce_limits=False)
    assert body["duration_s"] == pytest.approx(expected.duration_s)
    loader = client.app.state.viewer_loader
    deadline = time.monotonic() + 60
    while forced["content_hash"] not in loader._reports and time.monotonic() < deadline:
        time.sleep(0.05)
    drawn = loader._reports[forced["content_hash"]]
    independent = check_plan(expected).to_json()
    assert {(v["kind"], v["segment"]) for v in drawn["violations"]} == \
        {(v["kind"], v["segment"]) for v in independent["violations"]}
    seg = next(s for s in expected.segments if s.kind == "transition" and s.label == "lifted")
    assert any(v["kind"] == "transition_duration" and v["segment"] == seg.index for v in drawn["violations"])
    # A show within its limits has nothing to say.
    ok = client.post("/api/shows", json=show_doc("within limits")).json()
    r = client.post(f"/api/shows/{ok['id']}/playback")
    assert r.status_code == 200 and r.json()["problems"] == []


def test_simulated_playback_flies_it_too(client, forced):
    r = client.post(f"/api/shows/{forced['id']}/playback", json={"source": "simulated"})
    assert r.status_code == 200, r.text
    _names_the_field(r.json()["problems"])


def test_simulate_flies_it_as_designed_and_names_the_problem(client, forced):
    r = client.post(f"/api/shows/{forced['id']}/simulate", json={"engine": "numba"})
    assert r.status_code == 202, r.text
    events = read_events(client, r.json()["id"])
    assert events[-1][0] == "done", events[-1]
    result = client.get(f"/api/jobs/{r.json()['id']}").json()["result"]
    _names_the_field(result["problems"])
    assert result["flight"]["duration_s"] == pytest.approx(
        plan_show(parse_show(forced_doc()), enforce_limits=False).duration_s, abs=0.05)


@pytest.mark.parametrize("fmt", ["skyc", "skybrush-csv", "crazyswarm", "qgc-plan", "qgc-wpl", "waypoints-csv",
                                 "viser-html"])
def test_exports_refuse_it_naming_the_field(client, forced, fmt):
    params = {"origin": "47.0,8.0"} if fmt in ("skyc", "qgc-plan", "qgc-wpl") else {}  # others refuse an origin
    r = client.get(f"/api/shows/{forced['id']}/export/{fmt}", params=params)
    assert r.status_code == 422, (fmt, r.text)
    _names_the_field(r.json()["detail"])
    # The show file itself is the designer's work: it downloads as it is.
    assert client.get(f"/api/shows/{forced['id']}/export/show").status_code == 200


def test_montecarlo_refuses_it_naming_the_field(client, forced):
    """The Monte-Carlo job makes a safety report for the flight: like the flown exports, it refuses."""
    r = client.post(f"/api/shows/{forced['id']}/montecarlo", json={"runs": 2})
    assert r.status_code == 202, r.text
    events = read_events(client, r.json()["id"])
    assert events[-1][0] == "failed", events[-1]
    error = client.get(f"/api/jobs/{r.json()['id']}").json()["error"]
    assert error["status"] == 422
    _names_the_field(error["detail"])
