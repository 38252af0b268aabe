"""Light effects (issue 18): the show model's rules, and the vectorised evaluator against a scalar
reference written from the documented formulas (one drone, one frame at a time, plain ``math``)."""

from __future__ import annotations

import base64
import io
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from formations import ShowValidationError, parse_show
from sim.light import LightStack, show_colors
from sim.plan import plan_show

# ----------------------------------------------------------------------------- a small show


def _show_doc(effects: list[dict], *, groups: dict | None = None) -> dict:
    pts_a = [[x * 4.0, 0.0, 20.0 + z * 4.0] for z in range(3) for x in range(3)]
    pts_b = [[x * 4.0 - 4.0, 5.0, 25.0 + z * 4.0] for z in range(3) for x in range(3)]
    colors = ["#ff0000", "#00ff00", "#0000ff", "#ffffff", "#808080", "#102030", "#ffff00", "#00ffff", "#ff00ff"]
    lights: dict = {"effects": effects}
    if groups is not None:
        lights["groups"] = groups
    return {
        "format": "swarmshow/1",
        "name": "lights",
        "drones": 9,
        "home": {"grid": {"rows": 3, "cols": 3, "spacing_m": 3.0}},
        "formations": [
            {"name": "A", "hold_s": 6.0, "points": pts_a, "colors": colors},
            {"name": "B", "hold_s": 6.0, "points": pts_b, "color": "#4060a0"},
        ],
        "lights": lights,
    }


@pytest.fixture(scope="module")
def plan():
    return plan_show(parse_show(_show_doc([])))


def _fx(kind: dict, **extra) -> dict:
    return {"start_s": extra.pop("start_s", 2.0), "end_s": extra.pop("end_s", 30.0), "effect": kind, **extra}


# ------------------------------------------------------------------------- scalar reference


def _rgb(hexstr: str) -> list[float]:
    return [int(hexstr[k:k + 2], 16) / 255.0 for k in (1, 3, 5)]


_MASK = (1 << 64) - 1


def _mix(x: int) -> int:
    x &= _MASK
    x ^= x >> 30
    x = (x * 0xBF58476D1CE4E5B9) & _MASK
    x ^= x >> 27
    x = (x * 0x94D049BB133111EB) & _MASK
    return x ^ (x >> 31)


def _hash01(seed: int, drone: int, slot: int) -> float:
    h = _mix((_mix((seed << 32) | drone) + (slot & _MASK)) & _MASK)
    return (h >> 11) / 2.0**53


def _gradient(stops: list[list[float]], x: float, wrap: bool) -> list[float]:
    k = int(math.floor(x))
    k = min(max(k, 0), len(stops) - 1 if wrap else len(stops) - 2)
    w = x - k
    nxt = (k + 1) % len(stops) if wrap else k + 1
    return [stops[k][c] * (1 - w) + stops[nxt][c] * w for c in range(3)]


