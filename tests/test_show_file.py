"""The show file: every rejection names its JSON path and reason; valid files round-trip."""

from __future__ import annotations

import copy
import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from app.cli import main as cli_main
from formations import MAX_DRONES, ShowValidationError, dump_show, parse_show, show_json_schema


def _base() -> dict:
    """A valid 4-drone show as a plain dict (each test breaks one thing)."""
    return {
        "format": "swarmshow/1",
        "name": "base",
        "drones": 4,
        "home": {"grid": {"rows": 2, "cols": 2, "spacing_m": 3.0}},
        "formations": [
            {
                "name": "square",
                "hold_s": 5.0,
                "points": [[0, 0, 20], [4, 0, 20], [0, 0, 24], [4, 0, 24]],
                "colors": ["#ff0000", "#00ff00", "#0000ff", "#ffffff"],
            }
        ],
    }


def _reject(doc: dict | str) -> ShowValidationError:
    with pytest.raises(ShowValidationError) as info:
        parse_show(doc)
    return info.value


def test_base_is_valid_and_defaults_fill_settings() -> None:
    show = parse_show(_base())
    s = show.settings
    assert (s.min_distance_m, s.max_speed_xy_mps, s.max_speed_z_mps) == (3.0, 10.0, 2.0)
    assert (s.max_accel_mps2, s.max_altitude_m, s.takeoff_altitude_m) == (4.0, 150.0, 10.0)
    assert parse_show(dump_show(show)) == show


def test_non_finite_number_in_json_text_is_rejected_with_path() -> None:
    text = json.dumps(_base()).replace('"hold_s": 5.0', '"hold_s": NaN')
    err = _reject(text)
    assert err.errors[0]["path"] == "formations[0].hold_s"


@pytest.mark.parametrize("value", [math.inf, -math.inf, math.nan])
def test_non_finite_point_is_rejected(value: float) -> None:
    doc = _base()
    doc["formations"][0]["points"][2][0] = value
    err = _reject(doc)
    assert err.errors[0]["path"] == "formations[0].points[2][0]"
    assert "finite" in err.errors[0]["msg"]


def test_unknown_field_is_rejected_with_its_path() -> None:
    doc = _base()
    doc["settings"] = {"max_speed_mps": 5.0}
    err = _reject(doc)
    assert err.errors[0]["path"] == "settings.max_speed_mps"
    assert "Extra inputs" in err.errors[0]["msg"]


@pytest.mark.parametrize("hold", [0.0, -1.0])
def test_zero_or_negative_hold_is_rejected(hold: float) -> None:
    doc = _base()
    doc["formations"][0]["hold_s"] = hold
    err = _reject(doc)
    assert err.errors[0]["path"] == "formations[0].hold_s"
    assert "greater than or equal to 0.01" in err.errors[0]["msg"]


def test_fewer_points_than_drones_is_rejected() -> None:
    doc = _base()
    doc["formations"][0]["points"].pop()
    doc["formations"][0]["colors"].pop()
    err = _reject(doc)
    assert err.errors[0]["path"] == "formations[0].points"
    assert "3 points for 4 drones" in err.errors[0]["msg"]


def test_point_above_ceiling_and_below_ground_are_rejected() -> None:
    doc = _base()
    doc["formations"][0]["points"][3][2] = 151.0
    err = _reject(doc)
    assert err.errors[0]["path"] == "formations[0].points[3][2]"
    assert "above max_altitude_m 150.0" in err.errors[0]["msg"]
    doc = _base()
    doc["formations"][0]["points"][1][2] = -0.5
    err = _reject(doc)
    assert err.errors[0]["path"] == "formations[0].points[1][2]"
    assert "below the ground" in err.errors[0]["msg"]


def test_formation_points_too_close_name_both_indices_and_distance() -> None:
    doc = _base()
    doc["formations"][0]["points"][3] = [6.5, 0.0, 20.0]  # 2.5 m from point 1, >= 3 m from the others
    err = _reject(doc)
    assert err.errors[0]["path"] == "formations[0].points"
    assert err.errors[0]["msg"] == "points 1 and 3 are 2.500 m apart, closer than min_distance_m 3.0 m"


