"""The show store: SQLite (standard library) in the data directory.

Durability: WAL journal with ``synchronous=FULL``, so a commit that returned is
on disk even after a power cut. Every change is one transaction, and shows are
validated before any write, so a failed request never leaves half a change.
Updates are revision-checked (optimistic concurrency): a writer that read
revision r may only replace revision r; anything else is a
:class:`RevisionConflict`, never a silent overwrite.

The schema is versioned (table ``schema_version``); :data:`MIGRATIONS` lists the
steps from an empty file to the current version and each runs once, in its own
transaction. A database written by a newer swarmshow is refused, not altered.
"""

from __future__ import annotations

import builtins
import secrets
import sqlite3
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from formations import ShowFile

#: Schema steps; entry k brings the database from version k to k + 1.
MIGRATIONS: tuple[str, ...] = (
    # 1: shows, with the fields the list view needs kept beside the JSON.
    """
    CREATE TABLE shows (
        id TEXT PRIMARY KEY,
        name TEXT NOT NULL,
        revision INTEGER NOT NULL CHECK (revision >= 1),
        json TEXT NOT NULL,
        content_hash TEXT NOT NULL,
        drones INTEGER NOT NULL,
        formations INTEGER NOT NULL,
        created_at TEXT NOT NULL,
        updated_at TEXT NOT NULL
    );
    CREATE INDEX shows_by_updated ON shows (updated_at DESC, id);
    CREATE INDEX shows_by_hash ON shows (content_hash);
    """,
    # 2: results cached by show content hash, so an unchanged show is not recomputed after a restart.
    """
    CREATE TABLE results (
        key TEXT PRIMARY KEY,
        kind TEXT NOT NULL,
        content_hash TEXT NOT NULL,
        json TEXT NOT NULL,
        created_at TEXT NOT NULL
    );
    CREATE INDEX results_by_created ON results (created_at);
    """,
    # 3: every revision of every show (written in the same transaction as the show), so that a
    #    concurrent editor can see what happened and no acknowledged change is ever lost unseen.
    #    Old revisions keep their metadata; their text is dropped beyond ``keep_revisions``.
    """
    CREATE TABLE revisions (
        show_id TEXT NOT NULL,
        revision INTEGER NOT NULL CHECK (revision >= 1),
        name TEXT NOT NULL,
        content_hash TEXT NOT NULL,
        drones INTEGER NOT NULL,
        formations INTEGER NOT NULL,
        json TEXT,
        created_at TEXT NOT NULL,
        PRIMARY KEY (show_id, revision)
    ) WITHOUT ROWID;
    INSERT INTO revisions (show_id, revision, name, content_hash, drones, formations, json, created_at)
        SELECT id, revision, name, content_hash, drones, formations, json, updated_at FROM shows;
    """,
    # 4: job records (state, progress, error), so that a job's id still answers after a crash or a
    #    restart: the jobs that were queued or running are then marked interrupted.
    """
    CREATE TABLE jobs (
        id TEXT PRIMARY KEY,
        record TEXT NOT NULL,
        state TEXT NOT NULL,
        updated_at TEXT NOT NULL
    );
    CREATE INDEX jobs_by_updated ON jobs (updated_at);
    CREATE INDEX jobs_by_state ON jobs (state);
    """,
    # 5: drafts. A show (and a revision) may be stored half-finished: ``problems`` holds the JSON list
    #    of what is wrong with it (NULL: a valid show). Adding nullable columns keeps every stored row.
    """
    ALTER TABLE shows ADD COLUMN problems TEXT;
    ALTER TABLE revisions ADD COLUMN problems TEXT
    """,
    # 6: a show's music (issue 18): the uploaded file's bytes (streamed with HTTP ranges through
    #    SQLite's incremental blob I/O) and its analysis (waveform peaks, beats) as JSON. A new table:
    #    nothing existing is rewritten.
    """
    CREATE TABLE audio (
        show_id TEXT PRIMARY KEY,
        filename TEXT NOT NULL,
        media_type TEXT NOT NULL,
        size INTEGER NOT NULL,
        sha256 TEXT NOT NULL,
        analysis TEXT NOT NULL,
        data BLOB NOT NULL,
        created_at TEXT NOT NULL
    );
    """,
)
SCHEMA_VERSION = len(MIGRATIONS)


