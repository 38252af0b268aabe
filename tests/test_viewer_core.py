"""The live viewer: server lifecycle, frames against the plan, closest pair, GUI feedback guard."""

from __future__ import annotations

import socket
import time
from types import SimpleNamespace

import numpy as np
import pytest

from app.viewer import FlightTrack, Viewer, closest_pair, framing_camera, show_bounds
from sim import plan_show


@pytest.fixture
def plan(small_show):
    return plan_show(small_show)


@pytest.fixture
def viewer():
    v = Viewer(start_thread=False)
    yield v
    v.stop()


def _brute_closest(points: np.ndarray) -> tuple[int, int, float]:
    d = np.linalg.norm(points[:, None] - points[None], axis=-1)
    d[np.diag_indices(len(points))] = np.inf
    i, j = np.unravel_index(np.argmin(d), d.shape)
    return min(i, j), max(i, j), float(d[i, j])


def test_viewer_starts_on_loopback_and_stops():
    v = Viewer()
    try:
        assert v.host == "127.0.0.1"
        with socket.create_connection(("127.0.0.1", v.port), timeout=2):
            pass
        assert v._thread is not None and v._thread.is_alive()
    finally:
        v.stop()
    assert not v._thread.is_alive()
    with pytest.raises(OSError), socket.create_connection(("127.0.0.1", v.port), timeout=1):
        pass
    v.stop()  # idempotent


def test_frame_matches_plan_evaluate(viewer, plan):
    viewer.load(plan, name="small")
    for t in (0.0, 3.3, plan.duration_s / 2, plan.duration_s):
        viewer.seek(t)
        frame = viewer.render()
        expected = plan.evaluate([t])
        np.testing.assert_allclose(frame.positions_m, expected.positions_m[0], atol=1e-12)
        np.testing.assert_allclose(frame.colors_rgb, expected.colors_rgb[0], atol=1e-12)
        # What goes to the browsers is the same, in float32.
        np.testing.assert_allclose(viewer._drones.points, expected.positions_m[0], atol=1e-4)
        speed = np.linalg.norm(expected.velocities_mps[0], axis=1).max()
        assert frame.max_speed_mps == pytest.approx(speed)


def test_playback_advances_and_loops(viewer, plan):
    viewer.load(plan, name="small")
    viewer.set_speed(8.0)
    viewer.play()
    viewer.step(1.0)
    assert viewer.time_s == pytest.approx(8.0)
    viewer.step(plan.duration_s)  # past the end: loops to the start
    assert viewer.time_s == 0.0 and viewer.playing
    viewer._loop_cb.value = False
    viewer.step(plan.duration_s)
    assert viewer.time_s == pytest.approx(plan.duration_s) and not viewer.playing


def test_closest_pair_matches_brute_force():
    rng = np.random.default_rng(3)
    for n in (2, 3, 50, 400):
        pts = rng.uniform(-50, 50, (n, 3))
        want = _brute_closest(pts)
        assert closest_pair(pts) == pytest.approx(want)
        # A hint too small, exact and too large all give the exact answer.
        for hint in (want[2] * 0.5, want[2] * 1.0001, want[2] * 3):
            i, j, d = closest_pair(pts, hint_m=hint)
            assert (i, j) == want[:2] and d == pytest.approx(want[2])
    assert closest_pair(np.zeros((1, 3)))[2] == np.inf


def test_viewer_closest_pair_each_frame(viewer, plan):
    viewer.load(plan, name="small")
    viewer.play()
    for _ in range(40):
        frame = viewer.step(0.37)
        i, j, d = viewer.last_pair
        _, _, bd = _brute_closest(frame.positions_m)
        # Ties are common in formations: check the distance, and that the pair has it.
        assert d == pytest.approx(bd)
        assert np.linalg.norm(frame.positions_m[i] - frame.positions_m[j]) == pytest.approx(bd)
    assert viewer._pair_label.text == f"{viewer.last_pair[2]:.2f} m"


