"""Per segment and per CAPT transition, "no pair" is what the show-level minimum says it is: +inf in Python,
``null`` in JSON (and in the API's schema: number or null), never -1 (a distance below every limit).

Failed before: a one-drone show's ``by_transition[*].min_distance_m`` and
``transitions[*].capt.exact_min_distance_m`` were -1.0 in ``swarmshow check --json`` (the show-level one was
already null, tests/test_check_no_pair.py).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from app.cli import main as cli_main
from tests.conftest import app_client

DEMO = Path(__file__).resolve().parents[1] / "formations/data/demo_show.json"


def _solo_two_formations(tmp_path: Path) -> Path:
    """One drone, two formations: a takeoff, a CAPT transition and a landing, none with a pair."""
    show = {
        "format": "swarmshow/1", "name": "solo", "drones": 1,
        "home": {"grid": {"rows": 1, "cols": 1, "spacing_m": 3.0}},
        "formations": [{"name": "a", "hold_s": 1.0, "points": [[0.0, 0.0, 12.0]], "color": "#ffffff"},
                       {"name": "b", "hold_s": 1.0, "points": [[6.0, 0.0, 14.0]], "color": "#ff0000"}],
    }
    path = tmp_path / "solo2.json"
    path.write_text(json.dumps(show))
    return path


def test_json_of_one_drone_says_null_per_segment_and_transition(capsys, tmp_path):
    code = cli_main(["check", str(_solo_two_formations(tmp_path)), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 0 and report["ok"] is True
    assert report["transitions"] and report["by_transition"]
    for t in report["transitions"]:
        assert t["capt"]["exact_min_distance_m"] is None, t["capt"]
    for g in report["by_transition"]:
        assert g["min_distance_m"] is None and g["min_distance_pair"] == [], g


def test_python_report_of_one_drone_is_inf(tmp_path):
    from formations import parse_show
    from sim.verify import check_show

    report = check_show(parse_show(_solo_two_formations(tmp_path).read_bytes()))
    assert all(math.isinf(t.capt.exact_min_distance_m) and t.capt.exact_min_distance_m > 0
               for t in report.transitions)
    assert all(math.isinf(g.min_distance_m) and g.min_distance_m > 0 for g in report.by_transition)


def test_text_of_one_drone_prints_no_minus_one_or_inf(capsys, tmp_path):
    cli_main(["check", str(_solo_two_formations(tmp_path))])
    out = capsys.readouterr().out
    assert "-1" not in out and "inf" not in out, out


def test_a_pair_still_reports_segment_distances_against_sampling(capsys):
    """Two or more drones: each segment's number is the exact minimum, checked by dense sampling of the plan
    (the sampled minimum over the segment is >= the exact one and close to it)."""
    from formations import parse_show
    from sim import plan_show

    cli_main(["check", str(DEMO), "--json"])
    report = json.loads(capsys.readouterr().out)
    plan = plan_show(parse_show(DEMO.read_bytes()))
    for g in report["by_transition"]:
        d = g["min_distance_m"]
        assert isinstance(d, float), g
        t = np.linspace(g["start_s"], g["start_s"] + g["duration_s"], 401)
        pos = plan.evaluate(t).positions_m  # (T, N, 3)
        diff = pos[:, :, None, :] - pos[:, None, :, :]
        dist = np.sqrt((diff ** 2).sum(-1))
        n = dist.shape[1]
        dist[:, np.arange(n), np.arange(n)] = np.inf
        sampled = float(dist.min())
        assert d <= sampled + 1e-9 and sampled - d < 0.5, (g["segment"], d, sampled)


client = app_client("nopairseg", workers=1)


def test_api_schema_says_number_or_null(client):
    schemas = client.get("/api/openapi.json").json()["components"]["schemas"]

    def allows_null(prop: dict) -> bool:
        return any(s.get("type") == "null" for s in prop.get("anyOf", []))

    assert allows_null(schemas["TransitionCheck"]["properties"]["min_distance_m"])
    assert allows_null(schemas["CaptPremise"]["properties"]["exact_min_distance_m"])