def _reference(doc: dict, plan, t: float, i: int, pos: list[float], base: list[float], images=None) -> list[float]:
    """One drone's colour at one time, from the formulas of formations/_effects.py."""
    r = list(base)
    n = doc["drones"]
    for k, fx in enumerate(doc["lights"]["effects"]):
        if not fx.get("enabled", True) or not (fx["start_s"] <= t < fx["end_s"]):
            continue
        s0, s1 = fx["start_s"], fx["end_s"]
        env = 1.0
        if fx.get("fade_in_s", 0) > 0:
            env = min(env, (t - s0) / fx["fade_in_s"])
        if fx.get("fade_out_s", 0) > 0:
            env = min(env, (s1 - t) / fx["fade_out_s"])
        a = max(0.0, min(1.0, env)) * fx.get("opacity", 1.0)
        tg = fx.get("target", {"kind": "all"})
        if tg["kind"] == "drones" and i not in tg["indices"]:
            continue
        if tg["kind"] == "group" and i not in doc["lights"]["groups"][tg["group"]]:
            continue
        if tg["kind"] == "points":
            tr = next(tr for tr in plan.transitions if tr.to_name == tg["formation"])
            if int(tr.goal_index[i]) not in tg["indices"]:
                continue
        if tg["kind"] == "box" and not all(tg["min_m"][c] <= pos[c] <= tg["max_m"][c] for c in range(3)):
            continue
        if tg["kind"] == "plane" and sum((pos[c] - tg["point_m"][c]) * tg["normal"][c] for c in range(3)) < 0:
            continue
        if tg["kind"] == "formation":
            seg_in = [s for s in plan.segments if s.label == tg["formation"]]
            if not (min(s.start_s for s in seg_in) <= t < max(s.end_s for s in seg_in)):
                continue
        e = fx["effect"]
        kind = e["kind"]
        if kind == "solid":
            col = _rgb(e["color"])
        elif kind == "ramp":
            stops = [_rgb(c) for c in e["colors"]]
            col = _gradient(stops, (t - s0) / (s1 - s0) * (len(stops) - 1), wrap=False)
        elif kind == "sweep":
            stops = [_rgb(c) for c in e["colors"]]
            if e.get("mode", "linear") == "linear":
                ax = e.get("axis", [1, 0, 0])
                norm = math.sqrt(sum(v * v for v in ax))
                along = sum(pos[c] * ax[c] / norm for c in range(3))
            else:
                along = math.dist(pos, e.get("center_m", [0, 0, 0]))
            phase = (along - e.get("speed_mps", 10.0) * (t - s0)) / e.get("length_m", 20.0)
            col = _gradient(stops, (phase - math.floor(phase)) * len(stops), wrap=True)
        elif kind == "chase":
            col = _rgb(e["color"])
            order = e.get("order", "index")
            if order == "index":
                q = i / n
            else:
                ax = "xyz".index(order)
                p0 = plan.motion.evaluate([s0], derivatives=0).positions_m[0, :, ax]
                q = sorted(range(n), key=lambda j: (p0[j], j)).index(i) / n
            rel = q - (t - s0) / e.get("period_s", 2.0)
            rel -= math.floor(rel)
            if e.get("shape", "pulse") == "wave":
                b = 0.5 * (1 + math.cos(2 * math.pi * rel))
            else:
                b = max(0.0, 1 - min(rel, 1 - rel) / e.get("width", 0.1))
            a *= b
        elif kind == "sparkle":
            col = _rgb(e["color"])
            flash = e.get("flash_s", 0.3)
            x = (t - s0) / flash + _hash01(e.get("seed", 0), i, -1)
            slot = math.floor(x)
            u = x - slot
            a *= (1 - abs(2 * u - 1)) if _hash01(e.get("seed", 0), i, slot) < e.get("density", 0.2) else 0.0
        elif kind == "strobe":
            col = _rgb(e["color"])
            x = (t - s0) * e.get("frequency_hz", 4.0)
            a *= 1.0 if x - math.floor(x) < e.get("duty", 0.5) else 0.0
        elif kind == "image":
            img = images[k]
            h, w = len(img), len(img[0])
            cx, cy, cz = e["center_m"]
            x, z = pos[0], pos[2]
            if e.get("camera_m") is not None:  # similar triangles through the camera onto y = cy
                c = e["camera_m"]
                if pos[1] <= c[1]:
                    continue
                s = (cy - c[1]) / (pos[1] - c[1])
                x, z = c[0] + s * (pos[0] - c[0]), c[2] + s * (pos[2] - c[2])
            u = (x - (cx - e["width_m"] / 2)) / e["width_m"]
            v = (cz + e["height_m"] / 2 - z) / e["height_m"]
            if not (0 <= u < 1 and 0 <= v < 1):
                continue
            px = img[int(v * h)][int(u * w)]
            col = px[:3]
            a *= px[3]
        else:
            raise AssertionError(kind)
        mode = fx.get("blend", "replace")
        for c in range(3):
            if mode == "replace":
                v_ = r[c] + a * (col[c] - r[c])
            elif mode == "add":
                v_ = r[c] + a * col[c]
            elif mode == "multiply":
                v_ = r[c] * (1 - a + a * col[c])
            else:
                v_ = r[c] + a * (max(r[c], col[c]) - r[c])
            r[c] = min(1.0, max(0.0, v_))
    return r


def _check(doc: dict, plan, times: np.ndarray, images=None, tol: float = 2e-5) -> np.ndarray:
    show = parse_show(doc)
    got = show_colors(show, plan, times)
    sample = plan.evaluate(times)
    want = np.array([[_reference(doc, plan, float(t), i, sample.positions_m[k, i].tolist(),
                                 sample.colors_rgb[k, i].tolist(), images)
                      for i in range(show.drones)] for k, t in enumerate(times)])
    np.testing.assert_allclose(got, want, atol=tol)
    return got


