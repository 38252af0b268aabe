"""Per-drone piecewise-polynomial trajectories: the plan's one representation of motion.

Every drone's position over the whole show is a sequence of polynomial pieces of
degree <= :data:`DEGREE` in local time ``u = t - breaks_s[i, p]``:

* ``breaks_s``: (N, P+1) float64, nondecreasing along each row; every row starts at
  the same show start and ends at the same show end. Pieces may have zero length
  (a phase of a profile that vanishes, or padding); a zero-length piece carries the
  Taylor polynomial of the motion at its instant, so evaluating exactly there is
  still right.
* ``coeffs_m``: (N, P, 3, DEGREE+1) float64, ascending powers: the position on
  piece p is Σ_k coeffs_m[i, p, :, k]·u^k (metres; coefficient k in m/s^k).

Drones do not share piece boundaries: each has its own departure time and time law
(the planner staggers drones to keep them apart), so everything that consumes
motion (verification, flight references, playback, exports) reads this table, never
a shared time law. Pieces are looked up by a compiled binary search per drone, so evaluation stays
vectorised over drones; compiled frame loops (playback, the light effects) instead walk a piece
cursor per drone from frame to frame and evaluate by Horner's rule with the inlined helpers here
(:func:`step_piece`, :func:`position_at`, :func:`velocity_at`, :func:`states_at`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

#: Highest polynomial degree of a piece (the paper's quintic; jerk-limited profiles are cubic).
DEGREE = 5


@njit(inline="always", cache=True)
def _piece_of(b: np.ndarray, p: int, t: float) -> int:
    """Number of interior breaks ``b[1 .. p-1]`` at or before t (binary search, side="right"): t's piece."""
    lo, hi = 1, p
    while lo < hi:
        mid = (lo + hi) // 2
        if b[mid] <= t:
            lo = mid + 1
        else:
            hi = mid
    return lo - 1


@njit(inline="always", cache=True)
def _horner(c: np.ndarray, n: int, u: float) -> float:
    """``c[0] + c[1] u + ... + c[n-1] u^(n-1)`` by Horner's rule, highest coefficient first."""
    h: float = c[n - 1]
    for q in range(n - 2, -1, -1):
        h = h * u + c[q]
    return h


@njit(cache=True, nogil=True)
def _search_pieces(breaks_s: np.ndarray, rows: np.ndarray, times_s: np.ndarray, out: np.ndarray) -> None:
    """out[k, j] = number of interior breaks of drone rows[j] at or before times_s[k], at most P-1."""
    p = breaks_s.shape[1] - 1
    for j in range(rows.shape[0]):
        b = breaks_s[rows[j]]
        for k in range(times_s.shape[0]):
            out[k, j] = _piece_of(b, p, times_s[k])


@njit(inline="always", cache=True)
def step_piece(breaks_s: np.ndarray, i: int, p: int, t: float) -> int:
    """Drone i's piece at time ``t`` (the last starting at or before t), walked from its piece ``p``.

    The cursor search of playback and frame loops: between frames a drone moves a piece or two,
    so walking from the last one beats a binary search (forwards while playing, either way when
    scrubbing). ``t`` must lie in the show; it picks the piece :meth:`Trajectories.piece_index` picks.
    """
    last = breaks_s.shape[1] - 2
    while p < last and breaks_s[i, p + 1] <= t:
        p += 1
    while p > 0 and breaks_s[i, p] > t:
        p -= 1
    return p


@njit(inline="always", cache=True)
def _horner_at(coeffs_m: np.ndarray, i: int, p: int, a: int, u: float, deg: int) -> float:
    """Σ_{k<=deg} coeffs_m[i, p, a, k]·u^k by Horner's rule, highest power first."""
    acc: float = coeffs_m[i, p, a, deg]
    for k in range(deg - 1, -1, -1):
        acc = acc * u + coeffs_m[i, p, a, k]
    return acc


@njit(inline="always", cache=True)
def _horner_slope_at(coeffs_m: np.ndarray, i: int, p: int, a: int, u: float, deg: int) -> float:
    """Σ_{1<=k<=deg} k·coeffs_m[i, p, a, k]·u^(k-1) by Horner's rule, highest power first."""
    acc: float = deg * coeffs_m[i, p, a, deg]
    for k in range(deg - 1, 0, -1):
        acc = acc * u + k * coeffs_m[i, p, a, k]
    return acc


