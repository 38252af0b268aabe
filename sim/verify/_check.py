"""Exact verification of a planned show: separation, speeds, acceleration, altitude.

Separation is checked *continuously in time*, not sampled. Within a segment
every drone follows p_i(β) = A_i + β·D_i with one shared β in [0, 1], so a
pair's offset is a + β·c (a = A_j - A_i, c = D_j - D_i) and its minimum over
β has the closed form β* = clip(-a·c / c·c, 0, 1).

Candidate pairs come from ``scipy.spatial.cKDTree`` in β-slices, with a radius
that provably misses no pair: subtracting the mean motion (which does not change
any pair's distance), each drone moves at most L_i·h/2 away from its position at
the centre of a slice of width h, so a pair that comes within r somewhere in the
slice is within r + L_max·h at its centre. With h = 1/ceil(L_max/r) the query
radius is at most 2r.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from pydantic import BaseModel, Field
from scipy.spatial import cKDTree

from sim.plan._plan import ShowPlan
from sim.plan._quintic import PEAK_ACCEL_FACTOR, PEAK_SPEED_FACTOR, TAU_PEAK_ACCEL, invert_rest_to_rest

#: Relative tolerance on the limits, so that a value equal to its limit passes despite rounding.
_TOL = 1e-9
#: Violations listed in a report (all are counted in ``violations_total``).
MAX_LISTED_VIOLATIONS = 200
#: Drones named in one speed / acceleration / altitude violation.
MAX_DRONES_PER_VIOLATION = 10


class Violation(BaseModel):
    """One broken limit: which drones, when, the value and the limit."""

    kind: str = Field(description="min_distance, speed_xy, speed_z, acceleration, altitude or transition_duration.")
    drones: list[int] = Field(description="Drone indices involved (for speeds: the worst first, at most 10).")
    time_s: float = Field(description="When the value is reached, seconds from the start of the show.")
    value: float = Field(description="The offending value (metres, m/s, m/s² or seconds).")
    limit: float = Field(description="The limit it breaks, same unit.")
    segment: int = Field(description="Index of the show segment.")
    message: str = Field(description="One human-readable line.")


class CaptPremise(BaseModel):
    """CAPT's guarantee beside the exact result for one transition."""

    start_spacing_m: float
    goal_spacing_m: float
    guaranteed_min_distance_m: float = Field(description="min(start, goal spacing)/√2, metres.")
    exact_min_distance_m: float = Field(description="The exact minimum over the transition, metres.")
    holds: bool = Field(description="exact >= guaranteed (it must; False would be a planner bug).")


class TransitionReport(BaseModel):
    """A planned CAPT transition."""

    model_config = {"populate_by_name": True}

    from_: str = Field(alias="from")
    to: str
    segment: int
    start_s: float
    duration_s: float
    min_duration_s: float = Field(description="Shortest duration the limits allow, seconds (0.1 s steps).")
    assignment_cost_m2: float = Field(description="Σ squared distance of the optimal assignment, m².")
    capt: CaptPremise


class CheckReport(BaseModel):
    """Plan summary and exact verification report (``swarmshow check --json``)."""

    ok: bool
    show: str
    drones: int
    duration_s: float
    min_distance_m: float
    min_distance_pair: list[int]
    min_distance_time_s: float
    max_speed_xy_mps: float
    max_speed_z_mps: float
    max_accel_mps2: float
    max_altitude_m: float
    min_altitude_m: float
    limits: dict[str, float]
    transitions: list[TransitionReport]
    violations: list[Violation]
    violations_total: int

    def to_json(self) -> dict:
        """JSON-ready dict with DESIGN.md's key names (``from``, not ``from_``)."""
        return self.model_dump(mode="json", by_alias=True)


class _PairMinima:
    """Exact pair minima of one segment: i < j, distance (m), β at the minimum."""

    def __init__(self, i: np.ndarray, j: np.ndarray, dist: np.ndarray, beta: np.ndarray) -> None:
        self.i, self.j, self.dist, self.beta = i, j, dist, beta


def _closest_pair_distance(points: np.ndarray) -> float:
    if len(points) < 2:
        return math.inf
    d, _ = cKDTree(points).query(points, k=2)
    return float(d[:, 1].min())