def test_slider_guard(viewer, plan, monkeypatch):
    viewer.load(plan, name="small")
    seeks: list[float] = []
    playback = viewer._main  # the slider belongs to a playback (the server-wide one here)
    original = playback.seek
    monkeypatch.setattr(playback, "seek", lambda t: (seeks.append(t), original(t)))
    viewer.play()
    for _ in range(10):
        viewer.step(0.1)
    # Python moved the slider ten times; none of it came back as a scrub.
    assert seeks == []
    assert viewer._slider.value == pytest.approx(round(viewer.time_s / 0.05) * 0.05)
    # A browser's scrub does seek.
    callback = viewer._slider._impl.update_cb[0]
    viewer._slider._impl.value = 5.0
    callback(SimpleNamespace(client=object(), client_id=1, target=viewer._slider))
    assert seeks == [5.0] and viewer.time_s == 5.0


def test_registry_source_and_busy(viewer, plan):
    viewer.load(plan, name="a")
    viewer.load(plan, name="b")
    assert viewer.shows == ["a", "b"] and viewer.current == "b"
    assert viewer._show_dd.options == ("a", "b")
    assert viewer._source_dd.disabled
    with pytest.raises(ValueError):
        viewer.load(plan, name="bad", flight=SimpleNamespace(positions_m=np.zeros((2, 3, 3))))
    # A flight (here: the plan sampled at 10 Hz) enables the simulated source.
    t = plan.sample_times(10.0)
    s = plan.evaluate(t)
    flight = SimpleNamespace(times_s=t, positions_m=s.positions_m, colors_rgb=s.colors_rgb)
    viewer.load(plan, name="c", flight=flight)
    assert viewer.source == "simulated" and not viewer._source_dd.disabled
    viewer.seek(7.05)
    frame = viewer.render()
    np.testing.assert_allclose(frame.positions_m, plan.evaluate([7.05]).positions_m[0], atol=0.05)
    viewer.set_source("planned")
    assert viewer.source == "planned" and viewer.time_s == pytest.approx(7.05)
    viewer.set_busy("Planning", 0.4)
    assert viewer._progress.visible and viewer._progress.value == pytest.approx(40.0)
    viewer.set_busy(None)
    assert not viewer._progress.visible


def test_targets_trails_and_readout(viewer, plan):
    viewer.load(plan, name="small")
    ring_hold = next(s for s in plan.segments if s.kind == "hold")
    viewer.seek(0.5)
    viewer.render()
    # During takeoff the next targets are the first formation's.
    np.testing.assert_allclose(viewer._targets.points, plan.knot_positions_m[ring_hold.index], atol=1e-4)
    assert viewer._trails.visible
    assert viewer._trails.points.shape == (plan.drone_count * 6, 2, 3)
    viewer.seek(ring_hold.start_s + 0.5)
    viewer.render()
    assert "ring" in viewer._readout.content and "m/s" in viewer._readout.content


def test_flight_track_interpolates():
    times = np.array([0.0, 1.0, 2.0])
    pos = np.zeros((3, 2, 3))
    pos[:, 0, 0] = [0.0, 10.0, 30.0]
    track = FlightTrack(SimpleNamespace(times_s=times, positions_m=pos, colors_rgb=np.ones_like(pos)))
    f = track.frame(1.5)
    assert f.positions_m[0, 0] == pytest.approx(20.0) and f.max_speed_mps == pytest.approx(20.0)
    assert track.positions(np.array([0.5, 5.0]))[:, 0, 0] == pytest.approx([5.0, 30.0])


def test_framing_camera_sees_the_whole_show(plan):
    lo, hi = show_bounds(plan)
    pos, look = framing_camera(lo, hi, fov_rad=np.deg2rad(75))
    corners = np.array(np.meshgrid(*zip(lo, hi, strict=True))).reshape(3, -1).T
    view = (look - pos) / np.linalg.norm(look - pos)
    rel = corners - pos
    angle = np.arccos(rel @ view / np.linalg.norm(rel, axis=1))
    assert angle.max() < np.deg2rad(75) / 2


def test_playback_thread_paces_30hz(plan):
    v = Viewer()
    try:
        v.load(plan, name="small")
        v.play()
        n0, t0 = v.frames_rendered, time.perf_counter()
        time.sleep(2.0)
        rate = (v.frames_rendered - n0) / (time.perf_counter() - t0)
        # Never faster than 30 Hz (no burst after a slow frame); the lower bound leaves room for a machine
        # shared with other work (it must still run, and not at a fraction of the rate).
        assert 10 <= rate <= 31.5, rate
    finally:
        v.stop()


