"""``swarmshow simulate SHOW --runs K``: the Monte-Carlo command, its report files and its exit codes.

The HTML report is read back with the standard library's HTML parser (no external reference, the
plots inline), the PDF with pypdf (a real reader: pages, text of the tables).
"""

from __future__ import annotations

import dataclasses
import json
from html.parser import HTMLParser

import numpy as np
import pytest

from app.cli import _simulate as cli_sim
from app.cli import main
from formations import dump_show
from sim import flight as sim_flight
from tests.conftest import fibonacci_sphere, make_show, ring


@pytest.fixture(scope="module")
def show_file(tmp_path_factory):
    show = make_show(
        [
            {"name": "ring", "hold_s": 1.0, "points": ring(10, 9.0), "color": "#ff0000"},
            {"name": "ball", "hold_s": 1.0, "points": fibonacci_sphere(10, 7.0), "color": "#00ff00"},
        ],
        drones=10, rows=2, cols=5, spacing_m=4.5,
    )
    path = tmp_path_factory.mktemp("mc") / "show.json"
    path.write_text(dump_show(show))
    return path


class _Collect(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.tags: list[str] = []
        self.refs: list[str] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        for name, value in attrs:
            if name in ("src", "href", "xlink:href") and value and not value.startswith("#"):
                self.refs.append(value)

    def handle_data(self, data):
        self.text.append(data)


def test_constants_match_the_simulation() -> None:
    assert cli_sim.PRESETS == sim_flight.PRESETS
    assert cli_sim.DEFAULT_COLLISION_DISTANCE_M == sim_flight.DEFAULT_COLLISION_DISTANCE_M


def test_runs_json_and_reports(show_file, tmp_path, capsys) -> None:
    pdf = tmp_path / "report.pdf"
    code = main(["simulate", str(show_file), "--runs", "2", "--preset", "gusty-rtk", "--seed", "5",
                 "--confidence", "0.9", "--json", "--report", str(pdf)])
    out = json.loads(capsys.readouterr().out)
    assert code == 0
    assert out["runs"] == 2 and out["seed0"] == 5 and out["preset"] == "gusty-rtk" and out["confidence"] == 0.9
    assert [r["seed"] for r in out["run_list"]] == [5, 6]
    from pypdf import PdfReader

    reader = PdfReader(str(pdf))
    assert len(reader.pages) >= 7  # summary, 4 plots, segments, worst pairs
    text = "\n".join(p.extract_text() for p in reader.pages)
    assert "Safety report" in text and "Worst pairs" in text
    assert f"{out['show_min']['flown_min_m']['quantiles']['0']:.3f}" in text

    html_path = tmp_path / "report.html"
    assert main(["simulate", str(show_file), "--runs", "2", "--preset", "calm-rtk", "--report", str(html_path)]) == 0
    human = capsys.readouterr().out
    assert "flown min separation" in human and "OK:" in human and str(html_path) in human
    parser = _Collect()
    parser.feed(html_path.read_text())
    assert parser.tags.count("svg") == 4 and parser.refs == [] and "script" not in parser.tags
    assert "Worst pairs" in "".join(parser.text)


def test_exit_1_when_a_run_breaks_the_minimum_distance(show_file, monkeypatch, capsys) -> None:
    """The verdict follows the report: the same runs judged against a minimum distance above the flown one."""
    real = sim_flight.monte_carlo

    def stricter(plan, *args, **kwargs):
        res = real(plan, *args, **kwargs)
        floor = float(np.min([r["min_distance_m"] for r in res.runs]))
        settings = plan.settings.model_copy(update={"min_distance_m": floor + 0.5})
        res.plan = dataclasses.replace(plan, settings=settings)
        return res

    monkeypatch.setattr(sim_flight, "monte_carlo", stricter)
    assert main(["simulate", str(show_file), "--runs", "2", "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["show_min"]["p_below_min_distance"]["runs_below"] == 2


@pytest.mark.parametrize(
    ("argv", "needle"),
    [
        (["--runs", "0"], "--runs must be >= 1"),
        (["--runs", "2", "--confidence", "1.5"], "--confidence must be in (0, 1)"),
        (["--runs", "2", "--collision-distance", "-1"], "--collision-distance must be > 0"),
        (["--runs", "2", "--report", "out.txt"], "must end in .html or .pdf"),
        (["--runs", "2", "--report", "/nonexistent-dir/r.html"], "no such directory"),
        (["--confidence", "0.9"], "--confidence is only used with --runs"),
        (["--report", "x.html"], "--report is only used with --runs"),
    ],
)
def test_bad_arguments_exit_2_with_one_line(show_file, capsys, argv, needle) -> None:
    assert main(["simulate", str(show_file), *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "\n" not in err


def test_unknown_preset_and_scenario_mix_exit_2(show_file, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["simulate", str(show_file), "--runs", "2", "--preset", "windy"])
    assert exc.value.code == 2
    assert main(["simulate", "--scenario", "paper", "--runs", "2"]) == 2
    assert "--runs" in capsys.readouterr().err


def test_summary_states_the_largest_deviation_in_metres_and_names_the_drone(show_file, capsys) -> None:
    """QA: the summary printed 'largest deviation from the plan: 2.445e+01 m' (a drone 24 m off under calm RTK),
    in scientific notation and without saying which drone. It reads '24.45 m (drone 4)' now, and small values
    keep their digits."""
    assert main(["simulate", str(show_file), "--runs", "2", "--preset", "calm-rtk", "--json"]) in (0, 1)
    out = json.loads(capsys.readouterr().out)
    dev = out["deviation"]
    worst = dev["worst_drones"][0]
    line = next(s for s in cli_sim.format_montecarlo(out).splitlines() if "largest deviation" in s)
    assert line.strip() == f"largest deviation from the plan: {dev['max_m']:.4g} m (drone {worst['drone']})"
    assert worst["max_m"] == dev["max_m"] == max(dev["per_drone_max_m"])
    for value, text in [(24.4531, "24.45 m"), (0.000125490, "0.0001255 m"), (1.5, "1.5 m")]:
        fake = {**out, "deviation": {**dev, "max_m": value, "worst_drones": [{"drone": 4, "max_m": value}]}}
        line = next(s for s in cli_sim.format_montecarlo(fake).splitlines() if "largest deviation" in s)
        assert line.strip() == f"largest deviation from the plan: {text} (drone 4)"
