"""The Skybrush exports read back through independent ports of Skybrush's own readers (tests/skybrush_readers.py).

.skyc: Skybrush Server's conversion to the drone's binary format, then libskybrush's
player in float32 (what the drone flies), and the show-format loader (what Live and the
Viewer show). Skybrush CSV: Studio's zipped-CSV importer.
"""

from __future__ import annotations

import io
import json
import math
import zipfile

import numpy as np
import pytest

from app.exports import _skyc as skyc_module
from app.exports import export_show
from sim import plan_show
from tests.conftest import fibonacci_sphere, make_show, ring
from tests.skybrush_readers import (
    LibskybrushPlayer,
    _scale,
    server_binary_trajectory,
    show_format_positions,
    studio_csv_import,
)


def _wall(rows: int, cols: int, spacing_m: float, center) -> np.ndarray:
    """A vertical (x-z) grid of rows x cols points."""
    x, z = np.meshgrid((np.arange(cols) - (cols - 1) / 2) * spacing_m, (np.arange(rows) - (rows - 1) / 2) * spacing_m)
    return np.c_[x.ravel(), np.zeros(x.size), z.ravel()] + np.asarray(center)


def _big_show(n: int = 300):
    """n = 300 drones from a 15 x 20 grid through a sphere, a wall and an offset sphere (about 80 m across)."""
    return make_show(
        [
            {"name": "sphere", "hold_s": 3.3, "points": fibonacci_sphere(n, 30.0, center=(0.0, 0.0, 60.0)),
             "color": "#ff0000"},
            {"name": "wall", "hold_s": 2.7, "points": _wall(15, 20, 4.0, center=(5.0, 10.0, 50.0)),
             "color": "#00ff40"},
            {"name": "sphere2", "hold_s": 4.1, "points": fibonacci_sphere(n, 34.0, center=(-10.0, 8.0, 62.0)),
             "color": "#2040ff"},
        ],
        drones=n, rows=15, cols=20, spacing_m=4.5,
    )


@pytest.fixture(scope="module")
def big():
    show = _big_show()
    return show, plan_show(show)


@pytest.fixture(scope="module")
def big_doc(big):
    show, plan = big
    with zipfile.ZipFile(io.BytesIO(export_show(show, "skyc", plan=plan).content)) as z:
        return json.loads(z.read("show.json"))


@pytest.fixture(scope="module")
def big_quintic():
    """The same show under the paper's quintic time law: degree-5 legs, so the Bézier fit is at work."""
    show = _big_show()
    show = show.model_copy(update={"settings": show.settings.model_copy(update={"time_law": "quintic"})})
    plan = plan_show(show)
    with zipfile.ZipFile(io.BytesIO(export_show(show, "skyc", plan=plan).content)) as z:
        return show, plan, json.loads(z.read("show.json"))


@pytest.fixture(params=["min_time", "quintic"])
def skyc_case(request):
    if request.param == "quintic":
        return request.getfixturevalue("big_quintic")
    show, plan = request.getfixturevalue("big")
    return show, plan, request.getfixturevalue("big_doc")


def _sample_times(plan, n: int = 6000) -> np.ndarray:
    rng = np.random.default_rng(1)
    return np.sort(np.r_[np.linspace(0.0, plan.duration_s, n), rng.uniform(0, plan.duration_s, n)])


def test_skyc_through_server_and_libskybrush_within_7_mm(skyc_case):
    show, plan, big_doc = skyc_case
    t = _sample_times(plan)
    ref = plan.evaluate(t).positions_m  # (T, N, 3)
    worst, scales = 0.0, set()
    for i, d in enumerate(big_doc["swarm"]["drones"]):
        points = d["settings"]["trajectory"]["points"]
        block = server_binary_trajectory(points)
        scales.add(block[0])
        player = LibskybrushPlayer(block)
        # The drone's clock: the binary durations add up to the show, to the millisecond.
        assert player.total_ms == round(plan.duration_s * 1000)
        worst = max(worst, float(np.linalg.norm(player.positions(t) - ref[:, i], axis=1).max()))
    # The show is ~120 m across: the server picks scale 2 (2 mm units) or more, as the case.
    assert max(scales) >= 2
    assert worst <= 0.007, f"{worst * 1000:.2f} mm"


def test_skyc_through_show_format_loader_within_2_mm(skyc_case):
    show, plan, big_doc = skyc_case
    t = _sample_times(plan)
    ref = plan.evaluate(t).positions_m
    worst = 0.0
    for i, d in enumerate(big_doc["swarm"]["drones"]):
        got = show_format_positions(d["settings"]["trajectory"]["points"], t)
        worst = max(worst, float(np.linalg.norm(got - ref[:, i], axis=1).max()))
    assert worst <= 0.002, f"{worst * 1000:.2f} mm"


def test_skyc_times_are_whole_milliseconds_the_server_keeps(skyc_case):
    for d in skyc_case[2]["swarm"]["drones"]:
        times = [p[0] for p in d["settings"]["trajectory"]["points"]]
        ms = [round(t * 1000) for t in times]
        assert all(abs(t * 1000 - m) < 1e-9 for t, m in zip(times, ms, strict=True))
        for a, b, ta, tb in zip(ms, ms[1:], times, times[1:], strict=False):
            # Exactly what the server computes: no segment loses a millisecond.
            assert math.floor(round(tb - ta, 3) * 1000) == b - a
            assert b - a <= 65_000


