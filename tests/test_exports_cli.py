"""``swarmshow export``: exit codes, atomic writes, and hostile names that must not escape."""

from __future__ import annotations

import io
import json
import re
import zipfile
from pathlib import Path

import pytest

from app.cli import main
from app.exports import EXPORT_FORMATS, drone_file_stems, export_show, safe_stem
from app.exports._core import ORIGIN_FORMATS
from formations import dump_show, parse_show
from tests.conftest import make_show, ring

SAFE = re.compile(r"[A-Za-z0-9._+-]+")
HOSTILE = [
    "../../../etc/passwd",
    "/absolute/path",
    "..",
    ".",
    "",
    "   ",
    "a\x00b",
    "C:\\Windows\\system32",
    "con",
    "NUL.txt",
    "x" * 5000,
    "-rf",
    ".hidden",
    "ünïcödé ✈ name",
    "a/b",
    "a/b",
]


@pytest.fixture(scope="module")
def show():
    return make_show(
        [{"name": "ring", "hold_s": 1.0, "points": ring(len(HOSTILE), 12.0), "color": "#ff0000"}],
        drones=len(HOSTILE), rows=4, cols=4, spacing_m=4.5,
    )


@pytest.fixture(scope="module")
def hostile_show(show):
    data = json.loads(dump_show(show))
    data["name"] = "../../" + "evil/" * 50 + "x" * 150
    data["name"] = data["name"][:200]
    return parse_show(data)


@pytest.fixture(scope="module")
def plan(show):
    from sim import plan_show

    return plan_show(show)


def _check_member_names(names: list[str]) -> None:
    assert len(names) == len(set(names))
    for n in names:
        assert SAFE.fullmatch(n), n
        assert not n.startswith(("-", ".")) and ".." not in n.split(".")[0:1]
        assert len(n) <= 100


@pytest.mark.parametrize("name", HOSTILE)
def test_safe_stem(name):
    stem = safe_stem(name)
    assert SAFE.fullmatch(stem)
    assert stem not in (".", "..") and not stem.startswith((".", "-"))
    assert len(stem) <= 64
    assert stem.split(".")[0].upper() not in {"CON", "NUL", "PRN", "AUX"}


def test_drone_stems_are_unique_and_safe():
    stems = drone_file_stems(len(HOSTILE), HOSTILE)
    assert len(set(s.lower() for s in stems)) == len(HOSTILE)
    assert all(SAFE.fullmatch(s) for s in stems)
    assert drone_file_stems(3) == ["drone_001", "drone_002", "drone_003"]
    assert drone_file_stems(1500)[-1] == "drone_1500"


@pytest.mark.parametrize("fmt", [f for f in EXPORT_FORMATS if f not in ("show", "viser-html")])
def test_hostile_names_never_escape_the_archive(hostile_show, plan, fmt, tmp_path):
    # The origin only where it is used: the other formats refuse it (tests/test_exports_origin_unused.py).
    result = export_show(hostile_show, fmt, plan=plan, drone_names=HOSTILE,
                         origin=(47.0, 8.0, 400.0) if fmt in ORIGIN_FORMATS else None)
    assert SAFE.fullmatch(result.filename) and "/" not in result.filename
    assert len(result.filename) <= 100
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        names = z.namelist()
        _check_member_names(names)
        out = tmp_path / "extract"
        out.mkdir()
        z.extractall(out)
    extracted = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert len(extracted) == len(names)
    assert all(out.resolve() in p.resolve().parents for p in extracted)


def _write_show(tmp_path: Path, show) -> Path:
    path = tmp_path / "show.json"
    path.write_text(dump_show(show))
    return path


