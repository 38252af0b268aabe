"""Crazyswarm files read by Crazyswarm's own uav_trajectory.py (vendored, MIT) and a float32 port of the firmware.

The Crazyflie firmware (GPL-3.0) is not vendored: :func:`firmware_positions` is an
independent port of how it evaluates an uploaded poly4d trajectory, in float32
(piece start times accumulated in float32, Horner in float32).
"""

from __future__ import annotations

import io
import json
import os
import tempfile
import zipfile

import numpy as np
import pytest

from app.exports import ExportError, export_show
from app.exports import _crazyswarm as cs_module
from sim import plan_show
from tests.conftest import fibonacci_sphere, make_show, ring
from tests.vendor import uav_trajectory


def _show(n_formations: int):
    shapes = [ring(16, 12.0), fibonacci_sphere(16, 9.0), ring(16, 15.0, center=(5.0, 3.0, 40.0))]
    return make_show(
        [{"name": f"f{k}", "hold_s": 2.0 + k % 3, "points": shapes[k % 3], "color": "#ff0000"}
         for k in range(n_formations)],
        drones=16, rows=4, cols=4, spacing_m=4.5,
    )


@pytest.fixture(scope="module")
def long_show():
    show = _show(16)
    return show, plan_show(show)


def _load(text: bytes) -> uav_trajectory.Trajectory:
    """Crazyswarm's own loader reads a file from disk."""
    with tempfile.NamedTemporaryFile("wb", suffix=".csv", delete=False) as f:
        f.write(text)
    try:
        traj = uav_trajectory.Trajectory()
        traj.loadcsv(f.name)
        return traj
    finally:
        os.unlink(f.name)


def _eval(traj: uav_trajectory.Trajectory, t: np.ndarray) -> np.ndarray:
    # Trajectory.eval returns None at exactly t = duration when its running sum of piece
    # durations rounds below np.sum's: stay a nanosecond inside.
    return np.array([traj.eval(float(min(tj, traj.duration - 1e-9))).pos for tj in t])


def firmware_positions(text: bytes, t: np.ndarray) -> np.ndarray:
    """(T, 3) positions as the Crazyflie evaluates the uploaded pieces, in float32."""
    f32 = np.float32
    data = np.loadtxt(io.BytesIO(text), delimiter=",", skiprows=1, usecols=range(33), ndmin=2).astype(f32)
    dur = data[:, 0]
    starts = np.concatenate([[f32(0)], np.cumsum(dur, dtype=f32)[:-1]]).astype(f32)
    tt = np.asarray(t, dtype=f32)
    k = np.clip(np.searchsorted(starts, tt, side="right") - 1, 0, len(data) - 1)
    u = np.minimum(tt - starts[k], dur[k]).astype(f32)
    out = np.zeros((len(t), 3), dtype=f32)
    for axis in range(3):
        c = data[k, 1 + 8 * axis : 9 + 8 * axis]
        acc = c[:, 7].copy()
        for j in range(6, -1, -1):
            acc = (acc * u + c[:, j]).astype(f32)
        out[:, axis] = acc
    return out.astype(np.float64)


def _drone_positions(z: zipfile.ZipFile, parts: list[dict], i: int, t: np.ndarray):
    """(T, 3) positions of drone i over the whole show through each of its parts, twice:
    Crazyswarm's reader and the float32 firmware port."""
    got, got32 = np.empty((len(t), 3)), np.empty((len(t), 3))
    for k, p in enumerate(parts):
        name = f"drone_{i + 1:03d}.csv" if len(parts) == 1 else f"drone_{i + 1:03d}.part{k + 1}.csv"
        text = z.read(name)
        traj = _load(text)
        # A part fits its half of the memory; two consecutive parts fit a Crazyflie together.
        assert traj.n_pieces() <= (cs_module.CRAZYFLIE_MAX_PIECES if len(parts) == 1 else cs_module.PART_MAX_PIECES)
        assert p["piece_offset"] == (0 if k % 2 == 0 else 16) or len(parts) == 1
        assert traj.duration == pytest.approx(p["duration_s"], abs=1e-6)
        sel = (t >= p["start_s"]) & (t <= p["start_s"] + p["duration_s"])
        got[sel] = _eval(traj, t[sel] - p["start_s"])
        got32[sel] = firmware_positions(text, t[sel] - p["start_s"])
    return got, got32


def test_scale_and_offset_through_crazyswarms_reader():
    show = _show(2)
    plan = plan_show(show)
    result = export_show(show, "crazyswarm", plan=plan, scale=0.02, offset_m=(1.5, -2.0, 0.25))
    t = np.linspace(0.0, plan.duration_s, 301)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        manifest = json.loads(z.read("manifest.json"))
        assert manifest["scale"] == 0.02 and manifest["offset_m"] == [1.5, -2.0, 0.25]
        readme = z.read("README.txt").decode()
        assert "relative=False" in readme and "takeoff()" in readme
        for i in (0, 9, 15):
            got, got32 = _drone_positions(z, manifest["parts"], i, t)
            want = 0.02 * plan.evaluate(t, drones=np.array([i])).positions_m[:, 0] + np.array([1.5, -2.0, 0.25])
            assert np.abs(got - want).max() <= 1e-6
            # The firmware's float32 evaluation: within 0.1 mm indoors.
            assert np.abs(got32 - want).max() <= 1e-4


def test_bad_scale_and_offset_are_refused():
    show = _show(1)
    for kwargs, word in [({"scale": 0.0}, "scale"), ({"scale": float("nan")}, "scale"),
                         ({"offset_m": (1.0, 2.0)}, "offset"), ({"offset_m": (1e9, 0, 0)}, "offset")]:
        with pytest.raises(ExportError, match=word):
            export_show(show, "crazyswarm", **kwargs)


def test_long_show_is_split_into_uploadable_parts(long_show):
    show, plan = long_show
    result = export_show(show, "crazyswarm", plan=plan)
    assert any("split into" in w for w in result.warnings)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        manifest = json.loads(z.read("manifest.json"))
        parts = manifest["parts"]
        assert len(parts) >= 2
        assert "pieceOffset 0" in z.read("README.txt").decode()
        starts = [p["start_s"] for p in parts]
        assert starts[0] == 0.0
        assert sum(p["duration_s"] for p in parts) == pytest.approx(plan.duration_s, abs=1e-6)
        # Each cut lies in a hold, where every drone is at rest.
        for s in starts[1:]:
            assert any(seg.kind == "hold" and seg.start_s < s < seg.end_s for seg in plan.segments)
        t_all = np.linspace(0.0, plan.duration_s, 800)
        for i in range(16):
            got, got32 = _drone_positions(z, parts, i, t_all)
            want = plan.evaluate(t_all, drones=np.array([i])).positions_m[:, 0]
            assert np.linalg.norm(got - want, axis=1).max() <= 1e-6
            # float32 at ~60 m (6e-8 relative: a few micrometres) and times up to a part's length.
            assert np.linalg.norm(got32 - want, axis=1).max() <= 1e-3


def test_refusal_names_the_drones_when_no_hold_can_split(long_show, monkeypatch):
    show, plan = long_show
    monkeypatch.setattr(cs_module, "PART_MAX_PIECES", 2)
    with pytest.raises(ExportError, match=r"drone_0\d\d"):
        export_show(show, "crazyswarm", plan=plan)
