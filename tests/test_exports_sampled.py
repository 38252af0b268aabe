"""Sampled exports (skybrush-csv, waypoints-csv, show JSON) read back and compared with the plan."""

from __future__ import annotations

import csv
import io
import json
import re
import zipfile
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.exports import EXPORT_FORMATS, ExportError, ExportOptions, export_show
from app.exports._text import column_bytes, fixed_point_rows
from formations import parse_show
from sim import plan_show
from tests.conftest import fibonacci_sphere, make_show, ring

SAFE_NAME = re.compile(r"[A-Za-z0-9._+-]+")


@pytest.fixture(scope="module")
def show():
    return make_show(
        [
            {"name": "ring", "hold_s": 2.0, "points": ring(16, 12.0), "color": "#ff8000"},
            {"name": "sphere", "hold_s": 3.0, "points": fibonacci_sphere(16, 9.0), "color": "#00ff40"},
        ],
        drones=16, rows=4, cols=4, spacing_m=4.5,
    )


@pytest.fixture(scope="module")
def plan(show):
    return plan_show(show)


def read_zip_csvs(content: bytes) -> dict[str, list[list[str]]]:
    """Every CSV of the archive, parsed with the standard csv module (header row included)."""
    with zipfile.ZipFile(io.BytesIO(content)) as z:
        assert z.testzip() is None
        return {
            name: list(csv.reader(io.StringIO(z.read(name).decode("ascii"))))
            for name in z.namelist()
            if name.endswith(".csv")
        }


def test_registry_lists_every_issue_format():
    for fmt in ("show", "skybrush-csv", "skyc", "crazyswarm", "qgc-plan", "qgc-wpl", "waypoints-csv"):
        assert fmt in EXPORT_FORMATS
        module, _, func = EXPORT_FORMATS[fmt].partition(":")
        assert module and func


def test_show_json_round_trips(show):
    result = export_show(show, "show")
    assert result.media_type == "application/json"
    assert result.filename.endswith(".json")
    assert parse_show(result.content) == show


def test_skybrush_csv_rows_are_the_plan(show, plan):
    result = export_show(show, "skybrush-csv", plan=plan)
    assert result.media_type == "application/zip"
    files = read_zip_csvs(result.content)
    assert sorted(files) == [f"drone_{i:03d}.csv" for i in range(1, 17)]
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        # Skybrush Studio's importer reads every member as a drone: nothing but the CSVs,
        # the manifest is the archive comment.
        assert sorted(z.namelist()) == sorted(files)
        assert all(SAFE_NAME.fullmatch(n) for n in z.namelist())
        manifest = json.loads(z.comment)
        assert manifest["format"] == "skybrush-csv" and manifest["fps"] == 24.0 and manifest["drones"] == 16
    # Every 1/24 s (whole ms) from 0, plus the end of the show if it is not on that grid, plus
    # one row a frame later holding the end (Studio's importer drops the last row).
    expected_rows = int(np.floor(plan.duration_s * 24 + 1e-9)) + 1 + (plan.duration_s * 24 % 1 > 1e-9) + 1
    for i in range(16):
        rows = files[f"drone_{i + 1:03d}.csv"]
        assert rows[0] == ["Time [msec]", "x [m]", "y [m]", "z [m]", "Red", "Green", "Blue"]
        body = rows[1:]
        assert len(body) == expected_rows
        # Format: integer milliseconds, exactly 3 decimals, integer colours.
        assert all(re.fullmatch(r"\d+", r[0]) for r in body)
        assert all(re.fullmatch(r"-?\d+\.\d{3}", v) for r in body for v in r[1:4])
        data = np.array(body, dtype=float)
        t_ms = data[:, 0]
        assert t_ms[0] == 0 and np.all(np.diff(t_ms) > 0)
        assert t_ms[-2] == round(plan.duration_s * 1000) and t_ms[-1] == t_ms[-2] + 42
        np.testing.assert_array_equal(data[-1, 1:], data[-2, 1:])
        ref = plan.evaluate(np.minimum(t_ms / 1000.0, plan.duration_s), drones=np.array([i]))
        assert np.abs(data[:, 1:4] - ref.positions_m[:, 0]).max() <= 0.0005 + 1e-9
        assert np.linalg.norm(data[:, 1:4] - ref.positions_m[:, 0], axis=1).max() <= 0.001
        assert np.all((data[:, 4:] >= 0) & (data[:, 4:] <= 255))
        assert np.abs(data[:, 4:] - ref.colors_rgb[:, 0] * 255).max() <= 0.5 + 1e-9


def test_skybrush_csv_resampled_at_high_fps_matches_the_plan_within_1mm(show, plan):
    files = read_zip_csvs(export_show(show, "skybrush-csv", plan=plan, fps=100).content)
    rng = np.random.default_rng(7)
    for i in range(16):
        data = np.array(files[f"drone_{i + 1:03d}.csv"][1:], dtype=float)
        t = rng.uniform(0.0, plan.duration_s, 100)
        resampled = np.stack([np.interp(t * 1000, data[:, 0], data[:, 1 + a]) for a in range(3)], axis=1)
        ref = plan.evaluate(t, drones=np.array([i])).positions_m[:, 0]
        assert np.linalg.norm(resampled - ref, axis=1).max() <= 0.001