def test_the_server_would_lose_a_millisecond_on_some_durations():
    # The reason for the split: without it 1001 ms would be stored as 1000.
    assert skyc_module._server_truncates(1001) and not skyc_module._server_truncates(1000)
    split = skyc_module._safe_split_ms()
    bad = np.flatnonzero(split)
    assert len(bad) > 100
    for d in bad[:: max(1, len(bad) // 50)]:
        a = int(split[d])
        assert 0 < a < d and not skyc_module._server_truncates(a) and not skyc_module._server_truncates(d - a)


def test_skyc_uses_few_pieces_for_the_budget(big, big_doc):
    """Bézier pieces are fitted within 1 mm (well inside the budget), with no more points than needed."""
    _, plan = big
    counts = [len(d["settings"]["trajectory"]["points"]) for d in big_doc["swarm"]["drones"]]
    # Every drone: home, takeoff, 3 transitions + 3 holds, landing approach and landing, a few parts each.
    assert max(counts) <= 20 * len(plan.segments)


def test_skyc_validation_keys_are_studios(big, big_doc):
    show, _ = big
    v = big_doc["settings"]["validation"]
    # The keys Studio's SafetyCheckParams.as_dict writes.
    assert {"maxAltitude", "maxVelocityXY", "maxVelocityZ", "maxAccelerationXY", "maxAccelerationZ", "minDistance",
            "minNavAltitude", "maxYawRate"} <= set(v)
    s = show.settings
    assert v["minNavAltitude"] == s.min_altitude_m and v["minDistance"] == s.min_distance_m


def test_skyc_location_from_the_shows_origin_and_heading():
    show = _small_geo_show(heading_deg=30.0)
    result = export_show(show, "skyc")
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        doc = json.loads(z.read("show.json"))
    loc = doc["environment"]["location"]
    assert loc["origin"] == [round(47.3977419 * 1e7), round(8.5455938 * 1e7), round(430.5 * 1e3)]
    # Skybrush's +X points where our +x points: bearing heading + 90.
    assert loc["orientation"] == pytest.approx(120.0)
    assert not any("environment.location" in w for w in result.warnings)
    # Without a place on Earth: no location, and the export says what to do.
    bare = export_show(_small_geo_show(heading_deg=None), "skyc")
    with zipfile.ZipFile(io.BytesIO(bare.content)) as z:
        assert "location" not in json.loads(z.read("show.json"))["environment"]
    assert any("heading + 90" in w for w in bare.warnings)


def _small_geo_show(heading_deg: float | None):
    settings = {}
    if heading_deg is not None:
        settings["geo"] = {"origin_lat_deg": 47.3977419, "origin_lon_deg": 8.5455938, "origin_alt_m": 430.5,
                           "heading_deg": heading_deg}
    return make_show([{"name": "ring", "hold_s": 2.0, "points": ring(16, 12.0), "color": "#ff0000"}],
                     drones=16, rows=4, cols=4, spacing_m=4.5, **settings)


def test_skyc_says_plainly_that_live_refuses_over_5000(monkeypatch):
    monkeypatch.setattr(skyc_module, "SKYBRUSH_MAX_DRONES", 10)
    result = export_show(_small_geo_show(0.0), "skyc")
    msg = " ".join(result.warnings)
    assert "Skybrush Live" in msg and "refuse" in msg and "16 drones" in msg


def test_server_scale_port_matches_the_rule():
    # The server's rule: extremum (mm, rounded up) + 1 over 32768, rounded up.
    assert _scale([[0, [32.766, 0, 0], []]]) == 1
    assert _scale([[0, [32.767, 0, 0], []]]) == 2
    assert _scale([[0, [1, 2, 3], [[-65.535, 0, 0]]]]) == 2
    assert _scale([[0, [65.536, 0, 0], []]]) == 3


# ---------------------------------------------------------------- Skybrush CSV through Studio's importer


@pytest.mark.parametrize("blender_fps", [24, 25])
def test_skybrush_csv_defaults_import_into_studio_within_5_mm(big, blender_fps):
    show, plan = big
    result = export_show(show, "skybrush-csv", plan=plan)
    imported = studio_csv_import(result.content, fps=blender_fps)
    assert len(imported) == show.drones
    worst = 0.0
    for i, (name, (times, pos, pixels)) in enumerate(imported.items()):
        assert name == f"drone_{i + 1:03d}"
        ref = plan.evaluate(times, drones=np.array([i]))
        worst = max(worst, float(np.linalg.norm(pos - ref.positions_m[:, 0], axis=1).max()))
        # The last sample is kept: Studio's frames reach the end of the show, where the drone has landed.
        assert times[-1] >= plan.duration_s - 1e-9
        np.testing.assert_allclose(pos[-1], plan.knot_positions_m[-1, i], atol=1e-3)
        if i % 50 == 0:
            # Fades intact: one colour per Blender frame, each within a frame's fade of the plan.
            frames = np.arange(len(pixels)) / blender_fps
            want = plan.evaluate(np.minimum(frames, plan.duration_s), drones=np.array([i])).colors_rgb[:, 0] * 255
            fastest = 255.0 / min(s.duration_s for s in plan.segments if s.duration_s > 0)
            assert np.abs(pixels - want).max() <= 1.0 + 1.5 * fastest / blender_fps
    assert worst <= 0.005, f"{worst * 1000:.2f} mm"
