"""``origin`` is refused (naming it) by the formats that do not place the show on Earth, as scale, offset and fps
are (``app.exports._core.check_unused_options``): the library, the API and the CLI alike. The stored
``settings.geo`` is the show's own, not an option given: it never makes a format refuse.

Failed before: ``swarmshow export -f crazyswarm --origin 47,8`` (and the CSV formats, viser-html, the show
file) wrote the file without a word, the origin dropped.

Which formats use the origin is found, not trusted: each writer is run on the same plan with two origins, and a
format uses it iff the bytes differ.
"""

from __future__ import annotations

import io
import zipfile

import pytest

from app.cli import main
from app.exports import EXPORT_FORMATS, ExportError, ExportOptions, _core, export_show
from app.exports._core import ExportContext
from app.exports._formats import _load_exporter
from formations import dump_show
from tests.conftest import app_client

ORIGIN_A = (47.0, 8.0, 400.0)
ORIGIN_B = (46.0, 7.0, 10.0)


def _members(content: bytes) -> dict[str, bytes] | bytes:
    try:
        with zipfile.ZipFile(io.BytesIO(content)) as z:
            return {n: z.read(n) for n in z.namelist()}
    except zipfile.BadZipFile:
        return content


def _uses_origin(show, plan, fmt: str) -> bool:
    """Run the writer itself (below the option check) with two origins: does the file change?"""
    def write(origin):
        ctx = ExportContext(show, ExportOptions(origin=origin), fmt=fmt, plan=plan)
        return _members(_load_exporter(fmt)(ctx).content)
    return write(ORIGIN_A) != write(ORIGIN_B)


def test_origin_formats_are_the_writers_that_use_it(square, square_plan):
    found = tuple(f for f in EXPORT_FORMATS if f != "show" and _uses_origin(square, square_plan, f))
    assert set(found) == set(_core.ORIGIN_FORMATS), found
    assert "show" not in _core.ORIGIN_FORMATS  # the show file downloads as stored (its own settings.geo)


NOT_ORIGIN = [f for f in EXPORT_FORMATS if f not in ("skyc", "qgc-plan", "qgc-wpl")]


@pytest.mark.parametrize("fmt", NOT_ORIGIN)
def test_library_refuses_origin_where_unused(square, square_plan, fmt):
    with pytest.raises(ExportError) as err:
        export_show(square, fmt, plan=square_plan, origin=ORIGIN_A)
    assert err.value.field == "origin" and "qgc-plan" in str(err.value), str(err.value)


@pytest.mark.parametrize("fmt", [f for f in NOT_ORIGIN if f != "show"])
def test_stored_place_is_not_an_option_given(square, square_plan, fmt):
    """A show with settings.geo exports to every format (the stored place is the show's, not an option)."""
    import json

    from formations import parse_show

    doc = json.loads(dump_show(square))
    doc.setdefault("settings", {})["geo"] = {"origin_lat_deg": 47.0, "origin_lon_deg": 8.0, "origin_alt_m": 400.0,
                                             "heading_deg": 0.0}
    placed = parse_show(json.dumps(doc).encode())
    assert export_show(placed, fmt, plan=square_plan).content


def test_cli_refuses_origin_where_unused(square, tmp_path, capsys):
    src = tmp_path / "square.json"
    src.write_text(dump_show(square))
    for fmt in NOT_ORIGIN:
        out = tmp_path / f"o-{fmt}"
        code = main(["export", str(src), "--format", fmt, "--origin", "47,8,400", "-o", str(out)])
        err = capsys.readouterr().err
        assert code == 2 and "--origin" in err and len(err.strip().splitlines()) == 1, (fmt, err)
        assert not out.exists()


client = app_client("originunused", workers=1)


def test_api_refuses_origin_where_unused(client, square):
    r = client.post("/api/shows", content=dump_show(square), headers={"content-type": "application/json"})
    sid = r.json()["id"]
    for fmt in NOT_ORIGIN:
        r = client.get(f"/api/shows/{sid}/export/{fmt}", params={"origin": "47,8,400"})
        assert r.status_code == 422, (fmt, r.text)
        assert r.json()["detail"][0]["path"] == "origin", r.text
    r = client.get(f"/api/shows/{sid}/export/skyc", params={"origin": "47,8,400"})
    assert r.status_code == 200, r.text
