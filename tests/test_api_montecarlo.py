"""REST API, Monte-Carlo: the job (202, SSE progress, result), its bounds (422 naming the field, 413 on the
work) and the safety report (HTML parsed, PDF read back with pypdf)."""

from __future__ import annotations

import io
from html.parser import HTMLParser

import pytest

from app.api.models import MAX_MONTECARLO_RUNS
from tests.conftest import app_client
from tests.test_api_jobs import _show_id, read_events, show_doc, wait_for

client = app_client("data", workers=2)


@pytest.fixture(scope="module")
def finished(client):
    """A finished 3-run Monte-Carlo job of a small show: (show id, job)."""
    sid = _show_id(client, show_doc("mc api", hold_s=1.0))
    r = client.post(f"/api/shows/{sid}/montecarlo", json={"runs": 3, "preset": "gusty-rtk", "seed0": 4,
                                                          "confidence": 0.95})
    assert r.status_code == 202, r.text
    job = r.json()
    assert r.headers["location"] == f"/api/jobs/{job['id']}" and job["kind"] == "montecarlo"
    events = read_events(client, job["id"])
    assert events[-1][0] == "done", events[-1]
    fractions = [d["progress"] for e, d in events if e == "progress"]
    assert fractions == sorted(fractions)
    return sid, events[-1][1]


def test_api_presets_are_the_simulations():
    from typing import get_args

    from app.api.models import PresetName
    from sim.flight import PRESETS

    assert get_args(PresetName) == PRESETS


def test_job_result_holds_the_margin(finished):
    _, job = finished
    mc = job["result"]["montecarlo"]
    assert mc["runs"] == 3 and [r["seed"] for r in mc["run_list"]] == [4, 5, 6]
    assert mc["preset"] == "gusty-rtk" and mc["confidence"] == 0.95 and mc["drones"] == 4
    assert len(mc["segments"]) == len(job["result"]["plan"]["segments"])
    p = mc["show_min"]["p_below_min_distance"]
    assert p["runs"] == 3 and 0.0 <= p["ci_low"] <= p["ci_high"] <= 1.0
    assert mc["show_min"]["flown_min_m"]["quantiles"]["0"] == pytest.approx(
        min(r["min_distance_m"] for r in mc["run_list"]))


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"runs": MAX_MONTECARLO_RUNS + 1}, "runs"),
        ({"runs": 0}, "runs"),
        ({"confidence": 1.0}, "confidence"),
        ({"collision_distance_m": -1}, "collision_distance_m"),
        ({"preset": "windy"}, "preset"),
        ({"seed0": -1}, "seed0"),
        ({"bogus": 1}, "bogus"),
    ],
)
def test_bad_options_get_422_naming_the_field(client, body, field):
    sid = _show_id(client, show_doc("mc bounds"))
    r = client.post(f"/api/shows/{sid}/montecarlo", json=body)
    assert r.status_code == 422, r.text
    assert any(field in [str(x) for x in d["loc"]] for d in r.json()["detail"]), r.json()


def test_too_much_work_fails_the_job_naming_runs(client, monkeypatch):
    """Drones x seconds x runs over the limit: refused before flying, naming ``runs`` and how many fit."""
    import json

    from app import tasks

    sid = _show_id(client, show_doc("mc work"))
    plan = client.post(f"/api/shows/{sid}/check").json()["plan"]
    per_run = plan["drones"] * plan["duration_s"]
    assert per_run * MAX_MONTECARLO_RUNS < tasks.MAX_MONTECARLO_DRONE_S  # small shows always fit
    # In this process (the task called directly), a limit of 2.5 runs' work: 3 runs are refused.
    monkeypatch.setattr(tasks, "MAX_MONTECARLO_DRONE_S", per_run * 2.5)
    with pytest.raises(tasks.TaskFailure) as exc:
        tasks.montecarlo_task(json.dumps(show_doc("mc work")), {"runs": 3, "preset": "ideal"}, "j", _Queue(),
                              _Never())
    assert exc.value.kind == tasks.FailureKind.TOO_LARGE
    assert exc.value.detail[0]["loc"] == ["body", "runs"] and "use runs <= 2" in exc.value.detail[0]["msg"]


