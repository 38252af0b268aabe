"""Crazyswarm polynomials and the Skybrush ``.skyc`` read back with independent readers."""

from __future__ import annotations

import base64
import io
import json
import math
import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.exports import _skyc as skyc_module
from app.exports import export_show
from sim import plan_show
from tests.conftest import fibonacci_sphere, make_show, ring

CRAZYSWARM_HEADER = (
    "duration,x^0,x^1,x^2,x^3,x^4,x^5,x^6,x^7,y^0,y^1,y^2,y^3,y^4,y^5,y^6,y^7,"
    "z^0,z^1,z^2,z^3,z^4,z^5,z^6,z^7,yaw^0,yaw^1,yaw^2,yaw^3,yaw^4,yaw^5,yaw^6,yaw^7,"
)


def _show(n_formations: int = 2):
    shapes = [ring(16, 12.0), fibonacci_sphere(16, 9.0), ring(16, 15.0, center=(5.0, 3.0, 40.0))]
    colors = ["#ff0000", "#00ff00", "#2040ff"]
    return make_show(
        [
            {"name": f"f{k}", "hold_s": 2.0 + k, "points": shapes[k % 3], "color": colors[k % 3]}
            for k in range(n_formations)
        ],
        drones=16, rows=4, cols=4, spacing_m=4.5,
    )


@pytest.fixture(scope="module")
def show():
    return _show(3)


@pytest.fixture(scope="module")
def plan(show):
    return plan_show(show)


# ---------------------------------------------------------------- Crazyswarm


def load_uav_trajectory(text: str) -> np.ndarray:
    """What Crazyswarm's uav_trajectory.Trajectory.loadcsv does: skip the header, 33 columns."""
    return np.loadtxt(io.StringIO(text), delimiter=",", skiprows=1, usecols=range(33), ndmin=2)


def crazyswarm_tables(z: zipfile.ZipFile) -> tuple[dict[str, np.ndarray], np.ndarray, dict]:
    """Each drone's pieces over the whole show (its parts' rows one after the other), the cut
    times between parts, and the manifest."""
    manifest = json.loads(z.read("manifest.json"))
    parts = manifest["parts"]
    tables: dict[str, list[np.ndarray]] = {}
    for name in sorted(n for n in z.namelist() if n.endswith(".csv")):
        stem = name[:-4].split(".part")[0]
        text = z.read(name).decode("ascii")
        assert text.splitlines()[0] == CRAZYSWARM_HEADER
        tables.setdefault(stem, []).append(load_uav_trajectory(text))
    assert all(len(v) == len(parts) for v in tables.values())
    cuts = np.array([p["start_s"] for p in parts[1:]])
    return {k: np.concatenate(v) for k, v in tables.items()}, cuts, manifest


