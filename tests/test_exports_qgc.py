"""QGroundControl exports and the ENU <-> WGS84 conversion."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink import mavwp

from app.exports import ExportError, export_show
from app.exports._geodesy import (
    WGS84_A,
    WGS84_B,
    ecef_to_geodetic,
    geodetic_to_ecef,
    geodetic_to_local,
    local_to_geodetic,
)
from app.exports._qgc import mission_waypoints
from sim import plan_show
from tests.conftest import fibonacci_sphere, make_show, ring

ORIGIN = (47.397742, 8.545594, 488.0)
HEADING = 35.0


@pytest.fixture(scope="module")
def show():
    return make_show(
        [
            {"name": "ring", "hold_s": 2.0, "points": ring(16, 12.0), "color": "#ff0000"},
            {"name": "sphere", "hold_s": 3.5, "points": fibonacci_sphere(16, 9.0), "color": "#00ff00"},
        ],
        drones=16, rows=4, cols=4, spacing_m=4.5,
    )


@pytest.fixture(scope="module")
def plan(show):
    return plan_show(show)


def _expected_local(plan, i):
    knots, holds = mission_waypoints(plan)
    return plan.knot_positions_m[knots, i], holds


def _load_wpl(text: bytes, tmp_path, name: str) -> list:
    path = tmp_path / name
    path.write_bytes(text)
    loader = mavwp.MAVWPLoader()
    count = loader.load(str(path))
    assert count == loader.count()
    return [loader.wp(k) for k in range(count)]


def _expected_commands(n_legs: int) -> list[int]:
    """Home, takeoff, a waypoint at its top, per leg DO_CHANGE_SPEED + waypoint, land."""
    return [16, 22, 16] + [178, 16] * n_legs + [21]


def test_wpl_loads_in_pymavlink_with_the_right_count_and_coordinates(show, plan, tmp_path):
    result = export_show(show, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        names = sorted(n for n in z.namelist() if n.endswith(".waypoints"))
        assert len(names) == 16
        for i, name in enumerate(names):
            text = z.read(name)
            assert text.startswith(b"QGC WPL 110\n")
            wps = _load_wpl(text, tmp_path, name)
            local, holds = _expected_local(plan, i)
            assert [w.command for w in wps] == _expected_commands(len(holds))
            assert wps[0].current == 1 and all(w.current == 0 for w in wps[1:])
            nav = [w for w in wps if w.command != 178]
            speed = [w for w in wps if w.command == 178]
            # Holds are whole seconds (ArduPilot truncates), speeds ground speeds within the show's limit.
            assert all(w.param1 == int(w.param1) for w in nav)
            assert all(w.param1 == 1 and 0 < w.param2 <= show.settings.max_speed_xy_mps and w.param3 == -1
                       for w in speed)
            # (The holds themselves are checked by the replay: the plan's departure, to the nearest second.)
            lat = np.array([w.x for w in nav])
            lon = np.array([w.y for w in nav])
            alt = np.array([w.z for w in nav])
            # home, takeoff, its top again (hold), the formations and the landing approach, land.
            want = np.r_[local[:2], local[1:]]
            back = geodetic_to_local(lat, lon, alt, origin=ORIGIN, heading_deg=HEADING)
            assert np.linalg.norm(back - want, axis=1).max() <= 0.05
            # Independent of the inverse: ECEF distances equal local distances (a rigid map).
            ecef = geodetic_to_ecef(lat, lon, alt)
            d_ecef = np.linalg.norm(ecef[1:] - ecef[0], axis=1)
            d_local = np.linalg.norm(want[1:] - want[0], axis=1)
            assert np.abs(d_ecef - d_local).max() <= 0.05


def test_formation_holds_match_the_show(show, plan):
    _, holds = mission_waypoints(plan)
    assert holds == pytest.approx([f.hold_s for f in show.formations] + [0.0])


def test_plan_json_structure(show, plan):
    result = export_show(show, "qgc-plan", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        names = sorted(n for n in z.namelist() if n.endswith(".plan"))
        assert len(names) == 16
        manifest = json.loads(z.read("manifest.json"))
        assert manifest["origin"]["latitude_deg"] == ORIGIN[0]
        for i, name in enumerate(names):
            doc = json.loads(z.read(name))
            assert doc["fileType"] == "Plan" and doc["version"] == 1
            assert doc["groundStation"] == "QGroundControl"
            assert doc["geoFence"]["version"] == 2 and doc["rallyPoints"] == {"version": 2, "points": []}
            fence = doc["geoFence"]["polygons"][0]
            assert fence["inclusion"] is True and len(fence["polygon"]) == 4
            m = doc["mission"]
            for key in ("items", "plannedHomePosition", "firmwareType", "vehicleType", "cruiseSpeed", "hoverSpeed"):
                assert key in m
            local, holds = _expected_local(plan, i)
            home = geodetic_to_local(*m["plannedHomePosition"], origin=ORIGIN, heading_deg=HEADING)
            assert np.linalg.norm(home - local[0]) <= 0.05
            items = m["items"]
            assert [it["command"] for it in items] == _expected_commands(len(holds))[1:]
            want = np.r_[local[1:2], local[1:]]
            nav = [it for it in items if it["command"] != 178]
            for k, it in enumerate(items):
                assert it["type"] == "SimpleItem" and it["autoContinue"] is True
                assert it["doJumpId"] == k + 1 and it["frame"] == (2 if it["command"] == 178 else 0)
                assert len(it["params"]) == 7
            for k, it in enumerate(nav):
                p = geodetic_to_local(*it["params"][4:7], origin=ORIGIN, heading_deg=HEADING)
                assert np.linalg.norm(p - want[k]) <= 0.05


@pytest.mark.parametrize("fmt", ["qgc-plan", "qgc-wpl"])
def test_qgc_needs_an_origin(show, plan, fmt):
    with pytest.raises(ExportError, match="origin") as exc:
        export_show(show, fmt, plan=plan)
    assert "--origin" not in str(exc.value) and "show settings" in str(exc.value)


@pytest.mark.parametrize("fmt", ["qgc-plan", "qgc-wpl"])
def test_qgc_uses_the_place_stored_in_the_show(show, plan, fmt):
    """settings.geo gives the same file as passing its origin and heading; an explicit origin wins."""
    from formations import GeoPlacement

    geo = GeoPlacement(origin_lat_deg=ORIGIN[0], origin_lon_deg=ORIGIN[1], origin_alt_m=ORIGIN[2], heading_deg=HEADING)
    placed = show.model_copy(update={"settings": show.settings.model_copy(update={"geo": geo})})

    def members(result) -> dict[str, bytes]:
        with zipfile.ZipFile(io.BytesIO(result.content)) as z:
            # The manifest names the show's hash, which differs by the stored place itself.
            return {n: z.read(n) for n in z.namelist() if n != "manifest.json"}

    stored = members(export_show(placed, fmt, plan=plan))
    assert stored == members(export_show(show, fmt, plan=plan, origin=ORIGIN, heading_deg=HEADING))
    other = (ORIGIN[0] + 1.0, ORIGIN[1], ORIGIN[2])
    assert members(export_show(placed, fmt, plan=plan, origin=other)) != stored


def test_heading_rotates_the_show():
    # +y at bearing 90 degrees points east: longitude grows, latitude stays.
    lat, lon, _ = local_to_geodetic([0.0, 100.0, 0.0], origin=(0.0, 0.0, 0.0), heading_deg=90.0)
    assert abs(lat) < 1e-9 and lon > 0
    # +x at heading 0 points east; +y north.
    lat, lon, _ = local_to_geodetic([0.0, 100.0, 0.0], origin=(10.0, 20.0, 0.0))
    assert lat > 10.0 and abs(lon - 20.0) < 1e-9


def test_known_ecef_points():
    np.testing.assert_allclose(geodetic_to_ecef(0.0, 0.0, 0.0), [WGS84_A, 0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(geodetic_to_ecef(90.0, 0.0, 0.0), [0.0, 0.0, WGS84_B], atol=1e-6)
    lat, lon, h = ecef_to_geodetic([0.0, 0.0, WGS84_B + 100.0])
    assert lat == pytest.approx(90.0) and h == pytest.approx(100.0, abs=1e-6)
    # Published WGS84 value for 45 N 45 E on the ellipsoid.
    xyz = [3194419.145, 3194419.145, 4487348.409]
    np.testing.assert_allclose(geodetic_to_ecef(45.0, 45.0, 0.0), xyz, atol=2e-3)
    lat, lon, h = ecef_to_geodetic(xyz)
    assert (lat, lon) == (pytest.approx(45.0, abs=1e-7), pytest.approx(45.0, abs=1e-7))
    assert h == pytest.approx(0.0, abs=2e-3)


@settings(max_examples=150, deadline=None)
@given(
    lat=st.floats(-89.9, 89.9),
    lon=st.floats(-180.0, 180.0),
    alt=st.floats(-400.0, 9000.0),
    heading=st.floats(0.0, 360.0),
    offset=st.tuples(st.floats(-5000.0, 5000.0), st.floats(-5000.0, 5000.0), st.floats(-100.0, 2000.0)),
)
def test_geodetic_round_trip(lat, lon, alt, heading, offset):
    origin = (lat, lon, alt)
    p = np.array(offset)
    la, lo, h = local_to_geodetic(p, origin=origin, heading_deg=heading)
    assert -90.0 <= la <= 90.0 and -180.0 <= lo <= 180.0
    back = geodetic_to_local(la, lo, h, origin=origin, heading_deg=heading)
    assert np.linalg.norm(back - p) <= 0.05
    # The forward map is rigid: the straight-line distance to the origin is preserved.
    d = np.linalg.norm(geodetic_to_ecef(la, lo, h) - geodetic_to_ecef(*origin))
    assert d == pytest.approx(np.linalg.norm(p), abs=0.001)


@pytest.mark.parametrize("fmt", ["qgc-plan", "qgc-wpl"])
def test_qgc_keeps_the_knot_positions_under_per_drone_timing(show, plan, fmt):
    # Waypoints are where the drones rest at the window boundaries, which per-drone timing
    # inside the windows does not move: the same file.
    from tests.conftest import staggered_plan

    staggered, _ = staggered_plan(plan, seed=4)
    t = np.linspace(0.0, plan.duration_s, 500)
    assert np.abs(staggered.evaluate(t).positions_m - plan.evaluate(t).positions_m).max() > 1.0
    a = export_show(show, fmt, plan=plan, origin=ORIGIN, heading_deg=HEADING)
    b = export_show(show, fmt, plan=staggered, origin=ORIGIN, heading_deg=HEADING)
    assert a.content == b.content


# ---------------------------------------------------------------- timing: replay at ArduCopter's defaults


def _replay_all(content: bytes, plan, tmp_path, *, lim=None, use_speed_commands=True):
    from tests.wpnav_replay import Limits, replay

    reps = []
    with zipfile.ZipFile(io.BytesIO(content)) as z:
        names = sorted(n for n in z.namelist() if n.endswith(".waypoints"))
        for name in names:
            wps = _load_wpl(z.read(name), tmp_path, name)
            local = geodetic_to_local(np.array([w.x for w in wps]), np.array([w.y for w in wps]),
                                      np.array([w.z for w in wps]), origin=ORIGIN, heading_deg=HEADING)
            items = [(w.command, w.param1, w.param2, local[k]) for k, w in enumerate(wps)][1:]
            reps.append(replay(items, local[0], lim or Limits(), use_speed_commands=use_speed_commands))
    return names, reps


def _formation_arrivals(plan):
    return [s.end_s for s in plan.segments if s.kind == "transition"]


def _close_pairs(reps, plan, min_d):
    from tests.wpnav_replay import positions_at

    end = max(r.times_s[-1] for r in reps)
    t = np.arange(0.0, end, 0.05)
    pos = np.stack([positions_at(r, t) for r in reps], axis=1)  # (T, N, 3)
    ref = plan.evaluate(np.minimum(t, plan.duration_s)).positions_m
    d = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)
    dp = np.linalg.norm(ref[:, :, None] - ref[:, None], axis=-1)
    n = pos.shape[1]
    iu = np.triu_indices(n, 1)
    bad = (d < min_d) & (dp >= min_d)
    pairs = {(int(i), int(j)) for i, j in zip(*iu, strict=True) if bad[:, i, j].any()}
    return pairs, float(d[:, iu[0], iu[1]].min())


def test_wpl_replay_keeps_the_plans_timing(show, plan, tmp_path):
    result = export_show(show, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    names, reps = _replay_all(result.content, plan, tmp_path)
    want = np.array(_formation_arrivals(plan))
    departs = np.array([s.start_s for s in plan.segments if s.kind in ("transition", "landing")])
    top = show.settings.max_speed_xy_mps
    errors = []
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        for name, rep in zip(names, reps, strict=True):
            wps = _load_wpl(z.read(name), tmp_path, name)
            speeds = [w.param2 for w in wps if w.command == 178]
            # arrivals: takeoff top, top again (zero-length leg), each formation + the landing approach, land.
            got = np.array(rep.arrivals_s[2:-1])
            for k, (g, w_) in enumerate(zip(got, want, strict=True)):
                # Never late but on a leg flown at the fastest speed commanded; early only where the
                # leg cannot be flown slower (a steep leg at WPNAV_SPEED_UP / _DN): then it waits.
                assert g <= w_ + 0.1 or speeds[k] >= top - 0.01, (name, k, g, w_)
                errors.append(g - w_)
            # Departures from the takeoff top and each formation: within half a second of the plan's
            # unless the drone arrived after the plan had already left.
            dep = np.array(rep.departures_s[2:])
            arr = np.array(rep.arrivals_s[1:-1])
            ok = arr <= departs - 0.5
            assert np.abs(dep - departs)[ok].max(initial=0.0) <= 0.5 + 0.01  # + the replays' ms apart
    # Without the speed commands (ArduCopter's default 10 m/s and truncated holds) the timing is lost.
    _, plain = _replay_all(result.content, plan, tmp_path, use_speed_commands=False)
    plain_err = max(np.abs(np.array(r.arrivals_s[2:-1]) - want).max() for r in plain)
    assert plain_err > np.abs(errors).max()
    # The exporter's closed-form replay and this numeric one agree on the worst lateness (ArduCopter's
    # default climb / descent and jerk limits cannot fly every leg of this show in time) and say so.
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        claimed = json.loads(z.read("manifest.json"))["replay"]["worst_arrival_late_s"]
    assert claimed == pytest.approx(max(errors), abs=0.05)
    assert (claimed > 1.0) == any("after the plan" in w for w in result.warnings)


def test_wpl_replay_keeps_min_distance_or_names_the_pairs(show, plan, tmp_path):
    result = export_show(show, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    names, reps = _replay_all(result.content, plan, tmp_path)
    pairs, _ = _close_pairs(reps, plan, show.settings.min_distance_m)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        manifest = json.loads(z.read("manifest.json"))
    named = {tuple(p["drones"]) for p in manifest["replay"]["close_pairs"]}
    stems = [n[: -len(".waypoints")] for n in names]
    assert {(stems[i], stems[j]) for i, j in pairs} <= named
    assert bool(named) == any("closer than min_distance_m" in w for w in result.warnings)


def test_wpl_names_the_pairs_when_the_replay_loses_min_distance(show, plan, tmp_path, monkeypatch):
    """Limits too low to keep the timing: the independent replay finds close pairs and the export names them."""
    from app.exports import _qgc, _wpnav
    from tests.wpnav_replay import Limits

    slow = _wpnav.Wpnav(speed_mps=10.0, accel_mps2=0.4, accel_z_mps2=0.3, jerk_mps3=0.1, speed_up_mps=2.5)
    real = _qgc.time_mission
    monkeypatch.setattr(_qgc, "time_mission", lambda *a, **k: real(*a, wpnav=slow))
    result = export_show(show, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    lim = Limits(accel_mps2=0.4, accel_z_mps2=0.3, jerk_mps3=0.1)
    names, reps = _replay_all(result.content, plan, tmp_path, lim=lim)
    pairs, _ = _close_pairs(reps, plan, show.settings.min_distance_m)
    assert pairs, "the slowed replay should lose min_distance somewhere"
    stems = [n[: -len(".waypoints")] for n in names]
    warning = next(w for w in result.warnings if "closer than min_distance_m" in w)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        manifest = json.loads(z.read("manifest.json"))
        readme = z.read("README.txt").decode()
    named = {tuple(p["drones"]) for p in manifest["replay"]["close_pairs"]}
    # The pairs the exporter finds at its sampling are the ones the independent replay finds
    # (sampled every 0.05 s here: a pair grazing the limit between samples may differ).
    found = {(stems[i], stems[j]) for i, j in pairs}
    assert len(found & named) >= 0.8 * max(len(found), len(named))
    first = manifest["replay"]["close_pairs"][0]["drones"]
    assert first[0] in warning and first[1] in warning and "WARNING" in readme and first[0] in readme


@settings(max_examples=40, deadline=None)
@given(st.floats(0.05, 300.0), st.floats(0.3, 15.0), st.floats(0.3, 5.0), st.floats(0.2, 5.0))
def test_scurve_closed_form_respects_its_limits(length, vmax, amax, jerk):
    """The exporter's closed-form S-curve: reaches the end, never exceeds speed, acceleration or jerk
    (finite differences of dense samples), and takes as long as the numeric replay's."""
    from app.exports._wpnav import scurve_distance, scurve_duration
    from tests.wpnav_replay import STEP_S, leg_profile

    total = float(scurve_duration(length, vmax, amax, jerk))
    t = np.linspace(0.0, total, 4001)
    s = scurve_distance(t, length, vmax, amax, jerk)
    assert s[0] == pytest.approx(0.0, abs=1e-9) and s[-1] == pytest.approx(length, rel=1e-9, abs=1e-9)
    dt = t[1] - t[0]
    v = np.diff(s) / dt
    assert v.min() >= -1e-9 and v.max() <= vmax * (1 + 1e-6) + 1e-9
    a = np.diff(v) / dt
    assert np.abs(a).max() <= amax * 1.02 + jerk * dt * 2
    numeric = (len(leg_profile(length, vmax, amax, jerk)) - 1) * STEP_S
    # The numeric profile rounds its phases to its 1 ms step: a few ms apart at most.
    assert numeric == pytest.approx(total, abs=0.005)
