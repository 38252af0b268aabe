"""Light effects in the exports (issue 18): ``.skyc`` light programs replayed by an independent
``ledctrl`` reader within 1 colour level of the effect stack at 50 Hz, their size against fades
written by hand, and the effect colours in the Skybrush CSV, the waypoints CSV and the tracks."""

from __future__ import annotations

import base64
import csv
import io
import json
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.exports import export_show, make_track
from app.exports._ledctrl import encode_keyframes, fit_fades, fitted_program, varuint
from app.exports._skyc import light_program
from formations import parse_show
from sim.light import LightStack, show_colors
from sim.plan import plan_show
from tests import ledctrl_reader
from tests.test_light_effects import _png_url, _show_doc, _video_url

ALL_KINDS = [
    {"start_s": 0.0, "end_s": 40.0, "effect": {"kind": "ramp", "colors": ["#200000", "#0040ff", "#ff8000"]}},
    {"start_s": 4.0, "end_s": 20.0, "fade_in_s": 2.0, "fade_out_s": 2.0, "blend": "max",
     "effect": {"kind": "sweep", "colors": ["#ff0000", "#00ff00", "#0000ff"], "length_m": 12.0, "speed_mps": 4.0}},
    {"start_s": 10.0, "end_s": 26.0, "blend": "add", "effect": {"kind": "chase", "color": "#ffffff", "period_s": 3.0}},
    {"start_s": 18.0, "end_s": 34.0, "effect": {"kind": "sparkle", "color": "#ffffff", "density": 0.3, "seed": 5}},
    {"start_s": 24.0, "end_s": 27.0, "effect": {"kind": "strobe", "color": "#ff00ff", "frequency_hz": 4.0}},
    {"start_s": 28.0, "end_s": 38.0, "target": {"kind": "box", "min_m": [-1, -10, 0], "max_m": [5, 10, 60]},
     "blend": "multiply", "effect": {"kind": "solid", "color": "#8080ff"}},
]


@pytest.fixture(scope="module")
def lit():
    doc = _show_doc(ALL_KINDS + [{
        "start_s": 12.0, "end_s": 30.0, "effect": {
            "kind": "image", "frames": [_png_url(np.random.default_rng(k).integers(0, 256, (6, 8, 3), dtype=np.uint8))
                                        for k in range(2)],
            "fps": 1.0, "center_m": [4.0, 0.0, 26.0], "width_m": 16.0, "height_m": 16.0}}, {
        "start_s": 30.0, "end_s": 36.0, "blend": "add", "effect": {
            "kind": "video", "video": _video_url(2), "center_m": [4.0, 0.0, 26.0], "width_m": 6.0,
            "height_m": 30.0}}])
    show = parse_show(doc)
    return show, plan_show(show)


def _skyc_programs(show, plan) -> list[bytes]:
    result = export_show(show, "skyc", plan=plan)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        doc = json.loads(z.read("show.json"))
    return [base64.b64decode(d["settings"]["lights"]["data"]) for d in doc["swarm"]["drones"]]


def test_skyc_programs_replay_the_effect_stack_within_one_level(lit) -> None:
    show, plan = lit
    programs = _skyc_programs(show, plan)
    n_frames = int(np.ceil(plan.duration_s * 50)) + 1
    t = np.minimum(np.arange(n_frames) / 50.0, plan.duration_s)
    want = show_colors(show, plan, t).astype(np.float64) * 255.0
    assert len(programs) == show.drones
    for i, code in enumerate(programs):
        got = ledctrl_reader.replay(code, n_frames)
        assert np.abs(got - want[:, i]).max() <= 0.5 + 1e-3, i
        assert np.abs(np.rint(got) - np.rint(want[:, i])).max() <= 1, i
    # The effects are really there: the programs differ from the plan's own colours.
    base = plan.evaluate(t).colors_rgb * 255.0
    assert max(np.abs(ledctrl_reader.replay(c, n_frames) - base[:, i]).max() for i, c in enumerate(programs)) > 50
    per_minute = sum(map(len, programs)) / show.drones / (plan.duration_s / 60.0)
    print(f"bytes per drone per minute: {per_minute:.0f}")


def test_show_without_effects_keeps_the_exact_knot_programs() -> None:
    doc = _show_doc([])
    show = parse_show(doc)
    plan = plan_show(show)
    frames = np.rint(plan.knot_times_s * 50).astype(np.int64)
    colors = np.clip(np.rint(plan.knot_colors_rgb * 255.0), 0, 255).astype(np.int64)
    assert _skyc_programs(show, plan) == [light_program(frames, colors[:, i]) for i in range(show.drones)]


