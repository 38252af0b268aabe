"""REST API, shows: CRUD and import, revision conflicts, limits, check (with its cache), export, OpenAPI."""

from __future__ import annotations

import io
import json
import zipfile

import pytest
from fastapi.testclient import TestClient

from app.server import create_app
from app.settings import MAX_SHOW_BYTES, AppSettings
from formations import dump_show, parse_show


def show_doc(name: str = "api test", *, hold_s: float = 1.0, **settings) -> dict:
    """A valid, safe 4-drone show: a 5 m square at 6-11 m (4.5 m apart at home: CAPT's premise for 3 m)."""
    return {
        "format": "swarmshow/1",
        "name": name,
        "drones": 4,
        "home": {"grid": {"rows": 2, "cols": 2, "spacing_m": 4.5}},
        "settings": {"max_speed_z_mps": 5.0, "max_accel_mps2": 8.0, "takeoff_altitude_m": 3.0, **settings},
        "formations": [{"name": "square", "hold_s": hold_s,
                        "points": [[0, 0, 6], [5, 0, 6], [0, 0, 11], [5, 0, 11]], "color": "#ff0000"}],
    }


def stored(doc: dict) -> dict:
    """The show as the store keeps it (defaults filled in)."""
    return json.loads(dump_show(parse_show(doc)))


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("data"), workers=2))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


def _create(client, doc=None) -> dict:
    r = client.post("/api/shows", json=doc or show_doc())
    assert r.status_code == 201, r.text
    return r.json()


def _count(client) -> int:
    return client.get("/api/shows", params={"limit": 1}).json()["total"]


def test_health(client):
    r = client.get("/api/health")
    assert r.status_code == 200
    body = r.json()
    assert body["status"] == "ok" and body["schema_version"] >= 1 and body["workers"] == 2


def test_create_read_and_list(client):
    rec = _create(client, show_doc("created"))
    assert rec["revision"] == 1 and rec["show"] == stored(show_doc("created")) and rec["drones"] == 4
    r = client.get(f"/api/shows/{rec['id']}")
    assert r.status_code == 200 and r.json() == rec and r.headers["etag"] == '"1"'
    page = client.get("/api/shows", params={"limit": 2}).json()
    assert page["limit"] == 2 and page["total"] >= 1 and "show" not in page["items"][0]
    assert page["items"][0]["id"] == rec["id"]  # newest first


def test_paging(client):
    ids = {_create(client, show_doc(f"page {k}"))["id"] for k in range(3)}
    total = _count(client)
    seen = []
    for offset in range(0, total, 2):
        seen += [s["id"] for s in client.get("/api/shows", params={"limit": 2, "offset": offset}).json()["items"]]
    assert len(seen) == total == len(set(seen)) and ids <= set(seen)
    r = client.get("/api/shows", params={"limit": 0})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "limit"


def test_import_multipart_and_raw(client):
    text = json.dumps(show_doc("imported"))
    r = client.post("/api/shows", files={"file": ("show.json", text, "application/json")})
    assert r.status_code == 201 and r.json()["name"] == "imported"
    assert r.headers["location"] == f"/api/shows/{r.json()['id']}"
    r = client.post("/api/shows", content=text.encode(), headers={"content-type": "application/octet-stream"})
    assert r.status_code == 201 and r.json()["show"] == stored(show_doc("imported"))


def test_invalid_show_is_422_with_the_field_path(client):
    before = _count(client)
    doc = show_doc()
    doc["formations"][0]["hold_s"] = -1
    r = client.post("/api/shows", json=doc)
    assert r.status_code == 422
    (problem,) = r.json()["detail"]
    assert problem["path"] == "formations[0].hold_s" and problem["loc"] == ["body", "formations", 0, "hold_s"]
    assert "greater than or equal to 0.01" in problem["msg"]
    doc = show_doc()
    doc["formations"][0]["points"][1] = [1, 0, 6]  # 1 m from its neighbour: a cross-field rule
    assert client.post("/api/shows", json=doc).json()["detail"][0]["path"] == "formations[0].points"
    for body, ctype in ((b"{not json", "application/json"), (b"", "application/json"), (b"[]", "application/json")):
        r = client.post("/api/shows", content=body, headers={"content-type": ctype})
        assert r.status_code == 422, body
        assert r.json()["detail"][0]["msg"]
    r = client.post("/api/shows", files={"other": ("x.json", b"{}", "application/json")})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "file"
    assert _count(client) == before


