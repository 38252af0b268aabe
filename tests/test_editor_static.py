"""The editor's static files: everything index.html references exists, nothing loads from elsewhere."""

from __future__ import annotations

import re
from html.parser import HTMLParser
from pathlib import Path

FRONTEND = Path(__file__).resolve().parent.parent / "frontend"
#: Namespace identifiers that look like URLs but are never fetched.
NAMESPACES = {"http://www.w3.org/2000/svg", "http://www.w3.org/1999/xlink", "http://www.w3.org/1999/xhtml"}
URL = re.compile(r"""https?://[^\s"'`)<>]*""", flags=re.I)


class _Refs(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.refs: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        for name, value in attrs:
            if name in ("src", "href") and value and not value.startswith(("#", "about:", "data:")):
                self.refs.append(value)


def _frontend_files() -> list[Path]:
    return [p for p in FRONTEND.rglob("*") if p.is_file()]


def _module_imports(path: Path) -> list[str]:
    text = path.read_text(encoding="utf-8")
    return re.findall(r"""^\s*import\s[^;]*?from\s+["']([^"']+)["']""", text, flags=re.M | re.S) + re.findall(
        r"""^\s*import\s+["']([^"']+)["']""", text, flags=re.M
    )


def test_index_references_exist():
    parser = _Refs()
    parser.feed((FRONTEND / "index.html").read_text(encoding="utf-8"))
    assert parser.refs, "index.html references no files"
    for ref in parser.refs:
        assert not re.match(r"^[a-z]+:", ref) and not ref.startswith("//"), f"index.html loads {ref} from elsewhere"
        target = FRONTEND / ref.split("?")[0]
        assert target.is_file(), f"index.html references missing {ref}"


def test_every_module_import_resolves():
    """Follow the ES module graph from main.js: every relative import names an existing file."""
    seen: set[Path] = set()
    todo = [FRONTEND / "js" / "main.js"]
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        for spec in _module_imports(path):
            assert spec.startswith("./") or spec.startswith("../"), f"{path.name} imports {spec!r} (bare or remote)"
            target = (path.parent / spec).resolve()
            assert target.is_file(), f"{path.name} imports missing {spec}"
            todo.append(target)
    js = set((FRONTEND / "js").glob("*.js"))
    assert js <= seen, f"modules not reachable from main.js: {sorted(p.name for p in js - seen)}"


def test_no_remote_urls():
    for path in _frontend_files():
        text = path.read_text(encoding="utf-8")
        for match in URL.finditer(text):
            url = match.group(0)
            if url in NAMESPACES:
                continue
            raise AssertionError(f"{path.relative_to(FRONTEND)} refers to {url}")


def test_no_inline_scripts_or_styles():
    """A strict Content-Security-Policy (no 'unsafe-inline') must not break the editor."""
    html = (FRONTEND / "index.html").read_text(encoding="utf-8")
    assert not re.search(r"<script(?![^>]*\bsrc=)[^>]*>", html), "inline <script> in index.html"
    assert "<style" not in html, "inline <style> in index.html"
    assert not re.search(r"\son[a-z]+=", html), "inline event handler in index.html"
    assert not re.search(r"\sstyle=", html), "inline style attribute in index.html"


def test_interactive_controls_are_labelled():
    """Every button, input, select and textarea has an accessible name."""
    html = (FRONTEND / "index.html").read_text(encoding="utf-8")
    labels_for = set(re.findall(r'<label[^>]*\bfor="([^"]+)"', html))
    for m in re.finditer(r"<(button|input|select|textarea)\b([^>]*)>(.*?)(?=<)", html, flags=re.S):
        tag, attrs, text = m.group(1), m.group(2), m.group(3).strip()
        if 'type="submit"' in attrs and text:
            continue
        ident = re.search(r'\bid="([^"]+)"', attrs)
        named = "aria-label=" in attrs or (ident and ident.group(1) in labels_for) or (tag == "button" and text)
        assert named, f"unlabelled <{tag}{attrs}>"
