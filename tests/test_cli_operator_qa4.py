"""An operator's walk of the command line (QA, round 4): each test failed against the defect it names.

* ``swarmshow --version`` was a usage error ("the following arguments are required: COMMAND"), so a bug report
  could not say which swarmshow it was about;
* ``swarmshow validate --json`` of an invalid show printed nothing on stdout, and the text said "(and 4 more
  problems)" with no way to see them;
* an output named as a directory that does not exist (``-o out/``) was written as a *file* called ``out``
  (export, formation, home).
"""

from __future__ import annotations

import json
import subprocess
from importlib.metadata import version
from pathlib import Path

import pytest

from app.cli import main

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "formations/data/demo_show.json"


def _run(capsys, argv: list[str]) -> tuple[int, str, str]:
    try:
        code = main(argv)
    except SystemExit as exc:  # argparse's own exits (--version, --help, usage errors)
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


def test_version(capsys):
    code, out, err = _run(capsys, ["--version"])
    assert code == 0 and out == f"swarmshow {version('swarmshow')}\n" and err == "", (out, err)


def _bad_show(tmp_path: Path) -> tuple[Path, list[dict]]:
    doc = json.loads(DEMO.read_text())
    doc["drones"] = 0
    doc["settings"]["min_distance_m"] = -3
    doc["formations"][1]["hold_s"] = "long"
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    from formations import ShowValidationError, parse_show

    with pytest.raises(ShowValidationError) as exc:
        parse_show(path.read_bytes())
    return path, exc.value.errors


def test_validate_json_lists_every_problem(tmp_path, capsys):
    path, errors = _bad_show(tmp_path)
    assert len(errors) >= 3
    code, out, err = _run(capsys, ["validate", str(path), "--json"])
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    report = json.loads(out)
    assert report["valid"] is False
    assert [(e["path"], e["msg"]) for e in report["errors"]] == [(e["path"], e["msg"]) for e in errors]


def test_validate_text_says_where_the_other_problems_are(tmp_path, capsys):
    path, errors = _bad_show(tmp_path)
    code, out, err = _run(capsys, ["validate", str(path)])
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert f"and {len(errors) - 1} more problems" in err and "--json" in err, err


def test_validate_json_of_a_missing_file_is_still_one_line(tmp_path, capsys):
    code, out, err = _run(capsys, ["validate", str(tmp_path / "nope.json"), "--json"])
    assert code == 2 and out == "" and "no such file" in err


@pytest.mark.parametrize("argv", [
    ["export", str(DEMO), "--format", "show", "-o"],
    ["formation", "shape", "circle", "-n", "8", "-o"],
    ["home", str(DEMO), "--boxes", "10", "-o"],
])
def test_an_output_named_as_a_missing_directory_is_refused(tmp_path, capsys, argv):
    target = tmp_path / "out"
    code, out, err = _run(capsys, [*argv, f"{target}/"])
    assert code == 2 and len(err.strip().splitlines()) == 1 and "no such directory" in err, err
    assert not target.exists()


def test_export_into_an_existing_directory_with_a_slash_still_works(tmp_path, capsys):
    code, _, err = _run(capsys, ["export", str(DEMO), "--format", "show", "-o", f"{tmp_path}/"])
    assert code == 0, err
    assert json.loads((tmp_path / "Demo.json").read_text())["drones"] == 100


# -- serve: bad settings are one line naming the flag, before anything is printed as served ----------------


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_serve_with_a_data_dir_it_cannot_create_is_one_line(tmp_path, capsys):
    """Failed before: the server said "swarmshow server: http://..." and then died in its start-up with a
    70-line traceback (exit 3)."""
    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory")
    code, out, err = _run(capsys, ["serve", "--port", str(_free_port()), "--data-dir", str(blocker / "data")])
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, (out, err)
    assert "--data-dir" in err and str(blocker / "data") in err, err


@pytest.mark.parametrize(("argv", "flag"), [(["--port", "70000"], "--port"), (["--workers", "0"], "--workers")])
def test_serve_names_the_flag_at_fault(capsys, argv, flag):
    """Failed before: "swarmshow: error: port: Input should be ..." (the setting's name, not the flag's)."""
    code, out, err = _run(capsys, ["serve", *argv])
    assert code == 2 and err.startswith(f"swarmshow: error: {flag}: "), err


