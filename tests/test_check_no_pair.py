"""A show of one drone has no pair of drones: its check reports no minimum distance (JSON ``null``, the text
"n/a"), never a distance of -1 m below the limit (the editor drew that -1.00 m in red, "≥ 3.0").

Failed before: ``swarmshow check --json`` and ``POST /api/shows/{id}/check`` said ``"min_distance_m": -1.0``.
"""

from __future__ import annotations

import json
import math
import re

from app.cli import main as cli_main
from tests.conftest import app_client
from tests.test_cli_qa3 import _one_drone_show


def test_cli_check_json_of_one_drone_has_no_distance(capsys, tmp_path):
    code = cli_main(["check", str(_one_drone_show(tmp_path)), "--json"])
    out = capsys.readouterr().out
    report = json.loads(out)
    assert code == 0 and report["ok"] is True
    assert report["min_distance_m"] is None and report["min_distance_pair"] == [], report["min_distance_m"]


def test_cli_check_text_of_one_drone_says_no_pair(capsys, tmp_path):
    cli_main(["check", str(_one_drone_show(tmp_path))])
    out = capsys.readouterr().out
    assert re.search(r"min distance +n/a +\(limit 3\.0 m; one drone, no pair\)", out), out
    assert "-1" not in out and "inf" not in out, out


def test_report_in_memory_keeps_no_pair_apart_from_any_limit(tmp_path):
    """In Python the minimum over no pair is +inf (no limit is broken by it), never a negative distance."""
    from formations import parse_show
    from sim.verify import check_show

    report = check_show(parse_show(_one_drone_show(tmp_path).read_bytes()))
    assert math.isinf(report.min_distance_m) and report.min_distance_m > 0
    assert report.to_json()["min_distance_m"] is None


def test_a_pair_still_reports_its_distance(capsys):
    from pathlib import Path

    demo = Path(__file__).resolve().parents[1] / "formations/data/demo_show.json"
    cli_main(["check", str(demo), "--json"])
    report = json.loads(capsys.readouterr().out)
    assert isinstance(report["min_distance_m"], float) and report["min_distance_m"] >= 3.0 - 1e-9


client = app_client("nopair", workers=1)


def test_api_check_of_one_drone_has_no_distance(client, tmp_path):
    r = client.post("/api/shows", content=_one_drone_show(tmp_path).read_bytes(),
                    headers={"content-type": "application/json"})
    assert r.status_code == 201, r.text
    r = client.post(f"/api/shows/{r.json()['id']}/check")
    assert r.status_code == 200, r.text
    assert r.json()["report"]["min_distance_m"] is None
