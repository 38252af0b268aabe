""".skyc cue list: Skybrush Live shows the show's cues (formation starts, the music-pinned times, named)."""

from __future__ import annotations

import io
import json
import zipfile

import pytest

from app.exports import export_show
from sim import plan_show
from tests.conftest import fibonacci_sphere, make_show, ring
from tests.skybrush_readers import show_cues


def _formations(**pins):
    return [
        {"name": "ring", "hold_s": 2.0, "points": ring(16, 12.0), "color": "#ff0000", **pins.get("ring", {})},
        {"name": "sphere", "hold_s": 3.5, "points": fibonacci_sphere(16, 9.0), "color": "#00ff00",
         **pins.get("sphere", {})},
        {"name": "wide ring", "hold_s": 2.5, "points": ring(16, 15.0, center=(0.0, 0.0, 40.0)), "color": "#0000ff"},
    ]


@pytest.fixture(scope="module")
def pinned():
    """The ring -> sphere -> ring show with the sphere pinned to the music: reached and left at set times."""
    kw = {"drones": 16, "rows": 4, "cols": 4, "spacing_m": 4.5}
    free = plan_show(make_show(_formations(), **kw))
    hold = dict(free.formation_segments())["sphere"]
    arrive, leave = round(hold.start_s + 3.25, 3), round(hold.start_s + 3.25 + 6.5, 3)
    show = make_show(_formations(sphere={"arrive_at_s": arrive, "leave_at_s": leave}), **kw)
    return show, plan_show(show), arrive, leave


def _cues(show, plan):
    with zipfile.ZipFile(io.BytesIO(export_show(show, "skyc", plan=plan).content)) as z:
        return show_cues(json.loads(z.read("show.json")))


def test_skyc_cues_are_the_formation_starts_and_the_pinned_times(pinned):
    show, plan, arrive, leave = pinned
    cues = _cues(show, plan)
    assert cues, "the .skyc cue list is empty"
    # One cue per formation, named after it, when the drones reach it (the plan's hold start, to the ms).
    starts = [(name, seg.start_s) for name, seg in plan.formation_segments()]
    named = {name: t for name, t in cues}
    for name, t in starts:
        assert named[name] == pytest.approx(t, abs=5e-4)
    # The pinned times are exactly the designer's (the music's), and the pinned departure has its own cue.
    assert named["sphere"] == arrive
    assert named["sphere ends"] == leave
    assert [n for n, _ in cues] == ["ring", "sphere", "sphere ends", "wide ring"]
    assert [t for _, t in cues] == sorted(t for _, t in cues)
    # Times in whole milliseconds, within the show.
    assert all(round(t, 3) == t and 0.0 <= t <= plan.duration_s for _, t in cues)


def test_skyc_without_pins_lists_every_formation_start(pinned):
    show, _, _, _ = pinned
    free = make_show(_formations(), drones=16, rows=4, cols=4, spacing_m=4.5)
    plan = plan_show(free)
    cues = _cues(free, plan)
    assert [n for n, _ in cues] == [f.name for f in free.formations]
