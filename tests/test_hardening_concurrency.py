"""Concurrency: 20 clients edit the same show with revisions against a live server.

Every update is either acknowledged (200, a new revision) or refused (409, nothing
written). The history then holds exactly one revision per acknowledged update, each
with the content that client sent: no update was lost, none was applied twice, and
none overwrote another silently.
"""

from __future__ import annotations

import json
import threading

import httpx
import pytest

from tests.live_server import ServerProcess
from tests.test_api_live import SHOW

CLIENTS = 20


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    server = ServerProcess(tmp_path_factory.mktemp("concurrency"))
    server.start()
    try:
        yield server.base
    finally:
        server.stop()


def _edit(base: str, show_id: str, k: int, rounds: int, acked: list, refused: list, barrier) -> None:
    with httpx.Client(base_url=base, timeout=30) as http:
        barrier.wait()
        for i in range(rounds):
            current = http.get(f"/api/shows/{show_id}").json()
            doc = {**current["show"], "name": f"client {k} edit {i}"}
            r = http.put(f"/api/shows/{show_id}", json={"revision": current["revision"], "show": doc})
            if r.status_code == 200:
                body = r.json()
                assert body["revision"] == current["revision"] + 1 and body["name"] == doc["name"]
                acked.append((body["revision"], body["content_hash"], doc["name"]))
            else:
                assert r.status_code == 409, r.text
                assert r.json()["current_revision"] > current["revision"]
                refused.append((k, i))


@pytest.mark.parametrize("rounds", [10])
def test_20_clients_no_lost_update(live, rounds):
    show_id = httpx.post(f"{live}/api/shows", json=SHOW, timeout=30).json()["id"]
    acked: list = []
    refused: list = []
    barrier = threading.Barrier(CLIENTS)
    threads = [threading.Thread(target=_edit, args=(live, show_id, k, rounds, acked, refused, barrier))
               for k in range(CLIENTS)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    assert len(acked) + len(refused) == CLIENTS * rounds
    assert acked and refused  # they really raced

    history = httpx.get(f"{live}/api/shows/{show_id}/revisions", params={"limit": 1000}).json()
    by_rev = {item["revision"]: item for item in history["items"]}
    assert history["total"] == 1 + len(acked)  # one revision per acknowledged update, nothing else
    assert sorted(by_rev) == list(range(1, len(acked) + 2))
    for revision, content_hash, name in acked:
        assert by_rev[revision]["content_hash"] == content_hash and by_rev[revision]["name"] == name
    final = httpx.get(f"{live}/api/shows/{show_id}").json()
    assert final["revision"] == max(by_rev) and final["content_hash"] == by_rev[final["revision"]]["content_hash"]
    first = httpx.get(f"{live}/api/shows/{show_id}/revisions/1")
    assert first.status_code == 200 and first.json()["name"] == SHOW["name"]


def test_revision_history_api(live):
    created = httpx.post(f"{live}/api/shows", json=SHOW).json()
    sid = created["id"]
    r = httpx.put(f"{live}/api/shows/{sid}", json={"revision": 1, "show": {**SHOW, "name": "second"}})
    assert r.status_code == 200
    stale = httpx.put(f"{live}/api/shows/{sid}", json={"revision": 1, "show": {**SHOW, "name": "lost?"}})
    assert stale.status_code == 409
    items = httpx.get(f"{live}/api/shows/{sid}/revisions").json()["items"]
    assert [(i["revision"], i["name"]) for i in items] == [(2, "second"), (1, SHOW["name"])]
    assert all(i["has_show"] for i in items)
    assert httpx.get(f"{live}/api/shows/{sid}/revisions/3").status_code == 404
    assert httpx.get(f"{live}/api/shows/nope/revisions").status_code == 404
    assert httpx.delete(f"{live}/api/shows/{sid}").status_code == 204
    assert httpx.get(f"{live}/api/shows/{sid}/revisions").status_code == 404


def test_migration_gives_existing_shows_their_first_revision(tmp_path):
    """A store written before the revision history (schema 2) gets one history row per show on opening."""
    import sqlite3

    from app.store import MIGRATIONS, SCHEMA_VERSION, ShowStore
    from formations import parse_show

    path = tmp_path / "old.sqlite3"
    db = sqlite3.connect(path, isolation_level=None)
    db.execute("CREATE TABLE schema_version (version INTEGER NOT NULL)")
    db.execute("INSERT INTO schema_version VALUES (2)")
    for step in MIGRATIONS[:2]:
        db.executescript(step)
    show = parse_show(SHOW)
    db.execute("INSERT INTO shows VALUES ('old1', 'live', 3, ?, ?, 4, 1, 't0', 't1')",
               (json.dumps(SHOW), show.content_hash()))
    db.close()
    store = ShowStore(path)
    try:
        assert store.schema_version == SCHEMA_VERSION
        items, total = store.revisions("old1")
        assert total == 1 and items[0].revision == 3 and items[0].content_hash == show.content_hash()
        updated = store.update("old1", show.model_copy(update={"name": "new"}), expected_revision=3)
        assert updated.revision == 4 and store.revisions("old1")[1] == 2
    finally:
        store.close()
