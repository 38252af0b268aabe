"""A Dask worker says the flight kernel's cold-cache compile note as the command line does, ``swarmshow: ...``
on its stderr (it printed the bare sentence through logging's last-resort handler, unlike every other line the
CLI prints), once, and not a second time where a handler already hears the ``sim`` warnings (the CLI's own
process running an in-process cluster).

Failed before: ``sim.flight._dask`` had no ``worker_notes`` and neither task set anything up.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

_SCRIPT = """
import logging
from sim.flight import _dask
from sim.flight.engines._numba import COMPILE_NOTE
{setup}
_dask.worker_notes()
_dask.worker_notes()  # idempotent: one handler, one line
logging.getLogger("sim.flight.engines._numba").warning(COMPILE_NOTE)
"""


def _stderr(setup: str = "") -> str:
    out = subprocess.run([sys.executable, "-c", _SCRIPT.format(setup=setup)], cwd=ROOT, capture_output=True,
                         text=True, timeout=120, check=True)
    return out.stderr


def test_worker_prints_the_note_prefixed_once():
    from sim.flight.engines._numba import COMPILE_NOTE

    assert _stderr() == f"swarmshow: {COMPILE_NOTE}\n"


def test_a_process_that_already_hears_sim_adds_nothing():
    from sim.flight.engines._numba import COMPILE_NOTE

    setup = "from app.cli._common import show_library_notes; show_library_notes()"
    assert _stderr(setup) == f"swarmshow: {COMPILE_NOTE}\n"


def test_one_line_whichever_of_the_worker_and_the_command_line_asks_first():
    """A worker in the CLI's process (an in-process cluster) set up before the command line's notes: one
    handler, one line. Failed before: the worker's and the CLI's were two handler classes, two lines."""
    from sim.flight.engines._numba import COMPILE_NOTE

    setup = "_dask.worker_notes()\nfrom app.cli._common import show_library_notes; show_library_notes()"
    assert _stderr(setup) == f"swarmshow: {COMPILE_NOTE}\n"


def test_the_commands_that_do_not_run_sim_do_not_import_it():
    """The notes' handler is sim's: the command line installs it only for the commands that run sim, so that
    ``swarmshow validate`` does not pay a second for importing it."""
    code = ("import sys; from app.cli import main\n"
            "try:\n    main(['schema'])\nexcept SystemExit:\n    pass\n"
            "assert 'sim' not in sys.modules, 'schema imported sim'")
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120, check=True)


def test_both_worker_tasks_set_the_notes_up(monkeypatch):
    """The shard task (flight engine ``dask``) and the Monte-Carlo run task call it before flying."""
    from sim.flight import _dask, _montecarlo

    order: list[str] = []
    monkeypatch.setattr(_dask, "worker_notes", lambda: order.append("notes"))
    monkeypatch.setattr(_dask, "task_progress", lambda *a: None)
    monkeypatch.setattr(_dask, "fly_local", lambda *a, **k: order.append("fly"))
    monkeypatch.setattr(_montecarlo, "fly_run", lambda *a, **k: order.append("fly"))
    _dask._fly_shard(None, np.arange(2), None, "t", 0)  # type: ignore[arg-type]
    _montecarlo._dask_run(None, None, 0, 0, 10, "t")  # type: ignore[arg-type]
    assert order == ["notes", "fly", "notes", "fly"]
