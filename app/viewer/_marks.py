"""What the 3D view draws besides the drones: the check's violations and the gap between plan and flight.

Pure functions over numpy arrays (drones on the first axis), so that they are tested without a browser.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

#: A violation is drawn while the playhead is this close to its time, seconds.
PROBLEM_WINDOW_S = 1.5
#: Height of the warning tick drawn above a drone that breaks a limit alone (speed, altitude, ...), metres.
TICK_HEIGHT_M = 2.0
#: Drones marked per violation (a speed violation may name many).
MAX_MARKED_DRONES = 10


@dataclass(frozen=True)
class Problem:
    """One violation of the check report, for drawing: when, which drones, what."""

    time_s: float
    kind: str
    drones: tuple[int, ...]
    text: str
    formation: int


def problem_list(report: Mapping[str, Any] | None) -> list[Problem]:
    """The violations of a check report (``CheckReport.to_json()``), in time order.

    Reads ``by_transition`` (each group lists its violations, worst first) and falls back
    to the flat ``violations`` list when a report has no groups.
    """
    if not report:
        return []
    out: list[Problem] = []
    groups = report.get("by_transition") or []
    pairs = [(v, int(g.get("formation", -1))) for g in groups for v in g.get("violations", [])]
    if not pairs:
        pairs = [(v, -1) for v in report.get("violations", [])]
    for v, formation in pairs:
        out.append(Problem(
            time_s=float(v["time_s"]), kind=str(v["kind"]),
            drones=tuple(int(d) for d in v.get("drones", ())[:MAX_MARKED_DRONES]),
            text=str(v.get("message", v["kind"])), formation=formation,
        ))
    out.sort(key=lambda p: p.time_s)
    return out


def active_problems(problems: Sequence[Problem], time_s: float, window_s: float = PROBLEM_WINDOW_S) -> list[Problem]:
    """The problems within ``window_s`` of ``time_s``, nearest first."""
    near = [p for p in problems if abs(p.time_s - time_s) <= window_s]
    return sorted(near, key=lambda p: abs(p.time_s - time_s))


def problem_segments(problems: Sequence[Problem], positions_m: np.ndarray) -> np.ndarray:
    """Red segments marking ``problems`` on the drones at ``positions_m``.

    A separation violation joins its two drones; any other violation (speed, acceleration,
    altitude, geofence) puts a vertical tick of :data:`TICK_HEIGHT_M` above each drone it names.

    Args:
        problems: the problems to draw.
        positions_m: (N, 3) drone positions now, metres.

    Returns:
        (K, 2, 3) float32 segment end points, metres (K = 0 when there is nothing to draw).
    """
    n = len(positions_m)
    segs: list[np.ndarray] = []
    for p in problems:
        ids = np.array([d for d in p.drones if 0 <= d < n], dtype=np.intp)
        if p.kind == "min_distance" and len(ids) >= 2:
            segs.append(positions_m[ids[:2]][None])
        elif len(ids):
            base = positions_m[ids]
            segs.append(np.stack([base, base + [0.0, 0.0, TICK_HEIGHT_M]], axis=1))
    if not segs:
        return np.zeros((0, 2, 3), dtype=np.float32)
    return np.concatenate(segs).astype(np.float32)


def deviation_colors(deviation_m: np.ndarray, scale_m: float) -> np.ndarray:
    """Colour each drone's gap from plan to flight: green (0) through yellow (scale/2) to red (>= scale).

    Args:
        deviation_m: (N,) distance between the flown and the planned position, metres.
        scale_m: the deviation drawn full red (half the minimum distance: two drones each that far off
            could touch).

    Returns:
        (N, 3) uint8 RGB.
    """
    u = np.clip(np.asarray(deviation_m, dtype=np.float64) / max(float(scale_m), 1e-9), 0.0, 1.0)
    red = np.clip(2.0 * u, 0.0, 1.0)
    green = np.clip(2.0 * (1.0 - u), 0.0, 1.0)
    rgb = np.stack([red, green, np.full_like(u, 0.15)], axis=1)
    return np.asarray(np.round(rgb * 255.0), dtype=np.uint8)


__all__ = [
    "PROBLEM_WINDOW_S",
    "Problem",
    "active_problems",
    "check_report_json",
    "deviation_colors",
    "problem_list",
    "problem_segments",
]


def check_report_json(plan: Any) -> dict[str, Any]:
    """The exact check of ``plan`` as JSON (``CheckReport.to_json()``); run in a worker process by the app."""
    from sim.verify import check_plan

    return check_plan(plan).to_json()
