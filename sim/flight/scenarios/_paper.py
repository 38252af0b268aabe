"""The paper's single-drone scenario (docs/method.md §7), its metrics and its figure.

Reference ``p_ref = [sin t, cos t, sin t]`` (m), ψ_ref = 0; disturbances
``Δ1 = Δ2 = [0.1 sin t, 0.1 cos t, 0.1 (sin t + cos t)]`` with Δ1 in m/s² and Δ2 an
Euler-angle acceleration in rad/s² (see ``sim.flight._disturbance``); start at
``p0 = [2, -3, 2]`` m, at rest, ``Θ0 = [0.2, -0.3, 0.2]`` rad; the paper's gains;
20 s at the 1 ms step. Every control step is recorded.

Errors reported:

* ``pos_err_m``: ``||p - p_ref||`` (m).
* ``att_err_rad``: ``||Θ - Θ_ref||`` (rad) against the *raw* eq. 51 reference computed
  from the position loop's output at that step (the stricter of the two: it includes
  the command filter's lag). ``att_err_tracked_rad`` is the error to the filtered
  command ``Θ_c`` that the attitude ISMC actually tracks (its e3).

``settle_time_s`` is the first time after which the position error stays below
1e-3 m and the attitude error below 1e-2 rad until the end (the scenario's thresholds).
``max_thrust_step_n`` is the largest change of the thrust between consecutive steps
over the whole run; ``max_thrust_step_after_settle_n`` the same after settling.

What the figure shows: after settling the thrust is smooth (a few mN per step), while
the torques stay bounded (peak ~0.35 N·m, 60 % of the airframe's authority) but
carry a ~9 Hz limit cycle and change by up to ~0.17 N·m between steps. The cause is
the position loop's switching input u_d: it never stops moving (its rate is between
α/2 and 3α/2 and flips direction between steps in sliding), so Θ_ref zigzags by up to
~α dt / g per step, and the command filter passes ``ω_n² ΔΘ_ref`` straight into Θ̈_c;
closing the loop through the filter and attitude lag gives the classic sliding-mode
limit cycle with unmodelled actuator dynamics. A lower ω_n smooths the torques but
lets the lag break the 1e-3 m position requirement (table in ``sim.flight.control._attitude``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.flight._options import CONTROLLERS
from sim.flight.control._baseline import BaselineGains
from sim.flight.control._ismc import IsmcGains
from sim.flight.engines._driver import simulate
from sim.flight.engines._state import TELEMETRY_FIELDS, TrackingReference

__all__ = [
    "PAPER_ATT_THRESHOLD_RAD",
    "PAPER_POS_THRESHOLD_M",
    "PaperRun",
    "paper_report",
    "plot_paper",
    "run_paper_scenario",
]

PAPER_POS_THRESHOLD_M = 1e-3
PAPER_ATT_THRESHOLD_RAD = 1e-2
PAPER_STEADY_FROM_S = 8.0
PAPER_DURATION_S = 20.0
PAPER_P0_M = (2.0, -3.0, 2.0)
PAPER_THETA0_RAD = (0.2, -0.3, 0.2)

_F = {name: k for k, name in enumerate(TELEMETRY_FIELDS)}


@dataclass
class PaperRun:
    """One run of the scenario, every control step recorded.

    Attributes:
        controller: ``"ismc"`` or ``"baseline"``.
        times_s: ``(T,)`` step times (s).
        pos_err_m: ``(T, 3)`` p - p_ref (m).
        att_err_rad: ``(T, 3)`` Θ - Θ_ref, raw eq. 51 reference (rad).
        att_err_tracked_rad: ``(T, 3)`` Θ - Θ_c, the filtered command (rad).
        thrust_n: ``(T,)`` thrust acting (N).
        torque_nm: ``(T, 3)`` body torque acting (N·m).
        saturated: ``(T,)`` True where a rotor was clipped.
    """

    controller: str
    times_s: np.ndarray
    pos_err_m: np.ndarray
    att_err_rad: np.ndarray
    att_err_tracked_rad: np.ndarray
    thrust_n: np.ndarray
    torque_nm: np.ndarray
    saturated: np.ndarray

    def metrics(self) -> dict[str, Any]:
        """The scalar figures of the run (JSON-safe)."""
        t = self.times_s
        pe = np.linalg.norm(self.pos_err_m, axis=1)
        ae = np.linalg.norm(self.att_err_rad, axis=1)
        at = np.linalg.norm(self.att_err_tracked_rad, axis=1)
        steady = t >= PAPER_STEADY_FROM_S - 1e-9
        bad = np.flatnonzero((pe >= PAPER_POS_THRESHOLD_M) | (ae >= PAPER_ATT_THRESHOLD_RAD))
        settled = bool(bad.size == 0 or bad[-1] < t.size - 1)
        settle = float(t[bad[-1] + 1]) if bad.size and settled else (0.0 if settled else None)
        dthrust = np.abs(np.diff(self.thrust_n))
        after = dthrust[t[1:] > settle] if settle is not None else dthrust[:0]
        return {
            "controller": self.controller,
            "pos_err_m": {"max_t_ge_8s": float(pe[steady].max()), "at_20s": float(pe[-1])},
            "att_err_rad": {"max_t_ge_8s": float(ae[steady].max()), "at_20s": float(ae[-1])},
            "att_err_tracked_rad": {"max_t_ge_8s": float(at[steady].max()), "at_20s": float(at[-1])},
            "settle_time_s": settle,
            "max_thrust_step_n": float(dthrust.max()),
            "max_thrust_step_after_settle_n": float(after.max()) if after.size else None,
            "max_thrust_n": float(self.thrust_n.max()),
            "max_torque_nm": float(np.abs(self.torque_nm).max()),
            "max_torque_after_settle_nm": float(np.abs(self.torque_nm[1:][t[1:] > settle]).max())
            if settle is not None and after.size else None,
            "max_torque_step_after_settle_nm": float(np.abs(np.diff(self.torque_nm, axis=0))[t[1:] > settle].max())
            if settle is not None and after.size else None,
            "saturated_steps": int(self.saturated.sum()),
            "meets_thresholds": bool(
                pe[steady].max() < PAPER_POS_THRESHOLD_M and ae[steady].max() < PAPER_ATT_THRESHOLD_RAD
            ),
        }


def run_paper_scenario(
    *, controller: str = "ismc", engine: str = "numba", duration_s: float = PAPER_DURATION_S,
    integrator: str = "euler", switching: str = "sign",
) -> PaperRun:
    """Fly the scenario of docs/method.md §7 with the paper's gains (or the baseline PD) and record every step.

    Args:
        controller: ``"ismc"`` or ``"baseline"``.
        engine: ``"numba"`` or ``"numpy"``.
        duration_s: Length (s), default 20 s as in the paper.
        integrator: ``"euler"`` (both engines) or ``"rk4"`` (numpy engine only).
        switching: the ISMC's switching law, ``"sign"`` (the paper's, default) or ``"boundary"``.
    """
    if controller not in CONTROLLERS:
        raise ValueError(f"unknown controller {controller!r} (expected {' or '.join(CONTROLLERS)})")
    x0 = np.zeros((1, 12))
    x0[0, 0:3] = PAPER_P0_M
    x0[0, 6:9] = PAPER_THETA0_RAD
    # The paper's controllers exactly: the discontinuous switching law and a PD comparison.
    gains = BaselineGains.paper() if controller == "baseline" else IsmcGains.paper(switching=switching)
    res = simulate(
        TrackingReference.paper(), duration_s=duration_s, initial_state=x0, gains=gains,
        disturbance="paper", output_every=1, telemetry=True, engine=engine, integrator=integrator,
        chunk_steps=5000,
    )
    assert res.telemetry is not None  # asked for with telemetry=True
    tel = res.telemetry[:, 0]
    return PaperRun(
        controller=controller,
        times_s=res.frame_times_s,
        pos_err_m=tel[:, _F["e1_x"]:_F["e1_z"] + 1],
        att_err_rad=tel[:, _F["er_phi"]:_F["er_psi"] + 1],
        att_err_tracked_rad=tel[:, _F["e3_phi"]:_F["e3_psi"] + 1],
        thrust_n=tel[:, _F["thrust"]],
        torque_nm=tel[:, _F["tau_x"]:_F["tau_z"] + 1],
        saturated=tel[:, _F["saturated"]] > 0.5,
    )


def paper_report(*, controller: str = "ismc", engine: str = "numba") -> tuple[dict[str, Any], PaperRun, PaperRun]:
    """Run the scenario with ``controller`` and with the other one for comparison.

    Returns:
        ``(report, run, other_run)``; the report holds the run's metrics, the other
        controller's under ``"baseline"`` (or ``"ismc"``), the steady-error ratio
        baseline / ISMC for position and attitude, and the thresholds.
    """
    other = "baseline" if controller == "ismc" else "ismc"
    run = run_paper_scenario(controller=controller, engine=engine)
    cmp_run = run_paper_scenario(controller=other, engine=engine)
    m, o = run.metrics(), cmp_run.metrics()
    ismc, base = (m, o) if controller == "ismc" else (o, m)
    report = {
        "scenario": "paper",
        **m,
        other: {k: o[k] for k in ("pos_err_m", "att_err_rad", "att_err_tracked_rad", "settle_time_s",
                                  "max_thrust_step_n", "max_thrust_step_after_settle_n")},
        "baseline_over_ismc": {
            "pos_err": base["pos_err_m"]["max_t_ge_8s"] / max(ismc["pos_err_m"]["max_t_ge_8s"], 1e-300),
            "att_err": base["att_err_rad"]["max_t_ge_8s"] / max(ismc["att_err_rad"]["max_t_ge_8s"], 1e-300),
            "att_err_tracked": base["att_err_tracked_rad"]["max_t_ge_8s"]
            / max(ismc["att_err_tracked_rad"]["max_t_ge_8s"], 1e-300),
        },
        "thresholds": {
            "pos_err_m": PAPER_POS_THRESHOLD_M, "att_err_rad": PAPER_ATT_THRESHOLD_RAD,
            "steady_from_s": PAPER_STEADY_FROM_S,
        },
        "engine": engine,
    }
    return report, run, cmp_run


def plot_paper(runs: list[PaperRun], path: str) -> None:
    """Write a PNG like the paper's Figs. 3-5: position error, attitude error, inputs.

    Args:
        runs: One or more runs (the first drawn solid, the others dashed).
        path: Output file (PNG).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 8), constrained_layout=True)
    colors = ("tab:red", "tab:green", "tab:blue")
    for n, run in enumerate(runs):
        style = "-" if n == 0 else "--"
        t = run.times_s
        for k, (lab, c) in enumerate(zip("xyz", colors, strict=True)):
            axes[0, 0].plot(t, run.pos_err_m[:, k], style, color=c, lw=1, label=f"e_{lab} ({run.controller})")
        for k, (lab, c) in enumerate(zip(("φ", "θ", "ψ"), colors, strict=True)):
            axes[0, 1].plot(t, run.att_err_rad[:, k], style, color=c, lw=1, label=f"e_{lab} ({run.controller})")
        axes[1, 0].plot(t, run.thrust_n, style, color="k", lw=1, label=f"τ_f ({run.controller})")
        for k, (lab, c) in enumerate(zip(("τ_x", "τ_y", "τ_z"), colors, strict=True)):
            axes[1, 1].plot(t, run.torque_nm[:, k], style, color=c, lw=1, label=f"{lab} ({run.controller})")
    axes[0, 0].set(title="Position error p - p_ref", xlabel="t (s)", ylabel="m")
    axes[0, 1].set(title="Attitude error Θ - Θ_ref (eq. 51)", xlabel="t (s)", ylabel="rad")
    axes[1, 0].set(title="Thrust", xlabel="t (s)", ylabel="N")
    axes[1, 1].set(title="Body torques", xlabel="t (s)", ylabel="N·m")
    # Zoomed insets make the steady error visible next to the metre-scale transient.
    for ax, runs_err, unit in ((axes[0, 0], [r.pos_err_m for r in runs], "m"),
                               (axes[0, 1], [r.att_err_rad for r in runs], "rad")):
        inset = ax.inset_axes([0.45, 0.45, 0.52, 0.5])
        for n, (run, err) in enumerate(zip(runs, runs_err, strict=True)):
            m = run.times_s >= PAPER_STEADY_FROM_S
            for k, c in enumerate(colors):
                inset.plot(run.times_s[m], err[m, k], "-" if n == 0 else "--", color=c, lw=0.8)
        inset.set_title(f"t >= {PAPER_STEADY_FROM_S:g} s ({unit})", fontsize=8)
        inset.tick_params(labelsize=7)
    for ax in axes.flat:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    fig.suptitle("Paper scenario (docs/method.md §7): ISMC tracking under Δ1, Δ2")
    fig.savefig(path, dpi=110)
    plt.close(fig)
