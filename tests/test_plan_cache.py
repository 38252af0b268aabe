"""The per-process plan cache: one plan per show content, LRU-bounded, failures not cached."""

from __future__ import annotations

import numpy as np
import pytest

import sim.plan._cache as cache
from formations import parse_show
from sim import PlanError, plan_show
from sim.bench._shows import benchmark_show
from sim.plan import cached_plan_show, clear_plan_cache, plan_cache_info


@pytest.fixture(autouse=True)
def _fresh_cache():
    clear_plan_cache()
    yield
    clear_plan_cache()


@pytest.fixture
def counted(monkeypatch: pytest.MonkeyPatch) -> list[tuple[str, bool]]:
    calls: list[tuple[str, bool]] = []
    real = cache.plan_show

    def counting(show, *, enforce_limits=True, progress=None):
        calls.append((show.content_hash(), enforce_limits))
        return real(show, enforce_limits=enforce_limits, progress=progress)

    monkeypatch.setattr(cache, "plan_show", counting)
    return calls


def test_same_content_plans_once_and_equals_a_fresh_plan(counted: list) -> None:
    show = benchmark_show(9, formations=1)
    first = cached_plan_show(show)
    # A different object with the same content (a round trip through JSON) hits.
    again = cached_plan_show(parse_show(show.canonical_json()))
    assert again is first
    assert len(counted) == 1
    assert plan_cache_info() == {"hits": 1, "misses": 1, "size": 1}
    fresh = plan_show(show)
    np.testing.assert_array_equal(first.knot_positions_m, fresh.knot_positions_m)
    assert first.duration_s == fresh.duration_s


def test_other_content_and_the_limit_flag_are_other_keys(counted: list) -> None:
    a, b = benchmark_show(9, formations=1), benchmark_show(16, formations=1)
    pa, pb = cached_plan_show(a), cached_plan_show(b)
    assert pa is not pb and pa.drone_count == 9 and pb.drone_count == 16
    loose = cached_plan_show(a, enforce_limits=False)
    assert loose is not pa
    assert [c[1] for c in counted] == [True, True, False]


def test_a_hit_reports_progress_done(counted: list) -> None:
    show = benchmark_show(9, formations=1)
    cached_plan_show(show)
    seen: list[float] = []
    cached_plan_show(show, progress=seen.append)
    assert seen == [1.0]


def test_least_recently_used_plan_is_evicted(monkeypatch: pytest.MonkeyPatch, counted: list) -> None:
    monkeypatch.setattr(cache, "PLAN_CACHE_SIZE", 2)
    shows = [benchmark_show(n, formations=1) for n in (4, 9, 16)]
    cached_plan_show(shows[0])
    cached_plan_show(shows[1])
    cached_plan_show(shows[0])  # now 1 is the least recently used
    cached_plan_show(shows[2])  # evicts 1
    assert plan_cache_info()["size"] == 2
    cached_plan_show(shows[0])
    assert len(counted) == 3
    cached_plan_show(shows[1])
    assert len(counted) == 4


def test_failures_are_not_cached(monkeypatch: pytest.MonkeyPatch) -> None:
    calls = []

    def failing(show, *, enforce_limits=True, progress=None):
        calls.append(1)
        raise PlanError("too fast")

    monkeypatch.setattr(cache, "plan_show", failing)
    show = benchmark_show(4, formations=1)
    for _ in range(2):
        with pytest.raises(PlanError):
            cached_plan_show(show)
    assert len(calls) == 2 and plan_cache_info()["size"] == 0