class _Queue:
    def put(self, _item):
        pass


class _Never:
    def is_set(self):
        return False


class _Text(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tags: list[str] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)

    def handle_data(self, data):
        self.text.append(data)


def test_safety_report_html_and_pdf(client, finished):
    _, job = finished
    r = client.get(f"/api/jobs/{job['id']}/report.html")
    assert r.status_code == 200 and r.headers["content-type"].startswith("text/html")
    page = _Text()
    page.feed(r.text)
    assert page.tags.count("svg") == 4 and "script" not in page.tags
    assert "Safety report: mc api" in "".join(page.text)
    r = client.get(f"/api/jobs/{job['id']}/report.pdf")
    assert r.status_code == 200 and r.headers["content-type"] == "application/pdf"
    assert r.headers["content-disposition"].startswith("attachment")
    from pypdf import PdfReader

    reader = PdfReader(io.BytesIO(r.content))
    assert len(reader.pages) >= 7 and "Worst pairs" in "".join(p.extract_text() for p in reader.pages)
    assert client.get(f"/api/jobs/{job['id']}/report.html?download=true").headers[
        "content-disposition"].startswith("attachment")


def test_report_of_other_jobs_and_unknown_formats(client):
    sid = _show_id(client, show_doc("mc other"))
    sim = client.post(f"/api/shows/{sid}/simulate").json()
    wait_for(client, sim["id"], lambda j: j["state"] == "done", timeout_s=120)
    assert client.get(f"/api/jobs/{sim['id']}/report.html").status_code == 404
    assert client.get("/api/jobs/nope/report.html").status_code == 404
    assert client.get(f"/api/jobs/{sim['id']}/report.docx").status_code == 422


def test_playback_of_a_chosen_run(client, finished):
    """The viewer's simulated source plays run k of the job: its flown minimum is that run's."""
    import numpy as np
    from scipy.spatial.distance import pdist

    sid, job = finished
    mc = job["result"]["montecarlo"]
    flown = {}
    for k in (2, 0):
        r = client.post(f"/api/shows/{sid}/playback", json={"source": "simulated", "job_id": job["id"], "run": k})
        assert r.status_code == 200, r.text
        assert r.json()["source"] == "simulated"
        viewer = client.app.state.viewer
        flight = viewer._shows[viewer.current].flight
        pos = np.asarray(flight.positions_m, dtype=np.float64)
        brute = min(pdist(p).min() for p in pos)
        assert brute == pytest.approx(mc["run_list"][k]["min_distance_m"], rel=1e-9)
        flown[k] = pos
    assert not np.array_equal(flown[0], flown[2])  # different seeds, different flights
    again = client.post(f"/api/shows/{sid}/playback", json={"source": "simulated", "job_id": job["id"], "run": 0})
    assert again.json()["cached"] is True


def test_playback_run_errors_name_the_field(client, finished):
    sid, job = finished
    url = f"/api/shows/{sid}/playback"
    r = client.post(url, json={"source": "simulated", "job_id": job["id"], "run": 3})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "run"]
    r = client.post(url, json={"source": "simulated", "job_id": job["id"], "run": -1})
    assert r.status_code == 422 and "run" in r.json()["detail"][0]["loc"]
    r = client.post(url, json={"source": "simulated", "run": 1})
    # QA: loc said job_id while path said run; both name the missing field.
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "job_id"]
    assert r.json()["detail"][0]["path"] == "job_id"
    r = client.post(url, json={"source": "simulated", "job_id": job["id"]})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "run"
    r = client.post(url, json={"source": "planned", "job_id": job["id"], "run": 1})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "source"
    assert client.post(url, json={"source": "simulated", "job_id": "nope", "run": 0}).status_code == 404
    other = _show_id(client, show_doc("mc elsewhere"))
    r = client.post(f"/api/shows/{other}/playback", json={"source": "simulated", "job_id": job["id"], "run": 0})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "job_id"]