TIMES = np.linspace(0.0, 40.0, 161)


@pytest.mark.parametrize("kind", [
    {"kind": "solid", "color": "#ff8000"},
    {"kind": "ramp", "colors": ["#ff0000", "#00ff00", "#0000ff"]},
    {"kind": "sweep", "colors": ["#ff0000", "#0000ff", "#ffffff"], "axis": [1, 0, 1], "length_m": 7.0,
     "speed_mps": 3.0},
    {"kind": "sweep", "colors": ["#ff0000", "#00ff00"], "mode": "radial", "center_m": [4, 0, 24],
     "length_m": 5.0, "speed_mps": -2.0},
    {"kind": "chase", "color": "#00ffff", "period_s": 3.0, "width": 0.25},
    {"kind": "chase", "color": "#00ffff", "order": "x", "shape": "wave", "period_s": 1.5},
    {"kind": "sparkle", "color": "#ffffff", "density": 0.4, "flash_s": 0.5, "seed": 7},
    {"kind": "strobe", "color": "#ff00ff", "frequency_hz": 3.0, "duty": 0.3},
], ids=lambda k: f"{k['kind']}-{k.get('mode', k.get('order', ''))}")
def test_each_kind_matches_the_scalar_reference(plan, kind: dict) -> None:
    doc = _show_doc([_fx(kind, fade_in_s=2.0, fade_out_s=3.0)])
    got = _check(doc, plan, TIMES)
    # The effect changes something inside its range and nothing outside.
    base = plan.evaluate(TIMES).colors_rgb
    outside = (TIMES < 2.0) | (TIMES >= 30.0)
    np.testing.assert_allclose(got[outside], base[outside], atol=1e-6)
    assert np.abs(got[~outside] - base[~outside]).max() > 0.05


@pytest.mark.parametrize("blend", ["replace", "add", "multiply", "max"])
def test_blend_modes_and_stack_order(plan, blend: str) -> None:
    doc = _show_doc([
        _fx({"kind": "ramp", "colors": ["#204060", "#c08010"]}, start_s=0.0, end_s=35.0),
        _fx({"kind": "solid", "color": "#8040ff"}, blend=blend, opacity=0.7, fade_in_s=4.0, start_s=5.0),
    ])
    _check(doc, plan, TIMES)


def test_blend_closed_forms(plan) -> None:
    """Half-opacity grey 0.5 over base colour c: replace (c+0.5)/2, add c+0.25, multiply 0.75c, max."""
    t = np.array([10.0])
    base = plan.evaluate(t).colors_rgb[0]
    grey = 0x80 / 255
    want = {
        "replace": base + 0.5 * (grey - base),
        "add": np.minimum(1.0, base + 0.5 * grey),
        "multiply": base * (1 - 0.5 + 0.5 * grey),
        "max": base + 0.5 * (np.maximum(base, grey) - base),
    }
    for mode, expect in want.items():
        show = parse_show(_show_doc([_fx({"kind": "solid", "color": "#808080"}, blend=mode, opacity=0.5)]))
        np.testing.assert_allclose(show_colors(show, plan, t)[0], expect, atol=1e-6)


@pytest.mark.parametrize("target", [
    {"kind": "drones", "indices": [0, 4, 8]},
    {"kind": "group", "group": "left"},
    {"kind": "box", "min_m": [-1, -1, 19], "max_m": [5, 1, 25]},
    {"kind": "plane", "point_m": [4, 0, 0], "normal": [1, 0, 0.2]},
    {"kind": "formation", "formation": "B"},
    {"kind": "points", "formation": "B", "indices": [0, 2, 7]},
], ids=lambda t: t["kind"])
def test_targets(plan, target: dict) -> None:
    doc = _show_doc([_fx({"kind": "solid", "color": "#00ff80"}, target=target, start_s=0.0, end_s=40.0)],
                    groups={"left": [0, 3, 6]})
    got = _check(doc, plan, TIMES)
    base = plan.evaluate(TIMES).colors_rgb
    touched = np.abs(got - base).max(axis=2) > 1e-6
    assert touched.any() and not touched.all()  # the target picks some drones (or times), not all


def test_disabled_and_zero_opacity_effects_do_nothing(plan) -> None:
    doc = _show_doc([_fx({"kind": "solid", "color": "#00ff80"}, enabled=False),
                     _fx({"kind": "solid", "color": "#00ff80"}, opacity=0.0)])
    np.testing.assert_allclose(show_colors(parse_show(doc), plan, TIMES), plan.evaluate(TIMES).colors_rgb)


