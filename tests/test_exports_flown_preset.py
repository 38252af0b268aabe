"""Exports of the *flown* trajectories (``source=simulated``) fly the single flight the designer chose:
its error-model preset and seed (``sim.flight.single_flight_options``), not the ideal vehicle.

The reference is flown here, independently of the export path, with ``sim.flight`` itself; the
export's CSV rows are compared with it at the export's own sample times.
"""

from __future__ import annotations

import csv
import io
import json
import zipfile

import numpy as np
import pytest

from app.cli import main
from app.exports import ExportError, ExportOptions, export_show
from formations import dump_show
from tests.conftest import CSV_HALF_MM, app_client, flown_at


def _csv_rows(content: bytes, name: str = "drone_002.csv") -> tuple[dict, np.ndarray]:
    with zipfile.ZipFile(io.BytesIO(content)) as z:
        manifest = json.loads(z.read("manifest.json"))
        rows = np.array(list(csv.reader(io.StringIO(z.read(name).decode())))[1:], dtype=float)
    return manifest, rows


@pytest.fixture(scope="module")
def flights(square_plan):
    """The reference single flights, flown straight by ``sim.flight`` at the export's 25 Hz."""
    from sim.flight import FlightOptions, fly_show, single_flight_options

    def fly(preset: str | None, seed: int = 0):
        opts = FlightOptions(output_hz=25.0, seed=seed)
        return fly_show(square_plan, opts if preset is None else single_flight_options(preset, opts))

    return {"gusty-rtk/3": fly("gusty-rtk", 3), "calm-rtk/0": fly("calm-rtk", 0), "vehicle": fly(None)}


def test_simulated_export_flies_the_chosen_preset_and_seed(square, flights):
    """Failed before: the export flew ``FlightOptions()`` (the ideal vehicle, no error model) whatever the
    designer's simulation panel said; preset and seed were not options at all."""
    result = export_show(square, "waypoints-csv", source="simulated", fps=25, preset="gusty-rtk", seed=3)
    manifest, rows = _csv_rows(result.content)
    times = rows[:, 0]
    assert np.abs(rows[:, 1:4] - flown_at(flights["gusty-rtk/3"], 1, times)).max() <= CSV_HALF_MM
    # Not the ideal vehicle's track, nor another seed's: the gusty wind moves a drone by centimetres.
    assert np.abs(rows[:, 1:4] - flown_at(flights["vehicle"], 1, times)).max() > 0.01
    assert np.abs(rows[:, 1:4] - flown_at(flights["calm-rtk/0"], 1, times)).max() > 0.01
    assert manifest["flight"]["preset"] == "gusty-rtk" and manifest["flight"]["seed"] == 3


def test_simulated_export_defaults_to_the_single_flights_default(square, flights):
    """No preset, no seed: the single flight's default (calm-rtk, seed 0), as ``swarmshow simulate SHOW``."""
    result = export_show(square, "waypoints-csv", source="simulated", fps=25)
    manifest, rows = _csv_rows(result.content)
    assert np.abs(rows[:, 1:4] - flown_at(flights["calm-rtk/0"], 1, rows[:, 0])).max() <= CSV_HALF_MM
    assert manifest["flight"]["preset"] == "calm-rtk" and manifest["flight"]["seed"] == 0


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"source": "simulated", "preset": "stormy"}, "preset"),
    ({"source": "simulated", "preset": 3}, "preset"),
    ({"source": "simulated", "seed": -1}, "seed"),
    ({"source": "simulated", "seed": 2**31}, "seed"),
    ({"source": "simulated", "seed": 1.5}, "seed"),
    ({"source": "simulated", "seed": True}, "seed"),
    # What is not flown has no preset or seed: refused, not dropped without a word.
    ({"preset": "calm-rtk"}, "preset"),
    ({"seed": 4}, "seed"),
])
def test_bad_preset_or_seed_names_the_field(kwargs, field):
    with pytest.raises(ExportError) as err:
        ExportOptions(**kwargs)
    assert err.value.field == field


def test_export_presets_are_the_simulations():
    from app.cli import _simulate as cli_sim
    from app.exports import _core
    from sim import flight

    assert _core.FLIGHT_PRESETS == flight.PRESETS == cli_sim.PRESETS
    assert _core.DEFAULT_FLIGHT_PRESET == flight.DEFAULT_FLIGHT_PRESET == cli_sim.DEFAULT_FLIGHT_PRESET
    from app.api.models import MAX_SEED

    assert _core.MAX_SEED == MAX_SEED  # the export's seed bound is the simulation's


# -- the command line ---------------------------------------------------------------------------------------


def test_cli_export_takes_preset_and_seed(square, flights, tmp_path, capsys):
    show = tmp_path / "square.json"
    show.write_text(dump_show(square))
    out = tmp_path / "w.zip"
    code = main(["export", str(show), "--format", "waypoints-csv", "--source", "simulated", "--fps", "25",
                 "--preset", "gusty-rtk", "--seed", "3", "-o", str(out)])
    assert code == 0, capsys.readouterr().err
    _, rows = _csv_rows(out.read_bytes())
    assert np.abs(rows[:, 1:4] - flown_at(flights["gusty-rtk/3"], 1, rows[:, 0])).max() <= CSV_HALF_MM


@pytest.mark.parametrize(("argv", "needle"), [
    (["--source", "simulated", "--preset", "stormy"], "--preset"),
    (["--source", "simulated", "--seed", "-2"], "--seed"),
    (["--preset", "calm-rtk"], "--preset"),  # planned: nothing is flown
    (["--seed", "1"], "--seed"),
])
def test_cli_export_refuses_a_bad_preset_or_seed(square, tmp_path, capsys, argv, needle):
    show = tmp_path / "square.json"
    show.write_text(dump_show(square))
    with pytest.raises(SystemExit) as exc:  # argparse's choices, or the command's own CliError
        raise SystemExit(main(["export", str(show), "--format", "waypoints-csv", *argv, "-o", str(tmp_path / "o")]))
    err = capsys.readouterr().err
    assert exc.value.code == 2 and needle in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "o").exists()