class StoreError(Exception):
    """The store cannot be opened or used (for example a database from a newer version)."""


class ShowNotFound(StoreError):
    """No show has this id."""

    def __init__(self, show_id: str) -> None:
        super().__init__(f"no show with id {show_id!r}")
        self.show_id = show_id


class RevisionConflict(StoreError):
    """The caller's revision is not the stored one; ``current_revision`` is."""

    def __init__(self, show_id: str, *, expected: int, current: int) -> None:
        super().__init__(
            f"show {show_id!r} is at revision {current}, not {expected}: it was changed meanwhile; "
            "reload it and apply your change again"
        )
        self.show_id = show_id
        self.expected = expected
        self.current_revision = current


@dataclass(frozen=True)
class ShowRecord:
    """One stored show. ``json`` is the show file text (None in list results).

    ``problems`` is None for a valid show; for a draft, the JSON text of its problem list
    (``[{"loc", "path", "msg"}, ...]``, paths relative to the show).
    """

    id: str
    name: str
    revision: int
    content_hash: str
    drones: int
    formations: int
    created_at: str
    updated_at: str
    problems: str | None = None
    json: str | None = None

    @property
    def draft(self) -> bool:
        """True when the stored show is a draft (it has problems)."""
        return self.problems is not None


@dataclass(frozen=True)
class RevisionRecord:
    """One revision of a show; ``json`` is None in lists and once the text was pruned."""

    show_id: str
    revision: int
    name: str
    content_hash: str
    drones: int
    formations: int
    created_at: str
    has_json: bool = True
    json: str | None = None
    draft: bool = False


_REV_COLUMNS = "show_id, revision, name, content_hash, drones, formations, created_at, problems IS NOT NULL"


def _revision_record(row: Any, has_json: bool, json: str | None = None) -> RevisionRecord:
    """A :class:`RevisionRecord` from a row starting with the :data:`_REV_COLUMNS`."""
    show_id, revision, name, content_hash, drones, formations, created_at, draft = row[:8]
    return RevisionRecord(show_id, revision, name, content_hash, drones, formations, created_at, has_json, json,
                          bool(draft))


@dataclass(frozen=True)
class ShowData:
    """What the store keeps of a validated show (or a draft): its JSON text and the listed fields.

    Lets a show validated in another process be stored without parsing it again. ``problems`` is
    None for a valid show, the list of what is wrong for a draft (see :meth:`draft`).
    """

    text: str
    content_hash: str
    name: str
    drones: int
    formations: int
    problems: list[dict[str, Any]] | None = None

    @classmethod
    def draft(cls, doc: dict[str, Any], problems: list[dict[str, Any]]) -> ShowData:
        """A half-finished show kept as it is, with its problems (``ShowValidationError.errors``).

        Its listed fields are read leniently (a draft may lack any of them). Its content hash is
        taken over sorted-key JSON with a ``draft`` prefix, so a draft never shares a hash (and
        thus a cached check or flight) with a valid show.
        """
        import hashlib
        import json

        name = doc.get("name")
        drones = doc.get("drones")
        formations = doc.get("formations")
        canonical = json.dumps(doc, sort_keys=True, separators=(",", ":"))
        return cls(
            text=json.dumps(doc, separators=(",", ":")),
            content_hash=hashlib.sha256(b"draft\n" + canonical.encode()).hexdigest(),
            name=name.strip()[:200] if isinstance(name, str) and name.strip() else "Untitled draft",
            drones=drones if isinstance(drones, int) and not isinstance(drones, bool) and drones >= 0 else 0,
            formations=len(formations) if isinstance(formations, list) else 0,
            problems=_draft_problems(doc, problems),
        )

    @property
    def problems_text(self) -> str | None:
        """The problems as stored (JSON text), None for a valid show."""
        import json

        return None if self.problems is None else json.dumps(self.problems)

    @classmethod
    def of(cls, show: ShowFile | ShowData) -> ShowData:
        """The data of a validated show (returned as is if it already is one)."""
        if isinstance(show, ShowData):
            return show
        from formations import dump_show

        return cls(text=dump_show(show, indent=None), content_hash=show.content_hash(), name=show.name,
                   drones=show.drones, formations=len(show.formations))


