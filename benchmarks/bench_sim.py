"""Flight-simulation benchmarks (issue 4): ``make bench`` or ``pytest -m slow benchmarks/bench_sim.py``.

Figures: drone-steps per second (one drone advanced by one 1 ms step with the full ISMC
controllers and the rigid-body dynamics) of the numba kernel and of the numpy reference
in the same run, and the wall time of a whole 1000-drone show flight.
"""

from __future__ import annotations

import argparse
import functools
import re
import time

import numpy as np
import pytest

from app.cli._bench import BENCH_KINDS

pytestmark = pytest.mark.slow

#: Target of issue 4 on the 2-core reference machine.
TARGET_DRONE_STEPS_PER_S = 20e6


@pytest.mark.parametrize("n", [2000, 10000])
def test_bench_sim_engines(n: int, record_result) -> None:
    """numba vs numpy drone-steps/s at n drones (numba 5 simulated s, numpy 0.2 s)."""
    run = BENCH_KINDS["sim"][2]
    fig = run(argparse.Namespace(drones=n, seconds=5.0, numpy_seconds=0.2))
    fig["target_drone_steps_per_s"] = TARGET_DRONE_STEPS_PER_S
    fig["ratio_to_target"] = fig["drone_steps_per_s"] / TARGET_DRONE_STEPS_PER_S
    record_result(fig)
    assert fig["numba"]["diverged"] == 0 and fig["numpy"]["diverged"] == 0
    assert fig["speedup"] > 5.0


def test_bench_fly_show_1000_drones(record_result) -> None:
    """Plan and fly a 1000-drone show (two spheres) at 1 kHz, 25 Hz output."""
    from formations import parse_show
    from sim import plan_show
    from sim.flight import fly_show

    def sphere(n: int, radius_m: float, center: tuple[float, float, float]) -> list[list[float]]:
        i = np.arange(n) + 0.5
        phi, theta = np.arccos(1 - 2 * i / n), np.pi * (1 + 5**0.5) * i
        pts = np.c_[np.cos(theta) * np.sin(phi), np.sin(theta) * np.sin(phi), np.cos(phi)] * radius_m + center
        return np.round(pts, 6).tolist()

    show = parse_show({
        "format": "swarmshow/1", "name": "bench", "drones": 1000,
        "home": {"grid": {"rows": 25, "cols": 40, "spacing_m": 4.5}},
        "settings": {"max_speed_z_mps": 5.0},
        "formations": [
            {"name": "big sphere", "hold_s": 10.0, "points": sphere(1000, 60.0, (0.0, 0.0, 80.0)),
             "color": "#ff0000"},
            {"name": "small sphere", "hold_s": 10.0, "points": sphere(1000, 45.0, (20.0, 0.0, 70.0)),
             "color": "#00ff00"},
        ],
    })
    plan = plan_show(show)
    start = time.perf_counter()
    res = fly_show(plan)
    wall = time.perf_counter() - start
    s = res.summary()
    fig = {
        "drones": 1000,
        "show_duration_s": plan.duration_s,
        "fly_wall_s": wall,
        "drone_steps_per_s": s["drone_steps_per_s"],
        "tracking_max_m": s["tracking_max_m"],
        "flown_min_distance_m": s["flown_min_distance_m"],
        "diverged": len(res.diverged),
        "frames": int(res.times_s.size),
        "positions_mb": res.positions_m.nbytes / 1e6,
        "seconds_per_show_minute": wall / (plan.duration_s / 60.0),
    }
    record_result(fig)
    assert fig["diverged"] == 0 and np.isfinite(fig["flown_min_distance_m"])


def test_bench_sim_error_models(record_result) -> None:
    """numba drone-steps/s with the "gusty-rtk" error models on against ideal drones, same run (issue 20)."""
    from sim.flight import TrackingReference, error_preset, simulate

    n, seconds = 4000, 2.0
    rng = np.random.default_rng(0)
    centers = rng.uniform(-200.0, 200.0, (n, 3)) + [0.0, 0.0, 60.0]
    ref = TrackingReference.circle(centers, radius_m=3.0, omega_rad_s=0.5)
    figures: dict[str, float] = {}
    for name in ("ideal", "gusty-rtk"):
        errors = error_preset(name)
        simulate(ref.subset(np.arange(8)), duration_s=0.01, engine="numba", errors=errors)  # compile
        best = 0.0
        for _ in range(3):
            start = time.perf_counter()
            res = simulate(ref, duration_s=seconds, engine="numba", output_every=40, errors=errors)
            best = max(best, n * (int(round(seconds / 1e-3)) + 1) / (time.perf_counter() - start))
            assert res.diverged() == []
        figures[f"{name}_drone_steps_per_s"] = best
    figures["errors_over_ideal"] = figures["gusty-rtk_drone_steps_per_s"] / figures["ideal_drone_steps_per_s"]
    record_result(figures)


