"""``crazyswarm``: one polynomial trajectory CSV per drone in Crazyswarm's ``uav_trajectory`` format.

Each file has the header ``duration,x^0,...,x^7,y^0,...,y^7,z^0,...,z^7,yaw^0,...,yaw^7,``
and one row per piece: its duration in seconds, then the coefficients of x, y,
z (metres) and yaw (radians, always 0) in ascending powers of the piece's local
time t in [0, duration] (``uav_trajectory.Trajectory.loadcsv`` /
``Polynomial4D``; the Crazyflie firmware's ``poly4d``).

The plan is converted exactly, no fitting: every drone has its own polynomial
pieces (``plan.motion``: its own break times, degree <= 5 in the piece's local
time), which are exactly this format's pieces (degrees 6 and 7 zero). Zero-length
pieces carry no motion and are dropped; wherever a drone does not move (holds,
waiting for its turn in a staggered transition, transitions in which it keeps its
place) consecutive constant pieces merge into one, which keeps the piece count down.

Frame: the show's local x, y, z, then ``--scale`` and ``--offset`` (p' = scale·p +
offset: an outdoor show flown indoors, the origin placed in the motion-capture
frame); times are kept, so speeds and accelerations scale with ``scale``.

Piece limit: a Crazyflie's trajectory memory (4 KiB) holds :data:`CRAZYFLIE_MAX_PIECES`
= 31 pieces. When a drone needs more, every drone's trajectory is cut at the same
show times, in the middle of holds or at the end of the takeoff and the start of the landing (all drones
at rest), into parts of at most
:data:`PART_MAX_PIECES` = 15 pieces (``drone_001.part1.csv``, ...): part k is uploaded
at piece offset 0 (k odd) or 16 (k even), so the next part uploads into the other
half of the memory while the current one flies (Crazyswarm's
``uploadTrajectory(trajectoryId, pieceOffset, trajectory)``), and all drones start
part k together at its start time (``manifest.json``: ``parts``). If no such cut
exists (more than 15 pieces between two holds), the export refuses, naming the drones.
"""

from __future__ import annotations

import math

import numpy as np

from app.exports._archive import ZipBuilder, base_manifest, safe_stem
from app.exports._core import ExportContext, ExportError, ExportResult, require_planned

#: Pieces a Crazyflie 2.x holds in its 4 KiB trajectory memory (132 bytes per poly4d piece).
CRAZYFLIE_MAX_PIECES = 31
HEADER = (
    "duration,"
    + ",".join(f"{axis}^{k}" for axis in ("x", "y", "z", "yaw") for k in range(8))
    + ",\n"
)
# Degrees 0-5 of x, y, z: 19 numbers a row, degrees 6, 7 and yaw written as literal zeros.
_AXIS_FMT = "%.12g,%.12g,%.12g,%.12g,%.12g,%.12g,0,0"
_ROW_FMT = "%.12g," + ",".join([_AXIS_FMT] * 3) + "," + ",".join(["0"] * 8) + "\n"
#: Drones per formatting block.
_BLOCK = 64

#: Pieces per part when a trajectory is split: two consecutive parts fit the memory together.
PART_MAX_PIECES = 15
#: Piece offsets of odd and even parts (the two halves of the trajectory memory).
PART_OFFSETS = (0, 16)

_README = """\
Crazyswarm polynomial trajectories (one file per drone) made by swarmshow.

Each CSV is in the uav_trajectory format of Crazyswarm / Crazyswarm2: a header
"duration,x^0,...,x^7,y^0,...,y^7,z^0,...,z^7,yaw^0,...,yaw^7," and one row per
piece with its duration (s) and the polynomial coefficients in ascending powers
of the piece's local time (metres; yaw 0 rad). The pieces reproduce the plan
exactly (each drone's own polynomial pieces, rests as constant pieces).

Frame: the show's local x, y, z (metres; +y at bearing {heading:g} deg outdoors),
scaled by {scale:g} and offset by ({ox:g}, {oy:g}, {oz:g}) m: positions are absolute
in your motion-capture frame. Times are not scaled: speeds are {scale:g} x the show's.

Operator notes:
- The trajectory starts at t = 0 ON THE GROUND at the drone's home position and
  includes its own takeoff and landing: do not call takeoff() / land() around it.
- Place each drone at its home (the first row's x^0, y^0, z^0) before starting.
- Load with uav_trajectory.Trajectory().loadcsv(path), upload with
  cf.uploadTrajectory(trajectoryId, pieceOffset, traj), start with
  startTrajectory(trajectoryId, timescale=1.0, reverse=False, relative=False):
  relative=False, because the positions are absolute (relative=True would add
  the drone's current position to every point).
- A Crazyflie holds {max_pieces} pieces. {parts_note}
"""

