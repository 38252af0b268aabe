"""Shared fixtures and builders for the test suite."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import IO

import numpy as np
import pytest

from formations import ShowFile, parse_show

_ROOT = Path(__file__).resolve().parents[1]


def fibonacci_sphere(n: int, radius_m: float, center=(0.0, 0.0, 50.0)) -> np.ndarray:
    """n points spread evenly on a sphere (test helper, independent of formations.sources)."""
    i = np.arange(n) + 0.5
    phi = np.arccos(1 - 2 * i / n)
    theta = np.pi * (1 + 5**0.5) * i
    pts = np.c_[np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)] * radius_m
    return pts + np.asarray(center)


def ring(n: int, radius_m: float, center=(0.0, 0.0, 60.0)) -> np.ndarray:
    """n points on a vertical (x-z) circle."""
    a = 2 * np.pi * np.arange(n) / n
    return np.c_[radius_m * np.cos(a), np.zeros(n), radius_m * np.sin(a)] + np.asarray(center)


def make_show(formations: list[dict], *, drones: int, rows: int, cols: int, spacing_m: float = 3.0,
              **settings) -> ShowFile:
    """A validated show with a home grid and the given formations (points as arrays or lists)."""
    fs = []
    for f in formations:
        f = dict(f)
        f["points"] = np.round(np.asarray(f["points"], dtype=float), 6).tolist()
        fs.append(f)
    return parse_show(
        {
            "format": "swarmshow/1",
            "name": "test",
            "drones": drones,
            "home": {"grid": {"rows": rows, "cols": cols, "spacing_m": spacing_m}},
            "settings": settings,
            "formations": fs,
        }
    )

#: Rows of the waypoints CSV are written with 3 decimals (mm); a row read back is within half of that.
CSV_HALF_MM = 0.0005 + 1e-9


@pytest.fixture(scope="module")
def square():
    """Four drones on a 5 m square at 15 m for a second: the export tests' smallest flown show."""
    return make_show(
        [{"name": "square", "hold_s": 1.0, "points": [[0, 0, 15], [5, 0, 15], [0, 5, 15], [5, 5, 15]],
          "color": "#ffffff"}],
        drones=4, rows=2, cols=2, spacing_m=4.5,
    )


@pytest.fixture(scope="module")
def square_id(client, square) -> str:
    """The four-drone square stored through the module's API ``client`` (a module defines ``client``)."""
    from formations import dump_show

    r = client.post("/api/shows", content=dump_show(square), headers={"content-type": "application/json"})
    assert r.status_code == 201, r.text
    return str(r.json()["id"])


@pytest.fixture(scope="module")
def square_plan(square):
    from sim import plan_show

    return plan_show(square)


def flown_at(flight, drone: int, times_s: np.ndarray) -> np.ndarray:
    """``(T, 3)`` positions of ``drone`` of a flight result at ``times_s`` (linear between its frames)."""
    t = np.asarray(flight.times_s, dtype=np.float64)
    pos = np.asarray(flight.positions_m, dtype=np.float64)[:, drone]
    return np.stack([np.interp(times_s, t, pos[:, a]) for a in range(3)], axis=1)



def ring_to_sphere(drones: int, ring_m: float, sphere_m: float, sphere_hold_s: float, **settings) -> ShowFile:
    """``drones`` (a multiple of 4) on a vertical ring (held 2 s), then on a sphere, from a home grid
    4 wide spaced for CAPT's guarantee (4.5 m >= 3·√2 m); ``settings`` as the show file's."""
    return make_show(
        [
            {"name": "ring", "hold_s": 2.0, "points": ring(drones, ring_m), "color": "#ff0000"},
            {"name": "sphere", "hold_s": sphere_hold_s, "points": fibonacci_sphere(drones, sphere_m),
             "color": "#00ff00"},
        ],
        drones=drones, rows=drones // 4, cols=4, spacing_m=4.5, **settings,
    )


def small_show_file(**settings) -> ShowFile:
    """The small show: 16 drones, a 12 m ring then a 9 m sphere held 3 s."""
    return ring_to_sphere(16, 12.0, 9.0, 3.0, **settings)


@pytest.fixture
def small_show() -> ShowFile:
    """16 drones: ring then sphere, spaced for CAPT's guarantee (>= 3·√2 m)."""
    return small_show_file()


@pytest.fixture(scope="module")
def small_plan():
    """The small show (:func:`small_show_file`), planned."""
    from sim import plan_show

    return plan_show(small_show_file())