def _rate(ref, n: int, seconds: float, engine: str, errors, **kw) -> tuple[float, float]:
    """(drone-steps per wall second, per CPU second) of one run; CPU time because the machine is shared.
    ``kw``: more of ``simulate``'s arguments (``precision``, ``gains``)."""
    from sim.flight import simulate

    wall, cpu = time.perf_counter(), time.process_time()
    res = simulate(ref, duration_s=seconds, engine=engine, output_every=40, errors=errors, **kw)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    assert res.diverged() == []
    steps = n * (int(round(seconds / 1e-3)) + 1)
    return steps / wall, steps / cpu


def _peak_packed_fma_flops() -> tuple[float, float]:
    """Measured peak of packed double FMAs on every core: (flop per wall s, per CPU s) of a tiny numba loop.

    64 lanes held in L1, eight chained FMAs per lane and pass: LLVM vectorises the lane
    loop, and the eight independent vectors keep both FMA pipes busy.
    """
    import numba as nb

    # FMA contraction only: with reassociation LLVM folds the chain of FMAs into fewer ops.
    @nb.njit(parallel=True, fastmath={"contract"})
    def peak(reps: int, out: np.ndarray) -> None:
        for tno in nb.prange(out.size):
            acc = np.empty(64)
            for lane in range(64):
                acc[lane] = 1.0 + lane * 1e-3
            m, c = 0.999999, 1e-7
            for _ in range(reps):
                for lane in range(64):
                    x = acc[lane]
                    x = x * m + c
                    x = x * m + c
                    x = x * m + c
                    x = x * m + c
                    x = x * m + c
                    x = x * m + c
                    x = x * m + c
                    x = x * m + c
                    acc[lane] = x
            out[tno] = acc.sum()

    out = np.zeros(nb.get_num_threads())
    peak(10, out)
    reps, best, best_cpu = 1_000_000, 0.0, 0.0
    for _ in range(3):
        wall, cpu = time.perf_counter(), time.process_time()
        peak(reps, out)
        flops = out.size * reps * 64 * 8 * 2
        best = max(best, flops / (time.perf_counter() - wall))
        best_cpu = max(best_cpu, flops / (time.process_time() - cpu))
    return best, best_cpu


_PACKED_ARITH = re.compile(r"^\s*(v(?:fn?m(?:add|sub)\w*|add|sub|mul|div|sqrt)pd)\s[^\n]*%([yz])mm", re.M)


@functools.cache
def _kernel_lane_asm() -> str:
    """The machine code of the flight kernel, compiled afresh once per session (numba does not
    disassemble cached code)."""
    import numba as nb

    import sim.flight.engines._numba as kernel_module
    from sim.flight import TrackingReference, error_preset, simulate

    fresh = nb.njit(parallel=True, error_model="numpy", fastmath={"nsz", "afn", "contract", "reassoc"})(
        kernel_module._kernel.py_func)
    saved = kernel_module._kernel
    kernel_module._kernel = fresh
    try:
        simulate(TrackingReference.hover(np.zeros((2, 3))), duration_s=0.002, engine="numba",
                 errors=error_preset("gusty-rtk"))
    finally:
        kernel_module._kernel = saved
    asm: str = fresh.inspect_asm(fresh.signatures[0])
    return asm


