"""One broken limit of a planned show: the record every check of :mod:`sim.verify` returns."""

from __future__ import annotations

from pydantic import BaseModel, Field


class Violation(BaseModel):
    """One broken limit: which drones, when, the value and the limit."""

    kind: str = Field(description="min_distance, speed_xy, speed_z, acceleration, altitude, min_altitude, geofence, "
                      "downwash or transition_duration.")
    drones: list[int] = Field(description="Drone indices involved (for speeds: the worst first, at most 10).")
    time_s: float = Field(description="When the value is reached, seconds from the start of the show.")
    value: float = Field(description="The offending value (metres, m/s, m/s² or seconds; downwash: the distance "
                         "in ellipsoid units, < 1 inside).")
    limit: float = Field(description="The limit it breaks, same unit.")
    segment: int = Field(description="Index of the show segment.")
    message: str = Field(description="One human-readable line.")


__all__ = ["Violation"]
