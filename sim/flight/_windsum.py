"""The turbulence field's Fourier-mode sum, fused (numba): the error models' wind at 1,000s of drones.

Summing M = 128 modes with numpy makes ~10 passes over every point array per mode; at a
1,000-drone show that was 11 % of a Monte-Carlo run (issue 20: the wind tables of
:mod:`sim.flight.engines._tables`, evaluated per run because the field is seeded per run).
Here each point sums its modes in one register loop, points in parallel. The order of the
additions per point is the numpy loop's (mode by mode, x then y then z), and a point's
value does not depend on the other points or on the thread that computes it.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["turbulence_sum"]


@numba.njit(parallel=True, cache=True, nogil=True)
def turbulence_sum(
    out: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray, t: np.ndarray, k: np.ndarray,
    amp: np.ndarray, omega: np.ndarray, phase: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """``out[p] += Σ_m amp[m] cos(k[m]·(x, y, z)[p] + ω[m] t[p] + φ[m])`` for every point p, in place.

    Args:
        out: ``(P, 3)`` wind (m/s), added to.
        x, y, z: ``(P,)`` the advected point coordinates (m).
        t: ``(P,)`` times (s).
        k: ``(M, 3)`` wave vectors (rad/m).
        amp: ``(M, 3)`` mode amplitudes (m/s).
        omega: ``(M,)`` temporal drift (rad/s).
        phase: ``(M,)`` phases (rad).
    """
    for p in numba.prange(x.shape[0]):
        o0, o1, o2 = out[p, 0], out[p, 1], out[p, 2]
        xp, yp, zp, tp = x[p], y[p], z[p], t[p]
        for m in range(k.shape[0]):
            c = np.cos(k[m, 0] * xp + k[m, 1] * yp + k[m, 2] * zp + omega[m] * tp + phase[m])
            o0 += amp[m, 0] * c
            o1 += amp[m, 1] * c
            o2 += amp[m, 2] * c
        out[p, 0], out[p, 1], out[p, 2] = o0, o1, o2
