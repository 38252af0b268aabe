"""Problems in the designer's words come from the server: every problem the API sends for a show says ``where``
(``formations.plain_words``; formations by number and name) and, inside a formation, ``where_in_formation`` for its
card; the editor (frontend/js/errors.js) shows those words as they come and keeps no copy of the wording
(its ``plainPath`` port is gone). ``plainMsg`` still turns pydantic's messages for the show file's real rules into
the editor's words (the bound kept, the API phrasing gone).

Failed before: a strict save's, a check's and a query's 422 problems carried no ``where`` (only drafts did), and
the editor worded paths itself with a JavaScript copy of the server's rules."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from formations import ShowValidationError, parse_show, plain_path, plain_words
from tests.conftest import app_client
from tests.test_api_jobs import show_doc

NODE = shutil.which("node")
ERRORS_JS = Path(__file__).resolve().parent.parent / "frontend" / "js" / "errors.js"

client = app_client("plainwords", workers=1)


def _node(calls: list[tuple[str, list]], *, after: str = "") -> list:
    """Each (function name, arguments) called in errors.js under node; the answers in order, then ``after`` (a JS
    expression over the module ``e``) if given."""
    tail = f", {after}" if after else ""
    script = (f"import * as e from {json.dumps(ERRORS_JS.as_uri())};\n"
              f"const calls = {json.dumps(calls)};\n"
              f"console.log(JSON.stringify([calls.map(([f, a]) => e[f](...a)){tail}]));\n")
    proc = subprocess.run([NODE, "--input-type=module", "-e", script], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def _heart_doc(name: str = "Words") -> dict:
    doc = show_doc(name=name)
    doc["formations"].append(dict(doc["formations"][0], name="Heart"))
    return doc


#: The paths the editor's old JavaScript copy was kept equal to the server on, in the designer's words: indices
#: from 1 as people count, a formation named, a unit in brackets, a list field said once with its item's number.
WORDS = [
    ("formations[1].points[5][2]", 'formation 2 "Heart", point 6, z'),
    ("formations[0].hold_s", 'formation 1 "square", hold (s)'),
    ("settings.max_accel_mps2", "settings, max accel (m/s²)"),
    ("formations[1].points", 'formation 2 "Heart", points'),
    ("home.grid.spacing_m", "home, grid, spacing (m)"),
    ("lights[0].duty", "light 1, duty"),
    ("formations[3].colors[2]", "formation 4, colour 3"),
    ("formations[0].points[1][7]", 'formation 1 "square", point 2, coordinate 8'),
    ("settings.geofence.x_min_m", "settings, geofence, x min (m)"),
    ("drones", "drones"),
    ("lights.effects[0].end_s", "light effect 1, end (s)"),
    ("lights.effects[2].effect.duty", "light effect 3, effect, duty"),
    ("groups.a", "groups, a"),
]


@pytest.mark.parametrize(("path", "words"), WORDS)
def test_the_server_words_each_path(path, words):
    doc = _heart_doc()
    said = plain_words(path, doc)
    assert said["where"] == words == plain_path(path, doc)
    # The parsed show names its formations as the document does (the plan's refusals word paths from it).
    if path.startswith("formations[") and not path.startswith("formations[3]"):
        assert plain_words(path, parse_show(doc)) == said
    # Inside a formation: the words below it, for its own card (which names the formation).
    if path.startswith("formations["):
        inner = path.split("]", 1)[1].lstrip(".")
        assert said["where_in_formation"] == words.split(", ", 1)[1] == plain_path(inner)
    else:
        assert "where_in_formation" not in said


def _api_problems(client) -> dict[str, list[dict]]:
    """Real 422 problems of the API for a show, by what was asked."""
    out = {}
    bad = _heart_doc("Strict")
    bad["formations"][1]["hold_s"] = -1
    r = client.post("/api/shows", json=bad)
    assert r.status_code == 422, r.text
    out["create"] = r.json()["detail"]
    r = client.post("/api/shows", json=_heart_doc("Strict"))
    assert r.status_code == 201, r.text
    sid, rev = r.json()["id"], r.json()["revision"]
    r = client.put(f"/api/shows/{sid}", json={"revision": rev, "show": bad})
    assert r.status_code == 422, r.text
    out["update"] = r.json()["detail"]
    # A pinned arrival the transition cannot make: the check's plan refuses it.
    early = _heart_doc("Early")
    early["formations"][1]["arrive_at_s"] = 0.5
    r = client.post("/api/shows", json=early)
    assert r.status_code == 201, r.text
    r = client.post(f"/api/shows/{r.json()['id']}/check")
    assert r.status_code == 422, r.text
    out["check"] = r.json()["detail"]
    r = client.get(f"/api/shows/{sid}/export/crazyswarm", params={"offset": "1,2"})
    assert r.status_code == 422, r.text
    out["query"] = r.json()["detail"]
    r = client.post(f"/api/shows/{sid}/simulate", json={"output_hz": -1})
    assert r.status_code == 422, r.text
    out["body"] = r.json()["detail"]
    return out


def test_every_problem_the_api_sends_for_a_show_says_where(client):
    got = _api_problems(client)
    for p in (got["create"][0], got["update"][0]):
        assert p["path"] in ("formations[1].hold_s", "show.formations[1].hold_s"), p
        assert p["where"] == 'formation 2 "Heart", hold (s)' and p["where_in_formation"] == "hold (s)", p
    (p,) = got["check"]
    assert p["path"] == "formations[1].arrive_at_s", p
    assert p["where"] == 'formation 2 "Heart", arrive at (s)' and p["where_in_formation"] == "arrive at (s)", p
    assert got["query"][0]["where"] == "offset", got["query"]
    assert got["body"][0]["path"] == "output_hz" and got["body"][0]["where"] == "output (Hz)", got["body"]


def test_forced_transitions_say_where_with_the_formation_named():
    """What the 3D preview and a simulation list for a show they play as designed (``tasks.forced_problems``)."""
    from app import tasks
    from sim import plan_show

    doc = _heart_doc("Forced")
    doc["formations"][1].update(transition_s=0.2, points=[[x, y, z + 20] for x, y, z in doc["formations"][0]["points"]])
    (p,) = tasks.forced_problems(plan_show(parse_show(doc), enforce_limits=False))
    assert p["path"] == "formations[1].transition_s", p
    assert p["where"] == 'formation 2 "Heart", transition (s)' and p["where_in_formation"] == "transition (s)", p


@pytest.mark.skipif(NODE is None, reason="node is not installed")
def test_the_editor_shows_the_server_s_words(client):
    """errors.js over the API's own problems: a problem's line and a formation card's text say the server's words
    (stand-in words that only the server could have sent show that the editor words nothing itself)."""
    got = _api_problems(client)
    created, checked = got["create"][0], got["check"][0]
    stand_in = {**created, "where": "the server's words", "where_in_formation": "its own words"}
    ((said,),) = _node([("describe", [stand_in])])
    assert said["where"] == "the server's words", said
    cards = "[...e.formationProblems.entries()]"
    _, card = _node([("showShowErrors", [[stand_in]])], after=cards)
    assert card == [[1, f"its own words: must be at least {_hold_min():g}"]], card
    # A message that names its own path says the server's words in its place on the card.
    _, card = _node([("showShowErrors", [[checked]])], after=cards)
    assert card[0][0] == 1 and card[0][1].startswith("arrive at (s) = 0.5 s is too early"), card
    # No copy of the wording is left in the editor.
    _, names = _node([], after="Object.keys(e)")
    assert not {"plainPath", "plainKey"} & set(names), names
    assert "NAMED_LISTS" not in ERRORS_JS.read_text() and "UNITS" not in ERRORS_JS.read_text()


def _hold_min() -> float:
    from formations._show import Formation

    return Formation.model_json_schema()["properties"]["hold_s"]["minimum"]


@pytest.mark.skipif(NODE is None, reason="node is not installed")
def test_plain_msg_words_pydantic_s_messages_for_the_show_file_s_rules():
    doc = show_doc()
    doc["formations"][0]["hold_s"] = -1  # below a minimum
    doc["settings"]["max_speed_z_mps"] = 1e9  # above a maximum
    doc["settings"]["max_accel_mps2"] = "fast"  # not a number
    doc["drones"] = 2.5  # not a whole number
    del doc["home"]  # missing
    doc["surplus"] = 1  # not a field
    with pytest.raises(ShowValidationError) as exc:
        parse_show(doc)
    msgs = [e["msg"] for e in exc.value.errors]
    assert len(msgs) >= 5, msgs
    (plain,) = _node([("plainMsg", [m]) for m in msgs])
    for raw, said in zip(msgs, plain, strict=True):
        assert "Input should" not in said and "Field required" not in said and "Extra inputs" not in said, (raw, said)
        # Any bound the server named is still there.
        for word in raw.split():
            if word.replace(".", "", 1).isdigit():
                assert word in said, (raw, said)
