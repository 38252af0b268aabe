"""Per-drone error models: what makes a real fleet fly differently from the plan.

One frozen :class:`ErrorModel` switches on (with non-zero sizes) each of the effects
that matter most for separation in real shows (issue 20, in that order): GNSS/RTK
position error and the estimator the controller sees it through, clock-sync error,
wind varying across the formation, motor dynamics, per-drone parameter spread and
battery sag, and quadratic drag. Every field defaults to "off", so ``ErrorModel()`` is
the ideal vehicle of the paper and the engines take their old, exact path.

Randomness: every random quantity is drawn from a counter-based stream keyed by
``(FlightOptions.seed, drone index in the plan, stream, counter)``
(:mod:`sim.flight._random`), never from the order drones or chunks are processed, so
a drone flies the same whether it is flown alone, with the whole fleet, in a Dask
shard, or in chunks of any length.

How each effect enters the model (docs/method.md §8):

* **GNSS** (rate ``gnss_rate_hz``): the receiver reports ``p + b + n`` with white
  noise ``n`` (σ ``gnss_noise_m`` per horizontal axis, ``gnss_vertical_factor`` times
  that vertically) and a bias ``b`` starting at σ ``gnss_bias_m`` and walking with
  intensity ``gnss_bias_walk_m_per_sqrt_s``. A complementary filter (crossover
  ``estimator_bandwidth_rad_s``) fuses it with the accelerometer; the controller sees
  its estimate ``(p̂, v̂)``, not the true state.
* **GNSS innovation gate** (as PX4 EKF2 gates GNSS position fusion): an epoch whose
  innovation ``z - p̂`` exceeds ``gnss_gate_sigma`` σ on any axis (σ: the fix's white
  noise and one epoch of bias walk, floored at 1 cm) is rejected and the estimate
  coasts on the accelerometer; after ``gnss_gate_reset_s`` of consecutive rejections
  the fixes are taken again (a real, persistent offset is accepted) and the estimate
  slews to them at no more than ``gnss_reset_speed_mps`` per axis (the role of PX4's
  position-controller reset handling: the tracking error never steps).
* **GNSS step** (a test event: a multipath step, an RTK fix lost and re-acquired):
  ``gnss_step_m`` added to every fix from ``gnss_step_at_s`` for
  ``gnss_step_duration_s`` (None: for good), horizontally toward
  ``gnss_step_direction_rad`` (None: a seeded random direction per drone).
* **Clock**: drone i runs the show clock ``t + δ_i``, δ_i ~ N(0, ``clock_offset_s``²).
* **Wind**: mean wind ``wind_mean_mps`` toward ``wind_direction_rad`` at
  ``wind_ref_height_m`` with a power-law height profile (exponent
  ``wind_shear_exponent``), plus a frozen, isotropic turbulence field with the Dryden
  correlation ``exp(-r / L)`` (σ ``turbulence_sigma_mps``, L ``turbulence_length_m``)
  swept by the mean wind: drones at distance d see gusts correlated by Dryden's
  longitudinal/lateral correlation functions at d. It acts through quadratic drag.
* **Drag**: ``F = -c |v - w| (v - w)`` with ``c = drag_coeff_kg_per_m`` (= ½ ρ C_d A).
* **Motors**: first-order lag of the squared rotor speeds, time constant
  ``motor_time_constant_s``.
* **Spread**: plant mass, inertia and rotor thrust gain of each drone scaled by
  ``1 + N(0, spread²)`` (the controller keeps the nominal values).
* **Battery sag**: the rotor thrust gain falls linearly in time, to ``1 - sag_i`` at the
  pack's nominal endurance ``battery_duration_s``, and stays there after it: ``g_i(t) =
  k_i (1 - sag_i min(t, T) / T)``, ``sag_i`` ~ N(``battery_sag``, ``battery_sag_spread``²)
  clipped to [0, 0.9]. The sag belongs to the battery, not to the show: a 95-s show on a
  20-minute pack loses 95/1200 of ``sag_i``. (Until issue 20's QA the horizon was the
  flight's length, so a 95-s show sagged as much as a 20-minute one.) Held past T, not
  extrapolated: a pack run past its endurance is at its cut-off voltage, where a flight
  stack lands the drone (its low-battery failsafe); the model has no failsafe, and a
  thrust gain that kept falling would only say that the show outlasts its batteries, which
  the designer is told more plainly by the show's length against the endurance.

Presets (:data:`ERROR_PRESETS`) carry literature values, cited at each value.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

__all__ = ["ERROR_PRESETS", "ErrorModel", "error_preset"]


@dataclass(frozen=True)
class ErrorModel:
    """Per-drone, seeded error models; every field's default turns its effect off.

    Attributes:
        name: Label used in reports.
        gnss_noise_m: White GNSS position noise σ per horizontal axis (m); 0 = perfect position.
        gnss_vertical_factor: Vertical noise and bias σ over the horizontal ones (dimensionless).
        gnss_bias_m: Initial GNSS bias σ per horizontal axis (m).
        gnss_bias_walk_m_per_sqrt_s: Bias random-walk intensity (m/√s): σ of the drift after t is this·√t.
        gnss_rate_hz: GNSS solution rate (Hz).
        estimator_bandwidth_rad_s: Crossover ω_c of the GNSS/accelerometer complementary filter (rad/s).
        gnss_gate_sigma: Innovation gate in σ of the expected innovation (PX4 EKF2's
            ``EKF2_GPS_P_GATE``, default 5); 0 = no gate (every fix is fused).
        gnss_gate_reset_s: Consecutive rejection time after which the fixes are taken again (s)
            (EKF2's ``reset_timeout_max``, 7 s).
        gnss_reset_speed_mps: Largest speed of the estimate's correction per axis while the gate
            rejects or resets (m/s).
        gnss_step_m: Size of an injected horizontal GNSS step (m); 0 = none.
        gnss_step_at_s: Time the step starts (s).
        gnss_step_duration_s: How long it lasts (s); None = for the rest of the flight.
        gnss_step_direction_rad: Its direction from +x toward +y (rad); None = seeded per drone.
        clock_offset_s: σ of each drone's constant show-clock offset (s).
        wind_mean_mps: Mean wind speed at ``wind_ref_height_m`` (m/s).
        wind_direction_rad: Direction the mean wind blows toward, from +x toward +y (rad).
        wind_ref_height_m: Height of ``wind_mean_mps`` (m).
        wind_shear_exponent: Power-law exponent of the mean wind's height profile (dimensionless).
        turbulence_sigma_mps: RMS turbulence speed per horizontal axis (m/s).
        turbulence_length_m: Dryden scale length L (m): longitudinal correlation exp(-r/L).
        turbulence_vertical_factor: Vertical turbulence σ over horizontal σ (dimensionless).
        turbulence_modes: Number of random Fourier modes of the turbulence field.
        drag_coeff_kg_per_m: Quadratic drag coefficient c = ½ ρ C_d A (kg/m); wind needs it > 0.
        motor_time_constant_s: First-order motor lag of the squared rotor speeds (s); 0 = instant.
        mass_spread: σ of the relative plant-mass error per drone (dimensionless).
        inertia_spread: σ of the relative plant-inertia error per drone (dimensionless).
        thrust_spread: σ of the relative rotor thrust-gain error per drone (dimensionless).
        battery_sag: Mean thrust fraction lost by ``battery_duration_s`` (dimensionless).
        battery_sag_spread: σ of the per-drone sag (dimensionless).
        battery_duration_s: Nominal endurance of the pack (s): the sag grows linearly to its full
            value there and is held after it.
    """

    name: str = "ideal"
    gnss_noise_m: float = 0.0
    gnss_vertical_factor: float = 1.0
    gnss_bias_m: float = 0.0
    gnss_bias_walk_m_per_sqrt_s: float = 0.0
    gnss_rate_hz: float = 10.0
    estimator_bandwidth_rad_s: float = 2.0
    # The gate is on by default (a flight stack's estimator has one); it only acts with GNSS on.
    gnss_gate_sigma: float = 5.0
    gnss_gate_reset_s: float = 7.0
    gnss_reset_speed_mps: float = 0.5
    gnss_step_m: float = 0.0
    gnss_step_at_s: float = 0.0
    gnss_step_duration_s: float | None = None
    gnss_step_direction_rad: float | None = None
    clock_offset_s: float = 0.0
    wind_mean_mps: float = 0.0
    wind_direction_rad: float = 0.0
    wind_ref_height_m: float = 10.0
    wind_shear_exponent: float = 1.0 / 7.0
    turbulence_sigma_mps: float = 0.0
    turbulence_length_m: float = 150.0
    turbulence_vertical_factor: float = 1.0
    turbulence_modes: int = 128
    drag_coeff_kg_per_m: float = 0.0
    motor_time_constant_s: float = 0.0
    mass_spread: float = 0.0
    inertia_spread: float = 0.0
    thrust_spread: float = 0.0
    battery_sag: float = 0.0
    battery_sag_spread: float = 0.0
    # A show drone's endurance (the presets' value; see _VEHICLE).
    battery_duration_s: float = 1200.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("name", "wind_direction_rad", "gnss_step_direction_rad") or (
                    value is None and f.name == "gnss_step_duration_s"):
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"errors.{f.name} must be a finite number, got {value!r}")
            if value < 0:
                raise ValueError(f"errors.{f.name} must be >= 0, got {value}")
        for name in ("wind_direction_rad", "gnss_step_direction_rad"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                      or not math.isfinite(value)):
                raise ValueError(f"errors.{name} must be a finite number, got {value!r}")
        for name in ("gnss_rate_hz", "estimator_bandwidth_rad_s", "wind_ref_height_m", "turbulence_length_m",
                     "gnss_gate_reset_s", "gnss_reset_speed_mps"):
            if not getattr(self, name) > 0:
                raise ValueError(f"errors.{name} must be > 0, got {getattr(self, name)}")
        if self.gnss_rate_hz > 1000.0:
            raise ValueError(f"errors.gnss_rate_hz must be <= 1000 (the control rate), got {self.gnss_rate_hz}")
        if not 1 <= self.turbulence_modes <= 4096:
            raise ValueError(f"errors.turbulence_modes must be in [1, 4096], got {self.turbulence_modes}")
        if self.battery_sag > 0.9:
            raise ValueError(f"errors.battery_sag must be <= 0.9, got {self.battery_sag}")
        if not self.battery_duration_s > 0:
            raise ValueError(f"errors.battery_duration_s must be > 0, got {self.battery_duration_s}")
        if (self.wind_mean_mps > 0 or self.turbulence_sigma_mps > 0) and self.drag_coeff_kg_per_m == 0:
            raise ValueError("errors.drag_coeff_kg_per_m must be > 0 for the wind to act on the drones")

    # -- which parts are on (the engines skip the others) --------------------------------
    @property
    def has_gnss(self) -> bool:
        """True when the controller sees an estimate instead of the true position."""
        return (self.gnss_noise_m > 0 or self.gnss_bias_m > 0 or self.gnss_bias_walk_m_per_sqrt_s > 0
                or self.gnss_step_m > 0)

    @property
    def has_wind(self) -> bool:
        """True when a wind field acts (through quadratic drag)."""
        return self.wind_mean_mps > 0 or self.turbulence_sigma_mps > 0

    @property
    def has_spread(self) -> bool:
        """True when the drones' plants differ from each other."""
        return self.mass_spread > 0 or self.inertia_spread > 0 or self.thrust_spread > 0

    @property
    def is_ideal(self) -> bool:
        """True when every effect is off (the paper's ideal vehicle)."""
        return not (
            self.has_gnss or self.has_wind or self.has_spread or self.clock_offset_s > 0
            or self.drag_coeff_kg_per_m > 0 or self.motor_time_constant_s > 0
            or self.battery_sag > 0 or self.battery_sag_spread > 0
        )


# Literature values (docs/method.md §8 lists them with the sources):
#
# * RTK: u-blox ZED-F9P data sheet (UBX-17051259): RTK horizontal accuracy 0.01 m + 1 ppm CEP,
#   vertical 0.01 m + 1 ppm R50, RTK rate up to 20 Hz. CEP = 1.18 σ for a circular Gaussian,
#   so 1 cm CEP is ~0.85 cm per axis; we take 1 cm per axis horizontally and 1.5× that
#   vertically (vertical GNSS error is typically 1.5-2× the horizontal), 10 Hz.
# * GNSS only: u-blox NEO-M8N data sheet (UBX-15031086): 2.5 m CEP horizontal (autonomous);
#   the error is mostly a slowly varying bias (ionosphere, multipath), so 1.5 m bias σ
#   walking a few cm/√s, 0.3 m white, 2× vertically.
# * Turbulence: MIL-F-8785C §3.7 / MIL-HDBK-1797 low-altitude Dryden model at h = 30 m (98 ft):
#   L_u = h / (0.177 + 0.000823 h)^1.2 = 499 ft = 152 m, σ_w = 0.1 W20,
#   σ_u / σ_w = 1 / (0.177 + 0.000823 h)^0.4 = 1.72. "Light" turbulence is W20 = 15 kt
#   (7.7 m/s): σ_w = 0.77 m/s, σ_u = 1.3 m/s. Calm: W20 = 3 m/s: σ_u = 0.5 m/s.
# * Mean wind profile: power law, exponent 1/7 over open terrain (Hellmann; IEC 61400-1 uses 0.2).
# * Drag: c = ½ ρ C_d A with ρ = 1.225 kg/m³, C_d ≈ 1, A ≈ 0.03 m² for a 0.5 kg quadrotor: 0.018 kg/m.
# * Motors: 20 ms first-order time constant (small brushless motors with 5-inch props are
#   quoted at 20-50 ms; the measurements use 20 and 40 ms).
# * Spread: mass ±2 %, inertia ±5 %, thrust gain ±3 % (1 σ; manufacturing and payload spread).
# * Battery: LiPo voltage sag over a flight costs ~20-30 % of the thrust at a given command
#   by the end of the pack (issue 20); 25 % ± 5 %, reached at the pack's endurance: 20 minutes,
#   Intel's figure for its Shooting Star show drone ("can fly for up to 20 minutes", Intel and
#   Disney's Starbright Holidays announcement, Nov. 2016; eeNews Europe: "an autonomy up to
#   20 minutes").
_RTK: dict[str, Any] = {
    "gnss_noise_m": 0.01, "gnss_vertical_factor": 1.5, "gnss_bias_m": 0.01,
    "gnss_bias_walk_m_per_sqrt_s": 0.001, "gnss_rate_hz": 10.0, "estimator_bandwidth_rad_s": 2.0,
    # Show clocks synchronised to GNSS time through the ground station: ~1 ms.
    "clock_offset_s": 0.001,
}
_VEHICLE: dict[str, Any] = {
    "drag_coeff_kg_per_m": 0.018, "motor_time_constant_s": 0.02,
    "mass_spread": 0.02, "inertia_spread": 0.05, "thrust_spread": 0.03,
    "battery_sag": 0.25, "battery_sag_spread": 0.05, "battery_duration_s": 1200.0,
}
_WIND: dict[str, Any] = {"wind_ref_height_m": 10.0, "wind_shear_exponent": 1.0 / 7.0, "turbulence_length_m": 152.0,
         "turbulence_vertical_factor": 1.0 / 1.72}

#: Named error models ("ideal", "calm-rtk", "gusty-rtk", "gps-only").
ERROR_PRESETS: dict[str, ErrorModel] = {
    "ideal": ErrorModel(),
    "calm-rtk": ErrorModel(name="calm-rtk", **_RTK, **_VEHICLE, **_WIND,
                           wind_mean_mps=2.0, turbulence_sigma_mps=0.5),
    "gusty-rtk": ErrorModel(name="gusty-rtk", **_RTK, **_VEHICLE, **_WIND,
                            wind_mean_mps=7.7, turbulence_sigma_mps=1.3),
    "gps-only": ErrorModel(
        name="gps-only", **_VEHICLE, **_WIND, wind_mean_mps=2.0, turbulence_sigma_mps=0.5,
        gnss_noise_m=0.3, gnss_vertical_factor=2.0, gnss_bias_m=1.5, gnss_bias_walk_m_per_sqrt_s=0.03,
        gnss_rate_hz=5.0, estimator_bandwidth_rad_s=1.0,
        # Without RTK the show clock comes from each receiver's own time solution and the radio link.
        clock_offset_s=0.01,
    ),
}


def error_preset(name: str) -> ErrorModel:
    """The preset called ``name`` (one of :data:`ERROR_PRESETS`).

    Raises:
        ValueError: an unknown name (names it and lists the presets).
    """
    try:
        return ERROR_PRESETS[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"unknown error preset {name!r} (expected one of {', '.join(ERROR_PRESETS)})"
        ) from None