_ONE_PART = "Every drone fits: one file per drone, upload at pieceOffset 0, start all together at t = 0."
_PARTS = """This show needs more, so each drone's trajectory is cut into
  {n} parts at the same show times where every drone is at rest: in the middle of
  holds, at the end of the takeoff or at the start of the landing (manifest.json
  "parts": start time, duration, piece offset of each part).
  Files drone_NNN.partK.csv. Part K is uploaded at pieceOffset 0 (K odd) or 16
  (K even), with trajectoryId K: upload parts 1 and 2 before the show, start part 1
  on all drones at t = 0; when part K ends (at its start + duration) start part K+1
  on all drones, then upload part K+2 into the half part K used while K+1 flies."""


def piece_table(plan) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """All drones' pieces, drone-major.

    Returns:
        ``drone`` (P,) drone index of each piece, ``start`` (P,) its start time (s),
        ``duration`` (P,) seconds, ``coef`` (P, 3, 8) coefficients (metres, ascending
        powers of local time in seconds), and ``counts`` (N,) pieces per drone.
    """
    motion = plan.motion
    breaks, coeffs = motion.breaks_s, motion.coeffs_m  # (N, P+1), (N, P, 3, D+1)
    n = motion.drone_count
    # Zero-length pieces (a vanished profile phase, padding) carry no motion: drop them.
    drone, piece = np.nonzero(np.diff(breaks, axis=1) > 0)  # row-major: drone by drone, in time order
    constant = ~np.any(coeffs[drone, piece, :, 1:] != 0.0, axis=(1, 2))
    first = np.r_[True, drone[1:] != drone[:-1]]
    # A constant piece right after another constant piece of the same drone continues it
    # (the motion is continuous, so both hold the same position): one piece.
    new_piece = first | ~constant | ~np.r_[False, constant[:-1]]
    drone, piece = drone[new_piece], piece[new_piece]
    start = breaks[drone, piece]
    end = np.empty_like(start)
    end[:-1] = start[1:]
    last = np.r_[drone[1:] != drone[:-1], True]
    end[last] = breaks[drone[last], -1]
    coef = np.zeros((len(drone), 3, 8))
    coef[:, :, : coeffs.shape[-1]] = coeffs[drone, piece]
    counts = np.bincount(drone, minlength=n)
    return drone, start, end - start, coef, counts


def _shift_matrix(delta: np.ndarray) -> np.ndarray:
    """(P, 8, 8) M with c'_j = Σ_k M[j, k]·c_k: the polynomial re-expanded ``delta`` seconds later.

    Taylor shift: p(u + δ) = Σ_k c_k (u + δ)^k = Σ_j u^j Σ_{k>=j} C(k, j) δ^(k-j) c_k.
    """
    j, k = np.arange(8)[:, None], np.arange(8)[None, :]
    binom = np.array([[math.comb(int(b), int(a)) if b >= a else 0 for b in range(8)] for a in range(8)], float)
    power = np.where(k >= j, k - j, 0)
    return binom[None] * np.where(k >= j, delta[:, None, None] ** power[None], 0.0)


def cut_at(drone, start, duration, coef, n: int, cuts_s: np.ndarray):
    """The piece table with every piece that straddles a time in ``cuts_s`` split there (exact).

    Returns the new ``(drone, start, duration, coef)``, drone-major and in time order.
    """
    for cut in cuts_s:
        inside = np.flatnonzero((start < cut - 1e-9) & (start + duration > cut + 1e-9))
        if not len(inside):
            continue
        left = cut - start[inside]
        right_coef = np.einsum("pjk,pak->paj", _shift_matrix(left), coef[inside])
        order = np.argsort(np.r_[np.arange(len(drone)), inside + 0.5], kind="stable")
        drone = np.r_[drone, drone[inside]][order]
        new_start = np.r_[start, np.full(len(inside), cut)]
        new_dur = np.r_[duration, start[inside] + duration[inside] - cut]
        new_dur[inside] = left
        start, duration = new_start[order], new_dur[order]
        coef = np.concatenate([coef, right_coef])[order]
    return drone, start, duration, coef


