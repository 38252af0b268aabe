"""Flight simulation: the quadrotor model, the ISMC and baseline controllers, the engines.

Public names re-exported from the private modules (see each for the details)::

    from sim.flight import FlightOptions, fly_show
    result = fly_show(plan, FlightOptions(engine="numba", controller="ismc", disturbance="wind"))
    result.summary()

    # the same flight sharded over drones on a Dask cluster (identical arrays)
    result = fly_show(plan, FlightOptions(engine="dask", scheduler="tcp://127.0.0.1:8786"))

    # one flight under an error-model preset: Monte-Carlo run k of seed0 + k == seed
    result = fly_show(plan, single_flight_options("calm-rtk", FlightOptions(seed=7)))

    # K flights with seeds 0..K-1 folded into the flown-separation margin (Monte-Carlo)
    mc = monte_carlo(plan, options_for_preset("gusty-rtk"), runs=20, confidence=0.99)
    mc.to_json()

Layers (each imports only those below): ``_montecarlo`` -> ``_fly`` (the dispatcher) -> ``_dask`` ->
``_runner`` (local flight) -> ``_result``, ``_options`` -> ``engines`` -> ``control``,
``_quadrotor``, ``_disturbance``; ``scenarios`` sits on ``engines``.
"""

from __future__ import annotations

from sim.flight._dask import SchedulerUnreachableError as SchedulerUnreachableError
from sim.flight._dask import connect_scheduler as connect_scheduler
from sim.flight._dask import fly_show_dask as fly_show_dask
from sim.flight._disturbance import Disturbance as Disturbance
from sim.flight._disturbance import make_disturbance as make_disturbance
from sim.flight._errors import ERROR_PRESETS as ERROR_PRESETS
from sim.flight._errors import ErrorModel as ErrorModel
from sim.flight._errors import error_preset as error_preset
from sim.flight._fly import fly_show as fly_show
from sim.flight._montecarlo import DEFAULT_COLLISION_DISTANCE_M as DEFAULT_COLLISION_DISTANCE_M
from sim.flight._montecarlo import DEFAULT_FLIGHT_PRESET as DEFAULT_FLIGHT_PRESET
from sim.flight._montecarlo import PRESETS as PRESETS
from sim.flight._montecarlo import MonteCarloResult as MonteCarloResult
from sim.flight._montecarlo import RunStats as RunStats
from sim.flight._montecarlo import binomial_interval as binomial_interval
from sim.flight._montecarlo import fly_run as fly_run
from sim.flight._montecarlo import monte_carlo as monte_carlo
from sim.flight._montecarlo import options_for_preset as options_for_preset
from sim.flight._montecarlo import planned_closest as planned_closest
from sim.flight._montecarlo import single_flight_options as single_flight_options
from sim.flight._options import CONTROLLERS as CONTROLLERS
from sim.flight._options import DISTURBANCES as DISTURBANCES
from sim.flight._options import ENGINES as ENGINES
from sim.flight._options import ControllerName as ControllerName
from sim.flight._options import DisturbanceName as DisturbanceName
from sim.flight._options import EngineName as EngineName
from sim.flight._options import FlightOptions as FlightOptions
from sim.flight._quadrotor import QuadrotorParams as QuadrotorParams
from sim.flight._result import FLOWN_DISTANCE_TOLERANCE_M as FLOWN_DISTANCE_TOLERANCE_M
from sim.flight._result import FlightResult as FlightResult
from sim.flight._runner import plan_reference as plan_reference
from sim.flight.control._attitude import CommandFilter as CommandFilter
from sim.flight.control._attitude import resolve_attitude as resolve_attitude
from sim.flight.control._baseline import BaselineGains as BaselineGains
from sim.flight.control._ismc import AttitudeGains as AttitudeGains
from sim.flight.control._ismc import IsmcGains as IsmcGains
from sim.flight.control._ismc import PositionGains as PositionGains
from sim.flight.control._ismc import sig as sig
from sim.flight.control._ismc import unit as unit
from sim.flight.engines import PRECISIONS as PRECISIONS
from sim.flight.engines import SimResult as SimResult
from sim.flight.engines import TrackingReference as TrackingReference
from sim.flight.engines import hover_state as hover_state
from sim.flight.engines import numpy_step as numpy_step
from sim.flight.engines import simulate as simulate
from sim.flight.scenarios._paper import PaperRun as PaperRun
from sim.flight.scenarios._paper import paper_report as paper_report
from sim.flight.scenarios._paper import plot_paper as plot_paper
from sim.flight.scenarios._paper import run_paper_scenario as run_paper_scenario

__all__ = [
    "CONTROLLERS",
    "DEFAULT_COLLISION_DISTANCE_M",
    "DEFAULT_FLIGHT_PRESET",
    "PRECISIONS",
    "PRESETS",
    "MonteCarloResult",
    "RunStats",
    "binomial_interval",
    "fly_run",
    "monte_carlo",
    "options_for_preset",
    "planned_closest",
    "single_flight_options",
    "DISTURBANCES",
    "ENGINES",
    "ERROR_PRESETS",
    "ErrorModel",
    "FLOWN_DISTANCE_TOLERANCE_M",
    "ControllerName",
    "DisturbanceName",
    "EngineName",
    "FlightOptions",
    "AttitudeGains",
    "BaselineGains",
    "CommandFilter",
    "Disturbance",
    "FlightResult",
    "IsmcGains",
    "PaperRun",
    "PositionGains",
    "QuadrotorParams",
    "SchedulerUnreachableError",
    "SimResult",
    "TrackingReference",
    "connect_scheduler",
    "error_preset",
    "fly_show",
    "fly_show_dask",
    "hover_state",
    "make_disturbance",
    "numpy_step",
    "paper_report",
    "plan_reference",
    "plot_paper",
    "resolve_attitude",
    "run_paper_scenario",
    "sig",
    "simulate",
    "unit",
]
