"""REST API, jobs: simulate (202), progress events, results, cache, sharing, failure, cancellation, 429."""

from __future__ import annotations

import json
import time
from concurrent.futures import CancelledError

import pytest
from fastapi.testclient import TestClient

from app.server import create_app
from app.settings import AppSettings
from app.tasks import TaskCancelled


def show_doc(name: str = "job test", *, hold_s: float = 1.0, transition_s: float | None = None) -> dict:
    """A safe 4-drone show (about 10 s plus ``hold_s``)."""
    formation = {"name": "square", "hold_s": hold_s, "points": [[0, 0, 6], [5, 0, 6], [0, 0, 11], [5, 0, 11]],
                 "color": "#00ff00"}
    if transition_s is not None:
        formation["transition_s"] = transition_s
    return {
        "format": "swarmshow/1", "name": name, "drones": 4,
        "home": {"grid": {"rows": 2, "cols": 2, "spacing_m": 4.5}},
        "settings": {"max_speed_z_mps": 5.0, "max_accel_mps2": 8.0, "takeoff_altitude_m": 3.0},
        "formations": [formation],
    }


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("data"), workers=2))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


def _show_id(client, doc) -> str:
    r = client.post("/api/shows", json=doc)
    assert r.status_code == 201, r.text
    return r.json()["id"]


def read_events(client, job_id: str) -> list[tuple[str, dict]]:
    """Every (event, data) of a job's event stream, until the server closes it."""
    events, name = [], None
    with client.stream("GET", f"/api/jobs/{job_id}/events") as r:
        assert r.status_code == 200 and r.headers["content-type"].startswith("text/event-stream")
        for line in r.iter_lines():
            if line.startswith("event: "):
                name = line[7:]
            elif line.startswith("data: "):
                events.append((name, json.loads(line[6:])))
    return events


def wait_for(client, job_id: str, predicate, timeout_s: float = 30.0) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job = client.get(f"/api/jobs/{job_id}").json()
        if predicate(job):
            return job
        time.sleep(0.05)
    raise AssertionError(f"job {job_id} never got there: {job}")


def test_simulate_runs_in_the_background_with_progress_events(client):
    sid = _show_id(client, show_doc("fly me", hold_s=2.0))
    r = client.post(f"/api/shows/{sid}/simulate", json={"engine": "numba", "output_hz": 25})
    assert r.status_code == 202, r.text
    job = r.json()
    assert r.headers["location"] == f"/api/jobs/{job['id']}"
    assert job["state"] in ("queued", "running") and job["show_id"] == sid and job["show_revision"] == 1
    events = read_events(client, job["id"])
    names = [e for e, _ in events]
    assert names[-1] == "done" and set(names[:-1]) == {"progress"}
    fractions = [d["progress"] for e, d in events if e == "progress"]
    assert fractions == sorted(fractions) and any(0 < f < 1 for f in fractions)
    final = events[-1][1]
    assert final["progress"] == 1.0 and final["result"]["flight"]["drones"] == 4
    assert final["result"]["plan"]["duration_s"] > 0
    done = client.get(f"/api/jobs/{job['id']}").json()
    assert done["state"] == "done" and done["error"] is None and done["result"] == final["result"]
    assert done["finished_at"] >= done["started_at"] >= done["created_at"]
    # The same show and options again: answered from the cache, not recomputed.
    r = client.post(f"/api/shows/{sid}/simulate", json={"engine": "numba", "output_hz": 25})
    again = r.json()
    assert r.status_code == 202 and again["id"] != job["id"]
    assert again["state"] == "done" and again["cached"] is True and again["result"] == done["result"]
    assert [e for e, _ in read_events(client, again["id"])] == ["done"]
    listed = client.get("/api/jobs").json()["items"]
    assert {job["id"], again["id"]} <= {j["id"] for j in listed}


def test_simulate_validates_options_and_show(client):
    sid = _show_id(client, show_doc("options"))
    r = client.post(f"/api/shows/{sid}/simulate", json={"engine": "warp"})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "engine"
    r = client.post(f"/api/shows/{sid}/simulate", json={"output_hz": 0})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "output_hz"
    r = client.post(f"/api/shows/{sid}/simulate", json={"bogus": 1})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "bogus"
    assert client.post("/api/shows/nope/simulate").status_code == 404


