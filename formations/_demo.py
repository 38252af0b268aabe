"""The bundled demo show: 100 drones, a 10 x 10 home grid and five coloured formations.

Every formation keeps at least DEMO_SPACING_M between points. CAPT guarantees only
spacing/√2 during a transition, so 4.5 m keeps the flown separation above the default
3 m minimum distance (3·√2 ≈ 4.24 m) with margin.
"""

from __future__ import annotations

from importlib import resources
from typing import TYPE_CHECKING, Any

import numpy as np

from formations._show import SHOW_FORMAT, ShowFile, parse_show

if TYPE_CHECKING:
    from formations._points import PointSet

#: Drones in the demo show.
DEMO_DRONES = 100
#: Minimum spacing inside every demo formation, metres (>= 3 m · √2, see the module docstring).
DEMO_SPACING_M = 4.5
#: Bundled copy of :func:`demo_show` (regenerate with ``dump_show(demo_show())``).
DEMO_SHOW_FILE = "demo_show.json"
#: Coordinates are rounded to this many decimals (1 mm), so the bundled JSON is reproducible
#: on any platform whatever the last bits of its trigonometry.
_DECIMALS = 3


def _merge(*parts: PointSet) -> tuple[np.ndarray, list[str]]:
    points = np.round(np.vstack([p.points_m for p in parts]), _DECIMALS)
    colors = [c for p in parts for c in p.hex_colors()]
    return points, colors


def _gradient(z: np.ndarray, low: tuple[int, int, int], high: tuple[int, int, int]) -> list[str]:
    """Colours blending ``low`` (bottom) to ``high`` (top) by height."""
    t = ((z - z.min()) / max(float(np.ptp(z)), 1e-9))[:, None]
    rgb = np.rint((1 - t) * np.array(low) + t * np.array(high)).astype(np.int64)
    return [f"#{r:02x}{g:02x}{b:02x}" for r, g, b in rgb.tolist()]


def _formation(name: str, points: np.ndarray, colors: list[str], hold_s: float = 6.0) -> dict[str, Any]:
    return {"name": name, "hold_s": hold_s, "points": points.tolist(), "colors": colors}


def demo_show() -> ShowFile:
    """Build the demo show: 100 drones from a 10 x 10 grid (4.5 m) at default settings flying
    three concentric rings, three nested hearts, the text "HI!", a sphere and a helix (metres;
    every point between 15 and 90 m, the flat ones facing the audience in the x-z plane).

    Returns:
        The validated show (``check_show`` finds no violation).
    """
    # The shape and text sources (Pillow, FreeType) load only here: `swarmshow validate`
    # imports this package and should not pay for them.
    from formations._shapes import generate_shape
    from formations._text import text_points

    s = DEMO_SPACING_M
    rings = _merge(
        *(
            generate_shape("circle", n, size_m=size, center_m=(0, 0, 52), min_spacing_m=s, color=color)
            for n, size, color in ((45, 65.0, "#00c8ff"), (33, 48.0, "#ff40c0"), (22, 32.0, "#ffffff"))
        )
    )
    hearts = _merge(
        *(
            generate_shape("heart", n, size_m=size, center_m=(0, 0, 52), min_spacing_m=s, color=color)
            for n, size, color in ((45, 72.0, "#ff1030"), (33, 52.0, "#ff6080"), (22, 34.0, "#ffb0c0"))
        )
    )
    text = _merge(text_points("HI!", DEMO_DRONES, height_m=42.0, center_m=(0, 0, 45), min_spacing_m=s,
                              color="#ffd020"))
    sphere_pts = np.round(
        generate_shape("sphere", DEMO_DRONES, size_m=34.0, center_m=(0, 0, 40), min_spacing_m=s).points_m,
        _DECIMALS,
    )
    helix_pts = np.round(
        generate_shape(
            "helix", DEMO_DRONES, size_m=40.0, center_m=(0, 0, 42), min_spacing_m=s, turns=3.6, radius_m=20.0
        ).points_m,
        _DECIMALS,
    )
    doc = {
        "format": SHOW_FORMAT,
        "name": "Demo",
        "drones": DEMO_DRONES,
        "home": {"grid": {"rows": 10, "cols": 10, "spacing_m": s}},
        "formations": [
            _formation("rings", *rings),
            _formation("heart", *hearts),
            _formation("hi", *text),
            _formation("sphere", sphere_pts, _gradient(sphere_pts[:, 2], (40, 60, 255), (120, 255, 220))),
            _formation("helix", helix_pts, _gradient(helix_pts[:, 2], (255, 120, 0), (160, 40, 255))),
        ],
    }
    return parse_show(doc)


def load_demo_show() -> ShowFile:
    """Read and validate the bundled ``formations/data/demo_show.json``."""
    data = resources.files("formations").joinpath("data", DEMO_SHOW_FILE).read_bytes()
    return parse_show(data)
