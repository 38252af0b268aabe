"""Formation names after their source: the file's stem, the text spelled, the shape drawn.

A designer who imports ``Company Logo v2.svg`` expects a formation called "Company Logo v2",
not "Formation 3"; one who spells "Happy New Year" expects that. Names are cleaned (no folders,
no extension, no control characters, whitespace collapsed) and kept short enough to read in
the timeline.
"""

from __future__ import annotations

import re
import unicodedata

#: Longest name made from a source, characters (an ellipsis ends a longer text).
MAX_SOURCE_NAME_CHARS = 40
#: The name when the source gives nothing usable (an empty stem, a blank text).
_FALLBACK = {"image": "Image", "svg": "Drawing", "mesh": "Mesh", "text": "Text", "shape": "Shape"}


def _clean(text: str) -> str:
    """Control and format characters dropped, whitespace runs collapsed to one space, trimmed."""
    kept = "".join(" " if unicodedata.category(c) in ("Cc", "Zl", "Zp") else c for c in text
                   if unicodedata.category(c) not in ("Cf", "Cs", "Co", "Cn"))
    return re.sub(r"\s+", " ", kept).strip()


def _shorten(text: str) -> str:
    if len(text) <= MAX_SOURCE_NAME_CHARS:
        return text
    return text[: MAX_SOURCE_NAME_CHARS - 1].rstrip() + "…"


def file_stem(filename: str) -> str:
    """The file's name without folders (``/`` or ``\\``) and without its last extension.

    ``C:\\a\\star.final.svg`` -> ``star.final``; a dot file keeps its name (``.hidden``).
    """
    base = re.split(r"[\\/]", filename)[-1]
    stem, dot, ext = base.rpartition(".")
    return stem if dot and stem and ext else base


def source_name(kind: str, *, filename: str | None = None, text: str | None = None) -> str:
    """The name a formation made from a source should carry.

    Args:
        kind: ``"image"``, ``"svg"``, ``"mesh"`` (files: named after ``filename``), ``"text"`` (after
            ``text``) or ``"shape"`` (after ``text``, the shape's kind).
        filename: the uploaded file's name, as the browser sent it.
        text: the text spelled, or the shape's kind.
    """
    raw = file_stem(filename) if filename is not None else (text or "")
    name = _shorten(_clean(raw))
    return name or _FALLBACK.get(kind, "Formation")
