"""Plan: CAPT assignment, time laws and the whole-show plan (show file -> :class:`ShowPlan`), cached per show."""

from __future__ import annotations

from sim.plan._assignment import Assignment as Assignment
from sim.plan._assignment import AssignmentError as AssignmentError
from sim.plan._assignment import assign as assign
from sim.plan._assignment import assignment_cost as assignment_cost
from sim.plan._assignment import certify as certify
from sim.plan._cache import cached_plan_show as cached_plan_show
from sim.plan._cache import clear_plan_cache as clear_plan_cache
from sim.plan._cache import plan_cache_info as plan_cache_info
from sim.plan._motion import FIT_TOLERANCE_M as FIT_TOLERANCE_M
from sim.plan._motion import hold_pieces as hold_pieces
from sim.plan._plan import ForcedTransition as ForcedTransition
from sim.plan._plan import PlanError as PlanError
from sim.plan._plan import PlanSample as PlanSample
from sim.plan._plan import Segment as Segment
from sim.plan._plan import ShowPlan as ShowPlan
from sim.plan._plan import TransitionInfo as TransitionInfo
from sim.plan._plan import UnresolvedConflict as UnresolvedConflict
from sim.plan._plan import plan_show as plan_show
from sim.plan._quintic import PEAK_ACCEL_FACTOR as PEAK_ACCEL_FACTOR
from sim.plan._quintic import PEAK_SPEED_FACTOR as PEAK_SPEED_FACTOR
from sim.plan._quintic import quintic_coefficients as quintic_coefficients
from sim.plan._quintic import quintic_eval as quintic_eval
from sim.plan._quintic import rest_to_rest as rest_to_rest
from sim.plan._timing import min_transition_duration as min_transition_duration
from sim.plan._trajectory import Trajectories as Trajectories
from sim.plan._trajectory import TrajectoryBuilder as TrajectoryBuilder
from sim.plan._trajectory import TrajectorySample as TrajectorySample
from sim.plan._trajectory import horner as horner
from sim.plan._trajectory import position_at as position_at
from sim.plan._trajectory import states_at as states_at
from sim.plan._trajectory import step_piece as step_piece
from sim.plan._trajectory import velocity_at as velocity_at