def test_piecewise_linear_effects_cost_at_most_twice_the_hand_written_fades() -> None:
    """Ramps, fades and a strobe are piecewise linear in time: written by hand, one fade or hold per
    breakpoint (the plan's knots and every effect edge). The fitted programs stay within 2x of that."""
    effects = [
        {"start_s": 0.0, "end_s": 36.0, "blend": "multiply",
         "effect": {"kind": "ramp", "colors": ["#ffffff", "#4080ff", "#ff8040", "#ffffff"]}},
        {"start_s": 6.0, "end_s": 16.0, "fade_in_s": 3.0, "fade_out_s": 2.0, "effect": {"kind": "solid",
                                                                                          "color": "#00ff00"}},
        {"start_s": 20.0, "end_s": 22.0, "effect": {"kind": "strobe", "color": "#ffffff", "frequency_hz": 5.0,
                                                     "duty": 0.5}},
    ]
    show = parse_show(_show_doc(effects))
    plan = plan_show(show)
    programs = _skyc_programs(show, plan)
    edges = {0.0, 36.0, 6.0, 9.0, 14.0, 16.0, 12.0, 24.0}
    edges |= {20.0 + k * 0.1 for k in range(21)}  # strobe: on/off every 0.1 s
    edges |= set(plan.knot_times_s.tolist())
    frames = np.unique(np.rint(np.array(sorted(edges)) * 50).astype(np.int64))
    frames = frames[frames <= int(np.ceil(plan.duration_s * 50))]
    t = np.minimum(frames / 50.0, plan.duration_s)
    # A hard edge is two keyframes a frame apart (the colour before it and after it).
    hard = np.unique(np.r_[frames, frames[(frames > 1000) & (frames < 1100)] - 1])
    th = np.minimum(hard / 50.0, plan.duration_s)
    colors = np.clip(np.rint(show_colors(show, plan, th) * 255.0), 0, 255).astype(np.int64)
    hand = [light_program(hard, colors[:, i]) for i in range(show.drones)]
    ratio = sum(map(len, programs)) / sum(map(len, hand))
    print(f"fitted / hand-written fades: {ratio:.2f} ({sum(map(len, programs))} / {sum(map(len, hand))} bytes)")
    assert ratio <= 2.0
    assert len(t) > 10


@settings(max_examples=40, deadline=None)
@given(
    knots=st.lists(st.tuples(st.integers(1, 80), st.integers(0, 255), st.integers(0, 255), st.integers(0, 255)),
                   min_size=1, max_size=12),
    noise=st.floats(0.0, 0.3),
    seed=st.integers(0, 1000),
)
def test_fit_stays_within_tolerance_of_any_track(knots, noise, seed) -> None:
    """Random piecewise-linear tracks with jumps and noise: every frame replays within 0.5 levels."""
    rng = np.random.default_rng(seed)
    pieces = []
    for length, r, g, b in knots:
        start = rng.uniform(0, 255, 3)
        pieces.append(start + (np.array([r, g, b]) - start) * np.linspace(0, 1, length)[:, None])
    track = np.clip(np.concatenate(pieces) + rng.normal(0, noise, (sum(k[0] for k in knots), 3)), 0, 255)
    code = fitted_program(track)
    got = ledctrl_reader.replay(code, len(track))
    assert np.abs(got - track).max() <= 0.5 + 1e-9
    frames, colors = fit_fades(track)
    assert frames[0] == 0 and frames[-1] == len(track) - 1
    assert len(frames) <= len(track)


def test_a_straight_fade_is_one_command() -> None:
    track = np.linspace([0, 10, 200], [255, 100, 0], 5000)
    frames, colors = fit_fades(track)
    assert frames.tolist() == [0, 4999]
    assert colors.tolist() == [[0, 10, 200], [255, 100, 0]]
    code = encode_keyframes(frames, colors)
    assert code == bytes([0x04, 0, 10, 200, 0, 0x08, 255, 100, 0]) + varuint(4999) + b"\x00"


@pytest.mark.parametrize(("value", "encoded"), [(0, b"\x00"), (127, b"\x7f"), (128, b"\x80\x01"),
                                                (300, b"\xac\x02"), (2**21, b"\x80\x80\x80\x01")])
def test_varuint_is_leb128(value: int, encoded: bytes) -> None:
    assert varuint(value) == encoded


def _csv_colors(content: bytes, name: str) -> tuple[np.ndarray, np.ndarray]:
    with zipfile.ZipFile(io.BytesIO(content)) as z:
        rows = list(csv.reader(io.StringIO(z.read(name).decode())))[1:]
    arr = np.array(rows, dtype=float)
    return arr[:, 0], arr[:, 4:7]


@pytest.mark.parametrize(("fmt", "scale", "name"), [("skybrush-csv", 1000.0, "drone_004.csv"),
                                                     ("waypoints-csv", 1.0, "drone_004.csv")])
def test_csv_colours_carry_the_effects(lit, fmt: str, scale: float, name: str) -> None:
    show, plan = lit
    result = export_show(show, fmt, fps=10.0, plan=plan)
    t_col, rgb = _csv_colors(result.content, name)
    t = t_col / scale
    want = np.clip(np.rint(show_colors(show, plan, t)[:, 3] * 255.0), 0, 255)
    assert np.abs(rgb - want).max() <= 1  # float32 vs float64 rounding at .5
    base = np.clip(np.rint(plan.evaluate(t).colors_rgb[:, 3] * 255.0), 0, 255)
    assert np.abs(rgb - base).max() > 50


