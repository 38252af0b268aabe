"""Light: LED colours per drone per frame, the plan's base colours with the show's effect stack.

Sits after the plan in the data flow (it reads the plan's segments, positions and base colours)
and before playback and exports, which ask it for colours instead of fading the plan's knots.
"""

from __future__ import annotations

from sim.light._evaluate import LightStack as LightStack
from sim.light._evaluate import base_colors as base_colors
from sim.light._evaluate import plan_positions as plan_positions
from sim.light._evaluate import show_colors as show_colors
from sim.light._evaluate import uniform_hash as uniform_hash

__all__ = ["LightStack", "base_colors", "plan_positions", "show_colors", "uniform_hash"]