def test_show_selector_lists_and_loads_from_the_catalog(viewer, plan):
    loaded: list[str] = []
    viewer.set_catalog(lambda: {"k1": "Stored show"}, lambda key: (loaded.append(key), viewer.load(plan, name=key)))
    assert viewer._show_dd.options == ("(no show loaded)", "Stored show")
    viewer.load(plan, name="here")
    assert viewer._show_dd.options == ("here", "Stored show")
    callback = viewer._show_dd._impl.update_cb[0]
    viewer._show_dd._impl.value = "Stored show"
    callback(SimpleNamespace(client=object(), client_id=1, target=viewer._show_dd))
    deadline = time.monotonic() + 10
    while viewer.current != "k1" and time.monotonic() < deadline:
        time.sleep(0.02)
    assert loaded == ["k1"] and viewer.current == "k1"
    # Picking a loaded show switches back to it.
    viewer._show_dd._impl.value = "here"
    callback(SimpleNamespace(client=object(), client_id=1, target=viewer._show_dd))
    assert viewer.current == "here"


# ---------------------------------------------------------------- per-drone timing


def test_frames_trails_and_samples_follow_each_drones_own_timing(viewer, staggered_small):
    plan, legs = staggered_small
    viewer.load(plan, name="staggered")
    rng = np.random.default_rng(11)
    # Playing forward, then scrubbing back and forth (the piece cursors move both ways).
    times = np.r_[np.arange(0.0, plan.duration_s, 0.37), rng.uniform(0.0, plan.duration_s, 60), plan.duration_s]
    for t in times:
        viewer.seek(float(t))
        frame = viewer.render()
        expected = plan.evaluate([t])
        np.testing.assert_allclose(frame.positions_m, expected.positions_m[0], rtol=0, atol=1e-9)
        np.testing.assert_allclose(frame.positions_m, legs.positions([t])[0], rtol=0, atol=1e-9)
        np.testing.assert_allclose(frame.colors_rgb, expected.colors_rgb[0], atol=1e-12)
        speed = np.linalg.norm(expected.velocities_mps[0], axis=1).max()
        assert frame.max_speed_mps == pytest.approx(speed, rel=1e-9, abs=1e-12)
        # Trails: the 7 samples behind the drone, newest first.
        trail_times = np.clip(t - 0.25 * np.arange(7), 0.0, plan.duration_s)
        trail = plan.evaluate(trail_times).positions_m  # (7, N, 3)
        want = np.stack([trail[:-1], trail[1:]], axis=2).transpose(1, 0, 2, 3).reshape(-1, 2, 3)
        np.testing.assert_allclose(viewer._trails.points, want, atol=1e-4)  # float32 on the wire
    # Many times at once (the HTML export's batches), in random order.
    track = viewer._track
    batch = rng.uniform(0.0, plan.duration_s, 50)
    pos, col, speeds = track.sample(batch)
    want = plan.evaluate(batch)
    np.testing.assert_allclose(pos, want.positions_m, rtol=0, atol=1e-9)
    np.testing.assert_allclose(col, want.colors_rgb, atol=1e-12)
    np.testing.assert_allclose(speeds, np.linalg.norm(want.velocities_mps, axis=2).max(axis=1), rtol=1e-9)


def test_next_targets_and_bounds_with_per_drone_timing(viewer, staggered_small):
    plan, _ = staggered_small
    viewer.load(plan, name="staggered")
    ring_hold = next(s for s in plan.segments if s.kind == "hold")
    viewer.seek(0.5)
    viewer.render()
    np.testing.assert_allclose(viewer._targets.points, plan.knot_positions_m[ring_hold.index], atol=1e-4)
    # The bounds hold every position the show visits (dense sampling) and are no larger
    # than the Bézier hull of the pieces needs: here the straight legs' end points.
    lo, hi = show_bounds(plan)
    dense = plan.evaluate(np.linspace(0.0, plan.duration_s, 3000)).positions_m.reshape(-1, 3)
    assert np.all(dense >= lo - 1e-9) and np.all(dense <= hi + 1e-9)
    knots = plan.knot_positions_m.reshape(-1, 3)
    np.testing.assert_allclose(lo, knots.min(axis=0), atol=1e-9)
    np.testing.assert_allclose(hi, knots.max(axis=0), atol=1e-9)


