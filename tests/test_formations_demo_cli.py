"""The bundled demo show and the ``swarmshow formation ...`` commands."""

from __future__ import annotations

import io
import json
import math

import numpy as np
import pytest
from PIL import Image, ImageDraw
from scipy.spatial.distance import pdist

from app.cli import main as cli_main
from formations import dump_show, parse_show
from formations._demo import DEMO_SHOW_FILE, demo_show, load_demo_show
from sim import check_show


def min_dist(points: np.ndarray) -> float:
    return float(pdist(points).min()) if len(points) > 1 else math.inf


# -- demo show -------------------------------------------------------------------------------


def test_bundled_json_equals_demo_show():
    built = demo_show()
    bundled = load_demo_show()
    assert bundled == built
    assert parse_show(dump_show(built)) == built
    from importlib import resources

    raw = resources.files("formations").joinpath("data", DEMO_SHOW_FILE).read_text()
    assert json.loads(raw) == json.loads(dump_show(built))


def test_demo_show_shape_and_safety():
    show = load_demo_show()
    assert show.drones == 100
    grid = show.home.grid
    assert (grid.rows, grid.cols, grid.spacing_m) == (10, 10, 4.5)
    assert show.settings.model_dump() == type(show.settings)().model_dump()  # default settings
    assert len(show.formations) >= 4
    for f in show.formations:
        pts = f.points_m
        assert len(pts) >= show.drones
        # CAPT guarantees spacing / sqrt 2 in flight: >= 4.3 m keeps the 3 m minimum.
        assert min_dist(pts) >= 4.3, f.name
        assert pts[:, 2].min() >= 15.0 and pts[:, 2].max() <= show.settings.max_altitude_m
        assert f.colors is not None and len(set(f.colors)) >= 1 and "#000000" not in f.colors
    report = check_show(show)
    assert report.ok, [v.message for v in report.violations]
    assert report.violations == [] and report.min_distance_m >= show.settings.min_distance_m


# -- CLI -------------------------------------------------------------------------------------


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli_main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_shape_to_stdout_and_file(capsys, tmp_path):
    code, out, _ = run(capsys, "formation", "shape", "circle", "-n", "20", "--size-m", "40",
                       "--center", "1,2,50", "--color", "#ff0000")
    assert code == 0
    doc = json.loads(out)
    pts = np.array(doc["points"])
    assert pts.shape == (20, 3) and doc["colors"] == ["#ff0000"] * 20
    assert np.allclose(np.hypot(pts[:, 0] - 1, pts[:, 2] - 50), 20.0) and np.allclose(pts[:, 1], 2.0)
    assert doc["min_spacing_m"] == pytest.approx(min_dist(pts))

    target = tmp_path / "points.json"
    code, out, err = run(capsys, "formation", "shape", "polygon", "-n", "10", "--size-m", "30",
                         "--param", "sides=5", "--plane", "xy", "-o", str(target))
    assert code == 0 and out == "" and "wrote 10 points" in err
    pts = np.array(json.loads(target.read_text())["points"])
    assert len(pts) == 10 and np.allclose(pts[:, 2], 30.0)


def test_cli_too_many_points_exits_2_with_max_n(capsys):
    code, out, err = run(capsys, "formation", "shape", "heart", "-n", "400", "--size-m", "40")
    assert code == 2 and out == ""
    line = err.strip()
    assert "\n" not in line and "largest N that fits is" in line
    max_n = int(line.split("largest N that fits is ")[1].split()[0])
    assert run(capsys, "formation", "shape", "heart", "-n", str(max_n), "--size-m", "40")[0] == 0


@pytest.mark.parametrize(
    "argv",
    [
        ["formation", "shape", "star", "-n", "10", "--param", "bogus=1"],
        ["formation", "shape", "circle", "-n", "0"],
        ["formation", "shape", "circle", "-n", "5", "--color", "red"],
        ["formation", "svg", "/nonexistent/file.svg", "-n", "5"],
        ["formation", "image", "/nonexistent/file.png", "-n", "5"],
        ["formation", "text", "", "-n", "5"],
    ],
)
def test_cli_bad_input_exits_2(capsys, argv):
    code, out, err = run(capsys, *argv)
    assert code == 2 and out == "" and err.startswith("swarmshow: error: ")


def test_cli_usage_errors_exit_2(capsys):
    for argv in (["formation", "shape", "blob", "-n", "5"], ["formation", "shape", "circle", "-n", "5",
                                                               "--center", "1,2"]):
        with pytest.raises(SystemExit) as info:
            cli_main(argv)
        assert info.value.code == 2
    capsys.readouterr()