@njit(inline="always", cache=True)
def position_at(coeffs_m: np.ndarray, i: int, p: int, a: int, u: float) -> float:
    """Drone i's coordinate ``a`` (m) on piece p, ``u`` s into it: Σ_k coeffs_m[i, p, a, k]·u^k."""
    # The planner's tables have degree DEGREE: a loop of constant length, which the compiler unrolls
    # (about 1.7 times faster than a loop over the array's last axis).
    if coeffs_m.shape[3] == DEGREE + 1:
        return _horner_at(coeffs_m, i, p, a, u, DEGREE)
    return _horner_at(coeffs_m, i, p, a, u, coeffs_m.shape[3] - 1)


@njit(inline="always", cache=True)
def velocity_at(coeffs_m: np.ndarray, i: int, p: int, a: int, u: float) -> float:
    """The derivative (m/s) of :func:`position_at`: Σ_k k·coeffs_m[i, p, a, k]·u^(k-1)."""
    if coeffs_m.shape[3] == DEGREE + 1:
        return _horner_slope_at(coeffs_m, i, p, a, u, DEGREE)
    return _horner_slope_at(coeffs_m, i, p, a, u, coeffs_m.shape[3] - 1)


@njit(cache=True)
def states_at(breaks_s: np.ndarray, coeffs_m: np.ndarray, times_s: np.ndarray, cursor: np.ndarray,
              pos_m: np.ndarray, vel_mps: np.ndarray) -> None:  # pragma: no cover - compiled
    """Every drone's position and velocity at ``times_s`` (T,), each on its own piece: (T, N, 3) into
    ``pos_m``, ``vel_mps``.

    ``cursor`` (N,) holds each drone's piece from the previous call and is moved by
    :func:`step_piece`; times must lie in the show. Serial on purpose: 16,000 drones take
    ~0.2 ms, less than waking a thread pool (which costs milliseconds on a busy machine).
    """
    for j in range(times_s.shape[0]):
        t = times_s[j]
        for i in range(breaks_s.shape[0]):
            p = step_piece(breaks_s, i, cursor[i], t)
            cursor[i] = p
            u = t - breaks_s[i, p]
            for a in range(3):
                pos_m[j, i, a] = position_at(coeffs_m, i, p, a, u)
                vel_mps[j, i, a] = velocity_at(coeffs_m, i, p, a, u)