def test_show_over_20_mb_is_413_and_not_stored(client):
    before = _count(client)
    big = b" " * (MAX_SHOW_BYTES + 70_000)
    r = client.post("/api/shows", content=big, headers={"content-type": "application/json"})  # Content-Length
    assert r.status_code == 413 and "20 MB" in r.json()["detail"]

    def chunks():
        for _ in range(22):
            yield b" " * (1024 * 1024)

    r = client.post("/api/shows", content=chunks(), headers={"content-type": "application/json"})  # chunked
    assert r.status_code == 413
    # Within the multipart envelope allowance, but the file itself is over: still 413.
    r = client.post("/api/shows", files={"file": ("big.json", b" " * (MAX_SHOW_BYTES + 10), "application/json")})
    assert r.status_code == 413
    assert _count(client) == before


def test_other_requests_are_limited_too(client):
    r = client.post("/api/formations/shape", content=b"{" + b" " * (2 * 1024 * 1024) + b"}",
                    headers={"content-type": "application/json"})
    assert r.status_code == 413


def test_update_with_revisions(client):
    rec = _create(client, show_doc("v1"))
    url = f"/api/shows/{rec['id']}"
    r = client.put(url, json={"revision": 1, "show": show_doc("v2")})
    assert r.status_code == 200 and r.json()["revision"] == 2 and r.json()["name"] == "v2"
    assert r.headers["etag"] == '"2"'
    # Identical content: not a new revision.
    assert client.put(url, json={"revision": 2, "show": show_doc("v2")}).json()["revision"] == 2
    # Stale: 409 with the current revision; nothing overwritten.
    r = client.put(url, json={"revision": 1, "show": show_doc("lost update")})
    assert r.status_code == 409 and r.json()["current_revision"] == 2
    assert client.get(url).json()["name"] == "v2"
    # Bare show file with If-Match.
    r = client.put(url, json=show_doc("v3"), headers={"If-Match": '"2"'})
    assert r.status_code == 200 and r.json()["revision"] == 3
    r = client.put(url, json=show_doc("v4"), headers={"If-Match": '"2"'})
    assert r.status_code == 409 and r.json()["current_revision"] == 3


def test_update_errors(client):
    rec = _create(client, show_doc("update errors"))
    url = f"/api/shows/{rec['id']}"
    r = client.put(url, json={"show": show_doc()})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "revision"
    r = client.put(url, json={"revision": "1", "show": show_doc()})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "revision"
    bad = show_doc()
    bad["formations"][0]["hold_s"] = 0
    r = client.put(url, json={"revision": 1, "show": bad})
    assert r.status_code == 422
    assert r.json()["detail"][0]["path"] == "show.formations[0].hold_s"
    assert r.json()["detail"][0]["loc"] == ["body", "show", "formations", 0, "hold_s"]
    r = client.put(url, json={"revision": 1, "show": show_doc(), "extra": 1})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "extra"
    r = client.put(url, content=b"nope", headers={"content-type": "application/json"})
    assert r.status_code == 422
    assert client.get(url).json()["revision"] == 1  # nothing was written
    assert client.put("/api/shows/nope", json={"revision": 1, "show": show_doc()}).status_code == 404


def test_delete(client):
    rec = _create(client, show_doc("to delete"))
    url = f"/api/shows/{rec['id']}"
    r = client.delete(url, params={"revision": 7})
    assert r.status_code == 409 and r.json()["current_revision"] == 1
    assert client.delete(url, params={"revision": 1}).status_code == 204
    assert client.get(url).status_code == 404
    r = client.delete(url)
    assert r.status_code == 404 and "no show" in r.json()["detail"]


