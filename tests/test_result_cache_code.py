"""A result cached by other code is not served: the cache key carries a digest of the code's sources."""

from __future__ import annotations

import hashlib

from app import jobs
from app.version import code_digest, source_digest


def _tree(root, files):
    for rel, text in files.items():
        path = root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


def test_source_digest_follows_python_sources_only(tmp_path):
    files = {"pkg/__init__.py": "", "pkg/a.py": "X = 1\n", "pkg/sub/b.py": "Y = 2\n", "pkg/notes.txt": "hi"}
    root = _tree(tmp_path / "one", files)
    base = source_digest([root / "pkg"])
    # Independent computation: the documented layout hashed by hand.
    h = hashlib.sha256()
    for rel in ("__init__.py", "a.py", "sub/b.py"):
        h.update(f"pkg/{rel}\0".encode() + (root / "pkg" / rel).read_bytes() + b"\0")
    assert base == h.hexdigest()[:16]
    (root / "pkg/notes.txt").write_text("changed")
    assert source_digest([root / "pkg"]) == base  # not code
    (root / "pkg/sub/b.py").write_text("Y = 3\n")
    assert source_digest([root / "pkg"]) != base
    (root / "pkg/sub/b.py").write_text("Y = 2\n")
    assert source_digest([root / "pkg"]) == base
    (root / "pkg/sub/b.py").rename(root / "pkg/sub/c.py")  # same bytes, another module
    assert source_digest([root / "pkg"]) != base


def test_cache_key_changes_with_the_code(monkeypatch):
    before = jobs.cache_key("check", "abc", {"x": 1})
    assert before == jobs.cache_key("check", "abc", {"x": 1})
    assert len(code_digest()) == 16
    monkeypatch.setattr(jobs, "code_digest", lambda: "0" * 16)
    assert jobs.cache_key("check", "abc", {"x": 1}) != before
