"""QGC missions flown as exported keep the plan's separation (the demo show and a benchmark show).

The files are read back by real readers (pymavlink's ``MAVWPLoader`` for ``.waypoints``, the
JSON QGroundControl writes for ``.plan``), flown by the independent numeric replay of
``tests/wpnav_replay.py`` (ArduCopter's WPNAV defaults), and every pair's distance is computed
by brute force over dense samples: no pair the plan keeps ``min_distance_m`` apart may come closer.
"""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
from pymavlink import mavwp

from app.exports import export_show
from app.exports._geodesy import geodetic_to_local
from formations._demo import load_demo_show
from sim import plan_show
from sim.bench._shows import benchmark_show

ORIGIN = (47.397742, 8.545594, 488.0)
HEADING = 20.0
#: Dense sampling of the brute-force pair check, seconds.
DENSE_S = 0.02
#: What the files' coordinates resolve (latitude / longitude to 1e-10 degree, about 11 µm; altitude to
#: 0.1 mm): a pair read back that much under min_distance_m is rounding, not lost.
FILE_PRECISION_M = 1e-4


def _wpl_items(text: bytes, tmp_path, name: str) -> list:
    path = tmp_path / name
    path.write_bytes(text)
    loader = mavwp.MAVWPLoader()
    count = loader.load(str(path))
    wps = [loader.wp(k) for k in range(count)]
    local = geodetic_to_local(np.array([w.x for w in wps]), np.array([w.y for w in wps]),
                              np.array([w.z for w in wps]), origin=ORIGIN, heading_deg=HEADING)
    return [(w.command, w.param1, w.param2, local[k]) for k, w in enumerate(wps)]


def _plan_items(doc: dict) -> list:
    """A QGC .plan's items as (command, param1, param2, local point), home first (as in a .waypoints file)."""
    m = doc["mission"]
    home = geodetic_to_local(*m["plannedHomePosition"], origin=ORIGIN, heading_deg=HEADING)
    out = [(16, 0.0, 0.0, home)]
    for it in m["items"]:
        p = it["params"]
        nav = it["frame"] == 0
        point = geodetic_to_local(*p[4:7], origin=ORIGIN, heading_deg=HEADING) if nav else np.zeros(3)
        out.append((it["command"], p[0], p[1], point))
    return out


def read_limits(parm: bytes, tmp_path):
    """The WPNAV limits of the export's ``wpnav.parm``, read by pymavlink's parameter-file reader."""
    from pymavlink import mavparm

    from tests.wpnav_replay import Limits

    path = tmp_path / "wpnav.parm"
    path.write_bytes(parm)
    p = mavparm.MAVParmDict()
    p.load(str(path))
    # NAV_LAND descends at WPNAV_SPEED_DN to the ground (the replay's landing) only with these.
    assert p["LAND_SPEED_HIGH"] == 0 and p["LAND_SPEED"] == min(p["WPNAV_SPEED_DN"], 200)
    return Limits(speed_mps=p["WPNAV_SPEED"] / 100, speed_up_mps=p["WPNAV_SPEED_UP"] / 100,
                  speed_dn_mps=p["WPNAV_SPEED_DN"] / 100, accel_mps2=p["WPNAV_ACCEL"] / 100,
                  accel_z_mps2=p["WPNAV_ACCEL_Z"] / 100, jerk_mps3=p["WPNAV_JERK"])


def _replays(items_by_drone: list[list], lim):
    from tests.wpnav_replay import replay

    return [replay(items[1:], items[0][3], lim, sample_s=0.01) for items in items_by_drone]


