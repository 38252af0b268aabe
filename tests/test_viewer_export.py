"""The viser-html export: a self-contained page holding the whole recorded show, within its size budget."""

from __future__ import annotations

import base64
import re

import msgspec
import numpy as np
import pytest
import zstandard

from app.viewer import export_viser_html
from sim import plan_show
from tests.conftest import fibonacci_sphere, make_show

EMBED = re.compile(rb'window\.__VISER_EMBED_DATA__="([A-Za-z0-9+/=]+)"')


def decode_recording(html: bytes) -> dict:
    """The msgpack recording embedded in an exported page."""
    data = base64.b64decode(EMBED.search(html).group(1))
    inner_size = int.from_bytes(data[:8], "little")
    inner = zstandard.ZstdDecompressor().decompress(data[8:], max_output_size=inner_size)
    n = int.from_bytes(inner[:8], "little")
    return msgspec.msgpack.decode(inner[8:8 + n])


def test_export_holds_the_scene(small_show):
    plan = plan_show(small_show)
    html = export_viser_html(plan, fps=4.0)
    assert html.startswith(b"<!doctype html>")
    # Nothing to fetch: no external script, style or font references.
    assert not re.search(rb'(src|href)="https?://', html)
    rec = decode_recording(html)
    assert rec["durationSeconds"] == pytest.approx(plan.duration_s)
    updates = [m for _, m in rec["messages"] if m.get("name") == "/drones"]
    created = [m for m in updates if m["type"] == "PointCloudMessage"]
    assert len(created) == 1
    n_frames = len(plan.sample_times(4.0))
    point_updates = [m for m in updates if m["type"] == "SceneNodeUpdateMessage" and "points" in m["updates"]]
    # One update per keyframe, except when nothing moved (holds, the ends of the
    # rest-to-rest law in float16): an unchanged array sends nothing.
    hold_frames = sum(s.duration_s for s in plan.segments if s.kind == "hold") * 4.0
    assert 0.8 * (n_frames - hold_frames) <= len(point_updates) <= n_frames
    names = {m.get("name") for _, m in rec["messages"]}
    assert {"/ground", "/home_grid", "/closest_pair/line", "/closest_pair/label"} <= names


def test_thousand_drones_three_minutes_under_50_mb():
    n = 1000
    a = np.arange(n)
    wall = np.c_[(a % 40 - 20) * 5.0, np.zeros(n), (a // 40) * 4.0 + 25.0]
    show = make_show(
        [
            {"name": "sphere", "hold_s": 20.0, "points": fibonacci_sphere(n, 60.0, (0, 0, 80)), "color": "#ff0000"},
            {"name": "wall", "hold_s": 20.0, "points": wall, "color": "#00ff00"},
        ],
        drones=n, rows=25, cols=40, spacing_m=4.5,
    )
    plan = plan_show(show)
    assert plan.duration_s >= 180.0
    html = export_viser_html(plan)
    assert len(html) < 50_000_000
    rec = decode_recording(html)
    assert rec["durationSeconds"] == pytest.approx(plan.duration_s)
    print(f"1000 drones, {plan.duration_s:.0f} s: {len(html) / 1e6:.1f} MB")


def test_export_rejects_bad_fps(small_show):
    with pytest.raises(ValueError):
        export_viser_html(plan_show(small_show), fps=0.0)
