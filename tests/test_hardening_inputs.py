"""Bad-input matrix: every bad input gets a clear 4xx naming the field (CLI: exit 2), and the store is unchanged.

The same matrix, with the answers, is the table in ``docs/reliability.md``.
"""

from __future__ import annotations

import json
import select
import socket
import struct
import subprocess
import zlib

import httpx
import pytest
from fastapi.testclient import TestClient

from app.server import create_app
from app.settings import AppSettings
from tests.live_server import ServerProcess, swarmshow_command
from tests.test_api_live import SHOW


def show(**changes) -> dict:
    doc = json.loads(json.dumps(SHOW))
    doc.update(changes)
    return doc


def text(doc: dict) -> str:
    return json.dumps(doc, ensure_ascii=False)


def replaced(old: str, new: str, **changes) -> str:
    body = text(show(**changes))
    assert old in body
    return body.replace(old, new, 1)


# (case id, request body (str or bytes), status, field path or None, words in the message)
SHOW_CASES = [
    ("NaN", replaced('"hold_s": 2.0', '"hold_s": NaN'), 422, "formations[0].hold_s", "finite"),
    ("Infinity", replaced("[0, 0, 6]", "[0, 0, Infinity]"), 422, "formations[0].points[0][2]", "finite"),
    ("1e999 overflows to inf", replaced("[0, 0, 6]", "[0, 0, 1e999]"), 422, "formations[0].points[0][2]", "finite"),
    ("string for an integer", text(show(drones="4")), 422, "drones", "integer"),
    ("string for a number", replaced('"hold_s": 2.0', '"hold_s": "2.0"'), 422, "formations[0].hold_s", "number"),
    ("boolean for a number", replaced('"hold_s": 2.0', '"hold_s": true'), 422, "formations[0].hold_s", "number"),
    ("20,001 drones", text(show(drones=20_001)), 422, "drones", "20000"),
    ("no formations", text(show(formations=[])), 422, "formations", "at least 1"),
    ("fewer points than drones",
     text(show(drones=5, home={"grid": {"rows": 1, "cols": 5, "spacing_m": 4.5}})), 422,
     "formations[0].points", "4 points for 5 drones"),
    ("duplicate points", replaced("[5, 0, 6]", "[0, 0, 6]"), 422, "formations[0].points",
     "points 0 and 1 are 0.000 m apart"),
    ("altitude above the limit", replaced("[5, 0, 11]", "[5, 0, 500]"), 422, "formations[0].points[3][2]",
     "above max_altitude_m"),
    ("altitude below ground", replaced("[5, 0, 11]", "[5, 0, -3]"), 422, "formations[0].points[3][2]", "below"),
    ("max altitude out of range", text(show(settings={"max_altitude_m": 1e6})), 422, "settings.max_altitude_m",
     "less than or equal"),
    ("malformed JSON", '{"format": "swarmshow/1", "name": }', 422, "", "Invalid JSON"),
    ("truncated JSON", text(show())[:100], 422, "", "EOF"),
    ("not an object", "[1, 2, 3]", 422, "", "object"),
    ("empty body", "", 422, "", "empty"),
    ("wrong format tag", text(show(format="swarmshow/2")), 422, "format", "'swarmshow/1'"),
    ("missing format tag", text({k: v for k, v in SHOW.items() if k != "format"}), 422, "format", "required"),
    ("unknown field", text(show(pilot="me")), 422, "pilot", "not permitted"),
    ("non-UTF-8 text", text(show(name="Café")).encode("latin-1"), 422, "", "not UTF-8"),
    ("UTF-16 text", text(show()).encode("utf-16"), 422, "", "UTF-8"),
    ("NUL in the show name", text(show(name="a\u0000b")), 422, "name", "control characters"),
    ("newline in the show name", text(show(name="a\nb")), 422, "name", "control characters"),
    ("10 kB show name", text(show(name="x" * 10_000)), 422, "name", "at most 200"),
    ("blank show name", text(show(name="   ")), 422, "name", "blank"),
    ("NUL in a formation name", replaced('"square"', '"sq\\u0000"'), 422, "formations[0].name", "control"),
    ("10 kB formation name", replaced('"square"', '"' + "y" * 10_000 + '"'), 422, "formations[0].name",
     "at most 200"),
    ("bad colour", replaced('"#ff0000"', '"red"'), 422, "formations[0].colors[0]", "pattern"),
]


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("inputs"), workers=1, viewer=False))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        r = c.post("/api/shows", json=SHOW)
        assert r.status_code == 201
        c.existing = r.json()["id"]
        yield c


def snapshot(client) -> tuple:
    """Everything a write could change: the list (ids, revisions, hashes, times) and the revision history."""
    listing = client.get("/api/shows", params={"limit": 500}).json()
    store = client.app.state.store
    with store._read() as db:
        history = db.execute("SELECT show_id, revision, content_hash FROM revisions ORDER BY 1, 2").fetchall()
    return listing["total"], [(i["id"], i["revision"], i["content_hash"], i["updated_at"])
                              for i in listing["items"]], history