def segment_close_pairs(start_m: np.ndarray, end_m: np.ndarray, radius_m: float) -> _PairMinima:
    """Every pair whose exact minimum distance during the segment is <= ``radius_m``.

    Args:
        start_m, end_m: (N, 3) positions at β = 0 and β = 1, metres.
        radius_m: search radius, metres (> 0).

    Returns:
        The pairs (i < j) with their exact minimum distance and the β where it occurs.
    """
    n = len(start_m)
    empty = _PairMinima(*(np.zeros(0, dtype=np.int64),) * 2, np.zeros(0), np.zeros(0))
    if n < 2:
        return empty
    motion = end_m - start_m
    motion = motion - motion.mean(axis=0)  # a common translation changes no distance
    l_max = float(np.sqrt((motion**2).sum(axis=1).max()))
    slices = max(1, math.ceil(l_max / radius_m)) if l_max > 1e-12 else 1
    h = 1.0 / slices
    query_r = radius_m + l_max * h
    found = []
    for s in range(slices):
        centre = start_m + ((s + 0.5) * h) * motion
        pairs = cKDTree(centre).query_pairs(query_r, output_type="ndarray")
        if len(pairs):
            found.append(pairs[:, 0].astype(np.int64) * n + pairs[:, 1])
    if not found:
        return empty
    keys = np.unique(np.concatenate(found))
    i, j = np.minimum(keys // n, keys % n), np.maximum(keys // n, keys % n)
    a = start_m[j] - start_m[i]
    c = motion[j] - motion[i]
    cc = (c * c).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        beta = np.where(cc > 0, np.clip(-(a * c).sum(axis=1) / cc, 0.0, 1.0), 0.0)
    dist = np.linalg.norm(a + beta[:, None] * c, axis=1)
    keep = dist <= radius_m
    return _PairMinima(i[keep], j[keep], dist[keep], beta[keep])


def check_plan(plan: ShowPlan, *, progress: Callable[[float], None] | None = None) -> CheckReport:
    """Verify a plan exactly against its show's limits.

    Args:
        plan: the planned show.
        progress: optional callback receiving the fraction done in [0, 1].
    """
    s = plan.settings
    limit_d = s.min_distance_m
    P = plan.knot_positions_m
    times = plan.knot_times_s
    violations: list[Violation] = []

    best = (math.inf, (0, 0), 0.0)
    peak_xy = peak_z = peak_acc = 0.0
    seg_min: dict[int, float] = {}
    closest_at_knot = [_closest_pair_distance(P[0])]

    for k, seg in enumerate(plan.segments):
        A, B, T = P[k], P[k + 1], seg.duration_s
        closest_at_knot.append(_closest_pair_distance(B) if seg.kind != "hold" else closest_at_knot[-1])
        upper = min(closest_at_knot[-2], closest_at_knot[-1])
        radius = max(limit_d, upper) if math.isfinite(upper) else limit_d
        pairs = segment_close_pairs(A, B, radius)
        if len(pairs.dist):
            m = int(np.argmin(pairs.dist))
            seg_min[k] = float(pairs.dist[m])
            if pairs.dist[m] < best[0]:
                t_m = seg.start_s + T * float(invert_rest_to_rest(pairs.beta[m]))
                best = (float(pairs.dist[m]), (int(pairs.i[m]), int(pairs.j[m])), t_m)
            bad = np.flatnonzero(pairs.dist < limit_d * (1 - _TOL))
            bad = bad[np.argsort(pairs.dist[bad], kind="stable")]
            tau = invert_rest_to_rest(pairs.beta[bad])
            for q, tq in zip(bad, tau, strict=True):
                i, j, d = int(pairs.i[q]), int(pairs.j[q]), float(pairs.dist[q])
                t_q = seg.start_s + T * float(tq)
                violations.append(
                    Violation(
                        kind="min_distance", drones=[i, j], time_s=t_q, value=d, limit=limit_d, segment=k,
                        message=f"drones {i} and {j} come {d:.3f} m apart at t = {t_q:.2f} s "
                        f"({seg.kind} {seg.label!r}); the minimum is {limit_d} m",
                    )
                )

        D = B - A
        for kind, per_drone, limit, factor, tau_peak, unit in (
            ("speed_xy", np.hypot(D[:, 0], D[:, 1]), s.max_speed_xy_mps, PEAK_SPEED_FACTOR / T, 0.5, "m/s"),
            ("speed_z", np.abs(D[:, 2]), s.max_speed_z_mps, PEAK_SPEED_FACTOR / T, 0.5, "m/s"),
            ("acceleration", np.linalg.norm(D, axis=1), s.max_accel_mps2, PEAK_ACCEL_FACTOR / T**2,
             TAU_PEAK_ACCEL, "m/s²"),
        ):
            values = per_drone * factor
            top = float(values.max()) if len(values) else 0.0
            if kind == "speed_xy":
                peak_xy = max(peak_xy, top)
            elif kind == "speed_z":
                peak_z = max(peak_z, top)
            else:
                peak_acc = max(peak_acc, top)
            if top > limit * (1 + _TOL):
                over = np.flatnonzero(values > limit * (1 + _TOL))
                worst = over[np.argsort(-values[over], kind="stable")][:MAX_DRONES_PER_VIOLATION]
                t_v = seg.start_s + tau_peak * T
                violations.append(
                    Violation(
                        kind=kind, drones=[int(d) for d in worst], time_s=t_v, value=top, limit=limit, segment=k,
                        message=f"{len(over)} drone(s) exceed {kind} {limit} {unit} in {seg.kind} "
                        f"{seg.label!r}: drone {int(worst[0])} reaches {top:.3f} {unit} at t = {t_v:.2f} s",
                    )
                )
        if progress:
            progress((k + 1) / len(plan.segments))

    z = P[:, :, 2]
    max_alt, min_alt = float(z.max()), float(z.min())
    if max_alt > s.max_altitude_m * (1 + _TOL):
        kk, d = np.unravel_index(int(np.argmax(z)), z.shape)
        violations.append(
            Violation(
                kind="altitude", drones=[int(d)], time_s=float(times[kk]), value=max_alt, limit=s.max_altitude_m,
                segment=max(int(kk) - 1, 0),
                message=f"drone {int(d)} reaches {max_alt:.3f} m, above max_altitude_m {s.max_altitude_m}",
            )
        )

    transitions = []
    for tr in plan.transitions:
        exact = seg_min.get(tr.segment, math.inf)
        guaranteed = tr.guaranteed_separation_m
        transitions.append(
            TransitionReport(
                **{"from": tr.from_name},
                to=tr.to_name, segment=tr.segment, start_s=tr.start_s, duration_s=tr.duration_s,
                min_duration_s=tr.min_duration_s, assignment_cost_m2=tr.assignment_cost_m2,
                capt=CaptPremise(
                    start_spacing_m=_finite(tr.start_spacing_m), goal_spacing_m=_finite(tr.goal_spacing_m),
                    guaranteed_min_distance_m=_finite(guaranteed), exact_min_distance_m=_finite(exact),
                    holds=bool(exact >= guaranteed - 1e-9),
                ),
            )
        )
        if tr.duration_s < tr.min_duration_s - 1e-9:
            violations.append(
                Violation(
                    kind="transition_duration", drones=[], time_s=tr.start_s, value=tr.duration_s,
                    limit=tr.min_duration_s, segment=tr.segment,
                    message=f"transition {tr.from_name!r} -> {tr.to_name!r} lasts {tr.duration_s} s; "
                    f"the limits need at least {tr.min_duration_s:.1f} s",
                )
            )

    violations.sort(key=lambda v: (v.time_s, v.kind))
    min_d, pair, t_min = best
    return CheckReport(
        ok=not violations,
        show=plan.show_name,
        drones=plan.drone_count,
        duration_s=plan.duration_s,
        min_distance_m=_finite(min_d),
        min_distance_pair=list(pair),
        min_distance_time_s=t_min,
        max_speed_xy_mps=peak_xy,
        max_speed_z_mps=peak_z,
        max_accel_mps2=peak_acc,
        max_altitude_m=max_alt,
        min_altitude_m=min_alt,
        limits={
            "min_distance_m": s.min_distance_m,
            "max_speed_xy_mps": s.max_speed_xy_mps,
            "max_speed_z_mps": s.max_speed_z_mps,
            "max_accel_mps2": s.max_accel_mps2,
            "max_altitude_m": s.max_altitude_m,
        },
        transitions=transitions,
        violations=violations[:MAX_LISTED_VIOLATIONS],
        violations_total=len(violations),
    )


def _finite(x: float) -> float:
    """JSON has no infinity: a single drone's 'closest pair' is reported as -1."""
    return float(x) if math.isfinite(x) else -1.0


def check_show(show, *, progress: Callable[[float], None] | None = None) -> CheckReport:
    """Plan ``show`` (forced durations flown as asked) and verify it exactly.

    Args:
        show: a validated :class:`formations.ShowFile`.
        progress: optional callback receiving the fraction done in [0, 1]
            (planning is the first half, verification the second).
    """
    from sim.plan._plan import plan_show

    half = (lambda f: progress(0.5 * f)) if progress else None
    plan = plan_show(show, enforce_limits=False, progress=half)
    return check_plan(plan, progress=(lambda f: progress(0.5 + 0.5 * f)) if progress else None)