def _png_url(pixels: np.ndarray, fmt: str = "PNG") -> str:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(pixels).save(buf, format=fmt)
    mime = "png" if fmt == "PNG" else "jpeg"
    return f"data:image/{mime};base64," + base64.b64encode(buf.getvalue()).decode()


def test_image_sequence_projection_matches_the_pixels(plan) -> None:
    rng = np.random.default_rng(3)
    frames = [rng.integers(0, 256, (5, 6, 4), dtype=np.uint8) for _ in range(3)]
    frames[1][..., 3] = 255
    kind = {"kind": "image", "frames": [_png_url(f) for f in frames], "fps": 2.0,
            "center_m": [4.0, 0.0, 24.0], "width_m": 9.0, "height_m": 9.5}
    doc = _show_doc([_fx(kind, start_s=1.0, end_s=38.0)])
    # The reference is handed the frame shown at t, picked with its own index arithmetic.
    show = parse_show(doc)
    got = show_colors(show, plan, TIMES)
    sample = plan.evaluate(TIMES)
    for k, t in enumerate(TIMES):
        which = int(math.floor((t - 1.0) * 2.0 + 1e-9)) % 3 if t >= 1.0 else 0
        imgs = {0: [[list(px / 255.0) for px in row] for row in frames[which]]}
        for i in range(9):
            want = _reference(doc, plan, float(t), i, sample.positions_m[k, i].tolist(),
                              sample.colors_rgb[k, i].tolist(), imgs)
            np.testing.assert_allclose(got[k, i], want, atol=2e-5)
    # During the first hold (t in the hold of A) the drones sit on the 3 x 3 grid inside the picture.
    hold = next(s for s in plan.segments if s.kind == "hold" and s.label == "A")
    t = np.array([hold.start_s + 0.1])
    assert np.abs(show_colors(show, plan, t) - plan.evaluate(t).colors_rgb).max() > 0.05


def test_image_through_the_audience_camera(plan) -> None:
    """Perspective from a camera in front: the scalar reference and a closed form (a drone on the ray from
    the camera through a pixel's centre takes that pixel, whatever its depth)."""
    rng = np.random.default_rng(5)
    px = rng.integers(0, 256, (4, 5, 4), dtype=np.uint8)
    px[..., 3] = 255
    kind = {"kind": "image", "frames": [_png_url(px)], "center_m": [4.0, 40.0, 24.0], "width_m": 30.0,
            "height_m": 24.0, "camera_m": [2.0, -60.0, 1.7]}
    doc = _show_doc([_fx(kind, start_s=0.0, end_s=40.0)])
    imgs = {0: [[list(p / 255.0) for p in row] for row in px]}
    show = parse_show(doc)
    got = show_colors(show, plan, TIMES)
    sample = plan.evaluate(TIMES)
    for k, t in enumerate(TIMES):
        for i in range(9):
            want = _reference(doc, plan, float(t), i, sample.positions_m[k, i].tolist(),
                              sample.colors_rgb[k, i].tolist(), imgs)
            np.testing.assert_allclose(got[k, i], want, atol=2e-5)
    # Closed form: put drone positions on rays through pixel centres at two depths.
    from sim.light import LightStack

    cam = np.array([2.0, -60.0, 1.7])
    centres = np.array([[4.0 - 15.0 + (c + 0.5) * 6.0, 40.0, 24.0 + 12.0 - (r + 0.5) * 6.0]
                        for r in range(4) for c in range(5)])
    rays = np.concatenate([cam + (centres - cam) * s for s in (0.5, 1.7)])
    stack = LightStack.from_show(show, plan)
    base = np.zeros((1, len(rays), 3))
    # apply() takes any n columns with drone ids; the image effect does not read ids.
    stack.drone_count = len(rays)
    out = stack.apply([10.0], base, rays[None])[0]
    want = np.tile(px[..., :3].reshape(-1, 3) / 255.0, (2, 1))
    np.testing.assert_allclose(out, want, atol=1e-6)