@njit(cache=True, nogil=True)
def _evaluate_pieces(
    breaks_s: np.ndarray, coeffs_m: np.ndarray, rows: np.ndarray, times_s: np.ndarray, derivatives: int,
    pos: np.ndarray, vel: np.ndarray, acc: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """What :meth:`Trajectories.evaluate` documents, into ``pos``, ``vel``, ``acc`` ``(T, n, 3)``.

    The very operations of the numpy formulation it replaced, in the same order, so the
    same bits: the time clamped to the show, the piece by :func:`_search_pieces`'s rule,
    Horner's rule from the highest of the D+1 coefficients (the derivatives' coefficients
    ``c[k+1]·(k+1)``, padded with zeros at the top, which Horner multiplies through), and
    velocity and acceleration 0 outside the show. ``vel`` / ``acc`` are left as they are
    when ``derivatives`` < 1 / < 2.
    """
    p = breaks_s.shape[1] - 1
    nc = coeffs_m.shape[3]
    start, end = breaks_s[0, 0], breaks_s[0, p]
    d1 = np.empty(nc)
    d2 = np.empty(nc)
    for j in range(rows.shape[0]):
        row = rows[j]
        b = breaks_s[row]
        for k in range(times_s.shape[0]):
            t = times_s[k]
            live = t >= start and t <= end
            tc = start if t < start else (end if t > end else t)  # np.clip's rule (NaN stays NaN)
            piece = _piece_of(b, p, tc)
            u = tc - b[piece]
            for ax in range(3):
                c = coeffs_m[row, piece, ax]
                pos[k, j, ax] = _horner(c, nc, u)
                if derivatives >= 1:
                    for q in range(nc - 1):
                        d1[q] = c[q + 1] * float(q + 1)
                    d1[nc - 1] = 0.0
                    h = _horner(d1, nc, u)
                    vel[k, j, ax] = h if live else 0.0
                if derivatives >= 2:
                    for q in range(nc - 1):
                        d2[q] = d1[q + 1] * float(q + 1)
                    d2[nc - 1] = 0.0
                    h = _horner(d2, nc, u)
                    acc[k, j, ax] = h if live else 0.0


class TrajectorySample(NamedTuple):
    """Positions (m), velocities (m/s), accelerations (m/s²) at T times for n drones: (T, n, 3) each."""

    positions_m: np.ndarray
    velocities_mps: np.ndarray
    accelerations_mps2: np.ndarray


def _derivative_coeffs(c: np.ndarray, order: int) -> np.ndarray:
    """Coefficients (..., D+1) of the ``order``-th derivative in the same ascending layout (zero-padded)."""
    out = np.array(c, copy=True)
    for _ in range(order):
        k = np.arange(1, out.shape[-1], dtype=np.float64)
        out = np.concatenate([out[..., 1:] * k, np.zeros_like(out[..., :1])], axis=-1)
    return out


def horner(c: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Σ_k c[..., k]·u^k with ``u`` broadcast against ``c[..., 0]``."""
    acc = c[..., -1].copy()
    for k in range(c.shape[-1] - 2, -1, -1):
        acc = acc * u + c[..., k]
    return acc


class Trajectories:
    """Per-drone piecewise polynomials (see the module docstring for the layout).

    A plain class, not a dataclass: Dask rebuilds dataclass arguments field by field,
    which would drop the derived lookup table.
    """

    breaks_s: np.ndarray
    coeffs_m: np.ndarray

    def __init__(self, breaks_s: ArrayLike, coeffs_m: ArrayLike) -> None:
        b = np.ascontiguousarray(breaks_s, dtype=np.float64)
        c = np.ascontiguousarray(coeffs_m, dtype=np.float64)
        if b.ndim != 2 or c.ndim != 4 or c.shape[:2] != (b.shape[0], b.shape[1] - 1) or c.shape[2] != 3:
            raise ValueError(f"breaks (N, P+1) and coeffs (N, P, 3, D+1) do not match: {b.shape}, {c.shape}")
        if b.shape[1] < 2:
            raise ValueError("every drone needs at least one piece")
        if np.any(np.diff(b, axis=1) < 0):
            raise ValueError("breaks_s must be nondecreasing along each drone")
        self.breaks_s, self.coeffs_m = b, c

    def __repr__(self) -> str:
        return f"Trajectories(drones={self.drone_count}, pieces={self.piece_count}, {self.start_s}..{self.end_s} s)"

    @property
    def drone_count(self) -> int:
        """N."""
        return int(self.breaks_s.shape[0])

    @property
    def piece_count(self) -> int:
        """P, pieces per drone (zero-length ones included)."""
        return int(self.breaks_s.shape[1] - 1)

    @property
    def start_s(self) -> float:
        """Show start, seconds."""
        return float(self.breaks_s[0, 0])

    @property
    def end_s(self) -> float:
        """Show end, seconds."""
        return float(self.breaks_s[0, -1])

    def _rows(self, drones: slice | np.ndarray | None) -> np.ndarray:
        return np.arange(self.drone_count)[slice(None) if drones is None else drones]

    def piece_index(self, times_s: ArrayLike, drones: slice | np.ndarray | None = None) -> np.ndarray:
        """(T, n) index of the piece each drone is on at each time (the last piece starting at or before t).

        Times are clamped to [start, end]; at a break the later piece is chosen. A binary
        search per drone and time over that drone's own breaks, so no precision is lost
        to offsets however long the show or large the fleet.
        """
        t = np.clip(np.atleast_1d(np.asarray(times_s, dtype=np.float64)), self.start_s, self.end_s)
        rows = np.ascontiguousarray(self._rows(drones), dtype=np.int64)
        out = np.empty((len(t), len(rows)), dtype=np.int64)
        _search_pieces(self.breaks_s, rows, np.ascontiguousarray(t), out)
        return out

    def evaluate(
        self, times_s: ArrayLike, drones: slice | np.ndarray | None = None, *, derivatives: int = 2
    ) -> TrajectorySample:
        """Position and (up to ``derivatives``) velocity and acceleration at ``times_s`` (T,) for (some) drones.

        Returns (T, n, 3) arrays; those not asked for are zeros. Outside the show the
        drones rest at their first / last position.
        """
        t = np.atleast_1d(np.asarray(times_s, dtype=np.float64))
        rows = np.ascontiguousarray(self._rows(drones), dtype=np.int64)
        n_t, n = len(t), len(rows)
        pos = np.empty((n_t, n, 3))
        vel = np.zeros((n_t, n, 3))
        acc = np.zeros((n_t, n, 3))
        # One compiled pass per (time, drone): no gathered (T, n, 3, D+1) coefficient copies.
        _evaluate_pieces(self.breaks_s, self.coeffs_m, rows, np.ascontiguousarray(t), int(derivatives),
                         pos, vel, acc)
        return TrajectorySample(pos, vel, acc)

    def select(self, drones: slice | np.ndarray) -> Trajectories:
        """The trajectories of a subset of drones (same pieces)."""
        rows = self._rows(drones)
        return Trajectories(self.breaks_s[rows], self.coeffs_m[rows])


class TrajectoryBuilder:
    """Appends pieces to all N drones at once, each drone with its own piece times.

    Every call appends the same number of pieces to every drone (zero-length pieces
    where a drone has nothing to do), so the table stays a dense (N, P) array.
    """

    def __init__(self, start_positions_m: ArrayLike, start_s: float = 0.0) -> None:
        p = np.asarray(start_positions_m, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 3:
            raise ValueError(f"start positions must be (N, 3), got {p.shape}")
        self._pos_m = p.copy()
        self._time_s = np.full(len(p), float(start_s))
        self._breaks: list[np.ndarray] = [self._time_s.copy()]
        self._coeffs: list[np.ndarray] = []

    @property
    def positions_m(self) -> np.ndarray:
        """(N, 3) where each drone is after the pieces so far."""
        return self._pos_m.copy()

    @property
    def times_s(self) -> np.ndarray:
        """(N,) when each drone's pieces so far end."""
        return self._time_s.copy()

    def append(self, durations_s: ArrayLike, coeffs_m: ArrayLike) -> None:
        """Append one piece per drone: (N,) durations (>= 0) and (N, 3, k) ascending coefficients, k <= D+1.

        The constant coefficient must continue from where each drone is (checked to 1e-9 m).
        """
        d = np.broadcast_to(np.asarray(durations_s, dtype=np.float64), self._time_s.shape)
        c = np.asarray(coeffs_m, dtype=np.float64)
        if np.any(d < 0):
            raise ValueError("piece durations must be >= 0")
        full = np.zeros((len(d), 3, DEGREE + 1))
        full[..., : c.shape[-1]] = c
        if not np.allclose(full[..., 0], self._pos_m, rtol=0.0, atol=1e-9):
            raise ValueError("a piece does not start where the drone is")
        full[..., 0] = self._pos_m  # exact continuity
        self._coeffs.append(full)
        self._time_s = self._time_s + d
        self._pos_m = horner(full, d[:, None])
        self._breaks.append(self._time_s.copy())

    def hold_until(self, times_s: ArrayLike) -> None:
        """Each drone rests where it is until its time in ``times_s`` (N,) (or a scalar), never before now."""
        t = np.broadcast_to(np.asarray(times_s, dtype=np.float64), self._time_s.shape)
        if np.any(t < self._time_s - 1e-9):
            raise ValueError("hold_until goes back in time")
        self.append(np.maximum(t - self._time_s, 0.0), self._pos_m[..., None])

    def build(self, end_s: float | None = None) -> Trajectories:
        """The trajectories so far; every drone must end at the same time (use :meth:`hold_until`).

        ``end_s``: the show's end as its caller keeps it (e.g. the last knot time). Piece
        durations summed per drone can round an ulp away from it; the last break is snapped
        to it, so the motion and the plan's windows end at the very same instant.
        """
        if not self._coeffs:
            self.hold_until(self._time_s)
        end = self._time_s
        if np.ptp(end) > 1e-9:
            raise ValueError("drones end at different times; hold them until a common end first")
        if end_s is not None and abs(end_s - end.max()) > 1e-9 * max(1.0, abs(end_s)):
            raise ValueError(f"the pieces end at {end.max()} s, not at end_s = {end_s} s")
        breaks = np.stack(self._breaks, axis=1)
        breaks[:, -1] = end.max() if end_s is None else end_s
        return Trajectories(breaks, np.stack(self._coeffs, axis=1))


def rest_to_rest_quintic_coeffs(start_m: np.ndarray, end_m: np.ndarray, duration_s: np.ndarray) -> np.ndarray:
    """(N, 3, 6) coefficients of straight rest-to-rest quintic legs p(u) = A + (10τ³ - 15τ⁴ + 6τ⁵)·D, τ = u/T.

    Zero durations give a constant piece at ``start_m`` (the leg must then have D = 0).
    """
    a = np.asarray(start_m, dtype=np.float64)
    dvec = np.asarray(end_m, dtype=np.float64) - a
    t = np.asarray(duration_s, dtype=np.float64)
    safe = np.where(t > 0, t, 1.0)[:, None]
    c = np.zeros(a.shape + (DEGREE + 1,))
    c[..., 0] = a
    moving = (t > 0)[:, None]
    c[..., 3] = np.where(moving, 10.0 * dvec / safe**3, 0.0)
    c[..., 4] = np.where(moving, -15.0 * dvec / safe**4, 0.0)
    c[..., 5] = np.where(moving, 6.0 * dvec / safe**5, 0.0)
    return c


__all__ = [
    "DEGREE",
    "TrajectoryBuilder",
    "Trajectories",
    "TrajectorySample",
    "horner",
    "rest_to_rest_quintic_coeffs",
]
