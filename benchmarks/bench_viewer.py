"""3D viewer benchmarks (issue 6): ``pytest -m slow benchmarks/bench_viewer.py -s``.

* server-side cost of one frame update (sample the plan, closest pair, push the
  drones, the pair line, the readout and the slider to viser) at 1k, 10k and
  16k drones, with the default display (trails on up to 3,000 drones); target
  <= 2 ms at 10k;
* with headless Chromium connected through the app's relay: websocket frames
  delivered per second at the 30 Hz pacing, and bytes per second.

The plans are synthetic (grid -> sphere -> grid with the shared quintic law),
so that 16k drones need no 16k x 16k assignment.
"""

from __future__ import annotations

import os
import socket
import statistics
import threading
import time

import numpy as np
import pytest

from app.viewer import Viewer
from formations import Settings
from sim import Segment, ShowPlan

pytestmark = pytest.mark.slow
CHROMIUM = "/usr/bin/chromium"


def synthetic_plan(n: int, spacing_m: float = 3.0) -> ShowPlan:
    """Takeoff, a transition to a sphere, a hold, a transition back and landing, for n drones."""
    cols = int(np.ceil(np.sqrt(n)))
    i = np.arange(n)
    home = np.c_[(i % cols) * spacing_m, (i // cols) * spacing_m, np.zeros(n)]
    home[:, :2] -= home[:, :2].mean(axis=0)
    up = home + [0, 0, 10.0]
    k = i + 0.5
    phi, theta = np.arccos(1 - 2 * k / n), np.pi * (1 + 5**0.5) * k
    radius = spacing_m * np.sqrt(n / (4 * np.pi)) * 1.2
    sphere = np.c_[np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)] * radius
    sphere += [0, 0, radius + 20.0]
    knots = np.stack([home, up, sphere, sphere, up, home])
    colors = np.zeros_like(knots)
    colors[2:4] = np.c_[np.abs(np.cos(theta)), np.abs(np.sin(theta)), np.full(n, 0.5)]
    durations = [10.0, 30.0, 10.0, 30.0, 10.0]
    kinds = ["takeoff", "transition", "hold", "transition", "landing"]
    labels = ["takeoff", "sphere", "sphere", "landing", "landing"]
    times = np.concatenate([[0.0], np.cumsum(durations)])
    segments = tuple(Segment(s, kinds[s], labels[s], float(times[s]), durations[s]) for s in range(5))
    return ShowPlan(times, knots, colors, segments, (), Settings(min_distance_m=spacing_m), f"synthetic {n}")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("n", [1000, 10_000, 16_000])
def test_frame_update_cost(n, record_result):
    plan = synthetic_plan(n)
    viewer = Viewer(start_thread=False)
    try:
        viewer.load(plan, name=f"synthetic {n}")
        viewer.seek(25.0)  # mid-transition: everything moves, every array changes
        viewer.play()
        costs = []
        for _ in range(90):
            t0 = time.perf_counter()
            viewer.step(1.0 / 30.0)
            costs.append(time.perf_counter() - t0)
        ms = np.array(costs[10:]) * 1e3
        figures = {
            "drones": n,
            "trails": bool(viewer._trails_cb.value),
            "frame_ms_median": round(float(np.median(ms)), 3),
            "frame_ms_p90": round(float(np.percentile(ms, 90)), 3),
            # The least disturbed frame: on a shared, loaded machine the median mostly measures the others.
            "frame_ms_min": round(float(ms.min()), 3),
            "load_average_1min": round(os.getloadavg()[0], 2),
        }
        # The parts: sampling the plan and the closest pair.
        t0 = time.perf_counter()
        for _ in range(20):
            frame = viewer._track.frame(25.0)
        figures["sample_ms"] = round((time.perf_counter() - t0) / 20 * 1e3, 3)
        from app.viewer import closest_pair

        t0 = time.perf_counter()
        for _ in range(20):
            closest_pair(frame.positions_m, hint_m=viewer.last_pair[2] * 1.05)
        figures["closest_pair_ms"] = round((time.perf_counter() - t0) / 20 * 1e3, 3)
        record_result(figures)
    finally:
        viewer.stop()


@pytest.mark.skipif(not os.path.exists(CHROMIUM), reason="needs /usr/bin/chromium")
@pytest.mark.parametrize("n", [1000, 10_000, 16_000])
def test_browser_delivery_rate(n, tmp_path, record_result):
    import uvicorn
    from playwright.sync_api import sync_playwright

    from app.server import create_app
    from app.settings import AppSettings

    app = create_app(AppSettings(data_dir=tmp_path, workers=1))
    port = _free_port()
    server = uvicorn.Server(uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        deadline = time.time() + 30
        while getattr(app.state, "viewer", None) is None and time.time() < deadline:
            time.sleep(0.1)
        viewer = app.state.viewer
        viewer.load(synthetic_plan(n), name=f"synthetic {n}")
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True)
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            frames: list[tuple[float, int]] = []
            page.on("websocket", lambda ws: ws.on(
                "framereceived", lambda payload: frames.append((time.perf_counter(), len(payload)))))
            fps_js = ("() => new Promise(r => { let n = 0; const t0 = performance.now();"
                      " const f = () => { n++; if (performance.now() - t0 < 3000) requestAnimationFrame(f);"
                      " else r(n / 3); }; requestAnimationFrame(f); })")
            t_goto = time.perf_counter()
            page.goto(f"http://127.0.0.1:{port}/viser/")
            page.wait_for_selector("canvas", timeout=30_000)
            # Playwright delivers events while its own calls run: wait with wait_for_timeout, not sleep.
            page.wait_for_timeout(3000)
            viewer.seek(10.0)
            viewer.play()
            page.wait_for_timeout(1000)
            start = time.perf_counter()
            rendered0 = viewer.frames_rendered
            page.wait_for_timeout(5000)
            end = time.perf_counter()
            rendered = viewer.frames_rendered - rendered0
            got = [b for t, b in frames if start <= t <= end]
            render_fps = page.evaluate(fps_js)
            browser.close()
        span = end - start
        # Loaded = the first websocket message big enough to hold every drone's position (float16 x 3).
        first_cloud = next((t for t, b in frames if b >= 6 * n), None)
        record_result({
            "page_to_drones_loaded_s": None if first_cloud is None else round(first_cloud - t_goto, 3),
            "drones": n,
            "server_frames_per_s": round(rendered / span, 1),
            "ws_frames_per_s": round(len(got) / span, 1),
            "bytes_per_s": int(sum(got) / span),
            "mean_frame_bytes": int(statistics.mean(got)) if got else 0,
            "browser_render_fps": round(float(render_fps), 1),
        })
    finally:
        server.should_exit = True
        thread.join(timeout=15)