def test_jpeg_frames_decode(plan) -> None:
    px = np.full((4, 4, 3), (200, 30, 90), dtype=np.uint8)
    kind = {"kind": "image", "frames": [_png_url(px, "JPEG")], "center_m": [4.0, 0.0, 24.0],
            "width_m": 40.0, "height_m": 40.0}
    show = parse_show(_show_doc([_fx(kind, start_s=0.0, end_s=40.0)]))
    hold = next(s for s in plan.segments if s.kind == "hold" and s.label == "A")
    got = show_colors(show, plan, [hold.start_s + 1.0])[0]
    np.testing.assert_allclose(got, np.tile([200 / 255, 30 / 255, 90 / 255], (9, 1)), atol=4 / 255)


def test_sparkle_is_seeded_and_has_its_density(plan) -> None:
    """Over many slots the fraction of flashing slots is the density (binomial, 5 sigma)."""
    n_slots = 4000
    kind = {"kind": "sparkle", "color": "#ffffff", "density": 0.3, "flash_s": 0.1, "seed": 11}
    doc = _show_doc([_fx(kind, start_s=0.0, end_s=n_slots * 0.1, blend="replace")])
    doc["formations"][0]["hold_s"] = n_slots * 0.1
    doc["formations"][0]["color"] = "#000000"
    del doc["formations"][0]["colors"]
    show = parse_show(doc)
    p = plan_show(show)
    hold = next(s for s in p.segments if s.kind == "hold" and s.label == "A")
    # Sample every slot's peak-ish interior: 4 samples per slot, a slot is lit when any sample is bright.
    t = np.arange(hold.start_s + 1.0, hold.end_s - 1.0, 0.025)
    c = show_colors(show, p, t)[..., 0]
    again = show_colors(parse_show(doc), p, t)[..., 0]
    np.testing.assert_array_equal(c, again)
    lit = (c > 0.3).mean()
    # A lit slot is bright (> 0.3) for 70 % of it, so the bright fraction is 0.7 x density.
    assert abs(lit - 0.7 * 0.3) < 5 * math.sqrt(0.21 * 0.79 / (len(t) * 9 / 4)) + 0.01
    doc["lights"]["effects"][0]["effect"]["seed"] = 12
    assert not np.array_equal(show_colors(parse_show(doc), p, t)[..., 0], c)


@settings(max_examples=25, deadline=None)
@given(
    start=st.floats(0.0, 20.0), length=st.floats(0.5, 20.0), fin=st.floats(0, 1), fout=st.floats(0, 1),
    opacity=st.floats(0, 1), blend=st.sampled_from(["replace", "add", "multiply", "max"]),
    color=st.integers(0, 0xFFFFFF),
)
def test_fades_and_blends_random(plan, start, length, fin, fout, opacity, blend, color) -> None:
    kind = {"kind": "solid", "color": f"#{color:06x}"}
    doc = _show_doc([_fx(kind, start_s=start, end_s=start + length, fade_in_s=fin * length / 2,
                         fade_out_s=fout * length / 2, blend=blend, opacity=opacity)])
    _check(doc, plan, np.linspace(0, 45, 46))


def test_apply_checks_shapes(plan) -> None:
    stack = LightStack.from_show(parse_show(_show_doc([_fx({"kind": "sweep", "colors": ["#ff0000", "#00ff00"]})])),
                                 plan)
    assert stack.needs_positions
    with pytest.raises(ValueError, match="positions"):
        stack.apply([5.0], np.zeros((1, 9, 3)))
    with pytest.raises(ValueError, match="drones"):
        stack.apply([5.0], np.zeros((1, 4, 3)), np.zeros((1, 4, 3)))


# ----------------------------------------------------------------------------- validation


