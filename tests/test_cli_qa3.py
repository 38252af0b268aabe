"""QA pass on the command line (operator's view): odd but valid shows, bad flags and the README's examples.

Each test was written failing against the defect it names, before the fix.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from app.cli import main as cli_main

ROOT = Path(__file__).resolve().parents[1]


def _one_drone_show(tmp_path: Path, hold_s: float = 2.0) -> Path:
    show = {
        "format": "swarmshow/1", "name": "solo", "drones": 1,
        "home": {"grid": {"rows": 1, "cols": 1, "spacing_m": 3.0}},
        "formations": [{"name": "a", "hold_s": hold_s, "points": [[0.0, 0.0, 12.0]], "color": "#ffffff"}],
    }
    path = tmp_path / "solo.json"
    path.write_text(json.dumps(show))
    return path


def _run(capsys, argv: list[str]) -> tuple[int, str, str]:
    code = cli_main(argv)
    out, err = capsys.readouterr()
    return code, out, err


# --- simulate: bad --output-hz and a recording too large for memory -------------------------------------


@pytest.mark.parametrize("hz", ["inf", "-inf", "1e400"])
def test_simulate_output_hz_not_finite_is_a_one_line_error(capsys, tmp_path, hz):
    """``--output-hz inf`` passed the CLI's ``> 0`` test and died in FlightOptions with a traceback (exit 1)."""
    show = _one_drone_show(tmp_path)
    code, out, err = _run(capsys, ["simulate", str(show), f"--output-hz={hz}"])
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1 and "--output-hz" in err, err


def test_simulate_refuses_a_recording_larger_than_the_budget_before_flying(capsys, tmp_path, monkeypatch):
    """The CLI recorded every drone at ``--output-hz`` for the whole show with no bound (a 10,000-drone,
    17-minute show at 1 kHz asked numpy for 115 GiB and died with a MemoryError traceback). It now refuses,
    before planning or flying, naming ``--output-hz`` and the highest rate that fits, and that rate does fit."""
    from app.cli import _simulate

    show = _one_drone_show(tmp_path, hold_s=100.0)
    flew: list[int] = []
    import sim.flight

    monkeypatch.setattr(sim.flight, "fly_show", lambda *a, **k: flew.append(1))
    # A budget of 50,000 drone-frames: this one-drone show of ~125 s at 1 kHz needs ~125,000.
    monkeypatch.setattr(_simulate, "MAX_RECORDED_SAMPLES", 50_000)
    code, out, err = _run(capsys, ["simulate", str(show), "--output-hz", "1000"])
    assert code == 2 and out == "" and not flew
    assert err.count("\n") == 1 and "--output-hz" in err, err
    most = float(re.search(r"--output-hz ([0-9.]+) or less", err).group(1))
    # Independent count: the runner records frames every round(1000 / hz) steps of 1 ms over the plan.
    from formations import parse_show
    from sim.plan import plan_show

    duration_s = plan_show(parse_show(show.read_bytes())).duration_s
    steps = int(round(duration_s / 1e-3)) + 1
    every = max(int(round(1.0 / (most * 1e-3))), 1)
    assert (steps - 1) // every + 1 <= 50_000
    every_more = max(int(round(1.0 / (2 * most * 1e-3))), 1)
    assert (steps - 1) // every_more + 1 > 50_000  # the rate named is not needlessly low


# --- formation: results outside any show's space ----------------------------------------------------------


@pytest.mark.parametrize("argv, flag", [
    (["formation", "shape", "heart", "-n", "10", "--size-m", "1e9"], "--size-m"),
    (["formation", "shape", "circle", "-n", "10", "--center", "0,0,-50"], "--center"),
    (["formation", "text", "HI", "-n", "20", "--height-m", "30000"], "--height-m"),
    (["formation", "shape", "circle", "-n", "10", "--center", "50000,0,30"], "--center"),
])
def test_formation_result_outside_any_show_is_refused(capsys, argv, flag):
    """The API refuses formation results below the ground, above 10 km or beyond +-20 km (422 naming the
    size or the centre); the CLI wrote them (a heart of size 1e9 m reached z = -4.6e8 m) and exited 0."""
    code, out, err = _run(capsys, [*argv, "-o", "-"])
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and flag in err, err


def test_formation_result_inside_the_bounds_still_written(capsys):
    code, out, _ = _run(capsys, ["formation", "shape", "circle", "-n", "10", "--size-m", "60", "-o", "-"])
    assert code == 0
    pts = np.asarray(json.loads(out)["points"])
    assert pts.shape == (10, 3) and pts[:, 2].min() >= 0


# --- the README's examples --------------------------------------------------------------------------------