def test_check_report_and_cache(client):
    rec = _create(client, show_doc("check me", hold_s=1.5))
    r = client.post(f"/api/shows/{rec['id']}/check")
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["cached"] is False and body["revision"] == 1 and body["content_hash"] == rec["content_hash"]
    report = body["report"]
    for key in ("duration_s", "min_distance_m", "min_distance_pair", "max_speed_xy_mps", "transitions", "violations"):
        assert key in report
    assert report["ok"] is True and report["transitions"][0]["from"]
    assert [s["kind"] for s in body["plan"]["segments"]][0] == "takeoff"
    again = client.post(f"/api/shows/{rec['id']}/check").json()
    assert again["cached"] is True and again["report"] == report
    # Another show with the same content is the same computation.
    twin = _create(client, show_doc("check me", hold_s=1.5))
    assert client.post(f"/api/shows/{twin['id']}/check").json()["cached"] is True
    assert client.post("/api/shows/nope/check").status_code == 404


def test_check_reports_a_forced_too_short_transition_as_a_violation(client):
    doc = show_doc("too fast", hold_s=1.25)
    doc["formations"][0]["transition_s"] = 0.2
    rec = _create(client, doc)
    report = client.post(f"/api/shows/{rec['id']}/check").json()["report"]
    assert report["ok"] is False and report["violations_total"] >= 1
    # grouped per transition: the forced one fails, names the fix, and its violations carry points to select
    bad = [g for g in report["by_transition"] if not g["ok"]]
    assert [g["formation"] for g in bad] == [0] and bad[0]["kind"] == "transition"
    assert any(v["kind"] == "transition_duration" for v in bad[0]["violations"])
    assert any("formations[0].transition_s" in f for f in bad[0]["fixes"])
    assert all("points" in v for v in bad[0]["violations"])
    assert sum(g["violations_total"] for g in report["by_transition"]) == report["violations_total"]


def test_export_show_file(client):
    rec = _create(client, show_doc("My show/1"))
    r = client.get(f"/api/shows/{rec['id']}/export/show")
    assert r.status_code == 200 and r.json() == stored(show_doc("My show/1"))
    assert r.headers["content-disposition"] == 'attachment; filename="My-show-1.json"'
    assert client.get("/api/shows/nope/export/show").status_code == 404
    r = client.get(f"/api/shows/{rec['id']}/export/nope")
    assert r.status_code == 404 and "one of: show" in r.json()["detail"]


def test_export_formats(client):
    rec = _create(client, show_doc("exported"))
    r = client.get(f"/api/shows/{rec['id']}/export/skybrush-csv", params={"fps": 5})
    assert r.status_code == 200, r.text
    assert len(zipfile.ZipFile(io.BytesIO(r.content)).namelist()) >= 4
    assert json.loads(r.headers["x-swarmshow-warnings"]) == [] or r.headers["x-swarmshow-warnings"]
    # Bad options: 422 naming the reason (ours, or the exporter's).
    r = client.get(f"/api/shows/{rec['id']}/export/qgc-plan", params={"origin": "1,2,x"})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "origin"
    r = client.get(f"/api/shows/{rec['id']}/export/qgc-plan")
    assert r.status_code == 422 and "origin" in r.json()["detail"][0]["msg"]
    r = client.get(f"/api/shows/{rec['id']}/export/qgc-plan", params={"origin": "95,10,0"})
    assert r.status_code == 422 and "latitude" in r.json()["detail"][0]["msg"]
    r = client.get(f"/api/shows/{rec['id']}/export/qgc-plan", params={"origin": "47.4,8.5"})
    assert r.status_code == 200 and r.content
    assert client.get(f"/api/shows/{rec['id']}/export/skyc", params={"fps": 0}).status_code == 422
    # Crazyswarm scale / offset (issue 19): applied, and bad values named.
    r = client.get(f"/api/shows/{rec['id']}/export/crazyswarm", params={"scale": 0.5, "offset": "1,2,3"})
    assert r.status_code == 200, r.text
    manifest = json.loads(zipfile.ZipFile(io.BytesIO(r.content)).read("manifest.json"))
    assert manifest["scale"] == 0.5 and manifest["offset_m"] == [1.0, 2.0, 3.0]
    r = client.get(f"/api/shows/{rec['id']}/export/crazyswarm", params={"offset": "1,2"})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "offset"
    assert client.get(f"/api/shows/{rec['id']}/export/crazyswarm", params={"scale": 0}).status_code == 422


