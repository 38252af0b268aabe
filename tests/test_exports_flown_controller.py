"""A flown export ("source=simulated") flies the single flight's controller (ISMC or the PID baseline) and, with
preset "ideal", its fleet-wide disturbance, as preset and seed already were: the library, the API, the CLI and
the editor's request alike.

Failed before: ``controller`` and ``disturbance`` were not export options; a single flight flown with the
baseline controller was exported with ISMC.
"""

from __future__ import annotations

import csv
import io
import json
import zipfile

import numpy as np
import pytest

from app.cli import main
from app.exports import ExportError, export_show
from formations import dump_show
from sim import plan_show
from tests.conftest import CSV_HALF_MM, app_client, flown_at


@pytest.fixture(scope="module")
def flights(square):
    """The reference single flights, flown straight by ``sim.flight`` at the export's 25 Hz."""
    from sim.flight import FlightOptions, fly_show, single_flight_options

    plan = plan_show(square)

    def fly(preset: str, **kw):
        return fly_show(plan, single_flight_options(preset, FlightOptions(output_hz=25.0, seed=0, **kw)))

    return {"baseline": fly("calm-rtk", controller="baseline"), "ismc": fly("calm-rtk"),
            "ideal-wind": fly("ideal", disturbance="wind"), "ideal": fly("ideal")}


def _rows(content: bytes) -> tuple[dict, np.ndarray]:
    with zipfile.ZipFile(io.BytesIO(content)) as z:
        manifest = json.loads(z.read("manifest.json"))
        rows = np.array(list(csv.reader(io.StringIO(z.read("drone_002.csv").decode())))[1:], dtype=float)
    return manifest, rows


def test_export_flies_the_chosen_controller(square, flights):
    result = export_show(square, "waypoints-csv", source="simulated", fps=25, controller="baseline")
    manifest, rows = _rows(result.content)
    assert np.abs(rows[:, 1:4] - flown_at(flights["baseline"], 1, rows[:, 0])).max() <= CSV_HALF_MM
    # Not ISMC's track: the two controllers track differently by more than the file's rounding.
    assert np.abs(rows[:, 1:4] - flown_at(flights["ismc"], 1, rows[:, 0])).max() > 10 * CSV_HALF_MM
    assert manifest["flight"]["controller"] == "baseline"


def test_export_flies_the_disturbance_with_ideal(square, flights):
    result = export_show(square, "waypoints-csv", source="simulated", fps=25, preset="ideal", disturbance="wind")
    manifest, rows = _rows(result.content)
    assert np.abs(rows[:, 1:4] - flown_at(flights["ideal-wind"], 1, rows[:, 0])).max() <= CSV_HALF_MM
    assert np.abs(rows[:, 1:4] - flown_at(flights["ideal"], 1, rows[:, 0])).max() > 10 * CSV_HALF_MM


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"source": "simulated", "controller": "lqr"}, "controller"),
    ({"source": "simulated", "disturbance": "storm"}, "disturbance"),
    ({"source": "simulated", "preset": "gusty-rtk", "disturbance": "paper"}, "disturbance"),
    ({"controller": "baseline"}, "controller"),
    ({"disturbance": "paper"}, "disturbance"),
])
def test_bad_controller_or_disturbance_names_the_field(square, kwargs, field):
    with pytest.raises(ExportError) as err:
        export_show(square, "waypoints-csv", **kwargs)
    assert err.value.field == field, str(err.value)


def test_cli_export_takes_the_controller(square, flights, tmp_path, capsys):
    src = tmp_path / "square.json"
    src.write_text(dump_show(square))
    out = tmp_path / "o.zip"
    code = main(["export", str(src), "-f", "waypoints-csv", "--source", "simulated", "--fps", "25",
                 "--controller", "baseline", "-o", str(out)])
    assert code == 0, capsys.readouterr().err
    _, rows = _rows(out.read_bytes())
    assert np.abs(rows[:, 1:4] - flown_at(flights["baseline"], 1, rows[:, 0])).max() <= CSV_HALF_MM


client = app_client("flownctl", workers=1)


def test_api_export_takes_the_controller(client, square, flights):
    r = client.post("/api/shows", content=dump_show(square), headers={"content-type": "application/json"})
    sid = r.json()["id"]
    r = client.get(f"/api/shows/{sid}/export/waypoints-csv",
                   params={"source": "simulated", "fps": 25, "controller": "baseline"})
    assert r.status_code == 200, r.text
    _, rows = _rows(r.content)
    assert np.abs(rows[:, 1:4] - flown_at(flights["baseline"], 1, rows[:, 0])).max() <= CSV_HALF_MM
    r = client.get(f"/api/shows/{sid}/export/waypoints-csv", params={"controller": "baseline"})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "controller", r.text


def test_export_knows_the_simulations_controllers_and_disturbances():
    from app.exports import _core
    from sim import flight

    assert _core.FLIGHT_CONTROLLERS == tuple(flight.CONTROLLERS)
    assert _core.FLIGHT_DISTURBANCES == tuple(flight.DISTURBANCES)
