"""The installed swarmshow version, and a digest of the code that computes results."""

from __future__ import annotations

import functools
import hashlib
from collections.abc import Iterable
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

try:
    __version__ = version("swarmshow")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"

#: The packages whose code decides a cached result (plan, check, flight, exports, formations).
RESULT_PACKAGES = ("formations", "sim", "app")


def source_digest(roots: Iterable[Path]) -> str:
    """SHA-256 (hex, 16 digits) of every ``.py`` file under ``roots``: relative path and bytes, in path order.

    Why: the version number stays the same across an editable install's edits and a deploy of the
    same release number; results cached on disk by other code must not be served.
    """
    h = hashlib.sha256()
    for root in roots:
        root = Path(root)
        for path in sorted(root.rglob("*.py")):
            h.update(f"{root.name}/{path.relative_to(root).as_posix()}\0".encode())
            h.update(path.read_bytes())
            h.update(b"\0")
    return h.hexdigest()[:16]


@functools.cache
def code_digest() -> str:
    """:func:`source_digest` of this installation's :data:`RESULT_PACKAGES` (~10 ms, once per process)."""
    import importlib.util

    roots = []
    for name in RESULT_PACKAGES:  # found, not imported (importing sim would load numba)
        spec = importlib.util.find_spec(name)
        roots += [Path(p) for p in (spec.submodule_search_locations or [])] if spec else []
    return source_digest(roots)