def plan_parts(plan, drone, start, duration, n: int, names: list[str], coef: np.ndarray | None = None) -> np.ndarray:
    """Show times at which to cut every drone's trajectory so each part has <= PART_MAX_PIECES pieces.

    Candidates are the middles of holds (all drones at rest; in a moving hold, the instants
    where every drone rests), the end of the takeoff and the start of the landing (where every drone
    rests); greedily, each part runs
    to the last candidate it can reach. Raises :class:`ExportError` naming the drones
    that need more than PART_MAX_PIECES pieces between two candidates.
    """
    end = start + duration
    # (coef: the pieces' (P, 3, 8) coefficients, to tell moving pieces; without them every hold is still.)
    moving = np.zeros(len(start), bool) if coef is None else ~np.all(coef[:, :, 1:] == 0.0, axis=(1, 2))

    def still(a: float, b: float) -> bool:
        """No drone moves inside (a, b)."""
        return not np.any(moving & (start < b - 1e-9) & (end > a + 1e-9))

    def rests(a: float, b: float) -> list[float]:
        """Instants in [a, b] at which every drone rests: a moving hold's (issue 21) piece breaks with
        zero velocity (its start and end, and its "smooth" keys)."""
        t = np.unique(np.r_[start, end])
        t = t[(t >= a - 1e-9) & (t <= b + 1e-9)]
        v = plan.motion.evaluate(t).velocities_mps
        return [float(x) for x in t[np.abs(v).max(axis=(1, 2), initial=0.0) < 1e-9]]

    cands = [
        c for s in plan.segments if s.kind == "hold" and s.duration_s > 0
        for c in ([s.start_s + s.duration_s / 2] if still(s.start_s, s.end_s) else rests(s.start_s, s.end_s))
    ]
    # The end of the takeoff and the start of the landing: every drone rests there (a vertical rest-to-rest leg
    # meets a transition that starts or ends at rest), in waves (sim.plan._waves) or not. Without them a show
    # whose first transition is layered (7 takeoff pieces + ~14) could not be cut at all: the parts switch there
    # with no upload (parts 1 and 2 are both in memory before the show), the drones hovering meanwhile.
    edges = np.array([s.end_s for s in plan.segments if s.kind == "takeoff"]
                     + [s.start_s for s in plan.segments if s.kind == "landing"], dtype=np.float64)
    if edges.size:
        v = plan.motion.evaluate(edges).velocities_mps  # (E, N, 3)
        cands += [float(t) for t in edges[np.abs(v).max(axis=(1, 2), initial=0.0) < 1e-9]]
    candidates = np.array(sorted(cands))

    def pieces_in(a: float, b: float) -> np.ndarray:
        """(N,) pieces each drone flies in [a, b] once cut at a and b."""
        overlap = (start < b - 1e-9) & (end > a + 1e-9)
        return np.bincount(drone[overlap], minlength=n)

    cuts: list[float] = []
    a = 0.0
    horizon = float(end.max()) if len(end) else 0.0
    while pieces_in(a, horizon).max() > PART_MAX_PIECES:
        reachable = [c for c in candidates if c > a + 1e-9 and pieces_in(a, c).max() <= PART_MAX_PIECES]
        if not reachable:
            nxt = [c for c in candidates if c > a + 1e-9]
            b = nxt[0] if nxt else horizon
            bad = np.flatnonzero(pieces_in(a, b) > PART_MAX_PIECES)
            shown = ", ".join(names[i] for i in bad[:10]) + (f" and {len(bad) - 10} more" if len(bad) > 10 else "")
            # A transition that alone needs more than a part holds (no drone rests inside it: a layered or
            # blended one) cannot be cut; more holds cannot help, so say which it is.
            crowded = [(seg.label, int(pieces_in(seg.start_s, seg.end_s).max())) for seg in plan.segments
                       if seg.kind == "transition" and seg.start_s < b - 1e-9 and seg.end_s > a + 1e-9]
            crowded = [(label, k) for label, k in crowded if k > PART_MAX_PIECES]
            why = ("; " + ", ".join(f"the transition into {label!r} alone needs {k} pieces" for label, k in crowded)
                   + " (no instant inside it where every drone rests): space its formations wider so that it is "
                   "flown on straight lines, or fly .skyc" if crowded else "; add a hold or use fewer formations")
            raise ExportError(
                f"crazyswarm: {len(bad)} drone(s) need more than {PART_MAX_PIECES} trajectory pieces between "
                f"t = {a:.1f} s and {b:.1f} s with no hold to split at, so the trajectory cannot be uploaded to a "
                f"Crazyflie (31 pieces) in parts: {shown}{why}"
            )
        a = max(reachable)
        cuts.append(a)
    return np.array(cuts)


