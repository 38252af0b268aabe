"""The error models' per-drone inputs, shared by both engines (built once per run and per chunk).

:class:`ErrorTables` turns an :class:`~sim.flight._errors.ErrorModel` and a seed into

* ``drone`` ``(N, D_SIZE)``: each drone's constants (its true mass and inertia, thrust
  gain and battery sag rate, clock offset, motor-lag blend, drag over mass), drawn from
  the counter-based streams of :mod:`sim.flight._random` keyed by the drone's index in
  the plan, so a drone gets the same values in any subset, shard or order;
* per chunk, :class:`ChunkTables`: the GNSS measurement error ``b + n`` of each drone at
  each GNSS epoch of the chunk (the bias walk carried across chunks; its increments
  and the white noise are keyed by the epoch's global index, so chunking does not
  change them), and the wind *and its spatial derivatives* at each drone's planned
  position on a global 10 Hz grid (the engines interpolate the wind linearly in time and
  hold the derivatives over each grid interval, below).

The wind acts at the *flown* position ``p``: the engines expand the field to first order
about the planned position ``p_r`` (:func:`flown_wind`),

    w(p) ≈ w(p_r) + J_turb clamp(p - p_r, ±R) + S clamp(z - z_r, ±z_r / 2)

with ``J_turb`` the turbulence's Jacobian (closed form from its Fourier modes), ``S`` the
mean profile's ``∂U/∂z`` and ``R = L/150`` (constants and the error analysis in
:mod:`sim.flight._disturbance`). Exact to first order for the centimetres-to-metre
tracking errors of normal flight (the error falls with the square of the displacement);
for a drone blown far off the clamps stop the extrapolation, and the sheared mean wind of
where it actually is (10 m lower: the lower wind) keeps acting up to half its height. The
exact field at the flown position would need the M = 128 modes' cosines per drone-step
inside the kernel (~3,000 flops, about 7x the kernel's whole step). The expansion costs 11 multiply-adds and
8 min/max per drone-step: the wind is linear in time on its grid, but its 11 derivatives are
held over each 0.1 s interval at the mean of its two ends. Interpolating them too cost more
in the kernel (speed against the plan-position kernel, four alternating runs on the shared
2-core machine: 0.82-0.99 interpolated, 0.93-1.05 held, i.e. within the ±5 % noise) for
little: a drone 1 m off (the clamp) and 8 m/s through a 7.7 m/s field, the held derivatives'
error is 12.6 % RMS of the first-order term (2.5 % interpolated), while the wind's own linear
interpolation in time errs by 4.6 % of that term whatever the displacement; the held error
scales with the displacement, so it is below the interpolation's at under ~0.4 m. The tables'
mode sum (value and Jacobian) costs 2-2.7x the value alone.

Speed (issue 20): on one thread the tables were ~30 % of a 1-s, 4,000-drone "gusty-rtk"
flight's wall time (of 40 ms, the wind's mode sum 24, the GNSS draws 8). Now the mode sum's
point blocks are shared by the table threads (:mod:`sim.flight._windsum`) while the GNSS
draws run on a thread of their own, started once the wind's inputs are ready (their numpy
glue would otherwise take turns at the GIL with the wind's); the wind and its derivatives are
written straight into the tables' rows (no separate Jacobian and shear arrays to copy). The
same bits on any thread count (``tests/test_flight_table_threads.py``). Measured against the
one-thread tables (old and new tree in alternating processes, load 5-8 on the 2 shared cores,
medians [ranges]): a chunk's tables 1.12x less CPU [1.07, 1.18] (4 pairs); a whole 1-s
simulate 1.07x less CPU [0.99, 1.20] and 1.06x less wall [0.75, 1.77] (8 pairs), the kernel's
share of its wall 0.75 -> 0.80; 1,000 drones for 30 s (30 chunks: a thread start per chunk
costs nothing visible) 1.01x less CPU [0.89, 1.05], 1.04x less wall [1.00, 1.67] (4 pairs); a
500-drone, 357-s ``fly_show`` 1.02x less CPU [0.97, 1.08] (4 pairs).
At that load the second thread rarely finds a core free (``benchmarks/bench_tables.py``:
one thread against two in one process, 1.04x wall for the tables); with a core idle the two
threads should near halve the tables' wall, which this machine could not show. Not done, measured:
Box-Muller's logarithm and cosine compiled (numpy's cosine is 2.3 ms of the draws for 264,000
normals, its log 0.3 ms) would not be numpy's bits on every CPU (:mod:`sim.flight._random`);
drawing the next chunk's tables during this chunk's kernel would only fill cores the kernel's
two threads leave idle, which on this shared machine there are none of.

Both engines read the same tables, so they agree with the error models on.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numba
import numpy as np

from sim.flight._disturbance import SHEAR_LINEAR_RADIUS_FRACTION, WIND_GRADIENT_COLUMNS, WindField
from sim.flight._errors import ErrorModel
from sim.flight._quadrotor import QuadrotorParams
from sim.flight._random import STREAMS, hashed_normal, uniform_pairs_grid
from sim.flight._threads import table_threads
from sim.flight.engines._state import (
    D_CLOCK,
    D_DRAG,
    D_IX,
    D_IZ,
    D_MASS,
    D_MOTOR,
    D_SAG_RATE,
    D_SIZE,
    D_THRUST,
    ErrorSwitches,
    TrackingReference,
)

__all__ = ["WIND_GRID_S", "WIND_GRAD_SIZE", "ChunkTables", "ErrorTables", "flown_wind", "ideal_drone_constants"]

#: Spacing of the wind tables (s). The resolved turbulence (k·L ≤ 200 at L = 150 m) seen
#: by a drone moving at 20 m/s relative to the air changes below ~5 Hz.
WIND_GRID_S = 0.1
#: Entries of a wind-derivative row: the turbulence's ``∂u_i/∂x_j`` (row-major, 9) then the
#: mean profile's ``∂U_x/∂z, ∂U_y/∂z`` (2), all 1/s.
WIND_GRAD_SIZE = WIND_GRADIENT_COLUMNS
#: Relative parameter errors are clipped to this many σ (a normal has no bounds; a
#: negative mass has no meaning).
SPREAD_CLIP_SIGMA = 4.0
#: Bytes of Box-Muller inputs drawn at once for the GNSS tables (epochs × drones × 3 axes × 2
#: streams × 8 bytes, in each of two buffers): about an L2 cache.
_GNSS_BLOCK_BYTES = 1 << 18
#: Smallest wind-table work (rows x drones x modes) for which the GNSS table is drawn on a
#: thread of its own beside the wind's mode sum: ~1 ms of the sum on one core (~280 M
#: point-modes/s), against ~0.1 ms to start and join a thread.
_THREAD_MIN_POINT_MODES = 1 << 18


@dataclass(frozen=True)
class ChunkTables:
    """What the engines read, besides the constants, over one chunk of steps.

    Attributes:
        gnss: ``(E, N, 3)`` measurement error at the chunk's GNSS epochs (m); E = 0 when off.
        gnss_every: Steps between GNSS epochs (epochs at step k with k % gnss_every == 0).
        gnss_first: Step index of ``gnss[0]``.
        wind: ``(W, N, 3)`` wind at the reference positions on the grid (m/s); W = 0 when off.
        wind_k0: Grid index of ``wind[0]`` (time ``wind_k0 * wind_dt_s``).
        wind_dt_s: Grid spacing (s).
        wind_grad: ``(W, N, WIND_GRAD_SIZE)`` the wind's derivatives there (1/s; zeros without
            a wind field): the turbulence Jacobian, row-major, then the mean shear.
        wind_radius_m: Half-side of the turbulence expansion's clamp box (m).
    """

    gnss: np.ndarray
    gnss_every: int
    gnss_first: int
    wind: np.ndarray
    wind_k0: int
    wind_dt_s: float
    wind_grad: np.ndarray
    wind_radius_m: float

    @classmethod
    def empty(cls, n: int) -> ChunkTables:
        """No GNSS and no wind tables for n drones (ideal drones)."""
        return cls(gnss=np.zeros((0, n, 3)), gnss_every=1, gnss_first=0, wind=np.zeros((0, n, 3)), wind_k0=0,
                   wind_dt_s=1.0, wind_grad=np.zeros((0, n, WIND_GRAD_SIZE)), wind_radius_m=0.0)

    def wind_at(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """``(wind (N, 3), grad (N, WIND_GRAD_SIZE))`` at the planned positions at ``t_s``.

        The wind is linear on the grid; its derivatives are held at the mean of the grid
        interval's two ends (module docstring: half the kernel's cost of interpolating them).
        """
        x = t_s / self.wind_dt_s
        i0 = min(max(int(np.floor(x)) - self.wind_k0, 0), self.wind.shape[0] - 2)
        fr = x - (self.wind_k0 + i0)
        wind = self.wind[i0] + fr * (self.wind[i0 + 1] - self.wind[i0])
        grad = 0.5 * (self.wind_grad[i0] + self.wind_grad[i0 + 1])
        return wind, grad


def flown_wind(
    wind_mps: np.ndarray, grad_per_s: np.ndarray, displacement_m: np.ndarray, plan_height_m: np.ndarray,
    radius_m: float,
) -> np.ndarray:
    """The wind at the flown position, to first order about the planned one (module docstring).

    Args:
        wind_mps: ``(N, 3)`` the wind at the planned positions (m/s).
        grad_per_s: ``(N, WIND_GRAD_SIZE)`` its derivatives there (1/s), as in :class:`ChunkTables`.
        displacement_m: ``(N, 3)`` flown minus planned position (m).
        plan_height_m: ``(N,)`` the planned heights (m): the shear term's clamp is half of it.
        radius_m: The turbulence term's clamp (m), per axis.

    Returns:
        ``(N, 3)`` the wind (m/s).
    """
    d = np.minimum(np.maximum(displacement_m, -radius_m), radius_m)
    h = SHEAR_LINEAR_RADIUS_FRACTION * np.asarray(plan_height_m)
    dz = np.minimum(np.maximum(displacement_m[:, 2], -h), h)
    jac = grad_per_s[:, 0:9].reshape(-1, 3, 3)
    out: np.ndarray = wind_mps + np.einsum("nij,nj->ni", jac, d)
    out[:, 0:2] += grad_per_s[:, 9:11] * dz[:, None]
    return out


@numba.njit(cache=True, nogil=True)
def _gnss_walk(
    bias: np.ndarray, log_walk: np.ndarray, cos_walk: np.ndarray, log_white: np.ndarray, cos_white: np.ndarray,
    walk_sigma: np.ndarray, white_sigma: np.ndarray, first_is_zero: bool, out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """The GNSS error ``out`` ``(E, N, 3)``: the bias walk ``bias`` ``(N, 3)`` (advanced in place) plus white noise.

    ``log_*`` hold ln u1 and ``cos_*`` cos(2π u2) of the Box-Muller pairs ``(E, N, 3)``;
    ``walk_sigma``, ``white_sigma`` ``(3,)`` the per-axis step and noise σ. One epoch after
    the other (not a cumsum from the chunk's start): the same additions in the same order
    whatever the chunking, so the same bits.
    """
    for r in range(out.shape[0]):
        zero = first_is_zero and r == 0
        for i in range(out.shape[1]):
            for a in range(3):
                step = 0.0 if zero else walk_sigma[a] * (math.sqrt(-2.0 * log_walk[r, i, a]) * cos_walk[r, i, a])
                b = bias[i, a] + step
                bias[i, a] = b
                out[r, i, a] = b + white_sigma[a] * (math.sqrt(-2.0 * log_white[r, i, a]) * cos_white[r, i, a])


def ideal_drone_constants(plant: QuadrotorParams, n: int) -> np.ndarray:
    """``(N, D_SIZE)`` constants of ideal drones: the plant's values, no lag, no drag, no sag."""
    d = np.zeros((n, D_SIZE))
    d[:, D_MASS] = plant.mass_kg
    d[:, D_IX:D_IZ + 1] = plant.inertia_kgm2
    d[:, D_THRUST] = 1.0
    d[:, D_MOTOR] = 1.0
    return d


class ErrorTables:
    """Per-run realisation of an error model for a set of drones (see the module docstring).

    Args:
        errors: The error model.
        seed: The run's seed.
        drone_ids: ``(N,)`` the drones' indices in the plan (the keys of their streams).
        plant: The nominal plant (before the per-drone spread).
        dt_s: Control step (s).
        duration_s: Flight length (s).
    """

    def __init__(
        self, errors: ErrorModel, *, seed: int, drone_ids: np.ndarray, plant: QuadrotorParams,
        dt_s: float, duration_s: float,
    ) -> None:
        self.errors, self.seed = errors, int(seed)
        self.ids = np.asarray(drone_ids, dtype=np.int64)
        n = self.ids.size
        e = errors
        d = ideal_drone_constants(plant, n)

        def spread(stream: str, sigma: float, axes: int = 1) -> np.ndarray:
            z = hashed_normal(self.seed, self.ids[:, None], STREAMS[stream], np.arange(axes)[None, :])
            out: np.ndarray = 1.0 + sigma * np.clip(z, -SPREAD_CLIP_SIGMA, SPREAD_CLIP_SIGMA)
            return out

        if e.mass_spread > 0:
            d[:, D_MASS] *= spread("mass", e.mass_spread)[:, 0]
        if e.inertia_spread > 0:
            d[:, D_IX:D_IZ + 1] *= spread("inertia", e.inertia_spread, 3)
        if e.thrust_spread > 0:
            d[:, D_THRUST] *= spread("thrust", e.thrust_spread)[:, 0]
        if e.battery_sag > 0 or e.battery_sag_spread > 0:
            sag = e.battery_sag + e.battery_sag_spread * hashed_normal(self.seed, self.ids, STREAMS["sag"], 0)
            # Linear to sag_i at the pack's endurance, held after it (ErrorSwitches.battery_end_s).
            d[:, D_SAG_RATE] = np.clip(sag, 0.0, 0.9) / e.battery_duration_s
        if e.clock_offset_s > 0:
            d[:, D_CLOCK] = e.clock_offset_s * hashed_normal(self.seed, self.ids, STREAMS["clock"], 0)
        if e.motor_time_constant_s > 0:
            d[:, D_MOTOR] = -math.expm1(-dt_s / e.motor_time_constant_s)  # exact for a held command
        if e.drag_coeff_kg_per_m > 0:
            d[:, D_DRAG] = e.drag_coeff_kg_per_m / d[:, D_MASS]
        self.drone = d
        self.use_gnss = e.has_gnss
        self.use_motor = e.motor_time_constant_s > 0
        self.use_drag = e.drag_coeff_kg_per_m > 0
        self.use_clock = e.clock_offset_s > 0
        self.gnss_every = max(int(round(1.0 / (e.gnss_rate_hz * dt_s))), 1)
        # Continuous-time complementary filter p̂' = v̂ + k_p y, v̂' = a + k_v y with the
        # innovation y held between epochs: poles of s² + k_p s + k_v at ω_c, ζ = 1/√2.
        wc = e.estimator_bandwidth_rad_s
        self.est_kp, self.est_kv = math.sqrt(2.0) * wc, wc * wc
        # Innovation gate (PX4 EKF2: EKF2_GPS_P_GATE = 5 σ, states reset to the measurement after
        # reset_timeout_max = 7 s of rejections, src/modules/ekf2/EKF/common.h). σ of the innovation:
        # the fix's white noise and one epoch of bias walk (the estimate has converged on the
        # slowly varying bias; its prediction uses the exact accelerometer), floored at 1 cm as
        # EKF2 floors the GNSS position noise (EKF2_GPS_P_NOISE >= 0.01 m).
        epoch_s = self.gnss_every * dt_s
        sigma = max(math.hypot(e.gnss_noise_m, e.gnss_bias_walk_m_per_sqrt_s * math.sqrt(epoch_s)), 0.01)
        gate_on = e.gnss_gate_sigma > 0
        self.gate_h_m = e.gnss_gate_sigma * sigma if gate_on else math.inf
        self.gate_v_m = e.gnss_gate_sigma * sigma * e.gnss_vertical_factor if gate_on else math.inf
        self.gate_epochs = float(max(math.ceil(e.gnss_gate_reset_s / epoch_s - 1e-9), 1))
        self.step_xy_m = np.zeros((n, 2))
        if e.gnss_step_m > 0:
            if e.gnss_step_direction_rad is not None:
                angle = np.full(n, float(e.gnss_step_direction_rad))
            else:  # a seeded direction per drone (uniform: the angle of a 2-D standard normal)
                z = hashed_normal(self.seed, self.ids[:, None], STREAMS["gnss_step"], np.arange(2)[None, :])
                angle = np.arctan2(z[:, 1], z[:, 0])
            self.step_xy_m = e.gnss_step_m * np.stack([np.cos(angle), np.sin(angle)], axis=1)
        self._axis_sigma = np.array([1.0, 1.0, e.gnss_vertical_factor])
        self._bias = np.zeros((n, 3))
        self._bias_epoch = -1  # epoch index the bias is at
        # The last chunk's last wind row: (reference, grid index, wind (N, 3), derivatives (N, 11)).
        self._wind_tail: tuple[TrackingReference, int, np.ndarray, np.ndarray] | None = None
        if self.use_gnss:
            self._bias = e.gnss_bias_m * self._axis_sigma * hashed_normal(
                self.seed, self.ids[:, None], STREAMS["gnss_bias"], np.arange(3)[None, :]
            )
        self._initial_bias = self._bias.copy()
        self._scratch: tuple[np.ndarray, np.ndarray] | None = None
        self.wind_field = (
            WindField.dryden(
                mean_mps=e.wind_mean_mps, direction_rad=e.wind_direction_rad, ref_height_m=e.wind_ref_height_m,
                shear_exponent=e.wind_shear_exponent, sigma_mps=e.turbulence_sigma_mps,
                length_m=e.turbulence_length_m, vertical_factor=e.turbulence_vertical_factor,
                modes=e.turbulence_modes, seed=self.seed,
            )
            if e.has_wind else None
        )
        self.dt_s = float(dt_s)
        self.switches = ErrorSwitches(
            gnss=self.use_gnss, motor=self.use_motor, drag=self.use_drag, clock=self.use_clock,
            est_kp=self.est_kp, est_kv=self.est_kv, gate_h_m=self.gate_h_m, gate_v_m=self.gate_v_m,
            gate_epochs=self.gate_epochs, reset_mps=e.gnss_reset_speed_mps,
            battery_end_s=e.battery_duration_s,
        )

    def initial_gnss_error(self) -> np.ndarray:
        """``(N, 3)`` the measurement error of epoch 0 (m): the estimator starts at that fix."""
        if not self.use_gnss:
            return np.zeros((self.ids.size, 3))
        drone = self.ids[:, None]
        white = self.errors.gnss_noise_m * self._axis_sigma * hashed_normal(
            self.seed, drone, STREAMS["gnss_white"], np.arange(3)[None, :]
        )
        out: np.ndarray = self._initial_bias + white
        e = self.errors
        if e.gnss_step_m > 0 and e.gnss_step_at_s <= 1e-9 and (e.gnss_step_duration_s is None
                                                                or e.gnss_step_duration_s > 1e-9):
            out[:, 0:2] += self.step_xy_m  # a step from t = 0 is part of the first fix
        return out

    def _gnss_scratch(self, epochs: int) -> tuple[np.ndarray, np.ndarray]:
        """Two ``(2, epochs, N, 3)`` buffers, kept from chunk to chunk (fresh pages cost ~1 ms/MB here)."""
        if self._scratch is None or self._scratch[0].shape[1] < epochs:
            shape = (2, epochs, self.ids.size, 3)
            self._scratch = (np.empty(shape), np.empty(shape))
        return self._scratch[0][:, :epochs], self._scratch[1][:, :epochs]

    def _gnss_chunk(self, step0: int, count: int) -> tuple[np.ndarray, int]:
        """``(gnss (E, N, 3), step of gnss[0])`` for steps ``step0 .. step0 + count - 1`` (see :class:`ChunkTables`)."""
        n = self.ids.size
        gnss = np.zeros((0, n, 3))
        first = 0
        if self.use_gnss:
            ge = self.gnss_every
            first_epoch = -(-step0 // ge)
            last_epoch = (step0 + count - 1) // ge
            epochs = np.arange(first_epoch, last_epoch + 1)
            first = first_epoch * ge
            if epochs.size:
                if epochs[0] != self._bias_epoch + 1:
                    raise ValueError("ErrorTables.chunk: chunks must be asked for in order")
                e = self.errors
                counter = epochs[:, None] * 3 + np.arange(3)[None, :]  # (E, 3): epoch × 3 + axis
                # Box-Muller's uniforms of both streams, then numpy's log and cosine over both at
                # once (numpy's own, as hashed_normal: the same bits), then one compiled pass for
                # the rest: the same operations in the same order as
                # ``walk·σ_a·z`` cumulated epoch by epoch plus ``noise·σ_a·z'``, without temporaries.
                walk = e.gnss_bias_walk_m_per_sqrt_s * math.sqrt(ge * self.dt_s)
                walk_sigma, white_sigma = walk * self._axis_sigma, e.gnss_noise_m * self._axis_sigma
                gnss = np.empty((epochs.size, n, 3))
                # A few epochs at a time, through buffers that stay in the cache and are kept from
                # chunk to chunk (a fresh megabyte costs ~1 ms of page faults on this machine).
                block = max(1, _GNSS_BLOCK_BYTES // (48 * max(n, 1)))
                for r0 in range(0, epochs.size, block):
                    rows = slice(r0, min(r0 + block, epochs.size))
                    log_u, cos_u = self._gnss_scratch(rows.stop - r0)  # (2, B, N, 3) each
                    uniform_pairs_grid(self.seed, self.ids, STREAMS["gnss_walk"], counter[rows], log_u[0], cos_u[0])
                    uniform_pairs_grid(self.seed, self.ids, STREAMS["gnss_white"], counter[rows], log_u[1], cos_u[1])
                    np.log(log_u, out=log_u)
                    np.multiply(2.0 * math.pi, cos_u, out=cos_u)
                    np.cos(cos_u, out=cos_u)
                    # The bias starts at its initial draw: epoch 0 adds a zero step.
                    _gnss_walk(self._bias, log_u[0], cos_u[0], log_u[1], cos_u[1], walk_sigma, white_sigma,
                               bool(epochs[r0] == 0), gnss[rows])
                self._bias_epoch = int(epochs[-1])
                if e.gnss_step_m > 0:  # the injected step, on the epochs inside its window
                    t_epoch = epochs * ge * self.dt_s
                    end = math.inf if e.gnss_step_duration_s is None else e.gnss_step_at_s + e.gnss_step_duration_s
                    on = (t_epoch >= e.gnss_step_at_s - 1e-9) & (t_epoch < end - 1e-9)
                    gnss[on, :, 0:2] += self.step_xy_m[None, :, :]
        return gnss, first

    def chunk(
        self, step0: int, count: int, reference: TrackingReference, *, threads: int | None = None,
    ) -> ChunkTables:
        """The tables for steps ``step0 .. step0 + count - 1`` (chunks must come in order).

        Args:
            step0: The chunk's first step.
            count: Its steps.
            reference: What the drones track (the wind is taken at its positions).
            threads: Threads for the tables (default :func:`sim.flight._threads.table_threads`):
                the GNSS table is drawn on a thread of its own while the wind's mode sum
                shares its point blocks among the threads (module docstring); the same bits
                for any count.
        """
        n = self.ids.size
        threads = table_threads() if threads is None else max(1, int(threads))
        k0, k1 = self._wind_grid(step0, count)
        wind_rows = k1 - k0 + 1 if self.use_drag else 0
        if threads > 1 and self.use_gnss and wind_rows * n * self.wind_field_modes >= _THREAD_MIN_POINT_MODES:
            # The GNSS draws on a thread of their own, started once the wind's inputs are ready
            # (their numpy glue and the draws' would otherwise take turns at the GIL).
            drawn: list[tuple[np.ndarray, int]] = []
            wind, grad, k0, radius = self._wind_chunk(
                step0, count, reference, threads, lambda: drawn.append(self._gnss_chunk(step0, count)))
            gnss, first = drawn[0] if drawn else self._gnss_chunk(step0, count)
        else:
            gnss, first = self._gnss_chunk(step0, count)
            wind, grad, k0, radius = self._wind_chunk(step0, count, reference, threads)
        return ChunkTables(gnss=gnss, gnss_every=self.gnss_every, gnss_first=first, wind=wind,
                           wind_k0=k0, wind_dt_s=WIND_GRID_S, wind_grad=grad, wind_radius_m=radius)

    @property
    def wind_field_modes(self) -> int:
        """Fourier modes of the turbulence (0 without a wind field)."""
        return 0 if self.wind_field is None else int(self.wind_field.omega_rad_s.size)

    def _wind_grid(self, step0: int, count: int) -> tuple[int, int]:
        """The first and last wind grid index of a chunk's table (rows bracketing its steps' times)."""
        t0 = step0 * self.dt_s
        t1 = (step0 + count - 1) * self.dt_s
        return int(math.floor(t0 / WIND_GRID_S)), int(math.floor(t1 / WIND_GRID_S)) + 1

    def _wind_chunk(
        self, step0: int, count: int, reference: TrackingReference, threads: int,
        alongside: Callable[[], None] | None = None,
    ) -> tuple[np.ndarray, np.ndarray, int, float]:
        """``(wind (W, N, 3), grad (W, N, WIND_GRAD_SIZE), grid index of row 0, clamp radius)``.

        See :class:`ChunkTables`; ``alongside`` runs on a thread of its own while the mode sum
        runs (not at all when there is no sum to do).
        """
        n = self.ids.size
        wind = np.zeros((0, n, 3))
        grad = np.zeros((0, n, WIND_GRAD_SIZE))
        radius = 0.0
        k0 = 0
        if self.use_drag:
            k0, k1 = self._wind_grid(step0, count)
            grid = np.arange(k0, k1 + 1) * WIND_GRID_S
            if self.wind_field is None:
                wind = np.zeros((grid.size, n, 3))
                grad = np.zeros((grid.size, n, WIND_GRAD_SIZE))
            else:
                wind = np.empty((grid.size, n, 3))
                grad = np.empty((grid.size, n, WIND_GRAD_SIZE))
                # Consecutive chunks share their boundary grid time (a 1,000-step chunk spans 11
                # rows, the last of which opens the next chunk): that row is reused, not summed
                # again (the same planned points at the same time: the same bits).
                r0 = 0
                tail = self._wind_tail
                if tail is not None and tail[0] is reference and tail[1] == k0:
                    wind[0], grad[0] = tail[2], tail[3]
                    r0 = 1
                if r0 < grid.size:
                    rows = grid[r0:]
                    pts = reference.motion.evaluate(rows, derivatives=0).positions_m  # (W', N, 3)
                    if reference.offset is not None:
                        pts = pts + np.asarray(reference.offset(rows))[:, None, 0:3]
                    times = np.broadcast_to(rows[:, None], pts.shape[:2]).reshape(-1)
                    # Straight into the tables' rows (C-contiguous: W' x N points of 3 and 11 columns).
                    self.wind_field.velocity_and_gradients_into(
                        pts.reshape(-1, 3), times, wind[r0:].reshape(-1, 3), grad[r0:].reshape(-1, WIND_GRAD_SIZE),
                        threads=threads, alongside=alongside,
                    )
                self._wind_tail = (reference, k1, wind[-1].copy(), grad[-1].copy())
                radius = self.wind_field.linear_radius_m
        return wind, grad, k0, radius