def assert_names(r, status: int, path: str | None, words: str) -> None:
    assert r.status_code == status, r.text
    detail = r.json()["detail"]
    if isinstance(detail, list):
        assert any(p["path"] == path for p in detail) if path is not None else True, detail
        assert any(words.lower() in p["msg"].lower() for p in detail), detail
    else:
        assert words.lower() in detail.lower(), detail


@pytest.mark.parametrize("body,status,path,words", [c[1:] for c in SHOW_CASES], ids=[c[0] for c in SHOW_CASES])
def test_bad_show_file_create_and_update(client, body, status, path, words):
    before = snapshot(client)
    raw = body if isinstance(body, bytes) else body.encode()
    r = client.post("/api/shows", content=raw, headers={"Content-Type": "application/json"})
    assert_names(r, status, path, words)
    # The same show file as an update of an existing show (bare body + If-Match): refused, nothing changes.
    u = client.put(f"/api/shows/{client.existing}", content=raw,
                   headers={"Content-Type": "application/json", "If-Match": '"1"'})
    assert 400 <= u.status_code < 500, u.text
    assert snapshot(client) == before


def test_bad_revision_and_wrapper(client):
    before = snapshot(client)
    sid = client.existing
    for body, path in (({"revision": "1", "show": SHOW}, "revision"), ({"revision": 0, "show": SHOW}, "revision"),
                       ({"show": SHOW}, "revision"), ({"revision": 1, "show": [1]}, "show"),
                       ({"revision": 1, "show": SHOW, "extra": 1}, "extra")):
        r = client.put(f"/api/shows/{sid}", json=body)
        assert_names(r, 422, path, "")
    r = client.put(f"/api/shows/{sid}", json={"revision": 1, "show": show(drones=20_001)})
    assert_names(r, 422, "show.drones", "20000")
    assert snapshot(client) == before


def _gigabyte(pulled: list):
    for _ in range(1024):
        pulled.append(1)
        yield b" " * (1 << 20)


def test_one_gigabyte_upload_with_content_length_is_refused_at_once(client):
    before = snapshot(client)
    pulled: list = []
    headers = {"Content-Type": "application/json", "Content-Length": str(1 << 30)}
    r = client.post("/api/shows", content=_gigabyte(pulled), headers=headers)
    assert r.status_code == 413 and "20 MB" in r.json()["detail"]
    assert len(pulled) <= 1  # the declared length alone decided
    assert snapshot(client) == before


def test_one_gigabyte_chunked_upload_is_refused_while_streaming(tmp_path):
    """Over a real socket: a chunked 1 GB body gets 413 once 20 MB have arrived; the rest is never read."""
    server = ServerProcess(tmp_path)
    server.start()
    try:
        sent_mb, answer = 0, b""
        with socket.create_connection(("127.0.0.1", server.port), timeout=30) as sock:
            sock.sendall(f"POST /api/shows HTTP/1.1\r\nHost: 127.0.0.1:{server.port}\r\n"
                         "Content-Type: application/json\r\nTransfer-Encoding: chunked\r\n\r\n".encode())
            chunk = b"100000\r\n" + b" " * (1 << 20) + b"\r\n"
            try:
                while sent_mb < 1024 and not select.select([sock], [], [], 0)[0]:
                    sock.sendall(chunk)
                    sent_mb += 1
            except (BrokenPipeError, ConnectionResetError):
                pass  # the server hung up after answering
            sock.settimeout(10)
            while b"\r\n\r\n" not in answer:
                answer += sock.recv(65536)
        assert answer.startswith(b"HTTP/1.1 413"), answer[:200]
        assert sent_mb < 64, sent_mb  # 20 MB limit (+ socket buffers), never the whole gigabyte
        assert httpx.get(f"{server.base}/api/shows").json()["total"] == 0
    finally:
        server.stop()