def test_openapi_documents_every_endpoint_and_error(client):
    doc = client.get("/api/openapi.json").json()
    paths = doc["paths"]
    expected = {
        ("/api/health", "get"), ("/api/shows", "get"), ("/api/shows", "post"), ("/api/shows/{show_id}", "get"),
        ("/api/shows/{show_id}", "put"), ("/api/shows/{show_id}", "delete"), ("/api/shows/{show_id}/check", "post"),
        ("/api/shows/{show_id}/simulate", "post"), ("/api/shows/{show_id}/export/{fmt}", "get"),
        ("/api/jobs", "get"), ("/api/jobs/{job_id}", "get"), ("/api/jobs/{job_id}", "delete"),
        ("/api/jobs/{job_id}/events", "get"), ("/api/formations/shape", "post"), ("/api/formations/text", "post"),
        ("/api/formations/image", "post"), ("/api/formations/svg", "post"),
    }
    assert {(p, m) for p, ops in paths.items() for m in ops} >= expected
    schemas = doc["components"]["schemas"]
    needed = {"ShowFile", "ShowUpdate", "ShowOut", "JobOut", "CheckOut", "ValidationErrorOut", "ConflictOut"}
    assert needed <= set(schemas)
    assert "HTTPValidationError" not in json.dumps(doc)
    put = paths["/api/shows/{show_id}"]["put"]
    assert {"200", "404", "409", "413", "422"} <= set(put["responses"])
    assert put["requestBody"]["content"]["application/json"]["schema"]["$ref"].endswith("/ShowUpdate")
    assert "413" in paths["/api/formations/image"]["post"]["responses"]
    assert paths["/api/shows/{show_id}/simulate"]["post"]["responses"]["202"]
    fmt = next(p for p in paths["/api/shows/{show_id}/export/{fmt}"]["get"]["parameters"] if p["name"] == "fmt")
    assert "show" in fmt["schema"]["enum"]
    assert schemas["ShowFile"].get("examples")
    assert client.get("/api/docs").status_code == 200


def test_unknown_routes_are_404(client):
    assert client.get("/api/nope").status_code == 404


def test_large_show_is_validated_in_a_worker(client):
    from app.api.shows import INLINE_PARSE_BYTES

    doc = show_doc("large")
    doc["formations"][0]["points"] = [[4.0 * i, 4.0 * j, 20.0] for i in range(120) for j in range(120)]
    assert len(json.dumps(doc)) > INLINE_PARSE_BYTES
    r = client.post("/api/shows", json=doc)
    assert r.status_code == 201, r.text[:500]
    assert r.json()["show"]["formations"][0]["points"][-1] == [476.0, 476.0, 20.0]
    doc["formations"][0]["hold_s"] = -1.0
    r = client.put(f"/api/shows/{r.json()['id']}", json={"revision": 1, "show": doc})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "show.formations[0].hold_s"


def test_an_internal_error_is_a_json_500(tmp_path, monkeypatch, caplog):
    import app.api.shows as shows_api

    def broken(*_args, **_kwargs):
        raise RuntimeError("disk on fire")

    app = create_app(AppSettings(data_dir=tmp_path, workers=1))
    with TestClient(app, raise_server_exceptions=False, base_url="http://127.0.0.1") as c:
        monkeypatch.setattr(shows_api, "_summary", broken)
        rec = c.post("/api/shows", json=show_doc("x"))
        assert rec.status_code == 500
        body = rec.json()
        # No exception text for the client (issue 14.5); the traceback is logged under the request id.
        assert body["detail"] == "internal error" and "disk on fire" not in rec.text
        assert len(body["request_id"]) == 12
        logged = [r for r in caplog.records if body["request_id"] in r.getMessage()]
        assert logged and "disk on fire" in str(logged[0].exc_info[1])


