"""Finite-time multivariable integral sliding-mode control (docs/method.md §4 and §6).

Both loops share one structure, for an error pair ``(e, ė)`` with ``ë = u + f + d``::

    u_n = -k_a sig(e, r_a) - k_b sig(ė, r_b) - f          (nominal, eq. 28)
    s   = ė(t) - ė(0) - ∫0^t (u_n + f) dt                  (eq. 30; s(0) = 0)
    ω̃   = -α ( s/||s|| + 0.5 ṡ/||ṡ|| )                     (eq. 35)
    u_d = ∫ ω̃ dt                                          (eq. 36, continuous)
    u   = u_n + u_d

Discrete implementation at the control step ``dt`` (textbook sampled form, the paper is
silent on it):

* ``ṡ``'s direction is taken from the backward difference ``s_k - s_{k-1}`` (no
  accelerometer needed; only the direction enters ω̃). At k = 0 it is zero.
* ``∫(u_n + f)`` and ``u_d`` are integrated with the rectangle rule, values of step k
  held over ``[t_k, t_{k+1}]``; ``u`` at step k uses ``u_d`` of step k.
* Anti-windup: when any rotor of a drone saturates at step k, that drone's ``u_d``
  (position and attitude) is not advanced; ``∫(u_n + f)`` keeps integrating so ``s``
  keeps measuring the true mismatch.
* The two directions of ω̃ use a boundary layer ``x / max(||x||, SWITCH_EPS)`` with
  ``SWITCH_EPS = 1e-9`` (m/s or rad/s). In normal sliding the discrete twisting keeps
  ``||s||`` near ``α dt²`` (~5e-6), far above it, so performance is unchanged; it only
  replaces the direction of a vector made of rounding noise (e.g. ``s - s_prev`` when it
  is exactly or nearly zero) by a proportional term, so a 1e-17 difference cannot turn
  into a full-size switching step.
* ``sig`` and unit vectors are guarded at zero (ISMC makes ``s(0) = 0`` exactly, an
  unguarded ``||s||^(r-1)`` is NaN at step 0). ``r = 1/2`` is evaluated as
  ``1/sqrt(||x||)`` (exact and cheap) in every engine.

The paper's gains (section 3.4) are the defaults. Note they do not satisfy the
homogeneity relation ``r1 = r2 / (2 - r2)`` of Lemma 1 (that gives 5/9 for r2 = 5/7,
the paper uses 1/2); the paper's values are kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.flight.control._attitude import CommandFilter

__all__ = [
    "SWITCH_EPS",
    "AttitudeGains",
    "IsmcGains",
    "PositionGains",
    "ismc_nominal",
    "ismc_switching",
    "sig",
    "unit",
]


#: Boundary layer of the switching directions (m/s for the position loop, rad/s for attitude).
SWITCH_EPS = 1e-9


@dataclass(frozen=True, slots=True)
class PositionGains:
    """Position-loop gains (paper section 3.4).

    Attributes:
        k1: Gain on sig(e1) (1/s² · m^(1-r1)).
        k2: Gain on sig(e2) (units making k2 sig(e2) an acceleration, m/s²).
        r1: Exponent on the position error, 0 < r1 < 1.
        r2: Exponent on the velocity error, 0 < r2 < 1.
        alpha: Switching gain α (m/s³), must exceed twice the bound on ||ḋ||.
    """

    k1: float = 5.0
    k2: float = 4.0
    r1: float = 0.5
    r2: float = 5.0 / 7.0
    alpha: float = 5.0


@dataclass(frozen=True, slots=True)
class AttitudeGains:
    """Attitude-loop gains (paper section 3.4).

    Attributes:
        k3: Gain on sig(e3) (rad/s² scale).
        k4: Gain on sig(e4) (rad/s² scale).
        r3: Exponent on the angle error, 0 < r3 < 1.
        r4: Exponent on the angle-rate error, 0 < r4 < 1.
        beta: Switching gain β (rad/s³).
    """

    k3: float = 12.0
    k4: float = 5.0
    r3: float = 0.5
    r4: float = 5.0 / 7.0
    beta: float = 4.0


@dataclass(frozen=True, slots=True)
class IsmcGains:
    """All controller settings: both ISMC loops and the Θ_ref command filter."""

    position: PositionGains = PositionGains()
    attitude: AttitudeGains = AttitudeGains()
    filter: CommandFilter = CommandFilter()
    kind: str = "ismc"

    def as_vector(self) -> np.ndarray:
        """Pack for the fused kernel: ``[k1,k2,r1,r2,α,k3,k4,r3,r4,β,ω_n,ζ]``."""
        p, a, f = self.position, self.attitude, self.filter
        return np.array(
            [p.k1, p.k2, p.r1, p.r2, p.alpha, a.k3, a.k4, a.r3, a.r4, a.beta,
             f.omega_n_rad_s, f.zeta],
            dtype=np.float64,
        )


def sig(x: np.ndarray, r: float) -> np.ndarray:
    """Vector ``sig(x, r) = ||x||^r x / ||x||`` row-wise, 0 at x = 0.

    Args:
        x: ``(N, 3)`` vectors (any unit).
        r: Exponent (dimensionless); r = 1 returns x, r = 1/2 uses 1/sqrt.

    Returns:
        ``(N, 3)`` with norm ``||x||^r``.
    """
    n = np.sqrt(np.sum(x * x, axis=1))
    pos = n > 0.0
    safe = np.where(pos, n, 1.0)
    if r == 1.0:
        scale = np.ones_like(n)
    elif r == 0.5:
        scale = 1.0 / np.sqrt(safe)
    else:
        scale = np.power(safe, r - 1.0)
    return x * np.where(pos, scale, 0.0)[:, None]


def unit(x: np.ndarray, eps: float = 0.0) -> np.ndarray:
    """Row-wise ``x / max(||x||, eps)``, 0 where ``x = 0`` (``(N, 3)``).

    Args:
        x: ``(N, 3)`` vectors (any unit).
        eps: Boundary layer (unit of x): below it the result is ``x / eps``, linear
            instead of a unit vector. 0 gives the pure direction.
    """
    n = np.sqrt(np.sum(x * x, axis=1))
    pos = n > 0.0
    return x * np.where(pos, 1.0 / np.maximum(np.where(pos, n, 1.0), eps), 0.0)[:, None]


def ismc_nominal(
    e: np.ndarray, e_dot: np.ndarray, f: np.ndarray, *, k_a: float, k_b: float,
    r_a: float, r_b: float,
) -> np.ndarray:
    """Nominal finite-time control ``u_n = -k_a sig(e, r_a) - k_b sig(ė, r_b) - f`` (eq. 28)."""
    out: np.ndarray = -k_a * sig(e, r_a) - k_b * sig(e_dot, r_b) - f
    return out


def ismc_switching(s: np.ndarray, s_prev: np.ndarray, *, gain: float) -> np.ndarray:
    """Switching law ``ω̃ = -gain (s/||s|| + 0.5 ṡ/||ṡ||)`` (eq. 35), ṡ ∝ ``s - s_prev``.

    Both directions use the boundary layer ``SWITCH_EPS`` (see the module docstring).
    """
    return -gain * (unit(s, SWITCH_EPS) + 0.5 * unit(s - s_prev, SWITCH_EPS))