def test_cli_writes_each_format(show, tmp_path, capsys):
    src = _write_show(tmp_path, show)
    for fmt in ("show", "skybrush-csv", "skyc", "crazyswarm", "qgc-plan", "qgc-wpl", "waypoints-csv"):
        out = tmp_path / f"out-{fmt}.bin"
        # --fps only where the format samples: the others refuse it (tests/test_exports_flown_preset.py).
        rate = ["--fps", "2"] if fmt in ("skybrush-csv", "waypoints-csv") else []
        place = ["--origin", "47.1,8.2,420"] if fmt in ORIGIN_FORMATS else []
        # --heading where the format uses it: the show file keeps its heading in settings.geo and refuses it.
        heading = [] if fmt == "show" else ["--heading", "15"]
        code = main(["export", str(src), "--format", fmt, "-o", str(out), *place, *heading, *rate])
        assert code == 0, capsys.readouterr().err
        data = out.read_bytes()
        if fmt == "show":
            assert parse_show(data) == show
        else:
            with zipfile.ZipFile(io.BytesIO(data)) as z:
                assert z.testzip() is None
    # Atomic writes leave no temporary files behind.
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".swarmshow-")]


def test_cli_output_directory_gets_the_sanitised_name(hostile_show, tmp_path):
    src = _write_show(tmp_path, hostile_show)
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    assert main(["export", str(src), "--format", "skyc", "-o", str(out_dir)]) == 0
    files = list(out_dir.iterdir())
    assert len(files) == 1 and files[0].parent == out_dir and files[0].suffix == ".skyc"
    # Nothing was written anywhere else under tmp_path.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "show.json"]


def test_cli_stdout(show, tmp_path, capsysbinary):
    src = _write_show(tmp_path, show)
    assert main(["export", str(src), "--format", "crazyswarm", "-o", "-"]) == 0
    data = capsysbinary.readouterr().out
    with zipfile.ZipFile(io.BytesIO(data)) as z:
        assert "drone_001.csv" in z.namelist()


def test_cli_overwrites_atomically(show, tmp_path):
    src = _write_show(tmp_path, show)
    out = tmp_path / "show-copy.json"
    out.write_text("old")
    assert main(["export", str(src), "--format", "show", "-o", str(out)]) == 0
    assert parse_show(out.read_bytes()) == show


@pytest.mark.parametrize(
    "extra, reason",
    [
        (["--format", "gcode"], "unknown format"),
        (["--format", "qgc-wpl"], "--origin"),
        (["--format", "qgc-plan", "--origin", "1"], "--origin"),
        (["--format", "qgc-plan", "--origin", "1,2,3,4"], "--origin"),
        (["--format", "qgc-plan", "--origin", "nan,2"], "--origin"),
        (["--format", "qgc-plan", "--origin", "47,8", "--heading", "400"], "--heading"),
        (["--format", "qgc-plan", "--origin", "47,8", "--heading", "-360.5"], "--heading"),
        (["--format", "qgc-plan", "--origin", "47,8", "--heading", "nan"], "--heading"),
        (["--format", "qgc-plan", "--origin", "47,8", "--heading", "inf"], "--heading"),
        (["--format", "qgc-plan", "--origin", "a,b,c"], "--origin"),
        (["--format", "qgc-plan", "--origin", "95,0,0"], "latitude"),
        (["--format", "skybrush-csv", "--fps", "0"], "fps"),
        (["--format", "skybrush-csv", "--fps", "nan"], "fps"),
        (["--format", "skyc", "--source", "simulated"], "simulated"),
        (["--format", "crazyswarm", "--scale", "0"], "scale"),
        (["--format", "crazyswarm", "--offset", "1,2"], "--offset"),
        (["--format", "crazyswarm", "--offset", "1,2,x"], "--offset"),
        # The show file keeps its heading in settings.geo: --heading was dropped without a word (review).
        (["--format", "show", "--heading", "30"], "--heading"),
        (["--format", "show", "--offset", "0,0,1"], "--offset"),
    ],
)
def test_cli_bad_options_exit_2(show, tmp_path, capsys, extra, reason):
    src = _write_show(tmp_path, show)
    out = tmp_path / "out.zip"
    assert main(["export", str(src), "-o", str(out), *extra]) == 2
    err = capsys.readouterr().err
    assert reason in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_cli_takes_a_zero_offset_for_every_format_as_the_library_does(show, tmp_path, capsys):
    """0,0,0 moves nothing (as --scale 1): ``export_show`` takes it for any format, and so does the CLI (it refused
    it outside crazyswarm; failed before: exit 2). The file is the one written without it."""
    src = _write_show(tmp_path, show)
    plain, zero = tmp_path / "plain.json", tmp_path / "zero.json"
    assert main(["export", str(src), "--format", "show", "-o", str(plain)]) == 0
    assert main(["export", str(src), "--format", "show", "--offset", "0,0,0", "-o", str(zero)]) == 0, \
        capsys.readouterr().err
    assert zero.read_bytes() == plain.read_bytes() == export_show(show, "show", offset_m=(0.0, 0.0, 0.0)).content


