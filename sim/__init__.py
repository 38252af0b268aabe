"""Planning, verification and flight, a subpackage per stage.

``sim.plan`` (CAPT assignment, time laws, the show plan), ``sim.verify`` (the exact
check), ``sim.flight`` (quadrotor model, controllers, engines, runners), and
``sim.geometry`` (primitives shared by the stages, such as the closest-pair search).

Data flows one way: ``plan_show`` (show file -> :class:`ShowPlan`) ->
``check_plan`` (exact verification) -> flight simulation -> playback / export.
"""

from __future__ import annotations

from sim.geometry import closest_pair as closest_pair
from sim.plan import PEAK_ACCEL_FACTOR as PEAK_ACCEL_FACTOR
from sim.plan import PEAK_SPEED_FACTOR as PEAK_SPEED_FACTOR
from sim.plan import Assignment as Assignment
from sim.plan import AssignmentError as AssignmentError
from sim.plan import PlanError as PlanError
from sim.plan import PlanSample as PlanSample
from sim.plan import Segment as Segment
from sim.plan import ShowPlan as ShowPlan
from sim.plan import TransitionInfo as TransitionInfo
from sim.plan import assign as assign
from sim.plan import assignment_cost as assignment_cost
from sim.plan import cached_plan_show as cached_plan_show
from sim.plan import certify as certify
from sim.plan import min_transition_duration as min_transition_duration
from sim.plan import plan_show as plan_show
from sim.plan import quintic_coefficients as quintic_coefficients
from sim.plan import quintic_eval as quintic_eval
from sim.plan import rest_to_rest as rest_to_rest
from sim.verify import CheckReport as CheckReport
from sim.verify import Violation as Violation
from sim.verify import check_plan as check_plan
from sim.verify import check_show as check_show
from sim.verify import segment_close_pairs as segment_close_pairs

__all__ = [
    "PEAK_ACCEL_FACTOR",
    "PEAK_SPEED_FACTOR",
    "Assignment",
    "AssignmentError",
    "CheckReport",
    "PlanError",
    "PlanSample",
    "Segment",
    "ShowPlan",
    "TransitionInfo",
    "Violation",
    "assign",
    "assignment_cost",
    "cached_plan_show",
    "check_plan",
    "certify",
    "check_show",
    "closest_pair",
    "min_transition_duration",
    "plan_show",
    "quintic_coefficients",
    "quintic_eval",
    "rest_to_rest",
    "segment_close_pairs",
]