def _readme_formation_examples() -> list[list[str]]:
    """The ``swarmshow formation shape|text ...`` lines of the README's command-line examples (those that need
    no input file)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    lines = [ln.strip() for ln in text.splitlines() if ln.strip().startswith("swarmshow formation ")]
    cmds = [shlex.split(re.sub(r"\s+#\s.*$", "", ln))[1:] for ln in lines]
    return [c for c in cmds if c[1] in ("shape", "text")]


def test_readme_formation_examples_run(capsys, tmp_path):
    """``swarmshow formation shape heart -n 100 --size-m 90`` (the README's first example) exits 2: at most 90
    points fit that heart at 3 m."""
    examples = _readme_formation_examples()
    assert len(examples) >= 2
    for argv in examples:
        argv = [a if not a.endswith(".json") else str(tmp_path / a) for a in argv]
        code, _, err = _run(capsys, argv)
        assert code == 0, (argv, err)


def test_export_fps_help_states_the_real_defaults(capsys):
    """``export --help`` said the skybrush-csv default was 4 fps; the exporter's default is 24 (Blender's)."""
    from app.exports import _skybrush_csv, _waypoints_csv

    with pytest.raises(SystemExit):
        cli_main(["export", "--help"])
    out = " ".join(capsys.readouterr().out.split())
    assert f"skybrush-csv default {_skybrush_csv.DEFAULT_FPS:g}" in out
    assert f"waypoints-csv default {_waypoints_csv.DEFAULT_FPS:g}" in out


# --- check: a one-drone show has no pair --------------------------------------------------------------------


def test_check_text_of_a_one_drone_show_names_no_pair(capsys, tmp_path):
    """With one drone there is no pair: the text said "min distance -1.000 m (limit 3.0 m; drones 0 and 0)",
    below the limit although the show is fine, and each transition "exact min -1.000 m (CAPT bound -1.000 m)"."""
    code, out, _ = _run(capsys, ["check", str(_one_drone_show(tmp_path))])
    assert code == 0
    assert "-1.000" not in out
    assert "drones 0 and 0" not in out
    assert re.search(r"min distance +n/a", out), out


def test_check_text_prints_no_negative_zero_altitude(tmp_path):
    """The lowest altitude (the demo's -3.4e-14 m at the pads, rounding) printed as "-0.0"; a real dip still
    shows its sign."""
    from app.cli._check import format_report
    from formations import parse_show
    from sim.verify import check_show

    report = check_show(parse_show(_one_drone_show(tmp_path).read_bytes()))
    text = format_report(report.model_copy(update={"min_altitude_m": -3.375e-14}))
    assert re.search(r"altitude +0\.0 \.\.", text), text
    text = format_report(report.model_copy(update={"min_altitude_m": -0.25}))
    assert re.search(r"altitude +-0\.2 \.\.", text) or re.search(r"altitude +-0\.3 \.\.", text), text


# --- Monte-Carlo text: a formation's transition and hold read alike ----------------------------------------


def test_montecarlo_text_tells_a_transition_from_its_hold(capsys, tmp_path):
    """Two drones held at exactly min_distance_m: every segment is listed, and the text read
    "segment 1 'a'" and "segment 2 'a'" for the transition into 'a' and its hold."""
    show = {
        "format": "swarmshow/1", "name": "pair", "drones": 2,
        "home": {"points": [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]]},
        "formations": [{"name": "a", "hold_s": 2.0, "points": [[0.0, 0.0, 12.0], [3.0, 0.0, 12.0]],
                        "color": "#ffffff"}],
    }
    path = tmp_path / "pair.json"
    path.write_text(json.dumps(show))
    code, out, _ = _run(capsys, ["simulate", str(path), "--runs", "1", "--preset", "calm-rtk"])
    assert code in (0, 1)
    seg_lines = [ln.split(":")[0].strip() for ln in out.splitlines() if ln.strip().startswith("segment ")]
    assert seg_lines, out
    described = [re.sub(r"^segment \d+ ", "", s) for s in seg_lines]
    assert len(set(described)) == len(described), seg_lines
    assert any("hold 'a'" in s for s in seg_lines) or not any("'a'" in s for s in seg_lines), seg_lines


# --- home: an explicit 0 is not "the default" --------------------------------------------------------------


@pytest.mark.parametrize("flag", ["--rows", "--cols"])
@pytest.mark.parametrize("value", ["0", "-2"])
def test_home_boxes_zero_or_negative_rows_cols_are_refused(capsys, tmp_path, flag, value):
    """``--rows 0`` was read as "not given" (``args.rows or ...``) and wrote a layout of 1 x 2 boxes, exit 0;
    a negative count came back as a message about ``home.boxes.grid.cols``, not the flag given."""
    show = _one_drone_show(tmp_path)
    out_path = tmp_path / "out.json"
    code, _, err = _run(capsys, ["home", str(show), "--boxes", "1", flag, value, "-o", str(out_path)])
    assert code == 2 and not out_path.exists()
    assert err.count("\n") == 1 and flag in err, err


# --- simulate --preset: say which conditions were flown ----------------------------------------------------


def test_simulate_preset_and_disturbance_together_is_a_usage_error(capsys, tmp_path):
    """``--preset calm-rtk --disturbance paper`` flew calm-rtk and dropped the paper's disturbance without a
    word (the help says the preset replaces it)."""
    code, out, err = _run(capsys, ["simulate", str(_one_drone_show(tmp_path)), "--preset", "calm-rtk",
                                   "--disturbance", "paper"])
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "--preset" in err and "--disturbance" in err, err


def test_simulate_summary_names_the_preset_flown(capsys, tmp_path):
    """A flight with ``--preset gusty-rtk`` (Dryden wind, GNSS error, ...) was summarised as "disturbance none",
    and its JSON did not say which preset was flown."""
    show = str(_one_drone_show(tmp_path))
    code, out, _ = _run(capsys, ["simulate", show, "--preset", "gusty-rtk", "--json"])
    assert code in (0, 1)
    assert json.loads(out)["preset"] == "gusty-rtk"
    code, out, _ = _run(capsys, ["simulate", show, "--preset", "gusty-rtk"])
    assert "preset gusty-rtk" in out.splitlines()[0] and "disturbance none" not in out, out
    code, out, _ = _run(capsys, ["simulate", show, "--disturbance", "wind", "--json"])
    summary = json.loads(out)
    # --disturbance alone flies the ideal vehicle in that disturbance (single_flight_options), and says so.
    assert summary["preset"] == "ideal" and summary["disturbance"] != "none"
    code, out, _ = _run(capsys, ["simulate", show, "--preset", "ideal", "--disturbance", "wind", "--json"])
    assert code in (0, 1) and json.loads(out)["disturbance"] == "wind"
    code, out, err = _run(capsys, ["simulate", show, "--preset", "ideal", "--disturbance", "wind", "--runs", "2"])
    assert code == 2 and "--disturbance" in err  # a Monte-Carlo run flies the preset alone


# --- the safety report: labels a reader can tell apart, counts as counts -----------------------------------


@pytest.fixture(scope="module")
def pair_report() -> dict:
    """One calm-rtk run of two drones at exactly min_distance_m (every segment has a worst pair)."""
    from formations import parse_show
    from sim.flight import FlightOptions, monte_carlo, options_for_preset
    from sim.plan import plan_show

    show = parse_show(json.dumps({
        "format": "swarmshow/1", "name": "pair", "drones": 2,
        "home": {"points": [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]]},
        "formations": [{"name": "a", "hold_s": 2.0, "points": [[0.0, 0.0, 12.0], [3.0, 0.0, 12.0]],
                        "color": "#ffffff"}],
    }))
    plan = plan_show(show)
    result = monte_carlo(plan, options_for_preset("calm-rtk", FlightOptions()), runs=2, seed0=0,
                         preset="calm-rtk")
    report = result.to_json()
    report["show"] = show.name
    return report


def _figure_svg(page: str, heading: str) -> str:
    """The inline SVG under ``<h2>{heading}</h2>``."""
    start = page.index(f"<h2>{heading}</h2>")
    return page[start:page.index("</svg>", start)]


def test_report_names_a_transition_and_its_hold_apart(pair_report):
    """The per-segment plot and the worst-pairs table said "1: a" and "2: a" for the transition into 'a' and its
    hold (only the segments table had the kind)."""
    from app.exports import render_safety_report

    page = render_safety_report(pair_report, "html").decode()
    kinds = {s["index"]: s["kind"] for s in pair_report["segments"]}
    assert set(kinds.values()) >= {"transition", "hold"}
    pairs = page[page.index("<h2>Worst pairs</h2>"):]
    cells = re.findall(r"<td>(\d+: [^<]*)</td>", pairs)
    assert cells
    for cell in cells:
        index = int(cell.split(":")[0])
        assert kinds[index] in cell, cell
    plot = _figure_svg(page, "Per segment")
    for s in pair_report["segments"]:
        assert s["kind"] in plot


def test_report_deviation_histogram_counts_in_whole_numbers(pair_report):
    """The deviation histogram's count axis ("drones x runs") had ticks 0.25, 0.5, ... for 4 drone-runs."""
    from app.exports import render_safety_report

    page = render_safety_report(pair_report, "html").decode()
    svg = _figure_svg(page, "Deviation from the plan")
    # y tick labels are the plain numbers matplotlib writes as text (x ticks are 10^k, with "×" or "−").
    ticks = [float(t) for t in re.findall(r">\s*([0-9]+(?:\.[0-9]+)?)\s*<", svg)]
    assert ticks, "no tick labels found"
    assert all(t == int(t) for t in ticks), ticks


# --- export: options a format does not use are refused, not dropped ---------------------------------------


@pytest.mark.parametrize("fmt, extra, flag", [
    ("skybrush-csv", ["--scale", "0.1"], "--scale"),
    ("waypoints-csv", ["--offset", "1,2,0"], "--offset"),
    ("skyc", ["--scale", "0.5"], "--scale"),
    ("crazyswarm", ["--audio", "AUDIO"], "--audio"),
    ("waypoints-csv", ["--audio", "AUDIO"], "--audio"),
])
def test_export_refuses_an_option_the_format_does_not_use(capsys, tmp_path, fmt, extra, flag):
    """``export --format skybrush-csv --scale 0.1`` wrote the show at full size, exit 0 (only crazyswarm scales);
    ``--audio`` with crazyswarm or a CSV was dropped without a word (only skyc and viser-html embed it)."""
    wav = tmp_path / "a.wav"
    import wave

    with wave.open(str(wav), "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(8000)
        w.writeframes((np.sin(np.arange(8000) * 0.1) * 3000).astype("<i2").tobytes())
    out_path = tmp_path / "out.zip"
    argv = ["export", str(_one_drone_show(tmp_path)), "-f", fmt, "-o", str(out_path),
            *[str(wav) if a == "AUDIO" else a for a in extra]]
    code, _, err = _run(capsys, argv)
    assert code == 2 and not out_path.exists()
    assert err.count("\n") == 1 and flag in err and fmt in err, err


def test_export_keeps_the_options_its_format_uses(capsys, tmp_path):
    out_path = tmp_path / "cs.zip"
    code, _, err = _run(capsys, ["export", str(_one_drone_show(tmp_path)), "-f", "crazyswarm", "-o", str(out_path),
                                 "--scale", "0.5", "--offset", "1,0,0"])
    assert code == 0 and out_path.exists(), err


# --- bench: ratios below 1 ---------------------------------------------------------------------------------


def test_bench_texts_state_ratios_below_one_plainly():
    """``bench check --drones 2`` printed "a 10 Hz sampled check takes 0.091 s (0x the exact one)" and
    ``bench plan --drones 2`` "ours is 0.1x faster" (i.e. 10x slower)."""
    from app.cli._bench import _format_check, _format_plan

    check = _format_check({"drones": 2, "formations": 5, "show_duration_s": 60.0, "plan_s": 0.05, "check_s": 0.641,
                           "exact_min_distance_m": 4.5, "violations": 0, "sampled_10hz_s": 0.091,
                           "sampled_over_exact_check": 0.091 / 0.641, "sampled_10hz_min_distance_m": 4.5})
    assert "(0x" not in check and "0.14x the exact one" in check, check
    plan = {"kind": "plan", "drones": 2, "assign_s": 0.0004, "timing_s": 6e-5, "verify_s": 0.0,
            "plan_and_verify_s": 0.0004, "duration_s": 23.3, "min_distance_m": 4.09, "capt_guarantee_m": 3.18,
            "dense_lsa_s": 0.00004,
            "dense_over_ours_assign": 0.1, "cost_equal": True}
    text = _format_plan(plan)
    assert "0.1x faster" not in text and "10.0x slower" in text, text
    text = _format_plan({**plan, "dense_over_ours_assign": 119.0})
    assert "119.0x faster" in text, text


# --- sampled exports: say which rate fits ------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["skybrush-csv", "waypoints-csv"])
def test_sampled_export_over_budget_names_a_rate_that_fits(capsys, tmp_path, monkeypatch, fmt):
    """Past the sample budget the error said only "lower --fps" (also through the API, which has no such flag);
    a one-drone show of 4.3 M s needs a rate below 1 fps that nobody would guess. It now names the highest rate
    that fits, and that rate is accepted."""
    from app.exports import _sampling

    monkeypatch.setattr(_sampling, "MAX_SAMPLES", 1_000)
    show = str(_one_drone_show(tmp_path, hold_s=60.0))
    code, _, err = _run(capsys, ["export", show, "-f", fmt, "-o", str(tmp_path / "a.zip"), "--fps", "100"])
    assert code == 2 and err.count("\n") == 1, err
    most = float(re.search(r"fps <= ([0-9.]+)", err).group(1))
    code, _, err = _run(capsys, ["export", show, "-f", fmt, "-o", str(tmp_path / "b.zip"), "--fps", str(most)])
    assert code == 0, err
    code, _, err = _run(capsys, ["export", show, "-f", fmt, "-o", str(tmp_path / "c.zip"), "--fps", str(most * 1.2)])
    assert code == 2  # and the rate named is close to the highest