#: Problems a draft keeps (a 20 MB file of bad numbers has a million): the rest are counted.
MAX_DRAFT_PROBLEMS = 50


def _draft_problems(doc: dict[str, Any], problems: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The first :data:`MAX_DRAFT_PROBLEMS` problems, each also saying where in plain words (named
    formations), and a last line counting the others."""
    from formations import plain_words

    out = [{"loc": list(p.get("loc", ())), "path": p.get("path", ""), "msg": p["msg"],
            **plain_words(p.get("path", ""), doc)} for p in problems[:MAX_DRAFT_PROBLEMS]]
    if len(problems) > MAX_DRAFT_PROBLEMS:
        more = len(problems) - MAX_DRAFT_PROBLEMS
        out.append({"loc": [], "path": "", "msg": f"and {more} more problem{'s' if more > 1 else ''}",
                    "where": "the show"})
    return out or [{"loc": [], "path": "", "msg": "invalid show", "where": "the show"}]


@dataclass(frozen=True)
class AudioRecord:
    """A show's stored music: file name, MIME type, size (bytes), SHA-256, when; ``analysis`` JSON when asked."""

    show_id: str
    filename: str
    media_type: str
    size: int
    sha256: str
    created_at: str
    analysis: str | None = None


def _now() -> str:
    return datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def new_show_id() -> str:
    """A random, URL-safe show id (16 hex digits)."""
    return secrets.token_hex(8)


_COLUMNS = "id, name, revision, content_hash, drones, formations, created_at, updated_at, problems"


class ShowStore:
    """Shows and cached results in one SQLite file; safe to share between threads.

    Two connections, each serialised by its own lock: one writes (SQLite allows one
    writer at a time anyway; a durable commit is one fsync), the other reads, so a
    read never waits for a commit's fsync (WAL readers see the last commit).
    """

    def __init__(self, path: Path | str, *, keep_revisions: int = 200) -> None:
        self.path = Path(path)
        self.keep_revisions = keep_revisions
        memory = str(path) == ":memory:"
        if not memory:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self._read_lock = threading.Lock()
        try:
            self._db = self._connect(path)
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.execute("PRAGMA synchronous=FULL")
            self._migrate()
            self._rdb = self._db if memory else self._connect(path)
            if memory:
                self._read_lock = self._lock
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"{self.path}: cannot open the show store: {exc}") from exc

    @staticmethod
    def _connect(path: Path | str) -> sqlite3.Connection:
        db = sqlite3.connect(str(path), isolation_level=None, check_same_thread=False, timeout=30.0)
        db.execute("PRAGMA busy_timeout=30000")
        db.execute("PRAGMA synchronous=FULL")
        return db

    # -- plumbing ---------------------------------------------------------------------------

    @contextmanager
    def _tx(self) -> Iterator[sqlite3.Connection]:
        """One write transaction: committed on success, rolled back on any exception."""
        with self._lock:
            # IMMEDIATE takes the write lock up front, so a read-check-write never races another process.
            self._db.execute("BEGIN IMMEDIATE")
            try:
                yield self._db
            except BaseException:
                self._db.execute("ROLLBACK")
                raise
            self._db.execute("COMMIT")

    @contextmanager
    def _read(self) -> Iterator[sqlite3.Connection]:
        with self._read_lock:
            yield self._rdb

    def _migrate(self) -> None:
        with self._lock:
            self._db.execute("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)")
            row = self._db.execute("SELECT version FROM schema_version").fetchone()
            version = 0 if row is None else int(row[0])
            if row is None:
                self._db.execute("INSERT INTO schema_version (version) VALUES (0)")
        if version > SCHEMA_VERSION:
            raise StoreError(
                f"{self.path}: schema version {version} is newer than this swarmshow's ({SCHEMA_VERSION}); "
                "upgrade swarmshow"
            )
        for target in range(version + 1, SCHEMA_VERSION + 1):
            self._apply_migration(target)

    def _apply_migration(self, target: int) -> None:
        with self._tx() as db:
            for statement in MIGRATIONS[target - 1].split(";"):
                if statement.strip():
                    db.execute(statement)
            db.execute("UPDATE schema_version SET version = ?", (target,))

    @property
    def schema_version(self) -> int:
        """The schema version of the open database."""
        with self._read() as db:
            return int(db.execute("SELECT version FROM schema_version").fetchone()[0])

    def close(self) -> None:
        """Close the connection (the WAL is checkpointed by SQLite)."""
        with self._lock:
            if self._rdb is not self._db:
                with self._read_lock:
                    self._rdb.close()
            self._db.close()

    # -- shows ------------------------------------------------------------------------------

    def create(self, show: ShowFile | ShowData, *, show_id: str | None = None) -> ShowRecord:
        """Store a validated show (or a draft) as revision 1 and return its record (with JSON)."""
        data, now = ShowData.of(show), _now()
        text = data.text
        record = ShowRecord(
            id=show_id or new_show_id(), name=data.name, revision=1, content_hash=data.content_hash,
            drones=data.drones, formations=data.formations, created_at=now, updated_at=now,
            problems=data.problems_text, json=text,
        )
        with self._tx() as db:
            db.execute(
                f"INSERT INTO shows ({_COLUMNS}, json) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (record.id, record.name, 1, record.content_hash, record.drones, record.formations, now, now,
                 record.problems, text),
            )
            self._add_revision(db, record.id, 1, data, now)
        return record

    def _add_revision(self, db: sqlite3.Connection, show_id: str, revision: int, data: ShowData, now: str) -> None:
        db.execute(
            "INSERT INTO revisions (show_id, revision, name, content_hash, drones, formations, created_at, json, "
            "problems) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
            (show_id, revision, data.name, data.content_hash, data.drones, data.formations, now, data.text,
             data.problems_text),
        )
        if revision > self.keep_revisions:
            db.execute("UPDATE revisions SET json = NULL WHERE show_id = ? AND revision = ?",
                       (show_id, revision - self.keep_revisions))

    def get(self, show_id: str) -> ShowRecord:
        """The show with its JSON. Raises :class:`ShowNotFound`."""
        with self._read() as db:
            row = db.execute(f"SELECT {_COLUMNS}, json FROM shows WHERE id = ?", (show_id,)).fetchone()
        if row is None:
            raise ShowNotFound(show_id)
        return ShowRecord(*row)

    def get_revision_number(self, show_id: str) -> int:
        """The show's current revision (one indexed read). Raises :class:`ShowNotFound`."""
        with self._read() as db:
            row = db.execute("SELECT revision FROM shows WHERE id = ?", (show_id,)).fetchone()
        if row is None:
            raise ShowNotFound(show_id)
        return int(row[0])

    def list(self, *, limit: int = 50, offset: int = 0) -> tuple[list[ShowRecord], int]:
        """A page of shows, most recently updated first, and the total count."""
        with self._read() as db:
            db.execute("BEGIN")  # one snapshot for the page and the count
            try:
                rows = db.execute(
                    f"SELECT {_COLUMNS} FROM shows ORDER BY updated_at DESC, id LIMIT ? OFFSET ?", (limit, offset)
                ).fetchall()
                total = int(db.execute("SELECT COUNT(*) FROM shows").fetchone()[0])
            finally:
                db.execute("COMMIT")
        return [ShowRecord(*r) for r in rows], total

    def find_by_hash(self, content_hash: str) -> ShowRecord | None:
        """The oldest show with exactly this content, or None."""
        with self._read() as db:
            row = db.execute(
                f"SELECT {_COLUMNS} FROM shows WHERE content_hash = ? ORDER BY created_at LIMIT 1", (content_hash,)
            ).fetchone()
        return None if row is None else ShowRecord(*row)

    def update(self, show_id: str, show: ShowFile | ShowData, *, expected_revision: int) -> ShowRecord:
        """Replace revision ``expected_revision`` of a show; returns the new record.

        Saving identical content keeps the revision (a repeated save is not a change).

        Raises:
            ShowNotFound: no such show.
            RevisionConflict: the stored revision is not ``expected_revision``.
        """
        data = ShowData.of(show)
        text, content_hash = data.text, data.content_hash
        with self._tx() as db:
            row = db.execute("SELECT revision, content_hash FROM shows WHERE id = ?", (show_id,)).fetchone()
            if row is None:
                raise ShowNotFound(show_id)
            current, stored_hash = int(row[0]), row[1]
            if current != expected_revision:
                raise RevisionConflict(show_id, expected=expected_revision, current=current)
            if stored_hash != content_hash:
                now = _now()
                db.execute(
                    "UPDATE shows SET name = ?, revision = ?, json = ?, content_hash = ?, drones = ?, "
                    "formations = ?, updated_at = ?, problems = ? WHERE id = ? AND revision = ?",
                    (data.name, current + 1, text, content_hash, data.drones, data.formations, now,
                     data.problems_text, show_id, current),
                )
                self._add_revision(db, show_id, current + 1, data, now)
            row = db.execute(f"SELECT {_COLUMNS}, json FROM shows WHERE id = ?", (show_id,)).fetchone()
        return ShowRecord(*row)

    def delete(self, show_id: str, *, expected_revision: int | None = None) -> None:
        """Delete a show (only revision ``expected_revision`` if given).

        Raises:
            ShowNotFound: no such show.
            RevisionConflict: ``expected_revision`` is given and stale.
        """
        with self._tx() as db:
            row = db.execute("SELECT revision FROM shows WHERE id = ?", (show_id,)).fetchone()
            if row is None:
                raise ShowNotFound(show_id)
            if expected_revision is not None and int(row[0]) != expected_revision:
                raise RevisionConflict(show_id, expected=expected_revision, current=int(row[0]))
            db.execute("DELETE FROM shows WHERE id = ?", (show_id,))
            db.execute("DELETE FROM revisions WHERE show_id = ?", (show_id,))
            db.execute("DELETE FROM audio WHERE show_id = ?", (show_id,))

    def revisions(
        self, show_id: str, *, limit: int = 100, offset: int = 0
    ) -> tuple[builtins.list[RevisionRecord], int]:
        """A page of a show's revisions, newest first, and how many there are. Raises :class:`ShowNotFound`."""
        with self._read() as db:
            db.execute("BEGIN")  # one snapshot for the show, the page and the count
            try:
                if db.execute("SELECT 1 FROM shows WHERE id = ?", (show_id,)).fetchone() is None:
                    raise ShowNotFound(show_id)
                rows = db.execute(
                    f"SELECT {_REV_COLUMNS}, json IS NOT NULL FROM revisions WHERE show_id = ? "
                    "ORDER BY revision DESC LIMIT ? OFFSET ?",
                    (show_id, limit, offset),
                ).fetchall()
                total = int(db.execute("SELECT COUNT(*) FROM revisions WHERE show_id = ?", (show_id,)).fetchone()[0])
            finally:
                db.execute("COMMIT")
        return [_revision_record(r, bool(r[8])) for r in rows], total

    def get_revision(self, show_id: str, revision: int) -> RevisionRecord:
        """One revision with its text (None once pruned). Raises :class:`ShowNotFound`."""
        with self._read() as db:
            row = db.execute(
                f"SELECT {_REV_COLUMNS}, json IS NOT NULL, json FROM revisions WHERE show_id = ? AND revision = ?",
                (show_id, revision),
            ).fetchone()
        if row is None:
            raise ShowNotFound(f"{show_id}@{revision}")
        return _revision_record(row, bool(row[8]), row[9])

    # -- audio (issue 18) ---------------------------------------------------------------------

    def put_audio(self, show_id: str, *, filename: str, media_type: str, data: bytes, analysis: str) -> AudioRecord:
        """Store (or replace) a show's music. Raises :class:`ShowNotFound`."""
        import hashlib

        digest = hashlib.sha256(data).hexdigest()
        now = _now()
        with self._tx() as db:
            if db.execute("SELECT 1 FROM shows WHERE id = ?", (show_id,)).fetchone() is None:
                raise ShowNotFound(show_id)
            db.execute(
                "INSERT OR REPLACE INTO audio (show_id, filename, media_type, size, sha256, analysis, data, "
                "created_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (show_id, filename, media_type, len(data), digest, analysis, data, now),
            )
        return AudioRecord(show_id, filename, media_type, len(data), digest, now, analysis)

    def copy_audio(self, source_id: str, show_id: str) -> AudioRecord | None:
        """Give ``show_id`` the music of ``source_id`` (replacing any), in one transaction and without
        the bytes passing through Python; None (nothing changed) when the source has no music.
        Raises :class:`ShowNotFound` naming a show that does not exist."""
        now = _now()
        with self._tx() as db:
            for sid in (source_id, show_id):
                if db.execute("SELECT 1 FROM shows WHERE id = ?", (sid,)).fetchone() is None:
                    raise ShowNotFound(sid)
            if db.execute("SELECT 1 FROM audio WHERE show_id = ?", (source_id,)).fetchone() is None:
                return None
            if source_id != show_id:
                db.execute(
                    "INSERT OR REPLACE INTO audio (show_id, filename, media_type, size, sha256, analysis, data, "
                    "created_at) SELECT ?, filename, media_type, size, sha256, analysis, data, ? FROM audio "
                    "WHERE show_id = ?",
                    (show_id, now, source_id),
                )
            row = db.execute("SELECT show_id, filename, media_type, size, sha256, created_at FROM audio "
                             "WHERE show_id = ?", (show_id,)).fetchone()
        return None if row is None else AudioRecord(*row)

    def get_audio(self, show_id: str, *, analysis: bool = False) -> AudioRecord | None:
        """A show's music record (without its bytes), or None when it has none."""
        cols = "show_id, filename, media_type, size, sha256, created_at" + (", analysis" if analysis else "")
        with self._read() as db:
            row = db.execute(f"SELECT {cols} FROM audio WHERE show_id = ?", (show_id,)).fetchone()
        return None if row is None else AudioRecord(*row)

    def read_audio(self, show_id: str, start: int = 0, length: int | None = None) -> bytes:
        """``length`` bytes (all from ``start`` when None) of a show's music, read through SQLite's blob I/O
        (a range request never loads the whole file). Raises :class:`ShowNotFound` when there is none."""
        with self._read() as db:
            row = db.execute("SELECT rowid, size FROM audio WHERE show_id = ?", (show_id,)).fetchone()
            if row is None:
                raise ShowNotFound(f"{show_id}/audio")
            rowid, size = int(row[0]), int(row[1])
            start = max(0, min(start, size))
            n = size - start if length is None else max(0, min(length, size - start))
            with db.blobopen("audio", "data", rowid, readonly=True) as blob:
                blob.seek(start)
                return blob.read(n)

    def delete_audio(self, show_id: str) -> bool:
        """Remove a show's music; True if there was any."""
        with self._tx() as db:
            return db.execute("DELETE FROM audio WHERE show_id = ?", (show_id,)).rowcount > 0

    # -- cached results ---------------------------------------------------------------------

    def get_result(self, key: str) -> str | None:
        """A cached result's JSON text, or None."""
        with self._read() as db:
            row = db.execute("SELECT json FROM results WHERE key = ?", (key,)).fetchone()
        return None if row is None else row[0]

    def put_result(self, key: str, *, kind: str, content_hash: str, text: str, keep: int = 500) -> None:
        """Cache a result, keeping only the ``keep`` most recent."""
        with self._tx() as db:
            db.execute(
                "INSERT OR REPLACE INTO results (key, kind, content_hash, json, created_at) VALUES (?, ?, ?, ?, ?)",
                (key, kind, content_hash, text, _now()),
            )
            db.execute(
                "DELETE FROM results WHERE key IN "
                "(SELECT key FROM results ORDER BY created_at DESC LIMIT -1 OFFSET ?)",
                (keep,),
            )

    # -- job records ------------------------------------------------------------------------

    def put_job(self, job_id: str, record: str, *, state: str, keep: int = 1000) -> None:
        """Write a job's record (JSON text), keeping only the ``keep`` most recently changed."""
        with self._tx() as db:
            db.execute("INSERT OR REPLACE INTO jobs (id, record, state, updated_at) VALUES (?, ?, ?, ?)",
                       (job_id, record, state, _now()))
            db.execute("DELETE FROM jobs WHERE id IN "
                       "(SELECT id FROM jobs ORDER BY updated_at DESC LIMIT -1 OFFSET ?)", (keep,))

    def get_job(self, job_id: str) -> str | None:
        """A job's record (JSON text), or None."""
        with self._read() as db:
            row = db.execute("SELECT record FROM jobs WHERE id = ?", (job_id,)).fetchone()
        return None if row is None else row[0]

    def unfinished_jobs(self) -> builtins.list[str]:
        """Records of the jobs stored as queued or running (after a restart: interrupted)."""
        with self._read() as db:
            return [r[0] for r in db.execute("SELECT record FROM jobs WHERE state IN ('queued', 'running')")]