def test_cli_bad_paths_exit_2(show, tmp_path, capsys):
    src = _write_show(tmp_path, show)
    assert main(["export", str(tmp_path / "missing.json"), "--format", "skyc", "-o", str(tmp_path / "a")]) == 2
    assert main(["export", str(src), "--format", "skyc", "-o", str(tmp_path / "no" / "such" / "dir" / "a")]) == 2
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    assert main(["export", str(bad), "--format", "skyc", "-o", str(tmp_path / "a")]) == 2
    assert "error" in capsys.readouterr().err


def test_cli_prints_warnings(tmp_path, capsys):
    show = make_show(
        [{"name": f"f{k}", "hold_s": 1.0, "points": ring(4, 8.0 + 2 * (k % 2)), "color": "#ffffff"}
         for k in range(17)],
        drones=4, rows=2, cols=2, spacing_m=4.5,
    )
    src = _write_show(tmp_path, show)
    assert main(["export", str(src), "--format", "crazyswarm", "-o", str(tmp_path / "c.zip")]) == 0
    assert "warning" in capsys.readouterr().err


def test_cli_scale_and_offset_reach_the_crazyswarm_files(show, tmp_path):
    src = _write_show(tmp_path, show)
    out = tmp_path / "c.zip"
    assert main(["export", str(src), "--format", "crazyswarm", "--scale", "0.5", "--offset", "1,2,3",
                 "-o", str(out)]) == 0
    with zipfile.ZipFile(out) as z:
        manifest = json.loads(z.read("manifest.json"))
        first = sorted(n for n in z.namelist() if n.endswith(".csv"))[0]
        row = z.read(first).decode().splitlines()[1].split(",")
    assert manifest["scale"] == 0.5 and manifest["offset_m"] == [1.0, 2.0, 3.0]
    assert float(row[1 + 16]) == pytest.approx(3.0, abs=1e-9)  # z^0 of the first piece, on the ground: 0.5·0 + 3


def test_cli_usage_errors_are_one_line(show, tmp_path, capsys):
    """argparse's own refusals (a non-number, an unknown command) are one line too, exit 2 (QA: they printed the
    whole usage block first)."""
    src = _write_show(tmp_path, show)
    for argv in (["export", str(src), "-f", "skyc", "-o", str(tmp_path / "a"), "--heading", "north"],
                 ["exprot", str(src)]):
        with pytest.raises(SystemExit) as info:
            main(argv)
        err = capsys.readouterr().err.strip()
        assert info.value.code == 2 and "\n" not in err and err.startswith("swarmshow"), err


@pytest.fixture(scope="module")
def api(tmp_path_factory):
    from fastapi.testclient import TestClient

    from app.server import create_app
    from app.settings import AppSettings

    app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp("data"), workers=1, viewer=False))
    with TestClient(app, base_url="http://127.0.0.1") as c:
        yield c


