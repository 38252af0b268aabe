"""``swarmshow simulate``: fly a planned show, or reproduce the paper's scenario.

``swarmshow simulate SHOW [--json] [--preset calm-rtk] [--seed N] [--engine numba|numpy]
[--controller ismc|baseline] [--disturbance none|paper|wind] [--output-hz HZ] [--scheduler tcp://HOST:PORT]
[--precision float64|float32]``
plans the show, flies every drone at 1 kHz under the error-model preset (default
:data:`DEFAULT_FLIGHT_PRESET`, ``calm-rtk``: the ideal vehicle's tracking error of a fraction of
a millimetre tells a designer nothing; ``--disturbance`` alone flies the ideal vehicle in that
fleet-wide disturbance) with seed ``--seed`` (the same seed flies the same flight: it is Monte-Carlo
run k of ``--seed S --runs K`` when S + k is that seed) and reports the preset and seed, tracking
errors, the flown minimum distance and diverged drones. Exit 1 (unsafe) when any drone
diverged, or when the flown minimum distance is below the show's ``min_distance_m`` by more than
``sim.flight.FLOWN_DISTANCE_TOLERANCE_M`` (1 cm: plans that sit exactly on the limit,
such as a home grid spaced at the minimum distance, must not fail on millimetre
tracking deviations). A transition forced shorter than the limits allow is flown as designed (a
what-if, as the app's simulate) and named under ``problems``; the command then exits 1.

``--engine dask --scheduler tcp://HOST:PORT`` flies the drones in shards on a Dask
``distributed`` cluster (same results as the local engine; ``--scheduler local`` starts
an in-process cluster; the address defaults to ``$SWARMSHOW_DASK_SCHEDULER``). Exit 2
with a one-line message when the scheduler or a worker cannot be reached within
``--scheduler-timeout`` seconds.

``swarmshow simulate SHOW --runs K [--preset calm-rtk] [--seed S] [--confidence 0.99]
[--collision-distance M] [--report out.html|out.pdf]`` is the Monte-Carlo safety margin
(``sim.flight.monte_carlo``): K flights with seeds S .. S+K-1 under the preset (default as a single
flight's, so that run k is the single flight of seed S+k; none with ``--disturbance``) (on the local engine one after
the other, on ``--engine dask`` one task per run), the flown minimum separation per segment
and for the show, the probability of coming closer than the minimum distance and than the
collision distance (exact binomial intervals), the worst pairs, every drone's largest deviation
and the extra spacing each segment needs at ``--confidence``; ``--report`` writes the safety
report (HTML with inline plots, or PDF by the suffix). Exit 1 when any run came closer than
the minimum distance (with the flight tolerance) or a drone diverged.

``swarmshow simulate --scenario paper [--json] [--plot PNG] [--controller ...]`` runs
method.md §7 for 20 s with the chosen controller and the other one for comparison;
exit 1 if the chosen controller misses the paper scenario's thresholds.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import sys
from pathlib import Path
from typing import Any

from app.cli._common import (
    EXIT_FAILED,
    EXIT_OK,
    CliError,
    count,
    load_show_arg,
    print_json,
    progress_bar,
    write_atomically,
)

#: Error-model presets and the default collision distance (copied from ``sim.flight`` so that
#: building the parser does not import the simulation; a test keeps them equal).
PRESETS = ("ideal", "calm-rtk", "gusty-rtk", "gps-only")
DEFAULT_COLLISION_DISTANCE_M = 1.0
#: The preset a single flight flies by default (``sim.flight.DEFAULT_FLIGHT_PRESET``; a test keeps them equal).
DEFAULT_FLIGHT_PRESET = "calm-rtk"

#: What each divergence reason means physically (``sim.flight.engines._state``; the editor says the same).
_REASONS = {
    "overpowered": "held at its tilt/thrust limit and blown off, wind beyond its authority",
    "runaway": "unstable control or a tumble",
    "non-finite": "the state broke down",
    "ground": "sank 0.5 m below the show's ground, a crash",
}

#: Largest recording a flight may keep, drones x frames (``sim.flight``'s runner keeps every drone's
#: position at every recorded frame, float32: 12 bytes a sample, so 3.6 GB; a 10,000-drone, 17-minute
#: show at the default 25 Hz is 258 M). Past it the command refuses before flying and names the highest
#: ``--output-hz`` that fits, instead of asking numpy for 115 GiB at 1 kHz (a MemoryError traceback).
MAX_RECORDED_SAMPLES = 300_000_000

#: ``local`` (an alias for the in-process engine) is the numba kernel.
LOCAL_ALIAS = "local"
#: Environment variable giving the default ``--scheduler`` (shared with the server setting).
SCHEDULER_ENV = "SWARMSHOW_DASK_SCHEDULER"


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` command."""
    from sim.flight import CONTROLLERS, DISTURBANCES, ENGINES, PRECISIONS

    p = sub.add_parser(
        "simulate",
        help="fly every drone of a show with the quadrotor model and ISMC controllers at 1 kHz "
        "(exit 1 if a drone diverged or the flown separation broke the limit), or "
        "reproduce the paper's scenario with --scenario paper",
    )
    p.add_argument("show", metavar="SHOW", nargs="?",
                   help="show file (JSON; - reads standard input); omit with --scenario")
    p.add_argument("--scenario", choices=("paper",), help="run a built-in scenario instead of a show")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object on stdout")
    p.add_argument("--plot", metavar="PNG", help="with --scenario paper: write the error/input figure")
    p.add_argument("--engine", choices=(*ENGINES, LOCAL_ALIAS), default="numba",
                   help="numba (alias local): fused parallel kernel (default); numpy: the readable reference; "
                   "dask: numba on shards of drones on a Dask cluster (needs --scheduler)")
    p.add_argument("--scheduler", metavar="ADDR",
                   help=f"with --engine dask: scheduler address tcp://HOST:PORT, or 'local' for an in-process "
                   f"cluster (default ${SCHEDULER_ENV})")
    p.add_argument("--scheduler-timeout", metavar="S", type=float, default=10.0,
                   help="with --engine dask: seconds to reach the scheduler and a worker (default 10)")
    p.add_argument("--controller", choices=CONTROLLERS, default="ismc",
                   help="ismc: the paper's controllers (default); baseline: cascaded PD")
    p.add_argument("--disturbance", choices=DISTURBANCES, default=None,
                   help="external disturbance for a show flight (default none; not with --preset, whose error "
                   "models carry their own wind)")
    p.add_argument("--precision", choices=PRECISIONS, default="float64",
                   help="the numba kernel's arithmetic: float64 (default; agrees with the numpy reference to "
                        "1e-9) or float32 control laws (1.3-1.4x faster kernel, results differ at the rounding level)")
    p.add_argument("--output-hz", type=float, default=25.0, help="rate of recorded frames, Hz (default 25)")
    p.add_argument("--seed", type=int, default=0,
                   help="seed of the random errors (default 0); with --runs the first run's seed")
    p.add_argument("--preset", choices=PRESETS,
                   help=f"error-model preset: ideal, calm-rtk, gusty-rtk, gps-only (default {DEFAULT_FLIGHT_PRESET}, "
                   "for one flight and for --runs; with --disturbance: ideal for one flight, none for --runs; presets "
                   "other than ideal bring their own wind and replace --disturbance)")
    p.add_argument("--runs", type=int, metavar="K",
                   help="Monte-Carlo: fly the show K times with seeds SEED..SEED+K-1 and report the margin")
    p.add_argument("--confidence", type=float, default=None, metavar="C",
                   help="with --runs: level of the intervals and of the extra spacing, in (0, 1) (default 0.99)")
    p.add_argument("--collision-distance", type=float, default=None, metavar="M",
                   help=f"with --runs: centre distance counted as a collision, m (default "
                   f"{DEFAULT_COLLISION_DISTANCE_M:g})")
    p.add_argument("--report", metavar="FILE",
                   help="with --runs: write the safety report, HTML (.html) or PDF (.pdf)")
    p.set_defaults(func=_simulate)


