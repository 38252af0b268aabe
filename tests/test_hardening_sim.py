"""Simulation robustness: saturated rotors, absurd gains, a NaN in a reference; job timeout and a full queue.

The run finishes, its result names the drones that went wrong, and the server keeps
answering. Faults the API cannot express (gains, a poisoned reference) are injected by
job tasks in ``tests.hardening_tasks`` run through the server's own job manager.
"""

from __future__ import annotations

import time

import pytest
from fastapi.testclient import TestClient

from app.server import create_app
from app.settings import AppSettings
from tests import hardening_tasks
from tests.test_api_live import SHOW


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("sim"), workers=2, viewer=False, job_timeout_s=4))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


def _wait(client, job_id: str, timeout_s: float = 120.0) -> dict:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        job = client.get(f"/api/jobs/{job_id}").json()
        if job["state"] in ("done", "failed", "cancelled"):
            return job
        time.sleep(0.1)
    raise AssertionError(f"job {job_id} did not finish: {job}")


def _healthy(client) -> None:
    assert client.get("/api/health").json()["status"] == "ok"


def _submit(client, fn, name: str) -> dict:
    created = client.post("/api/shows", json={**SHOW, "name": name}).json()
    job = client.app.state.jobs.submit(
        name, fn, show_text=_show_text(client, created["id"]),
        content_hash=created["content_hash"], options={}, show_id=created["id"], show_revision=1)
    return job.snapshot()


def _show_text(client, show_id: str) -> str:
    return client.app.state.store.get(show_id).json


def test_saturated_rotors_through_the_api(client):
    """A show whose limits ask for 40 m/s² and 40 m/s: far beyond what the quadrotor's rotors give."""
    doc = {**SHOW, "name": "too fast",
           "settings": {"max_speed_xy_mps": 40.0, "max_speed_z_mps": 40.0, "max_accel_mps2": 40.0,
                        "max_jerk_mps3": 1000.0, "takeoff_altitude_m": 3.0},
           "formations": [SHOW["formations"][0],
                          {"name": "far", "hold_s": 1.0, "color": "#00ff00",
                           "points": [[80, 0, 60], [85, 0, 60], [80, 0, 65], [85, 0, 65]]}]}
    sid = client.post("/api/shows", json=doc).json()["id"]
    r = client.post(f"/api/shows/{sid}/simulate", json={"engine": "numba"})
    assert r.status_code == 202
    job = _wait(client, r.json()["id"])
    assert job["state"] == "done", job
    flight = job["result"]["flight"]
    assert flight["ok"] is False  # not flown as planned
    named = {d["drone"] for d in flight["worst_drones"]} | {d["drone"] for d in flight["diverged"]}
    assert named and named <= set(range(4))
    assert flight["tracking_max_m"] is None or flight["tracking_max_m"] > 0.5
    _healthy(client)


def test_absurd_gains_finish_and_name_the_drones(client):
    job = _wait(client, _submit(client, hardening_tasks.absurd_gains_task, "absurd gains")["id"])
    assert job["state"] == "done", job
    flight = job["result"]["flight"]
    assert flight["ok"] is False and flight["diverged"], flight
    assert {d["drone"] for d in flight["diverged"]} <= set(range(4))
    assert all(d["reason"] for d in flight["diverged"])
    _healthy(client)


def test_nan_in_a_reference_names_that_drone(client):
    job = _wait(client, _submit(client, hardening_tasks.nan_reference_task, "nan reference")["id"])
    assert job["state"] == "done", job
    flight = job["result"]["flight"]
    assert flight["ok"] is False
    assert 2 in {d["drone"] for d in flight["diverged"]}, flight["diverged"]
    _healthy(client)


def test_a_hung_job_times_out_and_the_pool_recovers(client):
    job = _submit(client, hardening_tasks.hung_task, "hung")
    t0 = time.monotonic()
    done = _wait(client, job["id"], timeout_s=60)
    assert done["state"] == "failed" and done["error"]["status"] == 504 and "timed out" in done["error"]["message"]
    assert time.monotonic() - t0 < 30
    _healthy(client)
    # The worker that ignored its cancel event was ended; new jobs still run.
    sid = client.post("/api/shows", json={**SHOW, "name": "after the hang"}).json()["id"]
    after = _wait(client, client.post(f"/api/shows/{sid}/simulate", json={"engine": "numba"}).json()["id"])
    assert after["state"] == "done", after


def test_full_queue_answers_429_with_retry_after(client):
    jobs = client.app.state.jobs
    saved = jobs.max_pending
    jobs.max_pending = 0
    try:
        sid = client.post("/api/shows", json={**SHOW, "name": "no room"}).json()["id"]
        r = client.post(f"/api/shows/{sid}/simulate", json={"engine": "numpy"})
        assert r.status_code == 429 and int(r.headers["retry-after"]) > 0
        assert "queued or running" in r.json()["detail"]
    finally:
        jobs.max_pending = saved