@pytest.mark.parametrize(("change", "path", "words"), [
    (lambda fx: fx.update(end_s=1.0), "lights.effects[0]", "after start_s"),
    (lambda fx: fx.update(fade_in_s=20.0, fade_out_s=10.0), "lights.effects[0]", "longer than the effect"),
    (lambda fx: fx.update(blend="screen"), "lights.effects[0].blend", ""),
    (lambda fx: fx.update(target={"kind": "drones", "indices": [3, 9]}), "lights.effects[0].target.indices",
     "out of range"),
    (lambda fx: fx.update(target={"kind": "group", "group": "nope"}), "lights.effects[0].target.group", "nope"),
    (lambda fx: fx.update(target={"kind": "formation", "formation": "C"}), "lights.effects[0].target.formation",
     "no formation"),
    (lambda fx: fx.update(target={"kind": "points", "formation": "A", "indices": [9]}),
     "lights.effects[0].target.indices", "formation 'A' has 9 points"),
    (lambda fx: fx.update(target={"kind": "box", "min_m": [0, 0, 5], "max_m": [1, 1, 1]}),
     "lights.effects[0].target", "min_m <= max_m"),
    (lambda fx: fx.update(effect={"kind": "strobe", "color": "#fff"}), "lights.effects[0].effect.color", ""),
    (lambda fx: fx.update(effect={"kind": "strobe", "color": "#ffffff", "frequency_hz": 100}),
     "lights.effects[0].effect.frequency_hz", ""),
    (lambda fx: fx.update(effect={"kind": "image", "frames": ["data:image/gif;base64,R0lG"],
                                  "center_m": [0, 0, 0], "width_m": 1, "height_m": 1}),
     "lights.effects[0].effect.frames", "data:image/png"),
    (lambda fx: fx.update(effect={"kind": "image", "frames": ["data:image/png;base64,aGVsbG8gd29ybGQhIQ=="],
                                  "center_m": [0, 0, 0], "width_m": 1, "height_m": 1}),
     "lights.effects[0].effect.frames", "neither a PNG"),
    (lambda fx: fx.update(effect={"kind": "sweep", "colors": ["#ffffff", "#000000"], "axis": [0, 0, 0]}),
     "lights.effects[0].effect.axis", "zero"),
    (lambda fx: fx.update(effect={"kind": "wobble"}), "lights.effects[0].effect", ""),
    (lambda fx: fx.update(effect={"kind": "image", "frames": [_png_url(np.zeros((2, 2, 3), np.uint8))],
                                  "center_m": [0, 10, 20], "width_m": 1, "height_m": 1, "camera_m": [0, 10, 2]}),
     "lights.effects[0].effect", "in front of the picture"),
])
def test_bad_effects_name_their_path(change, path: str, words: str) -> None:
    fx = _fx({"kind": "solid", "color": "#ffffff"})
    change(fx)
    with pytest.raises(ShowValidationError) as info:
        parse_show(_show_doc([fx]))
    err = info.value.errors[0]
    assert err["path"].startswith(path), err
    assert words in err["msg"], err


def test_group_index_out_of_range_is_rejected() -> None:
    with pytest.raises(ShowValidationError) as info:
        parse_show(_show_doc([], groups={"g": [1, 99]}))
    assert info.value.errors[0]["path"] == "lights.groups.g"


def test_show_without_lights_keeps_its_hash() -> None:
    doc = _show_doc([])
    del doc["lights"]
    show = parse_show(doc)
    assert "\"lights\":" not in show.canonical_json()


def test_plan_positions_kernel_matches_the_plan(plan) -> None:
    from sim.light import plan_positions

    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(-1.0, plan.duration_s + 1.0, 300))
    np.testing.assert_allclose(plan_positions(plan, t), plan.motion.evaluate(t).positions_m, atol=1e-9)
    shuffled = rng.permutation(t)
    np.testing.assert_allclose(plan_positions(plan, shuffled, np.array([2, 5])),
                               plan.motion.evaluate(shuffled, np.array([2, 5])).positions_m, atol=1e-9)
    part = plan_positions(plan, t, frames=np.arange(0, 300, 2))
    np.testing.assert_array_equal(part[1::2], 0.0)


VIDEO_COLORS = [(255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 0), (0, 255, 255), (255, 255, 255)]


def _video_url(fps: int, colors=VIDEO_COLORS, codec: str = "mpeg4", fmt: str = "mp4") -> str:
    """A small video made with PyAV: one solid colour per frame at ``fps``."""
    import av

    buf = io.BytesIO()
    with av.open(buf, mode="w", format=fmt) as out:
        stream = out.add_stream(codec, rate=fps)
        stream.width, stream.height, stream.pix_fmt = 32, 24, "yuv420p"
        for rgb in colors:
            frame = av.VideoFrame.from_ndarray(np.full((24, 32, 3), rgb, dtype=np.uint8), format="rgb24")
            for packet in stream.encode(frame):
                out.mux(packet)
        for packet in stream.encode():
            out.mux(packet)
    mime = "mp4" if fmt == "mp4" else fmt
    return f"data:video/{mime};base64," + base64.b64encode(buf.getvalue()).decode()


