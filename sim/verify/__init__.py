"""Verify: the exact continuous-time check of a planned show (separation, speeds, acceleration, altitude)."""

from __future__ import annotations

from sim.verify._bounds import check_bounds as check_bounds
from sim.verify._check import CheckReport as CheckReport
from sim.verify._check import ClosePairs as ClosePairs
from sim.verify._check import FixHint as FixHint
from sim.verify._check import TransitionCheck as TransitionCheck
from sim.verify._check import check_plan as check_plan
from sim.verify._check import check_show as check_show
from sim.verify._check import downwash_violations as downwash_violations
from sim.verify._check import piece_extrema as piece_extrema
from sim.verify._check import speed_bounds as speed_bounds
from sim.verify._check import window_close_pairs as window_close_pairs
from sim.verify._segments import segment_close_pairs as segment_close_pairs
from sim.verify._violation import Violation as Violation
