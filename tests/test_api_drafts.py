"""Drafts (issue 17): a half-finished show is stored with its problems (``?draft=true``), listed as a
draft, refused by check / simulate / export / playback with a 422 naming what is wrong in plain
words, and made a show again by a valid save. Without the flag the API stays strict. The store's
schema step that adds drafts keeps every stored row."""

from __future__ import annotations

import json
import sqlite3

import pytest
from fastapi.testclient import TestClient

from app.server import create_app
from app.settings import AppSettings
from app.store import MIGRATIONS, SCHEMA_VERSION, ShowData, ShowStore
from formations import ShowValidationError, parse_show, plain_path
from tests.conftest import app_client
from tests.test_api_shows import show_doc, stored


def _too_close(doc: dict) -> dict:
    """The show with its formation's second point 1 m from the first (min distance 3 m)."""
    bad = json.loads(json.dumps(doc))
    bad["formations"][0]["points"][1] = [1, 0, 6]
    return bad


client = app_client("drafts", workers=1)


def _strict_problems(doc: dict) -> list[dict]:
    """What the show file's own validator says (the independent reference)."""
    with pytest.raises(ShowValidationError) as exc:
        parse_show(doc)
    return exc.value.errors


def test_strict_save_still_refuses_and_a_draft_save_keeps_the_work(client):
    good = show_doc("draft api")
    created = client.post("/api/shows", json=good).json()
    sid = created["id"]
    assert created["draft"] is False and created["problems"] == []
    bad = _too_close(good)
    # Strict (the default): refused, nothing stored.
    r = client.put(f"/api/shows/{sid}", json={"revision": 1, "show": bad})
    assert r.status_code == 422
    assert client.get(f"/api/shows/{sid}").json()["revision"] == 1
    # Draft: stored exactly as sent, with the validator's problems.
    r = client.put(f"/api/shows/{sid}", params={"draft": "true"}, json={"revision": 1, "show": bad})
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["revision"] == 2 and body["draft"] is True and body["show"] == bad
    expected = _strict_problems(bad)
    assert [(p["path"], p["msg"]) for p in body["problems"]] == [(e["path"], e["msg"]) for e in expected]
    assert body["problems"][0]["where"] == 'formation 1 "square", points'
    # Read back, listed and in the history as a draft.
    got = client.get(f"/api/shows/{sid}").json()
    assert got["draft"] is True and got["show"] == bad and got["problems"] == body["problems"]
    listed = next(s for s in client.get("/api/shows").json()["items"] if s["id"] == sid)
    assert listed["draft"] is True and listed["problems"] == body["problems"]
    revs = client.get(f"/api/shows/{sid}/revisions").json()["items"]
    assert [(r["revision"], r["draft"]) for r in revs] == [(2, True), (1, False)]
    assert client.get(f"/api/shows/{sid}/revisions/2").json() == bad

    # Check, simulate, export and playback refuse the draft, naming the problem in plain words.
    for method, url in (("POST", f"/api/shows/{sid}/check"), ("POST", f"/api/shows/{sid}/simulate"),
                        ("GET", f"/api/shows/{sid}/export/skybrush-csv")):
        r = client.request(method, url)
        assert r.status_code == 422, (url, r.text)
        err = r.json()
        assert err["draft"] is True
        assert err["detail"][0]["path"] == expected[0]["path"]
        assert err["detail"][0]["loc"] == ["show", *expected[0]["loc"]]
        assert 'formation 1 "square", points: points 0 and 1 are 1.000 m apart' in err["message"]
        assert "draft api" in err["message"] and "draft" in err["message"]
    # The show file itself still downloads (it is the user's work).
    r = client.get(f"/api/shows/{sid}/export/show")
    assert r.status_code == 200 and json.loads(r.text) == bad

    # A valid save (with the flag or without) makes it a show again; check then works.
    r = client.put(f"/api/shows/{sid}", params={"draft": "true"}, json={"revision": 2, "show": good})
    assert r.status_code == 200 and r.json()["draft"] is False and r.json()["problems"] == []
    assert r.json()["show"] == stored(good)
    r = client.post(f"/api/shows/{sid}/check")
    assert r.status_code == 200, r.text


