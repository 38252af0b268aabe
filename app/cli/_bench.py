"""``swarmshow bench KIND``: measure the speed of a pipeline stage on synthetic drones.

Kinds live in ``BENCH_KINDS`` (name -> (help, add_arguments, run)); a kind's ``run``
returns a JSON-safe dict. ``plan`` and ``check``: see :mod:`sim.bench._shows`.
``sim``: the flight engines, numba and the numpy reference in
the same run, in drone-steps per second (one drone advanced by one 1 ms control step
with the full controller and dynamics).
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections.abc import Callable

from app.cli._common import EXIT_OK, CliError, print_json


def _sim_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--seconds", type=float, default=2.0,
                   help="simulated seconds for the numba engine (default 2)")
    p.add_argument("--numpy-seconds", type=float, default=None,
                   help="simulated seconds for the numpy reference (default min(seconds, 0.2))")


def _bench_sim(args: argparse.Namespace) -> dict:
    import numpy as np

    from sim.flight import TrackingReference, simulate

    n = int(args.drones)
    if n < 1:
        raise CliError(f"--drones must be >= 1, got {n}")
    if not args.seconds > 0:
        raise CliError(f"--seconds must be > 0, got {args.seconds}")
    np_seconds = min(args.seconds, 0.2) if args.numpy_seconds is None else float(args.numpy_seconds)
    # Drones on a 3 m grid, each flying a 2 m circle at 1 rad/s (a show-like load: full
    # controller, non-trivial reference, no drone at rest).
    side = int(np.ceil(np.sqrt(n)))
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side), indexing="ij"), -1).reshape(-1, 2)[:n]
    centers = np.c_[3.0 * grid, np.full(n, 30.0)]
    ref = TrackingReference.circle(centers, radius_m=2.0, omega_rad_s=1.0)

    # float32 frames, as a flown show records them (sim.flight._runner.fly_local): the frames' dtype
    # is part of the kernel's numba signature, and float64 frames made this command compile (minutes
    # of CPU on a cache that show flights had filled) a specialisation no show flight runs.
    def frames(seconds: float, drones: int) -> np.ndarray:
        return np.zeros(((int(round(seconds / 1e-3))) // 40 + 1, drones, 3), np.float32)

    def rate(engine: str, seconds: float) -> dict:
        steps = int(round(seconds / 1e-3)) + 1
        start, cpu0 = time.perf_counter(), time.process_time()
        res = simulate(ref, duration_s=seconds, engine=engine, output_every=40, frames_out=frames(seconds, n))
        wall, cpu = time.perf_counter() - start, time.process_time() - cpu0
        # Per CPU-second (all threads) as well: on a shared machine the wall-clock
        # rate drops with the other load, the CPU-time rate shows the code's own cost.
        return {"engine": engine, "drones": n, "simulated_s": seconds, "wall_s": wall, "cpu_s": cpu,
                "drone_steps_per_s": n * steps / wall, "drone_steps_per_cpu_s": n * steps / cpu,
                "diverged": len(res.diverged())}

    t0 = time.perf_counter()
    # Compile or load the cache (the kernel show flights run).
    simulate(ref.subset(slice(0, 1)), duration_s=0.002, engine="numba", frames_out=frames(0.002, 1))
    compile_s = time.perf_counter() - t0
    fast = rate("numba", float(args.seconds))
    ref_run = rate("numpy", np_seconds)
    return {
        "kind": "sim",
        "drones": n,
        "numba": fast,
        "numpy": ref_run,
        "drone_steps_per_s": fast["drone_steps_per_s"],
        "numpy_drone_steps_per_s": ref_run["drone_steps_per_s"],
        "speedup": fast["drone_steps_per_s"] / ref_run["drone_steps_per_s"],
        "numba_compile_or_cache_load_s": compile_s,
        "threads": _threads(),
        "load_average_1min": os.getloadavg()[0],
        "cpus": os.cpu_count(),
        "machine": platform.machine(),
    }


def _threads() -> int:
    import numba

    return int(numba.get_num_threads())


def _format_sim(r: dict) -> str:
    return "\n".join([
        f"bench sim: {r['drones']} drones, full ISMC + rigid-body step at 1 kHz ({r['threads']} threads, "
        f"{r['cpus']} CPUs)",
        f"  numba  {r['drone_steps_per_s'] / 1e6:8.2f} M drone-steps/s  ({r['numba']['simulated_s']:g} s "
        f"simulated in {r['numba']['wall_s']:.2f} s)",
        f"  numpy  {r['numpy_drone_steps_per_s'] / 1e6:8.2f} M drone-steps/s  ({r['numpy']['simulated_s']:g} s "
        f"simulated in {r['numpy']['wall_s']:.2f} s)",
        f"  speedup {r['speedup']:.1f}x; numba {r['numba']['drone_steps_per_cpu_s'] / 1e6:.2f} M per CPU-second "
        f"(load average {r['load_average_1min']:.1f})",
    ])


def _no_args(p: argparse.ArgumentParser) -> None:
    del p  # plan and check take only the common --drones / --json


def _check_drones(args: argparse.Namespace) -> int:
    n = int(args.drones)
    if not 2 <= n <= 20_000:
        raise CliError(f"--drones must be in [2, 20000], got {n}")
    return n


def _check_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--formations", type=int, default=5, help="formations in the synthetic show (default 5)")


def _plan_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dense", action="store_true",
                   help="the dense suite: 6 formations at exactly min_distance_m, 100/300/1000/5000 drones "
                        "(or --drones N), planned + checked, show length vs a lower bound")
    p.add_argument("--cold", action="store_true",
                   help="with --dense: also plan + check each show in fresh processes, first with an empty "
                        "numba cache (compiling, once per install), then with a filled one (loading)")


def _bench_plan(args: argparse.Namespace) -> dict:
    from sim.bench._shows import bench_transition

    if args.dense:
        from sim.bench._dense import DENSE_SIZES, bench_dense

        sizes = DENSE_SIZES if args.drones is None else (_check_drones(args),)
        out = {"kind": "plan-dense", "shows": [bench_dense(n, formations=6) for n in sizes]}
        if args.cold:
            from sim.bench._dense import cold_and_warm

            out["fresh"] = [cold_and_warm(n, formations=6) for n in sizes]
        return out
    if args.drones is None:
        args.drones = 2000
    n = _check_drones(args)
    # Dense scipy needs an N x N float64 matrix and minutes beyond ~5000 drones.
    return {"kind": "plan", **bench_transition(n, dense_baseline=n <= 5000)}


def _format_plan(r: dict) -> str:
    if r["kind"] == "plan-dense":
        lines = [
            "bench plan --dense: 6 formations drawn at exactly min_distance_m (disc, star, ball, text, image, wall)",
            "  (times: wall clock, CPU in brackets, kernels already loaded; kdtree x: the reference k-d-tree check's "
            "CPU over ours, same plan; ratio: show length over the lower bound)",
            f"  {'drones':>6} {'violations':>10} {'unresolved':>10} {'show s':>8} {'bound s':>8} {'ratio':>6} "
            f"{'plan s':>14} {'check s':>14} {'kdtree x':>8} {'peak MB':>8} {'sampled min m':>13}",
        ]
        for f in r["shows"]:
            kd = f"{f['kdtree_over_sweep_cpu']:>8.2f}" if "kdtree_over_sweep_cpu" in f else f"{'-':>8}"
            lines.append(
                f"  {f['drones']:>6} {f['violations']:>10} {f['unresolved']:>10} {f['show_duration_s']:>8.1f} "
                f"{f['lower_bound_s']:>8.1f} {f['ratio_to_bound']:>6.3f} "
                f"{f['plan_s']:>6.2f} ({f['plan_cpu_s']:>5.2f}) {f['check_s']:>6.2f} ({f['check_cpu_s']:>5.2f}) "
                f"{kd} {f['peak_rss_mb']:>8.0f} "
                + (f"{f['sampled_min_distance_m']:>13.6f}" if "sampled_min_distance_m" in f else f"{'-':>13}")
            )
        for f in r["shows"]:
            lines.append(f"  {f['drones']} drones, per transition (planned / lower bound, s): " + ", ".join(
                f"{t['to']} {t['duration_s']:.1f}/{t['bound_s']:.1f} {t['resolution']}" for t in f["transitions"]))
        if r["shows"] and r["shows"][0].get("kernel_load_s"):
            f = r["shows"][0]
            lines.append(f"  loading (or compiling) the kernels before the first show: {f['kernel_load_s']:.2f} s "
                         f"({f['kernel_load_cpu_s']:.2f} s CPU)")
        for f in r.get("fresh", []):
            c, w = f["cold"], f["warm"]
            lines.append(
                f"  {f['drones']} drones in a fresh process, plan + check, wall (CPU) s: cold numba cache "
                f"{c['plan_s']:.2f} ({c['plan_cpu_s']:.2f}) + {c['check_s']:.2f} ({c['check_cpu_s']:.2f}); warm cache "
                f"{w['plan_s']:.2f} ({w['plan_cpu_s']:.2f}) + {w['check_s']:.2f} ({w['check_cpu_s']:.2f}); "
                f"peak {w['peak_rss_mb']:.0f} MB; same plan: {f['same_plan']}")
        return "\n".join(lines)
    lines = [
        f"bench plan: one ground-grid -> sphere CAPT transition, {r['drones']} drones",
        f"  assign {r['assign_s']:.3f} s, timing {r['timing_s'] * 1e3:.2f} ms, exact verify {r['verify_s']:.3f} s "
        f"(total {r['plan_and_verify_s']:.3f} s); transition {r['duration_s']:g} s, min distance "
        f"{r['min_distance_m']:.3f} m (CAPT guarantees {r['capt_guarantee_m']:.3f} m)",
    ]
    if "dense_lsa_s" in r:
        ratio = r["dense_over_ours_assign"]
        # Below 1 (tiny inputs: scipy's constant cost is smaller) "0.1x faster" would mean 10x slower: say so.
        than = f"{ratio:.1f}x faster" if ratio >= 1 else f"{1 / max(ratio, 1e-12):.1f}x slower"
        lines.append(f"  scipy dense linear_sum_assignment {r['dense_lsa_s']:.3f} s: ours is "
                     f"{than}, equal cost: {r['cost_equal']}")
    return "\n".join(lines)


def _bench_check(args: argparse.Namespace) -> dict:
    from sim.bench._shows import bench_show

    n = _check_drones(args)
    if not 1 <= args.formations <= 50:
        raise CliError(f"--formations must be in [1, 50], got {args.formations}")
    return {"kind": "check", **bench_show(n, formations=int(args.formations))}


def _format_check(r: dict) -> str:
    return "\n".join([
        f"bench check: {r['drones']} drones, {r['formations']} formations, {r['show_duration_s']:g} s show",
        f"  plan {r['plan_s']:.3f} s, exact check {r['check_s']:.3f} s: min distance "
        f"{r['exact_min_distance_m']:.4f} m, {r['violations']} violations",
        f"  a 10 Hz sampled check takes {r['sampled_10hz_s']:.3f} s ({r['sampled_over_exact_check']:.2g}x the "
        f"exact one) and finds {r['sampled_10hz_min_distance_m']:.4f} m",
    ])


#: name -> (help, add its arguments, run(args) -> dict, format(dict) -> str)
BENCH_KINDS: dict[str, tuple[str, Callable, Callable, Callable]] = {
    "sim": ("flight engines: numba kernel vs numpy reference, drone-steps per second",
            _sim_args, _bench_sim, _format_sim),
    "plan": ("CAPT planning + exact verification of one grid -> sphere transition vs scipy dense LSA; "
             "--dense: the dense-show suite",
             _plan_args, _bench_plan, _format_plan),
    "check": ("plan + exact check of a whole synthetic show vs a 10 Hz sampled check",
              _check_args, _bench_check, _format_check),
}


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``bench`` command with one sub-command per kind of ``BENCH_KINDS``."""
    p = sub.add_parser("bench", help="measure the speed of a pipeline stage (" + ", ".join(BENCH_KINDS) + ")")
    kinds = p.add_subparsers(dest="kind", metavar="KIND")
    kinds.required = True
    for name, (help_text, add_args, run, fmt) in BENCH_KINDS.items():
        k = kinds.add_parser(name, help=help_text)
        k.add_argument("--drones", type=int, default=None if name == "plan" else 2000,
                       help="number of drones (default 2000; plan --dense: the whole suite)")
        k.add_argument("--json", action="store_true", help="print the result as one JSON object on stdout")
        add_args(k)
        k.set_defaults(func=_make_runner(run, fmt))


def _make_runner(run: Callable, fmt: Callable) -> Callable[[argparse.Namespace], int]:
    def runner(args: argparse.Namespace) -> int:
        result = run(args)
        if args.json:
            print_json(result)
        else:
            print(fmt(result))
        return EXIT_OK

    return runner
