"""The error models' per-drone inputs, shared by both engines (built once per run and per chunk).

:class:`ErrorTables` turns an :class:`~sim.flight._errors.ErrorModel` and a seed into

* ``drone`` ``(N, D_SIZE)``: each drone's constants (its true mass and inertia, thrust
  gain and battery sag rate, clock offset, motor-lag blend, drag over mass), drawn from
  the counter-based streams of :mod:`sim.flight._random` keyed by the drone's index in
  the plan, so a drone gets the same values in any subset, shard or order;
* per chunk, :class:`ChunkTables`: the GNSS measurement error ``b + n`` of each drone at
  each GNSS epoch of the chunk (the bias walk carried across chunks; its increments
  and the white noise are keyed by the epoch's global index, so chunking does not
  change them), and the wind at each drone's *reference* position on a global 10 Hz
  grid, which the engines interpolate linearly. Evaluating the wind at the planned
  instead of the flown position ignores the tracking error (centimetres) against the
  field's correlation length (~150 m): a relative error of ~1e-4 for the cost of a
  table lookup instead of M cosines per drone-step inside the kernel.

Both engines read the same tables, so they agree with the error models on.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.flight._disturbance import WindField
from sim.flight._errors import ErrorModel
from sim.flight._quadrotor import QuadrotorParams
from sim.flight._random import STREAMS, hashed_normal
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

__all__ = ["WIND_GRID_S", "ChunkTables", "ErrorTables", "ideal_drone_constants"]

#: Spacing of the wind tables (s). The resolved turbulence (k·L ≤ 200 at L = 150 m) seen
#: by a drone moving at 20 m/s relative to the air changes below ~5 Hz.
WIND_GRID_S = 0.1
#: Relative parameter errors are clipped to this many σ (a normal has no bounds; a
#: negative mass has no meaning).
SPREAD_CLIP_SIGMA = 4.0


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
    """

    gnss: np.ndarray
    gnss_every: int
    gnss_first: int
    wind: np.ndarray
    wind_k0: int
    wind_dt_s: float


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
        duration_s: Flight length (s), the default battery duration.
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
            horizon = e.battery_duration_s if e.battery_duration_s is not None else max(duration_s, dt_s)
            d[:, D_SAG_RATE] = np.clip(sag, 0.0, 0.9) / horizon
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
        if self.use_gnss:
            self._bias = e.gnss_bias_m * self._axis_sigma * hashed_normal(
                self.seed, self.ids[:, None], STREAMS["gnss_bias"], np.arange(3)[None, :]
            )
        self._initial_bias = self._bias.copy()
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

    def chunk(self, step0: int, count: int, reference: TrackingReference) -> ChunkTables:
        """The tables for steps ``step0 .. step0 + count - 1`` (chunks must come in order)."""
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
                counter = epochs[:, None, None] * 3 + np.arange(3)[None, None, :]
                drone = self.ids[None, :, None]
                walk = e.gnss_bias_walk_m_per_sqrt_s * math.sqrt(ge * self.dt_s)
                steps = walk * self._axis_sigma * hashed_normal(self.seed, drone, STREAMS["gnss_walk"], counter)
                steps[epochs == 0] = 0.0  # the bias starts at its initial draw
                # One epoch after the other (not a cumsum from the chunk's start): the same
                # additions in the same order whatever the chunking, so the same bits.
                bias = np.empty_like(steps)
                current = self._bias
                for e_row in range(epochs.size):
                    current = current + steps[e_row]
                    bias[e_row] = current
                self._bias = current.copy()
                self._bias_epoch = int(epochs[-1])
                white = e.gnss_noise_m * self._axis_sigma * hashed_normal(
                    self.seed, drone, STREAMS["gnss_white"], counter
                )
                gnss = bias + white
                if e.gnss_step_m > 0:  # the injected step, on the epochs inside its window
                    t_epoch = epochs * ge * self.dt_s
                    end = math.inf if e.gnss_step_duration_s is None else e.gnss_step_at_s + e.gnss_step_duration_s
                    on = (t_epoch >= e.gnss_step_at_s - 1e-9) & (t_epoch < end - 1e-9)
                    gnss[on, :, 0:2] += self.step_xy_m[None, :, :]
                gnss = np.ascontiguousarray(gnss)
        wind = np.zeros((0, n, 3))
        k0 = 0
        if self.use_drag:
            t0 = step0 * self.dt_s
            t1 = (step0 + count - 1) * self.dt_s
            k0 = int(math.floor(t0 / WIND_GRID_S))
            k1 = int(math.floor(t1 / WIND_GRID_S)) + 1
            grid = np.arange(k0, k1 + 1) * WIND_GRID_S
            if self.wind_field is None:
                wind = np.zeros((grid.size, n, 3))
            else:
                pts = reference.motion.evaluate(grid, derivatives=0).positions_m  # (W, N, 3)
                if reference.offset is not None:
                    pts = pts + np.asarray(reference.offset(grid))[:, None, 0:3]
                times = np.broadcast_to(grid[:, None], pts.shape[:2]).reshape(-1)
                wind = self.wind_field.velocity(pts.reshape(-1, 3), times).reshape(grid.size, n, 3)
        return ChunkTables(gnss=gnss, gnss_every=self.gnss_every, gnss_first=first, wind=wind,
                           wind_k0=k0, wind_dt_s=WIND_GRID_S)