def test_cli_text_image_svg(capsys, tmp_path):
    code, out, _ = run(capsys, "formation", "text", "HI\\nYOU", "-n", "30", "--height-m", "30",
                       "--color", "#00ff00")
    assert code == 0 and len(json.loads(out)["points"]) == 30

    im = Image.new("RGB", (100, 100), "black")
    ImageDraw.Draw(im).ellipse([10, 10, 90, 90], fill=(255, 128, 0))
    buf = io.BytesIO()
    im.save(buf, "PNG")
    png = tmp_path / "disk.png"
    png.write_bytes(buf.getvalue())
    code, out, _ = run(capsys, "formation", "image", str(png), "-n", "25", "--width-m", "40")
    doc = json.loads(out)
    assert code == 0 and len(doc["points"]) == 25 and set(doc["colors"]) == {"#ff8000"}

    svg = tmp_path / "line.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg"><path d="M 0 0 L 100 0" stroke="#0000ff"/></svg>')
    code, out, _ = run(capsys, "formation", "svg", str(svg), "-n", "8", "--width-m", "40")
    doc = json.loads(out)
    assert code == 0 and len(doc["points"]) == 8 and set(doc["colors"]) == {"#0000ff"}

    svg.write_text('<!DOCTYPE svg [<!ENTITY a "b">]><svg xmlns="http://www.w3.org/2000/svg">&a;</svg>')
    code, out, err = run(capsys, "formation", "svg", str(svg), "-n", "8")
    assert code == 2 and "DOCTYPE" in err


def test_cli_sources_name_their_formation(capsys, tmp_path):
    """The JSON carries the name a designer expects: the file's stem, the text, the shape's kind."""
    svg = tmp_path / "Company Logo.final.svg"
    svg.write_text('<svg xmlns="http://www.w3.org/2000/svg"><path d="M 0 0 L 100 0" stroke="#0000ff"/></svg>')
    code, out, _ = run(capsys, "formation", "svg", str(svg), "-n", "8", "--width-m", "40")
    assert code == 0 and json.loads(out)["name"] == "Company Logo.final"
    code, out, _ = run(capsys, "formation", "text", "HI\\nYOU", "-n", "30", "--height-m", "30")
    assert code == 0 and json.loads(out)["name"] == "HI YOU"
    code, out, _ = run(capsys, "formation", "shape", "heart", "-n", "12", "--size-m", "30")
    assert code == 0 and json.loads(out)["name"] == "heart"


def test_cli_repair(capsys, tmp_path):
    src = tmp_path / "in.json"
    pts = [[0.0, 0.0, 30.0], [0.5, 0.0, 30.0], [10.0, 0.0, 30.0]]
    src.write_text(json.dumps({"points": pts, "colors": ["#ff0000", "#00ff00", "#0000ff"]}))
    code, out, _ = run(capsys, "formation", "repair", str(src), "--min-spacing-m", "3")
    doc = json.loads(out)
    assert code == 0 and min_dist(np.array(doc["points"])) >= 3.0
    assert doc["colors"] == ["#ff0000", "#00ff00", "#0000ff"]
    src.write_text("{not json")
    assert run(capsys, "formation", "repair", str(src))[0] == 2


def test_cli_repair_rejects_bad_points_and_colours(capsys, tmp_path):
    src = tmp_path / "in.json"
    src.write_text(json.dumps({"points": [[0.0, 0.0], [1.0, 0.0]]}))
    code, _, err = run(capsys, "formation", "repair", str(src))
    assert code == 2 and "points" in err
    src.write_text(json.dumps({"points": [[0.0, 0.0, 20.0], [1.0, 0.0, 20.0]], "colors": ["#ff0000", "red"]}))
    code, _, err = run(capsys, "formation", "repair", str(src))
    assert code == 2 and "colors[1]" in err


def test_sources_exports_everything_it_lists():
    import formations.sources as sources

    for name in sources.__all__:
        assert getattr(sources, name) is not None
    for name in ("generate_shape", "stroke_points", "text_points", "image_points", "svg_points", "repair_spacing",
                 "fit_to_count", "scale", "rotate", "translate", "place_on_plane", "PointSet", "FormationError",
                 "InputTooLargeError", "SHAPE_KINDS", "MAX_POINTS", "MAX_IMAGE_PIXELS", "MAX_SVG_BYTES"):
        assert name in sources.__all__
    assert sources.MAX_IMAGE_PIXELS == 40_000_000 and sources.MAX_SVG_BYTES == 5 * 1024 * 1024