@pytest.fixture(scope="module")
def plan12():
    """12 drones, a 10 m ring then an 8 m sphere held 2 s, planned (the flight robustness and
    Monte-Carlo tests fly it)."""
    from sim import plan_show

    return plan_show(ring_to_sphere(12, 10.0, 8.0, 2.0))


def app_client(name: str, **settings):
    """A module-scoped ``client`` fixture: the app (``create_app(AppSettings(**settings))``) on a fresh data
    directory named after ``name``, under FastAPI's TestClient on a loopback base URL (its job pools start and
    stop with the module). Use it at module level as ``client = app_client("data", workers=1)``."""

    @pytest.fixture(scope="module", name="client")
    def _client(tmp_path_factory: pytest.TempPathFactory):
        from fastapi.testclient import TestClient

        from app.server import create_app
        from app.settings import AppSettings

        app = create_app(AppSettings(data_dir=tmp_path_factory.mktemp(name), **settings))
        with TestClient(app, base_url="http://127.0.0.1") as c:
            yield c

    return _client


def fleet_off_its_circles(n: int, seed: int, *, velocity_sd_mps: float, rate_sd_rad_s: float | None = None):
    """``n`` drones on circles (4 m, 0.8 rad/s) round random centres in a 60 m cube 50 m up, started 4 m off
    them at hover attitude with random velocities (and body rates): ``(ref, start)``, the flight-engine
    tests' busy start. Draws from ``default_rng(seed)``: the centres, the velocities, then the rates."""
    from sim.flight import TrackingReference, hover_state

    rng = np.random.default_rng(seed)
    centers = rng.uniform(-30.0, 30.0, (n, 3)) + [0.0, 0.0, 50.0]
    ref = TrackingReference.circle(centers, radius_m=4.0, omega_rad_s=0.8)
    start = hover_state(centers + [4.0, 0.0, 0.0])
    start[:, 6:9] = rng.normal(scale=velocity_sd_mps, size=(n, 3))
    if rate_sd_rad_s is not None:
        start[:, 9:12] = rng.normal(scale=rate_sd_rad_s, size=(n, 3))
    return ref, start


class StaggeredLegs:
    """Closed form of a plan re-timed by :func:`staggered_plan` (independent of the polynomial tables).

    Per segment k: every drone rests at ``start_m[k]`` until ``depart_s[k]``, flies the
    straight line to ``end_m[k]`` in ``duration_s[k]`` with s(τ) = 10τ³ - 15τ⁴ + 6τ⁵
    (or 3τ² - 2τ³ where ``cubic[k]``), then rests until the window ends.
    """

    def __init__(self) -> None:
        self.window_s: list[tuple[float, float]] = []
        self.start_m: list[np.ndarray] = []
        self.end_m: list[np.ndarray] = []
        self.depart_s: list[np.ndarray] = []
        self.duration_s: list[np.ndarray] = []
        self.cubic: list[np.ndarray] = []

    def positions(self, times_s: np.ndarray) -> np.ndarray:
        """(T, N, 3) positions at ``times_s`` (seconds, inside the show)."""
        t = np.asarray(times_s, dtype=float)
        starts = np.array([w[0] for w in self.window_s])
        out = np.empty((len(t), len(self.start_m[0]), 3))
        for j, tj in enumerate(t):
            k = min(max(int(np.searchsorted(starts, tj, side="right")) - 1, 0), len(starts) - 1)
            dur = self.duration_s[k]
            tau = np.clip((tj - self.depart_s[k]) / np.where(dur > 0, dur, 1.0), 0.0, 1.0)
            tau = np.where(dur > 0, tau, 1.0)
            s = np.where(self.cubic[k], tau**2 * (3 - 2 * tau), tau**3 * (10 - 15 * tau + 6 * tau**2))
            out[j] = self.start_m[k] + s[:, None] * (self.end_m[k] - self.start_m[k])
        return out


