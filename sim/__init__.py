"""Planning and flight: CAPT assignment, quintic time law, whole-show plans,
exact verification, the quadrotor model, ISMC controllers and simulation engines.

Data flows one way: ``plan_show`` (show file -> :class:`ShowPlan`) ->
``check_plan`` (exact verification) -> flight simulation -> playback / export.
"""

from __future__ import annotations

from sim._assignment import Assignment as Assignment
from sim._assignment import AssignmentError as AssignmentError
from sim._assignment import assign as assign
from sim._assignment import assignment_cost as assignment_cost
from sim._assignment import certify as certify
from sim._closest import closest_pair as closest_pair
from sim._plan import PlanError as PlanError
from sim._plan import PlanSample as PlanSample
from sim._plan import Segment as Segment
from sim._plan import ShowPlan as ShowPlan
from sim._plan import TimeLaw as TimeLaw
from sim._plan import TransitionInfo as TransitionInfo
from sim._plan import plan_show as plan_show
from sim._quintic import PEAK_ACCEL_FACTOR as PEAK_ACCEL_FACTOR
from sim._quintic import PEAK_SPEED_FACTOR as PEAK_SPEED_FACTOR
from sim._quintic import quintic_coefficients as quintic_coefficients
from sim._quintic import quintic_eval as quintic_eval
from sim._quintic import rest_to_rest as rest_to_rest
from sim._timing import min_transition_duration as min_transition_duration
from sim._verify import CheckReport as CheckReport
from sim._verify import Violation as Violation
from sim._verify import check_plan as check_plan
from sim._verify import check_show as check_show
from sim._verify import segment_close_pairs as segment_close_pairs

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
    "TimeLaw",
    "TransitionInfo",
    "Violation",
    "assign",
    "assignment_cost",
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
