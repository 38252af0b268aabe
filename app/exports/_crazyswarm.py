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
place) consecutive constant pieces merge into one, which keeps the piece count
down: the Crazyflie's trajectory memory (4 KiB) holds 31 pieces, and the export
warns about drones that need more.
"""

from __future__ import annotations

import numpy as np

from app.exports._archive import ZipBuilder, base_manifest, safe_stem
from app.exports._core import ExportContext, ExportResult, require_planned

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

_README = """\
Crazyswarm polynomial trajectories (one file per drone) made by swarmshow.

Each CSV is in the uav_trajectory format of Crazyswarm / Crazyswarm2: a header
"duration,x^0,...,x^7,y^0,...,y^7,z^0,...,z^7,yaw^0,...,yaw^7," and one row per
piece with its duration (s) and the polynomial coefficients in ascending powers
of the piece's local time (metres; yaw 0 rad). Load with
uav_trajectory.Trajectory().loadcsv(path), upload with cf.uploadTrajectory(...).
Times start at 0 on the ground at the drone's home position (the first piece
is the takeoff). The pieces reproduce the plan exactly (each drone's own
polynomial pieces, rests as constant pieces). A Crazyflie holds at most {max_pieces}
pieces; see manifest.json for the per-drone counts.
"""


def piece_table(plan) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """All drones' pieces, drone-major.

    Returns:
        ``drone`` (P,) drone index of each piece, ``duration`` (P,) seconds,
        ``coef`` (P, 3, 8) coefficients (metres, ascending powers of local
        time in seconds), and ``counts`` (N,) pieces per drone.
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
    return drone, end - start, coef, counts


def export_crazyswarm(ctx: ExportContext) -> ExportResult:
    """Build the Crazyswarm zip (see the module docstring)."""
    require_planned(ctx)
    plan = ctx.plan
    drone, duration, coef, counts = piece_table(plan)
    ctx.progress(0.2)
    names = ctx.drone_names
    n = ctx.show.drones
    header = HEADER.encode()
    # Columns in row order: duration, then c0..c5 for x, y, z.
    values = np.concatenate([duration[:, None], coef[:, :, :6].reshape(len(drone), 18)], axis=1)
    values += 0.0  # -0.0 (from -15·0) would print as "-0"
    bounds = np.r_[0, np.cumsum(counts)]
    z = ZipBuilder()
    for a in range(0, n, _BLOCK):
        b = min(a + _BLOCK, n)
        for i in range(a, b):
            rows = values[bounds[i] : bounds[i + 1]]
            text = (_ROW_FMT * len(rows)) % tuple(rows.ravel().tolist())
            z.add(f"{names[i]}.csv", header + text.encode())
        ctx.progress(0.2 + 0.75 * b / n)
    too_many = np.flatnonzero(counts > CRAZYFLIE_MAX_PIECES)
    if len(too_many):
        worst = int(counts.max())
        ctx.warn(
            f"{len(too_many)} drone(s) need more than the {CRAZYFLIE_MAX_PIECES} trajectory pieces a Crazyflie holds "
            f"(up to {worst}, e.g. {names[int(too_many[0])]}); upload the trajectory in parts or use fewer formations"
        )
    z.add_manifest(
        base_manifest(
            ctx,
            fmt="crazyswarm",
            max_pieces_per_drone=int(counts.max()),
            crazyflie_piece_limit=CRAZYFLIE_MAX_PIECES,
            pieces={names[i]: int(counts[i]) for i in range(n)},
            warnings=list(ctx.warnings),
        ),
        _README.format(max_pieces=CRAZYFLIE_MAX_PIECES),
    )
    return ExportResult(
        filename=f"{safe_stem(ctx.show.name)}-crazyswarm.zip",
        media_type="application/zip",
        content=z.finish(),
    )
