"""Simulation engines: the plain-numpy reference step, the numba lane kernel, and the driver.

``_state`` holds what both engines share (controller-state layout, reference type,
result); ``_numpy`` and ``_numba`` each import it and never each other (``_vmath`` holds
the kernel's vectorisable elementary functions); ``_numba_f32`` is the kernel with float32
control laws (``precision="float32"``, ``_vmath32`` its functions); ``_driver``
runs a flight in chunks with either (numba is imported only when it is asked for).
"""

from __future__ import annotations

from sim.flight.engines._driver import PRECISIONS as PRECISIONS
from sim.flight.engines._driver import simulate as simulate
from sim.flight.engines._driver import warm_up as warm_up
from sim.flight.engines._numpy import numpy_step as numpy_step
from sim.flight.engines._state import TELEMETRY_FIELDS as TELEMETRY_FIELDS
from sim.flight.engines._state import RefChunk as RefChunk
from sim.flight.engines._state import SimResult as SimResult
from sim.flight.engines._state import TrackingReference as TrackingReference
from sim.flight.engines._state import hover_state as hover_state

__all__ = [
    "PRECISIONS",
    "TELEMETRY_FIELDS",
    "RefChunk",
    "SimResult",
    "TrackingReference",
    "hover_state",
    "numpy_step",
    "simulate",
    "warm_up",
]