def png_bomb(width: int = 100_000, height: int = 100_000) -> bytes:
    """A 74-byte PNG that claims 10 gigapixels."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(b"\0" * 1000))
            + chunk(b"IEND", b""))


def test_decompression_bomb_png(client):
    before = snapshot(client)
    for w, h in ((100_000, 100_000), (7000, 7000)):  # over Pillow's own guard, and just over our 40 MP
        bomb = png_bomb(w, h)
        assert len(bomb) < 200
        r = client.post("/api/formations/image", files={"file": ("bomb.png", bomb, "image/png")}, data={"n": "10"})
        assert r.status_code == 413, r.text
        assert "pixels" in r.json()["detail"]
    assert snapshot(client) == before


SVG_NS = 'xmlns="http://www.w3.org/2000/svg"'
CIRCLE = '<circle cx="50" cy="50" r="40" stroke="red" fill="none"/>'
SVG_CASES = [
    ("external entity", f'<?xml version="1.0"?><!DOCTYPE svg [<!ENTITY x SYSTEM "file:///etc/passwd">]>'
                        f'<svg {SVG_NS}><text>&x;</text></svg>', "entity"),
    ("entity expansion", '<?xml version="1.0"?><!DOCTYPE svg [<!ENTITY a "aaaaaaaaaa">'
                         '<!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;"><!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;">]>'
                         f'<svg {SVG_NS}><text>&c;</text></svg>', "entity"),
    ("script element", f'<svg {SVG_NS} width="100" height="100"><script>alert(1)</script>{CIRCLE}</svg>',
     "<script>"),
    ("event handler", f'<svg {SVG_NS} width="100" height="100" onload="alert(1)">{CIRCLE}</svg>', "onload"),
    ("javascript: link", f'<svg {SVG_NS} xmlns:xlink="http://www.w3.org/1999/xlink" width="100" height="100">'
                         f'<a xlink:href="javascript:alert(1)">{CIRCLE}</a></svg>', "external reference"),
    ("external image", f'<svg {SVG_NS} width="100" height="100"><image href="http://evil.example/x.png"/>'
                       f'{CIRCLE}</svg>', "external reference"),
    ("foreignObject", f'<svg {SVG_NS} width="100" height="100"><foreignObject><div/></foreignObject>{CIRCLE}'
                      '</svg>', "foreignObject"),
    ("non-UTF-8 SVG", f'<svg {SVG_NS}><text>Café</text>{CIRCLE}</svg>'.encode("latin-1"), "well-formed"),
    ("not SVG", "<html><body/></html>", "not an SVG"),
]


@pytest.mark.parametrize("svg,words", [c[1:] for c in SVG_CASES], ids=[c[0] for c in SVG_CASES])
def test_unsafe_svg(client, svg, words):
    before = snapshot(client)
    data = svg if isinstance(svg, bytes) else svg.encode()
    r = client.post("/api/formations/svg", files={"file": ("x.svg", data, "image/svg+xml")}, data={"n": "10"})
    assert r.status_code == 422, r.text
    assert words.lower() in r.json()["detail"][0]["msg"].lower()
    assert snapshot(client) == before


def test_plain_svg_still_works(client):
    r = client.post("/api/formations/svg", files={"file": ("x.svg", f"<svg {SVG_NS} width='100' height='100'>"
                                                  f"{CIRCLE}</svg>".encode(), "image/svg+xml")}, data={"n": "10"})
    assert r.status_code == 200 and r.json()["count"] == 10


@pytest.mark.parametrize("params,path", [
    ({"kind": "circle", "n": 20_001}, "n"), ({"kind": "circle", "n": "ten"}, "n"),
    ({"kind": "circle", "n": 10, "center_m": [0, 0, "x"]}, "center_m[2]"), ({"kind": "blob", "n": 10}, "kind"),
    ({"kind": "circle", "n": 10, "size_m": 1e308 * 10}, "size_m"),
])
def test_bad_formation_parameters(client, params, path):
    r = client.post("/api/formations/shape", content=json.dumps(params).encode(),
                    headers={"Content-Type": "application/json"})
    assert_names(r, 422, path, "")


def test_text_with_nul_and_10kb(client):
    for body in ({"text": "a\u0000b", "n": 10}, {"text": "x" * 10_000, "n": 10}):
        r = client.post("/api/formations/text", json=body)
        assert r.status_code == 422, r.text


def test_names_with_dot_dot_and_slashes_are_text_never_paths(client):
    """'../' and slashes are legitimate in a name ('AC/DC tribute'); names are never used as paths, and
    export file names are reduced to safe characters."""
    r = client.post("/api/shows", json=show(name="../../etc/passwd/AC\\DC"))
    assert r.status_code == 201
    sid = r.json()["id"]
    assert client.get(f"/api/shows/{sid}").json()["name"] == "../../etc/passwd/AC\\DC"
    disposition = client.get(f"/api/shows/{sid}/export/show").headers["content-disposition"]
    filename = disposition.split("filename=")[1].strip('"')
    assert "/" not in filename and "\\" not in filename and not filename.startswith(".")
    assert client.delete(f"/api/shows/{sid}").status_code == 204


@pytest.mark.parametrize("content,words", [
    (text(show(drones=20_001)).encode(), "drones"),
    (replaced('"hold_s": 2.0', '"hold_s": NaN').encode(), "formations[0].hold_s"),
    (text(show())[:100].encode(), "JSON"),
    (text(show(name="Café")).encode("latin-1"), "UTF-8"),
    (text(show(name="a\u0000b")).encode(), "name"),
])
def test_cli_validate_exit_2_naming_the_field(tmp_path, content, words):
    path = tmp_path / "bad.json"
    path.write_bytes(content)
    r = subprocess.run([*swarmshow_command(), "validate", str(path)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2, r.stderr
    assert words in r.stderr and len(r.stderr.strip().splitlines()) == 1
