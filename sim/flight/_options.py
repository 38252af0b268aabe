"""Typed flight options: what :func:`sim.flight.fly_show` flies with, in one value.

One :class:`FlightOptions` is shared by the command line (``swarmshow simulate``), the
API's simulation request, the job cache key (:meth:`FlightOptions.cache_key`) and the
Dask shards (they get the same options back with ``engine="numba"``), so the names
and their checks exist once. The name sets (:data:`ENGINES`, :data:`CONTROLLERS`,
:data:`DISTURBANCES`) are derived from the ``Literal`` types the API models reuse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Any, Literal, get_args

from sim.flight._disturbance import Disturbance
from sim.flight._errors import ErrorModel
from sim.flight._quadrotor import QuadrotorParams
from sim.flight.control._baseline import BaselineGains
from sim.flight.control._ismc import IsmcGains
from sim.flight.engines import PRECISIONS

__all__ = [
    "CONTROLLERS",
    "DISTURBANCES",
    "ENGINES",
    "ControllerName",
    "DisturbanceName",
    "EngineName",
    "FlightOptions",
]

#: ``numba`` (fused parallel kernel), ``numpy`` (the readable reference) or ``dask``
#: (numba on shards of drones on a Dask cluster, the same arrays as ``numba``).
EngineName = Literal["numba", "numpy", "dask"]
#: ``ismc`` (the paper's controllers) or ``baseline`` (cascaded PD).
ControllerName = Literal["ismc", "baseline"]
#: ``none``, ``paper`` (the paper's disturbance, docs/method.md §7) or ``wind`` (seeded gusts).
DisturbanceName = Literal["none", "paper", "wind"]

ENGINES: tuple[str, ...] = get_args(EngineName)
CONTROLLERS: tuple[str, ...] = get_args(ControllerName)
DISTURBANCES: tuple[str, ...] = get_args(DisturbanceName)

#: Fields that do not change the flown arrays (only where or how fast they are computed).
_NOT_IN_KEY = frozenset({"scheduler", "shards", "connect_timeout_s", "chunk_s"})


@dataclass(frozen=True)
class FlightOptions:
    """How to fly a plan (every field has the default ``fly_show`` had as a keyword).

    Attributes:
        engine: one of :data:`ENGINES`.
        controller: one of :data:`CONTROLLERS`; ``gains`` overrides it.
        disturbance: one of :data:`DISTURBANCES`, or a :class:`Disturbance`.
        output_hz: rate of the recorded frames (Hz); frames are every
            ``round(1000 / output_hz)`` control steps, so 25, 40 and 50 Hz are exact.
        seed: seed of every random component (the wind gusts and every per-drone draw of
            ``errors``); each drone's streams are keyed by (seed, its index in the plan).
        params: vehicle parameters (default: the paper's quadrotor).
        gains: explicit controller gains; overrides ``controller``.
        mismatch: plant mass and inertia off by this fraction (dimensionless).
        divergence_limit_m: tracking error beyond which a drone is stopped ("runaway" or "overpowered") (m).
        chunk_s: simulated time per engine call (s); bounds the working memory.
        scheduler: with ``engine="dask"``: ``"tcp://HOST:PORT"``, ``"local"`` (an
            in-process ``LocalCluster``) or a ``distributed.Client``.
        shards: with ``engine="dask"``: number of tasks (default two per worker thread).
        connect_timeout_s: with ``engine="dask"``: how long to try to reach the
            scheduler and a first worker (s).
        flown_distance: compute the flown minimum distance; False leaves it inf (the
            Dask shards skip it and compute it once over all drones).
        errors: per-drone error models (GNSS, clock, wind field, motors, spread, battery,
            drag); default ideal (:class:`~sim.flight._errors.ErrorModel`).
        colors: evaluate the plan's LED colours at the frames (``FlightResult.colors_rgb``);
            False leaves them ``(0, N, 3)``: the Monte-Carlo runs never read them, and
            evaluating them cost 4-7 % of a run (issue 20).
        precision: the numba kernel's arithmetic, ``"float64"`` (default) or ``"float32"``
            (control laws in single precision, 1.3-1.4x faster kernel; see :func:`sim.flight.simulate`).

    Raises:
        ValueError: a field out of its range, naming the field (the API maps it to 422).
    """

    engine: str = "numba"
    controller: str = "ismc"
    disturbance: str | Disturbance = "none"
    output_hz: float = 25.0
    seed: int = 0
    params: QuadrotorParams | None = None
    gains: IsmcGains | BaselineGains | None = None
    mismatch: float = 0.0
    divergence_limit_m: float = 25.0
    chunk_s: float = 2.0
    scheduler: Any = None
    shards: int | None = None
    connect_timeout_s: float = 10.0
    flown_distance: bool = True
    errors: ErrorModel = field(default_factory=ErrorModel)
    colors: bool = True
    precision: str = "float64"

    def __post_init__(self) -> None:
        if self.engine not in ENGINES:
            raise ValueError(f"unknown engine {self.engine!r} (expected one of {', '.join(ENGINES)})")
        if self.controller not in CONTROLLERS:
            raise ValueError(
                f"unknown controller {self.controller!r} (expected one of {', '.join(CONTROLLERS)})"
            )
        if not isinstance(self.disturbance, Disturbance) and self.disturbance not in DISTURBANCES:
            raise ValueError(
                f"unknown disturbance {self.disturbance!r} (expected one of {', '.join(DISTURBANCES)})"
            )
        if not (isinstance(self.output_hz, (int, float)) and math.isfinite(self.output_hz) and self.output_hz > 0):
            raise ValueError(f"output_hz must be > 0, got {self.output_hz}")
        if not self.chunk_s > 0:
            raise ValueError(f"chunk_s must be > 0, got {self.chunk_s}")
        if not isinstance(self.errors, ErrorModel):
            raise ValueError(f"errors must be an ErrorModel, got {type(self.errors).__name__}")
        if self.precision not in PRECISIONS:
            raise ValueError(f"unknown precision {self.precision!r} (expected one of {', '.join(PRECISIONS)})")
        if self.precision != "float64" and self.engine == "numpy":
            raise ValueError("precision 'float32' needs the numba engine (the numpy reference is float64)")
        if self.engine != "dask" and (self.scheduler is not None or self.shards is not None):
            # A scheduler given to a local engine would silently fly on this machine instead.
            raise ValueError(f"scheduler and shards are only used with engine='dask', not {self.engine!r}")

    @classmethod
    def from_kwargs(cls, **kwargs: Any) -> FlightOptions:
        """Options from ``fly_show``'s old keyword arguments (an unknown name is a ``TypeError``)."""
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(kwargs) - names)
        if unknown:
            raise TypeError(f"unknown flight option(s): {', '.join(unknown)}")
        return cls(**kwargs)

    def with_(self, **changes: Any) -> FlightOptions:
        """A copy with ``changes`` applied (and checked)."""
        return replace(self, **changes)

    def cache_key(self) -> tuple[tuple[str, Any], ...]:
        """The fields that change the flown arrays, as a hashable, ``repr``-stable tuple.

        ``scheduler``, ``shards``, ``connect_timeout_s`` and ``chunk_s`` are left out:
        the Dask engine returns the numba engine's arrays bit for bit, and chunking
        only bounds memory. ``engine="dask"`` is keyed as ``"numba"`` for the same reason.
        """
        out: list[tuple[str, Any]] = []
        for f in fields(self):
            if f.name in _NOT_IN_KEY:
                continue
            value = getattr(self, f.name)
            if f.name == "engine" and value == "dask":
                value = "numba"
            elif isinstance(value, Disturbance):
                # A hand-made disturbance has no stable content key: key it by identity, so it
                # is never confused with another (and simply never hits across processes).
                value = ("instance", value.name, id(value))
            elif value is not None and not isinstance(value, (str, int, float, bool)):
                value = repr(value)  # frozen dataclasses: the repr lists every field
            out.append((f.name, value))
        return tuple(out)
