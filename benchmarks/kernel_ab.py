"""Two versions of a flight kernel module in ONE process: speed ratio and bit-identity.

Flies the same 4,000-drone gusty-rtk flight (0.3 s, as ``bench_precision``) with kernel module A and
kernel module B in alternating single-thread rounds (``numba.set_num_threads(1)``), timing the
kernel's own CPU time, and checks that both give bit-identical results (positions, final state,
statistics; and telemetry on a smaller flight). B is a copy of another version of the kernel kept
beside it in the same checkout (e.g. main's ``_numba.py`` copied to ``_numba_base.py``, whose
``_numba_f32`` copy imports its helpers from it), so both are compiled into (or loaded from) the same
``NUMBA_CACHE_DIR``:

    .venv/bin/python -m benchmarks.kernel_ab float64 sim.flight.engines._numba sim.flight.engines._numba_base

Prints the rate ratio A/B per round and its median (> 1: A faster).
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys
import time
from typing import Any

import numpy as np

DEFAULT = {"float64": "sim.flight.engines._numba", "float32": "sim.flight.engines._numba_f32"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("precision", choices=sorted(DEFAULT))
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--rounds", type=int, default=6)
    ap.add_argument("--drones", type=int, default=4000)
    args = ap.parse_args()

    import numba

    from sim.flight import TrackingReference, error_preset, simulate

    mods = {"a": importlib.import_module(args.a), "b": importlib.import_module(args.b)}
    p, n = args.precision, args.drones
    rng = np.random.default_rng(0)
    ref = TrackingReference.circle(rng.uniform(-200.0, 200.0, (n, 3)) + [0.0, 0.0, 60.0], radius_m=3.0,
                                   omega_rad_s=0.5)
    errors = error_preset("gusty-rtk")
    spent = [0.0]

    def fly(which: str, timed: bool, **kw: Any) -> Any:
        mod = mods[which]
        sys.modules[DEFAULT[p]] = mod  # simulate imports its runner from there
        kernel = mod._kernel

        def run(*a: Any) -> None:
            start = time.process_time()
            kernel(*a)
            spent[0] += time.process_time() - start

        if timed:
            mod._kernel = run
        spent[0] = 0.0
        try:
            return simulate(errors=errors, engine="numba", precision=p, **kw)
        finally:
            mod._kernel = kernel

    def same(x: Any, y: Any) -> bool:
        return all(np.array_equal(getattr(x, f), getattr(y, f), equal_nan=True) for f in
                   ("positions_m", "final_state", "rms_error_m", "max_error_m", "max_thrust_step_n",
                    "diverged_step"))

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    rates: dict[str, list[float]] = {"a": [], "b": []}
    identical = True
    try:
        small = ref.subset(np.arange(64))
        t = {w: fly(w, False, reference=small, duration_s=1.0, telemetry=True, output_every=10) for w in mods}
        tel_identical = same(t["a"], t["b"]) and np.array_equal(t["a"].telemetry, t["b"].telemetry, equal_nan=True)
        for r in range(args.rounds):
            order = ("a", "b") if r % 2 == 0 else ("b", "a")
            res = {}
            for w in order:
                res[w] = fly(w, True, reference=ref, duration_s=0.3, output_every=40)
                rates[w].append(n * 301 / spent[0])
            identical = identical and same(res["a"], res["b"])
            print(f"round {r}: a/b {rates['a'][-1] / rates['b'][-1]:.3f}", flush=True)
    finally:
        numba.set_num_threads(threads)
    ratio = np.array(rates["a"]) / np.array(rates["b"])
    print(json.dumps({"precision": p, "a": args.a, "b": args.b, "drones": n, "rounds": args.rounds,
                      "a_drone_steps_per_cpu_s": float(np.median(rates["a"])),
                      "b_drone_steps_per_cpu_s": float(np.median(rates["b"])),
                      "ratio_median": round(float(np.median(ratio)), 3), "ratio_min": round(float(ratio.min()), 3),
                      "ratio_max": round(float(ratio.max()), 3), "bit_identical": identical,
                      "telemetry_flight_bit_identical": tel_identical}))


if __name__ == "__main__":
    main()
