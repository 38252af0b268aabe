"""External disturbances: none, the paper's Δ1/Δ2 (docs/method.md §7) and seeded wind.

Every disturbance is built from *sinusoid banks*, each a function of time only::

    b(t) = bias + Σ_k amp[k] * sin(omega[k] t + phase[k])        (3 components)

and enters the model as

    Δ1 = accel(t) + drag_per_s * (wind(t) - v)       (m/s², added to v̇)
    Δ2 = angular(t)                                   (rad/s², added to Θ̈)

``Δ2`` is an **angular acceleration of the Euler angles**, not a torque: the paper's
``0.1 sin t``-sized Δ2 read as N·m would be ~42 rad/s² on this airframe, far beyond
what β = 4 rejects, and the paper's Figs. 3-5 are consistent with rad/s² in the e4
dynamics (docs/method.md §7). The plant adds ``W⁻¹ Δ2`` to Ω̇ so ``Θ̈`` gets exactly Δ2.

The ``"wind"`` disturbance is a linear-drag model: steady wind plus gusts drawn as a seeded
sum of sinusoids (frequencies log-spread over 0.05-1 Hz), uniform over the fleet (every
drone sees the same wind at the same time). Because banks depend on time only, engines
evaluate them once per step for all drones. The error models' wind varies in space and
time (:class:`WindField`, below): the engines feel it at each drone's flown position.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np

__all__ = ["Disturbance", "SinusoidBank", "make_disturbance"]

T = TypeVar("T")

#: Columns of a wind-derivative row (:meth:`WindField.velocity_and_gradients_into`): the
#: turbulence's Jacobian, row-major (9), then the mean shear (2); the engines' table layout.
WIND_GRADIENT_COLUMNS = 11


@dataclass(frozen=True)
class SinusoidBank:
    """``b(t) = bias + Σ_k amp[k] sin(omega[k] t + phase[k])`` per axis.

    Attributes:
        bias: ``(3,)`` constant part (unit of the bank).
        amp: ``(K, 3)`` amplitudes (unit of the bank).
        omega_rad_s: ``(K,)`` angular frequencies (rad/s).
        phase_rad: ``(K, 3)`` phases (rad).
    """

    bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    amp: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    omega_rad_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    phase_rad: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __call__(self, times_s: np.ndarray) -> np.ndarray:
        """Evaluate at ``(T,)`` times (s); returns ``(T, 3)``."""
        t = np.asarray(times_s, dtype=np.float64).reshape(-1)
        out = np.broadcast_to(np.asarray(self.bias, dtype=np.float64), (t.size, 3)).copy()
        for k in range(len(self.omega_rad_s)):
            out += self.amp[k] * np.sin(self.omega_rad_s[k] * t[:, None] + self.phase_rad[k])
        return out


@dataclass(frozen=True)
class Disturbance:
    """Additive disturbances for every drone.

    Attributes:
        name: Label used in reports.
        accel: Bank for the direct part of Δ1 (m/s²).
        wind: Bank for the wind velocity (m/s), world frame.
        drag_per_s: Linear drag coefficient over mass (1/s); 0 disables the wind.
        angular: Bank for Δ2 (rad/s², Euler-angle acceleration).
    """

    name: str = "none"
    accel: SinusoidBank = field(default_factory=SinusoidBank)
    wind: SinusoidBank = field(default_factory=SinusoidBank)
    drag_per_s: float = 0.0
    angular: SinusoidBank = field(default_factory=SinusoidBank)

    def signals(self, times_s: np.ndarray) -> np.ndarray:
        """Time-only signals for the engines, ``(T, 9)``: accel (m/s²), wind (m/s), Δ2."""
        return np.concatenate(
            [self.accel(times_s), self.wind(times_s), self.angular(times_s)], axis=1
        )

    @classmethod
    def none(cls) -> Disturbance:
        """No disturbance."""
        return cls()

    @classmethod
    def paper(cls) -> Disturbance:
        """Spec section 7: ``Δ1 = Δ2 = [0.1 sin t, 0.1 cos t, 0.1 (sin t + cos t)]``.

        Δ1 in m/s², Δ2 in rad/s² (Euler-angle acceleration, see the module docstring).
        ``0.1 (sin t + cos t) = 0.1 √2 sin(t + π/4)``, so one bank mode suffices.
        """
        bank = SinusoidBank(
            bias=np.zeros(3),
            amp=np.array([[0.1, 0.1, 0.1 * np.sqrt(2.0)]]),
            omega_rad_s=np.array([1.0]),
            phase_rad=np.array([[0.0, np.pi / 2.0, np.pi / 4.0]]),
        )
        return cls(name="paper", accel=bank, angular=bank)

    @classmethod
    def wind_gusts(
        cls,
        *,
        mean_mps: tuple[float, float, float] = (4.0, 0.0, 0.0),
        gust_mps: float = 1.5,
        drag_per_s: float = 0.3,
        modes: int = 6,
        seed: int = 0,
    ) -> Disturbance:
        """Steady wind plus seeded gusts acting through linear drag.

        Args:
            mean_mps: Steady wind velocity, world frame (m/s).
            gust_mps: RMS gust speed per horizontal axis (m/s); vertical gusts are
                a third of that.
            drag_per_s: Linear drag coefficient over mass (1/s).
            modes: Number of sinusoids in the gust sum.
            seed: Random seed (same seed, same wind).
        """
        rng = np.random.default_rng(seed)
        freq_hz = np.geomspace(0.05, 1.0, modes) * rng.uniform(0.8, 1.25, modes)
        # Energy falls with frequency like a von Kármán-ish spectrum (~f^-5/6 in amplitude).
        weights = freq_hz ** (-5.0 / 6.0)
        weights *= np.sqrt(2.0 / np.sum(weights**2))  # RMS of the sum equals 1
        amp = weights[:, None] * np.array([gust_mps, gust_mps, gust_mps / 3.0])[None, :]
        bank = SinusoidBank(
            bias=np.asarray(mean_mps, dtype=np.float64),
            amp=amp,
            omega_rad_s=2.0 * np.pi * freq_hz,
            phase_rad=rng.uniform(0.0, 2.0 * np.pi, (modes, 3)),
        )
        return cls(name="wind", wind=bank, drag_per_s=float(drag_per_s))


def make_disturbance(kind: str | Disturbance | None, *, seed: int = 0) -> Disturbance:
    """Resolve ``"none" | "paper" | "wind"`` (or an instance, or None) to a Disturbance."""
    if isinstance(kind, Disturbance):
        return kind
    if kind is None or kind == "none":
        return Disturbance.none()
    if kind == "paper":
        return Disturbance.paper()
    if kind == "wind":
        return Disturbance.wind_gusts(seed=seed)
    raise ValueError(f"unknown disturbance {kind!r} (expected none, paper or wind)")


# ----------------------------------------------------------------------------------------
# A wind field varying in space and time (the error models' wind, sim.flight._errors)
# ----------------------------------------------------------------------------------------
#: Largest k·L of the turbulence modes: the Dryden energy above it (0.85 % of the variance,
#: wavelengths below L/30) is left out; it would only alias in the 10 Hz wind tables.
TURBULENCE_KL_MAX = 200.0
#: Lowest height of the mean-wind profile (m): the power law vanishes at the ground.
WIND_MIN_HEIGHT_M = 1.0
#: The engines feel the wind at the *flown* position by a first-order expansion about the
#: planned one (see :func:`sim.flight.engines._tables.flown_wind`). The turbulence part uses
#: the displacement clamped per axis to ``±L / 150`` (1 m at L = 150 m): the resolved modes
#: reach k = 200 / L, and a linear term extrapolated past ~1/k overshoots a bounded cosine.
#: Averaged over the Dryden ensemble (seeds, points, isotropic displacement directions), the
#: mean-square error of the expansion, relative to that of the wind at the planned position
#: (the model before), is 0.007 at d = L/500, 0.07 at L/150, 0.17 at L/100, 0.53 at L/50,
#: 0.89 at L/20 and 1.00 (within the 0.5 % sampling error: never worse) at d ≥ L/2. Clamping
#: per axis needs no square root or division in the kernel; a ball clamp of the same radius
#: does no better, and a box of L/70 is already worse than no correction at d ≈ L/20
#: (``tests/test_flight_wind.py`` checks "never worse" over seeds).
TURBULENCE_LINEAR_RADIUS_FRACTION = 1.0 / 150.0
#: The mean profile's part uses the vertical displacement clamped to ``±0.5 z_plan``: the
#: power law ``(z/z_ref)^a`` is concave, its tangent is within 2.6 % (a = 1/7) of it down to
#: half the height and 1.2 % up to 1.5 times the height.
SHEAR_LINEAR_RADIUS_FRACTION = 0.5


def _dryden_cdf(x: np.ndarray) -> np.ndarray:
    """∫0^x s⁴/(1+s²)³ ds: the cumulative Dryden energy spectrum in k·L (unnormalised)."""
    out: np.ndarray = (3.0 * np.arctan(x) - x * (5.0 * x * x + 3.0) / (1.0 + x * x) ** 2) / 8.0
    return out


def dryden_correlation(distance_m: np.ndarray, length_m: float, *, longitudinal: bool) -> np.ndarray:
    """Dryden's velocity correlation coefficient at separation r (MIL-F-8785C; von Kármán & Howarth).

    Longitudinal (velocity component along the separation): ``f(r) = exp(-r/L)``;
    lateral (component across it): ``g(r) = f + r f'/2 = (1 - r/(2L)) exp(-r/L)``.
    """
    r = np.asarray(distance_m, dtype=np.float64) / float(length_m)
    out: np.ndarray = np.exp(-r) if longitudinal else (1.0 - 0.5 * r) * np.exp(-r)
    return out


@dataclass(frozen=True)
class WindField:
    """Mean wind with a power-law height profile plus frozen isotropic Dryden turbulence.

    Turbulence is a sum of M random Fourier modes (Kraichnan 1970, "Diffusion by a
    random velocity field"): wave vectors ``k_m`` drawn isotropically with ``|k|`` from
    the Dryden energy spectrum ``E(k) ∝ (kL)⁴ / (1 + (kL)²)³`` (the 3-D spectrum whose
    longitudinal correlation is ``exp(-r/L)``, Pope 2000 eq. 6.207 applied to the
    Dryden 1-D spectrum), amplitudes ``P(k_m) g_m`` (projected normals, so the field is
    divergence-free) scaled so that ``E[u uᵀ](r)`` equals the Dryden correlation tensor
    in expectation over seeds::

        u(x, t) = √(3/M) σ Σ_m P(k_m) g_m cos(k_m·(x - U t) + ω_m t + φ_m)

    It is advected by the mean wind at the reference height (Taylor's frozen
    turbulence) and each mode also drifts in time with ``ω_m ~ N(0, (σ |k_m|)²)`` so
    that a calm field still changes. The vertical component is scaled by
    ``vertical_factor`` (MIL-F-8785C's σ_w / σ_u at low altitude).

    Attributes:
        mean_mps: Mean wind speed at ``ref_height_m`` (m/s).
        direction_rad: Direction the mean wind blows toward (rad from +x toward +y).
        ref_height_m: Reference height of ``mean_mps`` (m).
        shear_exponent: Power-law exponent of the height profile.
        wavevectors: ``(M, 3)`` k_m (rad/m).
        amplitudes: ``(M, 3)`` the modes' velocity amplitudes (m/s).
        omega_rad_s: ``(M,)`` temporal drift of each mode (rad/s).
        phase_rad: ``(M,)`` phases (rad).
        length_m: Dryden scale length L (m), which sets the linearisation radius.
    """

    mean_mps: float
    direction_rad: float
    ref_height_m: float
    shear_exponent: float
    wavevectors: np.ndarray
    amplitudes: np.ndarray
    omega_rad_s: np.ndarray
    phase_rad: np.ndarray
    length_m: float = 150.0

    @classmethod
    def dryden(
        cls, *, mean_mps: float = 0.0, direction_rad: float = 0.0, ref_height_m: float = 10.0,
        shear_exponent: float = 1.0 / 7.0, sigma_mps: float = 0.0, length_m: float = 150.0,
        vertical_factor: float = 1.0, modes: int = 128, seed: int = 0,
    ) -> WindField:
        """Draw a field (one per seed; the same for every drone, shard and chunk)."""
        rng = np.random.default_rng(np.random.SeedSequence([int(seed) & 0xFFFFFFFF, 0x57494E44]))
        m = int(modes)
        # |k| L by inverting the Dryden energy CDF on a fine grid.
        grid = np.concatenate([[0.0], np.geomspace(1e-4, TURBULENCE_KL_MAX, 4000)])
        cdf = _dryden_cdf(grid)
        kl = np.interp(rng.uniform(0.0, cdf[-1], m), cdf, grid)
        direction = rng.normal(size=(m, 3))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        k = direction * (kl / float(length_m))[:, None]
        g = rng.normal(size=(m, 3))
        g -= np.sum(g * direction, axis=1, keepdims=True) * direction  # P(k) g: across k
        amp = np.sqrt(3.0 / m) * float(sigma_mps) * g
        amp[:, 2] *= float(vertical_factor)
        return cls(
            mean_mps=float(mean_mps), direction_rad=float(direction_rad), ref_height_m=float(ref_height_m),
            shear_exponent=float(shear_exponent), wavevectors=k, amplitudes=amp,
            omega_rad_s=rng.normal(size=m) * float(sigma_mps) * np.linalg.norm(k, axis=1),
            phase_rad=rng.uniform(0.0, 2.0 * np.pi, m), length_m=float(length_m),
        )

    @property
    def linear_radius_m(self) -> float:
        """Half-side (m) of the box the turbulence's first-order expansion is clamped to."""
        return TURBULENCE_LINEAR_RADIUS_FRACTION * self.length_m

    def mean_velocity(self, heights_m: np.ndarray) -> np.ndarray:
        """Mean wind ``(P, 3)`` (m/s) at heights ``(P,)``: ``U (z / z_ref)^a`` horizontally."""
        z = np.maximum(np.asarray(heights_m, dtype=np.float64), WIND_MIN_HEIGHT_M)
        speed = self.mean_mps * (z / self.ref_height_m) ** self.shear_exponent
        out = np.zeros((z.size, 3))
        out[:, 0] = speed * np.cos(self.direction_rad)
        out[:, 1] = speed * np.sin(self.direction_rad)
        return out

    def mean_shear(self, heights_m: np.ndarray) -> np.ndarray:
        """``(P, 2)`` the mean wind's ``∂U_x/∂z, ∂U_y/∂z`` (1/s) at heights ``(P,)``: ``a U(z) / z``, 0 below 1 m."""
        z = np.asarray(heights_m, dtype=np.float64).reshape(-1)
        zc = np.maximum(z, WIND_MIN_HEIGHT_M)
        speed = self.mean_mps * (zc / self.ref_height_m) ** self.shear_exponent
        rate = np.where(z > WIND_MIN_HEIGHT_M, self.shear_exponent * speed / zc, 0.0)
        return np.stack([rate * np.cos(self.direction_rad), rate * np.sin(self.direction_rad)], axis=1)

    def _advected(self, points_m: np.ndarray, times_s: np.ndarray) -> tuple[np.ndarray, ...]:
        """Points ``(P, 3)``, times ``(P,)`` and the coordinates x, y, z of the frozen field (contiguous)."""
        pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 3)
        t = np.ascontiguousarray(np.broadcast_to(np.asarray(times_s, dtype=np.float64), pts.shape[:1]))
        ux = self.mean_mps * np.cos(self.direction_rad)
        uy = self.mean_mps * np.sin(self.direction_rad)
        # Frozen turbulence swept by the mean wind at the reference height.
        x, y, z = pts[:, 0] - ux * t, pts[:, 1] - uy * t, pts[:, 2]
        return pts, t, np.ascontiguousarray(x), np.ascontiguousarray(y), np.ascontiguousarray(z)

    def velocity_and_gradients(
        self, points_m: np.ndarray, times_s: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The wind and its spatial derivatives, split as the engines' expansion uses them.

        Returns:
            ``velocity (P, 3)`` (m/s, the same bits as :meth:`velocity`), the turbulence's
            Jacobian ``(P, 3, 3)`` ``∂u_i/∂x_j`` (1/s; closed form: each mode's cosine
            differentiates to ``-amp k_j sin``) and the mean profile's shear ``(P, 2)``
            (:meth:`mean_shear`). The full Jacobian is their sum (:meth:`jacobian`).
        """
        n = np.asarray(points_m).reshape(-1, 3).shape[0]
        vel, grad = np.empty((n, 3)), np.empty((n, WIND_GRADIENT_COLUMNS))
        self.velocity_and_gradients_into(points_m, times_s, vel, grad)
        return vel, np.ascontiguousarray(grad[:, 0:9]).reshape(-1, 3, 3), np.ascontiguousarray(grad[:, 9:11])

    def velocity_and_gradients_into(
        self, points_m: np.ndarray, times_s: np.ndarray, velocity_out: np.ndarray, gradients_out: np.ndarray, *,
        threads: int = 1, alongside: Callable[[], T] | None = None,
    ) -> T | None:
        """:meth:`velocity_and_gradients` written into the engines' table layout (the same bits).

        Args:
            points_m: ``(P, 3)`` points (m).
            times_s: ``(P,)`` times (s).
            velocity_out: ``(P, 3)`` overwritten with the wind (m/s).
            gradients_out: ``(P, WIND_GRADIENT_COLUMNS)`` overwritten with the turbulence's
                Jacobian, row-major (columns 0-8), then the mean shear (9-10), 1/s: the wind
                tables' rows, written in place instead of assembled from three fresh arrays.
            threads: Threads for the mode sum (:func:`sim.flight._windsum.turbulence_sum_and_jacobian`).
            alongside: A task run on a thread of its own while the mode sum runs, started once
                the sum's inputs are ready (the tables' GNSS draws: their numpy glue and this
                method's would otherwise take turns at the GIL).

        Returns:
            ``alongside()``, or None without it.
        """
        pts, t, x, y, z = self._advected(points_m, times_s)
        if velocity_out.shape != (pts.shape[0], 3) or gradients_out.shape != (pts.shape[0], WIND_GRADIENT_COLUMNS):
            raise ValueError(f"velocity_and_gradients_into: {velocity_out.shape}, {gradients_out.shape} "
                             f"for {pts.shape[0]} points")
        # The mean profile and its shear from one power (the expressions of mean_velocity and mean_shear,
        # so their bits; the power of 48,000 heights is ~1 ms, each of the two had its own).
        z_m = np.ascontiguousarray(pts[:, 2])
        zc = np.maximum(z_m, WIND_MIN_HEIGHT_M)
        speed = self.mean_mps * (zc / self.ref_height_m) ** self.shear_exponent
        cos_d, sin_d = np.cos(self.direction_rad), np.sin(self.direction_rad)
        velocity_out[:, 0] = speed * cos_d
        velocity_out[:, 1] = speed * sin_d
        velocity_out[:, 2] = 0.0
        rate = np.where(z_m > WIND_MIN_HEIGHT_M, self.shear_exponent * speed / zc, 0.0)
        gradients_out[:, 0:9] = 0.0
        gradients_out[:, 9] = rate * cos_d
        gradients_out[:, 10] = rate * sin_d
        from sim.flight._threads import Beside
        from sim.flight._windsum import turbulence_sum_and_jacobian

        beside = None if alongside is None else Beside(alongside)
        try:
            turbulence_sum_and_jacobian(velocity_out, gradients_out, x, y, z, t, *self._modes(), threads=threads)
        finally:
            value = None if beside is None else beside.result()
        return value

    def jacobian(self, points_m: np.ndarray, times_s: np.ndarray) -> np.ndarray:
        """``(P, 3, 3)`` the full spatial Jacobian ``∂w_i/∂x_j`` (1/s) at points ``(P, 3)`` and times ``(P,)``."""
        _, jac, shear = self.velocity_and_gradients(points_m, times_s)
        jac[:, 0:2, 2] += shear
        return jac

    def _modes(self) -> tuple[np.ndarray, ...]:
        return (np.ascontiguousarray(self.wavevectors, dtype=np.float64),
                np.ascontiguousarray(self.amplitudes, dtype=np.float64),
                np.ascontiguousarray(self.omega_rad_s, dtype=np.float64),
                np.ascontiguousarray(self.phase_rad, dtype=np.float64))

    def velocity(self, points_m: np.ndarray, times_s: np.ndarray) -> np.ndarray:
        """Wind ``(P, 3)`` (m/s) at points ``(P, 3)`` (m) and times ``(P,)`` (s).

        Element-wise and in a fixed order (no BLAS), so a point's value does not depend
        on which other points are evaluated with it.
        """
        pts, t, x, y, z = self._advected(points_m, times_s)
        out = self.mean_velocity(pts[:, 2])
        # The mode sum, compiled and vectorised (sim.flight._windsum; imported here: numba loads in ~1 s).
        from sim.flight._windsum import turbulence_sum

        turbulence_sum(out, x, y, z, t, *self._modes())
        return out