def brute_force_lost_pairs(reps, plan, min_d: float) -> tuple[float, list[tuple[int, int, float, float]]]:
    """Every pair's distance at every DENSE_S sample (all pairs, no tree), the replay against the plan.

    Returns the closest replayed distance of any pair and the pairs that come under ``min_d``
    where the plan at the same instant keeps them at least ``min_d`` apart (i, j, distance, time).
    """
    from tests.wpnav_replay import positions_at

    end = max(r.times_s[-1] for r in reps)
    t_all = np.arange(0.0, end + DENSE_S, DENSE_S)
    n = len(reps)
    iu = np.triu_indices(n, 1)
    closest = np.inf
    worst: dict[tuple[int, int], tuple[float, float]] = {}
    for chunk in np.array_split(t_all, max(1, len(t_all) // 200)):
        pos = np.stack([positions_at(r, chunk) for r in reps], axis=1)  # (T, N, 3)
        ref = plan.evaluate(np.minimum(chunk, plan.duration_s)).positions_m
        d = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=-1)[:, iu[0], iu[1]]
        dp = np.linalg.norm(ref[:, :, None] - ref[:, None], axis=-1)[:, iu[0], iu[1]]
        closest = min(closest, float(d.min()))
        # Closer by more than the files' rounding where the plan keeps the pair apart (to 1 µm).
        bad = (d < min_d - FILE_PRECISION_M) & (dp >= min_d - 1e-6)
        for k, p in zip(*np.nonzero(bad), strict=True):
            key = (int(iu[0][p]), int(iu[1][p]))
            if key not in worst or d[k, p] < worst[key][0]:
                worst[key] = (float(d[k, p]), float(chunk[k]))
    return closest, sorted(((i, j, d, t) for (i, j), (d, t) in worst.items()), key=lambda x: x[2])


def check_show(show, tmp_path, plan=None) -> dict:
    """Export both formats, read them back, check they agree, replay and brute-force every pair."""
    plan = plan or plan_show(show)
    min_d = show.settings.min_distance_m
    wpl = export_show(show, "qgc-wpl", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    with zipfile.ZipFile(io.BytesIO(wpl.content)) as z:
        names = sorted(n for n in z.namelist() if n.endswith(".waypoints"))
        by_wpl = [_wpl_items(z.read(n), tmp_path, n) for n in names]
        manifest = json.loads(z.read("manifest.json"))
        lim = read_limits(z.read("wpnav.parm"), tmp_path)
    plan_zip = export_show(show, "qgc-plan", plan=plan, origin=ORIGIN, heading_deg=HEADING)
    with zipfile.ZipFile(io.BytesIO(plan_zip.content)) as z:
        by_plan = [_plan_items(json.loads(z.read(n[: -len(".waypoints")] + ".plan"))) for n in names]
    # The two formats carry the same mission (commands, parameters, points within 5 cm).
    for a, b in zip(by_wpl, by_plan, strict=True):
        assert [x[0] for x in a] == [x[0] for x in b]
        assert np.allclose([x[1:3] for x in a], [x[1:3] for x in b], atol=1e-3)
        nav = [k for k, x in enumerate(a) if x[0] in (16, 21, 22)]
        assert max(float(np.linalg.norm(a[k][3] - b[k][3])) for k in nav) <= 0.05
    closest, lost = brute_force_lost_pairs(_replays(by_wpl, lim), plan, min_d)
    assert not lost, f"{len(lost)} pair(s) lost min_distance_m in the replay, closest {lost[:5]}"
    assert manifest["replay"]["close_pair_count"] == 0
    assert not any("closer than min_distance_m" in w for w in wpl.warnings + plan_zip.warnings)
    # The missions stay within what ArduPilot stores, and the limits within the show's.
    assert manifest["replay"]["max_items"] == max(len(x) - 1 for x in by_wpl) <= 700
    s = show.settings
    assert lim.speed_mps <= s.max_speed_xy_mps and lim.speed_up_mps <= s.max_speed_z_mps
    assert lim.accel_mps2 * 2**0.5 <= s.max_accel_mps2 + 0.01 and lim.accel_z_mps2 <= s.max_accel_mps2 + 0.01
    assert lim.jerk_mps3 <= s.max_jerk_mps3
    return {"closest_m": closest, "manifest": manifest, "items": by_wpl}


@pytest.mark.parametrize("make", [load_demo_show, lambda: benchmark_show(36, formations=4)],
                         ids=["demo", "benchmark_show-36"])
def test_missions_flown_as_exported_keep_min_distance(make, tmp_path):
    check_show(make(), tmp_path)


def test_parked_drones_exactly_min_distance_apart_are_no_lost_pair(tmp_path):
    """Homes on a grid spaced exactly min_distance_m (the default layout): drones waiting there, before
    and after the show, are as far apart as the plan has them, not a pair lost to rounding."""
    from tests.conftest import fibonacci_sphere, make_show, ring

    show = make_show([{"name": "ring", "hold_s": 2.0, "points": ring(16, 12.0), "color": "#ff0000"},
                      {"name": "sphere", "hold_s": 2.0, "points": fibonacci_sphere(16, 9.0), "color": "#00ff00"}],
                     drones=16, rows=4, cols=4, spacing_m=3.0)
    assert show.settings.min_distance_m == 3.0
    out = check_show(show, tmp_path)
    assert out["closest_m"] == pytest.approx(3.0, abs=FILE_PRECISION_M)  # the parked grid itself
