"""Job tasks for the simulation-robustness tests (top level, so the spawned workers import them by name).

Each has the signature of :func:`app.tasks.simulate_task` and flies the show through
``sim.fly_show`` with one fault injected; none edits the flight code.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

from app.tasks import Progress, plan_summary


def _fly(show_text: str, job_id: str, queue: Any, cancel: Any, **kwargs: Any) -> dict[str, Any]:
    from app.tasks import _fly_show
    from formations import parse_show
    from sim import plan_show

    fly_show = _fly_show()

    progress = Progress(job_id, queue, cancel)
    progress.started()
    plan = plan_show(parse_show(show_text))
    result = fly_show(plan, engine="numba", progress=progress, **kwargs)
    return {"plan": plan_summary(plan), "flight": result.summary()}


def absurd_gains_task(show_text: str, options: dict, job_id: str, queue: Any, cancel: Any) -> dict[str, Any]:
    """Position gains a million times the paper's: the controller saturates and drones diverge."""
    from sim.flight.control._ismc import IsmcGains, PositionGains

    gains = IsmcGains(position=PositionGains(k1=5e6, k2=4e6, alpha=5e6))
    return _fly(show_text, job_id, queue, cancel, gains=gains)


def nan_reference_task(show_text: str, options: dict, job_id: str, queue: Any, cancel: Any) -> dict[str, Any]:
    """A NaN in one drone's reference (drone 2, from its second piece on)."""
    import numpy as np

    import sim.flight._runner as flight

    original = flight.plan_reference

    def poisoned(plan, *, drones=None):
        ref = original(plan, drones=drones)
        from sim.plan import Trajectories

        coeffs = np.array(ref.motion.coeffs_m, copy=True)
        coeffs[2, 1:] = np.nan
        return replace(ref, motion=Trajectories(ref.motion.breaks_s, coeffs))

    flight.plan_reference = poisoned
    try:
        return _fly(show_text, job_id, queue, cancel)
    finally:
        flight.plan_reference = original


def hung_task(show_text: str, options: dict, job_id: str, queue: Any, cancel: Any) -> dict[str, Any]:
    """Starts, then never reports progress again (a numerical loop gone wrong)."""
    Progress(job_id, queue, cancel).started()
    time.sleep(3600)
    return {}