def test_skybrush_csv_odd_fps_rows_stay_exact(show, plan):
    files = read_zip_csvs(export_show(show, "skybrush-csv", plan=plan, fps=3).content)
    data = np.array(files["drone_005.csv"][1:], dtype=float)
    assert data[1, 0] == 333 and data[2, 0] == 667
    ref = plan.evaluate(data[:, 0] / 1000.0, drones=np.array([4])).positions_m[:, 0]
    assert np.abs(data[:, 1:4] - ref).max() <= 0.0005 + 1e-9


def test_waypoints_csv_planned(show, plan):
    files = read_zip_csvs(export_show(show, "waypoints-csv", plan=plan, fps=5).content)
    assert len(files) == 16
    rows = files["drone_016.csv"]
    assert rows[0] == ["t", "x", "y", "z", "r", "g", "b"]
    data = np.array(rows[1:], dtype=float)
    np.testing.assert_allclose(data[:6, 0], [0.0, 0.2, 0.4, 0.6, 0.8, 1.0])
    assert data[-1, 0] == pytest.approx(plan.duration_s, abs=5e-4)
    ref = plan.evaluate(data[:, 0], drones=np.array([15]))
    assert np.abs(data[:, 1:4] - ref.positions_m[:, 0]).max() <= 0.0005 + 1e-9
    assert np.abs(data[:, 4:] - ref.colors_rgb[:, 0] * 255).max() <= 0.5 + 1e-9


@dataclass
class _Flight:
    times_s: np.ndarray
    positions_m: np.ndarray
    colors_rgb: np.ndarray


def test_waypoints_csv_simulated_interpolates_the_flight(show, plan):
    t = np.arange(0.0, plan.duration_s + 1e-9, 0.04)
    s = plan.evaluate(t)
    offset = np.array([0.25, -0.5, 0.125])
    flight = _Flight(t, (s.positions_m + offset).astype(np.float32), s.colors_rgb.astype(np.float32))
    files = read_zip_csvs(export_show(show, "waypoints-csv", plan=plan, flight=flight, source="simulated",
                                      fps=10).content)
    data = np.array(files["drone_003.csv"][1:], dtype=float)
    flown = np.stack([np.interp(data[:, 0], t, flight.positions_m[:, 2, a]) for a in range(3)], axis=1)
    assert np.abs(data[:, 1:4] - flown).max() <= 0.0006
    assert np.abs(data[:, 1:4] - offset - plan.evaluate(data[:, 0], drones=np.array([2])).positions_m[:, 0]).max() < 0.2


def test_skybrush_csv_simulated_uses_the_flight(show, plan):
    t = np.arange(0.0, plan.duration_s + 1e-9, 0.04)
    s = plan.evaluate(t)
    flight = _Flight(t, s.positions_m + np.array([0.0, 0.0, 1.0]), s.colors_rgb)
    files = read_zip_csvs(export_show(show, "skybrush-csv", plan=plan, flight=flight, source="simulated").content)
    data = np.array(files["drone_001.csv"][1:], dtype=float)
    ref = plan.evaluate(data[:, 0] / 1000.0, drones=np.array([0])).positions_m[:, 0]
    assert np.abs(data[:, 3] - ref[:, 2] - 1.0).max() < 0.01


@pytest.mark.parametrize("fmt", ["skyc", "crazyswarm", "qgc-wpl", "qgc-plan", "show"])
def test_exact_formats_refuse_simulated_source(show, plan, fmt):
    with pytest.raises(ExportError, match="simulated"):
        export_show(show, fmt, plan=plan, source="simulated",
                    origin=(47.0, 8.0, 400.0) if fmt.startswith("qgc") else None)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"fps": 0},
        {"fps": -4},
        {"fps": float("nan")},
        {"fps": 1e6},
        {"fps": True},
        {"origin": (91.0, 0.0, 0.0)},
        {"origin": (0.0, 181.0, 0.0)},
        {"origin": (0.0, 0.0, float("inf"))},
        {"origin": (1.0, 2.0)},
        {"heading_deg": float("nan")},
        {"source": "dreamed"},
    ],
)
def test_bad_options_raise_export_error(kwargs):
    with pytest.raises(ExportError):
        ExportOptions(**kwargs)


def test_unknown_format(show):
    with pytest.raises(ExportError, match="unknown export format"):
        export_show(show, "gcode")


