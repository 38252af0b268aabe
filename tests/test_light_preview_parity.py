"""The editor's live light preview (frontend/js/lighteval.js) paints the same colours as sim.light.

Drones resting on a formation's points, every effect kind the browser evaluates by itself
(images need the browser's decoder and are covered by the browser test), at many times: node
runs the JavaScript, numpy the server's kernels, and the two agree to float32 rounding.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from formations import parse_show
from sim.light import LightStack
from sim.plan import plan_show
from tests.test_light_effects import _show_doc

NODE = shutil.which("node")
LIGHTEVAL = Path(__file__).resolve().parents[1] / "frontend" / "js" / "lighteval.js"

EFFECTS = [
    {"start_s": 0.0, "end_s": 30.0, "effect": {"kind": "ramp", "colors": ["#200000", "#0040ff", "#ff8000"]}},
    {"start_s": 2.0, "end_s": 20.0, "fade_in_s": 2.0, "fade_out_s": 2.0, "blend": "max",
     "effect": {"kind": "sweep", "colors": ["#ff0000", "#00ff00", "#0000ff"], "axis": [1, 0, 1], "length_m": 9.0,
                "speed_mps": 4.0}},
    {"start_s": 1.0, "end_s": 25.0, "blend": "add", "opacity": 0.6,
     "effect": {"kind": "sweep", "colors": ["#ffffff", "#000000"], "mode": "radial", "center_m": [4, 0, 24]}},
    {"start_s": 5.0, "end_s": 26.0, "blend": "add", "effect": {"kind": "chase", "color": "#ffffff", "period_s": 3.0,
                                                                "width": 0.3}},
    {"start_s": 3.0, "end_s": 28.0, "blend": "multiply", "target": {"kind": "group", "group": "g"},
     "effect": {"kind": "chase", "color": "#ffff00", "shape": "wave", "period_s": 2.0}},
    {"start_s": 8.0, "end_s": 30.0, "effect": {"kind": "sparkle", "color": "#ffffff", "density": 0.4, "seed": 9,
                                                "flash_s": 0.5}},
    {"start_s": 12.0, "end_s": 16.0, "effect": {"kind": "strobe", "color": "#ff00ff", "frequency_hz": 3.0,
                                                 "duty": 0.4}},
    {"start_s": 0.0, "end_s": 30.0, "blend": "multiply", "target": {"kind": "box", "min_m": [-1, -1, 19],
                                                                      "max_m": [5, 1, 25]},
     "effect": {"kind": "solid", "color": "#8080ff"}},
    {"start_s": 0.0, "end_s": 30.0, "blend": "add", "target": {"kind": "plane", "point_m": [4, 0, 0],
                                                                 "normal": [1, 0, 0]},
     "effect": {"kind": "solid", "color": "#202020"}},
    {"start_s": 0.0, "end_s": 30.0, "target": {"kind": "drones", "indices": [2, 7]}, "opacity": 0.5,
     "effect": {"kind": "solid", "color": "#00ff00"}},
]

_RUNNER = """
import { evaluateColors } from %s;
let text = "";
process.stdin.on("data", (d) => { text += d; });
process.stdin.on("end", () => {
  const c = JSON.parse(text);
  const out = c.times.map((t) => evaluateColors(c.show, c.formation, c.points, c.base, t));
  process.stdout.write(JSON.stringify(out));
});
"""


@pytest.mark.skipif(NODE is None, reason="node is not installed")
def test_browser_preview_matches_the_server() -> None:
    doc = _show_doc(EFFECTS, groups={"g": [0, 1, 2, 3]})
    show = parse_show(doc)
    plan = plan_show(show)
    f = show.formations[0]
    points = f.points_m[: show.drones]
    base = f.colors_rgb[: show.drones]
    times = np.linspace(0.0, 31.0, 125)
    stack = LightStack.from_show(show, plan)
    want = stack.apply(times, np.broadcast_to(base, (len(times), *base.shape)).copy(),
                       np.broadcast_to(points, (len(times), *points.shape)).copy())
    case = {"show": doc, "formation": f.name, "points": points.tolist(), "base": base.tolist(),
            "times": times.tolist()}
    assert NODE is not None
    proc = subprocess.run([NODE, "--input-type=module", "-e", _RUNNER % json.dumps(LIGHTEVAL.as_uri())],
                          input=json.dumps(case), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    got = np.array(json.loads(proc.stdout))
    np.testing.assert_allclose(got, want, atol=2e-5)
    assert np.abs(got - base).max() > 0.3  # the effects change the colours
