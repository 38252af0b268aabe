"""``swarmshow check SHOW [--json]``: plan the show and verify it exactly."""

from __future__ import annotations

import argparse
import math

from app.cli._common import EXIT_FAILED, EXIT_OK, CliError, count, load_show_arg, print_json, progress_bar


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``check`` command."""
    p = sub.add_parser(
        "check",
        help="plan the show with CAPT and verify separation, speeds, acceleration and altitude exactly "
        "(exit 1 if any limit is broken)",
    )
    p.add_argument("show", metavar="SHOW", help="show file (JSON; - reads standard input)")
    p.add_argument("--json", action="store_true", help="print the report as one JSON object on stdout")
    p.set_defaults(func=_check)


def _check(args: argparse.Namespace) -> int:
    from sim import PlanError, check_show

    show = load_show_arg(args.show)
    try:
        with progress_bar("check") as update:
            report = check_show(show, progress=update)
    except PlanError as exc:  # the show cannot be planned as drawn: one line naming the field (exit 2)
        raise CliError(f"{args.show}: {exc}") from exc
    if args.json:
        print_json(report.to_json())
    else:
        print(format_report(report))
    return EXIT_OK if report.ok else EXIT_FAILED


def format_report(report) -> str:
    """The check report as a few human-readable lines."""
    lim = report.limits
    # A show of one drone has no pair: no distance (+inf in the report, null in its JSON), not a distance.
    if math.isfinite(report.min_distance_m):
        closest = (f"{report.min_distance_m:8.3f} m   (limit {lim['min_distance_m']} m; drones "
                   f"{report.min_distance_pair[0]} and {report.min_distance_pair[1]} at t = "
                   f"{report.min_distance_time_s:.2f} s)")
    else:
        closest = f"     n/a     (limit {lim['min_distance_m']} m; one drone, no pair)"
    lines = [
        f"show {report.show!r}: {count(report.drones, 'drone')}, {report.duration_s:.1f} s, "
        f"{len(report.transitions)} transitions",
        f"  min distance   {closest}",
        f"  speed xy       {report.max_speed_xy_mps:8.3f} m/s (limit {lim['max_speed_xy_mps']})",
        f"  speed z        {report.max_speed_z_mps:8.3f} m/s (limit {lim['max_speed_z_mps']})",
        f"  acceleration   {report.max_accel_mps2:8.3f} m/s² (limit {lim['max_accel_mps2']})",
        # + 0.0 turns the pads' -3e-14 m (rounding) into 0.0, not "-0.0".
        f"  altitude       {round(report.min_altitude_m, 1) + 0.0:.1f} .. {report.max_altitude_m:.1f} m "
        f"(limit {lim['max_altitude_m']} m)",
    ]
    for t in report.transitions:
        lines.append(
            f"  {t.from_!r} -> {t.to!r}: start {t.start_s:.1f} s, {t.duration_s:.1f} s, "
            f"cost {t.assignment_cost_m2:.1f} m²"
            + (f", exact min {t.capt.exact_min_distance_m:.3f} m (CAPT bound {t.capt.guaranteed_min_distance_m:.3f} m)"
               if math.isfinite(t.capt.exact_min_distance_m) else "")
        )
    lines.append("per transition (worst first):")
    for g in report.worst_transitions():
        head = (f"  {'✓' if g.ok else '✗'} {g.kind} {g.from_!r} -> {g.to!r}: {g.duration_s:.1f} s"
                f"{f' (stagger {g.stagger_s:.1f} s)' if g.stagger_s > 0 else ''}"
                f"{f', min {g.min_distance_m:.3f} m' if math.isfinite(g.min_distance_m) else ''}")
        if not g.ok:
            head += f", {g.violations_total} violation(s)"
        lines.append(head)
        lines.extend(f"      - {v.message}" for v in g.violations[:3])
        if g.violations_total > 3:
            lines.append(f"      ... and {g.violations_total - 3} more in this transition")
        lines.extend(f"      fix: {f}" for f in g.fixes)
    if report.ok:
        lines.append("OK: no limit is broken")
    else:
        lines.append(f"UNSAFE: {report.violations_total} violation(s) (see --json for all)")
    return "\n".join(lines)