def test_bezier_control_points_bound_curved_pieces():
    from app.exports._tracks import bezier_control_points
    from sim.plan import Trajectories

    rng = np.random.default_rng(12)
    coeffs = rng.normal(size=(5, 3, 3, 6))
    breaks = np.cumsum(np.c_[np.zeros(5), rng.uniform(0.0, 2.0, (5, 3))], axis=1)
    breaks[:, -1] = breaks[:, -1].max()
    motion = Trajectories(breaks, coeffs)
    cp = bezier_control_points(motion)
    for i in range(5):
        for p in range(3):
            h = breaks[i, p + 1] - breaks[i, p]
            u = np.linspace(0.0, h, 200)
            curve = (u[:, None, None] ** np.arange(6) * coeffs[i, p][None]).sum(axis=2)  # (200, 3)
            # The control polygon's ends are the piece's ends; the curve stays in its box.
            np.testing.assert_allclose(cp[i, p, 0], curve[0], atol=1e-9)
            np.testing.assert_allclose(cp[i, p, -1], curve[-1], atol=1e-9)
            assert np.all(curve >= cp[i, p].min(axis=0) - 1e-9) and np.all(curve <= cp[i, p].max(axis=0) + 1e-9)


def test_audience_camera_sees_the_show_from_the_front(plan):
    from app.viewer._viewer import AUDIENCE_EYE_M, audience_camera

    lo, hi = show_bounds(plan)
    fov = np.deg2rad(75)
    pos, look = audience_camera(lo, hi, fov_rad=fov)
    assert pos[2] == AUDIENCE_EYE_M and pos[1] < lo[1] and pos[0] == pytest.approx((lo[0] + hi[0]) / 2)
    corners = np.array(np.meshgrid(*zip(lo, hi, strict=True))).reshape(3, -1).T
    view = (look - pos) / np.linalg.norm(look - pos)
    rel = corners - pos
    assert np.arccos(rel @ view / np.linalg.norm(rel, axis=1)).max() < fov / 2
    assert view[1] > 0.5  # facing +y, away from the audience
    # Standing at the geofence's audience edge instead.
    pos2, _ = audience_camera(lo, hi, fov_rad=fov, audience_y_m=-40.0)
    assert pos2[1] == -40.0


def test_camera_mode_switch(viewer, plan):
    viewer.load(plan, name="small")
    viewer.set_camera("audience")
    assert viewer._camera_dd.value == "audience" and viewer._main.camera == "audience"
    assert viewer.server.initial_camera.position[2] == pytest.approx(1.7)
    viewer.set_camera("free")
    assert viewer.server.initial_camera.position[2] > 1.7
    with pytest.raises(ValueError):
        viewer.set_camera("sideways")


def test_a_browser_joining_a_running_playback_plays_along(plan):
    """The editor's music lane can start the show before its preview page has connected (CI failure of
    test_editor_music: the sound played, the page's own playback sat paused at 0 s while the headless
    default one ran on unseen). A browser that connects then joins the default playback: same show,
    time, speed, and playing."""
    v = Viewer(start_thread=False, per_client=True)
    try:
        v.load(plan, name="small")
        main = v.playbacks[0]
        main.set_speed(2.0)
        main.seek(3.0)
        main.play()
        fake = SimpleNamespace(client_id=7, scene=v.server.scene, gui=v.server.gui, atomic=v.server.atomic,
                               camera=SimpleNamespace(image_width=1200, position=(0, 0, 0), look_at=(0, 0, 0)))
        v._on_connect(fake)
        pb = v._clients[7]
        assert (pb.current, pb.time_s, pb.speed, pb.playing) == ("small", 3.0, 2.0, True)
        main.pause()
        fake2 = SimpleNamespace(**{**vars(fake), "client_id": 8})
        v._on_connect(fake2)
        assert not v._clients[8].playing  # a paused default playback: the newcomer waits too
    finally:
        v.stop()
