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

The wind is a linear-drag model: steady wind plus gusts drawn as a seeded sum of
sinusoids (frequencies log-spread over 0.05-1 Hz). The gust field is uniform over the
fleet (every drone sees the same wind at the same time); spatial decorrelation is
not modelled. Because banks depend on time only, engines evaluate them once per
step for all drones.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Disturbance", "SinusoidBank", "make_disturbance"]


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