def test_tracks_carry_the_effects(lit) -> None:
    show, plan = lit
    stack = LightStack.from_show(show, plan)
    track = make_track(plan, None, "planned", stack)
    t = np.array([5.0, 15.0, 25.0])
    pos, colors, _ = track.sample(t)
    np.testing.assert_allclose(colors, show_colors(show, plan, t), atol=1e-6)
    frame = track.frame(15.0)
    np.testing.assert_allclose(frame.colors_rgb, show_colors(show, plan, [15.0])[0], atol=1e-6)
    plain = make_track(plan, None, "planned")
    assert np.abs(plain.sample(t)[1] - colors).max() > 0.1


def _recorded_drone_colors(html: bytes) -> list[np.ndarray]:
    """Every colour array recorded for the drones' point cloud, resolving viser's binary placeholders
    (buffers stored 8-byte aligned after the msgpack, in ``binaryBufferLengths`` order)."""
    import msgspec
    import zstandard

    from tests.test_viewer_export import EMBED

    data = base64.b64decode(EMBED.search(html).group(1))
    inner = zstandard.ZstdDecompressor().decompress(data[8:], max_output_size=int.from_bytes(data[:8], "little"))
    n = int.from_bytes(inner[:8], "little")
    rec = msgspec.msgpack.decode(inner[8:8 + n])
    buffers, pos = [], 8 + n
    for length in rec["binaryBufferLengths"]:
        pos += (8 - pos % 8) % 8
        buffers.append(inner[pos:pos + length])
        pos += length
    out = []
    for _, m in rec["messages"]:
        if m.get("name") == "/drones" and m["type"] == "SceneNodeUpdateMessage" and "colors" in m["updates"]:
            ref = m["updates"]["colors"]
            out.append(np.frombuffer(buffers[ref["__binary_index"]], dtype=np.uint8).reshape(-1, 3))
    return out


def test_offline_html_playback_carries_the_effects() -> None:
    """A solid green over 5-15 s: recorded keyframes paint every drone green (and never without it)."""
    from app.exports._viser_html import _led_uint8

    show = parse_show(_show_doc([{"start_s": 5.0, "end_s": 15.0, "effect": {"kind": "solid", "color": "#00ff00"}}]))
    plan = plan_show(show)
    green = _led_uint8(np.tile([0.0, 1.0, 0.0], (show.drones, 1)))
    lit = _recorded_drone_colors(export_show(show, "viser-html", fps=2.0, plan=plan).content)
    assert sum(np.array_equal(c, green) for c in lit) >= 1
    plain = _recorded_drone_colors(export_show(parse_show(_show_doc([])), "viser-html", fps=2.0, plan=plan).content)
    assert len(plain) > 3 and not any(np.array_equal(c, green) for c in plain)


def test_light_fitting_has_a_budget(lit, monkeypatch) -> None:
    from app.exports import ExportError, _ledctrl

    show, plan = lit
    monkeypatch.setattr(_ledctrl, "MAX_LIGHT_CELLS", show.drones * 100)
    with pytest.raises(ExportError, match="exceeds the limit"):
        export_show(show, "skyc", plan=plan)


def test_undecodable_image_base64_is_a_validation_error() -> None:
    from formations import ShowValidationError

    bad = "data:image/png;base64,iVBORw0KGgoAAAANSUhEUg" + "!!!!"
    kind = {"kind": "image", "frames": [bad], "center_m": [0, 0, 20], "width_m": 10, "height_m": 10}
    with pytest.raises(ShowValidationError) as info:
        parse_show(_show_doc([{"start_s": 0.0, "end_s": 5.0, "effect": kind}]))
    assert info.value.errors[0]["path"] == "lights.effects[0].effect.frames"


def test_simulated_source_paints_the_effects_at_the_flown_positions(lit) -> None:
    """With ``--source simulated`` the effects go over the flown colours at the flown positions: a flight
    that is the plan shifted 1 m along x moves a sweep's colours by exactly that shift."""
    from types import SimpleNamespace

    show, plan = lit
    t = np.arange(int(plan.duration_s * 20) + 1) / 20.0
    sample = plan.evaluate(t)
    shift = np.array([1.0, 0.0, 0.0])
    flight = SimpleNamespace(times_s=t, positions_m=sample.positions_m + shift, colors_rgb=sample.colors_rgb)
    result = export_show(show, "waypoints-csv", fps=4.0, plan=plan, flight=flight, source="simulated")
    t_col, rgb = _csv_colors(result.content, "drone_006.csv")
    stack = LightStack.from_show(show, plan)
    ev = plan.evaluate(t_col)
    want = stack.apply(t_col, ev.colors_rgb[:, 5:6], ev.positions_m[:, 5:6] + shift, np.array([5]))[:, 0]
    assert np.abs(rgb - np.clip(np.rint(want * 255.0), 0, 255)).max() <= 1
    unshifted = show_colors(show, plan, t_col)[:, 5]
    assert np.abs(rgb - np.clip(np.rint(unshifted * 255.0), 0, 255)).max() > 20  # the flown positions were used
