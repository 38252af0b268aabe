"""QGroundControl exports and the ENU <-> WGS84 conversion."""

from __future__ import annotations

import io
import json
import re
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
    """Drone i's navigation points for a plan of synchronised straight transitions: home, the takeoff's
    top, the end of every transition (the formations and the landing approach), the landing."""
    knots = [0, 1] + [s.index + 1 for s in plan.segments if s.kind == "transition"] + [len(plan.segments)]
    return plan.knot_positions_m[knots, i]


def _load_wpl(text: bytes, tmp_path, name: str) -> list:
    path = tmp_path / name
    path.write_bytes(text)
    loader = mavwp.MAVWPLoader()
    count = loader.load(str(path))
    assert count == loader.count()
    return [loader.wp(k) for k in range(count)]


def _check_commands(commands: list[int]) -> int:
    """Home, (NAV_DELAY) takeoff, per leg NAV_DELAY + DO_CHANGE_SPEED (one to three) + waypoint,
    NAV_DELAY + land; returns the number of legs."""
    text = " ".join(map(str, commands))
    assert re.fullmatch(r"16 (93 )?22( 93( 178){0,3} 16)+ 93 21", text), text
    return text.count(" 16")


def test_wpl_loads_in_pymavlink_with_the_right_count_and_coordinates(show, plan, tmp_path):
    result = export_show(show, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        names = sorted(n for n in z.namelist() if n.endswith(".waypoints"))
        assert len(names) == 16
        for i, name in enumerate(names):
            text = z.read(name)
            assert text.startswith(b"QGC WPL 110\n")
            wps = _load_wpl(text, tmp_path, name)
            local = _expected_local(plan, i)
            assert _check_commands([w.command for w in wps]) == len(local) - 3
            assert wps[0].current == 1 and all(w.current == 0 for w in wps[1:])
            nav = [w for w in wps if w.command in (16, 21, 22)]
            speed = [w for w in wps if w.command == 178]
            delay = [w for w in wps if w.command == 93]
            s = show.settings
            top = {1: s.max_speed_xy_mps, 2: s.max_speed_z_mps, 3: s.max_speed_z_mps}
            # Ground / climb / descent speeds within the show's limits, throttle unchanged; waypoints hold 0
            # (the NAV_DELAY after each waits); delays of at least 0.1 s (0 would wait for a UTC time).
            assert all(w.param1 in top and 0 < w.param2 <= top[w.param1] and w.param3 == -1 for w in speed)
            assert all(w.param1 == 0 for w in nav)
            assert all(w.param1 >= 0.1 and (w.param2, w.param3, w.param4) == (-1, -1, -1) for w in delay)
            lat = np.array([w.x for w in nav])
            lon = np.array([w.y for w in nav])
            alt = np.array([w.z for w in nav])
            # home, takeoff, the formations and the landing approach, land.
            want = local
            back = geodetic_to_local(lat, lon, alt, origin=ORIGIN, heading_deg=HEADING)
            assert np.linalg.norm(back - want, axis=1).max() <= 0.05
            # Independent of the inverse: ECEF distances equal local distances (a rigid map).
            ecef = geodetic_to_ecef(lat, lon, alt)
            d_ecef = np.linalg.norm(ecef[1:] - ecef[0], axis=1)
            d_local = np.linalg.norm(want[1:] - want[0], axis=1)
            assert np.abs(d_ecef - d_local).max() <= 0.05


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
            local = _expected_local(plan, i)
            home = geodetic_to_local(*m["plannedHomePosition"], origin=ORIGIN, heading_deg=HEADING)
            assert np.linalg.norm(home - local[0]) <= 0.05
            items = m["items"]
            assert _check_commands([16] + [it["command"] for it in items]) == len(local) - 3
            want = local[1:]
            nav = [it for it in items if it["command"] in (16, 21, 22)]
            for k, it in enumerate(items):
                assert it["type"] == "SimpleItem" and it["autoContinue"] is True
                assert it["doJumpId"] == k + 1 and it["frame"] == (2 if it["command"] in (93, 178) else 0)
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


def test_qgc_flies_each_drones_own_timing(staggered_small, tmp_path):
    """A plan with per-drone departures and arrivals inside its windows (the planner's delays; the
    quintic show, whose windows leave room for them within the limits): each drone's mission
    leaves when its own planned leg does (never early) and arrives when it does."""
    from tests.conftest import small_show_file

    show = small_show_file(time_law="quintic")
    plan = plan_show(show)
    staggered, legs = staggered_small
    t = np.linspace(0.0, plan.duration_s, 500)
    assert np.abs(staggered.evaluate(t).positions_m - plan.evaluate(t).positions_m).max() > 1.0
    result = export_show(show, "qgc-wpl", plan=staggered, origin=ORIGIN, heading_deg=HEADING)
    assert result.content != export_show(show, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING).content
    _, reps = _replay_all(result.content, staggered, tmp_path)
    moves = [k for k, (t0, t1) in enumerate(legs.window_s)
             if t1 > t0 and staggered.segments[k].kind == "transition"]
    for i, rep in enumerate(reps):
        # departures / arrivals after the takeoff: one per transition, then the landing.
        dep = np.array(rep.departures_s[1:1 + len(moves)])
        arr = np.array(rep.arrivals_s[1:1 + len(moves)])
        want_dep = np.array([legs.depart_s[k][i] for k in moves])
        want_arr = want_dep + np.array([legs.duration_s[k][i] for k in moves])
        late_before = np.r_[0.0, arr[:-1] - want_dep[1:]]
        assert np.all(dep >= want_dep - 2e-3)  # never early (the replays differ by their 1 ms steps)
        assert np.all((dep <= want_dep + 0.1 + 1e-3) | (late_before > -0.1))  # the wait, not longer
        assert np.abs(arr - want_arr).max() <= 0.1
    # This re-timing is random (not the planner's certified one) and its quintic / cubic profiles are
    # not ArduCopter's S-curves: a pair may come closer in the replay; if so the export names it.
    pairs, _ = _close_pairs(reps, staggered, show.settings.min_distance_m)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        named = {tuple(p["drones"]) for p in json.loads(z.read("manifest.json"))["replay"]["close_pairs"]}
        stems = sorted(n[: -len(".waypoints")] for n in z.namelist() if n.endswith(".waypoints"))
    assert {(stems[i], stems[j]) for i, j in pairs} <= named


# ---------------------------------------------------------------- timing: replay at the exported WPNAV


def _replay_all(content: bytes, plan, tmp_path, *, lim=None, use_speed_commands=True):
    from tests.test_exports_qgc_safety import read_limits
    from tests.wpnav_replay import replay

    reps = []
    with zipfile.ZipFile(io.BytesIO(content)) as z:
        lim = lim or read_limits(z.read("wpnav.parm"), tmp_path)
        names = sorted(n for n in z.namelist() if n.endswith(".waypoints"))
        for name in names:
            wps = _load_wpl(z.read(name), tmp_path, name)
            local = geodetic_to_local(np.array([w.x for w in wps]), np.array([w.y for w in wps]),
                                      np.array([w.z for w in wps]), origin=ORIGIN, heading_deg=HEADING)
            items = [(w.command, w.param1, w.param2, local[k]) for k, w in enumerate(wps)][1:]
            reps.append(replay(items, local[0], lim, use_speed_commands=use_speed_commands))
    return names, reps


def _formation_arrivals(plan):
    return [s.end_s for s in plan.segments if s.kind == "transition"]


def _close_pairs(reps, plan, min_d):
    from tests.test_exports_qgc_safety import brute_force_lost_pairs

    _, lost = brute_force_lost_pairs(reps, plan, min_d)
    return {(i, j) for i, j, _, _ in lost}, lost


def test_wpl_replay_keeps_the_plans_timing(show, plan, tmp_path):
    result = export_show(show, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    names, reps = _replay_all(result.content, plan, tmp_path)
    want = np.array(_formation_arrivals(plan))
    departs = np.array([s.start_s for s in plan.segments if s.kind in ("transition", "landing")])
    errors = []
    for rep in reps:
        # arrivals: the takeoff's top, each formation + the landing approach, land.
        got = np.array(rep.arrivals_s[1:-1])
        errors.extend(got - want)
        # Departures from the takeoff top, each formation and the landing approach: never before the
        # plan's, and no later than its NAV_DELAY's rounding unless the drone arrived after the plan left.
        dep = np.array(rep.departures_s[1:])
        arr = np.array(rep.arrivals_s[:-1])
        assert np.all(dep >= departs - 2e-3)  # the replays differ by their 1 ms steps
        ok = arr <= departs - 0.1
        assert np.abs(dep - departs)[ok].max(initial=0.0) <= 2.5e-3  # ms rounding, the replay's ms steps
    # At the show's own limits (wpnav.parm) nearly every formation is reached on time (within the
    # replays' ms steps); a leg the plan flies at the full acceleration on one axis is a little late
    # (ArduCopter's per-axis limits are max_accel_mps2 / √2), never early.
    assert np.median(np.abs(errors)) <= 0.005 and -0.005 <= min(errors) and max(errors) <= 0.5
    # Without the speed commands (the parameters' speeds) the timing is lost.
    _, plain = _replay_all(result.content, plan, tmp_path, use_speed_commands=False)
    plain_err = max(np.abs(np.array(r.arrivals_s[1:-1]) - want).max() for r in plain)
    assert plain_err > 10 * np.abs(errors).max()
    # The exporter's closed-form replay and this numeric one agree on the worst lateness.
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        claimed = json.loads(z.read("manifest.json"))["replay"]["worst_arrival_late_s"]
    assert claimed == pytest.approx(max(max(errors), 0.0), abs=0.05)
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
    """WPNAV limits too low to keep the timing (written to wpnav.parm): the independent replay at
    the file's limits finds close pairs, and the export names them and says to fly .skyc."""
    from app.exports import _qgc, _wpnav

    slow = _wpnav.Wpnav(speed_mps=10.0, accel_mps2=0.4, accel_z_mps2=0.3, jerk_mps3=0.1, speed_up_mps=2.5)
    monkeypatch.setattr(_qgc, "show_wpnav", lambda settings: slow)
    result = export_show(show, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    names, reps = _replay_all(result.content, plan, tmp_path)
    pairs, _ = _close_pairs(reps, plan, show.settings.min_distance_m)
    assert pairs, "the slowed replay should lose min_distance somewhere"
    stems = [n[: -len(".waypoints")] for n in names]
    warning = next(w for w in result.warnings if "closer than min_distance_m" in w)
    assert "fly it with .skyc" in warning
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        manifest = json.loads(z.read("manifest.json"))
        readme = z.read("README.txt").decode()
    named = {tuple(p["drones"]) for p in manifest["replay"]["close_pairs"]}
    # The pairs the exporter finds at its sampling are the ones the independent replay finds
    # (sampled every 0.02 s here: a pair grazing the limit between samples may differ).
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


def test_qgc_says_drones_landing_mid_show_cannot_fly_as_waypoints():
    """A subset formation whose others land: their waypoints go down to the ground and back up, which
    ArduCopter does not fly in AUTO (touching down idles the motors); the export says so."""
    sub = make_show([{"name": "ring", "hold_s": 2.0, "points": ring(16, 12.0), "color": "#ff0000"},
                     {"name": "small", "hold_s": 3.0, "points": fibonacci_sphere(8, 6.0), "color": "#00ff00",
                      "drones": {"count": 8}, "others": "land"},
                     {"name": "ring2", "hold_s": 2.0, "points": ring(16, 14.0), "color": "#0000ff"}],
                    drones=16, rows=4, cols=4, spacing_m=4.5)
    plan = plan_show(sub)
    assert plan.grounded
    result = export_show(sub, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    warning = next(w for w in result.warnings if "land mid-show" in w)
    assert "'small'" in warning and ".skyc" in warning
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        assert warning in json.loads(z.read("manifest.json"))["warnings"]


def test_qgc_warns_past_the_items_a_board_holds(show, plan, tmp_path, monkeypatch):
    """Missions longer than ArduPilot's FRAM holds (MAX_ITEMS) are written with a warning naming the
    longest, counted as pymavlink reads the file (home excluded)."""
    from app.exports import _qgc

    result = export_show(show, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        names = sorted(n for n in z.namelist() if n.endswith(".waypoints"))
        counts = [len(_load_wpl(z.read(n), tmp_path, n)) - 1 for n in names]
        assert json.loads(z.read("manifest.json"))["replay"]["max_items"] == max(counts)
    assert not any("items" in w for w in result.warnings)
    monkeypatch.setattr(_qgc, "MAX_ITEMS", max(counts) - 1)
    warned = export_show(show, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING).warnings
    longest = names[int(np.argmax(counts))][: -len(".waypoints")]
    assert any(f"{longest}'s mission has {max(counts)} items" in w for w in warned)
