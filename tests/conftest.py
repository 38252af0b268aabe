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


@pytest.fixture
def small_show() -> ShowFile:
    """16 drones: ring then sphere, spaced for CAPT's guarantee (>= 3·√2 m)."""
    return make_show(
        [
            {"name": "ring", "hold_s": 2.0, "points": ring(16, 12.0), "color": "#ff0000"},
            {"name": "sphere", "hold_s": 3.0, "points": fibonacci_sphere(16, 9.0), "color": "#00ff00"},
        ],
        drones=16, rows=4, cols=4, spacing_m=4.5,
    )


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
