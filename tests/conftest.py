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