def _flops_per_drone_step(asm: str) -> tuple[float, int]:
    """(flops per drone-step of the vectorised lane loop, vector copies of it) from its packed instructions.

    Each packed add/sub/mul/div/sqrt is one flop per lane and each FMA two; the loop body
    holds ``copies`` interleaved copies of the step (the lane loop has 10 roundings per
    step: 3 sin/cos reductions with their quadrant, 4 exp reductions), so one drone-step
    is the sum over lanes divided by the lanes per instruction and the copies.
    """
    flops = 0.0
    for name, _ in _PACKED_ARITH.findall(asm):
        flops += 2.0 if name.startswith("vf") else 1.0
    copies = max(len(re.findall(r"vrndscalepd\s[^\n]*%[yz]mm", asm)) // 10, 1)
    return flops / copies, copies


def _lane_loop_body(asm: str) -> list[str]:
    """The instructions of the lane loop: the innermost loop holding most of the packed (zmm/ymm) code.

    Loops are found by their backward jumps; the step loop and the block loop contain the lane
    loop, so the shortest loop with at least 80 % of the largest packed count is the lane loop
    (its latch: the last backward jump to its header). With 8 lanes (one AVX-512 vector) LLVM
    knows the trip count from the scratch's size and the lane loop is a single straight pass,
    so the loop found is the step loop: its counts then include the per-step scalar parts
    (piece search, table rows), which branches skip on most steps; the packed counts are the
    lane step's.
    """
    lines = asm.splitlines()
    labels = {m.group(1): i for i, line in enumerate(lines) if (m := re.match(r"^(\.LBB\S+):", line))}
    latch: dict[str, int] = {}
    for i, line in enumerate(lines):
        m = re.match(r"\s+j\w+\s+(\.LBB\S+)", line)
        if m and labels.get(m.group(1), i) < i:
            latch[m.group(1)] = i
    loops = []
    for label, end in latch.items():
        body = [x.strip() for x in lines[labels[label]:end + 1] if x.startswith("\t") and not x.strip().startswith(".")]
        loops.append((end - labels[label], sum(re.search(r"%[yz]mm", x) is not None for x in body), body))
    if not loops:
        return []
    most = max(packed for _, packed, _ in loops)
    return min((lp for lp in loops if lp[1] >= 0.8 * most), key=lambda lp: lp[0])[2]


def lane_loop_profile(asm: str) -> dict[str, int]:
    """Instruction mix of one pass of the vectorised lane loop (one vector of drones per copy of the step).

    Classes, as Zen 4 executes them: ``fma_pipe`` the packed multiplies and FMAs (only two of
    the four FP pipes take them: with 512-bit operands one per cycle, what the peak-FMA
    microbenchmark measures), ``fp_other`` every other packed floating-point operation that is
    not a plain move (add, compare, min/max, blend, logic, rounding, conversion; the other
    pipes), ``divider`` the divisions and square roots (counted in ``fp_other`` too; one unit,
    not pipelined like the FMA pipes); ``stack`` the loads and stores of the stack frame
    (register spills and reloads: ``(%rsp)`` operands); ``memory`` every other load or store
    (the scratch, the tables, broadcast constants, the masked commits).
    """
    body = _lane_loop_body(asm)
    prof = {"instructions": len(body), "fma_pipe": 0, "fp_other": 0, "divider": 0, "stack": 0, "memory": 0}
    for ins in body:
        op = ins.split()[0]
        mem = "(" in ins and not op.startswith(("lea", "j", "prefetch"))
        if mem:
            prof["stack" if "(%rsp)" in ins else "memory"] += 1
        if re.search(r"%[yz]mm", ins) is None or not op.startswith("v"):
            continue
        if op.startswith(("vmov", "vbroadcast", "vpbroadcast")) and (mem or "{%k" not in ins):
            continue  # a load, a store or a register copy (a masked register move is a select: FP)
        if re.match(r"vf\w*m(add|sub)|vmul", op):
            prof["fma_pipe"] += 1
        else:
            prof["fp_other"] += 1
            prof["divider"] += op.startswith(("vdiv", "vsqrt"))
    return prof


def lane_step_blocks(asm: str) -> list[str]:
    """The lane step's straight vector code: the basic blocks of :func:`_lane_loop_body`'s loop that are
    longer than 40 instructions and mostly packed (zmm/ymm), jumps left out, in program order.

    With 8 lanes the step loop's body also holds the scalar piece search, GNSS and wind-row
    loads and frame stores, which branches skip on most steps; these blocks are what every
    step runs (plus the GNSS epoch's innovation block, one step in 100, which is kept: it is
    small).
    """
    body = _lane_loop_body(asm)
    lines = asm.splitlines()
    ins = [(i, x.strip()) for i, x in enumerate(lines) if x.startswith("\t") and not x.strip().startswith(".")]
    txt = [t for _, t in ins]
    start = next(ins[k][0] for k in range(len(txt)) if txt[k:k + 30] == body[:30])
    blocks: list[list[str]] = [[]]
    done, i = 0, start
    while done < len(body) and i < len(lines):
        line = lines[i]
        if re.match(r"^\.LBB", line):
            blocks.append([])
        elif line.startswith("\t") and not line.strip().startswith("."):
            done += 1
            if not line.strip().startswith("j"):
                blocks[-1].append(line.strip())
        i += 1
    return [x for b in blocks if len(b) > 40 and sum(re.search(r"%[yz]mm", y) is not None for y in b) > 0.6 * len(b)
            for x in b]


def mca_lane_step(asm: str, mcpu: str = "icelake-server") -> dict[str, float | str] | None:
    """llvm-mca's timing of one lane step (:func:`lane_step_blocks`), or None without llvm-mca.

    ``cycles``: one step simulated alone (dispatch in program order, the model's reorder
    buffer and its latencies: what a real core does with one block's step); ``throughput``:
    the cycles the step's instructions need on the model's ports alone (``Block RThroughput``).
    Their ratio says whether the step waits on its dependency chains (large) or its ports (~1).
    LLVM 14's llvm-mca has no Zen 4 model; Ice Lake's is the nearest with AVX-512 (similar
    latencies; two 512-bit FMA ports where Zen 4 issues one 512-bit FMA per cycle).
    """
    import shutil
    import subprocess
    import tempfile

    exe = shutil.which("llvm-mca")
    if exe is None:
        return None
    with tempfile.NamedTemporaryFile("w", suffix=".s") as f:
        f.write("\n".join(lane_step_blocks(asm)) + "\n")
        f.flush()
        out = subprocess.run([exe, f"-mcpu={mcpu}", "-iterations=1", f.name], capture_output=True, text=True,
                             timeout=300, check=False).stdout
    cycles = re.search(r"Total Cycles:\s+(\d+)", out)
    rthr = re.search(r"Block RThroughput:\s+([\d.]+)", out)
    n = re.search(r"Instructions:\s+(\d+)", out)
    if cycles is None or rthr is None or n is None:
        return None
    return {"instructions": float(n.group(1)), "cycles": float(cycles.group(1)), "throughput": float(rthr.group(1)),
            "mcpu": mcpu}


def test_kernel_lane_loop_is_vectorised() -> None:
    """The lane loop compiles to packed (ymm/zmm) arithmetic: a libm call or a branch that stops the
    vectoriser would leave it scalar (issue 20 item 6). Slow: compiles the kernel afresh (~1 min)."""
    asm = _kernel_lane_asm()
    packed = len(_PACKED_ARITH.findall(asm))
    rounds = len(re.findall(r"vrndscalepd\s[^\n]*%[yz]mm", asm))
    # ~400 flops per drone-step: at least 300 packed arithmetic instructions and the 10
    # vector roundings of the sin/cos and exp reductions.
    assert packed >= 300, packed
    assert rounds >= 10, rounds


def test_bench_kernel_against_numpy_with_error_models(record_result) -> None:
    """Lane kernel vs the numpy reference step, "gusty-rtk" on, 4,000 drones, same run (issue 20 item 6).

    Also the ratio to a measured vector ceiling: the peak packed-FMA flop rate of this
    machine (``_peak_packed_fma_flops``) divided by the kernel's own flops per drone-step
    (counted from its vectorised machine code), i.e. the drone-steps/s the same arithmetic
    would reach if every instruction were a full-width FMA issued at peak. Per CPU second
    as well: the shared machine's load moves the wall-clock peak as much as the kernel.
    And the tighter bound of the machine code as it is: its multiplies and FMAs alone at the
    peak FMA instruction rate (``lane_loop_profile``; the adds, compares and selects run on the
    other pipes, the loads and stores on the load/store units).

    CPU time as well as wall time: the machine is shared with other jobs, so the wall
    ratio moves with their load; per CPU second the numba kernel (2 threads) is compared
    with numpy's (mostly single-threaded) work, which understates the wall-clock speed-up
    on an idle machine by up to the thread count.
    """
    from sim.flight import IsmcGains, TrackingReference, error_preset, simulate

    n = 4000
    rng = np.random.default_rng(0)
    centers = rng.uniform(-200.0, 200.0, (n, 3)) + [0.0, 0.0, 60.0]
    ref = TrackingReference.circle(centers, radius_m=3.0, omega_rad_s=0.5)
    errors = error_preset("gusty-rtk")
    single_rate = IsmcGains(position_rate_hz=None)  # every loop at 1 kHz, as before position_rate_hz
    for p in ("float64", "float32"):  # compile or load
        simulate(ref.subset(np.arange(8)), duration_s=0.01, engine="numba", errors=errors, precision=p)
    # The variants in turns (three rounds, the best of each): the default gains (position loop at
    # 250 Hz) in float64 and float32, and every loop at 1 kHz in float64.
    runs: dict[str, list[tuple[float, float]]] = {"f64": [], "f32": [], "f64_1khz": []}
    for _ in range(3):
        runs["f64"].append(_rate(ref, n, 1.0, "numba", errors))
        runs["f32"].append(_rate(ref, n, 1.0, "numba", errors, precision="float32"))
        runs["f64_1khz"].append(_rate(ref, n, 1.0, "numba", errors, gains=single_rate))
    numba_wall, numba_cpu = max(runs["f64"])
    f32_wall, f32_cpu = max(runs["f32"])
    khz_wall, khz_cpu = max(runs["f64_1khz"])
    numpy_wall, numpy_cpu = _rate(ref, n, 0.05, "numpy", errors)
    peak, peak_cpu = _peak_packed_fma_flops()
    # With the outer loop at its own rate the kernel holds two lane bodies (the full step and the
    # inner-only one, ``_numba._lane_step``): this counts both, i.e. a full step plus an inner one.
    flops, copies = _flops_per_drone_step(_kernel_lane_asm())
    ceiling, ceiling_cpu = peak / flops, peak_cpu / flops
    # The bound of this machine code on the FMA pipes alone: the peak FMA instruction rate over the
    # lane loop's multiplies and FMAs per drone-step (peak flops = FMA instructions x 2 x lanes, and a
    # pass of the loop is ``copies`` x lanes drone-steps, so the lane width cancels).
    prof = lane_loop_profile(_kernel_lane_asm())
    fma_ceiling = peak * copies / (2.0 * prof["fma_pipe"])
    fig: dict[str, object] = {
        "drones": n, "preset": "gusty-rtk",
        "numba_drone_steps_per_wall_s": numba_wall, "numba_drone_steps_per_cpu_s": numba_cpu,
        "numpy_drone_steps_per_wall_s": numpy_wall, "numpy_drone_steps_per_cpu_s": numpy_cpu,
        "speedup_wall": numba_wall / numpy_wall, "speedup_cpu": numba_cpu / numpy_cpu,
        "peak_packed_fma_flops_per_s": peak, "kernel_flops_per_drone_step": flops, "vector_copies": copies,
        "peak_packed_fma_flops_per_cpu_s": peak_cpu,
        "vector_ceiling_drone_steps_per_s": ceiling, "ratio_to_vector_ceiling": numba_wall / ceiling,
        "vector_ceiling_drone_steps_per_cpu_s": ceiling_cpu, "ratio_to_vector_ceiling_cpu": numba_cpu / ceiling_cpu,
        "lane_loop_profile": prof, "fma_pipe_ceiling_drone_steps_per_s": fma_ceiling,
        "llvm_mca_lane_step": mca_lane_step(_kernel_lane_asm()),
        "ratio_to_fma_pipe_ceiling": numba_wall / fma_ceiling,
        "target_drone_steps_per_s": 5e7, "target_speedup": 35.0,
        "outer_every_steps": IsmcGains().outer_every(1e-3),  # the default position loop: every 4 ms
        "float32_drone_steps_per_wall_s": f32_wall, "float32_drone_steps_per_cpu_s": f32_cpu,
        "float64_meets_target": numba_wall >= 5e7, "float32_meets_target": f32_wall >= 5e7,
        "float32_speedup_wall": f32_wall / numpy_wall, "float32_ratio_to_vector_ceiling": f32_wall / ceiling,
        "single_rate_drone_steps_per_wall_s": khz_wall, "single_rate_drone_steps_per_cpu_s": khz_cpu,
        "multirate_gain_wall": numba_wall / khz_wall, "multirate_gain_cpu": numba_cpu / khz_cpu,
    }
    record_result(fig)
    assert numba_wall / numpy_wall > 5.0


def test_bench_colours_skipped_in_monte_carlo_runs(record_result) -> None:
    """fly_show with and without the LED colours (FlightOptions.colors), CPU time, same run (issue 20)."""
    from sim import plan_show
    from sim.bench._shows import benchmark_show
    from sim.flight import FlightOptions, error_preset, fly_show

    plan = plan_show(benchmark_show(500, formations=3))
    opts = FlightOptions(errors=error_preset("gusty-rtk"), flown_distance=False)
    fly_show(plan, opts.with_(colors=False))  # compile and warm
    cpu: dict[str, float] = {}
    for colors in (True, False, True, False):
        start = time.process_time()
        fly_show(plan, opts.with_(colors=colors))
        key = "with_colours_cpu_s" if colors else "without_colours_cpu_s"
        cpu[key] = min(cpu.get(key, float("inf")), time.process_time() - start)
    fig = {**cpu, "drones": plan.drone_count, "saved_fraction": 1.0 - cpu["without_colours_cpu_s"]
           / cpu["with_colours_cpu_s"]}
    record_result(fig)
    assert fig["saved_fraction"] > 0.0