def test_failed_job_says_why(client):
    # An arrival pinned before the drones can get there cannot be planned at all (a transition forced too short
    # is flown as designed instead, see test_api_forced_short).
    doc = show_doc("too early")
    doc["formations"][0]["arrive_at_s"] = 0.5
    sid = _show_id(client, doc)
    job = client.post(f"/api/shows/{sid}/simulate").json()
    events = read_events(client, job["id"])
    assert events[-1][0] == "failed"
    error = client.get(f"/api/jobs/{job['id']}").json()["error"]
    assert error["status"] == 422 and "too early" in error["message"]
    assert error["detail"][0]["path"] == "formations[0].arrive_at_s"
    assert error["detail"][0]["loc"] == ["show", "formations", 0, "arrive_at_s"]


def test_unknown_job_is_404(client):
    for method, url in (("GET", "/api/jobs/nope"), ("DELETE", "/api/jobs/nope"), ("GET", "/api/jobs/nope/events")):
        r = client.request(method, url)
        assert r.status_code == 404 and "no job" in r.json()["detail"]


def _long_job(client, name: str, hold_s: float) -> dict:
    # The numpy engine at 1 kHz flies this for minutes: long enough to cancel mid-run.
    sid = _show_id(client, show_doc(name, hold_s=hold_s))
    r = client.post(f"/api/shows/{sid}/simulate", json={"engine": "numpy"})
    assert r.status_code == 202
    return r.json()


def test_cancel_a_running_job_stops_its_worker(client):
    jobs = client.app.state.jobs
    job = _long_job(client, "cancel running", 600.0)
    # Identical request while it runs: the same job, not a second computation.
    sid = job["show_id"]
    assert client.post(f"/api/shows/{sid}/simulate", json={"engine": "numpy"}).json()["id"] == job["id"]
    wait_for(client, job["id"], lambda j: j["state"] == "running" and j["progress"] > 0.05)
    future = jobs.get(job["id"]).future
    r = client.delete(f"/api/jobs/{job['id']}")
    assert r.status_code == 200 and r.json()["state"] == "cancelled"
    assert r.json()["error"]["message"] == "cancelled"
    assert [e for e, _ in read_events(client, job["id"])] == ["cancelled"]
    with pytest.raises(TaskCancelled):
        future.result(timeout=15)  # the worker saw the cancel event and stopped
    assert client.delete(f"/api/jobs/{job['id']}").json()["state"] == "cancelled"  # harmless twice
    # A cancelled run is not cached: asking again starts a new job.
    again = client.post(f"/api/shows/{sid}/simulate", json={"engine": "numpy"}).json()
    assert again["id"] != job["id"] and again["cached"] is False
    client.delete(f"/api/jobs/{again['id']}")


def test_cancel_a_queued_job_and_429_when_full(client):
    jobs = client.app.state.jobs
    a = _long_job(client, "busy a", 601.0)
    b = _long_job(client, "busy b", 602.0)
    c = _long_job(client, "queued c", 603.0)
    wait_for(client, a["id"], lambda j: j["state"] == "running")
    wait_for(client, b["id"], lambda j: j["state"] == "running")
    assert client.get(f"/api/jobs/{c['id']}").json()["state"] == "queued"
    future_c = jobs.get(c["id"]).future
    r = client.delete(f"/api/jobs/{c['id']}")
    assert r.status_code == 200 and r.json()["state"] == "cancelled"

    saved = jobs.max_pending
    jobs.max_pending = jobs.pending()
    try:
        sid = _show_id(client, show_doc("no room", hold_s=3.0))
        r = client.post(f"/api/shows/{sid}/simulate")
        assert r.status_code == 429 and r.headers["retry-after"] and "queued or running" in r.json()["detail"]
    finally:
        jobs.max_pending = saved

    for job in (a, b):
        assert client.delete(f"/api/jobs/{job['id']}").json()["state"] == "cancelled"
    try:
        future_c.result(timeout=15)
    except (CancelledError, TaskCancelled):
        pass
    else:
        raise AssertionError("the cancelled queued job ran")
    # The pool is free again: a short job completes.
    sid = _show_id(client, show_doc("after cancels", hold_s=0.5))
    job = client.post(f"/api/shows/{sid}/simulate").json()
    assert read_events(client, job["id"])[-1][0] == "done"


def test_cancelling_a_finished_job_is_409(client):
    sid = _show_id(client, show_doc("finished", hold_s=0.75))
    job = client.post(f"/api/shows/{sid}/simulate").json()
    assert read_events(client, job["id"])[-1][0] == "done"
    r = client.delete(f"/api/jobs/{job['id']}")
    assert r.status_code == 409 and r.json()["state"] == "done"
