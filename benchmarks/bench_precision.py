"""The float32-controller kernel against the float64 one (issue 20 item 6): speed in one run, machine code.

Both kernels fly the same 4,000-drone gusty-rtk flight in alternating rounds in one process,
single-threaded (``numba.set_num_threads(1)``), timed by the kernel's own CPU time (the machine is
shared: only a ratio measured this way means anything). Slow: the machine-code check compiles
the float32 kernel afresh (~1-2 min).
"""

from __future__ import annotations

import re
import time
from typing import Any

import numpy as np
import pytest

from benchmarks.bench_sim import _lane_loop_body, lane_loop_profile

pytestmark = pytest.mark.slow

_PACKED_PS = re.compile(r"^\s*v(?:fn?m(?:add|sub)\w*|add|sub|mul|div|sqrt|min|max)ps\s[^\n]*%[yz]mm", re.M)
_PACKED_PD = re.compile(r"^\s*v(?:fn?m(?:add|sub)\w*|add|sub|mul|div|sqrt|min|max)pd\s[^\n]*%[yz]mm", re.M)


def _f32_kernel_asm() -> str:
    """The float32 kernel's machine code, compiled afresh (numba does not disassemble cached code)."""
    import numba as nb

    import sim.flight.engines._numba_f32 as kernel_module
    from sim.flight import TrackingReference, error_preset, simulate

    fresh = nb.njit(parallel=True, error_model="numpy", fastmath={"nsz", "afn", "contract", "reassoc"})(
        kernel_module._kernel.py_func)
    saved = kernel_module._kernel
    kernel_module._kernel = fresh
    try:
        simulate(TrackingReference.hover(np.zeros((2, 3))), duration_s=0.002, engine="numba",
                 errors=error_preset("gusty-rtk"), precision="float32")
    finally:
        kernel_module._kernel = saved
    asm: str = fresh.inspect_asm(fresh.signatures[0])
    return asm


def test_f32_kernel_lane_loop_is_packed_single(record_result) -> None:
    """The control laws compile to packed single-precision arithmetic (a float64 literal would promote
    them to ``...pd``); the float64 plant and integrators stay packed double."""
    asm = _f32_kernel_asm()
    body = "\n".join(_lane_loop_body(asm))
    ps, pd = len(_PACKED_PS.findall(body)), len(_PACKED_PD.findall(body))
    cvt = len(re.findall(r"vcvt(?:pd2ps|ps2pd)", body))
    fig = {"packed_single_arith": ps, "packed_double_arith": pd, "float_conversions": cvt,
           "lane_loop_profile": lane_loop_profile(asm)}
    record_result(fig)
    assert ps >= 500 and ps > pd, fig
    assert cvt < 200, fig  # conversions only where float64 and float32 meet (~90 per 8 drones)


def test_bench_kernel_float32_against_float64(record_result) -> None:
    """Kernel CPU time of the two precisions, alternating rounds in one process (issue 20 item 6)."""
    import numba

    import sim.flight.engines._numba as k64
    import sim.flight.engines._numba_f32 as k32
    from sim.flight import IsmcGains, TrackingReference, error_preset, simulate

    n, rounds = 4000, 6
    rng = np.random.default_rng(0)
    ref = TrackingReference.circle(rng.uniform(-200.0, 200.0, (n, 3)) + [0.0, 0.0, 60.0], radius_m=3.0,
                                   omega_rad_s=0.5)
    errors = error_preset("gusty-rtk")
    spent = [0.0]
    saved = {"float64": k64._kernel, "float32": k32._kernel}
    modules: dict[str, Any] = {"float64": k64, "float32": k32}

    def timed(kernel):  # type: ignore[no-untyped-def]
        def run(*args):  # type: ignore[no-untyped-def]
            start = time.process_time()
            kernel(*args)
            spent[0] += time.process_time() - start
        return run

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    # Each precision at the default outer-loop rate (250 Hz) and with every loop at 1 kHz.
    variants = {"float64": ("float64", None), "float32": ("float32", None),
                "float64_1khz": ("float64", IsmcGains(position_rate_hz=None)),
                "float32_1khz": ("float32", IsmcGains(position_rate_hz=None))}
    rates: dict[str, list[float]] = {v: [] for v in variants}
    try:
        for p in modules:  # compile or load
            simulate(ref.subset(np.arange(8)), duration_s=0.01, engine="numba", errors=errors, precision=p)
        for _ in range(rounds):
            for v, (p, gains) in variants.items():
                mod = modules[p]
                mod._kernel = timed(saved[p])
                spent[0] = 0.0
                try:
                    simulate(ref, duration_s=0.3, engine="numba", output_every=40, errors=errors, precision=p,
                             gains=gains)
                finally:
                    mod._kernel = saved[p]
                rates[v].append(n * 301 / spent[0])
    finally:
        numba.set_num_threads(threads)
    ratio = np.array(rates["float32"]) / np.array(rates["float64"])
    fig: dict[str, Any] = {"drones": n, "preset": "gusty-rtk", "rounds": rounds, "threads": 1,
           "float64_drone_steps_per_cpu_s": float(np.median(rates["float64"])),
           "float32_drone_steps_per_cpu_s": float(np.median(rates["float32"])),
           "ratio_median": float(np.median(ratio)), "ratio_min": float(ratio.min()), "ratio_max": float(ratio.max())}
    base = np.array(rates["float64_1khz"])
    for v in ("float64", "float32", "float32_1khz"):  # against float64 with every loop at 1 kHz
        r = np.array(rates[v]) / base
        fig[f"{v}_over_float64_1khz_median"] = float(np.median(r))
        fig[f"{v}_over_float64_1khz_range"] = [float(r.min()), float(r.max())]
    record_result(fig)
    assert fig["ratio_median"] > 1.1