def _simulate(args: argparse.Namespace) -> int:
    if args.scenario is not None:
        if args.show is not None:
            raise CliError("give either SHOW or --scenario, not both")
        if args.runs is not None or args.preset is not None or args.report is not None:
            raise CliError("--runs, --preset and --report fly a SHOW, not --scenario paper")
        if args.precision != "float64":
            raise CliError("--precision flies a SHOW; the paper scenario is float64")
        if args.plot is not None:
            check_plot_path(args.plot)
        return _paper(args)
    if args.show is None:
        raise CliError("a SHOW file or --scenario is required")
    if args.plot is not None:
        raise CliError("--plot is only available with --scenario paper")
    if args.preset is not None and args.disturbance is not None and (args.preset != "ideal" or args.runs):
        # A preset other than ideal brings its own wind field, and a Monte-Carlo run flies the preset alone
        # (sim.flight.options_for_preset sets the disturbance to none): flying one and dropping the other
        # without a word misreports the run. One flight of the ideal vehicle in a disturbance is the API's
        # preset "ideal" with a disturbance (sim.flight.single_flight_options).
        why = ("a Monte-Carlo run flies the preset alone" if args.preset == "ideal" else
               "the preset's error models bring their own wind (one flight of --preset ideal can take it)")
        raise CliError(f"--preset {args.preset} and --disturbance {args.disturbance} cannot be combined: {why}; "
                       "drop --disturbance")
    args.disturbance = args.disturbance or "none"
    if not (math.isfinite(args.output_hz) and args.output_hz > 0):
        raise CliError(f"--output-hz must be a finite number > 0, got {args.output_hz}")
    if args.scheduler is not None and args.engine != "dask":
        raise CliError("--scheduler is only used with --engine dask")
    if args.precision != "float64" and args.engine == "numpy":
        raise CliError("--precision float32 needs the numba engine (the numpy reference is float64)")
    if not args.scheduler_timeout > 0:
        raise CliError(f"--scheduler-timeout must be > 0, got {args.scheduler_timeout}")
    if args.runs is None:
        for flag, value in (("--confidence", args.confidence), ("--collision-distance", args.collision_distance),
                            ("--report", args.report)):
            if value is not None:
                raise CliError(f"{flag} is only used with --runs K (the Monte-Carlo safety margin)")
        return _show(args)
    if args.runs < 1:
        raise CliError(f"--runs must be >= 1, got {args.runs}")
    if args.confidence is not None and not 0.0 < args.confidence < 1.0:
        raise CliError(f"--confidence must be in (0, 1), got {args.confidence}")
    if args.collision_distance is not None and not (math.isfinite(args.collision_distance)
                                                    and args.collision_distance > 0):
        raise CliError(f"--collision-distance must be > 0, got {args.collision_distance}")
    if args.report is not None and _report_format(args.report) is None:
        raise CliError(f"--report {args.report}: the file name must end in .html or .pdf")
    return _montecarlo(args)