def staggered_plan(plan, *, seed: int = 0, fraction: float = 0.5):
    """``plan`` with per-drone timing inside every transition window, windows and knots kept.

    A random ``fraction`` of the drones depart up to 30 % of the window late and arrive up
    to 20 % early; half of those fly a cubic smoothstep instead of the quintic, so the
    plan mixes degree-3 and degree-5 pieces, zero-length pieces (drones without delay)
    and drone-specific break times. Returns ``(plan, StaggeredLegs)``.
    """
    from dataclasses import replace

    from sim.plan import TrajectoryBuilder

    rng = np.random.default_rng(seed)
    knots, times = plan.knot_positions_m, plan.knot_times_s
    n = plan.drone_count
    builder = TrajectoryBuilder(knots[0], float(times[0]))
    legs = StaggeredLegs()
    for k, seg in enumerate(plan.segments):
        t0, t1 = float(times[k]), float(times[k + 1])
        a, b = knots[k], knots[k + 1]
        chosen = (rng.random(n) < fraction) & (seg.kind == "transition") & (t1 > t0)
        depart = t0 + np.where(chosen, rng.uniform(0.0, 0.3, n), 0.0) * (t1 - t0)
        arrive = t1 - np.where(chosen, rng.uniform(0.0, 0.2, n), 0.0) * (t1 - t0)
        cubic = chosen & (rng.random(n) < 0.5)
        dur = arrive - depart
        builder.hold_until(depart)
        d = b - a
        c = np.zeros((n, 3, 6))
        c[..., 0] = a
        safe = np.where(dur > 0, dur, 1.0)[:, None]
        c[..., 2] = np.where(cubic[:, None], 3 * d / safe**2, 0.0)
        c[..., 3] = np.where(cubic[:, None], -2 * d / safe**3, 10 * d / safe**3)
        c[..., 4] = np.where(cubic[:, None], 0.0, -15 * d / safe**4)
        c[..., 5] = np.where(cubic[:, None], 0.0, 6 * d / safe**5)
        c[dur <= 0, :, 1:] = 0.0
        builder.append(dur, c)
        builder.hold_until(np.full(n, t1))
        legs.window_s.append((t0, t1))
        legs.start_m.append(a)
        legs.end_m.append(b)
        legs.depart_s.append(depart)
        legs.duration_s.append(dur)
        legs.cubic.append(cubic)
    return replace(plan, trajectories=builder.build()), legs


@pytest.fixture(scope="session")
def staggered_small():
    """The 16-drone ring -> sphere show, planned, then re-timed per drone: ``(plan, legs)``.

    Planned with the quintic, whose windows leave room for the re-timed legs (late
    departures, early arrivals) within the limits the controller tracks; minimum-time
    windows are too tight to be squeezed further.
    """
    from sim import plan_show

    return staggered_plan(plan_show(small_show_file(time_law="quintic")), seed=1)


# ``make test-fast`` leaves out the ``integration`` tests: those that start a server, a worker
# pool, a Dask cluster or a browser, kill processes, fuzz the API, or fly / plan a large show
# (each several seconds). Marked here, by module and by test name, so the test files stay as
# they are; ``make test`` runs everything.
INTEGRATION_MODULES = frozenset({
    "test_api_fuzz", "test_api_jobs", "test_api_live", "test_assignment_scale", "test_flight_dask",
    "test_hardening_concurrency", "test_hardening_crash", "test_hardening_exposure", "test_hardening_inputs",
    "test_hardening_sim", "test_viewer_app",
})
INTEGRATION_TESTS = frozenset({
    "test_step_reference_converges",  # 30 s of flight
    "test_thousand_drones_three_minutes_under_50_mb",  # a 1000-drone HTML export
    "test_demo_show_flies_with_flown_min_distance",  # the 100-drone demo flown
    "test_check_matches_dense_sampling_on_the_papers_12_drones",
    "test_diverging_drones_are_reported_and_the_rest_fly_on",
    "test_check_cache_and_shows_survive_a_restart",
    "test_check_report_and_cache",  # a worker pool
    "test_an_internal_error_is_a_json_500",  # a worker pool
    "test_cli_paper_scenario",  # two 20 s flights
    "test_diverging_drone_in_a_show",
})


def _module(item: pytest.Item) -> str:
    module = getattr(item, "module", None)
    return module.__name__.rpartition(".")[2] if module is not None else ""


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        name = item.originalname if isinstance(item, pytest.Function) else item.name
        if _module(item) in INTEGRATION_MODULES or name in INTEGRATION_TESTS:
            item.add_marker(pytest.mark.integration)
    # The modules that never fly run first, while the flight kernel compiles beside them (below).
    # A stable sort: each module's tests keep their order, and the modules theirs within each group.
    items.sort(key=lambda item: _module(item) not in KERNEL_FREE_MODULES)


