"""The flight kernel's specialisations and the note a cold-cache compile prints.

numba compiles the kernel once per tuple of argument types (array dtype, layout, read-only flag),
each a minute or two of CPU on a machine without the cache. QA: ``swarmshow bench sim --drones 1``
sat silent for 338 s because it recorded float64 frames where a flown show records float32 ones,
a specialisation no show flight had put in the cache.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numba
import pytest

import sim.flight.engines._numba as K
from app.cli._bench import _bench_sim
from app.cli._common import show_library_notes
from sim.flight import fly_show

ROOT = Path(__file__).resolve().parents[1]


def _requested_signatures(monkeypatch: pytest.MonkeyPatch, run: Any) -> set[tuple[Any, ...]]:
    """The kernel argument types ``run()`` asks the float64 kernel for (the kernel itself not run:
    nothing compiles, and the types do not depend on the values)."""
    kernel, seen = K._kernel, set()

    def record(dispatcher: Any, args: tuple[Any, ...]) -> None:
        seen.add(tuple(kernel.typeof_pyval(a) for a in args))

    monkeypatch.setattr(K, "_cached_machine_code", record)
    monkeypatch.setattr(K, "_kernel", lambda *args: None)
    run()
    monkeypatch.undo()
    return seen


@pytest.mark.parametrize("drones", [1, 5])
def test_bench_sim_runs_the_kernel_specialisation_a_show_flight_runs(monkeypatch, small_plan, drones):
    show = _requested_signatures(monkeypatch, lambda: fly_show(small_plan))
    bench = _requested_signatures(monkeypatch, lambda: _bench_sim(
        argparse.Namespace(drones=drones, seconds=0.05, numpy_seconds=0.002)))
    assert len(show) == 1 and bench, (show, bench)
    extra = bench - show
    # Name the differing arguments, so that a failure says which type the bench got wrong.
    diffs = [(i, a, b) for s in extra for i, (a, b) in enumerate(zip(s, next(iter(show)), strict=True)) if a != b]
    assert not extra, f"bench sim compiles a specialisation no show flight runs: (arg, bench, show) {diffs}"


_STAND_IN = """
import numba


@numba.njit(cache=True)
def stand_in(x, y):
    return x * y + 1.0
"""


def _fresh_stand_in(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Any:
    """A new dispatcher (nothing compiled in memory) for the stand-in's one source file."""
    mod = tmp_path / "kernel_stand_in.py"
    if not mod.exists():
        mod.write_text(_STAND_IN)
    spec = importlib.util.spec_from_file_location("kernel_stand_in", mod)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "kernel_stand_in", module)  # the compiling child imports it by this name
    spec.loader.exec_module(module)
    return module.stand_in


def test_a_cold_cache_compile_says_so_once_and_a_warm_cache_says_nothing(tmp_path, monkeypatch, capsys):
    # A two-line jitted function in a module of its own stands in for the kernel: the same path
    # through _cached_machine_code (the decision, the note, the compiling child process), compiled
    # in a second instead of minutes. Each "process" here is a fresh dispatcher, which like a new
    # process has nothing in memory and must load from the disk cache or compile.
    cache = tmp_path / "cache"
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(cache))  # read when a dispatcher is made
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(cache))  # the compiling child's
    monkeypatch.syspath_prepend(str(tmp_path))
    show_library_notes()
    note = f"swarmshow: {K.COMPILE_NOTE}"
    args = (2.0, 3.0)

    def run(fn: Any) -> str:
        for _ in range(3):  # a flight calls it once per chunk: only a cache miss may print the note
            K._cached_machine_code(fn, args)
        assert fn(*args) == 7.0 and len(fn.signatures) == 1
        return capsys.readouterr().err

    def indexes() -> list[Path]:
        return list(cache.rglob("*stand_in*.nbi"))

    cold = _fresh_stand_in(tmp_path, monkeypatch)
    sig = tuple(cold.typeof_pyval(a) for a in args)
    assert not K._in_disk_cache(cold, sig) and not indexes()
    assert run(cold).count(note) == 1
    assert indexes(), "the child did not compile into the cache"

    warm = _fresh_stand_in(tmp_path, monkeypatch)
    assert K._in_disk_cache(warm, sig)
    assert note not in run(warm)

    # Without the index files numba has no entry for the signature: a compile again, and its note.
    for index in indexes():
        index.unlink()
    again = _fresh_stand_in(tmp_path, monkeypatch)
    assert not K._in_disk_cache(again, sig)
    assert run(again).count(note) == 1


_LIMITS_PROBE = """
import importlib, os, resource, sys
sys.path.insert(0, sys.argv[1])
from app.tasks import limit_memory
import sim.flight.engines._numba as K
limit_memory(int(sys.argv[2]))  # as a server's worker does (worker_memory_mb)
stand_in = importlib.import_module("kernel_stand_in").stand_in  # records this process's limits
K._cached_machine_code(stand_in, (2.0, 3.0))  # a cold cache: the compiling child records its own
assert stand_in(2.0, 3.0) == 7.0
"""

_RECORD_LIMITS = """
import os, resource
with open(os.environ["STAND_IN_LIMITS"], "a") as f:
    f.write("%d %d\\n" % resource.getrlimit(resource.RLIMIT_DATA))
"""