def eval_pieces(data: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Position (T, 3) of a piecewise polynomial trajectory at absolute times t (ascending powers)."""
    ends = np.cumsum(data[:, 0])
    k = np.minimum(np.searchsorted(ends, t, side="right"), len(data) - 1)
    local = t - (ends[k] - data[k, 0])
    powers = local[:, None] ** np.arange(8)[None, :]
    return np.stack([(data[k, 1 + 8 * a : 9 + 8 * a] * powers).sum(axis=1) for a in range(3)], axis=1)


def test_crazyswarm_pieces_are_the_plan(show, plan):
    result = export_show(show, "crazyswarm", plan=plan)
    rng = np.random.default_rng(3)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        tables, cuts, manifest = crazyswarm_tables(z)
        assert len(tables) == 16
        for i, name in enumerate(sorted(tables)):
            data = tables[name]
            assert data.shape[1] == 33
            assert np.all(data[:, 0] > 0)
            assert data[:, 0].sum() == pytest.approx(plan.duration_s, abs=1e-6)
            assert np.all(data[:, 25:] == 0.0)  # yaw
            assert np.all(data[:, [7, 8, 15, 16, 23, 24]] == 0.0)  # degree 6, 7 unused by a quintic
            t = np.r_[rng.uniform(0.0, plan.duration_s, 100), plan.knot_times_s]
            ref = plan.evaluate(t, drones=np.array([i])).positions_m[:, 0]
            assert np.linalg.norm(eval_pieces(data, t) - ref, axis=1).max() <= 0.001
            assert np.sum(manifest["pieces"][name]) == len(data)
    # A Crazyflie holds 31 pieces: split (and said so) exactly when some drone needs more
    # (minimum-time legs are up to 7 cubic pieces each, so a few formations exceed it).
    assert bool(result.warnings) == (len(manifest["parts"]) > 1)


def test_crazyswarm_merges_holds_into_constant_pieces(show, plan):
    with zipfile.ZipFile(io.BytesIO(export_show(show, "crazyswarm", plan=plan).content)) as z:
        tables, cuts, _ = crazyswarm_tables(z)
        data = tables["drone_001"]
    # A piece moves when any coefficient of degree >= 1 is non-zero (columns 2-8, 10-16, 18-24).
    moving = np.any(data[:, np.r_[2:9, 10:17, 18:25]] != 0.0, axis=1)
    # Never two constant pieces in a row (consecutive rests are one piece) but where parts meet.
    starts = np.r_[0.0, np.cumsum(data[:, 0])[:-1]]
    at_cut = np.min(np.abs(starts[1:, None] - np.r_[cuts, -1.0][None, :]), axis=1) < 1e-9
    assert not np.any(~moving[1:] & ~moving[:-1] & ~at_cut)
    # Every moving piece of the plan is written once; rests between them merge into one piece each.
    lengths = np.diff(plan.motion.breaks_s[0])
    plan_moving = (lengths > 0) & np.any(plan.motion.coeffs_m[0, :, :, 1:] != 0.0, axis=(1, 2))
    assert moving.sum() == plan_moving.sum()
    assert len(data) <= 2 * plan_moving.sum() + 1 + len(cuts)


def test_crazyswarm_warns_beyond_31_pieces():
    show = _show(16)
    result = export_show(show, "crazyswarm")
    assert any("31" in w and "Crazyflie" in w for w in result.warnings)


# ---------------------------------------------------------------- skyc


def check_skybrush_rules(doc: dict) -> None:
    """The Skybrush show-format rules the issue lists."""
    assert doc["version"] == 1
    drones = doc["swarm"]["drones"]
    assert drones
    for d in drones:
        assert d["type"] == "generic"
        s = d["settings"]
        assert {"name", "home", "trajectory", "lights"} <= set(s)
        traj = s["trajectory"]
        assert traj["version"] == 1
        points = traj["points"]
        assert points
        times = [p[0] for p in points]
        assert all(b > a for a, b in zip(times, times[1:], strict=False))
        assert points[0][2] == []
        for t, pos, controls in points:
            assert isinstance(t, float | int) and len(pos) == 3
            assert len(controls) <= 2 and all(len(c) == 3 for c in controls)
        assert s["lights"]["version"] == 1
        base64.b64decode(s["lights"]["data"], validate=True)


def eval_skyc(points: list, t: np.ndarray) -> np.ndarray:
    """Evaluate Skybrush Bézier trajectory points at times t (held at the ends)."""
    times = np.array([p[0] for p in points])
    out = np.empty((len(t), 3))
    for j, tj in enumerate(t):
        k = int(np.clip(np.searchsorted(times, tj, side="left"), 1, len(times) - 1))
        (t0, p0, _), (t1, p1, ctrl) = points[k - 1], points[k]
        u = min(max((tj - t0) / (t1 - t0), 0.0), 1.0)
        cps = [np.array(p0)] + [np.array(c) for c in ctrl] + [np.array(p1)]
        deg = len(cps) - 1
        out[j] = sum(math.comb(deg, i) * (1 - u) ** (deg - i) * u**i * cps[i] for i in range(deg + 1))
    return out


def run_light_program(code: bytes, until_frame: int) -> np.ndarray:
    """An independent ledctrl interpreter for SET_COLOR / FADE_TO_COLOR / END: colour at each 1/50 s frame."""
    colors = np.zeros((until_frame + 1, 3))
    current = np.zeros(3)
    frame = 0
    i = 0

    def varuint() -> int:
        nonlocal i
        value, shift = 0, 0
        while True:
            b = code[i]
            i += 1
            value |= (b & 0x7F) << shift
            shift += 7
            if b < 0x80:
                return value

    while i < len(code):
        op = code[i]
        i += 1
        if op == 0x00:
            break
        assert op in (0x04, 0x08), f"unexpected opcode {op:#x}"
        target = np.array(list(code[i : i + 3]), dtype=float)
        i += 3
        dur = varuint()
        for f in range(frame, min(frame + dur, until_frame + 1)):
            colors[f] = target if op == 0x04 else current + (target - current) * (f - frame) / dur
        current = target
        frame += dur
    colors[frame:] = current
    return colors


def test_skyc_passes_the_rules_and_evaluates_to_the_plan(show, plan):
    result = export_show(show, "skyc", plan=plan)
    assert result.filename.endswith(".skyc")
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        assert "show.json" in z.namelist()
        doc = json.loads(z.read("show.json"))
    check_skybrush_rules(doc)
    assert len(doc["swarm"]["drones"]) == 16
    v = doc["settings"]["validation"]
    s = show.settings
    assert v["minDistance"] == s.min_distance_m and v["maxAltitude"] == s.max_altitude_m
    assert v["maxVelocityXY"] == s.max_speed_xy_mps and v["maxVelocityZ"] == s.max_speed_z_mps
    assert v["maxAccelerationXY"] == s.max_accel_mps2
    seg = doc["meta"]["segments"]
    assert seg["takeoff"][0] == 0.0 and seg["landing"][1] == pytest.approx(plan.duration_s)
    assert seg["takeoff"][1] == seg["show"][0] and seg["show"][1] == seg["landing"][0]
    t = np.linspace(0.0, plan.duration_s, 1500)
    for i, d in enumerate(doc["swarm"]["drones"]):
        points = d["settings"]["trajectory"]["points"]
        assert points[-1][0] == pytest.approx(plan.duration_s, abs=1e-6)
        ref = plan.evaluate(t, drones=np.array([i])).positions_m[:, 0]
        assert np.linalg.norm(eval_skyc(points, t) - ref, axis=1).max() <= 0.01
        np.testing.assert_allclose(d["settings"]["home"], plan.knot_positions_m[0, i], atol=1e-4)


def test_skyc_lights_replay_the_plan_colours(show, plan):
    with zipfile.ZipFile(io.BytesIO(export_show(show, "skyc", plan=plan).content)) as z:
        doc = json.loads(z.read("show.json"))
    last = int(round(plan.duration_s * 50))
    frames = np.arange(last + 1)
    for i in (0, 7, 15):
        code = base64.b64decode(doc["swarm"]["drones"][i]["settings"]["lights"]["data"])
        assert code[-1] == 0x00
        got = run_light_program(code, last)
        ref = plan.evaluate(frames / 50.0, drones=np.array([i])).colors_rgb[:, 0] * 255
        # Knot times are rounded to the 20 ms frame grid: allow one frame of fade plus rounding.
        max_rate = 255 / 50 / min(s.duration_s for s in plan.segments if s.duration_s > 0)
        assert np.abs(got - ref).max() <= 1.0 + 2 * max_rate


def _hermite_error_dense(c: np.ndarray, duration_s: float, parts: int) -> float:
    """Largest distance between one piece (3, 6) and its cubic Hermite parts, sampled densely (independent)."""
    t = np.linspace(0.0, duration_s, 4001)
    powers = lambda x: x[:, None] ** np.arange(6)  # noqa: E731
    dpowers = lambda x: np.c_[np.zeros(len(x)), x[:, None] ** np.arange(5) * np.arange(1, 6)]  # noqa: E731
    h = duration_s / parts
    j = np.minimum((t // h).astype(int), parts - 1)
    a, b = j * h, (j + 1) * h
    pa, pb, va, vb = powers(a) @ c.T, powers(b) @ c.T, dpowers(a) @ c.T, dpowers(b) @ c.T
    s = ((t - a) / h)[:, None]
    # Cubic Hermite basis (independent of the exporter's Bézier form).
    cubic = ((2 * s**3 - 3 * s**2 + 1) * pa + (s**3 - 2 * s**2 + s) * h * va + (-2 * s**3 + 3 * s**2) * pb
             + (s**3 - s**2) * h * vb)
    return float(np.linalg.norm(cubic - powers(t) @ c.T, axis=1).max())


@pytest.mark.parametrize("length_m", [0.5, 10.0, 250.0, 2000.0])
def test_skyc_piece_count_meets_the_tolerance(length_m):
    # A straight rest-to-rest quintic leg (the paper's time law) of this length, 40 s long.
    duration = 40.0
    direction = np.array([0.6, 0.0, 0.8])
    c = np.zeros((3, 6))
    c[:, 3], c[:, 4], c[:, 5] = (10 * direction * length_m / duration**3, -15 * direction * length_m / duration**4,
                                 6 * direction * length_m / duration**5)
    n = int(skyc_module.subdivisions(c[None], np.array([duration]))[0])
    assert _hermite_error_dense(c, duration, n) <= skyc_module.TOLERANCE_M
    # n is the smallest count the bound allows, and the bound is tight: at most one part more than needed.
    bound = skyc_module.hermite_error_bound(c[None], np.array([duration]), np.array([max(n - 1, 1)]))[0]
    assert n == 1 or bound > skyc_module.TOLERANCE_M
    assert n <= 2 or _hermite_error_dense(c, duration, n - 2) > skyc_module.TOLERANCE_M


# ---------------------------------------------------------------- per-drone timing


@pytest.fixture(scope="module")
def staggered(plan):
    from tests.conftest import staggered_plan

    return staggered_plan(plan, seed=5)


def test_crazyswarm_converts_each_drones_own_pieces_exactly(show, staggered):
    plan, legs = staggered
    breaks = plan.motion.breaks_s
    rng = np.random.default_rng(6)
    with zipfile.ZipFile(io.BytesIO(export_show(show, "crazyswarm", plan=plan).content)) as z:
        tables, cuts, _ = crazyswarm_tables(z)
        for i, name in enumerate(sorted(tables)):
            data = tables[name]
            assert np.all(data[:, 0] > 0)  # zero-length pieces dropped
            assert data[:, 0].sum() == pytest.approx(plan.duration_s, abs=1e-6)
            assert np.all(data[:, 25:] == 0.0) and np.all(data[:, [7, 8, 15, 16, 23, 24]] == 0.0)
            # The drone's own break times are piece boundaries (merged rests excepted), and the cuts.
            ends = np.cumsum(data[:, 0])
            own = np.r_[breaks[i, 1:][np.diff(breaks[i]) > 0], cuts]
            assert np.all(np.min(np.abs(ends[:, None] - own[None, :]), axis=1) < 1e-9)
            t = np.r_[rng.uniform(0.0, plan.duration_s, 200), breaks[i]]
            want = plan.evaluate(t, drones=np.array([i])).positions_m[:, 0]
            assert np.linalg.norm(eval_pieces(data, t) - want, axis=1).max() <= 0.001
            assert np.linalg.norm(eval_pieces(data, t) - legs.positions(t)[:, i], axis=1).max() <= 0.001
            # Rests merged: never two constant pieces in a row but where parts meet.
            moving = np.any(data[:, np.r_[2:7, 10:15, 18:23]] != 0.0, axis=1)
            assert np.sum(~moving[1:] & ~moving[:-1]) <= len(cuts)


def test_skyc_follows_each_drones_own_pieces(show, staggered):
    plan, legs = staggered
    with zipfile.ZipFile(io.BytesIO(export_show(show, "skyc", plan=plan).content)) as z:
        doc = json.loads(z.read("show.json"))
    check_skybrush_rules(doc)
    t = np.linspace(0.0, plan.duration_s, 3000)
    cubic_legs = 0
    for i, d in enumerate(doc["swarm"]["drones"]):
        points = d["settings"]["trajectory"]["points"]
        assert points[-1][0] == pytest.approx(plan.duration_s, abs=5e-4)
        got = eval_skyc(points, t)
        ref = plan.evaluate(t, drones=np.array([i])).positions_m[:, 0]
        err = np.linalg.norm(got - ref, axis=1).max()
        assert err <= 0.01
        # Within the fitting tolerance plus the 0.1 mm rounding of the written numbers.
        assert err <= skyc_module.TOLERANCE_M + 3e-4
        assert np.linalg.norm(got - legs.positions(t)[:, i], axis=1).max() <= skyc_module.TOLERANCE_M + 3e-4
        # A cubic (smoothstep) leg is one Bézier, exactly: a point at its arrival time
        # whose previous point is its departure.
        times = np.array([p[0] for p in points])
        for k in range(len(legs.window_s)):
            if legs.cubic[k][i]:
                dep, arr = legs.depart_s[k][i], legs.depart_s[k][i] + legs.duration_s[k][i]
                j = int(np.argmin(np.abs(times - arr)))
                # Times are whole milliseconds; a duration the Skybrush server would cut by a
                # millisecond is written as two Béziers (the same cubic, split).
                whole = round(arr * 1000) - round(dep * 1000)
                back = 2 if skyc_module._server_truncates(whole) else 1
                assert times[j] == pytest.approx(arr, abs=5e-4) and times[j - back] == pytest.approx(dep, abs=5e-4)
                assert len(points[j][2]) == 2
                cubic_legs += 1
    assert cubic_legs > 0


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 6))
def test_hermite_error_bound_holds_for_any_quintic(seed, parts):
    rng = np.random.default_rng(seed)
    c = rng.normal(size=(3, 6)) * rng.uniform(0.01, 3.0, 6)
    duration = float(rng.uniform(0.1, 20.0))
    bound = skyc_module.hermite_error_bound(c[None], np.array([duration]), np.array([parts]))[0]
    assert _hermite_error_dense(c, duration, parts) <= bound * (1 + 1e-9) + 1e-12


def test_skyc_leaves_the_garbage_collector_as_it_found_it(show, plan, monkeypatch):
    import gc

    assert gc.isenabled()
    export_show(show, "skyc", plan=plan)
    assert gc.isenabled()

    def boom(ctx):
        raise RuntimeError("boom")

    monkeypatch.setattr(skyc_module, "build_show_json", boom)
    with pytest.raises(RuntimeError):
        export_show(show, "skyc", plan=plan)
    assert gc.isenabled()
    gc.disable()
    try:
        monkeypatch.undo()
        export_show(show, "skyc", plan=plan)
        assert not gc.isenabled()  # not switched on behind the caller's back
    finally:
        gc.enable()
