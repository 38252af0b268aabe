"""The editor's copy of the server's plain words (frontend/js/errors.js: plainPath, plainMsg) against the server:
plainPath must say a path as formations._show.plain_path does, and plainMsg must turn pydantic's messages for the
show file's real rules into the editor's words (the bound kept, the API phrasing gone)."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from formations._show import ShowValidationError, parse_show, plain_path
from tests.test_api_jobs import show_doc

NODE = shutil.which("node")
ERRORS_JS = Path(__file__).resolve().parent.parent / "frontend" / "js" / "errors.js"


def _node(calls: list[tuple[str, list]]) -> list[str]:
    """Each (function name, arguments) called in errors.js under node; the answers in order."""
    script = (f"import * as e from {json.dumps(ERRORS_JS.as_uri())};\n"
              f"const calls = {json.dumps(calls)};\n"
              "console.log(JSON.stringify(calls.map(([f, a]) => e[f](...a))));\n")
    proc = subprocess.run([NODE, "--input-type=module", "-e", script], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


@pytest.mark.skipif(NODE is None, reason="node is not installed")
def test_plain_path_says_paths_as_the_server_does():
    doc = show_doc(name="Words")
    doc["formations"].append(dict(doc["formations"][0], name="Heart"))
    paths = ["formations[1].points[5][2]", "formations[0].hold_s", "settings.max_accel_mps2", "formations[1].points",
             "home.grid.spacing_m", "lights[0].duty", "formations[3].colors[2]", "formations[0].points[1][7]",
             "settings.geofence.x_min_m", "drones", "lights.effects[0].end_s", "lights.effects[2].effect.duty",
             "groups.a"]
    got = _node([("plainPath", [p, doc]) for p in paths])
    assert got == [plain_path(p, doc) for p in paths]
    # A list field is said once with its item's number (CI: 'lights, effects, effects 1, end (s)').
    assert got[paths.index("lights.effects[0].end_s")] == "light effect 1, end (s)"


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
    plain = _node([("plainMsg", [m]) for m in msgs])
    for raw, said in zip(msgs, plain, strict=True):
        assert "Input should" not in said and "Field required" not in said and "Extra inputs" not in said, (raw, said)
        # Any bound the server named is still there.
        for word in raw.split():
            if word.replace(".", "", 1).isdigit():
                assert word in said, (raw, said)
