"""Shared fixtures and builders for the test suite."""

from __future__ import annotations

import numpy as np
import pytest

from formations import ShowFile, parse_show


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


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        module = item.module.__name__.rpartition(".")[2] if item.module is not None else ""
        name = item.originalname if isinstance(item, pytest.Function) else item.name
        if module in INTEGRATION_MODULES or name in INTEGRATION_TESTS:
            item.add_marker(pytest.mark.integration)


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