def test_options_normalise_heading():
    assert ExportOptions(heading_deg=-90).heading_deg == 270.0


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(min_value=-1e7, max_value=1e7, allow_nan=False), min_size=1, max_size=40),
    st.integers(min_value=0, max_value=3),
)
def test_fast_fixed_point_text_matches_printf(values, decimals):
    # Values on a (decimals)-grid shifted by a quarter unit: no exact ties, so both roundings agree.
    x = (np.round(np.asarray(values), decimals) + 0.25 * 10.0**-decimals).tolist()
    (text,) = fixed_point_rows([np.asarray(x), column_bytes(np.asarray(x), decimals)], [decimals, None])
    expected = "".join(f"{v:.{decimals}f},{v:.{decimals}f}\n" for v in x)
    assert text.decode() == expected


def test_waypoints_csv_from_the_real_flight_simulation():
    small = make_show(
        [{"name": "square", "hold_s": 1.0, "points": [[0, 0, 15], [5, 0, 15], [0, 5, 15], [5, 5, 15]],
          "color": "#ffffff"}],
        drones=4, rows=2, cols=2, spacing_m=4.5,
    )
    result = export_show(small, "waypoints-csv", source="simulated", fps=5)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        manifest = json.loads(z.read("manifest.json"))
        data = np.array(list(csv.reader(io.StringIO(z.read("drone_002.csv").decode())))[1:], dtype=float)
    assert manifest["source"] == "simulated" and "flight" in manifest
    plan = plan_show(small)
    ref = plan.evaluate(data[:, 0], drones=np.array([1])).positions_m[:, 0]
    # Flown, not planned: close to the plan (controller tracking error), not equal to it.
    assert np.abs(data[:, 1:4] - ref).max() < 0.5


def skybrush_studio_import(content: bytes) -> dict[str, np.ndarray]:
    """The parsing loop of Skybrush Studio for Blender's "Import Skybrush CSV" (import_from_csv.py).

    Every member is read as a drone; a row whose first cell starts with "t" is the header; any
    other unparsable row aborts the import.
    """
    out = {}
    with zipfile.ZipFile(io.BytesIO(content)) as z:
        for name in z.namelist():
            rows = []
            for row in csv.reader([line.decode("ascii") for line in z.open(name)]):
                if row[0].lower().startswith("t"):
                    continue
                t = float(row[0]) / 1000.0
                x, y, zz = (float(v) for v in row[1:4])
                r, g, b = (int(v) for v in row[4:7])
                rows.append((t, x, y, zz, r, g, b))
            out[name.rsplit(".", 1)[0]] = np.array(rows)
    return out


def test_skybrush_studio_importer_accepts_the_archive(show, plan):
    drones = skybrush_studio_import(export_show(show, "skybrush-csv", plan=plan).content)
    assert sorted(drones) == [f"drone_{i:03d}" for i in range(1, 17)]
    first = np.array([d[0, 1:4] for d in drones.values()])
    np.testing.assert_allclose(first, plan.knot_positions_m[0], atol=5e-4)


# ---------------------------------------------------------------- per-drone timing


@pytest.fixture(scope="module")
def staggered(plan):
    from tests.conftest import staggered_plan

    return staggered_plan(plan, seed=3)


@pytest.mark.parametrize("fmt", ["skybrush-csv", "waypoints-csv"])
def test_sampled_rows_follow_each_drones_own_timing(show, staggered, fmt):
    plan, legs = staggered
    files = read_zip_csvs(export_show(show, fmt, plan=plan, fps=7).content)
    names = sorted(files)
    assert len(names) == 16
    for i, name in enumerate(names):
        data = np.array(files[name][1:], dtype=float)
        t = data[:, 0] / (1000.0 if fmt == "skybrush-csv" else 1.0)
        ref = plan.evaluate(t, drones=np.array([i]))
        assert np.abs(data[:, 1:4] - ref.positions_m[:, 0]).max() <= 0.0005 + 1e-9
        assert np.abs(data[:, 1:4] - legs.positions(t)[:, i]).max() <= 0.0005 + 1e-9
        assert np.abs(data[:, 4:] - ref.colors_rgb[:, 0] * 255).max() <= 0.5 + 1e-9


@pytest.mark.parametrize("fmt, default", [("skybrush-csv", 24.0), ("waypoints-csv", 10.0)])
def test_default_rate_fits_the_sample_budget_with_a_warning(show, plan, monkeypatch, fmt, default):
    from app.exports import _sampling

    # A budget that 16 drones at the default rate exceed: the default drops to the highest whole
    # rate that fits, and the export says what that costs; an explicit rate is still refused.
    budget = int(16 * plan.duration_s * 3.5)
    monkeypatch.setattr(_sampling, "MAX_SAMPLES", budget)
    result = export_show(show, fmt, plan=plan)
    files = read_zip_csvs(result.content)
    rows = len(files["drone_001.csv"]) - 1
    assert rows * 16 <= budget
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        manifest = json.loads(z.comment if fmt == "skybrush-csv" else z.read("manifest.json"))
    assert manifest["fps"] == 3.0 < default
    assert any("sample limit" in w and "3 fps" in w for w in result.warnings)
    with pytest.raises(ExportError, match="exceeds the limit"):
        export_show(show, fmt, plan=plan, fps=default)
