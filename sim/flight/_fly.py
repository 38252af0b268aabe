"""The entry point :func:`fly_show`: a small dispatcher over :class:`FlightOptions`.

``engine="numba"`` or ``"numpy"`` flies in this process (:mod:`sim.flight._runner`);
``engine="dask"`` shards the drones over a Dask cluster (:mod:`sim.flight._dask`, imported
only then), whose workers fly the same local runner.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from sim.flight._options import FlightOptions
from sim.flight._result import FlightResult
from sim.flight._runner import fly_local
from sim.plan._plan import ShowPlan

__all__ = ["fly_show"]


def fly_show(
    plan: ShowPlan,
    options: FlightOptions | None = None,
    *,
    drones: slice | np.ndarray | None = None,
    progress: Callable[[float], None] | None = None,
    **kwargs: Any,
) -> FlightResult:
    """Fly every drone of ``plan`` along its planned trajectory at 1 kHz.

    Args:
        plan: The planned show (``sim.plan_show``).
        options: How to fly (engine, controller, disturbance, output rate, ...; see
            :class:`FlightOptions`). Default: ``FlightOptions()``.
        drones: Optional subset (slice or index array) of the plan's drones to fly.
        progress: Called with the completed fraction in [0, 1] after every chunk; if it
            raises, the run stops and the exception propagates (cancellation).
        **kwargs: Instead of ``options``, its fields as keywords (``engine="numpy"``,
            ``output_hz=50``, ...), the older spelling.

    Returns:
        A :class:`FlightResult`.

    Raises:
        ValueError: an option out of range (names it).
        TypeError: an unknown keyword, or both ``options`` and keywords.
        SchedulerUnreachableError: with ``engine="dask"``, no scheduler or worker answered.
    """
    if options is None:
        options = FlightOptions.from_kwargs(**kwargs)
    elif kwargs:
        raise TypeError("give the flight options either as FlightOptions or as keywords, not both")
    if options.engine == "dask":
        from sim.flight._dask import fly_show_dask

        return fly_show_dask(plan, options, drones=drones, progress=progress)
    return fly_local(plan, options, drones=drones, progress=progress)
