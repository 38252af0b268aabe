"""Safe file names and deterministic zip archives for the exports.

Archive members are always flat (no directories) and their names are built
only from ``[A-Za-z0-9._+-]``, so a hostile show or drone name (``../``,
slashes, NUL, thousands of characters) can neither escape the directory the
archive is extracted into nor break a file system.
"""

from __future__ import annotations

import io
import json
import re
import zipfile
from collections.abc import Iterable
from typing import Any

from app.exports._frames import LOCAL_FRAME

#: Longest file-name stem, characters (file systems allow 255 bytes; leave room for suffixes).
MAX_STEM_CHARS = 64
_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]+")
# Names Windows refuses whatever the extension.
_WINDOWS_RESERVED = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(1, 10)), *(f"LPT{i}" for i in range(1, 10))}
# A fixed timestamp keeps archives byte-identical for identical shows (zip cannot store dates before 1980).
_ZIP_DATE = (1980, 1, 1, 0, 0, 0)


def safe_stem(name: str, *, default: str = "show", max_chars: int = MAX_STEM_CHARS) -> str:
    """A file-name stem made only of ``[A-Za-z0-9._+-]`` derived from ``name``.

    Runs of other characters (slashes, NUL, spaces, non-ASCII) become one
    ``_``; leading dots and dashes are dropped (no ``..``, no hidden files, no
    option-like names); the result is cut to ``max_chars`` and falls back to
    ``default`` when nothing is left.
    """
    stem = _UNSAFE.sub("_", str(name))
    stem = stem.lstrip(".-_")
    stem = stem[:max_chars].rstrip("._")
    if not stem:
        stem = default
    if stem.split(".")[0].upper() in _WINDOWS_RESERVED:
        stem = "_" + stem
    return stem


def drone_file_stems(count: int, names: Iterable[str] | None = None) -> list[str]:
    """Unique, safe per-drone stems: ``drone_001``, ... or the given names sanitised.

    Zero padding grows with the fleet (``drone_0001`` for 1000+ drones) so that
    the files sort in drone order. Sanitised names that collide get ``-2``,
    ``-3``, ... appended.
    """
    width = max(3, len(str(count)))
    if names is None:
        return [f"drone_{i + 1:0{width}d}" for i in range(count)]
    out: list[str] = []
    seen: set[str] = set()
    for i, name in enumerate(names):
        stem = safe_stem(name, default=f"drone_{i + 1:0{width}d}")
        candidate, k = stem, 1
        while candidate.lower() in seen:
            k += 1
            candidate = f"{stem[: MAX_STEM_CHARS - 8]}-{k}"
        seen.add(candidate.lower())
        out.append(candidate)
    return out


class ZipBuilder:
    """A zip archive built in memory with flat, sanitised member names."""

    def __init__(self, *, compresslevel: int = 1) -> None:
        # Level 1 deflate compresses CSV text ~4x at several times the speed of the default level 6.
        self._buf = io.BytesIO()
        self._zip = zipfile.ZipFile(self._buf, "w", compression=zipfile.ZIP_DEFLATED, compresslevel=compresslevel)
        self._level = compresslevel
        self.names: list[str] = []

    def add(self, name: str, data: bytes | str) -> str:
        """Add one member; ``name`` is sanitised again here, so no caller can create a path. Returns it."""
        stem, dot, ext = name.rpartition(".")
        safe = f"{safe_stem(stem, default='file')}.{safe_stem(ext, default='txt', max_chars=16)}" if dot else (
            safe_stem(name, default="file")
        )
        if safe in self.names:
            raise ValueError(f"duplicate archive member {safe!r}")
        info = zipfile.ZipInfo(safe, date_time=_ZIP_DATE)
        info.compress_type = zipfile.ZIP_DEFLATED
        info.external_attr = 0o644 << 16
        self._zip.writestr(info, data.encode() if isinstance(data, str) else data, compresslevel=self._level)
        self.names.append(safe)
        return safe

    def add_manifest(self, manifest: dict[str, Any], readme: str) -> None:
        """Add ``manifest.json`` (listing every member added so far) and ``README.txt``."""
        manifest = {**manifest, "files": list(self.names)}
        self.add("manifest.json", json.dumps(manifest, indent=2, allow_nan=False) + "\n")
        self.add("README.txt", readme.rstrip() + "\n")

    def set_comment(self, manifest: dict[str, Any]) -> None:
        """Store a manifest as the archive comment (for archives whose readers parse every member)."""
        text = json.dumps(manifest, separators=(",", ":"), allow_nan=False).encode()
        # A zip comment holds at most 65535 bytes.
        self._zip.comment = text if len(text) <= 65535 else text[:65535]

    def finish(self) -> bytes:
        """Close the archive and return its bytes."""
        self._zip.close()
        return self._buf.getvalue()


def base_manifest(ctx: Any, *, fmt: str, **extra: Any) -> dict[str, Any]:
    """Manifest fields common to every archive: generator, format, show summary."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        generator = f"swarmshow {version('swarmshow')}"
    except PackageNotFoundError:
        generator = "swarmshow"
    plan = ctx.plan
    return {
        "generator": generator,
        "format": fmt,
        "show": ctx.show.name,
        "show_hash": ctx.show.content_hash(),
        "drones": ctx.show.drones,
        "duration_s": round(plan.duration_s, 6),
        "coordinates": LOCAL_FRAME,
        "heading_deg": ctx.options.heading_deg,
        **extra,
    }
