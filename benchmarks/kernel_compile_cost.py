"""Cold-cache compile cost of the numba flight kernels: CPU, wall and peak memory of one compile.

Each measurement is a child process on an EMPTY numba cache (a fresh temporary ``NUMBA_CACHE_DIR``)
that compiles one kernel specialisation (the one a one-drone hover ``simulate`` asks for, float64
frames, as the compiling child of ``_numba._cached_machine_code`` would) and reports its own CPU time
(user + system), wall time, peak RSS (``ru_maxrss``) and the time spent inside LLVM (numba's
``numba:llvm_lock`` event) and in numba's own passes (``numba:run_pass``, top-level passes only).
The machine is shared: compare variants measured in the same session, not against old figures.

    .venv/bin/python -m benchmarks.kernel_compile_cost float64 float32
    .venv/bin/python -m benchmarks.kernel_compile_cost float64 --module sim.flight.engines._numba_base

``--module``: the kernel module to compile instead (it replaces the precision's module for the
flight, so that a copy of another version of the kernel can be measured in the same checkout).
``--keep DIR``: compile into ``DIR`` (kept) instead of a temporary cache.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

MODULES = {"float64": "sim.flight.engines._numba", "float32": "sim.flight.engines._numba_f32"}

_CHILD = r"""
import importlib, json, resource, sys, time
from collections import defaultdict
t0_wall, t0_cpu = time.perf_counter(), time.process_time()
import numpy as np
from numba.core import event
precision, module = sys.argv[1], sys.argv[2]
llvm = [0.0]
passes = defaultdict(float)

class _Passes(event.Listener):  # each pass's own time, less the passes nested in it (a callee's compile)
    stack = []
    def on_start(self, ev):
        self.stack.append([time.perf_counter(), 0.0])
    def on_end(self, ev):
        t0, nested = self.stack.pop()
        took = time.perf_counter() - t0
        passes[ev.data["name"]] += took - nested
        if self.stack:
            self.stack[-1][1] += took

def _add(dt):
    llvm[0] += dt

mod = importlib.import_module(module)
default = {"float64": "sim.flight.engines._numba", "float32": "sim.flight.engines._numba_f32"}[precision]
sys.modules[default] = mod  # simulate imports its runner from here
compiled = []
def _compile(dispatcher, args):
    sig = tuple(dispatcher.typeof_pyval(a) for a in args)
    if sig not in dispatcher.overloads:
        compiled.append(str(sig)[:80])
        dispatcher.compile(sig)
mod._cached_machine_code = _compile
from sim.flight import TrackingReference, simulate
ref = TrackingReference.hover(np.zeros((1, 3)))
imp_wall, imp_cpu = time.perf_counter() - t0_wall, time.process_time() - t0_cpu
with event.install_timer("numba:llvm_lock", _add), event.install_listener("numba:run_pass", _Passes()):
    c_wall, c_cpu = time.perf_counter(), time.process_time()
    simulate(ref, duration_s=0.002, engine="numba", output_every=1, precision=precision)
    c_wall, c_cpu = time.perf_counter() - c_wall, time.process_time() - c_cpu
ru = resource.getrusage(resource.RUSAGE_SELF)
top = sorted(passes.items(), key=lambda kv: -kv[1])[:12]
print(json.dumps({"module": module, "compiled": compiled, "compile_wall_s": c_wall, "compile_cpu_s": c_cpu,
                  "import_cpu_s": imp_cpu, "llvm_s": llvm[0],
                  "passes_total_s": sum(passes.values()), "numba_passes_s": {k: round(v, 1) for k, v in top},
                  "maxrss_mib": ru.ru_maxrss / 1024}))
"""


def measure(precision: str, module: str | None = None, keep: str | None = None) -> dict[str, object]:
    """One cold compile of ``precision``'s kernel (or ``module``'s) in a child process on an empty cache."""
    module = module or MODULES[precision]
    with tempfile.TemporaryDirectory(prefix="kernel-compile-") as tmp:
        cache = keep or tmp
        if keep and any(Path(keep).rglob("*.nbi")):
            raise SystemExit(f"--keep {keep}: not empty")
        env = dict(os.environ, NUMBA_CACHE_DIR=cache,
                   PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", _CHILD, precision, module], env=env, cwd=ROOT,
                             capture_output=True, text=True, timeout=3600, check=False)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if out.returncode != 0:
            raise SystemExit(out.stderr[-4000:])
        fig: dict[str, object] = json.loads(out.stdout.strip().splitlines()[-1])
        fig.update(precision=precision, process_wall_s=wall,
                   process_cpu_s=(after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
                   process_maxrss_mib=after.ru_maxrss / 1024)
        return fig


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("precisions", nargs="+", choices=sorted(MODULES))
    ap.add_argument("--module", default=None)
    ap.add_argument("--keep", default=None)
    a = ap.parse_args()
    for p in a.precisions:
        fig = measure(p, a.module, a.keep)
        print(json.dumps({k: (round(v, 1) if isinstance(v, float) else v) for k, v in fig.items()}), flush=True)


if __name__ == "__main__":
    main()