def test_a_workers_memory_cap_is_soft_and_the_compiling_child_lifts_it(tmp_path):
    # On a cold cache every simulation in a server's worker failed 413 "too_large": the worker's
    # RLIMIT_DATA cap (2 GiB by default), inherited by the child that compiles the kernel, is
    # less than LLVM needs for the two lane bodies. The worker caps the soft limit only and the
    # compiling child lifts its soft limit to the hard one. The stand-in records the limits of
    # each process that imports it: the capped worker, then the compiling child.
    import resource

    (tmp_path / "kernel_stand_in.py").write_text(_STAND_IN + _RECORD_LIMITS)
    probe = tmp_path / "probe.py"
    probe.write_text(_LIMITS_PROBE)
    limits = tmp_path / "limits.txt"
    cap = 3 << 30  # above what this small flight of imports needs, below any real hard limit here
    _, hard = resource.getrlimit(resource.RLIMIT_DATA)
    assert hard == resource.RLIM_INFINITY or hard > cap, "the test needs a hard data limit above the cap"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"), STAND_IN_LIMITS=str(limits),
               PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    subprocess.run([sys.executable, str(probe), str(tmp_path), str(cap)], env=env, check=True, timeout=600)
    rows = [tuple(int(v) for v in line.split()) for line in limits.read_text().splitlines()]
    assert rows[0] == (cap, hard), "the worker's hard limit must stay: its compiling child cannot raise past it"
    assert len(rows) == 2, f"no compiling child imported the stand-in: {rows}"
    assert rows[1] == (hard, hard), "the compiling child kept the worker's cap"
    assert any((tmp_path / "cache").rglob("*stand_in*.nbi")), "the child did not compile into the cache"


_FAIL_IN_CHILD = """
import os
if os.getpid() != int(os.environ["STAND_IN_PARENT"]):
    raise RuntimeError("the stand-in refuses to compile in a child")
"""


def test_a_failed_compiling_child_says_why_and_this_process_compiles(tmp_path, monkeypatch, caplog):
    # The child's output was captured and dropped: when it failed, nothing said why before this
    # process compiled the kernel itself (minutes, and bits that may differ from the cache's).
    (tmp_path / "kernel_stand_in.py").write_text(_STAND_IN + _FAIL_IN_CHILD)
    monkeypatch.setenv("STAND_IN_PARENT", str(os.getpid()))
    cache = tmp_path / "cache"
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(cache))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(cache))
    monkeypatch.syspath_prepend(str(tmp_path))
    fn = _fresh_stand_in(tmp_path, monkeypatch)
    with caplog.at_level("WARNING", logger=K.__name__):
        K._cached_machine_code(fn, (2.0, 3.0))
    assert fn(2.0, 3.0) == 7.0 and len(fn.signatures) == 1
    failed = [r.getMessage() for r in caplog.records if "compiling process failed" in r.getMessage()]
    assert len(failed) == 1 and "refuses to compile in a child" in failed[0], caplog.text


@pytest.mark.slow
def test_cli_bench_sim_on_a_cold_cache_says_it_compiles(tmp_path):
    # End to end (minutes of CPU: a real compile of the flight kernel on an empty cache).
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    cmd = [sys.executable, "-c", "from app.cli import main; main()",
           "bench", "sim", "--drones", "1", "--seconds", "0.01", "--numpy-seconds", "0.002", "--json"]
    note = f"swarmshow: {K.COMPILE_NOTE}"
    walls = []
    for _ in range(2):
        t0 = time.perf_counter()
        out = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True, timeout=1800, check=True)
        walls.append(time.perf_counter() - t0)
        assert out.stderr.count(note) == (1 if len(walls) == 1 else 0), out.stderr
    print(f"cold {walls[0]:.1f} s, warm {walls[1]:.1f} s wall")


def test_a_jobs_compile_note_reaches_its_status_and_clears_when_it_moves_on():
    # The worker side: while a task flies, sim's warnings go to its job as a "note" event.
    import logging
    import queue
    import threading
    import types

    from app.api.errors import job_body
    from app.api.models import JobOut
    from app.jobs import Job, JobManager
    from app.tasks import Progress, library_notes

    events: queue.Queue[Any] = queue.Queue()
    progress = Progress("j1", events, threading.Event())
    log = logging.getLogger(K.__name__)
    with library_notes(progress):
        log.warning(K.COMPILE_NOTE)
    log.warning("after the task: not the job's")
    assert events.get_nowait() == ("j1", "note", K.COMPILE_NOTE) and events.empty()

    # The server side: the relay puts it on the job (its snapshot, so the API and the event stream),
    # and the next progress clears it.
    job = Job(id="j1", kind="simulate", content_hash="h", options={})
    relay = types.SimpleNamespace(_events=events, _lock=threading.Lock(), _jobs={"j1": job}, _closed=False,
                                  _save=lambda j: None)
    for item in [("j1", "running", 0.0), ("j1", "progress", 0.1), ("j1", "note", K.COMPILE_NOTE), None]:
        events.put(item)
    JobManager._relay_loop(relay)  # type: ignore[arg-type]
    assert JobOut(**job_body(job.snapshot())).note == K.COMPILE_NOTE
    for item in [("j1", "progress", 0.5), None]:
        events.put(item)
    JobManager._relay_loop(relay)  # type: ignore[arg-type]
    assert JobOut(**job_body(job.snapshot())).note == "" and job.progress == 0.5
