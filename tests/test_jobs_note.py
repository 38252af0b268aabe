"""A job's ``note`` (what holds its progress up, e.g. "compiling the flight kernel...") goes when the job ends,
whatever the end: done, failed, cancelled, timed out, or interrupted by a server stop (its stored record).

Failed before: ``JobManager._finish`` left the note on a failed or cancelled job (a done one too, when no
progress came after the note), and an earlier server's interrupted job kept its note in the store.
"""

from __future__ import annotations

import json
import threading
import types

import pytest

from app.jobs import ErrorKind, Job, JobManager, JobState

NOTE = "compiling the flight kernel for this machine (first run, a few minutes of CPU; cached afterwards)"


def _manager_with(job: Job) -> tuple[types.SimpleNamespace, list[dict]]:
    """The parts of a JobManager that ``_finish`` and ``_cancel_job`` use; ``saved`` gets every record written."""
    saved: list[dict] = []
    mgr = types.SimpleNamespace(_lock=threading.Lock(), _inflight={}, _jobs={job.id: job},
                                _save=lambda j: saved.append(j.snapshot(with_result=False)))
    return mgr, saved


@pytest.mark.parametrize(("state", "error"), [
    (JobState.DONE, None),
    (JobState.FAILED, {"kind": ErrorKind.FAILED.value, "message": "boom"}),
    (JobState.FAILED, {"kind": ErrorKind.TIMEOUT.value, "message": "took too long"}),
    (JobState.CANCELLED, {"kind": ErrorKind.CANCELLED.value, "message": "cancelled"}),
])
def test_an_ended_job_has_no_note(state, error):
    job = Job(id="j1", kind="simulate", content_hash="h", options={}, state=JobState.RUNNING, progress=0.1,
              note=NOTE)
    mgr, saved = _manager_with(job)
    JobManager._finish(mgr, job, state, result={"ok": True} if state == JobState.DONE else None,  # type: ignore[arg-type]
                       error=error)
    assert job.state == state and job.note == ""
    assert saved and saved[-1]["note"] == "" and saved[-1]["state"] == state.value


def test_a_cancelled_job_has_no_note():
    job = Job(id="j2", kind="montecarlo", content_hash="h", options={}, state=JobState.RUNNING, note=NOTE)
    mgr, _ = _manager_with(job)
    mgr._finish = lambda *a, **k: JobManager._finish(mgr, *a, **k)  # type: ignore[arg-type]
    JobManager._cancel_job(mgr, job, reason="cancelled")  # type: ignore[arg-type]
    assert job.state == JobState.CANCELLED and job.note == ""


def test_an_interrupted_jobs_record_has_no_note():
    """A server that stopped mid-compile left the record ``running`` with its note; the next server marks it
    failed (``interrupted``), and the note goes with it."""
    record = Job(id="j3", kind="simulate", content_hash="h", options={}, state=JobState.RUNNING,
                 note=NOTE).snapshot(with_result=False)
    written: list[tuple[str, tuple[str, str]]] = []
    mgr = types.SimpleNamespace(store=types.SimpleNamespace(unfinished_jobs=lambda: [json.dumps(record)]),
                                _persist=lambda job_id, rec: written.append((job_id, rec)))
    JobManager._mark_interrupted(mgr)  # type: ignore[arg-type]
    (job_id, (text, state)), = written
    rec = json.loads(text)
    assert job_id == "j3" and state == "failed" and rec["error"]["kind"] == "interrupted"
    assert rec["note"] == ""