def test_cli_and_api_share_the_origin_and_heading_rules(show, tmp_path, capsys, api):
    """QA: ``--heading 400`` was accepted (the API refuses > 360) and ``--origin`` needed an altitude (the API takes
    'lat,lon'). Both now go through ``app.exports.parse_origin`` / ``check_heading``: the same values pass or fail,
    and 'lat,lon' means altitude 0 in both (the file is the one of 'lat,lon,0', and the API's)."""
    from app.exports import MAX_HEADING_DEG

    src = _write_show(tmp_path, show)
    sid = api.post("/api/shows", content=dump_show(show), headers={"content-type": "application/json"}).json()["id"]
    # The API's query bound is the shared constant.
    schema = api.get("/api/openapi.json").json()["paths"]["/api/shows/{show_id}/export/{fmt}"]["get"]["parameters"]
    heading = next(p for p in schema if p["name"] == "heading_deg")["schema"]
    heading = next(s for s in heading.get("anyOf", [heading]) if s.get("type") == "number")  # optional: or null
    assert heading["maximum"] == MAX_HEADING_DEG and heading["minimum"] == -MAX_HEADING_DEG

    def cli(origin: str, heading: str) -> tuple[int, bytes | None]:
        out = tmp_path / "out.waypoints"
        out.unlink(missing_ok=True)
        code = main(["export", str(src), "-f", "qgc-wpl", "-o", str(out), "--origin", origin, "--heading", heading])
        capsys.readouterr()
        return code, out.read_bytes() if out.exists() else None

    def http(origin: str, heading: str) -> tuple[int, bytes]:
        r = api.get(f"/api/shows/{sid}/export/qgc-wpl", params={"origin": origin, "heading_deg": heading})
        return r.status_code, r.content

    for origin, heading in (("47.1,8.2", "0"), ("47.1,8.2,0", "0"), ("47.1,8.2", "360"), ("47.1,8.2", "-360"),
                            ("47.1,8.2,12.5", "359.5")):
        code, data = cli(origin, heading)
        status, body = http(origin, heading)
        assert code == 0 and status == 200, (origin, heading, code, status, body[:200])
        assert data == body, (origin, heading)
    assert cli("47.1,8.2", "0") == cli("47.1,8.2,0", "0")
    assert cli("47.1,8.2", "0") != cli("47.1,8.2,12.5", "0")  # the altitude is used when given
    for origin, heading in (("47.1,8.2", "400"), ("47.1,8.2", "-360.5"), ("47.1", "0"), ("a,b", "0"),
                            ("47.1,8.2,1,2", "0"), ("inf,8.2", "0"), ("95,8.2", "0")):
        code, data = cli(origin, heading)
        status, body = http(origin, heading)
        assert code == 2 and data is None and status == 422, (origin, heading, code, status)
        field = "heading_deg" if heading not in ("0",) else "origin"
        assert json.loads(body)["detail"][0]["path"] == field, (origin, heading, body)


def test_an_explicit_heading_turns_a_show_with_a_stored_place(show, tmp_path, capsys, api):
    """QA: with ``settings.geo`` in the show, ``--heading 90`` (and the API's ``heading_deg=90``) without an origin
    was silently replaced by the stored heading. Given, it turns the show about its stored origin; not given, the
    stored heading holds."""
    doc = json.loads(dump_show(show))
    doc["settings"]["geo"] = {"origin_lat_deg": 47.1, "origin_lon_deg": 8.2, "origin_alt_m": 12.0, "heading_deg": 30.0}
    src = tmp_path / "geo.json"
    src.write_text(json.dumps(doc))
    sid = api.post("/api/shows", json=doc).json()["id"]

    def cli(*extra: str) -> bytes:
        out = tmp_path / "geo.waypoints"
        out.unlink(missing_ok=True)
        assert main(["export", str(src), "-f", "qgc-wpl", "-o", str(out), *extra]) == 0
        capsys.readouterr()
        return out.read_bytes()

    def http(**params: str) -> bytes:
        r = api.get(f"/api/shows/{sid}/export/qgc-wpl", params=params)
        assert r.status_code == 200, r.text
        return r.content

    stored = cli("--origin", "47.1,8.2,12", "--heading", "30")
    turned = cli("--origin", "47.1,8.2,12", "--heading", "90")
    assert stored != turned
    assert cli() == stored == http()
    assert cli("--heading", "90") == turned == http(heading_deg="90")
