"""The SQLite show store: migrations, durability settings, revision checks, atomic writes."""

from __future__ import annotations

import sqlite3
import threading

import pytest

from app.store import MIGRATIONS, SCHEMA_VERSION, RevisionConflict, ShowNotFound, ShowStore, StoreError
from formations import parse_show


def _show(name: str = "store test", hold_s: float = 2.0):
    return parse_show({
        "format": "swarmshow/1", "name": name, "drones": 2,
        "home": {"grid": {"rows": 1, "cols": 2, "spacing_m": 3.0}},
        "formations": [{"name": "pair", "hold_s": hold_s, "points": [[0, 0, 20], [5, 0, 20]], "color": "#ff0000"}],
    })


@pytest.fixture
def store(tmp_path):
    s = ShowStore(tmp_path / "shows.sqlite3")
    yield s
    s.close()


def test_new_store_is_durable_wal_at_the_current_schema(store):
    assert store.schema_version == SCHEMA_VERSION == len(MIGRATIONS)
    assert store._db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert store._db.execute("PRAGMA synchronous").fetchone()[0] == 2  # FULL


def test_old_database_is_migrated_keeping_its_shows(tmp_path):
    path = tmp_path / "old.sqlite3"
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE schema_version (version INTEGER NOT NULL)")
    db.execute("INSERT INTO schema_version VALUES (1)")
    db.executescript(MIGRATIONS[0])
    db.execute(
        "INSERT INTO shows VALUES ('abc', 'old', 3, '{}', 'h', 2, 1, '2026-01-01T00:00:00Z', '2026-01-01T00:00:00Z')"
    )
    db.commit()
    db.close()
    s = ShowStore(path)
    try:
        assert s.schema_version == SCHEMA_VERSION
        assert s.get("abc").revision == 3
        s.put_result("k", kind="check", content_hash="h", text="{}")
        assert s.get_result("k") == "{}"
    finally:
        s.close()


def test_database_from_a_newer_version_is_refused_untouched(tmp_path):
    path = tmp_path / "new.sqlite3"
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE schema_version (version INTEGER NOT NULL)")
    db.execute("INSERT INTO schema_version VALUES (99)")
    db.commit()
    db.close()
    with pytest.raises(StoreError, match="newer"):
        ShowStore(path)
    db = sqlite3.connect(path)
    assert db.execute("SELECT version FROM schema_version").fetchone()[0] == 99
    db.close()


def test_create_get_list_update_delete(store):
    a = store.create(_show("a"))
    b = store.create(_show("b", hold_s=3.0))
    assert a.revision == 1 and a.json and store.get(a.id).json == a.json
    page, total = store.list(limit=1, offset=0)
    assert total == 2 and [r.id for r in page] == [b.id]  # most recently updated first
    assert page[0].json is None
    updated = store.update(a.id, _show("a2"), expected_revision=1)
    assert updated.revision == 2 and updated.name == "a2"
    assert store.update(a.id, _show("a2"), expected_revision=2).revision == 2  # same content: no new revision
    assert store.find_by_hash(_show("a2").content_hash()).id == a.id
    store.delete(a.id, expected_revision=2)
    with pytest.raises(ShowNotFound):
        store.get(a.id)
    with pytest.raises(ShowNotFound):
        store.delete(a.id)


def test_stale_revision_is_a_conflict_and_changes_nothing(store):
    rec = store.create(_show("a"))
    store.update(rec.id, _show("b"), expected_revision=1)
    with pytest.raises(RevisionConflict) as info:
        store.update(rec.id, _show("c"), expected_revision=1)
    assert info.value.current_revision == 2
    assert store.get(rec.id).name == "b"
    with pytest.raises(RevisionConflict):
        store.delete(rec.id, expected_revision=1)
    assert store.get(rec.id).revision == 2


def test_concurrent_writers_of_one_revision_exactly_one_wins(store):
    rec = store.create(_show("start"))
    outcomes: list[str] = []

    def write(k: int) -> None:
        try:
            store.update(rec.id, _show(f"writer {k}"), expected_revision=1)
            outcomes.append("ok")
        except RevisionConflict:
            outcomes.append("conflict")

    threads = [threading.Thread(target=write, args=(k,)) for k in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sorted(outcomes) == ["conflict"] * 7 + ["ok"]
    assert store.get(rec.id).revision == 2


def test_failed_write_leaves_nothing_behind(store):
    rec = store.create(_show("a"))
    with pytest.raises(sqlite3.IntegrityError):
        store.create(_show("b"), show_id=rec.id)  # duplicate id: the transaction rolls back
    assert store.list()[1] == 1 and store.get(rec.id).name == "a"
    store.create(_show("c"))  # and the store still writes afterwards
    assert store.list()[1] == 2


def test_result_cache_keeps_the_most_recent(store):
    for k in range(5):
        store.put_result(f"k{k}", kind="check", content_hash="h", text=str(k), keep=3)
    assert [store.get_result(f"k{k}") for k in range(5)] == [None, None, "2", "3", "4"]
