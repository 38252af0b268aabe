"""Plan each show once per process: an LRU of plans keyed by the show's content hash.

``swarmshow check``, ``simulate``, ``export`` and playback all start from
``plan_show(show)``; planning a 1,000-drone show is most of a check's time. With
:func:`cached_plan_show` the second stage asking for the same show (same
:meth:`formations.ShowFile.content_hash`, the SHA-256 of its canonical JSON) gets the
same :class:`~sim.plan._plan.ShowPlan` back. The server's job manager can call it in
each worker process the same way.

The returned plan is shared: callers must not modify its arrays (nothing in the code
base does; the plan is a value).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from typing import TYPE_CHECKING

from sim.plan._plan import ProgressFn, ShowPlan, plan_show

if TYPE_CHECKING:
    from formations import ShowFile

__all__ = ["PLAN_CACHE_SIZE", "cached_plan_show", "clear_plan_cache", "plan_cache_info"]

#: Plans kept per process (a 16,000-drone plan is a few MB of knots and colours).
PLAN_CACHE_SIZE = 8

_lock = threading.Lock()
_plans: OrderedDict[tuple[str, bool], ShowPlan] = OrderedDict()
_stats = {"hits": 0, "misses": 0}


def cached_plan_show(
    show: ShowFile, *, enforce_limits: bool = True, progress: ProgressFn | None = None
) -> ShowPlan:
    """``plan_show(show, enforce_limits=...)``, computed once per show content and flag.

    Args:
        show: a validated show file.
        enforce_limits: as in :func:`~sim.plan._plan.plan_show` (part of the key: ``check``
            plans without enforcing, to report the violation).
        progress: optional callback receiving the fraction done in [0, 1] (a hit reports 1.0).

    Raises:
        PlanError: as ``plan_show`` (failures are not cached).
    """
    # The plan does not read the light effects (issue 18): editing only them must not plan again.
    key = (show.content_hash() if show.lights is None else show.model_copy(update={"lights": None}).content_hash(),
           bool(enforce_limits))
    with _lock:
        plan = _plans.get(key)
        if plan is not None:
            _plans.move_to_end(key)
            _stats["hits"] += 1
    if plan is not None:
        if progress is not None:
            progress(1.0)
        return plan
    # Planned outside the lock: two threads asking for a new show at once both plan it
    # (same result), rather than one show's planning blocking every other show's.
    plan = plan_show(show, enforce_limits=enforce_limits, progress=progress)
    with _lock:
        _stats["misses"] += 1
        _plans[key] = plan
        _plans.move_to_end(key)
        while len(_plans) > PLAN_CACHE_SIZE:
            _plans.popitem(last=False)
    return plan


def clear_plan_cache() -> None:
    """Forget every cached plan (and the hit/miss counts)."""
    with _lock:
        _plans.clear()
        _stats.update(hits=0, misses=0)


def plan_cache_info() -> dict[str, int]:
    """``{"hits", "misses", "size"}`` of this process's plan cache."""
    with _lock:
        return {**_stats, "size": len(_plans)}