def export_crazyswarm(ctx: ExportContext) -> ExportResult:
    """Build the Crazyswarm zip (see the module docstring)."""
    require_planned(ctx)
    plan = ctx.plan
    names = ctx.drone_names
    n = ctx.show.drones
    drone, start, duration, coef, counts = piece_table(plan)
    # Scale and offset (indoor shows): p' = scale·p + offset, exactly on the coefficients.
    scale, offset = ctx.options.scale, np.asarray(ctx.options.offset_m, dtype=np.float64)
    coef = coef * scale
    coef[:, :, 0] += offset
    cuts = np.zeros(0)
    if counts.max(initial=0) > CRAZYFLIE_MAX_PIECES:
        cuts = plan_parts(plan, drone, start, duration, n, names, coef)
        drone, start, duration, coef = cut_at(drone, start, duration, coef, n, cuts)
    ctx.progress(0.2)
    bounds_s = np.r_[0.0, cuts, plan.duration_s]
    n_parts = len(bounds_s) - 1
    part = np.searchsorted(cuts, start + 1e-9, side="right") if n_parts > 1 else np.zeros(len(drone), np.int64)
    # Rows grouped by (drone, part), in time order: drone-major already, part non-decreasing per drone.
    key = drone * n_parts + part
    header = HEADER.encode()
    # Columns in row order: duration, then c0..c5 for x, y, z.
    values = np.concatenate([duration[:, None], coef[:, :, :6].reshape(len(drone), 18)], axis=1)
    values += 0.0  # -0.0 (from -15·0) would print as "-0"
    per_key = np.bincount(key, minlength=n * n_parts)
    bounds = np.r_[0, np.cumsum(per_key)]
    z = ZipBuilder()
    for a in range(0, n, _BLOCK):
        b = min(a + _BLOCK, n)
        for i in range(a, b):
            for k in range(n_parts):
                rows = values[bounds[i * n_parts + k] : bounds[i * n_parts + k + 1]]
                text = (_ROW_FMT * len(rows)) % tuple(rows.ravel().tolist())
                name = f"{names[i]}.csv" if n_parts == 1 else f"{names[i]}.part{k + 1}.csv"
                z.add(name, header + text.encode())
        ctx.progress(0.2 + 0.75 * b / n)
    pieces = per_key.reshape(n, n_parts)
    parts = [
        {"part": k + 1, "start_s": round(float(bounds_s[k]), 6), "duration_s": round(float(bounds_s[k + 1] -
                                                                                            bounds_s[k]), 6),
         "piece_offset": PART_OFFSETS[k % 2] if n_parts > 1 else 0, "max_pieces": int(pieces[:, k].max())}
        for k in range(n_parts)
    ]
    if n_parts > 1:
        ctx.warn(
            f"crazyswarm: drones need up to {int(counts.max())} trajectory pieces, more than the "
            f"{CRAZYFLIE_MAX_PIECES} a Crazyflie holds: each trajectory is split into {n_parts} parts at holds "
            f"(upload and start them in turn; see README.txt)"
        )
    off = ctx.options.offset_m
    z.add_manifest(
        base_manifest(
            ctx,
            fmt="crazyswarm",
            scale=scale,
            offset_m=list(off),
            frame="local x, y, z scaled by 'scale' then offset by 'offset_m': absolute mocap-frame metres",
            max_pieces_per_drone=int(pieces.max(initial=0)),
            crazyflie_piece_limit=CRAZYFLIE_MAX_PIECES,
            parts=parts,
            pieces={names[i]: pieces[i].tolist() if n_parts > 1 else int(pieces[i, 0]) for i in range(n)},
            warnings=list(ctx.warnings),
        ),
        _README.format(max_pieces=CRAZYFLIE_MAX_PIECES, heading=ctx.options.heading_deg, scale=scale,
                       ox=off[0], oy=off[1], oz=off[2],
                       parts_note=_ONE_PART if n_parts == 1 else _PARTS.format(n=n_parts)),
    )
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}-crazyswarm.zip",
        media_type="application/zip",
        content=z.finish(),
    )
