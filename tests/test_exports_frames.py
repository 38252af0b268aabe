"""One frame convention across every export, checked with a non-zero heading (app/exports/_frames.py).

Each drone's home as every format writes it must land on the same spot on Earth:
QGroundControl's WGS84 coordinates, and the .skyc's X, Y placed the way Skybrush Live
places a show (X at ``location.orientation``, Y 90° to its left, from ``location.origin``).
"""

from __future__ import annotations

import io
import json
import math
import zipfile

import numpy as np
import pytest

from app.exports import export_show
from app.exports._frames import local_to_enu, skybrush_orientation_deg
from app.exports._geodesy import geodetic_to_local
from sim import plan_show
from tests.conftest import make_show, ring

HEADING = 30.0
ORIGIN = (47.3977419, 8.5455938, 430.5)


@pytest.fixture(scope="module")
def placed():
    show = make_show([{"name": "ring", "hold_s": 2.0, "points": ring(16, 12.0), "color": "#ff0000"}],
                     drones=16, rows=4, cols=4, spacing_m=4.5,
                     geo={"origin_lat_deg": ORIGIN[0], "origin_lon_deg": ORIGIN[1], "origin_alt_m": ORIGIN[2],
                          "heading_deg": HEADING})
    return show, plan_show(show)


def _skybrush_live_enu(xy: np.ndarray, orientation_deg: float) -> np.ndarray:
    """Where Live puts show X, Y: X along bearing o, Y along bearing o - 90 (left of X). (east, north)."""
    o = math.radians(orientation_deg)
    x_axis = np.array([math.sin(o), math.cos(o)])
    y_axis = np.array([math.sin(o - math.pi / 2), math.cos(o - math.pi / 2)])
    return xy[:, :1] * x_axis + xy[:, 1:2] * y_axis


def test_every_format_puts_the_homes_on_the_same_spot(placed, tmp_path):
    show, plan = placed
    home = plan.knot_positions_m[0]
    # Our convention: +y at the heading, +x 90° clockwise of it.
    enu = local_to_enu(home, HEADING)
    north_of_y = local_to_enu(np.array([[0.0, 1.0, 0.0]]), HEADING)[0]
    assert math.degrees(math.atan2(north_of_y[0], north_of_y[1])) == pytest.approx(HEADING)

    with zipfile.ZipFile(io.BytesIO(export_show(show, "skyc", plan=plan).content)) as z:
        doc = json.loads(z.read("show.json"))
    loc = doc["environment"]["location"]
    assert loc["orientation"] == pytest.approx((HEADING + 90.0) % 360.0)
    assert loc["orientation"] == pytest.approx(skybrush_orientation_deg(HEADING))
    skyc_home = np.array([d["settings"]["home"] for d in doc["swarm"]["drones"]])
    live = _skybrush_live_enu(skyc_home[:, :2], loc["orientation"])
    assert np.abs(live - enu[:, :2]).max() <= 1e-3

    from pymavlink import mavwp

    with zipfile.ZipFile(io.BytesIO(export_show(show, "qgc-wpl", plan=plan).content)) as z:
        manifest = json.loads(z.read("manifest.json"))
        assert manifest["heading_deg"] == HEADING
        for i, name in enumerate(sorted(n for n in z.namelist() if n.endswith(".waypoints"))):
            path = tmp_path / name
            path.write_bytes(z.read(name))
            loader = mavwp.MAVWPLoader()
            loader.load(str(path))
            w = loader.wp(0)
            # Back to east-north-up at the origin (heading 0 = ENU), independent of our heading.
            back = geodetic_to_local(w.x, w.y, w.z, origin=ORIGIN, heading_deg=0.0)
            assert np.abs(back[:2] - enu[i, :2]).max() <= 0.01
            # And Live's placement of the .skyc home agrees with QGroundControl's.
            assert np.abs(back[:2] - live[i]).max() <= 0.01


@pytest.mark.parametrize("fmt", ["skybrush-csv", "waypoints-csv", "crazyswarm"])
def test_local_formats_keep_local_coordinates_and_state_the_heading(placed, fmt):
    show, plan = placed
    result = export_show(show, fmt, plan=plan)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        manifest = json.loads(z.comment if fmt == "skybrush-csv" else z.read("manifest.json"))
        assert manifest["heading_deg"] == HEADING and "bearing heading_deg" in manifest["coordinates"]
        first = sorted(n for n in z.namelist() if n.startswith("drone_001"))[0]
        row = z.read(first).decode().splitlines()[1].split(",")
        if fmt == "waypoints-csv":
            assert str(HEADING).rstrip("0").rstrip(".") in z.read("README.txt").decode()
    xyz = [float(row[1]), float(row[2]), float(row[3])] if fmt != "crazyswarm" else [
        float(row[1]), float(row[9]), float(row[17])]
    # Not rotated by the heading: the home as planned, in the show's own frame.
    np.testing.assert_allclose(xyz, plan.knot_positions_m[0, 0], atol=1e-3)


def test_importing_app_exports_loads_no_numba_and_playback_still_compiles():
    """app.exports is imported by the API and the CLI on start-up: it must not pull in numba (a
    second or more of import); the plan track compiles its kernel on first use. A fresh
    interpreter, since this test process has numba loaded already."""
    import subprocess
    import sys

    code = (
        "import sys, numpy as np\n"
        "import app.exports\n"
        "assert 'numba' not in sys.modules, 'numba imported by app.exports'\n"
        "from sim import plan_show\n"
        "from tests.conftest import make_show, ring\n"
        "show = make_show([{'name': 'r', 'hold_s': 1.0, 'points': ring(4, 6.0), 'color': '#ff0000'}],"
        " drones=4, rows=2, cols=2, spacing_m=4.5)\n"
        "plan = plan_show(show)\n"
        "track = app.exports.make_track(plan, None, 'planned')\n"
        "t = np.linspace(0, plan.duration_s, 7)\n"
        "assert np.allclose(track.positions(t), plan.evaluate(t).positions_m)\n"
        "assert 'numba' in sys.modules\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
