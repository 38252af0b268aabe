"""Crazyswarm export of a dense show (QA pass): the takeoff's end is a place to cut the trajectory.

A show whose first formation is drawn at the minimum distance is flown in layers (spread, CAPT, contract):
7 takeoff pieces and about 14 in the first transition are more than the 15 of one part, and the only cut
candidates were the middles of holds (the takeoff's end only with takeoff waves), so the export refused
every such show ("add a hold or use fewer formations", for a show of one formation).
"""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

from app.exports import ExportError, export_show
from app.exports import _crazyswarm as cs_module
from sim import plan_show
from sim.bench._dense import dense_show
from tests.test_exports_crazyswarm import _drone_positions


def test_dense_one_formation_show_is_cut_where_every_drone_rests():
    show = dense_show(25, formations=1)
    plan = plan_show(show)
    result = export_show(show, "crazyswarm", plan=plan)
    with zipfile.ZipFile(io.BytesIO(result.content)) as z:
        parts = json.loads(z.read("manifest.json"))["parts"]
        assert len(parts) >= 2
        starts = np.array([p["start_s"] for p in parts])
        assert starts[0] == 0.0
        assert abs(sum(p["duration_s"] for p in parts) - plan.duration_s) <= 1e-6
        # Every cut is an instant at which every drone is at rest (independently: the plan's own velocities
        # and accelerations there, and just before and after).
        for s in starts[1:]:
            probe = np.array([s - 1e-6, s, s + 1e-6])
            sample = plan.evaluate(probe)
            assert np.abs(sample.velocities_mps).max() <= 1e-5, s
        # Crazyswarm's reader (and the float32 firmware port) through the parts give the plan.
        t_all = np.linspace(0.0, plan.duration_s, 600)
        for i in range(show.drones):
            got, got32 = _drone_positions(z, parts, i, t_all)
            want = plan.evaluate(t_all, drones=np.array([i])).positions_m[:, 0]
            assert np.linalg.norm(got - want, axis=1).max() <= 1e-6
            assert np.linalg.norm(got32 - want, axis=1).max() <= 1e-3
    # Each part fits its half of the memory (checked per file in _drone_positions too).
    assert cs_module.PART_MAX_PIECES == 15


def test_refusal_names_the_transition_that_needs_too_many_pieces():
    """A layered transition of 22 pieces cannot be cut (no drone rests inside it); the refusal said
    "add a hold or use fewer formations", which cannot help. It now names the transition and its piece count
    (counted here from the exported piece table) and what does help."""
    show = dense_show(25, formations=2)
    plan = plan_show(show)
    drone, start, duration, _, *_ = cs_module.piece_table(plan)
    end = start + duration
    worst = None
    for seg in plan.segments:
        inside = (start < seg.end_s - 1e-9) & (end > seg.start_s + 1e-9)
        count = int(np.bincount(drone[inside], minlength=show.drones).max())
        if seg.kind == "transition" and count > cs_module.PART_MAX_PIECES:
            worst = (seg, count)
    assert worst is not None
    seg, count = worst
    with pytest.raises(ExportError) as info:
        export_show(show, "crazyswarm", plan=plan)
    msg = str(info.value)
    assert f"transition into {seg.label!r}" in msg and f"{count} pieces" in msg, msg
    assert "add a hold" not in msg