def test_create_as_draft_and_what_a_draft_cannot_be(client):
    doc = show_doc("half")
    del doc["home"]
    doc["formations"][0]["hold_s"] = -1
    r = client.post("/api/shows", params={"draft": "1"}, json=doc)
    assert r.status_code == 201, r.text
    body = r.json()
    assert body["draft"] is True and body["name"] == "half" and body["drones"] == 4 and body["formations"] == 1
    assert {p["path"] for p in body["problems"]} == {e["path"] for e in _strict_problems(doc)}
    wheres = {p["where"] for p in body["problems"]}
    assert 'formation 1 "square", hold (s)' in wheres and "home" in wheres
    # Not a JSON object, or not JSON at all: nothing to keep, even as a draft.
    for content in (b"[1, 2]", b"{not json"):
        r = client.post("/api/shows", params={"draft": "true"}, content=content,
                        headers={"content-type": "application/json"})
        assert r.status_code == 422, r.text
    # Strict create of the same document is refused.
    assert client.post("/api/shows", json=doc).status_code == 422


def test_a_large_draft_is_validated_in_a_worker_too(client):
    """Over the inline limit the validation runs in a worker process; the draft comes back the same."""
    from app.api.shows import INLINE_PARSE_BYTES

    n = 10_000
    doc = show_doc("big draft")
    doc["drones"] = n
    doc["home"] = {"grid": {"rows": 100, "cols": 100, "spacing_m": 4.5}}
    pts = [[(i % 25) * 4.0 + 0.123456, (i // 25 % 20) * 4.0 + 0.654321, 10 + (i // 500) * 4.0 + 0.111111]
           for i in range(n)]
    pts[7] = [pts[6][0] + 0.5, 0, pts[6][2]]
    doc["formations"][0]["points"] = pts
    text = json.dumps(doc)
    assert len(text) > INLINE_PARSE_BYTES
    r = client.post("/api/shows", params={"draft": "true"}, content=text,
                    headers={"content-type": "application/json"})
    assert r.status_code == 201, r.text
    assert r.json()["draft"] is True
    assert [p["path"] for p in r.json()["problems"]] == [e["path"] for e in _strict_problems(doc)]


@pytest.mark.parametrize(("path", "words"), [
    ("formations[1].points[5][2]", 'formation 2 "B", point 6, z'),
    ("formations[0].hold_s", 'formation 1 "A", hold (s)'),
    ("settings.min_distance_m", "settings, min distance (m)"),
    ("settings.max_accel_mps2", "settings, max accel (m/s²)"),
    ("settings.geo.heading_deg", "settings, geo, heading (°)"),
    ("home.grid.rows", "home, grid, rows"),
    ("formations[7].colors[3]", "formation 8, colour 4"),
    ("lights.effects[0].end_s", "light effect 1, end (s)"),
    ("", "the show"),
])
def test_plain_path(path, words):
    doc = {"formations": [{"name": "A"}, {"name": "B"}]}
    assert plain_path(path, doc) == words


def test_schema_step_for_drafts_keeps_every_stored_row(tmp_path):
    """A database at the previous version (a show, two revisions, a result, a job) is migrated to
    the draft schema with all of it intact, and then stores a draft beside it."""
    path = tmp_path / "v4.sqlite3"
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE schema_version (version INTEGER NOT NULL)")
    # Version 4: the last schema before drafts (migration 5); later steps (6: audio) follow it.
    db.execute("INSERT INTO schema_version VALUES (4)")
    for step in MIGRATIONS[:4]:
        db.executescript(step)
    show = parse_show(show_doc("old"))
    data = ShowData.of(show)
    db.execute("INSERT INTO shows VALUES ('old1', 'old', 2, ?, ?, 4, 1, 't0', 't1')", (data.text, data.content_hash))
    for rev in (1, 2):
        db.execute("INSERT INTO revisions VALUES ('old1', ?, 'old', ?, 4, 1, ?, 't')",
                   (rev, data.content_hash, data.text))
    db.execute("INSERT INTO results VALUES ('k', 'check', 'h', '{}', 't')")
    db.execute("INSERT INTO jobs VALUES ('j', '{}', 'done', 't')")
    db.commit()
    before = {t: db.execute(f"SELECT * FROM {t} ORDER BY 1").fetchall() for t in ("shows", "revisions", "results",
                                                                                   "jobs")}
    db.close()

    s = ShowStore(path)
    try:
        assert s.schema_version == SCHEMA_VERSION
        rec = s.get("old1")
        assert rec.json == data.text and rec.revision == 2 and not rec.draft
        revs, total = s.revisions("old1")
        assert total == 2 and not any(r.draft for r in revs)
        assert s.get_result("k") == "{}" and s.get_job("j") == "{}"
        bad = _too_close(show_doc("old"))
        rec = s.update("old1", ShowData.draft(bad, _strict_problems(bad)), expected_revision=2)
        assert rec.draft and rec.revision == 3 and json.loads(rec.json) == bad
    finally:
        s.close()
    db = sqlite3.connect(path)
    try:
        # Every old row is still there, column for column (the new column comes last, NULL = valid).
        for table in ("results", "jobs"):
            assert db.execute(f"SELECT * FROM {table} ORDER BY 1").fetchall() == before[table]
        revs = db.execute("SELECT * FROM revisions WHERE revision <= 2 ORDER BY 2").fetchall()
        assert [r[:-1] for r in revs] == before["revisions"] and all(r[-1] is None for r in revs)
    finally:
        db.close()


def test_a_draft_never_shares_a_hash_with_a_valid_show():
    doc = show_doc("same")
    valid = ShowData.of(parse_show(doc))
    as_draft = ShowData.draft(doc, [{"loc": [], "path": "", "msg": "x"}])
    assert as_draft.content_hash != valid.content_hash
    # Key order does not change a draft's hash; content does.
    reordered = dict(reversed(list(doc.items())))
    assert ShowData.draft(reordered, [{"msg": "x"}]).content_hash == as_draft.content_hash
    assert ShowData.draft({**doc, "name": "other"}, [{"msg": "x"}]).content_hash != as_draft.content_hash


def test_the_3d_viewer_refuses_a_draft_and_does_not_list_it(tmp_path):
    app = create_app(AppSettings(data_dir=tmp_path, workers=1))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        good = c.post("/api/shows", json=show_doc("listed")).json()
        draft = c.post("/api/shows", params={"draft": "true"}, json=_too_close(show_doc("unfinished"))).json()
        assert draft["draft"] is True
        r = c.post(f"/api/shows/{draft['id']}/playback", json={"source": "planned"})
        assert r.status_code == 422 and r.json()["draft"] is True
        assert "cannot be shown in the 3D viewer" in r.json()["message"]
        assert 'formation 1 "square", points' in r.json()["message"]
        assert set(app.state.viewer_loader.catalog()) == {good["id"]}
        assert c.post(f"/api/shows/{good['id']}/playback", json={"source": "planned"}).status_code == 200


def test_a_draft_keeps_a_bounded_list_of_problems():
    """Thousands of bad values make thousands of problems: the draft keeps the first ones and counts the rest."""
    from app.store import MAX_DRAFT_PROBLEMS

    doc = show_doc("many")
    doc["formations"][0]["points"] = [["x", "y", "z"]] * 400
    errors = _strict_problems(doc)
    assert len(errors) > MAX_DRAFT_PROBLEMS + 1
    kept = ShowData.draft(doc, errors).problems
    assert kept is not None and len(kept) == MAX_DRAFT_PROBLEMS + 1
    assert [p["path"] for p in kept[:-1]] == [e["path"] for e in errors[:MAX_DRAFT_PROBLEMS]]
    assert kept[-1]["msg"] == f"and {len(errors) - MAX_DRAFT_PROBLEMS} more problems"