@pytest.mark.parametrize(("fps", "codec", "fmt"), [(2, "mpeg4", "mp4"), (50, "libvpx", "webm")])
def test_video_projection_shows_the_frame_at_each_time(plan, fps: int, codec: str, fmt: str) -> None:
    """Each frame is one solid colour, so every drone inside the picture takes the colour of the frame
    at (t - start) into the video (sampled at min(fps, 25), looped); codecs lose a few levels."""
    colors = VIDEO_COLORS if fps < 25 else [c for c in VIDEO_COLORS for _ in range(fps // 2)]
    kind = {"kind": "video", "video": _video_url(fps, colors, codec, fmt), "center_m": [4.0, 0.0, 24.0],
            "width_m": 40.0, "height_m": 40.0}
    hold = next(s for s in plan.segments if s.kind == "hold" and s.label == "A")
    start = hold.start_s
    show = parse_show(_show_doc([_fx(kind, start_s=start, end_s=start + 6.0)]))
    rate = min(fps, 25)
    seconds_per_colour = 1.0 / fps * (1 if fps < 25 else fps // 2)
    times = start + np.arange(1, 11) * 0.55
    got = show_colors(show, plan, times)
    for k, t in enumerate(times):
        sample = math.floor((t - start) * rate + 1e-9)
        n_samples = math.ceil(len(colors) / fps * rate)  # the video's length in samples: it loops
        video_t = (sample % n_samples) / rate
        want = np.array(VIDEO_COLORS[min(int(video_t / seconds_per_colour + 1e-9), len(VIDEO_COLORS) - 1)]) / 255
        np.testing.assert_allclose(got[k], np.tile(want, (9, 1)), atol=12 / 255, err_msg=f"t - start = {t - start}")


def test_bad_videos_are_refused_with_their_path() -> None:
    bad = {"kind": "video", "video": "data:video/mp4;base64," + base64.b64encode(b"not a video at all").decode(),
           "center_m": [0, 0, 20], "width_m": 10, "height_m": 10}
    with pytest.raises(ShowValidationError) as info:
        parse_show(_show_doc([_fx(bad)]))
    assert info.value.errors[0]["path"] == "lights.effects[0].effect.video"
    assert "cannot read the video" in info.value.errors[0]["msg"]
    bad["video"] = "data:video/avi;base64,AAAA"
    with pytest.raises(ShowValidationError, match="data:video/mp4"):
        parse_show(_show_doc([_fx(bad)]))


def test_decoding_budgets_are_enforced_when_the_show_is_loaded() -> None:
    """A small PNG can hold a huge image and a show many of them: pixels are counted from the headers."""
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (4100, 4100)).save(buf, format="PNG")
    huge = "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()
    kind = {"kind": "image", "frames": [huge], "center_m": [0, 0, 20], "width_m": 10, "height_m": 10}
    with pytest.raises(ShowValidationError) as info:
        parse_show(_show_doc([_fx(kind)]))
    assert info.value.errors[0]["path"] == "lights.effects[0].effect.frames"
    assert "pixels" in info.value.errors[0]["msg"]

    buf = io.BytesIO()
    Image.new("RGB", (4000, 4000)).save(buf, format="PNG")
    big = "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()
    kind["frames"] = [big] * 5  # 80 M pixels together
    with pytest.raises(ShowValidationError) as info:
        parse_show(_show_doc([_fx(kind)]))
    assert info.value.errors[0]["path"] == "lights.effects[0].effect.frames"

    video = {"kind": "video", "video": _video_url(2, VIDEO_COLORS[:2]), "center_m": [0, 0, 20], "width_m": 10,
             "height_m": 10}
    parse_show(_show_doc([_fx(video)] * 4))
    with pytest.raises(ShowValidationError) as info:
        parse_show(_show_doc([_fx(video)] * 5))
    assert info.value.errors[0]["path"] == "lights.effects[4].effect.video"


def test_editing_only_the_effects_does_not_plan_again() -> None:
    from sim.plan import cached_plan_show, clear_plan_cache, plan_cache_info

    clear_plan_cache()
    a = cached_plan_show(parse_show(_show_doc([_fx({"kind": "solid", "color": "#ff0000"})])))
    b = cached_plan_show(parse_show(_show_doc([_fx({"kind": "strobe", "color": "#00ff00"})])))
    assert a is b and plan_cache_info()["misses"] == 1
    doc = _show_doc([])
    doc["formations"][0]["hold_s"] = 7.0
    assert cached_plan_show(parse_show(doc)) is not a
