"""The editor's live light preview (frontend/js/lighteval.js) paints the same colours as sim.light.

Drones resting on a formation's points, every effect kind (images handed to the JavaScript already
decoded, as the browser's canvas decodes them; the front view and through an audience camera), at
many times: node runs the JavaScript, numba the server's kernels, and the two agree to float32
rounding.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from formations import parse_show
from sim.light import LightStack, show_colors
from sim.plan import plan_show
from tests.test_light_effects import _png_url, _show_doc

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
  const images = (fx) => (c.images[fx.name] || null);
  const out = c.times.map((t) => evaluateColors(c.show, c.formation, c.points, c.base, t, images));
  process.stdout.write(JSON.stringify(out));
});
"""


@pytest.mark.skipif(NODE is None, reason="node is not installed")
def test_browser_preview_matches_the_server() -> None:
    rng = np.random.default_rng(1)
    frames = [rng.integers(0, 256, (5, 7, 4), dtype=np.uint8) for _ in range(2)]
    image_fx = [
        {"name": "front", "start_s": 4.0, "end_s": 22.0, "blend": "max", "effect": {
            "kind": "image", "frames": [_png_url(f) for f in frames], "fps": 1.5, "center_m": [4.0, 0.0, 24.0],
            "width_m": 11.0, "height_m": 10.0}},
        {"name": "camera", "start_s": 10.0, "end_s": 30.0, "effect": {
            "kind": "image", "frames": [_png_url(frames[1])], "center_m": [4.0, 30.0, 24.0], "width_m": 20.0,
            "height_m": 16.0, "camera_m": [1.0, -50.0, 2.0]}},
    ]
    decoded = {
        "front": [{"w": 7, "h": 5, "data": f.ravel().tolist()} for f in frames],
        "camera": [{"w": 7, "h": 5, "data": frames[1].ravel().tolist()}],
    }
    doc = _show_doc(EFFECTS + image_fx, groups={"g": [0, 1, 2, 3]})
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
            "times": times.tolist(), "images": decoded}
    assert NODE is not None
    proc = subprocess.run([NODE, "--input-type=module", "-e", _RUNNER % json.dumps(LIGHTEVAL.as_uri())],
                          input=json.dumps(case), capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    got = np.array(json.loads(proc.stdout))
    np.testing.assert_allclose(got, want, atol=2e-5)
    assert np.abs(got - base).max() > 0.3  # the effects change the colours


@pytest.mark.skipif(NODE is None, reason="node is not installed")
def test_browser_preview_of_a_points_target() -> None:
    """The canvas shows points, so a ``points`` target paints exactly those points of the formation on
    screen (the server finds the drones that fly there); on another formation it paints nothing."""
    fx = [{"start_s": 0.0, "end_s": 30.0, "target": {"kind": "points", "formation": "A", "indices": [1, 3]},
           "effect": {"kind": "solid", "color": "#ff00ff"}}]
    doc = _show_doc(fx)
    f = parse_show(doc).formations[0]
    base = f.colors_rgb[:9]
    out = []
    for name in ("A", "B"):
        case = {"show": doc, "formation": name, "points": f.points_m[:9].tolist(), "base": base.tolist(),
                "times": [5.0], "images": {}}
        assert NODE is not None
        proc = subprocess.run([NODE, "--input-type=module", "-e", _RUNNER % json.dumps(LIGHTEVAL.as_uri())],
                              input=json.dumps(case), capture_output=True, text=True, timeout=60)
        assert proc.returncode == 0, proc.stderr[-2000:]
        out.append(np.array(json.loads(proc.stdout))[0])
    want = base.copy()
    want[[1, 3]] = [1.0, 0.0, 1.0]
    np.testing.assert_allclose(out[0], want, atol=1e-9)
    np.testing.assert_allclose(out[1], base, atol=1e-9)


_PLANNED_RUNNER = """
import { evaluatePlanned } from %s;
let text = "";
process.stdin.on("data", (d) => { text += d; });
process.stdin.on("end", () => {
  const c = JSON.parse(text);
  const out = c.cases.map((x) => evaluatePlanned(c.show, x.k, x.points, x.base, x.t, c.plan));
  process.stdout.write(JSON.stringify(out));
});
"""


@pytest.mark.skipif(NODE is None, reason="node is not installed")
def test_planned_preview_matches_the_server_on_the_drones_holding_a_formation() -> None:
    """With a check's plan summary (app.tasks.plan_summary: its assignment and segments) the editor paints each
    formation's points with the colour the server gives the drone the plan sends there: drone indices, groups,
    sparkle seeds, index chases, points targets of any formation and formation targets in their planned windows."""
    from app.tasks import plan_summary

    effects = [
        {"start_s": 0.0, "end_s": 60.0, "effect": {"kind": "ramp", "colors": ["#200000", "#0040ff"]}, "opacity": 0.5},
        {"start_s": 0.0, "end_s": 60.0, "target": {"kind": "drones", "indices": [0, 4]},
         "effect": {"kind": "solid", "color": "#00ff00"}},
        {"start_s": 0.0, "end_s": 60.0, "target": {"kind": "group", "group": "g"}, "blend": "add",
         "effect": {"kind": "solid", "color": "#000080"}},
        {"start_s": 0.0, "end_s": 60.0, "target": {"kind": "points", "formation": "B", "indices": [2, 6]},
         "effect": {"kind": "solid", "color": "#ff00ff"}},
        {"start_s": 0.0, "end_s": 60.0, "target": {"kind": "formation", "formation": "A"}, "blend": "multiply",
         "effect": {"kind": "solid", "color": "#80ff80"}},
        {"start_s": 1.0, "end_s": 60.0, "blend": "add", "effect": {"kind": "chase", "color": "#ffffff",
                                                                   "period_s": 3.0, "width": 0.3}},
        {"start_s": 0.0, "end_s": 60.0, "blend": "max", "effect": {"kind": "sparkle", "color": "#ffffff",
                                                                    "density": 0.4, "seed": 5, "flash_s": 0.5}},
        {"start_s": 0.0, "end_s": 60.0, "blend": "max", "target": {"kind": "box", "min_m": [-5, -1, 19],
                                                                    "max_m": [3, 6, 26]},
         "effect": {"kind": "sweep", "colors": ["#ff0000", "#0000ff"], "axis": [1, 0, 0], "length_m": 7.0}},
    ]
    doc = _show_doc(effects, groups={"g": [1, 2, 3, 8]})
    # B lies flat (one height: its own z order is the drone index), listed so that the assignment is not the identity.
    doc["formations"][1]["points"] = [[x * 4.0 - 4.0, 5.0 + y * 4.0, 25.0] for y in range(3) for x in range(3)][::-1]
    plan = plan_show(parse_show(doc))
    # A chase along z that starts in A's hold: ranked by where the plan put the drones in A, also later in B.
    a_hold = plan.formation_segments()[0][1]
    doc["lights"]["effects"].append({"start_s": a_hold.start_s + 1.0, "end_s": 60.0, "blend": "add", "effect": {
        "kind": "chase", "color": "#404040", "order": "z", "period_s": 2.5, "width": 0.4}})
    show = parse_show(doc)
    plan = plan_show(show)
    summary = json.loads(json.dumps(plan_summary(plan)))
    assignment = np.array(summary["assignment"])
    assert assignment.shape == (2, 9) and (assignment != np.arange(9)).any()
    cases, want = [], []
    for k, (_, hold) in enumerate(plan.formation_segments()):
        f = show.formations[k]
        for t in np.linspace(hold.start_s + 0.01, hold.end_s - 0.01, 7):
            cases.append({"k": k, "t": float(t), "points": f.points_m.tolist(), "base": f.colors_rgb.tolist()})
            drones = show_colors(show, plan, [t])[0]  # the server: drone i's colour
            per_point = np.empty((9, 3))
            per_point[assignment[k]] = drones
            want.append(per_point)
    assert NODE is not None
    proc = subprocess.run([NODE, "--input-type=module", "-e", _PLANNED_RUNNER % json.dumps(LIGHTEVAL.as_uri())],
                          input=json.dumps({"show": doc, "plan": summary, "cases": cases}),
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]
    got = np.array(json.loads(proc.stdout))
    np.testing.assert_allclose(got, np.array(want), atol=2e-5)