# -- the API ------------------------------------------------------------------------------------------------

client = app_client("flown", workers=1)


def test_api_export_takes_preset_and_seed(client, square_id, flights):
    r = client.get(f"/api/shows/{square_id}/export/waypoints-csv",
                   params={"source": "simulated", "fps": 25, "preset": "gusty-rtk", "seed": 3})
    assert r.status_code == 200, r.text
    _, rows = _csv_rows(r.content)
    assert np.abs(rows[:, 1:4] - flown_at(flights["gusty-rtk/3"], 1, rows[:, 0])).max() <= CSV_HALF_MM


@pytest.mark.parametrize(("params", "field"), [
    ({"source": "simulated", "preset": "stormy"}, "preset"),
    ({"source": "simulated", "seed": -1}, "seed"),
    ({"preset": "calm-rtk"}, "preset"),
    ({"seed": 2}, "seed"),
])
def test_api_export_refuses_a_bad_preset_or_seed(client, square_id, params, field):
    r = client.get(f"/api/shows/{square_id}/export/waypoints-csv", params=params)
    assert r.status_code == 422, r.text
    assert any(field in (e.get("loc") or []) or e.get("path") == field for e in r.json()["detail"]), r.text


def test_editor_sends_what_the_server_takes():
    """The editor's lists of formats taking scale/offset and the flown trajectories are the server's."""
    import re
    from pathlib import Path

    from app.exports import _core

    js = (Path(__file__).parents[1] / "frontend/js/exportcheck.js").read_text()

    def js_list(name: str) -> tuple[str, ...]:
        body = re.search(rf"export const {name} = \[([^\]]*)\]", js).group(1)
        return tuple(re.findall(r'"([^"]+)"', body))

    assert js_list("SCALING_FORMATS") == _core.SCALING_FORMATS
    assert js_list("FLOWN_FORMATS") == _core.FLOWN_FORMATS
    assert js_list("SAMPLED_FORMATS") == _core.SAMPLED_FORMATS


# -- scale and offset: only where they apply (crazyswarm) ---------------------------------------------------

NOT_SCALING = ["skybrush-csv", "skyc", "qgc-plan", "qgc-wpl", "waypoints-csv", "viser-html"]


@pytest.mark.parametrize("fmt", NOT_SCALING)
@pytest.mark.parametrize(("kwargs", "field"), [({"scale": 0.5}, "scale"), ({"offset_m": (1.0, 0.0, 0.0)}, "offset")])
def test_formats_without_scaling_refuse_scale_and_offset(square, square_plan, fmt, kwargs, field):
    """Failed before: every format but crazyswarm dropped scale and offset without a word (the file at full
    size, at the show's origin) while the command line refused them."""
    with pytest.raises(ExportError) as err:
        export_show(square, fmt, plan=square_plan, origin=(47.0, 8.0, 400.0), **kwargs)
    assert err.value.field == field and "crazyswarm" in str(err.value)


@pytest.mark.parametrize("fmt", NOT_SCALING)
def test_api_refuses_scale_and_offset_where_unused(client, square_id, fmt):
    for params, field in (({"scale": 0.5}, "scale"), ({"offset": "1,0,0"}, "offset")):
        r = client.get(f"/api/shows/{square_id}/export/{fmt}", params={"origin": "47,8,400", **params})
        assert r.status_code == 422, (fmt, params, r.text)
        problem = r.json()["detail"][0]
        assert problem["path"] == field and "crazyswarm" in problem["msg"], problem


def test_api_crazyswarm_still_scales(client, square_id):
    """The one format that applies them: its manifest records them."""
    r = client.get(f"/api/shows/{square_id}/export/crazyswarm", params={"scale": 0.5, "offset": "1,2,0"})
    assert r.status_code == 200, r.text
    with zipfile.ZipFile(io.BytesIO(r.content)) as z:
        manifest = json.loads(z.read("manifest.json"))
    assert manifest["scale"] == 0.5 and manifest["offset_m"] == [1.0, 2.0, 0.0], manifest


# -- fps: only the sampled formats sample ----------------------------------------------------------------------

NOT_SAMPLED = ["skyc", "crazyswarm", "qgc-plan", "qgc-wpl"]


@pytest.mark.parametrize("fmt", NOT_SAMPLED)
def test_formats_that_do_not_sample_refuse_fps(square, square_plan, client, square_id, tmp_path, capsys, fmt):
    """Failed before: ``fps`` was dropped without a word by the formats that hold exact trajectories (a
    "25 Hz" skyc is the same file as any other), while scale and offset were refused."""
    with pytest.raises(ExportError) as err:
        export_show(square, fmt, plan=square_plan, origin=(47.0, 8.0, 400.0), fps=25)
    assert err.value.field == "fps" and "skybrush-csv" in str(err.value)
    r = client.get(f"/api/shows/{square_id}/export/{fmt}", params={"origin": "47,8,400", "fps": 25})
    assert r.status_code == 422 and r.json()["detail"][0]["path"] == "fps", r.text
    show = tmp_path / "square.json"
    show.write_text(dump_show(square))
    code = main(["export", str(show), "--format", fmt, "--origin", "47,8,400", "--fps", "25",
                 "-o", str(tmp_path / "o")])
    err_text = capsys.readouterr().err
    assert code == 2 and "--fps" in err_text and len(err_text.strip().splitlines()) == 1, err_text