# -- the flight kernel, compiled beside the first tests ----------------------------------------------
# A fresh clone has no numba cache, and the parallel flight kernel (sim/flight/engines/_numba.py) takes
# about a minute of CPU to compile for each of its two variants (float64 frames for ``simulate``,
# float32 for ``fly_show``). Every process of the run (this one, each server, worker pool and Dask
# worker a test starts) shares one on-disk cache (``__pycache__`` next to the source, or
# ``NUMBA_CACHE_DIR`` when set, which child processes inherit), so each variant is compiled once per
# run; but the first test that flies used to wait for that compile on one core while the other
# idled. So a child process compiles both variants into that same cache (``warm_up``, which compiles
# through numba's cache exactly as a first flight would, see ``_cached_machine_code``) while the
# modules below run, and the first test outside them waits for it. With a warm cache the child only
# loads the kernels. Tests of cold-cache behaviour use cache directories of their own, except that the
# compile-vs-load test takes the warm-up as its cold process when the warm-up met a cold cache (it flies
# that test's flight first, tests/kernel_witness.py): a fresh clone then compiles the kernel once, not
# twice. These modules neither fly nor start a process that does (checked with a fresh cache: running
# them alone writes no flight kernel), nor analyse music.
KERNEL_FREE_MODULES = frozenset({
    "test_api_formations", "test_api_lights", "test_api_locs", "test_api_store", "test_architecture",
    "test_assignment_scale", "test_bench_cli", "test_editor_js_units", "test_editor_static",
    "test_exports_crazyswarm", "test_exports_frames", "test_exports_moving", "test_exports_qgc",
    "test_exports_qgc_safety", "test_exports_skybrush_readers", "test_exports_skyc_cues",
    "test_exports_trajectories", "test_formations_closest_pair", "test_formations_demo_cli",
    "test_formations_filled", "test_formations_image_svg", "test_formations_mesh", "test_formations_shapes",
    "test_formations_strokes_text", "test_formations_transforms", "test_geometry_closest_pair", "test_launch",
    "test_launch_api", "test_launch_exports", "test_light_effects", "test_light_preview_parity",
    "test_plan_assignment", "test_plan_blend", "test_plan_cache", "test_plan_cues", "test_plan_groups",
    "test_plan_motion", "test_plan_quintic", "test_plan_schedule", "test_plan_show", "test_plan_timelaw",
    "test_plan_trajectory", "test_plan_verify", "test_show_file", "test_verify_bounds", "test_verify_downwash",
    "test_verify_exact", "test_verify_sweep", "test_viewer_export", "test_viewer_lights_preview",
    "test_viewer_marks", "test_plan_group_through", "test_flight_vmath32", "test_flight_kernel_compile",
})
#: Fewer kernel-free tests than this to overlap with, and the warm-up is not worth its compile of a
#: variant the selected tests may not need (e.g. one test file run alone): they compile on first use.
_WARM_UP_MIN_OVERLAP = 50
#: Then librosa's beat tracker (its jitted kernels, about 25 s of CPU cold), which the first test that
#: analyses music would compile in its server process.
_WARM_UP_CODE = """
from sim.flight.engines import warm_up
warm_up()
import numpy as np
from app.media._beats import detect_beats
clicks = np.zeros(4 * 22_050, np.float32)
clicks[::11_025] = 1.0
detect_beats(clicks, 22_050)
# The tests that fly float64 may start now; the opt-in float32 kernel (FLOAT32_MODULES) compiles last,
# still beside the tests instead of on the test thread.
import pathlib
(pathlib.Path(sys.argv[1]) / "phase1.ok").touch()
warm_up(precisions=("float32",))
"""
#: Modules that fly the opt-in float32 kernel: they wait for the whole warm-up, the others only for its
#: float64 kernels and the beat tracker (a fresh clone's tests waited 149 s for the float32 compile).
FLOAT32_MODULES = frozenset({"test_flight_precision"})