def test_serve_names_the_environment_variable_at_fault(capsys, monkeypatch):
    monkeypatch.setenv("SWARMSHOW_PORT", "70000")
    code, out, err = _run(capsys, ["serve"])
    assert code == 2 and err.startswith("swarmshow: error: SWARMSHOW_PORT: "), err


# -- simulate --scenario paper --plot: a path it cannot write is refused before flying ------------------------


@pytest.mark.parametrize(("name", "needle"), [("plot.txt", ".txt"), ("missing/plot.png", "no such directory")])
def test_paper_plot_path_is_checked_before_flying(tmp_path, capsys, monkeypatch, name, needle):
    """Failed before: ``--plot x.txt`` flew the 20 s scenario and then died in matplotlib with a traceback (exit 1);
    a missing directory was found only after flying."""
    import sim.flight

    flew: list[bool] = []
    monkeypatch.setattr(sim.flight, "paper_report", lambda **k: flew.append(True) or ({}, None, None))
    code, out, err = _run(capsys, ["simulate", "--scenario", "paper", "--plot", str(tmp_path / name)])
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and needle in err, err
    assert flew == []


# -- SHOW as '-': standard input, so that `swarmshow home SHOW ... | swarmshow check -` composes --------------


def _swarmshow(args: list[str], stdin: bytes) -> subprocess.CompletedProcess:
    """``swarmshow ARGS`` with ``stdin``, in this session's environment: its numba cache (``NUMBA_CACHE_DIR``
    or ``__pycache__``, tests/conftest.py) is the child's, so the child loads the planner's compiled
    functions. (It used to set a cache of its own, empty in a fresh clone: 20.4 s of compiling in CI.)"""
    from tests.live_server import swarmshow_command

    return subprocess.run([*swarmshow_command(), *args], input=stdin, capture_output=True, cwd=ROOT,
                          timeout=300)


def test_show_from_standard_input():
    """Failed before: "swarmshow: error: -: no such file", though ``home`` writes the show to stdout by default
    and ``export -o -`` writes to it."""
    r = _swarmshow(["validate", "-", "--json"], DEMO.read_bytes())
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["drones"] == 100
    home = _swarmshow(["home", str(DEMO), "--boxes", "10"], b"")
    assert home.returncode == 0, home.stderr
    r = _swarmshow(["check", "-", "--json"], home.stdout)
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    assert report["ok"] is True and report["drones"] == 100


def test_empty_standard_input_is_one_line():
    r = _swarmshow(["validate", "-"], b"")
    assert r.returncode == 2 and r.stderr.decode().strip().count("\n") == 0 and "stdin" in r.stderr.decode()


# -- a one-drone show's summaries read as English: "1 drone", "n/a" without a unit ---------------------------


@pytest.mark.parametrize("argv", [["check"], ["simulate"], ["simulate", "--runs", "2"]])
def test_one_drone_summaries_read_right(tmp_path, capsys, argv):
    """Failed before: "1 drones", "flown min distance n/a m (plan n/a m, ...)", "worst n/a m, 5 % n/a m"."""
    from tests.test_cli_qa3 import _one_drone_show

    code, out, err = _run(capsys, [argv[0], str(_one_drone_show(tmp_path)), *argv[1:]])
    assert code == 0, err
    assert ": 1 drone, " in out.splitlines()[0], out
    assert "n/a m" not in out and "1 drones" not in out, out


@pytest.mark.parametrize(("redirect", "says"), [("<&-", "stdin: is closed"), ("</dev/null", "stdin: is empty")])
def test_a_closed_or_empty_stdin_is_said_in_one_line(redirect, says):
    """``swarmshow check - <&-`` said "stdin: no such file" (``/dev/stdin`` names nothing once fd 0 is closed): the
    operator read it as a missing file. Failed before: that message for the closed stdin."""
    import sys

    swarmshow = Path(sys.executable).with_name("swarmshow")
    proc = subprocess.run(["bash", "-c", f'exec "$0" check - {redirect}', str(swarmshow)], capture_output=True,
                          text=True, timeout=120)
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1, (proc.returncode, proc.stderr)
    assert lines[0].startswith(f"swarmshow: error: {says}"), lines
    assert "no such file" not in proc.stderr
