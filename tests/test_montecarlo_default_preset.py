"""One documented default error preset (calm-rtk, ``sim.flight.DEFAULT_FLIGHT_PRESET``) for a single flight and a
Monte-Carlo, in the API, the command line and the editor's menu.

Failed before: the API's Monte-Carlo defaulted to gusty-rtk and the CLI's ``--runs K`` without ``--preset`` flew the
ideal vehicle (its report said "preset none"), while single flights and the editor's menu said calm-rtk; run k of
a default Monte-Carlo was then not the default single flight of seed seed0 + k.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

from app.cli import _simulate as cli_sim
from app.cli import main
from sim import flight as sim_flight
from tests.conftest import app_client
from tests.test_api_jobs import show_doc, wait_for

ROOT = Path(__file__).resolve().parents[1]


def test_api_montecarlo_default_is_the_single_flights():
    from app.api.models import MonteCarloOptions, SimulateOptions

    assert MonteCarloOptions().preset == SimulateOptions().preset == sim_flight.DEFAULT_FLIGHT_PRESET


def test_cli_keeps_the_simulations_default():
    """The CLI keeps its own copy (building the parser must not import the simulation)."""
    assert cli_sim.DEFAULT_FLIGHT_PRESET == sim_flight.DEFAULT_FLIGHT_PRESET
    assert cli_sim.PRESETS == sim_flight.PRESETS


def test_editor_menu_selects_the_default():
    html = (ROOT / "frontend/index.html").read_text()
    select = re.search(r'<select id="sim-preset"[^>]*>(.*?)</select>', html, re.S).group(1)
    selected = re.findall(r'<option value="([^"]+)" selected', select)
    assert selected == [sim_flight.DEFAULT_FLIGHT_PRESET], selected


def _show_file(tmp_path: Path) -> Path:
    path = tmp_path / "mc.json"
    path.write_text(json.dumps(show_doc("mc default", hold_s=1.0)))
    return path


def test_cli_montecarlo_default_run_is_the_default_single_flight(tmp_path, capsys):
    show = _show_file(tmp_path)
    assert main(["simulate", str(show), "--runs", "2", "--seed", "4", "--json"]) == 0
    mc = json.loads(capsys.readouterr().out)
    assert mc["preset"] == sim_flight.DEFAULT_FLIGHT_PRESET
    # Run 1 (seed 5) flies again alone with the defaults: the same flown minimum, to the bit.
    assert main(["simulate", str(show), "--seed", "5", "--json"]) == 0
    single = json.loads(capsys.readouterr().out)
    assert single["preset"] == sim_flight.DEFAULT_FLIGHT_PRESET
    assert mc["run_list"][1]["seed"] == 5
    assert mc["run_list"][1]["min_distance_m"] == single["flown_min_distance_m"], (mc["run_list"], single)


def test_cli_montecarlo_with_a_disturbance_keeps_flying_it(tmp_path, capsys):
    """``--runs K --disturbance wind`` (no preset): the ideal vehicle in that wind, as before (the preset's own
    wind would count twice). The report records the disturbance, and the wind was flown: the same run in still
    air (``--preset ideal``: the ideal vehicle, no error model at all) deviates differently from the plan.
    (Review: the test checked only ``preset is None``, which a run that dropped the wind passes too.)"""
    show = _show_file(tmp_path)
    code = main(["simulate", str(show), "--runs", "1", "--disturbance", "wind", "--json"])
    windy = json.loads(capsys.readouterr().out)
    assert code in (0, 1) and windy["preset"] is None and windy["disturbance"] == "wind"
    assert sim_flight.error_preset("ideal") == sim_flight.ErrorModel()  # so --preset ideal is the same vehicle
    code = main(["simulate", str(show), "--runs", "1", "--preset", "ideal", "--json"])
    still = json.loads(capsys.readouterr().out)
    assert code in (0, 1) and still["preset"] == "ideal" and still["disturbance"] == "none"
    assert (windy["seed0"], windy["controller"], windy["engine"]) == (still["seed0"], still["controller"],
                                                                      still["engine"])
    assert windy["deviation"]["per_drone_max_m"] != still["deviation"]["per_drone_max_m"], (windy["deviation"],
                                                                                          still["deviation"])


client = app_client("mcdefault", workers=1)


def test_api_montecarlo_without_a_preset_flies_the_default(client):
    r = client.post("/api/shows", json=show_doc("mc api default", hold_s=1.0))
    assert r.status_code == 201, r.text
    r = client.post(f"/api/shows/{r.json()['id']}/montecarlo", json={"runs": 1})
    assert r.status_code == 202, r.text
    assert r.json()["options"]["preset"] == sim_flight.DEFAULT_FLIGHT_PRESET
    job = wait_for(client, r.json()["id"], lambda j: j["state"] in ("done", "failed", "cancelled"), timeout_s=120.0)
    assert job["state"] == "done" and job["result"]["montecarlo"]["preset"] == sim_flight.DEFAULT_FLIGHT_PRESET
