"""Every number field of the editor's settings form carries the show file's own bounds (its JSON schema) as its
min/max, so the browser and the editor's marks (settings.js, markRange) refuse an out-of-range value before a
request: a designer typing 500 m/s as a speed limit was told only by the save (a draft)."""

from __future__ import annotations

from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest

from formations._show import ShowFile

INDEX = Path(__file__).resolve().parent.parent / "frontend" / "index.html"


class _NumberFields(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.fields: list[dict[str, str | None]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        a = dict(attrs)
        if tag == "input" and a.get("type") == "number" and a.get("data-path"):
            self.fields.append(a)


def _fields() -> list[dict[str, str | None]]:
    parser = _NumberFields()
    parser.feed(INDEX.read_text(encoding="utf-8"))
    return parser.fields


def _bound(path: str) -> dict[str, Any]:
    """The schema of the field at a dotted show-file path (through $refs, and the union member that has it)."""
    schema = ShowFile.model_json_schema()
    defs = schema.get("$defs", {})

    def resolve(s: dict[str, Any], key: str | None = None) -> dict[str, Any]:
        while True:
            if "$ref" in s:
                s = defs[s["$ref"].rsplit("/", 1)[-1]]
            elif "anyOf" in s or "oneOf" in s:
                subs = [resolve(x) for x in s.get("anyOf", s.get("oneOf", [])) if x.get("type") != "null"]
                s = next((x for x in subs if key is None or key in x.get("properties", {})), subs[0])
            else:
                return s

    node: dict[str, Any] = schema
    for key in path.split("."):
        node = resolve(node, key)["properties"][key]
    return resolve(node)


FIELDS = _fields()


def test_the_form_has_its_number_fields():
    assert len(FIELDS) >= 10, [f.get("id") for f in FIELDS]


@pytest.mark.parametrize("field", FIELDS, ids=lambda f: str(f.get("data-path")))
def test_each_settings_number_field_carries_the_show_file_s_bounds(field: dict[str, str | None]):
    bound = _bound(str(field["data-path"]))
    lo = bound.get("minimum", bound.get("exclusiveMinimum"))
    hi = bound.get("maximum", bound.get("exclusiveMaximum"))
    assert lo is not None or hi is not None, f"{field['data-path']} has no bound in the schema"
    assert (float(field["min"]) if field.get("min") else None) == lo, (field, bound)
    assert (float(field["max"]) if field.get("max") else None) == hi, (field, bound)
    strict = {k for k, key in (("min", "exclusiveMinimum"), ("max", "exclusiveMaximum")) if key in bound}
    assert set((field.get("data-exclusive") or "").split()) == strict, (field, bound)
