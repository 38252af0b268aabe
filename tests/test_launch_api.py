"""Launch layouts through the API and the CLI: home CSV upload, boxed shows stored, bad input 4xx / exit 2 naming
the field."""

from __future__ import annotations

import json

import numpy as np
import pytest
from fastapi.testclient import TestClient

from app.cli import main
from app.server import create_app
from app.settings import AppSettings
from formations import MAX_HOME_CSV_BYTES, dump_show, home_points_to_csv, parse_show
from tests.test_launch import boxes_show


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("data"), workers=1))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


def _upload(client, data: bytes):
    return client.post("/api/formations/home-csv", files={"file": ("homes.csv", data, "text/csv")})


def test_home_csv_upload_round_trips(client):
    pts = np.array([[x * 3.0, y * 3.0, 0.0] for x in range(8) for y in range(6)])
    r = _upload(client, home_points_to_csv(pts).encode())
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["count"] == 48 and body["names"][0] == "Drone 1"
    np.testing.assert_array_equal(np.array(body["points"]), pts)
    assert body["min_spacing_m"] == pytest.approx(3.0)
    # ...and the points make a show the API stores.
    doc = boxes_show().model_dump(mode="json", exclude_none=True)
    doc["home"] = {"points": body["points"]}
    assert client.post("/api/shows", json=doc).status_code in (200, 201)


@pytest.mark.parametrize("data, status, words", [
    (b"Name,x,y,z\nA,1,2,0\nB,1,x,0\n", 422, "line 3"),
    (b"1,2,3,4,5\n", 422, "line 1"),
    (b"", 422, "empty"),
    (b"\xff\xfe\x00", 422, "UTF-8"),
])
def test_bad_home_csv_is_422_naming_the_file_and_line(client, data, status, words):
    r = _upload(client, data)
    assert r.status_code == status, r.text
    assert r.json()["detail"][0]["path"] == "file" and words in r.json()["detail"][0]["msg"]


def test_oversized_home_csv_is_413(client):
    r = _upload(client, b"1,2\n" * (MAX_HOME_CSV_BYTES // 4 + 10))
    assert r.status_code == 413


def test_boxed_show_is_stored_and_bad_boxes_name_the_field(client):
    doc = boxes_show().model_dump(mode="json", exclude_none=True)
    r = client.post("/api/shows", json=doc)
    assert r.status_code in (200, 201), r.text
    doc["home"]["boxes"]["grid"]["spacing_m"] = 3.0
    r = client.post("/api/shows", json=doc)
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "home.boxes.grid.spacing_m"
    doc["home"]["boxes"]["spacing_m"] = "0.8"
    r = client.post("/api/shows", json=doc)
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "home.boxes.spacing_m"


def test_cli_sets_boxes_and_csv_homes(tmp_path, capsys):
    show = boxes_show()
    src = tmp_path / "show.json"
    src.write_text(dump_show(show))
    out = tmp_path / "boxed.json"
    assert main(["home", str(src), "--boxes", "8", "--box-spacing", "0.8", "--box-cols", "4", "--rows", "2",
                 "--cols", "3", "-o", str(out)]) == 0
    boxed = parse_show(out.read_bytes())
    np.testing.assert_allclose(boxed.home_positions_m, show.home_positions_m)
    csv_path = tmp_path / "homes.csv"
    csv_path.write_text(home_points_to_csv(np.array([[x * 3.0, y * 3.0, 0.0] for x in range(8) for y in range(6)])))
    assert main(["home", str(src), "--csv", str(csv_path)]) == 0
    assert json.loads(capsys.readouterr().out)["home"]["points"][1] == [0.0, 3.0, 0.0]
    csv_path.write_text("1,2\n1,oops\n")
    assert main(["home", str(src), "--csv", str(csv_path)]) == 2
    assert "line 2" in capsys.readouterr().err
    assert main(["home", str(src), "--boxes", "8", "--grid-spacing", "3"]) == 2
    assert "home.boxes.grid.spacing_m" in capsys.readouterr().err