def test_home_points_too_close_name_both_indices() -> None:
    doc = _base()
    doc["home"] = {"points": [[0, 0, 0], [10, 0, 0], [20, 0, 0], [21, 0, 0]]}
    err = _reject(doc)
    assert err.errors[0]["path"] == "home.points"
    assert "home points 2 and 3 are 1.000 m apart" in err.errors[0]["msg"]


def test_home_grid_spacing_below_minimum_is_rejected() -> None:
    doc = _base()
    doc["home"]["grid"]["spacing_m"] = 2.0
    err = _reject(doc)
    assert err.errors[0]["path"] == "home.grid.spacing_m"


def test_home_grid_smaller_than_drone_count_is_rejected() -> None:
    doc = _base()
    doc["home"]["grid"]["rows"] = 1
    err = _reject(doc)
    assert err.errors[0]["path"] == "home.grid"
    assert "1 x 2 = 2 positions is smaller than drones = 4" in err.errors[0]["msg"]


@pytest.mark.parametrize("color", ["red", "#ff000", "#gg0000", "ff0000", "#ff00001"])
def test_bad_colour_strings_are_rejected(color: str) -> None:
    doc = _base()
    doc["formations"][0]["colors"][1] = color
    err = _reject(doc)
    assert err.errors[0]["path"] == "formations[0].colors[1]"
    assert "pattern" in err.errors[0]["msg"]


def test_drone_ceiling_is_documented_and_enforced() -> None:
    doc = _base()
    doc["drones"] = MAX_DRONES + 1
    err = _reject(doc)
    assert err.errors[0]["path"] == "drones"
    assert str(MAX_DRONES) in err.errors[0]["msg"]
    assert str(MAX_DRONES) in show_json_schema()["properties"]["drones"]["description"]


def test_colors_length_must_match_points() -> None:
    doc = _base()
    doc["formations"][0]["colors"].append("#000000")
    err = _reject(doc)
    assert "'colors' has 5 entries but 'points' has 4" in err.errors[0]["msg"]


def test_wrong_format_tag_and_malformed_json() -> None:
    doc = _base()
    doc["format"] = "swarmshow/2"
    assert _reject(doc).errors[0]["path"] == "format"
    assert "Invalid JSON" in _reject('{"format": ').errors[0]["msg"]


def test_oversized_and_non_utf8_bytes_are_rejected() -> None:
    assert "not UTF-8" in _reject_bytes(b"\xff\xfe{}").one_line()
    assert "limit" in _reject_bytes(b" " * (20 * 1024 * 1024 + 1)).one_line()


def _reject_bytes(data: bytes) -> ShowValidationError:
    with pytest.raises(ShowValidationError) as info:
        parse_show(data)
    return info.value


@settings(max_examples=25, deadline=None)
@given(
    spacing=st.floats(3.0, 20.0),
    z=st.floats(0.0, 140.0),
    hold=st.floats(0.01, 1000.0),
)
def test_valid_shows_round_trip_through_json(spacing: float, z: float, hold: float) -> None:
    doc = _base()
    doc["home"]["grid"]["spacing_m"] = spacing
    doc["formations"][0]["hold_s"] = hold
    doc["formations"][0]["points"] = [[i * spacing, 0.0, z] for i in range(4)]
    show = parse_show(doc)
    again = parse_show(dump_show(show))
    assert again == show and again.content_hash() == show.content_hash()


def test_content_hash_ignores_key_order_but_not_content() -> None:
    doc = _base()
    reordered = dict(reversed(list(copy.deepcopy(doc).items())))
    assert parse_show(doc).content_hash() == parse_show(reordered).content_hash()
    doc["formations"][0]["hold_s"] = 6.0
    assert parse_show(doc).content_hash() != parse_show(reordered).content_hash()


def test_cli_validate_and_schema(tmp_path, capsys) -> None:
    good = tmp_path / "good.json"
    good.write_text(json.dumps(_base()))
    assert cli_main(["validate", str(good)]) == 0
    bad_doc = _base()
    bad_doc["formations"][0]["hold_s"] = -1
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(bad_doc))
    capsys.readouterr()
    assert cli_main(["validate", str(bad)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("swarmshow: error:") and "formations[0].hold_s" in err and err.count("\n") == 1
    assert cli_main(["validate", str(tmp_path / "missing.json")]) == 2
    assert cli_main(["schema"]) == 0
    schema = json.loads(capsys.readouterr().out)
    assert schema["properties"]["format"]["const"] == "swarmshow/1"