def test_check_cache_and_shows_survive_a_restart(tmp_path):
    settings = AppSettings(data_dir=tmp_path, workers=1)
    with TestClient(create_app(settings), base_url="http://127.0.0.1") as c:
        sid = _create(c, show_doc("persistent", hold_s=2.5))["id"]
        assert c.post(f"/api/shows/{sid}/check").json()["cached"] is False
    with TestClient(create_app(settings), base_url="http://127.0.0.1") as c:
        assert c.get(f"/api/shows/{sid}").json()["name"] == "persistent"
        assert c.post(f"/api/shows/{sid}/check").json()["cached"] is True


def test_export_refusals_name_the_field(client):
    """Every 422 of an export names the option at fault (QA: the missing origin came back with ``path`` "", so
    neither a script nor the editor could tell which field to fix)."""
    rec = _create(client, show_doc("refused exports"))
    cases = [
        ("qgc-plan", {}, "origin"),  # no settings.geo and no origin
        ("qgc-wpl", {}, "origin"),
        ("qgc-plan", {"origin": "95,10,0"}, "origin"),  # latitude out of range (the exporter's check)
        ("qgc-plan", {"origin": "47,8,1e9"}, "origin"),  # altitude out of range
        ("crazyswarm", {"source": "simulated"}, "source"),  # exact-plan formats refuse the flown source
    ]
    for fmt, params, field in cases:
        r = client.get(f"/api/shows/{rec['id']}/export/{fmt}", params=params)
        assert r.status_code == 422, (fmt, params, r.text)
        problem = r.json()["detail"][0]
        assert problem["path"] == field and problem["loc"] == ["query", field], (fmt, params, problem)


def test_export_of_an_unplannable_show_names_the_show_field(client):
    """QA: a forced transition too short for the limits was refused by every export with loc ["query"] and
    path "" ("the show cannot be planned: formations[1].transition_s = 0.2 s is shorter ..."): the field at fault
    is the show's, and the 422 names it as the check's does."""
    doc = show_doc("too short")
    doc["formations"].append({**doc["formations"][0], "name": "lifted", "transition_s": 0.2,
                              "points": [[x, y, z + 20] for x, y, z in doc["formations"][0]["points"]]})
    rec = _create(client, doc)
    for fmt in ("skyc", "skybrush-csv", "crazyswarm"):
        r = client.get(f"/api/shows/{rec['id']}/export/{fmt}")
        assert r.status_code == 422, (fmt, r.text)
        problem = r.json()["detail"][0]
        assert problem["path"] == "formations[1].transition_s", (fmt, problem)
        assert problem["loc"] == ["show", "formations", 1, "transition_s"], (fmt, problem)
        assert "shorter" in problem["msg"]


def test_show_rule_problems_have_loc_and_path_naming_the_same_field(client):
    """QA: show-level rules answered a coarse loc beside an exact path, e.g. loc ["body","show"] with path
    "show.groups.front", or loc ["body"] with "formations[0].points[0][2]"."""
    high = show_doc("ceiling", max_altitude_m=8.0)
    r = client.post("/api/shows", json=high)
    assert r.status_code == 422
    p = r.json()["detail"][0]
    assert p["path"] == "formations[0].points[2][2]" and p["loc"] == ["body", "formations", 0, "points", 2, 2], p
    rec = _create(client, show_doc("groups"))
    doc = client.get(f"/api/shows/{rec['id']}").json()["show"]
    doc["groups"] = {"front": [0, 1, 99]}
    r = client.put(f"/api/shows/{rec['id']}", json={"revision": rec["revision"], "show": doc})
    assert r.status_code == 422
    p = r.json()["detail"][0]
    assert p["path"] == "show.groups.front" and p["loc"] == ["body", "show", "groups", "front"], p
    assert client.get(f"/api/shows/{rec['id']}").json()["revision"] == rec["revision"]  # nothing stored