def recorded_frames(duration_s: float, output_hz: float) -> int:
    """Frames the flight runner records over ``duration_s`` at ``output_hz``: one every
    ``round(1 / (output_hz * 1 ms))`` control steps of 1 ms, the first at t = 0 (``sim.flight._runner``)."""
    steps = int(round(duration_s / 1e-3)) + 1
    every = max(int(round(1.0 / (output_hz * 1e-3))), 1)  # as the runner computes it
    return (steps - 1) // every + 1


def check_recording_size(plan: Any, output_hz: float) -> None:
    """Refuse a flight whose recording (drones x frames) exceeds :data:`MAX_RECORDED_SAMPLES`.

    Raises:
        CliError: naming ``--output-hz`` and the highest rate that fits (one frame every ``k`` ms).
    """
    drones, duration_s = int(plan.drone_count), float(plan.duration_s)
    samples = drones * recorded_frames(duration_s, output_hz)
    if samples <= MAX_RECORDED_SAMPLES:
        return
    steps = int(round(duration_s / 1e-3)) + 1
    frames = max(MAX_RECORDED_SAMPLES // max(drones, 1), 1)
    # Smallest step count between frames with (steps - 1) // every + 1 <= frames.
    every = max(-(-(steps - 1) // max(frames - 1, 1)) if frames > 1 else steps, 1)
    while (steps - 1) // every + 1 > frames:
        every += 1
    # Rounded down, so that the rate as printed still records one frame every ``every`` steps or fewer.
    most_hz = f"{math.floor(1000.0 / every * 1e4) / 1e4:.4f}".rstrip("0").rstrip(".")
    raise CliError(
        f"--output-hz {output_hz:g}: {drones} drones x {duration_s:.0f} s would record {samples:,} positions, "
        f"over the limit of {MAX_RECORDED_SAMPLES:,} ({MAX_RECORDED_SAMPLES * 12 / 1e9:.1f} GB); "
        f"use --output-hz {most_hz} or less"
    )


def _report_format(path: str) -> str | None:
    suffix = Path(path).suffix.lower()
    return {".html": "html", ".htm": "html", ".pdf": "pdf"}.get(suffix)


def _base_options(args: argparse.Namespace, dask: dict) -> Any:
    """The FlightOptions the flags give (engine, controller, disturbance, output rate, seed, precision,
    Dask), before any error preset."""
    from sim.flight import FlightOptions

    return FlightOptions(
        engine=_engine(args), controller=args.controller, disturbance=args.disturbance,
        output_hz=args.output_hz, seed=args.seed, precision=args.precision, **dask,
    )


def montecarlo_preset(args: argparse.Namespace) -> str | None:
    """The preset a Monte-Carlo flies: ``--preset``, else none with ``--disturbance`` (the ideal vehicle in that
    disturbance: a preset's own wind would count it twice), else the single flight's default, so that run k is
    ``swarmshow simulate SHOW --seed S+k`` (the API's and the editor's default too)."""
    if args.preset is not None:
        return str(args.preset)
    return None if args.disturbance != "none" else DEFAULT_FLIGHT_PRESET


def _flight_options(args: argparse.Namespace, dask: dict) -> Any:
    """A Monte-Carlo run's FlightOptions: :func:`_base_options` and the error preset (if any)."""
    from sim.flight import options_for_preset

    options = _base_options(args, dask)
    preset = montecarlo_preset(args)
    return options if preset is None else options_for_preset(preset, options)


def single_preset(args: argparse.Namespace) -> str:
    """The preset a single flight flies: ``--preset``, else ideal with ``--disturbance``, else the default."""
    if args.preset is not None:
        return str(args.preset)
    return "ideal" if args.disturbance != "none" else DEFAULT_FLIGHT_PRESET


def _montecarlo(args: argparse.Namespace) -> int:
    from sim.flight import monte_carlo

    dask = _dask_options(args)
    show = load_show_arg(args.show)
    report_path = Path(args.report) if args.report else None
    if report_path is not None and not report_path.parent.is_dir():
        raise CliError(f"{report_path}: cannot write: no such directory {str(report_path.parent)!r}")
    with contextlib.ExitStack() as stack:
        plan = _connect_and_plan(args, stack, dask, show)
        check_recording_size(plan, args.output_hz)
        with progress_bar(f"monte-carlo x{args.runs}") as update:
            result = monte_carlo(
                plan, _flight_options(args, dask), runs=args.runs, seed0=args.seed,
                confidence=0.99 if args.confidence is None else args.confidence,
                collision_distance_m=(DEFAULT_COLLISION_DISTANCE_M if args.collision_distance is None
                                      else args.collision_distance),
                preset=montecarlo_preset(args), progress=update,
            )
    report = result.to_json()
    report["show"] = show.name
    if report_path is not None:
        from app.exports import render_safety_report

        fmt = _report_format(str(report_path)) or "html"
        write_atomically(report_path, render_safety_report(report, fmt))
        report["report"] = str(report_path)
    if args.json:
        print_json(report)
    else:
        print(format_montecarlo(report))
    unsafe = report["show_min"]["p_below_min_distance"]["runs_below"] > 0 or report["diverged_count"] > 0
    return EXIT_FAILED if unsafe else EXIT_OK


def _segment_name(seg: dict) -> str:
    """A segment as the report's table names it: its kind and its label ("transition 'a'", "hold 'a'"), so that
    a formation's transition and its hold do not read alike; takeoff and landing by their kind alone."""
    kind, label = seg.get("kind") or "", seg["label"]
    return kind if kind == label else f"{kind} {label!r}".strip()


def format_montecarlo(r: dict) -> str:
    """The Monte-Carlo summary as a few human-readable lines."""

    def num(x: float | None, fmt: str = ".3f") -> str:
        return "n/a" if x is None else format(x, fmt)

    def metres(x: float | None, fmt: str = ".3f") -> str:  # "n/a" without a unit (one drone: no pair)
        return "n/a" if x is None else f"{format(x, fmt)} m"

    s = r["show_min"]
    q = s["flown_min_m"]["quantiles"]
    # Plain metres with four significant digits (24.45 m, 0.0001255 m), and whose it is.
    worst = r["deviation"].get("worst_drones") or []
    worst_drone = f" (drone {worst[0]['drone']})" if worst else ""

    def prob(p: dict) -> str:
        return (f"{p['runs_below']}/{p['runs']} runs ({100 * p['ci_low']:.1f}-{100 * p['ci_high']:.1f} % at "
                f"{100 * p['confidence']:g} %)")

    lines = [
        f"show {r['show']!r}: {count(r['drones'], 'drone')}, {r['duration_s']:.1f} s, {r['runs']} runs (seeds "
        f"{r['seed0']}-"
        f"{r['seed0'] + r['runs'] - 1}, preset {r['preset'] or 'none'}, {r['controller']}, {r['engine']} engine) "
        f"in {r['wall_time_s']:.1f} s",
        f"  flown min separation: worst {metres(q.get('0'))}, 5 % {metres(q.get('0.05'))}, median "
        f"{metres(q.get('0.5'))} (plan {metres(s['planned_min_m'])}, limit {r['min_distance_m']:g} m)",
        f"  closer than {r['min_distance_m']:g} m: {prob(s['p_below_min_distance'])}",
        f"  closer than {r['collision_distance_m']:g} m (collision): {prob(s['p_collision'])}",
        f"  extra spacing needed at {100 * r['confidence']:g} %: {num(s['extra_spacing']['extra_m'], '.3f')} m",
        f"  largest deviation from the plan: {num(r['deviation']['max_m'], '.4g')} m{worst_drone}",
    ]
    for seg in r["segments"]:
        if seg["extra_spacing"]["extra_m"] > 0 or seg["p_below_min_distance"]["runs_below"]:
            lines.append(
                f"  segment {seg['index']} {_segment_name(seg)}: worst "
                f"{num(seg['flown_min_m']['quantiles'].get('0'))} m, "
                f"{seg['p_below_min_distance']['runs_below']} runs below, needs "
                f"+{seg['extra_spacing']['extra_m']:.3f} m")
    for p in r["worst_pairs"][:3]:
        lines.append(f"  pair {p['drones'][0]} & {p['drones'][1]}: {p['distance_m']:.3f} m at t = "
                     f"{p['time_s']:.2f} s ({p['label']}, run {p['run']}, seed {p['seed']})")
    if r["diverged_count"]:
        why = ", ".join(f"{n} {k}" for k, n in sorted((r.get("diverged_by_reason") or {}).items()))
        lines.append(f"  DIVERGED: {r['diverged_count']} drone-runs" + (f" ({why})" if why else ""))
    if r.get("report"):
        lines.append(f"  report written to {r['report']}")
    unsafe = s["p_below_min_distance"]["runs_below"] > 0 or r["diverged_count"] > 0
    lines.append("UNSAFE: some runs broke the minimum distance (see above)" if unsafe
                 else "OK: every run kept the minimum distance")
    return "\n".join(lines)


def _dask_options(args: argparse.Namespace) -> dict:
    """``fly_show`` keywords of the dask engine (empty for the local engines)."""
    if args.engine != "dask":
        return {}
    scheduler = args.scheduler or os.environ.get(SCHEDULER_ENV, "").strip() or None
    if scheduler is None:
        raise CliError(f"--engine dask needs --scheduler tcp://HOST:PORT (or 'local', or ${SCHEDULER_ENV})")
    return {"scheduler": scheduler, "connect_timeout_s": args.scheduler_timeout}


def _engine(args: argparse.Namespace) -> str:
    return "numba" if args.engine == LOCAL_ALIAS else args.engine


def _show(args: argparse.Namespace) -> int:
    from sim.flight import fly_show, planned_closest, single_flight_options

    if args.seed < 0:
        raise CliError(f"--seed must be >= 0, got {args.seed}")
    dask = _dask_options(args)
    preset = single_preset(args)
    try:
        options = single_flight_options(preset, _base_options(args, dask))
    except ValueError as exc:
        raise CliError(f"--disturbance {args.disturbance} goes only with --preset ideal (--preset {preset} "
                       "brings its own wind field)" if "disturbance" in str(exc) else str(exc)) from None
    show = load_show_arg(args.show)
    with contextlib.ExitStack() as stack:
        # A what-if, as the app's simulate: a transition forced shorter than the limits allow is flown as
        # designed and named in ``problems`` (then exit 1: the show cannot be flown as it is).
        plan = _connect_and_plan(args, stack, dask, show, enforce_limits=False)
        check_recording_size(plan, args.output_hz)
        # The summary never reads the LED colours: not evaluating them saves as much memory again as the
        # positions (and 4-7 % of the time).
        options = options.with_(colors=False)
        with progress_bar("simulate") as update:
            result = fly_show(plan, options, progress=update)  # the scheduler is in the options already
    summary = result.summary()
    summary["show"] = show.name
    summary["preset"], summary["seed"] = preset, args.seed
    summary.update(planned_closest(plan, result.times_s))
    summary["problems"] = [{"path": f.path, "msg": f.message, "minimum_s": f.minimum_s} for f in plan.forced]
    if args.json:
        print_json(summary)
    else:
        print(format_flight(summary))
    return EXIT_OK if result.ok and not plan.forced else EXIT_FAILED


def format_flight(s: dict) -> str:
    """The flight summary as a few human-readable lines."""

    def num(x: float | None, fmt: str) -> str:
        return "n/a" if x is None else format(x, fmt)

    def metres(x: float | None, fmt: str) -> str:  # "n/a" without a unit (one drone: no pair)
        return "n/a" if x is None else f"{format(x, fmt)} m"

    pair = s["flown_min_distance_pair"]
    lines = [
        f"show {s['show']!r}: {count(s['drones'], 'drone')}, {s['duration_s']:.1f} s flown at 1 kHz "
        f"({s['engine']} engine, {s['controller']}, "
        f"{'disturbance ' + str(s['disturbance']) if s.get('preset') in (None, 'ideal') else 'preset ' + s['preset']}"
        f") in {s['wall_time_s']:.1f} s",
        f"  error preset {s.get('preset', 'ideal')}, seed {s.get('seed', 0)} (the same seed flies the same flight)",
        f"  deviation from the plan  rms {num(s['tracking_rms_m'], '.3g')} m, max {num(s['tracking_max_m'], '.3g')} m",
        f"  flown min distance {metres(s['flown_min_distance_m'], '.3f')} (plan "
        f"{metres(s.get('planned_min_distance_m'), '.3f')}, limit {s['min_distance_limit_m']} m"
        + (f"; drones {pair[0]} and {pair[1]} at t = {s['flown_min_distance_time_s']:.2f} s)" if pair else ")"),
    ]
    lines.extend(
        f"  worst drone {w['drone']}: rms {num(w['rms_m'], '.2e')} m, max {num(w['max_m'], '.2e')} m"
        for w in s["worst_drones"][:3]
    )
    if s["diverged"]:
        counts: dict[str, int] = {}
        for d in s["diverged"]:
            counts[d["reason"]] = counts.get(d["reason"], 0) + 1
        lines.append(f"  DIVERGED: {len(s['diverged'])} drones ("
                     + ", ".join(f"{n} {why}: {_REASONS.get(why, why)}" for why, n in sorted(counts.items())) + ")")
    for d in s["diverged"][:20]:
        lines.append(f"  DIVERGED drone {d['drone']} at t = {d['time_s']:.3f} s ({d['reason']})")
    if len(s["diverged"]) > 20:
        lines.append(f"  ... and {len(s['diverged']) - 20} more (see --json)")
    for p in s.get("problems", []):
        lines.append(f"  NOT FLYABLE AS DESIGNED: {p['msg']}")
    lines.append("OK: every drone flew and kept the separation" if s["ok"] and not s.get("problems")
                 else "UNSAFE: see above")
    return "\n".join(lines)


def check_plot_path(path: str) -> None:
    """Refuse a ``--plot`` file that cannot be written, before the scenario flies: a missing directory, or a
    suffix matplotlib cannot write (``x.txt`` died in matplotlib with a traceback after the flight).

    Raises:
        CliError: naming ``--plot`` and why.
    """
    target = Path(path)
    if not target.parent.is_dir():
        raise CliError(f"--plot {path}: no such directory {str(target.parent)!r}")
    suffix = target.suffix.lower().lstrip(".")
    if suffix:
        from matplotlib.backend_bases import FigureCanvasBase

        if suffix not in FigureCanvasBase.get_supported_filetypes():
            raise CliError(f"--plot {path}: cannot write .{suffix} images; name it .png, .pdf or .svg")


def _paper(args: argparse.Namespace) -> int:
    from sim.flight import paper_report, plot_paper

    if args.engine == "dask" or args.scheduler is not None:
        raise CliError("--engine dask flies shows only; the paper scenario is one drone")
    with progress_bar("paper scenario") as update:
        report, run, other = paper_report(controller=args.controller, engine=_engine(args))
        update(1.0)
    if args.plot:
        try:
            plot_paper([run, other], args.plot)
        except OSError as exc:
            raise CliError(f"{args.plot}: cannot write the plot ({exc.strerror or exc})") from exc
        report["plot"] = args.plot
    if args.json:
        print_json(report)
    else:
        print(format_paper(report))
    if not report["meets_thresholds"]:
        print(f"swarmshow: {args.controller} misses the paper scenario's thresholds", file=sys.stderr)
    return EXIT_OK if report["meets_thresholds"] else EXIT_FAILED


def format_paper(r: dict) -> str:
    """The paper-scenario report as a few human-readable lines."""
    other = "baseline" if r["controller"] == "ismc" else "ismc"
    o = r[other]
    th = r["thresholds"]
    settle = "never" if r["settle_time_s"] is None else f"{r['settle_time_s']:.3f} s"
    return "\n".join([
        f"paper scenario (docs/method.md §7), {r['controller']} controller, 20 s at 1 ms:",
        f"  position error  max(t>=8 s) {r['pos_err_m']['max_t_ge_8s']:.3e} m, at 20 s "
        f"{r['pos_err_m']['at_20s']:.3e} m   (required < {th['pos_err_m']:g})",
        f"  attitude error  max(t>=8 s) {r['att_err_rad']['max_t_ge_8s']:.3e} rad, at 20 s "
        f"{r['att_err_rad']['at_20s']:.3e} rad (required < {th['att_err_rad']:g}; to the filtered "
        f"command {r['att_err_tracked_rad']['max_t_ge_8s']:.1e})",
        f"  settle time {settle}, max thrust step {r['max_thrust_step_n']:.3g} N "
        f"(after settling {r['max_thrust_step_after_settle_n'] or 0:.3g} N)",
        f"  {other}: position error max(t>=8 s) {o['pos_err_m']['max_t_ge_8s']:.3e} m, attitude "
        f"{o['att_err_rad']['max_t_ge_8s']:.3e} rad",
        f"  baseline / ismc steady error: position {r['baseline_over_ismc']['pos_err']:.0f}x, attitude "
        f"{r['baseline_over_ismc']['att_err']:.1f}x (to the filtered command "
        f"{r['baseline_over_ismc']['att_err_tracked']:.0f}x)",
        "OK: meets the paper scenario's thresholds" if r["meets_thresholds"]
        else "FAILED: misses the paper scenario's thresholds",
    ])


def _connect_and_plan(args: argparse.Namespace, stack: contextlib.ExitStack, dask: dict[str, Any] | None,
                      show: Any, *, enforce_limits: bool = True) -> Any:
    """Connect to the Dask cluster (kept open by ``stack``) when asked, then plan ``show``.

    Connecting comes first so that an unreachable cluster fails in seconds, not after a large show
    has been planned. Both failures are one-line :class:`CliError` (exit 2). ``enforce_limits``: as in
    ``plan_show`` (False: a transition forced shorter than the limits allow is flown as designed).
    """
    from sim import PlanError, cached_plan_show
    from sim.flight import SchedulerUnreachableError, connect_scheduler

    if dask:
        try:
            dask["scheduler"] = stack.enter_context(connect_scheduler(dask["scheduler"], dask["connect_timeout_s"]))
        except SchedulerUnreachableError as exc:
            raise CliError(" ".join(str(exc).split())) from None
    try:
        return cached_plan_show(show, enforce_limits=enforce_limits)
    except PlanError as exc:
        raise CliError(f"{args.show}: {exc}") from exc