class _WarmUp:
    """The warm-up child process (:data:`_WARM_UP_CODE`) and its figures."""

    def __init__(self) -> None:
        self.proc: subprocess.Popen[bytes] | None = None
        self.log: IO[bytes] | None = None
        self.t0 = self.took_s = self.waited_s = 0.0
        self.error = ""
        self.done = False
        self.first_s = self.first_waited_s = 0.0
        self.first_done = False
        self.witness_dir: Path | None = None

    def start(self) -> None:
        from tests.kernel_witness import WITNESS_IN_WARM_UP

        self.log = tempfile.TemporaryFile()  # its stderr (a pipe could fill up and stall it)
        self.witness_dir = Path(tempfile.mkdtemp(prefix="swarmshow-warm-up-"))
        # First the compile-vs-load test's cold flight (tests/kernel_witness.py), then the warm-up.
        code = f"import sys; sys.path.insert(0, {str(_ROOT)!r})\n{WITNESS_IN_WARM_UP}\n{_WARM_UP_CODE}"
        self.proc = subprocess.Popen([sys.executable, "-c", code, str(self.witness_dir)],
                                     stdout=subprocess.DEVNULL, stderr=self.log, start_new_session=True)
        self.t0 = time.monotonic()

    def cold_flight(self) -> Path | None:
        """Positions of tests/kernel_witness.py's flight by the warm-up child on a cold cache (it compiled
        the kernel), once the warm-up is done; None if there is none (no warm-up, or the cache was warm)."""
        self.wait_first()
        if self.witness_dir is None or not (self.witness_dir / "cold.ok").exists():
            return None
        return self.witness_dir / "cold.npy"

    def wait_first(self) -> None:
        """Until the float64 kernels and the beat tracker are in the cache (or the child ended)."""
        if self.proc is None or self.first_done or self.done:
            return
        t = time.monotonic()
        assert self.witness_dir is not None
        while self.proc.poll() is None and not (self.witness_dir / "phase1.ok").exists():
            if time.monotonic() - t > 1800:  # then the tests compile on first use
                self.stop()
                break
            time.sleep(0.2)
        self.first_done = True
        self.first_waited_s, self.first_s = time.monotonic() - t, time.monotonic() - self.t0

    def wait(self) -> None:
        """Until the whole warm-up (the float32 kernel too) is done."""
        if self.proc is None or self.done:
            return
        self.wait_first()
        t = time.monotonic()
        try:
            self.proc.wait(timeout=1800)
        except subprocess.TimeoutExpired:  # then the tests compile on first use
            self.stop()
        self.done = True
        self.waited_s, self.took_s = time.monotonic() - t, time.monotonic() - self.t0
        if self.proc.returncode and self.log is not None:  # not fatal: each process compiles on first use
            self.log.seek(0)
            self.error = self.log.read().decode(errors="replace")[-2000:] or f"exit {self.proc.returncode}"

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGKILL)  # its compiling grandchild too
            self.proc.wait()
        if self.witness_dir is not None:
            shutil.rmtree(self.witness_dir, ignore_errors=True)


_warm_up = _WarmUp()


def pytest_collection_finish(session: pytest.Session) -> None:
    free = sum(_module(item) in KERNEL_FREE_MODULES for item in session.items)
    if os.environ.get("SWARMSHOW_TEST_WARM_UP", "1") == "0":  # off (e.g. to measure without it)
        return
    if free >= _WARM_UP_MIN_OVERLAP and free < len(session.items):
        _warm_up.start()


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    if _module(item) in FLOAT32_MODULES:
        _warm_up.wait()
    elif _module(item) not in KERNEL_FREE_MODULES:
        _warm_up.wait_first()


def pytest_sessionfinish(session: pytest.Session) -> None:
    _warm_up.stop()
    live_server = sys.modules.get("tests.live_server")  # imported only where a test used it
    if live_server is not None:
        live_server.close_chromiums()


@pytest.fixture(scope="session")
def cold_kernel_flight() -> Path | None:
    """The compile-vs-load test's cold witness from the session's warm-up, if it has one
    (:meth:`_WarmUp.cold_flight`, tests/kernel_witness.py)."""
    return _warm_up.cold_flight()


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    if _warm_up.first_done:
        terminalreporter.write_line(f"numba warm-up (flight kernel, beat tracker): {_warm_up.first_s:.1f} s beside "
                                    f"the first tests, then waited {_warm_up.first_waited_s:.1f} s for it")
    if _warm_up.done:
        terminalreporter.write_line(f"numba warm-up of the float32 kernel: done {_warm_up.took_s:.1f} s after the "
                                    f"start, waited {_warm_up.waited_s:.1f} s for it")
    if _warm_up.error:
        terminalreporter.write_line(f"numba warm-up failed (the tests compiled on first use):\n{_warm_up.error}")


# -- browser tests -------------------------------------------------------------------------------
# Every browser test module starts its own Chromium (module scope: a crash stays in its module) and
# defines its own `server` fixture, mostly as `server = server_for("x-data", viewer=...)` from
# tests/live_server.py (its own data directory and viewer switch); `ui` is a fresh editor page on
# that server. The imports are lazy so that collecting the fast suite never loads Playwright.


@pytest.fixture(scope="module")
def browser():
    """Debian's Chromium through Playwright (see tests/live_server.py)."""
    from tests.live_server import chromium_browser

    with chromium_browser() as b:
        yield b


@pytest.fixture
def ui(browser, server, tmp_path):
    """The editor open in a new page of ``browser`` on the module's ``server``."""
    from tests.test_editor_browser import Page

    p = Page(browser, server, tmp_path)
    yield p
    p.close()
